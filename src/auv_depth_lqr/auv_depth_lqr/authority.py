"""Plane authority of the depth pilot: how much of the plane holding depth takes, and how
often the plane is at its stop. Clock- and ROS-free.

A vehicle holds its depth at the plane angle of its level trim. On the design model that is a
known angle (the A18M at 2 m/s: -4.8 deg of its 25 deg); on a real vehicle a buoyancy or
trim offset, a current the speed loop does not see, or a weaker plane than modelled moves
it, and the plane left for manoeuvres and for braking shrinks with it. When the trim takes
most of the plane no pilot can brake, climb or dive as the design planned (REMUS 100 with
1 % more buoyancy than weight: 12.9 of its 13.6 deg); that is a ballast or trim problem for
the operator, which the pilot can see and say but not fly away.

:class:`AuthorityMonitor` measures it without a model, over the commands of the last
``window`` seconds of normal control, at the samples at which the pilot's governed reference
was at rest at the commanded depth (holding depth, not manoeuvring: a manoeuvre may use the
whole plane by design):

* the **hold plane**: the mean plane command, and its share of the plane's travel;
* the share of that time with the plane **at its stop**: a pilot that needs more plane than
  there is to hold depth flies a vehicle that answers its plane less than its model says (a
  weaker plane, more damping) or carries a load it does not know.

Once the hold samples cover half the window it judges: **low** when the hold plane takes more
than ``share_max`` of the travel (the governor's ``trim_bar_share``: the room the design
leaves the trim) or the plane was at its stop for more than ``saturated_max`` of the hold
time; else **ok**. Before, **unknown**; the share of the whole window with the plane at its
stop is then still given (a vehicle that never comes to rest at the command with the plane
at its stop most of the time: REMUS 100 with 30 % less fin lift).

Units: plane angle BAR [rad], times [s] on any one clock.
"""
from __future__ import annotations

import collections
import math
from typing import NamedTuple

from auv_depth_lqr.errors import DesignError

UNKNOWN = 'unknown'
OK = 'ok'
LOW = 'low'


class Authority(NamedTuple):
    """The plane authority over the last window (see module docstring)."""

    level: str
    """``unknown`` (not enough hold samples yet), ``ok`` or ``low``."""
    hold_bar: float
    """Mean plane command [rad] while holding depth (nan without hold samples)."""
    share: float
    """``|hold_bar| / bar_max`` [-] (nan without hold samples)."""
    saturated: float
    """Share of the hold time with the plane at its stop [-] (nan without hold samples)."""
    hold_time: float
    """Time [s] the hold samples of the window cover."""
    at_stop: float
    """Share of the whole window's normal control with the plane at its stop [-] (nan without
    samples)."""

    def message(self, share_max: float, saturated_max: float) -> str:
        """One line for an operator."""
        stop = ('' if not math.isfinite(self.at_stop) else
                f'; plane at its stop {100.0 * self.at_stop:.0f} % of the window')
        if self.level == UNKNOWN:
            return f'not judged: {self.hold_time:.1f} s of depth holding in the window{stop}'
        hold = (f'holding depth takes {math.degrees(self.hold_bar):+.1f} deg of plane, '
                f'{100.0 * self.share:.0f} % of its travel, at its stop '
                f'{100.0 * self.saturated:.0f} % of the time')
        if self.level == OK:
            return hold
        if self.saturated > saturated_max:
            return (f'{hold}: the vehicle answers its plane less than its model says, or '
                    f'carries a load it does not know')
        return (f'{hold}: more than {100.0 * share_max:.0f} %, little left to manoeuvre and '
                f'brake; check ballast and trim')


class AuthorityMonitor:
    """Trailing-window measure of the plane authority (see module docstring).

    ``bar_max`` [rad] the plane's travel, ``window`` [s] the trailing window, ``share_max``
    (0 < s <= 1) the share of the travel beyond which holding depth leaves low authority,
    ``saturated_max`` (0 < s <= 1, default 0.5, assumed: a plane at its stop more often than
    not) the share of the time at the stop beyond which authority is low.
    """

    def __init__(self, bar_max: float, window: float, share_max: float,
                 saturated_max: float = 0.5) -> None:
        for name, value in (('bar_max', bar_max), ('window', window)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not (math.isfinite(value) and value > 0):
                raise DesignError(f'authority monitor {name} = {value!r} must be finite and > 0')
        for name, value in (('share_max', share_max), ('saturated_max', saturated_max)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not 0.0 < value <= 1.0:
                raise DesignError(f'authority monitor {name} = {value!r} must be in (0, 1]')
        self.bar_max, self.window = float(bar_max), float(window)
        self.share_max, self.saturated_max = float(share_max), float(saturated_max)
        self._samples: collections.deque[list[float]] = collections.deque()
        """[time [s], BAR [rad], duration [s], holding (1.0 or 0.0)] of each sample in the
        window; a sample lasts until the next one, at most the window."""
        self._sums = [0.0] * 5
        """Running sums over the window: covered time, time at the stop, hold time, hold
        BAR x time [rad s], hold time at the stop [s]."""
        self.authority = Authority(UNKNOWN, math.nan, math.nan, math.nan, 0.0, math.nan)

    def reset(self) -> None:
        """Forget the window (after a time the pilot was not in normal control)."""
        self._samples.clear()
        self._sums = [0.0] * 5
        self.authority = Authority(UNKNOWN, math.nan, math.nan, math.nan, 0.0, math.nan)

    def _add(self, sample: list[float], sign: float) -> None:
        """Add (``sign`` 1) or remove (-1) a sample's share of the running sums."""
        _, bar, duration, holding = sample
        stop = duration if abs(bar) >= self.bar_max * (1.0 - 1e-9) else 0.0
        for k, value in enumerate((duration, stop, holding * duration,
                                   holding * bar * duration, holding * stop)):
            self._sums[k] += sign * value

    def update(self, t: float, bar: float, holding: bool) -> Authority:
        """Add the plane command ``bar`` [rad] of normal control given at ``t`` [s];
        ``holding``: the pilot's reference was at rest at the commanded depth. Returns the
        authority over the window ending at ``t``. Samples with a non-finite value or the
        time of the last one are ignored; a time before the last one (a clock set back: a
        replay restarted) starts the window afresh."""
        if not (math.isfinite(t) and math.isfinite(bar)) \
                or (self._samples and t == self._samples[-1][0]):
            return self.authority
        if self._samples and t < self._samples[-1][0]:
            self.reset()
        if self._samples:
            last = self._samples[-1]
            last[2] = min(t - last[0], self.window)
            self._add(last, 1.0)
        self._samples.append([t, bar, 0.0, 1.0 if holding else 0.0])
        while self._samples[0][0] < t - self.window:
            self._add(self._samples.popleft(), -1.0)
        covered, stop_time, hold_time, hold_sum, hold_stop = (max(x, 0.0) if k != 3 else x
                                                              for k, x in enumerate(self._sums))
        at_stop = stop_time / covered if covered > 0.0 else math.nan
        if hold_time > 0.0:
            mean, saturated = hold_sum / hold_time, hold_stop / hold_time
        else:
            mean = saturated = math.nan
        share = abs(mean) / self.bar_max
        if hold_time < 0.5 * self.window:
            level = UNKNOWN
        elif saturated > self.saturated_max or share > self.share_max:
            level = LOW
        else:
            level = OK
        self.authority = Authority(level, float(mean), float(share), float(saturated),
                                   hold_time, float(at_stop))
        return self.authority
