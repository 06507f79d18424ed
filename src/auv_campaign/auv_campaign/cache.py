"""Mission results cached by the log's content hash and the settings.

The key of a mission is the SHA-256 of (campaign kind, the log's content hash, the settings
that change the result, the content hashes of the vehicle file and of the map, the code
version (:func:`code_version`), :data:`FORMAT`). The content hash covers the log file byte for
byte, or every storage file of a bag directory (``.mcap``, ``.db3``) and its
``metadata.yaml``, so a renamed or moved log is still found and a re-recorded one is not.
Entries are JSON files in the cache directory; a worker reads and writes them, so on a
cluster the directory must be on a file system the workers share (as the output directory
must).
"""
from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import pathlib
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

#: Bumped when the cached record's layout or meaning changes.
FORMAT = 2
_BLOCK = 1 << 20
#: Packages whose source files make the code version (the tools, the simulator).
CODE_PACKAGES = ('auv_ident', 'auv_gap', 'auv_logs', 'auv_sim')
#: Installed distributions whose versions make the code version (numerics, readers).
LIBRARIES = ('numpy', 'scipy', 'numba', 'rosbags', 'mcap', 'python-control', 'control')
#: Files of a bag directory that hold its content.
_BAG_FILES = ('.mcap', '.db3')


def file_hash(path: str | os.PathLike[str], h: Any = None) -> str:
    """SHA-256 (hex) of a file's bytes, or of several files when a hash object is passed."""
    h = h or hashlib.sha256()
    with open(path, 'rb') as fh:
        while block := fh.read(_BLOCK):
            h.update(block)
    return str(h.hexdigest())


def content_hash(log: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of a log's content: the file, or a bag directory's storage files
    (``.mcap``, ``.db3``) and ``metadata.yaml`` in name order, each preceded by its name."""
    p = pathlib.Path(log)
    if p.is_file():
        return file_hash(p)
    h = hashlib.sha256()
    files = sorted(f for f in p.iterdir() if f.suffix in _BAG_FILES or f.name == 'metadata.yaml')
    for f in files:
        h.update(f.name.encode() + b'\0')
        file_hash(f, h)
    return str(h.hexdigest())


def tree_hash(roots: Iterable[str | os.PathLike[str]]) -> str:
    """SHA-256 (hex) of every ``.py`` file under ``roots`` (each preceded by its path
    relative to its root; ``__pycache__`` skipped), in path order."""
    h = hashlib.sha256()
    for root in roots:
        r = pathlib.Path(root)
        h.update(r.name.encode() + b'\0')
        for f in sorted(r.rglob('*.py')):
            if '__pycache__' in f.parts:
                continue
            h.update(f.relative_to(r).as_posix().encode() + b'\0')
            file_hash(f, h)
    return str(h.hexdigest())


def _package_dir(name: str) -> pathlib.Path | None:
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        return None
    return pathlib.Path(next(iter(spec.submodule_search_locations)))


@functools.lru_cache(maxsize=1)
def code_version(packages: Sequence[str] = CODE_PACKAGES,
                 libraries: Sequence[str] = LIBRARIES) -> dict[str, Any]:
    """What the results depend on besides the inputs: the hash of the source files of
    ``packages`` (:func:`tree_hash`) and the installed versions of ``libraries`` (absent ones
    left out). An upgrade of either changes every cache key."""
    dirs = [d for d in (_package_dir(n) for n in packages) if d is not None]
    versions = {}
    for lib in libraries:
        try:
            versions[lib] = importlib.metadata.version(lib)
        except importlib.metadata.PackageNotFoundError:
            continue
    return {'source': tree_hash(dirs), 'packages': list(packages), 'libraries': versions}


def mission_key(kind: str, log_hash: str, settings: Mapping[str, Any]) -> str:
    """Cache key of one mission (hex): kind, log content and settings."""
    doc = json.dumps({'format': FORMAT, 'kind': kind, 'log': log_hash, 'settings': settings},
                     sort_keys=True)
    return hashlib.sha256(doc.encode()).hexdigest()


class Cache:
    """A directory of ``<key>.json`` mission records."""

    def __init__(self, directory: str | os.PathLike[str]) -> None:
        self.directory = pathlib.Path(directory)

    def get(self, key: str) -> dict[str, Any] | None:
        """The record stored under ``key``, or None (also for an unreadable entry)."""
        try:
            doc = json.loads((self.directory / f'{key}.json').read_text())
        except (OSError, ValueError):
            return None
        return doc if isinstance(doc, dict) else None

    def put(self, key: str, record: Mapping[str, Any]) -> None:
        """Store ``record`` atomically (written to a temporary file, then renamed)."""
        self.directory.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.directory, suffix='.tmp')
        with os.fdopen(fd, 'w') as fh:
            json.dump(record, fh, indent=1)
        os.replace(tmp, self.directory / f'{key}.json')
