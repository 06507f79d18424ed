"""Topic names of the node graph and their message types (docs/architecture.md, "Topics").

Names are absolute in the default namespace ``/auv``; every node also runs in another
namespace or with its topics remapped (``--ros-args -r``), so code that must work in any
namespace uses :func:`topic_basename` of these names.
"""
from __future__ import annotations

__all__ = ['CLOCK_TOPIC', 'COMMAND_TOPICS', 'DEPTH_ANSWER_TOPIC', 'DEPTH_COMMAND_TOPIC',
           'DIAGNOSTICS_TOPIC', 'FORCES_TOPIC', 'MEASURED_TOPICS', 'MESSAGE_TYPES', 'NAMESPACE',
           'ODOM_TOPIC', 'STATE_TOPIC', 'topic_basename']

NAMESPACE = '/auv'
"""Default namespace of the vehicle's topics."""
STATE_TOPIC = '/auv/state'
"""``auv_msgs/msg/VehicleState``: NED position and ZYX Euler angles, FRD velocities."""
ODOM_TOPIC = '/auv/odom'
"""``nav_msgs/msg/Odometry``: the same state in ENU/FLU (REP-103/105), for viewers."""
FORCES_TOPIC = '/auv/hydrodynamic_forces'
"""``auv_msgs/msg/HydrodynamicForces``: body FRD wrenches, same stamp as the state."""
DEPTH_COMMAND_TOPIC = '/auv/depth_command'
"""``std_msgs/msg/Float64``: commanded depth [m], positive down."""
COMMAND_TOPICS = {'bar': '/auv/bar_command', 'helm': '/auv/helm_command',
                  'thrust': '/auv/thrust_command'}
"""Actuator channel -> ``auv_msgs/msg/ActuatorSetpoint`` topic (BAR and helm [rad], thrust
[N])."""
MEASURED_TOPICS = {'bar': '/auv/bar_measured', 'helm': '/auv/helm_measured'}
"""Measured fin positions where a vehicle logs them (``ActuatorSetpoint``, rad): used in place
of the commands of the same channel."""
CLOCK_TOPIC = '/clock'
"""``rosgraph_msgs/msg/Clock``: simulated time, when the graph runs on it."""
DIAGNOSTICS_TOPIC = '/diagnostics'
"""``diagnostic_msgs/msg/DiagnosticArray``: the nodes' status."""
DEPTH_ANSWER_TOPIC = '/auv/depth_command_answer'
"""``diagnostic_msgs/msg/DiagnosticStatus``: the depth pilot's answer to each depth command
(accepted, clamped or refused; reliable, transient local)."""

MESSAGE_TYPES = {
    STATE_TOPIC: 'auv_msgs/msg/VehicleState',
    ODOM_TOPIC: 'nav_msgs/msg/Odometry',
    FORCES_TOPIC: 'auv_msgs/msg/HydrodynamicForces',
    DEPTH_COMMAND_TOPIC: 'std_msgs/msg/Float64',
    **{topic: 'auv_msgs/msg/ActuatorSetpoint' for topic in COMMAND_TOPICS.values()},
    **{topic: 'auv_msgs/msg/ActuatorSetpoint' for topic in MEASURED_TOPICS.values()},
    CLOCK_TOPIC: 'rosgraph_msgs/msg/Clock',
    DIAGNOSTICS_TOPIC: 'diagnostic_msgs/msg/DiagnosticArray',
    DEPTH_ANSWER_TOPIC: 'diagnostic_msgs/msg/DiagnosticStatus',
}
"""Topic -> message type name, as rosbag2 and rosbags spell it."""


def topic_basename(topic: str) -> str:
    """The last name of a topic, relative or absolute (``/auv1/bar_command`` ->
    ``bar_command``)."""
    return topic.rstrip('/').rsplit('/', 1)[-1]
