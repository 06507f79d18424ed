"""Command a depth to the depth pilot from a Python script, the way that never loses it.

    python examples/depth_command.py 15.0 [NAMESPACE]

1. Publish reliable and transient local (latched): a subscription that matches late still
   gets the command from the publisher's history.
2. Publish only once DDS has matched the pilot: a sample published before that is lost to
   it (DDS delivers to the subscriptions it has matched, nothing else).
3. Wait for the pilot's answer on ``depth_command_answer`` (``DiagnosticStatus``): accepted,
   clamped or refused, and why. Exit status 0 when accepted, 1 otherwise.

``auv depth 15`` does the same from a shell. Depth in metres, positive down (NED).
"""
import sys
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

depth = float(sys.argv[1])
ns = sys.argv[2] if len(sys.argv) > 2 else '/auv'
latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
rclpy.init()
node = rclpy.create_node('depth_command_example')
pub = node.create_publisher(Float64, f'{ns}/depth_command', latched)
answers = []
node.create_subscription(DiagnosticStatus, f'{ns}/depth_command_answer', answers.append,
                         QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.TRANSIENT_LOCAL))
deadline = time.monotonic() + 30.0


def pilot_matched():
    """The pilot's subscriptions are listed and every listed subscription is matched."""
    subs = node.get_subscriptions_info_by_topic(f'{ns}/depth_command')
    return (any(s.node_name == 'depth_pilot' for s in subs)
            and pub.get_subscription_count() >= len(subs))


while not pilot_matched():
    if time.monotonic() > deadline:
        sys.exit('no depth pilot on ' + ns)
    rclpy.spin_once(node, timeout_sec=0.05)
pub.publish(Float64(data=depth))
me = next(bytes(i.endpoint_gid).hex() for i in node.get_publishers_info_by_topic(
    f'{ns}/depth_command') if i.node_name == node.get_name())
while time.monotonic() < deadline:
    for status in answers:
        values = {kv.key: kv.value for kv in status.values}
        if values.get('publisher') == me:  # the answer to this command
            print(status.message)
            sys.exit(0 if values['result'] == 'accepted' else 1)
    rclpy.spin_once(node, timeout_sec=0.05)
sys.exit('no answer from the pilot')
