"""The depth runaway: off the command and not coming back, the plane at the stop that would
bring the vehicle back (:mod:`auv_depth_lqr.runaway`).

Oracles: hand-written samples whose verdict is worked out from the rule (more than 1 m off,
the plane at 98 % of its travel towards the command, 5 s without a break, no nearer than at
the start); and flights whose outcome is known without the monitor: the REMUS 100 with 30 %
less fin lift and its thrust held, which cannot hold level with its plane at 1.5 m/s in the
dive's pitch (its level trim takes 13.0 of its 13.6 deg, :mod:`auv_sim.trim`) and ends the
flight more than 15 m past its command; and flights of the vehicle files that settle on
their command.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT, load_bench
from diagnostic_msgs.msg import DiagnosticStatus

from auv_depth_lqr.closed_loop import foreign_plant, model_error_plant, run_closed_loop
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.node_status import control_status
from auv_depth_lqr.pilot import DepthPilot
from auv_depth_lqr.runaway import RunawayMonitor
from auv_sim.params import load_vehicle
from auv_sim.trim import VerticalPlane

BAR_MAX = math.radians(20.0)
FOREIGN_PLANTS = load_bench('foreign_plants')


def _fly(monitor: RunawayMonitor, samples: list[tuple[float, float, float, float]]) -> list[bool]:
    return [monitor.update(*s) is not None for s in samples]


def test_too_deep_with_the_nose_up_stop_held_for_5_s_is_a_runaway() -> None:
    """30 m commanded; from t = 10 s the vehicle is 1.5 m below it and sinking 0.1 m/s, the
    plane at -20 deg (nose up, its stop): declared at t = 15 s, not before."""
    monitor = RunawayMonitor(BAR_MAX)
    samples = [(10.0 + 0.5 * k, 31.5 + 0.05 * k, 30.0, -BAR_MAX) for k in range(13)]
    verdicts = _fly(monitor, samples)
    assert verdicts == [False] * 10 + [True] * 3
    state = monitor.state
    assert state is not None and state.below and state.since == 10.0
    assert state.off == pytest.approx(31.5 + 0.6 - 30.0)
    assert state.stop_time == pytest.approx(6.0)


@pytest.mark.parametrize(('case', 'samples'), [
    # within 1 m of the command
    ('0.9 m off', [(0.5 * k, 30.9, 30.0, -BAR_MAX) for k in range(20)]),
    # the plane short of its stop (97 % of its travel)
    ('plane at 97 %', [(0.5 * k, 32.0, 30.0, -0.97 * BAR_MAX) for k in range(20)]),
    # the plane at the stop that drives it further away (nose down, too deep)
    ('wrong stop', [(0.5 * k, 32.0, 30.0, BAR_MAX) for k in range(20)]),
    # coming back: 2.0 m off at the start, 1.9 m off 5 s later
    ('coming back', [(0.5 * k, 32.0 - 0.01 * k, 30.0, -BAR_MAX) for k in range(11)]),
])
def test_no_runaway(case: str, samples: list[tuple[float, float, float, float]]) -> None:
    assert not any(_fly(RunawayMonitor(BAR_MAX), samples)), case


def test_a_break_starts_the_count_again() -> None:
    """4.5 s at the stop, one sample off it, 4.5 s at the stop again: no runaway; above the
    command (a climb past it) the stop is the nose-down one."""
    monitor = RunawayMonitor(BAR_MAX)
    first = [(0.5 * k, 8.0, 10.0, BAR_MAX) for k in range(10)]
    gap = [(5.0, 8.0, 10.0, 0.5 * BAR_MAX)]
    second = [(5.5 + 0.5 * k, 8.0, 10.0, BAR_MAX) for k in range(10)]
    assert not any(_fly(monitor, first + gap + second))
    assert _fly(monitor, [(10.5, 8.0, 10.0, BAR_MAX)]) == [True]
    assert monitor.state is not None and not monitor.state.below


@pytest.mark.parametrize(('field', 'value'), [('bar_max', 0.0), ('distance', math.nan),
                                              ('stop_time', -1.0), ('at_stop', 1.5)])
def test_bad_settings_are_refused(field: str, value: float) -> None:
    kwargs = {'bar_max': BAR_MAX, field: value}
    with pytest.raises(DesignError, match=field):
        RunawayMonitor(**kwargs)


def _runaways(name: str, error: str | None, z0: float, z1: float, u0: float
              ) -> tuple[list[float], np.ndarray, DepthPilot]:
    """Fly ``z0 -> z1`` [m] at ``u0`` [m/s], thrust held, the pilot on the file ``name``,
    the plant the file with ``error`` (``foreign``: :func:`foreign_plant`): the times [s]
    the pilot's runaway report began (the benchmark's listener), the depths [m], the pilot."""
    design = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    real, environment = ((design, None) if error is None else
                         (foreign_plant(design, u0), None) if error == 'foreign' else
                         model_error_plant(design, error))
    pilot = DepthPilot.for_vehicle(design)
    began = FOREIGN_PLANTS.listen_for_runaway(pilot)
    run = run_closed_loop(real, [(0.0, z1)], 200.0, z0=z0, u0=u0, environment=environment,
                          pilot=pilot)
    return began, run.record.x[:, 2], pilot


def test_a_dive_the_plane_cannot_pull_out_of_is_said() -> None:
    """The REMUS 100 with 30 % less fin lift, thrust held, 10 -> 30 m: said once, as a
    runaway below the command at the nose-up stop, while the vehicle dives on."""
    design = load_vehicle(ROOT / 'config' / 'remus100.yaml')
    real, _ = model_error_plant(design, 'fins*0.7')
    trim = VerticalPlane(real).trim(1.5)
    assert abs(trim.bar) > 0.9 * real.bar_max  # the premise: hardly any plane left
    began, z, pilot = _runaways('remus100', 'fins*0.7', 10.0, 30.0, 1.5)
    assert float(z[-1]) > 45.0  # the outcome, without the monitor
    assert len(began) == 1 and began[0] < 130.0, began
    text = pilot.runaway_warning()  # still on at the end
    assert 'below the commanded 30 m' in text and 'nose-up stop' in text, text
    # the node's depth-control status at the end of the flight
    status = control_status(pilot, '/auv/depth_pilot', '/auv', 200.0, '', '', None)
    values = {kv.key: kv.value for kv in status.values}
    assert status.level == DiagnosticStatus.ERROR
    assert 'depth runaway' in status.message
    off, side = values['depth_runaway_m'].split()
    assert side == 'below' and float(off) == pytest.approx(float(z[-1]) - 30.0, abs=0.1)


@pytest.mark.parametrize(('name', 'error', 'z0', 'z1', 'u0'), [
    ('a18m', None, 40.0, 10.0, 2.0),
    ('remus100', None, 10.0, 30.0, 1.5),     # thrust held: 0.66 m of overshoot
    ('a18m', 'foreign', 20.0, 10.0, 1.5),    # 0.91 m of overshoot, taken back
])
def test_flights_that_settle_say_no_runaway(name: str, error: str | None, z0: float,
                                            z1: float, u0: float) -> None:
    """Flights that pass their command and come back (``foreign``:
    :func:`~auv_depth_lqr.closed_loop.foreign_plant`)."""
    began, z, _ = _runaways(name, error, z0, z1, u0)
    assert abs(float(z[-1]) - z1) < 0.1  # the outcome, without the monitor
    assert began == []
