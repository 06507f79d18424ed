"""The lockstep protocol's instants (``docs/lockstep.md``): which control instant a stamp
stands for, shared by the simulator, the depth pilot and a mission.

Kept here, import-free, so that a node answering lockstep states does not load the
simulator's model to tell an instant.
"""
from __future__ import annotations

__all__ = ['LOCKSTEP_TOLERANCE_NS', 'NS_PER_S', 'control_instant']

NS_PER_S = 1_000_000_000
"""Nanoseconds per second."""
LOCKSTEP_TOLERANCE_NS = 1_000
"""Largest distance [ns] between a command's stamp and a control instant for which it stands
for that instant (lockstep): sub-microsecond rounding of float stamps, far below any step."""


def control_instant(stamp_ns: int, period_ns: int) -> int | None:
    """The control instant a stamp stands for (lockstep).

    Parameters
    ----------
    stamp_ns : int
        A message's header stamp [ns].
    period_ns : int
        The control period [ns], > 0.

    Returns
    -------
    int or None
        The nearest multiple of ``period_ns`` [ns] if the stamp is within
        :data:`LOCKSTEP_TOLERANCE_NS` of it, else None. A stamp computed in floating point
        (``Time(seconds=k * 0.02)``) is up to a few nanoseconds off its instant.
    """
    k = (stamp_ns + period_ns // 2) // period_ns
    instant = k * period_ns
    return instant if abs(stamp_ns - instant) <= LOCKSTEP_TOLERANCE_NS else None
