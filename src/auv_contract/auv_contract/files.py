"""The shipped configuration, found through the ament index, and the one YAML loader.

The vehicle files, missions, effect files and example maps of ``config/`` are installed as
this package's data (``share/auv_contract/config``) and found with
:func:`ament_index_python.get_package_share_directory`, as ``ros2 run`` finds a package's
files on any ROS 2 install. ``AUV_CONFIG_DIR`` overrides the directory.

YAML files (vehicle, effect, mission files, bag metadata) are read by :func:`read_yaml` and
:func:`parse_yaml` (PyYAML's safe loader, its C version where present: a bag's
``metadata.yaml`` in about 1 ms); only mapping files are read with line numbers
(:func:`parse_yaml_with_lines`, ruamel's round-trip loader), for errors that name the line.
"""
from __future__ import annotations

import os
import pathlib
from typing import Any

__all__ = ['YamlError', 'config_dir', 'config_path', 'parse_yaml', 'parse_yaml_with_lines',
           'read_yaml']

PACKAGE = 'auv_contract'


class YamlError(ValueError):
    """A file is not valid YAML; the message names the file (or text) and the line."""


def config_dir() -> pathlib.Path:
    """The shipped ``config`` directory: ``$AUV_CONFIG_DIR``, else this package's share
    directory in the ament index.

    Raises
    ------
    FileNotFoundError
        Neither names an existing directory (the message says how to set up the workspace).
    """
    override = os.environ.get('AUV_CONFIG_DIR')
    if override:
        path = pathlib.Path(override)
        if not path.is_dir():
            raise FileNotFoundError(f'AUV_CONFIG_DIR={override} is not a directory')
        return path
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    try:
        share = pathlib.Path(get_package_share_directory(PACKAGE))
    except (PackageNotFoundError, ValueError, LookupError):
        raise FileNotFoundError(
            f'{PACKAGE} is not in the ament index (AMENT_PREFIX_PATH): source '
            '.venv/bin/auv-env (or the workspace install) first') from None
    return share / 'config'


def config_path(*parts: str) -> pathlib.Path:
    """A file or directory of the shipped configuration (``config_path('a18m.yaml')``,
    ``config_path('missions', 'pitch.yaml')``); it need not exist."""
    return config_dir().joinpath(*parts)


def parse_yaml(text: str, source: str = '<text>') -> Any:
    """The data of YAML ``text``.

    Raises
    ------
    YamlError
        Not valid YAML; the message names ``source`` and the line.
    """
    import yaml

    loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
    try:
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}' if mark is not None else ''
        problem = getattr(exc, 'problem', None)
        raise YamlError(f'{source}: malformed YAML{where}'
                        + (f' ({problem})' if problem else '')) from None


def read_yaml(path: str | os.PathLike[str]) -> Any:
    """The data of the YAML file at ``path``.

    Raises
    ------
    OSError
        The file cannot be read.
    YamlError
        Not valid YAML (the message names the file and the line).
    """
    path = pathlib.Path(path)
    return parse_yaml(path.read_text(), str(path))


def read_yaml_file(path: str | os.PathLike[str], what: str,
                   error: type[Exception]) -> Any:
    """The data of the YAML file at ``path``, a failure raised as one line of the caller's
    error family: ``cannot read <what> <path>: <reason>``, or the malformed-YAML line.

    Raises
    ------
    error
        The file cannot be read, or it is not valid YAML.
    """
    try:
        return read_yaml(path)
    except OSError as exc:
        raise error(f'cannot read {what} {path}: {exc.strerror}') from None
    except YamlError as exc:
        raise error(str(exc)) from None


def parse_yaml_with_lines(text: str, source: str = '<text>') -> Any:
    """The data of YAML ``text`` as ruamel round-trip containers, whose ``.lc`` gives each
    key's line (for errors that point at a line of a user's file).

    Raises
    ------
    YamlError
        Not valid YAML; the message names ``source`` and the line.
    """
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    try:
        return YAML(typ='rt').load(text)
    except YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        line = f' line {mark.line + 1}' if mark is not None else ''
        raise YamlError(f'{source}{line}: not valid YAML ({getattr(exc, "problem", exc)})') \
            from None
