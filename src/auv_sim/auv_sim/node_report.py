"""A node's report of its run, written at exit for the launcher (pure: no rclpy).

A node of the graph given a report file (parameter ``report_file`` of the simulator and the
depth pilot, ``--report-file`` of ``auv mission``) writes one JSON object there when it exits:
``node`` (its full name), ``published`` (topic -> messages it published on it, counting any it
had to drop) and what else it has to say (the simulator: ``lockstep_missed``,
``recorder_pacing_given_up``, ``t_end`` [s]; the depth pilot: ``first_command_time``, the
wall-clock time [s since the epoch] it published its first BAR command). ``auv launch``
compares the published counts with what the recorder wrote.
"""
from __future__ import annotations

import json
import pathlib
from typing import Any

__all__ = ['read_report', 'write_report']


def write_report(path: str | pathlib.Path, report: dict[str, Any]) -> None:
    """Write ``report`` as JSON to ``path`` (atomically: a reader sees all of it or none);
    nothing for an empty path."""
    if not str(path):
        return
    out = pathlib.Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + '.tmp')
    tmp.write_text(json.dumps(report, indent=1) + '\n')
    tmp.replace(out)


def read_report(path: str | pathlib.Path) -> dict[str, Any] | None:
    """The report at ``path``, or None when there is none (the node did not get to write
    it) or it is not a JSON object."""
    try:
        report = json.loads(pathlib.Path(path).read_text())
    except (OSError, ValueError):
        return None
    return report if isinstance(report, dict) else None
