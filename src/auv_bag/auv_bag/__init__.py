"""rosbag2 bags in MCAP storage, written and read without a ROS graph.

* :mod:`auv_bag.writer`: :class:`BagWriter`, bags as ``ros2 bag record -s mcap`` writes them;
* :mod:`auv_bag.read`: :func:`read_arrays` (topics into numpy arrays, decoded column by
  column), :func:`read_messages` (message by message), :func:`bag_topics`;
* :mod:`auv_bag.typestore`: the ROS 2 typestore with the auv_msgs types registered;
* :mod:`auv_bag.repair`: :func:`repair_bag`, the whole messages of a damaged bag (a killed
  recorder's) written to a new bag every reader takes;
* :mod:`auv_bag.metadata`: ``metadata.yaml``, QoS profiles, the files of a bag;
* :mod:`auv_bag.scan`, :mod:`auv_bag.locate`, :mod:`auv_bag.damage`, :mod:`auv_bag.columnar`:
  the container scan (``mcap`` records), message location, damage handling and the vectorised
  CDR decode behind :func:`read_arrays`.

Every error on bad input is a :class:`BagError`. No module here imports rclpy.
"""
from __future__ import annotations

from .errors import BagError
from .metadata import DEFAULT_QOS_DEPTH, bag_files, qos_profiles_yaml
from .read import REPAIR_HINT, BagArrays, BagMessage, bag_topics, read_arrays, read_messages
from .repair import RepairReport, repair_bag
from .scan import ProgressCallback, default_workers
from .typestore import msg_dir, normalize_msgtype, typestore
from .writer import BagWriter

__all__ = [
    'DEFAULT_QOS_DEPTH',
    'REPAIR_HINT',
    'BagArrays',
    'BagError',
    'BagMessage',
    'BagWriter',
    'ProgressCallback',
    'RepairReport',
    'bag_files',
    'bag_topics',
    'default_workers',
    'msg_dir',
    'normalize_msgtype',
    'qos_profiles_yaml',
    'read_arrays',
    'read_messages',
    'repair_bag',
    'typestore',
]
