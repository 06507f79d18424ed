"""The identification node's parameters as data (pure, no DDS): descriptions with their unit
or unitless by declaration, choices, and each range accepted just inside and refused just
outside with a message naming the parameter (the running node: test_ident_node.py)."""
from __future__ import annotations

import math
import re

import pytest
from test_pilot_parameters import edges

from auv_contract.parameters import ParameterSpec
from auv_ident.identify import EQUATIONS, ERROR_METHODS
from auv_ident.motion import SOURCES
from auv_ident.node_parameters import PARAMETERS, START_ONLY, problem

DEFAULTS = {name: spec.default for name, spec in PARAMETERS.items()}
RANGED = [spec for spec in PARAMETERS.values() if spec.range is not None]


def test_the_parameters_their_descriptions_units_and_choices() -> None:
    assert list(PARAMETERS) == ['vehicle_file', 'out', 'source', 'fit_c0', 'fit_planes',
                                'bounds', 'errors', 'equations', 'window', 'estimate_period',
                                'qos_depth']
    for spec in PARAMETERS.values():
        assert spec.description and '\n' not in spec.description, spec.name
        if spec.unit:
            assert f'[{spec.unit}]' in spec.description, spec.name
        else:
            assert not re.search(r'\[[a-z]', spec.description), spec.name
    assert {s.name: s.unit for s in RANGED} == {'window': 's', 'estimate_period': 's',
                                                'qos_depth': 'messages'}
    assert PARAMETERS['source'].choices == SOURCES
    assert PARAMETERS['errors'].choices == ERROR_METHODS
    assert START_ONLY == ('qos_depth',)
    assert problem(DEFAULTS) is None


@pytest.mark.parametrize('spec', RANGED, ids=[s.name for s in RANGED])
def test_each_range_accepts_just_inside_and_refuses_just_outside(spec: ParameterSpec) -> None:
    pairs = edges(spec)
    assert pairs, spec.name
    for inside, outside in pairs:
        assert problem({**DEFAULTS, spec.name: inside}) is None
        wrong = problem({**DEFAULTS, spec.name: outside})
        assert wrong is not None and wrong.startswith(f'parameter {spec.name} must be '), wrong


def test_hand_worked_messages() -> None:
    assert problem({'window': -1.0}) == 'parameter window must be > 0 s, got -1.0'
    assert problem({'window': 0}) == 'parameter window must be > 0 s, got 0'
    assert problem({'window': 2}) is None  # an integer for a float parameter
    assert problem({'window': math.inf}) == 'parameter window must be > 0 s, got inf'
    assert problem({'estimate_period': math.nan}) == \
        'parameter estimate_period must be >= 0 s, got nan'
    assert problem({'qos_depth': 0}) == 'parameter qos_depth must be >= 1 messages, got 0'
    assert problem({'qos_depth': 1.5}) == \
        'parameter qos_depth must be >= 1 messages, got 1.5'
    assert problem({'qos_depth': True}) == \
        'parameter qos_depth must be >= 1 messages, got True'
    assert problem({'source': 'radar'}) == \
        f"parameter source must be one of {SOURCES}, got 'radar'"
    assert problem({'equations': ['heave', 'roll']}) == \
        "parameter equations: unknown equation 'roll'"
    assert problem({'equations': [''], 'errors': 'iid'}) is None
    assert set(EQUATIONS) >= {'heave', 'pitch'}
