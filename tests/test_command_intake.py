"""The pilot's depth-command bookkeeping (:mod:`auv_depth_lqr.command_intake`), hand-worked:
each sample once, a publisher's order kept, and the samples lost before the match counted."""
from __future__ import annotations

from auv_depth_lqr.command_intake import CommandIntake

A, B = b'A' * 16, b'B' * 16


def test_a_sample_older_than_one_applied_is_superseded() -> None:
    """Publisher A's sequence 2 arrives (through one subscription) before its sequence 1
    (through the other): 2 is taken, 1 is superseded by 2; 3 is taken after it. Publisher
    B's order is its own, and a sample without identity is never superseded."""
    intake = CommandIntake()
    assert intake.superseded(A, 2) is None
    assert intake.superseded(A, 1) == 2
    assert intake.superseded(B, 1) is None
    assert intake.superseded(A, 3) is None
    assert intake.superseded(A, 2) == 3
    assert intake.superseded(None, 1) is None and intake.superseded(A, None) is None


def test_duplicates_and_samples_lost_before_the_match() -> None:
    """The same sample through two subscriptions acts once; a volatile publisher whose first
    sample to arrive is its third lost two; a latched one's late joiner lost none; after
    a publisher's first sample nothing more is counted."""
    intake = CommandIntake(remember=2)
    assert intake.first_time(A, 3) and not intake.first_time(A, 3)
    assert intake.missed_before(A, 3, volatile=True) == 2
    assert intake.missed_before(A, 4, volatile=True) == 0
    assert intake.missed_before(B, 5, volatile=False) == 0
    assert intake.first_time(A, 4) and intake.first_time(A, 5)
    assert intake.first_time(A, 3)  # forgotten: only the newest two are remembered
