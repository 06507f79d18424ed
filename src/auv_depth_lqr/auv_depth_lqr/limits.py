"""Physical limits of the depth pilot's command and motion (SI units, radians)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.validate import finite

__all__ = ['THETA_MAX_DEFAULT', 'Limits']

THETA_MAX_DEFAULT = math.radians(25.0)
"""Default pitch limit [rad] (25 deg = 0.436 rad): the usual attitude limit of torpedo AUVs
of this class (sonar geometry, stall margin of the hull); assumed, adjust per vehicle."""


@dataclass(frozen=True)
class Limits:
    """Physical limits the command and the motion must respect."""

    bar_max: float = math.radians(25.0)
    """BAR angle limit, symmetric [rad] (25 deg: mechanical stop, assumed for the A18M)."""
    bar_rate_max: float = math.radians(20.0)
    """BAR slew-rate limit [rad/s] (20 deg/s: typical fin servo, assumed)."""
    theta_max: float = THETA_MAX_DEFAULT
    """Pitch limit for large depth changes, symmetric [rad] (default 25 deg = 0.436 rad)."""
    integral_pitch_share: float = 0.5
    """Largest share of ``theta_max`` the integral term may command as pitch [-]: the LQR
    turns ``K_xi xi`` into the pitch offset ``K_xi xi / K_theta`` of its attitude loop, so
    the integrator is bounded by ``|K_xi xi| <= integral_pitch_share * theta_max *
    |K_theta|`` (0.5: 12.5 deg at 25 deg; a vertical current of 0.1 m/s needs ~8 deg on
    the REMUS 100, whose heave term the integrator must also cancel; the pitch guard
    clips the depth and integral terms' pitch at ``pitch_guard * theta_max`` anyway)."""

    @property
    def integral_pitch_max(self) -> float:
        """Largest pitch offset of the integral term [rad]:
        ``integral_pitch_share * theta_max``."""
        return self.integral_pitch_share * self.theta_max

    def __post_init__(self) -> None:
        for name in ('bar_max', 'bar_rate_max', 'theta_max', 'integral_pitch_share'):
            finite(f'Limits.{name}', getattr(self, name), positive=True)
        if self.integral_pitch_share > 1.0:
            raise DesignError(f'Limits.integral_pitch_share must be in (0, 1], got '
                              f'{self.integral_pitch_share!r}')
        if self.theta_max >= math.pi / 2:
            raise DesignError(f'Limits.theta_max must be < pi/2 rad, got {self.theta_max!r}')

