"""Envelope fallback of the depth pilot: when to stop trusting the design model, and what to
fly instead. Clock- and ROS-free.

The LQR pilot is designed on a model. When the vehicle is far outside the conditions that
model describes, its commands are no longer a safe bet, so :class:`EnvelopeMonitor` watches
two symptoms at each control instant:

* **pitch beyond the limit plus a margin**: ``|theta| > theta_max + pitch_margin`` [rad];
  the pilot never asks for more than ``theta_max``, so beyond that the vehicle is being
  pushed by something the model does not hold (a stall, a snag, a broken plane, a far-off
  model);
* **a depth rate the model cannot explain**: over the last ``rate_window`` seconds the
  measured depth change differs from the one the vertical-plane kinematics of the measured
  velocities gives, ``z_dot = -u sin(theta) + w cos(theta)`` (NED, z down; body FRD ``u``,
  ``w`` [m/s]; roll taken as zero), by more than ``rate_residual_max`` [m/s] on average.
  A vertical current, wave pumping near the surface, a depth sensor or a velocity sensor in
  fault all show here; a windowed mean keeps depth-sensor noise out (a noise of standard
  deviation ``s`` [m] gives a residual noise of about ``s * sqrt(2) / rate_window``).

Either symptom puts the pilot in **recovery**: :func:`recovery_bar` levels the vehicle at the
trim pitch of its speed with a low-gain copy of the LQR's own heave/pitch feedback (the depth
and integral terms left out, so it never chases depth), within the plane's limits (travel,
optionally a fraction of it, and rate). Control resumes (hysteresis) once
``|theta| <= theta_max`` and the residual is below half its threshold, both without a break
for ``resume_time`` seconds.

Units: SI, radians; NED/FRD as in ``auv_msgs/VehicleState``.
"""
from __future__ import annotations

import collections
import dataclasses
import math
from typing import NamedTuple

from auv_depth_lqr.errors import DesignError

NORMAL = 'normal'
RECOVERY = 'recovery'


@dataclasses.dataclass(frozen=True)
class RecoverySettings:
    """When the pilot falls back to recovery and how hard the recovery law acts.

    ``enabled``: False never leaves normal control (the symptoms are still computed);
    ``pitch_margin`` [rad] beyond the pilot's pitch limit that starts recovery (default
    5 deg, assumed: on its design model the pilot holds its limit to a fraction of a degree,
    so 5 deg beyond it is not normal flight);
    ``rate_residual_max`` [m/s] unexplained depth rate that starts it (default 0.3 m/s,
    assumed: about a third of the A18M's largest commanded vertical speed, about eight times
    the residual noise of a 0.05 m depth-sensor noise over the 2 s window); ``rate_window``
    [s] of the residual mean; ``resume_time`` [s] back inside before control resumes;
    ``gain`` (0 < g <= 1) the share of the LQR's heave/pitch feedback the recovery law uses;
    ``bar_fraction`` (0 < f <= 1) of the plane limit it may use (default 1: out of a large
    upset the law saturates the plane anyway, and less travel only prolongs it: the A18M
    pitched to -45 deg at 2 m/s resumes after 10.9 s with the full plane, 15.7 s with half).
    """

    enabled: bool = True
    pitch_margin: float = math.radians(5.0)
    rate_residual_max: float = 0.3
    rate_window: float = 2.0
    resume_time: float = 3.0
    gain: float = 0.5
    bar_fraction: float = 1.0

    def __post_init__(self) -> None:
        for name in ('pitch_margin', 'rate_residual_max', 'rate_window', 'resume_time'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not (math.isfinite(value) and value > 0):
                raise DesignError(f'recovery setting {name} = {value!r} must be finite and > 0')
        for name in ('gain', 'bar_fraction'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not 0 < value <= 1:
                raise DesignError(f'recovery setting {name} = {value!r} must be in (0, 1]')


class Verdict(NamedTuple):
    """Outcome of one :meth:`EnvelopeMonitor.update`.

    ``mode``: ``normal`` or ``recovery``; ``changed``: the mode switched at this call;
    ``reason``: why the last switch happened (human-readable); ``pitch`` [rad];
    ``residual`` [m/s] windowed unexplained depth rate (None until half a window of data).
    """

    mode: str
    changed: bool
    reason: str
    pitch: float
    residual: float | None


class EnvelopeMonitor:
    """Decides normal control or recovery from the measured states (see module docstring).

    ``theta_max`` [rad] is the pilot's pitch limit. Call :meth:`update` once per control
    instant with the latest measured state; times ``t`` [s] on one clock, increasing.
    """

    def __init__(self, theta_max: float, settings: RecoverySettings | None = None) -> None:
        self.theta_max = float(theta_max)
        self.settings = settings or RecoverySettings()
        self.mode = NORMAL
        self.reason = ''
        # (t [s], z [m], z_dot of the kinematics [m/s], cumulative integral of it [m])
        self._history: collections.deque[tuple[float, float, float, float]] = \
            collections.deque()
        self._inside_since: float | None = None

    def reset(self) -> None:
        """Forget the history (after a gap in the state): the residual restarts."""
        self._history.clear()
        self._inside_since = None

    def residual(self, t: float, z: float, theta: float, w: float, u: float) -> float | None:
        """Add a sample and return the mean unexplained depth rate [m/s] over the window
        (None until it spans half the window)."""
        z_dot = -u * math.sin(theta) + w * math.cos(theta)
        if self._history and t <= self._history[-1][0]:
            return self._last_residual(t)
        integral = 0.0
        if self._history:
            t0, _, zd0, i0 = self._history[-1]
            integral = i0 + 0.5 * (z_dot + zd0) * (t - t0)  # trapezoid
        self._history.append((t, z, z_dot, integral))
        window = self.settings.rate_window
        while len(self._history) > 2 and self._history[1][0] <= t - window:
            self._history.popleft()
        return self._last_residual(t)

    def _last_residual(self, t: float) -> float | None:
        t0, z0, _, i0 = self._history[0]
        t1, z1, _, i1 = self._history[-1]
        if t1 - t0 < 0.5 * self.settings.rate_window:
            return None
        return ((z1 - z0) - (i1 - i0)) / (t1 - t0)

    def update(self, t: float, z: float, theta: float, w: float, u: float) -> Verdict:
        """Feed the state at ``t`` [s] (z [m] down, theta [rad] nose up, w, u [m/s] FRD)."""
        s = self.settings
        residual = self.residual(t, z, theta, w, u)
        pitch_limit = self.theta_max + s.pitch_margin
        changed = False
        if self.mode == NORMAL:
            cause = ''
            if abs(theta) > pitch_limit:
                cause = (f'pitch {math.degrees(theta):.1f} deg beyond '
                         f'{math.degrees(pitch_limit):.1f} deg (limit + margin)')
            elif residual is not None and abs(residual) > s.rate_residual_max:
                cause = (f'depth rate {residual:+.2f} m/s not explained by the vehicle\'s '
                         f'kinematics (threshold {s.rate_residual_max:g} m/s)')
            if cause and s.enabled:
                self.mode, self.reason, changed = RECOVERY, cause, True
                self._inside_since = None
        else:
            inside = abs(theta) <= self.theta_max and (
                residual is None or abs(residual) <= 0.5 * s.rate_residual_max)
            if not inside:
                self._inside_since = None
            elif self._inside_since is None:
                self._inside_since = t
            if self._inside_since is not None and t - self._inside_since >= s.resume_time:
                self.mode, changed = NORMAL, True
                self.reason = (f'back inside the envelope for {s.resume_time:g} s: '
                               'depth control resumed')
                self._inside_since = None
        return Verdict(self.mode, changed, self.reason, theta, residual)


def recovery_bar(k_w: float, k_q: float, k_theta: float, w_e: float, theta_e: float,
                 bar_e: float, w: float, q: float, theta: float, gain: float,
                 bar_limit: float) -> float:
    """The recovery law's BAR [rad] (positive = dive): level at the trim pitch.

    ``BAR = BAR_e - gain (k_w (w - w_e) + k_q q + k_theta (theta - theta_e))`` limited to
    ``+-bar_limit``; ``k_*`` are the LQR gains on heave [rad/(m/s)], pitch rate [rad/(rad/s)]
    and pitch [rad/rad] at the present speed, ``(w_e, theta_e, BAR_e)`` its trim.
    """
    bar = bar_e - gain * (k_w * (w - w_e) + k_q * q + k_theta * (theta - theta_e))
    return min(max(bar, -bar_limit), bar_limit)
