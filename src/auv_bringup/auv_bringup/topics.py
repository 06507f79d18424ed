"""The node graph's topics, shared by the launcher, the recorder and the Foxglove bridge.

Names are relative to a node's namespace (``/auv`` unless remapped with ``-r __ns:=/NS``);
absolute ones (``/clock``, ``/diagnostics``) are taken as they are. Pure module: no rclpy.
"""
from __future__ import annotations

import struct
from typing import Any

#: Types of the project's topics (architecture contract), subscribed without waiting.
KNOWN_TOPICS: dict[str, str] = {
    'state': 'auv_msgs/msg/VehicleState',
    'odom': 'nav_msgs/msg/Odometry',
    'hydrodynamic_forces': 'auv_msgs/msg/HydrodynamicForces',
    'bar_command': 'auv_msgs/msg/ActuatorSetpoint',
    'helm_command': 'auv_msgs/msg/ActuatorSetpoint',
    'thrust_command': 'auv_msgs/msg/ActuatorSetpoint',
    'depth_command': 'std_msgs/msg/Float64',
    '/clock': 'rosgraph_msgs/msg/Clock',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
}
#: The namespace of the graph's nodes unless ``--namespace`` moves them.
NAMESPACE = '/auv'
#: Streams stamped alike on every sample or control instant, whose progress the recorder
#: reports (each message opens with its stamp: a ``std_msgs/Header`` or the clock's time).
PACED_TOPICS = ('state', 'odom', 'hydrodynamic_forces', 'bar_command', '/clock')
DEFAULT_TOPICS = list(KNOWN_TOPICS)
#: The depth pilot's answer to each depth command (diagnostic_msgs/DiagnosticStatus,
#: reliable, transient local; see :mod:`auv_depth_lqr.node`), relative to the namespace.
DEPTH_ANSWER_TOPIC = 'depth_command_answer'


def known_types(node: Any) -> dict[str, str]:
    """:data:`KNOWN_TOPICS` by their names resolved for ``node`` (an rclpy node: relative
    names in its namespace, e.g. ``/auv/state``) -> message type."""
    return {node.resolve_topic_name(name): msgtype for name, msgtype in KNOWN_TOPICS.items()}


def topic_basename(topic: str) -> str:
    """The last name of a topic, relative or absolute (``/auv1/bar_command`` ->
    ``bar_command``)."""
    return topic.rstrip('/').rsplit('/', 1)[-1]


def header_stamp(data: bytes) -> tuple[int, int] | None:
    """``(sec, nanosec)`` of the ``std_msgs/Header`` that opens a CDR-serialized message (after
    its 4-byte encapsulation header, little- or big-endian); ``None`` if too short."""
    if len(data) < 12:
        return None
    order = '<' if data[1] == 1 else '>'
    sec, nanosec = struct.unpack_from(f'{order}iI', data, 4)
    return int(sec), int(nanosec)

