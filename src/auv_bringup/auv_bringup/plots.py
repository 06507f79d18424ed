"""The report's result plots (figures 10-15) of a depth manoeuvre, from logged arrays.

Inputs are the arrays of a bag or an offline run: time [s], NED position [m], Euler angles
[rad], body FRD velocities [m/s, rad/s], dive-plane angle [rad]. Degrees only on the plots.
"""
from __future__ import annotations

import pathlib
from collections.abc import Mapping

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure


def plot_depth_run(state: Mapping[str, np.ndarray], bar_t: np.ndarray, bar: np.ndarray,
                   out_dir: str | pathlib.Path, z_ref_t: np.ndarray | None = None,
                   z_ref: np.ndarray | None = None, title: str = '') -> list[pathlib.Path]:
    """Write depth, XY track, Euler angles, linear speeds, angular speeds and BAR plots.

    ``state`` maps ``t, x, y, z, phi, theta, psi, u, v, w, p, q, r`` to arrays. Returns the
    PNG paths (``fig10_depth.png`` ... ``fig15_bar.png``).
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = state['t'] - state['t'][0]
    t0 = state['t'][0]
    paths = []

    def save(fig: Figure, name: str) -> None:
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)

    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t, state['z'], label='depth z')
    if z_ref is not None and z_ref_t is not None and len(z_ref):
        ax.step(np.concatenate([z_ref_t - t0, [t[-1]]]), np.concatenate([z_ref, [z_ref[-1]]]),
                where='post', ls='--', label='depth command')
    ax.invert_yaxis()
    ax.set(xlabel='time [s]', ylabel='depth [m] (down)', title=f'Depth profile {title}')
    ax.grid(True)
    ax.legend()
    save(fig, 'fig10_depth.png')

    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(state['y'], state['x'])
    ax.set(xlabel='east y [m]', ylabel='north x [m]', title='XY track (NED, seen from above)')
    ax.axis('equal')
    ax.grid(True)
    save(fig, 'fig11_xy.png')

    def three_panels(keys: tuple[str, str, str], labels: tuple[str, str, str], unit: str,
                     degrees: bool, title: str, name: str) -> None:
        fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True)
        for ax, key, label in zip(axes, keys, labels):
            ax.plot(t, np.degrees(state[key]) if degrees else state[key])
            ax.set(ylabel=f'{label} [{unit}]')
            ax.grid(True)
        axes[-1].set(xlabel='time [s]')
        axes[0].set(title=title)
        save(fig, name)

    three_panels(('phi', 'theta', 'psi'), ('roll', 'pitch', 'yaw'), 'deg', True,
                 'Euler angles (ZYX)', 'fig12_euler.png')
    three_panels(('u', 'v', 'w'), ('u', 'v', 'w'), 'm/s', False, 'Linear speeds (body FRD)',
                 'fig13_linear_speed.png')
    three_panels(('p', 'q', 'r'), ('p', 'q', 'r'), 'deg/s', True, 'Angular speeds (body FRD)',
                 'fig14_angular_speed.png')

    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.step(bar_t - t0, np.degrees(bar), where='post')
    ax.set(xlabel='time [s]', ylabel='BAR [deg]', title='Dive plane (BAR) command')
    ax.grid(True)
    save(fig, 'fig15_bar.png')
    return paths
