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
    integral_bar_share: float = 0.32
    """Largest share of ``bar_max`` the integral term ``|K_xi xi|`` may command [-]: bounds
    the integrator to what trim errors can need (0.32: 8 deg of a 25 deg plane, ~2x the
    report's trim BAR; a fraction, so that it scales with the vehicle's plane)."""

    @property
    def integral_bar_max(self) -> float:
        """Largest BAR of the integral term [rad]: ``integral_bar_share * bar_max``."""
        return self.integral_bar_share * self.bar_max

    def __post_init__(self) -> None:
        for name in ('bar_max', 'bar_rate_max', 'theta_max', 'integral_bar_share'):
            finite(f'Limits.{name}', getattr(self, name), positive=True)
        if self.integral_bar_share > 1.0:
            raise DesignError(f'Limits.integral_bar_share must be in (0, 1], got '
                              f'{self.integral_bar_share!r}')
        if self.theta_max >= math.pi / 2:
            raise DesignError(f'Limits.theta_max must be < pi/2 rad, got {self.theta_max!r}')

