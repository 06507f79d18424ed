"""The contract every package, script and stored bag relies on, written once.

* :mod:`.topics`: topic names (default namespace ``/auv``) and their message types;
* :mod:`.state`: the vehicle state's layout (Fossen's 12 states, NED/FRD) and the actuator
  channels;
* :mod:`.files`: the shipped configuration (vehicle files, missions, effects, maps) found
  through the ament index, and the one YAML loader;
* :mod:`.jsonout`: the strict JSON every command prints and every report file holds;
* :mod:`.dds`: the Fast DDS profile the toolkit's processes use unless the user names one.

Nothing here imports another package of the project: it is the lowest layer.
"""
from auv_contract.files import (
    YamlError,
    config_dir,
    config_path,
    parse_yaml,
    read_yaml,
    read_yaml_file,
)
from auv_contract.state import CHANNELS, STATE_FIELDS, STATE_UNITS
from auv_contract.topics import (
    CLOCK_TOPIC,
    COMMAND_TOPICS,
    DEPTH_ANSWER_TOPIC,
    DEPTH_COMMAND_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCES_TOPIC,
    MEASURED_TOPICS,
    MESSAGE_TYPES,
    NAMESPACE,
    ODOM_TOPIC,
    STATE_TOPIC,
    topic_basename,
)

__all__ = ['CHANNELS', 'CLOCK_TOPIC', 'COMMAND_TOPICS', 'DEPTH_ANSWER_TOPIC',
           'DEPTH_COMMAND_TOPIC', 'DIAGNOSTICS_TOPIC', 'FORCES_TOPIC', 'MEASURED_TOPICS',
           'MESSAGE_TYPES', 'NAMESPACE', 'ODOM_TOPIC', 'STATE_FIELDS', 'STATE_TOPIC',
           'STATE_UNITS', 'YamlError', 'config_dir', 'config_path', 'parse_yaml', 'read_yaml',
           'read_yaml_file',
           'topic_basename']
