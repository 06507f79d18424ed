"""The simulator node's parameters as data (pure, no DDS): every description carries its unit
or is unitless by declaration, and each declared range is the one check_settings enforces
(the running node's descriptors and refusals are in test_sim_node.py)."""
from __future__ import annotations

import math
import re

import pytest
from test_pilot_parameters import edges

from auv_contract.parameters import ParameterSpec
from auv_sim.errors import ParameterError
from auv_sim.sim_settings import (
    FLOAT_FIELDS,
    PARAMETERS,
    RUNTIME_FIELDS,
    SimSettings,
    check_settings,
)

RANGED = [spec for spec in PARAMETERS.values() if spec.range is not None]
#: initial_pitch is given only without the trim (the trim sets it)
BASE = SimSettings(initial_trim=False)


def test_every_field_is_a_parameter_with_a_one_line_description_and_its_unit() -> None:
    assert list(PARAMETERS) == [f for f in SimSettings.__dataclass_fields__]
    for spec in PARAMETERS.values():
        assert spec.description and '\n' not in spec.description, spec.name
        if spec.unit:
            assert re.search(rf'\[{re.escape(spec.unit)}[] ,]', spec.description) \
                or f'[wall {spec.unit}]' in spec.description, spec.name
        else:
            assert '[' not in spec.description, spec.name
    # the unitless floats are the three subscriber counts
    assert {n for n in FLOAT_FIELDS if not PARAMETERS[n].unit} \
        == {'start_subscribers', 'start_stream_subscribers', 'start_odom_subscribers'}
    assert {n for n, s in PARAMETERS.items() if not s.start_only} == set(RUNTIME_FIELDS)


def test_the_ranges_are_the_ones_the_code_checked_before() -> None:
    texts = {s.name: s.range.text() for s in RANGED}  # type: ignore[union-attr]
    assert texts == {
        'publish_rate': '(0, inf)', 'control_period': '(0, inf)',
        'lockstep_timeout': '(0, inf)', 'lockstep_startup_timeout': '(0, inf)',
        'recorder_timeout': '(0, inf)', 'dt': '[0, inf)', 'real_time_factor': '[0, inf)',
        'initial_depth': '[0, inf)', 'stop_time': '[0, inf)', 'start_subscribers': '[0, inf)',
        'start_stream_subscribers': '[0, inf)', 'start_odom_subscribers': '[0, inf)',
        'initial_pitch': '(-1.5708, 1.5708)'}


@pytest.mark.parametrize('spec', RANGED, ids=[s.name for s in RANGED])
def test_each_range_accepts_just_inside_and_refuses_just_outside(spec: ParameterSpec) -> None:
    pairs = edges(spec)
    assert pairs, spec.name
    for inside, outside in pairs:
        check_settings(BASE.replace(**{spec.name: inside}))
        with pytest.raises(ParameterError, match=rf'^parameter {spec.name} = '):
            check_settings(BASE.replace(**{spec.name: outside}))


def test_hand_worked_messages() -> None:
    with pytest.raises(ParameterError) as info:
        check_settings(BASE.replace(publish_rate=0.0))
    assert str(info.value) == 'parameter publish_rate = 0.0 must be > 0'
    with pytest.raises(ParameterError) as info:
        check_settings(BASE.replace(stop_time=-1.0))
    assert str(info.value) == 'parameter stop_time = -1.0 must be >= 0'
    with pytest.raises(ParameterError) as info:
        check_settings(BASE.replace(initial_pitch=-math.pi / 2))
    assert str(info.value) == \
        f'parameter initial_pitch = {-math.pi / 2} rad must be within (-1.5708, 1.5708)'
