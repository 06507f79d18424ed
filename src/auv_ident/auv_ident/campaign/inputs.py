"""Which logs a campaign runs on: bags, directories of bags, globs and list files.

A *bag* is a ``.mcap`` file or a bag directory: one with a ``metadata.yaml``, or without one
(a recorder that crashed) whose ``.mcap`` files are all named as rosbag2 splits them,
``<directory name>_<N>.mcap``. Any other directory is searched (recursively) for bags, so a
directory of ``.mcap`` files is a directory of single-file bags. A ``.txt`` or
``.list`` file names one log per line (blank lines and ``#`` comments skipped; relative paths
are relative to the list file). Anything else is a glob pattern.
"""
from __future__ import annotations

import glob
import pathlib
import re
from collections.abc import Sequence

from auv_ident.campaign.errors import CampaignError

LIST_SUFFIXES = ('.txt', '.list')


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


def _bags_under(directory: pathlib.Path) -> list[pathlib.Path]:
    found: list[pathlib.Path] = []
    for child in sorted(directory.iterdir()):
        if is_bag(child):
            found.append(child)
        elif child.is_dir():
            found += _bags_under(child)
    return found


def expand(item: str, _depth: int = 0) -> list[pathlib.Path]:
    """The bags ``item`` names (see the module docstring)."""
    path = pathlib.Path(item)
    if path.is_file() and path.suffix in LIST_SUFFIXES:
        if _depth > 3:
            raise CampaignError(f'list file {path} nests list files too deep')
        out: list[pathlib.Path] = []
        for line in path.read_text().splitlines():
            line = line.split('#', 1)[0].strip()
            if line:
                entry = pathlib.Path(line)
                entry = entry if entry.is_absolute() else path.parent / entry
                out += expand(str(entry), _depth + 1)
        return out
    if is_bag(path):
        return [path]
    if path.is_dir():
        return _bags_under(path)
    if path.exists():
        raise CampaignError(f'{path} is neither a bag, a directory nor a list file')
    matches = [pathlib.Path(m) for m in sorted(glob.glob(item, recursive=True))]
    if not matches:
        raise CampaignError(f'no log matches {item!r}')
    out = []
    for m in matches:
        if is_bag(m):
            out.append(m)
        elif m.is_dir():
            out += _bags_under(m)
    return out


def find_logs(items: Sequence[str]) -> list[pathlib.Path]:
    """Every bag the arguments name, each once (first occurrence kept), in argument order.

    Raises:
        CampaignError: an argument names nothing, or no bag is found at all.
    """
    seen: set[pathlib.Path] = set()
    logs: list[pathlib.Path] = []
    for item in items:
        for p in expand(item):
            key = p.resolve()
            if key not in seen:
                seen.add(key)
                logs.append(p)
    if not logs:
        raise CampaignError('no bag found in ' + ' '.join(items))
    return logs


def mission_names(logs: Sequence[pathlib.Path]) -> list[str]:
    """A unique, file-system safe name per log (the bag's name, numbered on a clash)."""
    names: list[str] = []
    used: set[str] = set()
    for p in logs:
        stem = p.name[:-5] if p.name.endswith('.mcap') else p.name
        stem = ''.join(c if c.isalnum() or c in '-_.' else '_' for c in stem) or 'log'
        name, k = stem, 2
        while name in used:
            name, k = f'{stem}-{k}', k + 1
        used.add(name)
        names.append(name)
    return names
