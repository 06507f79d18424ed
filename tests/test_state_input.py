"""The pilot's state from nav_msgs/Odometry: frame cases worked by hand, and the same BAR
commands as from the equivalent VehicleState."""
from __future__ import annotations

import math

import pytest
from conftest import A18M

from auv_depth_lqr.errors import InvalidInputError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_depth_lqr.recovery import RecoverySettings
from auv_depth_lqr.state_input import plane_state_from_odometry
from auv_sim.frames import euler_to_quaternion, state_to_odometry
from auv_sim.params import load_vehicle

DEG = math.pi / 180


def test_enu_flu_case_worked_by_hand() -> None:
    """Heading north, nose 10 deg up, 12 m deep, 2 m/s ahead, climbing 0.1 m/s in the body
    frame, pitching nose up at 0.05 rad/s.

    ENU/FLU: heading north is a yaw of +90 deg about z (up); nose up is a rotation of -10 deg
    about the body y axis (to port). q = q_z(90) q_y(-10): with s = c = sqrt(1/2), the
    Hamilton product of (0, 0, s, c) and (0, -sin 5, 0, cos 5) is
    sqrt(1/2) (sin 5, -sin 5, cos 5, cos 5) (x, y, z, w). Position up is -12 m; body z (up)
    velocity +0.1 m/s is FRD w = -0.1 m/s; a nose-up rate is about -y in FLU (+0.05 about
    port is nose down), so angular.y = -0.05 gives FRD q = +0.05.
    """
    r = math.sqrt(0.5)
    s5, c5 = math.sin(5 * DEG), math.cos(5 * DEG)
    state = plane_state_from_odometry(
        position=(3.0, 4.0, -12.0), orientation=(r * s5, -r * s5, r * c5, r * c5),
        linear=(2.0, 0.0, 0.1), angular=(0.0, -0.05, 0.0), frame='enu_flu')
    assert state.z == pytest.approx(12.0, abs=1e-12)
    assert state.theta == pytest.approx(10 * DEG, abs=1e-12)
    assert state.u == pytest.approx(2.0, abs=1e-12)
    assert state.w == pytest.approx(-0.1, abs=1e-12)
    assert state.q == pytest.approx(0.05, abs=1e-12)


def test_ned_frd_case_worked_by_hand() -> None:
    """NED/FRD: heading east (yaw +90 deg about down), nose 10 deg up (+10 deg about the
    starboard axis): q = q_z(90) q_y(10) = sqrt(1/2) (-sin 5, sin 5, cos 5, cos 5)."""
    r = math.sqrt(0.5)
    s5, c5 = math.sin(5 * DEG), math.cos(5 * DEG)
    state = plane_state_from_odometry(
        position=(1.0, 2.0, 12.0), orientation=(-r * s5, r * s5, r * c5, r * c5),
        linear=(2.0, 0.3, 0.1), angular=(0.0, 0.05, 0.01), frame='ned_frd')
    assert state == pytest.approx((12.0, 10 * DEG, 0.1, 0.05, 2.0), abs=1e-12)


@pytest.mark.parametrize(('kwargs', 'needle'), [
    ({'frame': 'enu'}, 'not one of'),
    ({'position': (0.0, 0.0, math.nan)}, 'non-finite'),
    ({'orientation': (0.0, 0.0, 0.0, 0.0)}, 'zero quaternion'),
])
def test_bad_odometry_is_refused(kwargs: dict[str, object], needle: str) -> None:
    args: dict[str, object] = {'position': (0.0, 0.0, -5.0), 'orientation': (0.0, 0.0, 0.0, 1.0),
                               'linear': (2.0, 0.0, 0.0), 'angular': (0.0, 0.0, 0.0),
                               'frame': 'enu_flu'}
    args.update(kwargs)
    with pytest.raises(InvalidInputError, match=needle):
        plane_state_from_odometry(**args)  # type: ignore[arg-type]


def hand_made_states() -> list[tuple[float, ...]]:
    """A made-up dive at 2 m/s, 0.1 s apart: (x, y, z, phi, theta, psi, u, v, w, p, q, r)."""
    out = []
    for k in range(120):
        t = 0.1 * k
        theta = -0.15 * math.sin(0.2 * t)
        out.append((2.0 * t, 0.1 * t, 20.0 + 0.3 * t - 0.01 * t * t, 0.02, theta, 0.4,
                    2.0 - 0.002 * t, 0.01, 0.05 * math.cos(0.3 * t), 0.0,
                    -0.03 * math.cos(0.2 * t), 0.0))
    return out


@pytest.mark.parametrize('frame', ['enu_flu', 'ned_frd'])
def test_odometry_and_vehicle_state_give_the_same_bar_commands(frame: str) -> None:
    params = load_vehicle(A18M)
    # learning off: the hand-made sequence is no vehicle's motion
    settings = PilotSettings(recovery=RecoverySettings(enabled=False), pitch_envelope=False,
                             learn=False)
    from_state = DepthPilot.for_vehicle(params, settings)
    from_odom = DepthPilot.for_vehicle(params, settings)
    bars_state, bars_odom = [], []
    for k, x in enumerate(hand_made_states()):
        t = 0.1 * k
        if k == 5:
            from_state.set_depth_command(30.0)
            from_odom.set_depth_command(30.0)
        from_state.on_state(t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
        if frame == 'enu_flu':
            odom = state_to_odometry(list(x))
            pos, quat, lin, ang = odom.position, odom.orientation, odom.linear, odom.angular
        else:
            pos, quat = x[0:3], euler_to_quaternion(x[3], x[4], x[5])
            lin, ang = x[6:9], x[9:12]
        s = plane_state_from_odometry(pos, quat, lin, ang, frame)
        from_odom.on_state(t, z=s.z, theta=s.theta, w=s.w, q=s.q, u=s.u)
        bars_state.append(from_state.command(t)[0])
        bars_odom.append(from_odom.command(t)[0])
    # the pilot acted on the sequence: its commands followed it (a made-up state, not a
    # trajectory of the model, so part of them sit at the plane's limit; the pitch envelope
    # selector is off, its hold law would take the made-up pitch accelerations, which no
    # plane gives, for a plant it must hold)
    assert len(set(bars_state)) > 30
    assert max(abs(a - b) for a, b in zip(bars_state, bars_odom)) <= 1e-9
