"""Each package.xml declares every package its modules import at run time, so that
``rosdep install`` and ``ros2 run`` work on a full ROS 2 install."""
from __future__ import annotations

import ast
import pathlib
import re
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PYTHON_PACKAGES = tuple(sorted(p.parent.name for p in (ROOT / 'src').glob('*/setup.py')))
#: import name -> rosdep key, for imports whose key is not the import name itself
ROSDEP_KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'numba': 'python3-numba', 'matplotlib': 'python3-matplotlib', 'lz4': 'python3-lz4',
    'zstandard': 'python3-zstandard', 'ruamel': 'python3-ruamel.yaml',
    'control': 'python3-control-pip', 'mcap': 'python3-mcap-pip',
    'rosbags': 'python3-rosbags-pip', 'dask': 'python3-dask',
    'distributed': 'python3-distributed', 'foxglove': 'python3-foxglove-sdk-pip',
    'websockets': 'python3-websockets', 'pandas': 'python3-pandas',
    'statsmodels': 'python3-statsmodels', 'psutil': 'python3-psutil',
}


def _imports(package: str) -> set[str]:
    names: set[str] = set()
    for path in (ROOT / 'src' / package / package).rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names.update(a.name.split('.')[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names) - {'__future__', package}


@pytest.mark.parametrize('package', PYTHON_PACKAGES)
def test_package_xml_declares_every_import(package: str) -> None:
    text = (ROOT / 'src' / package / 'package.xml').read_text()
    declared = set(re.findall(r'<(?:exec_)?depend>([^<]+)</(?:exec_)?depend>', text))
    missing = sorted(f'{name} ({ROSDEP_KEYS.get(name, name)})' for name in _imports(package)
                     if ROSDEP_KEYS.get(name, name) not in declared)
    assert not missing, f'src/{package}/package.xml lacks exec_depend on {", ".join(missing)}'


def test_recorded_message_packages_are_declared() -> None:
    """The recorder and the Foxglove bridge load the message types of their known topics by
    name at run time (no import statement names them): their packages are declared too."""
    from auv_bringup.record_node import KNOWN_TOPICS
    text = (ROOT / 'src' / 'auv_bringup' / 'package.xml').read_text()
    declared = set(re.findall(r'<(?:exec_)?depend>([^<]+)</(?:exec_)?depend>', text))
    needed = {msgtype.split('/')[0] for msgtype in KNOWN_TOPICS.values()}
    assert needed - declared == set(), sorted(needed - declared)
