# Two commands a user needs (README): `make demo` and `make test`. Each sets up what it needs.
SHELL := /bin/bash
ENV := . .venv/bin/auv-env &&
OUT ?= out/demo

.PHONY: setup demo test bench lint clean
setup:
	@tools/bootstrap.sh

demo: setup
	@$(ENV) auv demo --out $(OUT)

test: setup
	@$(ENV) python -m pytest -q -p no:cacheprovider -n auto --maxprocesses 4 --dist loadfile --durations=25 tests src

bench: setup
	@$(ENV) python bench/run_all.py --out bench/results/latest.json

lint: setup
	@$(ENV) python -m ruff check src tests bench tools
	@$(ENV) python -m mypy

clean:
	rm -rf build install log out
