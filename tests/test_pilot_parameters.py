"""The depth-pilot node's parameters: schema, ranges and checks (pure), and their descriptors
and validation on a running node (over DDS)."""
from __future__ import annotations

import math
import pathlib
import re
import time
from typing import Any

import numpy as np
import pytest

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.parameters import (
    PARAMETERS,
    START_ONLY,
    ParameterSpec,
    Range,
    checked_values,
    pilot_from_values,
)
from auv_sim.errors import AuvSimError

DEFAULTS = {name: spec.default for name, spec in PARAMETERS.items()}
RANGED = [spec for spec in PARAMETERS.values() if spec.range is not None]


def with_value(name: str, value: Any) -> dict[str, Any]:
    return {**DEFAULTS, name: value}


def refused(name: str, value: Any) -> str:
    """The message of checked_values refusing ``value`` for ``name`` (fails if accepted)."""
    with pytest.raises(DesignError) as info:
        checked_values(with_value(name, value))
    return str(info.value)


def is_integer(spec: ParameterSpec) -> bool:
    return isinstance(spec.default, int) and not isinstance(spec.default, bool)


def edges(spec: ParameterSpec) -> list[tuple[float | int, float | int]]:
    """(just inside, just outside) each finite bound of the parameter's range: the next
    integer for an integer parameter, the next double (math.nextafter) for a float one."""
    assert spec.range is not None
    r = spec.range
    out = []
    for bound, is_open, outward in ((r.lower, r.lower_open, -math.inf),
                                    (r.upper, r.upper_open, math.inf)):
        if math.isinf(bound):
            continue
        if is_integer(spec):
            step = -1 if outward < 0 else 1
            assert not is_open
            out.append((int(bound), int(bound) + step))
        elif is_open:
            out.append((math.nextafter(bound, -outward), bound))
        else:
            out.append((bound, math.nextafter(bound, outward)))
    return out


# -- the schema -------------------------------------------------------------------------------
def test_every_parameter_has_a_one_line_description_with_its_unit_or_none_declared() -> None:
    assert len(PARAMETERS) == 33
    for spec in PARAMETERS.values():
        assert spec.description and '\n' not in spec.description, spec.name
        if spec.unit:
            assert re.search(rf'\[{re.escape(spec.unit)}[],]', spec.description), spec.name
        else:
            # unitless by declaration: no bracketed unit in the text either
            assert '[' not in spec.description, spec.name
    # every physical float parameter carries a unit; the unitless floats are the two shares
    unitless_floats = {s.name for s in PARAMETERS.values()
                       if isinstance(s.default, float) and not s.unit}
    assert unitless_floats == {'recovery_gain', 'recovery_bar_fraction'}


def test_defaults_pass_the_checks_and_match_the_declared_ranges_and_choices() -> None:
    values = checked_values(DEFAULTS)
    for spec in PARAMETERS.values():
        if spec.range is not None:
            assert values[spec.name] in spec.range, spec.name
        if spec.choices:
            assert spec.default in spec.choices, spec.name
            assert isinstance(spec.default, str), spec.name
        if spec.nan:
            assert isinstance(spec.default, float) and spec.range is None, spec.name
    assert set(START_ONLY) == {
        'realtime_priority', 'state_source', 'state_reliability', 'diagnostics_period',
        'start_subscribers', 'startup_timeout', 'diagnostics_subscribers', 'report_file',
        'learn', 'pitch_envelope', 'plane_rate_design'}


@pytest.mark.parametrize('spec', RANGED, ids=[s.name for s in RANGED])
def test_declared_range_agrees_with_checked_values(spec: ParameterSpec) -> None:
    pairs = edges(spec)
    assert pairs, spec.name
    for inside, outside in pairs:
        assert checked_values(with_value(spec.name, inside))[spec.name] == inside
        assert f'parameter {spec.name} = ' in refused(spec.name, outside)
    if not is_integer(spec):
        assert 'must be finite' in refused(spec.name, math.inf)
        assert 'must be finite' in refused(spec.name, math.nan)


#: Parameters the pure core checks itself (PilotSettings, RecoverySettings, Limits): a value
#: 1e-6 outside the declared range must be refused there too, so the declared range is not
#: tighter than the core's own. The others are checked by the node only. (The core is not
#: asked about the next double outside: a bar_max of -5e-324 rad squares to 0 in
#: derive_tuning, a ZeroDivisionError, not a DesignError; checked_values refuses it first.)
CORE_CHECKED = [s for s in RANGED if s.name not in START_ONLY]


@pytest.mark.parametrize('spec', CORE_CHECKED, ids=[s.name for s in CORE_CHECKED])
def test_value_outside_a_range_is_refused_by_the_pure_core_too(spec: ParameterSpec) -> None:
    values = checked_values(DEFAULTS)
    for _, outside in edges(spec):
        beyond = outside + math.copysign(1e-6, outside - spec.default)
        assert beyond not in spec.range  # type: ignore[operator]
        with pytest.raises((DesignError, AuvSimError)):
            pilot_from_values({**values, spec.name: beyond})


def test_hand_worked_cases_of_each_range_kind() -> None:
    # open lower bound: rate > 0 Hz
    assert refused('rate', 0.0) == \
        'parameter rate = 0.0 Hz must be in (0, inf) (pilot setting rate_hz)'
    assert checked_values(with_value('rate', 0.001))['rate'] == 0.001
    # an integer for a float parameter is taken as a float
    five = checked_values(with_value('rate', 5))['rate']
    assert five == 5.0 and isinstance(five, float)
    # open upper bound: theta_max < pi/2 = 1.5707963 rad
    assert 'must be in (0, 1.5708)' in refused('theta_max', 1.5708)
    assert checked_values(with_value('theta_max', 1.5707))['theta_max'] == 1.5707
    # closed upper bound: recovery_bar_fraction <= 1
    assert checked_values(with_value('recovery_bar_fraction', 1))['recovery_bar_fraction'] \
        == 1.0
    assert 'must be in (0, 1]' in refused('recovery_bar_fraction', 1.001)
    assert 'must be in (0, 1]' in refused('recovery_bar_fraction', 0.0)
    # closed lower bound: water_speed >= 0 m/s (0: the measured surge)
    assert checked_values(with_value('water_speed', 0))['water_speed'] == 0.0
    assert refused('water_speed', -0.001) == \
        'parameter water_speed = -0.001 m/s must be in [0, inf)'
    # integer range 0-99
    assert checked_values(with_value('realtime_priority', 99))['realtime_priority'] == 99
    assert refused('realtime_priority', 100) == \
        'parameter realtime_priority = 100 must be in [0, 99]'
    assert 'must be in [0, 99]' in refused('realtime_priority', -1)
    assert refused('realtime_priority', 7.0) == \
        'parameter realtime_priority = 7.0 must be an integer'
    # NaN: allowed only where it means "derived"
    assert math.isnan(checked_values(with_value('safe_bar', math.nan))['safe_bar'])
    assert refused('safe_bar', math.inf) == \
        'parameter safe_bar = inf rad must be finite (or NaN)'
    # choices and types
    assert "must be one of ['refuse', 'clamp']" in refused('depth_command_mode', 'round')
    assert 'must be true or false' in refused('lockstep', 1)
    assert 'must be a number' in refused('rate', True)


def test_range_text_and_membership() -> None:
    share = Range(0.0, 1.0, lower_open=True)
    assert share.text() == '(0, 1]'
    assert 1.0 in share and 0.5 in share and 0.0 not in share and 1.0000001 not in share
    assert Range(0.0).text() == '[0, inf)'
    assert 0.0 in Range(0.0) and -1e-300 not in Range(0.0)


def test_docs_table_lists_every_parameter_with_its_range() -> None:
    text = (pathlib.Path(__file__).parents[1] / 'docs' / 'pilot-interfaces.md').read_text()
    rows = [line for line in text.splitlines() if line.startswith('| `')]
    for spec in PARAMETERS.values():
        row = [r for r in rows if f'`{spec.name}`' in r.split('|')[1]]
        assert len(row) == 1, spec.name
        cells = [c.strip() for c in row[0].split('|')]
        assert ('(start)' in cells[1]) == spec.start_only, spec.name
        if spec.range is not None:
            assert cells[4].startswith(spec.range.text()), (spec.name, cells[4])


# -- on a running node ------------------------------------------------------------------------
def test_running_node_describes_rate_refuses_out_of_range_and_applies_a_change(ros_env,
                                                                              ) -> None:
    import rclpy
    from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
    from rclpy.parameter import parameter_value_to_python
    from test_pilot_interfaces import DEADLINE_S, PilotProcess, set_remote_parameter

    pilot = PilotProcess(ros_env)
    pilot.wait_ready()
    rclpy.init()
    node = rclpy.create_node('pilot_parameter_probe')
    service = '/auv/depth_pilot/'
    describe = node.create_client(DescribeParameters, service + 'describe_parameters')
    get = node.create_client(GetParameters, service + 'get_parameters')
    put = node.create_client(SetParameters, service + 'set_parameters')

    def call(client: Any, request: Any) -> Any:
        future = client.call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=DEADLINE_S)
        assert future.done(), client.srv_name
        return future.result()

    def rate() -> object:
        answer = call(get, GetParameters.Request(names=['rate']))
        return parameter_value_to_python(answer.values[0])

    try:
        for client in (describe, get, put):
            assert client.wait_for_service(timeout_sec=DEADLINE_S)
        names = list(PARAMETERS)
        found = call(describe, DescribeParameters.Request(names=names)).descriptors
        assert [d.description for d in found] == [PARAMETERS[n].description for n in names]
        rate_d = found[names.index('rate')]
        assert '[Hz]' in rate_d.description and '(0, inf)' in rate_d.additional_constraints
        assert len(rate_d.floating_point_range) == 1
        assert rate_d.floating_point_range[0].from_value == 0.0
        assert rate_d.floating_point_range[0].to_value == math.inf
        priority = found[names.index('realtime_priority')]
        assert (priority.integer_range[0].from_value, priority.integer_range[0].to_value) \
            == (0, 99)
        assert 'applied at start only' in priority.additional_constraints
        # refused by ROS on the declared range, by the node on its check (an integer and the
        # open bound 0 are not checked by ROS): nothing changes
        for bad, reason in ((-1.0, 'out of range'), (-2, 'must be in (0, inf)'),
                            (0.0, 'must be in (0, inf)')):
            ok, why = set_remote_parameter(node, put, 'rate', bad)
            assert not ok and reason in why and 'rate' in why, (bad, why)
            assert rate() == 10.0
        ok, why = set_remote_parameter(node, put, 'realtime_priority', 5)
        assert not ok and 'applied at start only; restart the node' in why, why
        assert pilot.proc.poll() is None
        assert pilot.count('controller redesigned') == 0
        # an integer for the float parameter, as `ros2 param set /auv/depth_pilot rate 5`
        ok, why = set_remote_parameter(node, put, 'rate', 5)
        assert ok, why
        assert rate() == 5
        end = time.monotonic() + DEADLINE_S
        while pilot.count('controller redesigned') == 0 and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        assert pilot.count('controller redesigned') == 1, pilot.output
    finally:
        node.destroy_node()
        rclpy.shutdown()
        pilot.stop()


@pytest.mark.parametrize('bar_max', [5e-324, 1e-9, math.inf])
def test_a_plane_travel_too_small_to_weigh_is_a_design_error(bar_max: float) -> None:
    """The BAR weight is 1 / (0.2292 bar_max)^2: at 5e-324 rad it overflows (a division by
    zero before); the core refuses such a travel by name."""
    from auv_contract import config_path
    from auv_depth_lqr.pilot import DepthPilot, PilotSettings
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(config_path('a18m.yaml'))
    with pytest.raises(DesignError, match=r'^bar_max = .* rad must be finite and at least '):
        DepthPilot.for_vehicle(vehicle, PilotSettings(bar_max=bar_max))


def test_plane_rate_design_parameter_designs_the_rate_gains() -> None:
    """``plane_rate_design`` reaches the design: a plane-rate gain per scheduled speed with
    it, none without (docs/pilot-design.md, 4b)."""
    off = pilot_from_values(checked_values(DEFAULTS)).controller.design
    on = pilot_from_values(checked_values(with_value('plane_rate_design', True))
                           ).controller.design
    assert off.K_rate.shape == (0, 6)
    assert on.K_rate.shape == (on.speeds.size, 6)
    assert np.array_equal(on.K, off.K)  # the angle design's gains are the same
