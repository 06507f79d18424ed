"""Did the recorder write every message the graph published? (pure: no rclpy)

Each node of a launched graph writes at exit a report of the messages it published per topic
(:mod:`auv_sim.node_report`); the recorder's bag states how many it wrote per topic
(``metadata.yaml``, counted by the writer). :func:`check_recording` puts the two side by side
for every topic the recorder was meant to record. A topic with fewer messages in the bag than
were published lost messages; a node without a report (killed, crashed) leaves its topics
uncounted, which is reported too: nothing is taken as whole unless it was counted.
"""
from __future__ import annotations

import os
import pathlib
from collections.abc import Collection, Mapping
from typing import NamedTuple

from auv_bag import BagError
from auv_bag.metadata import bag_contents

__all__ = ['RecordingCheck', 'TopicCount', 'check_recording']


class TopicCount(NamedTuple):
    """Messages of one topic: published by the graph's nodes, written to the bag."""

    topic: str
    published: int
    recorded: int

    @property
    def ratio(self) -> float:
        """Recorded over published (1.0 for a topic nothing was published on)."""
        return self.recorded / self.published if self.published else 1.0


class RecordingCheck(NamedTuple):
    """The comparison for one bag.

    Attributes
    ----------
    counts
        every recorded topic some node reported publishing on, sorted by name.
    problems
        why the bag cannot be called whole: missing messages (topic, recorded of
        published), a node without a report, a bag without metadata; empty when whole.
    """

    counts: list[TopicCount]
    problems: list[str]

    @property
    def complete(self) -> bool:
        return not self.problems

    def summary(self) -> str:
        """One line: the counts, or what is missing."""
        if self.problems:
            return '; '.join(self.problems)
        total = sum(c.recorded for c in self.counts)
        return (f'{total} messages on {len(self.counts)} topics, every message the graph '
                'published: ' + ', '.join(f'{c.topic} {c.recorded}' for c in self.counts))


def check_recording(bag: str | os.PathLike[str],
                    reports: Mapping[str, Mapping[str, object] | None],
                    recorded_topics: Collection[str]) -> RecordingCheck:
    """Compare what the nodes published with what ``bag`` holds.

    Parameters
    ----------
    bag
        the recorder's bag directory.
    reports
        node name -> its report (``published``: topic -> count), None for a node
        that wrote none.
    recorded_topics
        full names of the topics the recorder was to record.

    Returns
    -------
    The per-topic counts and the problems (none when the bag is whole).
    """
    problems = [f'no report from the {name} (it did not exit cleanly): its messages are not '
                'counted' for name, report in reports.items() if report is None]
    published: dict[str, int] = {}
    for report in reports.values():
        counts = report.get('published') if report else None
        if isinstance(counts, Mapping):
            for topic, n in counts.items():
                if topic in recorded_topics and isinstance(n, int):
                    published[str(topic)] = published.get(str(topic), 0) + n
    recorded: dict[str, int] = {}
    if not (pathlib.Path(bag) / 'metadata.yaml').is_file():
        problems.append(f'bag {bag} has no metadata.yaml (the recorder did not close it; '
                        f'`auv bag repair {bag} --out DIR` recovers what it wrote)')
    else:
        try:
            recorded = bag_contents(bag)[1]
        except BagError as exc:
            problems.append(str(exc))
    counts = [TopicCount(t, n, recorded.get(t, 0)) for t, n in sorted(published.items())]
    missing = [c for c in counts if c.recorded < c.published]
    if missing and recorded:
        problems.append('messages missing from the bag (recorded of published): '
                        + ', '.join(f'{c.topic} {c.recorded} of {c.published}'
                                    for c in missing))
    return RecordingCheck(counts, problems)
