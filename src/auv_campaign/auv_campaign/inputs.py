"""Which logs a campaign runs on: logs, directories of logs, globs and list files.

Without a map (contract bags), a *log* is a bag: a ``.mcap`` file or a bag directory, one
with a ``metadata.yaml``, or without one (a recorder that crashed) whose ``.mcap`` files are
all named as rosbag2 splits them, ``<directory name>_<N>.mcap``. With a map
(:mod:`auv_logs`), a log is what the map's kind reads
(:func:`auv_logs.readers.log_kind`): for ``kind: bag`` a rosbag2 directory
(``metadata.yaml``; ``.mcap`` or ``.db3`` storage), a ``.mcap`` file or a ROS 1 ``.bag``
file; for ``kind: text`` a text log (``.csv .txt .log .dat .tsv``).

Any other directory is searched (recursively) for logs, so a directory of ``.mcap`` files is
a directory of single-file bags. A ``.list`` file, and a ``.txt`` file unless the map reads
text logs, names one log per line (blank lines and ``#`` comments skipped; relative paths
are relative to the list file). Anything else is a glob pattern.
"""
from __future__ import annotations

import glob
import pathlib
import re
from collections.abc import Sequence

from auv_campaign.errors import CampaignError
from auv_logs.readers import TEXT_SUFFIXES

LIST_SUFFIXES = ('.txt', '.list')
#: Kinds of log a campaign reads: contract bags (no map), or what a map of that kind reads.
LOG_KINDS = (None, 'bag', 'text')


def _is_list(path: pathlib.Path, kind: str | None) -> bool:
    """A list file: ``.list``, or ``.txt`` unless the logs are text logs."""
    return path.is_file() and (path.suffix == '.list'
                               or (path.suffix == '.txt' and kind != 'text'))


def is_log(path: pathlib.Path, kind: str | None = None) -> bool:
    """True for a log the campaign reads (``kind``: None for contract bags, else the map's
    kind; see the module docstring)."""
    if kind is None:
        return is_bag(path)
    if kind == 'text':
        return path.is_file() and path.suffix.lower() in TEXT_SUFFIXES
    if path.is_file():
        return path.suffix.lower() in ('.mcap', '.bag')
    return is_bag(path)


def is_bag(path: pathlib.Path) -> bool:
    """True for a ``.mcap`` file or a bag directory (see the module docstring)."""
    if path.is_file():
        return path.suffix == '.mcap'
    if not path.is_dir():
        return False
    if (path / 'metadata.yaml').is_file():
        return True
    files = list(path.glob('*.mcap'))
    return bool(files) and all(re.fullmatch(re.escape(path.name) + r'_\d+\.mcap', f.name)
                               for f in files)


def _logs_under(directory: pathlib.Path, kind: str | None) -> list[pathlib.Path]:
    found: list[pathlib.Path] = []
    for child in sorted(directory.iterdir()):
        if is_log(child, kind):
            found.append(child)
        elif child.is_dir():
            found += _logs_under(child, kind)
    return found


def expand(item: str, kind: str | None = None, _depth: int = 0) -> list[pathlib.Path]:
    """The logs ``item`` names (``kind``: None for contract bags, else the map's kind; see
    the module docstring)."""
    path = pathlib.Path(item)
    if kind == 'bag' and path.is_file() and path.suffix == '.db3' \
            and (path.parent / 'metadata.yaml').is_file():
        path = path.parent   # a sqlite3 bag is read with its directory
    if _is_list(path, kind):
        if _depth > 3:
            raise CampaignError(f'list file {path} nests list files too deep')
        out: list[pathlib.Path] = []
        for line in path.read_text().splitlines():
            line = line.split('#', 1)[0].strip()
            if line:
                entry = pathlib.Path(line)
                entry = entry if entry.is_absolute() else path.parent / entry
                out += expand(str(entry), kind, _depth + 1)
        return out
    if is_log(path, kind):
        return [path]
    if path.is_dir():
        return _logs_under(path, kind)
    if path.exists():
        what = 'a bag' if kind is None else f'a log the map (kind: {kind}) reads'
        raise CampaignError(f'{path} is neither {what}, a directory nor a list file')
    matches = [pathlib.Path(m) for m in sorted(glob.glob(item, recursive=True))]
    if not matches:
        raise CampaignError(f'no log matches {item!r}')
    out = []
    for m in matches:
        if is_log(m, kind):
            out.append(m)
        elif m.is_dir():
            out += _logs_under(m, kind)
    return out


def find_logs(items: Sequence[str], kind: str | None = None) -> list[pathlib.Path]:
    """Every log the arguments name, each once (first occurrence kept), in argument order
    (``kind``: None for contract bags, else the map's kind).

    Raises
    ------
    CampaignError
        an argument names nothing, or no log is found at all.
    """
    if kind not in LOG_KINDS:
        raise CampaignError(f'unknown log kind {kind!r}')
    seen: set[pathlib.Path] = set()
    logs: list[pathlib.Path] = []
    for item in items:
        for p in expand(item, kind):
            key = p.resolve()
            if key not in seen:
                seen.add(key)
                logs.append(p)
    if not logs:
        what = 'bag' if kind is None else f'log the map (kind: {kind}) reads'
        raise CampaignError(f'no {what} found in ' + ' '.join(items))
    return logs


def mission_names(logs: Sequence[pathlib.Path]) -> list[str]:
    """A unique, file-system safe name per log (the bag's or file's name without its suffix,
    numbered on a clash)."""
    names: list[str] = []
    used: set[str] = set()
    for p in logs:
        stem = p.stem if p.suffix and not p.is_dir() else p.name
        stem = ''.join(c if c.isalnum() or c in '-_.' else '_' for c in stem) or 'log'
        name, k = stem, 2
        while name in used:
            name, k = f'{stem}-{k}', k + 1
        used.add(name)
        names.append(name)
    return names
