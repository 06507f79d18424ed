"""The node graph's recorded topics, relative to a node's namespace, shared by the launcher,
the recorder and the Foxglove bridge (names and types from :mod:`auv_contract.topics`).

Names are relative to a node's namespace (``/auv`` unless remapped with ``-r __ns:=/NS``);
absolute ones (``/clock``, ``/diagnostics``) are taken as they are. Pure module: no rclpy.
"""
from __future__ import annotations

import struct
from typing import Any

from auv_contract import (
    CLOCK_TOPIC,
    COMMAND_TOPICS,
    DEPTH_ANSWER_TOPIC,
    DEPTH_COMMAND_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCES_TOPIC,
    MESSAGE_TYPES,
    NAMESPACE,
    ODOM_TOPIC,
    STATE_TOPIC,
    topic_basename,
)

__all__ = ['DEFAULT_TOPICS', 'DEPTH_ANSWER', 'KNOWN_TOPICS', 'NAMESPACE', 'PACED_TOPICS',
           'header_stamp', 'known_types', 'topic_basename']

#: Types of the topics the graph records (the architecture contract's, but for a vehicle's
#: measured fin positions, which the simulated graph does not publish), subscribed without
#: waiting; relative names are in the node's namespace.
KNOWN_TOPICS: dict[str, str] = {
    topic_basename(t) if t.startswith(NAMESPACE + '/') else t: MESSAGE_TYPES[t]
    for t in (STATE_TOPIC, ODOM_TOPIC, FORCES_TOPIC, *COMMAND_TOPICS.values(),
              DEPTH_COMMAND_TOPIC, CLOCK_TOPIC, DIAGNOSTICS_TOPIC)}
#: Streams stamped alike on every sample or control instant, whose progress the recorder
#: reports (each message opens with its stamp: a ``std_msgs/Header`` or the clock's time).
PACED_TOPICS = (topic_basename(STATE_TOPIC), topic_basename(ODOM_TOPIC),
                topic_basename(FORCES_TOPIC), topic_basename(COMMAND_TOPICS['bar']),
                CLOCK_TOPIC)
DEFAULT_TOPICS = list(KNOWN_TOPICS)
#: The depth pilot's answer to each depth command, relative to the namespace.
DEPTH_ANSWER = topic_basename(DEPTH_ANSWER_TOPIC)


def known_types(node: Any) -> dict[str, str]:
    """:data:`KNOWN_TOPICS` by their names resolved for ``node`` (an rclpy node: relative
    names in its namespace, e.g. ``/auv/state``) -> message type."""
    return {node.resolve_topic_name(name): msgtype for name, msgtype in KNOWN_TOPICS.items()}


def header_stamp(data: bytes) -> tuple[int, int] | None:
    """``(sec, nanosec)`` of the ``std_msgs/Header`` that opens a CDR-serialized message (after
    its 4-byte encapsulation header, little- or big-endian); ``None`` if too short."""
    if len(data) < 12:
        return None
    order = '<' if data[1] == 1 else '>'
    sec, nanosec = struct.unpack_from(f'{order}iI', data, 4)
    return int(sec), int(nanosec)
