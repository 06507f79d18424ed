"""Campaigns: the single-log tools mapped over many logs, and Monte Carlo runs of the closed
loop, on a Dask cluster (an embedded local one by default).

Modules: :mod:`.engine` (the Dask client), :mod:`.inputs` (which logs), :mod:`.cache`
(results by content hash and settings), :mod:`.tasks` (one log, one task), :mod:`.runner`
(submit, gather, retries), :mod:`.trend` (drift and step tests), :mod:`.report` (the
campaign report), :mod:`.montecarlo` (draws and closed-loop chunks), :mod:`.synthetic`
(simulated campaigns for tests and benchmarks), :mod:`.cli`.
"""
