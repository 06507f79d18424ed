"""Depth runaway: the vehicle away from its commanded depth and not coming back while the
plane is held at the stop that would bring it back. Clock- and ROS-free.

A vehicle whose level trim takes nearly all its plane cannot pull out of a dive (or a climb)
once its speed falls: the plane's force goes with ``u^2``, its buoyancy and trim moment do
not. The REMUS 100 file with 30 % less fin lift and its propeller held at the trim rpm needs
13.0 of its 13.6 deg of plane to hold level at 1.5 m/s; told to dive 10 -> 30 m it pitches
nose down, slows to about 1.05 m/s, and dives on at 15-20 deg with the plane at its nose-up
stop, past 50 m within 200 s. No plane command brings it back; more speed (the vehicle's
speed loop), less buoyancy or a trim change would. :class:`RunawayMonitor` says so, from the
depth, the command and the plane command alone (no model).

A runaway is declared when, for ``stop_time`` seconds without a break:

* the depth is more than ``distance`` off the command, on either side (past it after a
  change, or short of it: a climb that stalls and sinks back);
* the plane command is at its stop on the side that brings the vehicle back (nose up,
  ``BAR <= -at_stop bar_max``, when it is too deep; nose down when it is too shallow);

and the vehicle is no nearer the command than when that began. It ends as soon as one of
these no longer holds. An overshoot the pilot is taking back (the vehicle turning towards
the command, with the plane at its stop for a few seconds) is not one.

Units: depth [m] (NED, positive down), BAR [rad] (positive nose down), times [s] on any
one clock.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from auv_depth_lqr.errors import DesignError

__all__ = ['AT_STOP', 'DISTANCE', 'STOP_TIME', 'Runaway', 'RunawayMonitor']

DISTANCE = 1.0
"""Distance from the command [m] from which a runaway may be declared: ten times the
+-0.1 m settling band (the largest overshoot of the pilot's benchmark flights that it
took back is 0.91 m: the A18M foreign plant of ``bench/bench_foreign_plants.py``)."""
STOP_TIME = 5.0
"""Time [s] the conditions must hold without a break."""
AT_STOP = 0.98
"""Share of ``bar_max`` from which the plane command is at its stop [-]."""


class Runaway(NamedTuple):
    """A runaway in progress (module docstring)."""

    off: float
    """Distance from the command [m] (> ``distance``)."""
    below: bool
    """True below the command (too deep), False above it."""
    since: float
    """Time [s] the conditions began to hold."""
    stop_time: float
    """Time [s] they have held."""


class RunawayMonitor:
    """Declares a runaway from successive ``(t, z, z_cmd, bar)`` (module docstring).

    Parameters
    ----------
    bar_max : float
        Plane travel [rad], > 0.
    distance, stop_time, at_stop : float, optional
        :data:`DISTANCE` [m], :data:`STOP_TIME` [s] and :data:`AT_STOP` [-].
    """

    def __init__(self, bar_max: float, distance: float = DISTANCE,
                 stop_time: float = STOP_TIME, at_stop: float = AT_STOP) -> None:
        for name, value in (('bar_max', bar_max), ('distance', distance),
                            ('stop_time', stop_time)):
            if not (math.isfinite(value) and value > 0.0):
                raise DesignError(f'runaway monitor: {name} = {value!r} must be finite and > 0')
        if not (math.isfinite(at_stop) and 0.0 < at_stop <= 1.0):
            raise DesignError(f'runaway monitor: at_stop = {at_stop!r} must be in (0, 1]')
        self.bar_max, self.distance = float(bar_max), float(distance)
        self.stop_time, self.at_stop = float(stop_time), float(at_stop)
        self.reset()

    def reset(self) -> None:
        """Forget the conditions held so far (a restart of normal control)."""
        self._start: tuple[float, float, bool] | None = None
        """``(t [s], distance from the command [m], below)`` when the conditions began."""
        self.state: Runaway | None = None
        """The runaway in progress, None if none."""

    def update(self, t: float, z: float, z_cmd: float, bar: float) -> Runaway | None:
        """Take one sample: time ``t`` [s], depth ``z`` and command ``z_cmd`` [m, down],
        plane command ``bar`` [rad]; returns :attr:`state`."""
        error = z - z_cmd
        below = error > 0.0
        back = -bar if below else bar  # the plane towards the command, in shares of its stop
        if not (math.isfinite(error) and math.isfinite(bar) and abs(error) > self.distance
                and back >= self.at_stop * self.bar_max):
            self.reset()
            return None
        if self._start is None or self._start[2] != below:
            self._start = (t, abs(error), below)
        t0, off0, _ = self._start
        held = t - t0
        if held >= self.stop_time and abs(error) >= off0:
            self.state = Runaway(abs(error), below, t0, held)
        else:
            self.state = None
        return self.state
