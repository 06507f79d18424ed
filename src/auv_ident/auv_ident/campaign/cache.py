"""Mission results cached by the log's content hash and the settings.

The key of a mission is the SHA-256 of (campaign kind, the log's content hash, the settings
that change the result, the content hash of the vehicle file, :data:`FORMAT`). The content
hash covers every ``.mcap`` file of the bag (and its ``metadata.yaml``) byte for byte, so a
renamed or moved bag is still found and a re-recorded one is not. Entries are JSON files in
the cache directory; a worker reads and writes them, so on a cluster the directory must be
on a file system the workers share (as the output directory must).
"""
from __future__ import annotations

import hashlib
import json
import os
import pathlib
import tempfile
from collections.abc import Mapping
from typing import Any

#: Bumped when the cached record's layout or meaning changes.
FORMAT = 1
_BLOCK = 1 << 20


def file_hash(path: str | os.PathLike[str], h: Any = None) -> str:
    """SHA-256 (hex) of a file's bytes, or of several files when a hash object is passed."""
    h = h or hashlib.sha256()
    with open(path, 'rb') as fh:
        while block := fh.read(_BLOCK):
            h.update(block)
    return str(h.hexdigest())


def content_hash(bag: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of a bag's content: its ``.mcap`` files (and ``metadata.yaml``) in name
    order, each preceded by its name within the bag."""
    p = pathlib.Path(bag)
    if p.is_file():
        return file_hash(p)
    h = hashlib.sha256()
    files = sorted(f for f in p.iterdir() if f.suffix == '.mcap' or f.name == 'metadata.yaml')
    for f in files:
        h.update(f.name.encode() + b'\0')
        file_hash(f, h)
    return str(h.hexdigest())


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
