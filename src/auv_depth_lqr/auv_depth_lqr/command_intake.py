"""Depth commands as the pilot node receives them: each sample once, its answer, and what was
lost on the way (pure bookkeeping: no rclpy; the node feeds it DDS message info).

A depth command is a ``std_msgs/Float64`` sample; DDS identifies each by its publisher's GID
(16 bytes) and the publication sequence number (1, 2, ... per publisher). The pilot subscribes
the topic more than once (see :mod:`auv_depth_lqr.node`), so a sample can arrive several
times: :meth:`CommandIntake.first_time` lets it act once.

Order is kept per publisher: the subscriptions deliver independently, so a publisher's
earlier sample can arrive after a later one (an earlier sample repaired by the reliable
subscription after the best-effort one took the next). A sample older than the newest one of
its publisher already applied is superseded (:meth:`CommandIntake.superseded`): the pilot does
not fly back to it.

Loss is never silent where the pilot can see it:

* a publisher's first sample to arrive has sequence number ``n > 1`` (and did not come as the
  last sample a latched publisher keeps for late joiners): its ``n - 1`` earlier samples were
  published before DDS matched it with the pilot (:meth:`CommandIntake.missed_before`);
* a publisher matched the pilot's reliable subscription and left without a sample arriving
  through it (:meth:`CommandIntake.silent_departures`): a script that published once right
  after ``create_publisher`` and exited lost its command that way (if it published at all).

What no node can see: a publisher whose process publishes and exits before DDS discovery has
matched it with the pilot at all (tens of milliseconds on an idle machine) leaves no trace in
the pilot; only the script can avoid that loss, by waiting for the match (``auv depth``,
``examples/depth_command.py``).
"""
from __future__ import annotations

import collections
from collections.abc import Collection
from typing import NamedTuple

__all__ = ['ACCEPTED', 'CLAMPED', 'REFUSED', 'CommandAnswer', 'CommandIntake', 'gid_text']

ACCEPTED, CLAMPED, REFUSED = 'accepted', 'clamped', 'refused'


class CommandAnswer(NamedTuple):
    """The pilot's answer to one depth command.

    Attributes
    ----------
    value
        the commanded depth as received [m, positive down].
    result
        ``accepted``, ``clamped`` (to the envelope) or ``refused``.
    depth
        the depth the pilot flies to after it [m]: the command in force.
    reason
        why it was clamped or refused ('' when accepted).
    publisher
        the publisher's GID as hex ('' when the middleware gives none).
    sequence
        its publication sequence number (0 when unknown).
    """

    value: float
    result: str
    depth: float | None
    reason: str
    publisher: str
    sequence: int

    def text(self) -> str:
        """One line for logs and ``/diagnostics``."""
        if self.result == ACCEPTED:
            return f'depth command {self.value:g} m accepted'
        if self.result == CLAMPED:
            return f'depth command {self.value:g} m clamped to {self.depth:g} m: {self.reason}'
        return f'depth command {self.value:g} m refused: {self.reason}'


def gid_text(gid: bytes | None) -> str:
    """A publisher GID as lower-case hex ('' for None)."""
    return gid.hex() if gid else ''


class CommandIntake:
    """Samples seen (to apply each once) and publishers that delivered (to see losses).

    Parameters
    ----------
    remember
        samples remembered for :meth:`first_time` (the newest ones).
    """

    def __init__(self, remember: int = 64) -> None:
        self._remember = remember
        self._seen: collections.OrderedDict[tuple[bytes, int], None] = collections.OrderedDict()
        self._first_sequence: dict[bytes, int] = {}
        self._newest: dict[bytes, int] = {}
        self._delivered_reliably: set[bytes] = set()
        self._silent = 0

    def first_time(self, publisher: bytes | None, sequence: int | None) -> bool:
        """True the first time the sample (``publisher``, ``sequence``) is seen; True also
        when it has no identity (a repeated value changes nothing)."""
        if publisher is None or sequence is None:
            return True
        key = (publisher, sequence)
        if key in self._seen:
            return False
        self._seen[key] = None
        while len(self._seen) > self._remember:
            self._seen.popitem(last=False)
        return True

    def superseded(self, publisher: bytes | None, sequence: int | None) -> int | None:
        """The sequence number of the newest sample of ``publisher`` already taken when
        ``sequence`` is older than it (the sample arrived out of order: not to be applied),
        else None, and ``sequence`` becomes the newest taken. None also when the identity is
        unknown."""
        if publisher is None or sequence is None:
            return None
        newest = self._newest.get(publisher)
        if newest is not None and sequence < newest:
            return newest
        self._newest[publisher] = sequence
        return None

    def arrived(self, publisher: bytes | None, reliable_subscription: bool) -> None:
        """Note that a sample of ``publisher`` arrived (through the pilot's reliable, volatile
        subscription or another one), before :meth:`first_time` drops duplicates."""
        if publisher is not None and reliable_subscription:
            self._delivered_reliably.add(publisher)

    def missed_before(self, publisher: bytes | None, sequence: int | None,
                      volatile: bool) -> int:
        """Samples of ``publisher`` published before the first one that reached the pilot (0
        after its first sample, when the sample came as the last one a latched publisher
        keeps for late joiners, ``volatile`` False, or when the identity is unknown)."""
        if publisher is None or sequence is None or publisher in self._first_sequence:
            return 0
        self._first_sequence[publisher] = sequence
        return max(0, sequence - 1) if volatile else 0

    def silent_departures(self, total_matched: int, current_matched: int,
                          present: Collection[bytes]) -> int:
        """Publishers that left the pilot's reliable subscription without a sample arriving
        through it, new since the last call.

        Parameters
        ----------
        total_matched
            publishers the subscription ever matched (DDS matched status).
        current_matched
            publishers it matches now.
        present
            GIDs of the topic's publishers the graph lists now (after the departures
            settled).
        """
        left = total_matched - current_matched
        left_delivered = sum(1 for g in self._delivered_reliably if g not in present)
        silent = max(0, left - left_delivered)
        new = silent - self._silent
        self._silent = max(self._silent, silent)
        return max(0, new)
