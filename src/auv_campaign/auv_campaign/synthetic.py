"""Synthetic campaigns for tests and benchmarks: missions flown on the simulator with effects
that change from mission to mission, written as vehicle bags.

Each mission is :func:`auv_gap.synth.simulate` (the simulator with effects, the
project's LQR depth pilot, BAR doublets, seeded sensor noise) over the first ``duration``
seconds of :func:`auv_gap.synth.panel_scenario`, written by
:func:`auv_gap.synth.write_bag` with the mission's start time as its log time. The
campaign's diagnosis is told none of it.
"""
from __future__ import annotations

import dataclasses
import pathlib
from collections.abc import Callable, Mapping

from auv_gap import synth
from auv_sim.params import VehicleParams

Effects = Mapping[str, Mapping[str, float]]
#: 2026-05-01 00:00 UTC [ns]: the first mission's start.
CAMPAIGN_START_NS = 1_777_593_600_000_000_000


@dataclasses.dataclass(frozen=True)
class Mission:
    """A written mission: bag path, start [s since the epoch], true effects."""

    path: pathlib.Path
    start_s: float
    effects: dict[str, dict[str, float]]


def short_scenario(duration: float) -> synth.Scenario:
    """The first ``duration`` seconds (at most 900) of the panel scenario."""
    sc = synth.panel_scenario()
    return dataclasses.replace(
        sc, duration=float(duration), depth=tuple(r for r in sc.depth if r[0] < duration),
        thrust=tuple(r for r in sc.thrust if r[0] < duration),
        doublets=tuple(r for r in sc.doublets if r[0] < duration))


def write_campaign(out: str | pathlib.Path, vehicle: VehicleParams, missions: int,
                   effects_of: Callable[[int], Effects], duration: float = 300.0,
                   spacing_h: float = 8.0, seed: int = 0) -> list[Mission]:
    """Write ``missions`` bags ``out/mission_NNN.mcap``, mission ``i`` flown with
    ``effects_of(i)`` and starting ``spacing_h`` hours after the previous one."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = short_scenario(duration)
    written = []
    for i in range(missions):
        eff = {k: dict(v) for k, v in effects_of(i).items()}
        log = synth.simulate(vehicle, {'effects': eff}, scenario, seed=seed * 100003 + i)
        t0 = CAMPAIGN_START_NS + int(round(i * spacing_h * 3600.0)) * 10**9
        path = out / f'mission_{i:03d}.mcap'
        synth.write_bag(path, log, t0_ns=t0)
        written.append(Mission(path, t0 * 1e-9, eff))
    return written
