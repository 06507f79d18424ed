"""The diagnosis of ``auv gap`` as one library call: :class:`GapOptions` in, :class:`GapRun`
out (:func:`run_gap`).

The logs are read (contract bags, or original logs through a mapping file: :mod:`auv_logs`),
the vehicle's actuator limits widened to what was logged (:mod:`auv_logs.limits`, never
clipped), the gap diagnosed (:func:`auv_gap.diagnose.diagnose`) and the report written into
the output directory (:mod:`auv_gap.report`, with ``inputs.json``: the imports, what was left
out, the commands logged outside the limits). ``auv gap`` and campaigns
(:mod:`auv_campaign.tasks`) are adapters over these objects. Units: SI; the state in NED/FRD.
"""
from __future__ import annotations

import dataclasses
import json
import math
import pathlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from auv_gap.errors import GapError

if TYPE_CHECKING:
    from auv_gap.diagnose import Diagnosis

Progress = Callable[[str], None]


@dataclasses.dataclass(frozen=True)
class GapOptions:
    """Which logs, against which vehicle file, how (the options of ``auv gap``).

    Raises
    ------
    GapError
        On construction: no log, a window that is not a finite time > 0 s, ``top`` < 1, held-out
        logs that are not among the logs or are all of them.
    """

    logs: tuple[str, ...]
    """Contract bags (directories or ``.mcap`` files), or original logs with :attr:`map`."""
    vehicle: str
    """The nominal vehicle file."""
    out: str
    """Output directory."""
    map: str | None = None
    """Mapping file the original logs are read through."""
    holdout: tuple[str, ...] = ()
    """Logs (among :attr:`logs`) held out whole; empty: every third window."""
    window: float | None = None
    """Window the logs are cut into and held out by [s]; None: chosen from the data."""
    ranges: str | None = None
    """Typical and possible ranges file; None: ``config/plausible_ranges.yaml``."""
    strict: bool = False
    """With :attr:`map`: refuse a bad row or a log without a usable segment."""
    effects: tuple[str, ...] | None = None
    """Catalogue effects to try; None: all."""
    top: int = 3
    """Effects refined by free run and combined."""
    plots: bool = True
    """Write the PNG plots."""

    def __post_init__(self) -> None:
        if not self.logs:
            raise GapError('no log given')
        if self.window is not None and not (math.isfinite(self.window) and self.window > 0):
            raise GapError(f'--window must be > 0 s, got {self.window}')
        if self.top < 1:
            raise GapError(f'--top must be at least 1, got {self.top}')
        held = self.held_out_indices()
        if held and len(held) == len(self.logs):
            raise GapError('--holdout cannot hold out every bag')

    def held_out_indices(self) -> list[int]:
        """Indices into :attr:`logs` of the held-out logs.

        Raises
        ------
        GapError
            A held-out log that is not one of the logs.
        """
        index = {str(pathlib.Path(b).resolve()): i for i, b in enumerate(self.logs)}
        out = []
        for h in self.holdout:
            key = str(pathlib.Path(h).resolve())
            if key not in index:
                raise GapError(f'--holdout {h} is not one of the bags given')
            out.append(index[key])
        return sorted(set(out))


@dataclasses.dataclass(frozen=True)
class GapRun:
    """The outcome of :func:`run_gap`."""

    diagnosis: Diagnosis
    """Report, details and plot data."""
    path: pathlib.Path
    """The written ``report.md``."""
    imports: list[dict[str, Any]]
    """Import reports of logs read through a map (empty for bags)."""
    skipped: list[str]
    """Logs left out, one line each (a cut-off or empty log, with a map)."""
    limits: dict[str, Any]
    """Commands logged outside the vehicle file's limits (channel -> count, range)."""


def run_gap(opts: GapOptions, progress: Progress | None = None) -> GapRun:
    """Read, diagnose and write (see the module docstring).

    Raises
    ------
    GapError, LogError
        Bad input: a log that cannot be read, too short, every log left out.
    ParameterError
        A bad vehicle file.
    OSError
        A file that cannot be read or written.
    """
    from auv_gap.diagnose import diagnose
    from auv_gap.logs import GapLog, from_contract_arrays, load_bag, measured_fins_vehicle
    from auv_gap.ranges import load_ranges
    from auv_gap.report import write_report
    from auv_logs.limits import as_logged, describe
    from auv_sim.params import load_vehicle

    say = progress or (lambda _msg: None)
    vehicle = load_vehicle(opts.vehicle)
    held_bags = opts.held_out_indices()
    ranges = load_ranges(opts.ranges) if opts.ranges else None
    logs: list[GapLog] = []
    held_logs: list[int] = []
    imports: list[dict[str, Any]] = []
    skipped: list[str] = []
    for i, b in enumerate(opts.logs):
        say(f'reading {b}')
        if opts.map is not None:
            from auv_logs.contract_bag import contract_arrays
            from auv_logs.importer import SKIPPABLE, import_log
            from auv_logs.mapping import load_map
            from auv_logs.plausibility import envelope_of

            try:
                imported = import_log(load_map(opts.map), b, strict=opts.strict,
                                      envelope=envelope_of(vehicle))
            except SKIPPABLE as exc:
                if opts.strict or len(opts.logs) == 1:
                    raise
                skipped.append(f'{b}: left out: {str(exc).splitlines()[0]}')
                say(skipped[-1])
                continue
            imports.append(dict(imported.report))
            pieces = from_contract_arrays(imported.name, contract_arrays(imported),
                                          [imported.report])
        else:
            pieces = load_bag(b)
        for piece in pieces:
            if i in held_bags:
                held_logs.append(len(logs))
            logs.append(piece)
    unique = {id(lg.commands): lg.commands for lg in logs}
    vehicle, limits = as_logged(vehicle, list(unique.values()))
    for line in describe(limits):
        say(line)
    vehicle = measured_fins_vehicle(vehicle, logs)
    if not logs:
        raise GapError('every log was left out: ' + '; '.join(skipped))
    diag = diagnose(vehicle, logs, window=opts.window, held_out_logs=held_logs,
                    effects=None if opts.effects is None else list(opts.effects), top=opts.top,
                    progress=say, ranges=ranges)
    diag.details['skipped'] = skipped
    path = write_report(diag, opts.out, plots=opts.plots)
    (path.parent / 'inputs.json').write_text(json.dumps(
        {'logged_outside_limits': limits, 'imports': imports, 'skipped': skipped},
        indent=2) + '\n')
    return GapRun(diag, path, imports, skipped, limits)
