"""Logs for the gap diagnosis: loading from bags, checking, smoothing.

A :class:`GapLog` is one continuous piece of a vehicle log on a uniform time grid: the
measured state (``/auv/state``: NED position and ZYX Euler angles, body-FRD velocities over
ground; SI units, radians) and the actuator commands as they were sent (time-stamped
set-points, held until the next one). No force topic is needed.
"""
from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.signal import savgol_filter

from auv_ident.errors import GapError

STATE_FIELDS = ('x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')
CHANNELS = ('bar', 'helm', 'thrust')
STATE_TOPIC = '/auv/state'
COMMAND_TOPICS = {'bar': '/auv/bar_command', 'helm': '/auv/helm_command',
                  'thrust': '/auv/thrust_command'}
#: A pause in the state stream longer than this many median sample periods splits the log.
GAP_SPLIT = 5.0


@dataclasses.dataclass(frozen=True)
class GapLog:
    """One continuous log piece: ``t`` (N) uniform [s], ``state`` (N x 12) as measured, and
    per channel the commands ``(stamps [s], values [rad or N])`` sorted by time."""

    name: str
    t: np.ndarray
    state: np.ndarray
    commands: Mapping[str, tuple[np.ndarray, np.ndarray]]
    notes: tuple[str, ...] = ()

    @property
    def period(self) -> float:
        """Sample period [s]."""
        return float(self.t[1] - self.t[0])

    @property
    def duration(self) -> float:
        """Length [s]."""
        return float(self.t[-1] - self.t[0])


def from_arrays(name: str, t: np.ndarray, state: np.ndarray,
                commands: Mapping[str, tuple[np.ndarray, np.ndarray]],
                notes: Sequence[str] = ()) -> list[GapLog]:
    """Check and regularise a log: split at pauses, resample onto a uniform grid.

    ``t`` (N) [s] must be non-decreasing and finite; ``state`` (N x 12) finite. Yaw is
    unwrapped before resampling. Channels missing from ``commands`` other than the helm are
    an error; a missing helm is held at 0 rad (and said so in ``notes``).
    """
    t = np.asarray(t, dtype=np.float64)
    state = np.asarray(state, dtype=np.float64)
    if t.ndim != 1 or state.shape != (t.size, 12):
        raise GapError(f'{name}: state must be N x 12 with N time stamps, got {state.shape}')
    if t.size < 20:
        raise GapError(f'{name}: only {t.size} state samples; a diagnosis needs a log of '
                       'a minute or more')
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(state))):
        bad = int(np.flatnonzero(~(np.isfinite(t) & np.all(np.isfinite(state), axis=1)))[0])
        raise GapError(f'{name}: non-finite state sample at index {bad}')
    dt = np.diff(t)
    if np.any(dt < 0):
        i = int(np.flatnonzero(dt < 0)[0]) + 1
        raise GapError(f'{name}: state time stamps go back at sample {i}')
    keep = np.concatenate([[True], dt > 0])
    t, state = t[keep], state[keep]
    notes = list(notes)
    cmds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for ch in CHANNELS:
        if ch not in commands or len(commands[ch][0]) == 0:
            if ch == 'helm':
                cmds[ch] = (np.array([t[0]]), np.array([0.0]))
                notes.append('no helm commands in the log: helm held at 0 rad')
                continue
            raise GapError(f'{name}: no {ch} commands ({COMMAND_TOPICS[ch]}) in the log')
        st = np.asarray(commands[ch][0], dtype=np.float64)
        va = np.asarray(commands[ch][1], dtype=np.float64)
        if not (np.all(np.isfinite(st)) and np.all(np.isfinite(va))):
            raise GapError(f'{name}: non-finite {ch} command')
        order = np.argsort(st, kind='stable')
        cmds[ch] = (st[order], va[order])
        if st.min() > t[0] + 1e-6:
            notes.append(f'{ch}: first command at {st.min() - t[0]:.2f} s after the log starts; '
                         'the first command is assumed before it')
    state = state.copy()
    state[:, 5] = np.unwrap(state[:, 5])
    period = float(np.median(np.diff(t)))
    cuts = np.flatnonzero(np.diff(t) > GAP_SPLIT * period) + 1
    pieces = []
    for k, (a, b) in enumerate(zip(np.r_[0, cuts], np.r_[cuts, t.size])):
        if b - a < 20:
            continue
        tp = t[a:b]
        n = int(np.floor((tp[-1] - tp[0]) / period + 1e-9)) + 1
        grid = tp[0] + period * np.arange(n)
        xs = np.empty((n, 12))
        for i in range(12):
            xs[:, i] = np.interp(grid, tp, state[a:b, i])
        label = name if len(cuts) == 0 else f'{name}#{k}'
        pieces.append(GapLog(label, grid, xs, cmds, tuple(notes)))
    if not pieces:
        raise GapError(f'{name}: no continuous stretch of 20 samples or more')
    return pieces


def load_bag(path: str | os.PathLike[str]) -> list[GapLog]:
    """Read a bag (directory or ``.mcap``) into log pieces (see :func:`from_arrays`)."""
    from auv_bag import bag_topics, read_arrays
    from auv_ident.errors import BagError

    try:
        present = bag_topics(path)
    except BagError as exc:
        raise GapError(str(exc)) from None
    if STATE_TOPIC not in present:
        raise GapError(f'bag {path} has no {STATE_TOPIC} topic')
    topics = [STATE_TOPIC] + [tp for tp in COMMAND_TOPICS.values() if tp in present]
    try:
        arrays = read_arrays(path, topics)
    except BagError as exc:
        raise GapError(str(exc)) from None
    return from_contract_arrays(os.fspath(path), arrays)


def from_contract_arrays(name: str, arrays: Mapping[str, np.ndarray]) -> list[GapLog]:
    """Log pieces from a contract bag's topic arrays (as :func:`auv_bag.read_arrays`
    or :func:`auv_ident.realog.importer.contract_arrays` give them)."""
    st = arrays[STATE_TOPIC]
    state = np.column_stack([st[f] for f in STATE_FIELDS])
    commands = {ch: (arrays[tp]['t'], arrays[tp]['value'])
                for ch, tp in COMMAND_TOPICS.items() if tp in arrays}
    return from_arrays(name, st['t'], state, commands)


@dataclasses.dataclass(frozen=True)
class Smoothed:
    """Savitzky-Golay smoothed state (N x 12), its time derivative (N x 12) [unit/s], and
    the white measurement noise per state (12) estimated from second differences."""

    state: np.ndarray
    rate: np.ndarray
    noise: np.ndarray
    deriv_gain: float   # ||h||_2 of the derivative filter [1/s]: noise std -> derivative std
    smooth_gain: float  # ||h||_2 of the smoothing filter: noise std -> smoothed std
    length: int         # filter length [samples]


def smooth(log: GapLog, window: float = 1.0, order: int = 3) -> Smoothed:
    """Smooth a log with a Savitzky-Golay filter of ``window`` [s] and polynomial ``order``."""
    n = max(order + 2, int(round(window / log.period)) | 1)
    if n % 2 == 0:
        n += 1
    n = min(n, log.t.size - (1 - log.t.size % 2))
    xs = savgol_filter(log.state, n, order, axis=0, mode='interp')
    xd = savgol_filter(log.state, n, order, deriv=1, delta=log.period, axis=0, mode='interp')
    d2 = np.diff(log.state, 2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    noise = 1.4826 * mad / np.sqrt(6.0)
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    hd = savgol_filter(imp, n, order, deriv=1, delta=log.period, mode='interp')
    hs = savgol_filter(imp, n, order, mode='interp')
    return Smoothed(xs, xd, noise, float(np.sqrt(np.sum(hd ** 2))),
                    float(np.sqrt(np.sum(hs ** 2))), n)
