"""``auv design``: trim, linear model, LQR gain and closed-loop poles of a vehicle, as JSON.

Example::

    auv design --vehicle config/a18m.yaml --speed 2.0 --weights report_5 --Ts 0.1

prints one JSON document (see :func:`design`): the vertical-plane trim at the forward speed
(``w`` [m/s], ``theta`` [rad, nose up], ``bar`` [rad], ``thrust`` [N]), the Jacobians ``A``
(5 x 5) and ``B`` (5 x 1) over the states ``(w, q, z, theta, int(z - z_ref))`` [m/s, rad/s,
m, rad, m s] (NED, body FRD), the weights, the discrete gain ``K`` (``BAR = BAR_e - K (X -
X_e)``), the closed-loop poles (continuous-equivalent and discrete, each with natural
frequency [rad/s] and damping ratio) and the controllability (rank, condition number).

``--kinematics full`` uses the correct depth kinematics ``z_dot = -u sin(theta) + w
cos(theta)`` (report section 4.3); ``w`` the report's simplified ``z_dot = w`` (section 4.2).
Errors (unreadable or invalid vehicle file, a speed with no trim within the plane's limits, bad
weights or sample period) raise the package's exceptions; the ``auv`` command prints them as
one line ``error: ...`` and exits 1.
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
from typing import Any

from auv_contract.jsonout import plain
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.summary import design_summary
from auv_depth_lqr.weights import PRESETS, preset
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.trim import Kinematics, VerticalPlane

__all__ = ['add_arguments', 'design', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv design``."""
    parser.add_argument('--vehicle', type=pathlib.Path, required=True,
                        help='vehicle file (YAML), e.g. config/a18m.yaml')
    parser.add_argument('--speed', type=float, default=2.0,
                        help='forward speed u0 of the trim [m/s] (default 2.0)')
    parser.add_argument('--weights', default='default', choices=sorted(PRESETS),
                        help='LQR weight preset (default: default)')
    parser.add_argument('--Ts', type=float, default=0.1,
                        help='sample period of the discrete design [s] (default 0.1)')
    parser.add_argument('--kinematics', choices=('full', 'w'), default='full',
                        help="depth kinematics: 'full' z_dot = -u sin(theta) + w cos(theta), "
                             "'w' z_dot = w (default full)")


def design(params: VehicleParams, speed: float, weights: str = 'default', Ts: float = 0.1,
           kinematics: Kinematics = 'full') -> dict[str, Any]:
    """The design summary of a vehicle at forward speed ``speed`` [m/s], JSON-ready.

    The dict of :func:`auv_depth_lqr.summary.design_summary` plus ``vehicle``, ``weights``,
    ``kinematics`` and, in ``trim``, the holding ``thrust`` [N]. Non-finite numbers (the
    frequency of a deadbeat pole) are ``None``.

    Raises
    ------
    DesignError
        Non-positive or non-finite ``speed`` or ``Ts``, unknown ``weights``, or a design
        failure (the message says which).
    auv_sim.errors.TrimError
        No trim at ``speed`` within the plane's angle limit.
    """
    u0 = float(speed)
    if not (math.isfinite(u0) and u0 > 0.0):
        raise DesignError(f'--speed must be a finite forward speed > 0 m/s, got {speed!r}')
    ts = float(Ts)
    if not (math.isfinite(ts) and ts > 0.0):
        raise DesignError(f'--Ts must be a finite sample period > 0 s, got {Ts!r}')
    Q, R = preset(weights).matrices()
    plane = VerticalPlane(params)
    trim = plane.trim(u0, kinematics=kinematics)
    A, B = plane.linearize(trim)

    def linearize(_u0: float) -> tuple[list[float], float, Any, Any]:
        return [trim.w, 0.0, trim.z, trim.theta, 0.0], trim.bar, A, B

    summary = design_summary(linearize, u0, Q, R, ts)
    summary['trim']['thrust'] = trim.thrust
    summary = {'vehicle': params.name, 'weights': weights, 'kinematics': kinematics, **summary}
    ready: dict[str, Any] = plain(summary)
    return ready


def run(args: argparse.Namespace) -> int:
    """Print the design summary as JSON; errors propagate (the ``auv`` command reports them)."""
    params = load_vehicle(args.vehicle)
    summary = design(params, args.speed, args.weights, args.Ts, args.kinematics)
    print(json.dumps(summary, indent=2, allow_nan=False))
    return 0
