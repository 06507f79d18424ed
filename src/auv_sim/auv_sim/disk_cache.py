"""On-disk cache of what a node computes at every start from its files alone (the pilot's gain
schedule, the simulator's initial trim), so that a start does not redo it.

Where: ``$AUV_CACHE_DIR`` when set (an empty value turns the cache off), else
``$XDG_CACHE_HOME/auv``, else ``~/.cache/auv``. One JSON file per entry,
``<kind>-<key>.json``; delete the directory (``rm -rf ~/.cache/auv``) to clear it, at any time.

Correct by construction: an entry's key is the SHA-256 of everything the computation depends
on, namely its inputs as given (for the pilot: the vehicle's parameters as loaded, the
gain-scheduling grid, the weights, the sample period), the source of the packages whose code
computes it (every ``.py`` file of them: any edit of the code makes a new key) and the versions
of Python, NumPy, SciPy and Numba. A file whose key, kind or payload checksum does not match,
or that cannot be read or decoded, is ignored and the value computed afresh (and written
again): an entry is never trusted beyond what its key proves. Entries are written atomically
(a temporary file renamed over the entry), so a reader sees a whole entry or none, also with
several nodes starting at once; a cache directory that cannot be written only costs the
computation.

Size: every edit of the code makes new keys, so old entries would pile up. A read renews an
entry's modification time, and writing an entry removes the least recently used ones of its
kind beyond :data:`MAX_ENTRIES` (a pilot design is about 30 kB: 8 MB at most per kind).
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import pathlib
import platform
import sys
import tempfile
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

__all__ = ['CACHE_ENV', 'FORMAT', 'MAX_ENTRIES', 'cache_dir', 'cached', 'entry_key',
           'entry_path', 'payload_digest', 'source_digest']

T = TypeVar('T')

CACHE_ENV = 'AUV_CACHE_DIR'
"""Environment variable naming the cache directory ('' turns the cache off)."""
FORMAT = 1
"""Version of the entry layout (part of every key)."""
MAX_ENTRIES = 256
"""Entries kept per kind: writing one more removes the least recently used beyond it (by
modification time, renewed at every read)."""


def cache_dir() -> pathlib.Path | None:
    """The cache directory (see the module docstring), or None when the cache is off.

    Returns
    -------
    pathlib.Path or None
        ``$AUV_CACHE_DIR``, ``$XDG_CACHE_HOME/auv`` or ``~/.cache/auv``; None when
        ``AUV_CACHE_DIR`` is set but empty.
    """
    given = os.environ.get(CACHE_ENV)
    if given is not None:
        return pathlib.Path(given).expanduser() if given else None
    base = os.environ.get('XDG_CACHE_HOME') or str(pathlib.Path.home() / '.cache')
    return pathlib.Path(base) / 'auv'


@functools.cache
def source_digest(packages: tuple[str, ...]) -> str:
    """SHA-256 of the code that computes a cached value and of the libraries it runs on.

    Parameters
    ----------
    packages : tuple of str
        Top-level packages (``auv_sim``, ``auv_depth_lqr``): every ``.py`` file below each,
        by relative path and content, as imported (the installed copy or the source tree).

    Returns
    -------
    str
        Hex digest, also over the versions of Python, NumPy, SciPy and Numba and the machine.
    """
    h = hashlib.sha256()
    for package in packages:
        spec = importlib.util.find_spec(package)
        if spec is None or spec.origin is None:
            raise ImportError(f'package {package} not found')
        root = pathlib.Path(spec.origin).parent
        for path in sorted(root.rglob('*.py')):
            h.update(f'{package}/{path.relative_to(root).as_posix()}\0'.encode())
            h.update(path.read_bytes())
            h.update(b'\0')
    versions = [sys.version, platform.machine()]
    for library in ('numpy', 'scipy', 'numba'):
        try:
            versions.append(f'{library} {importlib.metadata.version(library)}')
        except importlib.metadata.PackageNotFoundError:
            versions.append(f'{library} absent')
    h.update('\n'.join(versions).encode())
    return h.hexdigest()


def entry_key(kind: str, inputs: Any, packages: Sequence[str]) -> str:
    """The key of an entry: SHA-256 of ``kind``, ``inputs`` and the code's digest.

    Parameters
    ----------
    kind : str
        What is cached (``pilot-design``, ``trim``), also the entry file's prefix.
    inputs : JSON-serialisable
        Everything the value depends on besides the code; floats are written exactly
        (shortest round-trip form), dict keys sorted.
    packages : sequence of str
        The packages whose code computes the value (:func:`source_digest`).

    Returns
    -------
    str
        Hex digest.
    """
    text = json.dumps({'format': FORMAT, 'kind': kind, 'inputs': inputs,
                       'code': source_digest(tuple(packages))},
                      sort_keys=True, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def entry_path(kind: str, key: str) -> pathlib.Path | None:
    """The file of entry ``key`` of ``kind`` (None with the cache off)."""
    root = cache_dir()
    return None if root is None else root / f'{kind}-{key}.json'


def payload_digest(payload: Any) -> str:
    """SHA-256 of an entry's payload as written (sorted keys, exact floats): its checksum."""
    return hashlib.sha256(json.dumps(payload, sort_keys=True, allow_nan=True).encode()
                          ).hexdigest()


def _read(path: pathlib.Path, kind: str, key: str) -> Any:
    """The payload of the entry at ``path``; KeyError, ValueError or OSError when it is
    missing, unreadable or not the entry of ``kind`` and ``key`` whole."""
    entry = json.loads(path.read_text())
    if not isinstance(entry, dict) or entry.get('kind') != kind or entry.get('key') != key \
            or entry.get('format') != FORMAT:
        raise ValueError('another entry')
    payload = entry['payload']
    if entry.get('payload_sha256') != payload_digest(payload):
        raise ValueError('payload checksum')
    return payload


def _write(path: pathlib.Path, kind: str, key: str, payload: Any) -> None:
    """Write the entry atomically (a temporary file in the directory, renamed over it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    entry = {'format': FORMAT, 'kind': kind, 'key': key,
             'payload_sha256': payload_digest(payload), 'payload': payload}
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name}.', dir=path.parent)
    try:
        with os.fdopen(fd, 'w') as fh:
            json.dump(entry, fh, allow_nan=True)
        os.replace(tmp, path)
    except BaseException:
        pathlib.Path(tmp).unlink(missing_ok=True)
        raise


def _prune(root: pathlib.Path, kind: str) -> None:
    """Remove the least recently used entries of ``kind`` in ``root`` beyond
    :data:`MAX_ENTRIES` (an entry another process removes or renews meanwhile is skipped)."""
    def used(path: pathlib.Path) -> float:
        try:
            return path.stat().st_mtime
        except OSError:
            return float('inf')

    entries = sorted(root.glob(f'{kind}-*.json'), key=used)
    for old in entries[:max(len(entries) - MAX_ENTRIES, 0)]:
        old.unlink(missing_ok=True)


def cached(kind: str, inputs: Any, packages: Sequence[str], compute: Callable[[], T],
           encode: Callable[[T], Any], decode: Callable[[Any], T]) -> T:
    """The value of ``compute()``, from the cache when a whole entry of the same key is there.

    Parameters
    ----------
    kind : str
        What is cached (the entry file's prefix).
    inputs : JSON-serialisable
        Everything the value depends on besides the code (see :func:`entry_key`).
    packages : sequence of str
        The packages whose code computes the value.
    compute : callable
        Computes the value (its exceptions pass through; nothing is cached then).
    encode : callable
        The value as JSON-serialisable data (floats are kept exactly).
    decode : callable
        ``encode``'s inverse; it raises KeyError, TypeError or ValueError on data that is not
        a whole value (the entry is then ignored).

    Returns
    -------
    T
        The cached value when an entry of the key decodes, else ``compute()`` (then stored).
    """
    key = entry_key(kind, inputs, packages)
    path = entry_path(kind, key)
    if path is not None:
        try:
            value = decode(_read(path, kind, key))
        except (OSError, KeyError, TypeError, ValueError):
            pass  # missing, unreadable or not this entry whole: computed afresh below
        else:
            with contextlib.suppress(OSError):
                os.utime(path)  # used now: the last to be pruned
            return value
    value = compute()
    if path is not None:
        # a cache that cannot be written only costs the computation next time
        with contextlib.suppress(OSError):
            _write(path, kind, key, encode(value))
            _prune(path.parent, kind)
    return value
