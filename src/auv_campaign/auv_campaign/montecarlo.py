"""Monte Carlo of the closed loop over a user-chosen draw of vehicles, effects and commands.

Run ``i`` of a :class:`Draw` is reproducible on its own: its random numbers come from
``numpy.random.default_rng([seed, i])``, so results do not depend on how runs are chunked
into tasks or on the number of workers. Each run:

* vehicle: every coefficient named in ``spreads`` multiplied by ``1 + rel * N(0, 1)``
  (relative 1-sigma spread); a draw the vehicle file's validation rejects (a wrong sign) is
  a failed run with the reason;
* effects: every field named in ``effects`` uniform in its ``[low, high]`` (SI units, as in
  ``config/effects/*.yaml``);
* command: one depth step from the trim depth ``z0`` [m, NED down] at ``u0`` [m/s] to
  ``z0 +- dz``, ``dz`` uniform in ``step`` [m], sign at random, commanded at t = 0;
* the depth pilot is designed on the *nominal* vehicle (it does not know the draw) and flies
  the drawn one with :func:`auv_depth_lqr.closed_loop.run_closed_loop` (the simulator's RK4
  with its actuator model; the lockstep protocol of the node graph).

The fixed cost of a command (imports, the simulator's compiled kernels, the pilot's design:
several CPU-seconds) is paid once: :func:`nominal_pilot` designs the pilot once per process and
:func:`warm` loads the kernels by flying the draw's first run for a second; the command does
both on the client, then forks the embedded cluster's workers from it (they inherit both), or
on an external cluster scatters the designed pilot to the workers (:func:`run_chunk`'s
``pilot``), whose processes outlive the command and load the kernels once.

Outputs per run: ``settling_time`` [s] (within ``band`` of the target to the end; NaN if
never), ``peak_pitch_deg``, ``final_error`` [m] (``|z(T) - z_target|``), ``tumbled`` (the
state diverged or ``|pitch|`` or ``|roll|`` exceeded ``tumble_angle`` [rad]), ``steps``
(integration steps, for throughput).
"""
from __future__ import annotations

import copy
import dataclasses
import functools
import math
import os
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_campaign.errors import CampaignError


@dataclasses.dataclass(frozen=True)
class Draw:
    """What varies between the runs (see module docstring); SI units, degrees where named."""

    vehicle: str
    runs: int
    seed: int = 0
    duration: float = 120.0
    z0: float = 40.0
    u0: float = 2.0
    spreads: Mapping[str, float] = dataclasses.field(default_factory=dict)
    effects: Mapping[str, Mapping[str, tuple[float, float]]] = dataclasses.field(
        default_factory=dict)
    step: tuple[float, float] = (5.0, 20.0)
    band: float = 0.1
    tumble_angle: float = math.radians(60.0)  # rad

    def check(self) -> None:
        """Raises CampaignError naming the first bad field."""
        from auv_sim.environment import EFFECT_FIELDS
        from auv_sim.params import load_vehicle

        vehicle = load_vehicle(self.vehicle)
        if self.runs < 1:
            raise CampaignError(f'--runs must be >= 1, got {self.runs}')
        for name, value in (('duration', self.duration), ('u0', self.u0), ('band', self.band),
                            ('tumble_angle', self.tumble_angle)):
            if not (math.isfinite(value) and value > 0):
                raise CampaignError(f'{name} must be finite and > 0, got {value}')
        for key, rel in self.spreads.items():
            if key not in vehicle.values:
                raise CampaignError(f'--spread {key}: not a parameter of {self.vehicle}')
            if not (math.isfinite(rel) and rel >= 0):
                raise CampaignError(f'--spread {key}={rel}: must be a finite share >= 0')
        for effect, fields in self.effects.items():
            if effect not in EFFECT_FIELDS:
                raise CampaignError(f'--effect {effect}: unknown effect (known: '
                                    f'{", ".join(EFFECT_FIELDS)})')
            for field, (lo, hi) in fields.items():
                if field not in EFFECT_FIELDS[effect]:
                    raise CampaignError(f'--effect {effect}.{field}: unknown field')
                if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                    raise CampaignError(f'--effect {effect}.{field}: need low <= high')
        lo, hi = self.step
        if not (0 <= lo <= hi) or not vehicle.depth_min <= self.z0 - hi \
                or not self.z0 + hi <= vehicle.depth_max:
            raise CampaignError(f'--step {lo}:{hi} m from z0 = {self.z0} m leaves the depth '
                                f'envelope [{vehicle.depth_min:g}, {vehicle.depth_max:g}] m')


def draw_run(draw: Draw, i: int) -> dict[str, Any]:
    """The random choices of run ``i``: coefficient factors, effect fields, depth step."""
    rng = np.random.default_rng([draw.seed, i])
    factors = {k: 1.0 + rel * float(rng.standard_normal()) for k, rel in
               sorted(draw.spreads.items())}
    effects = {e: {f: float(rng.uniform(lo, hi)) for f, (lo, hi) in sorted(fields.items())}
               for e, fields in sorted(draw.effects.items())}
    dz = float(rng.uniform(*draw.step)) * (1.0 if rng.random() < 0.5 else -1.0)
    return {'run': i, 'factors': factors, 'effects': effects, 'z_target': draw.z0 + dz}


@functools.lru_cache(maxsize=4)
def _nominal_pilot(vehicle: str, _stamp: tuple[int, int]) -> tuple[Any, Any]:
    from auv_depth_lqr.pilot import DepthPilot, PilotSettings
    from auv_sim.params import load_vehicle

    nominal = load_vehicle(vehicle)
    return nominal, DepthPilot.for_vehicle(nominal, PilotSettings())


def nominal_pilot(vehicle: str) -> tuple[Any, Any]:
    """The nominal vehicle and the depth pilot designed on it, designed once per process and
    file version (the file's mtime and size)."""
    st = os.stat(vehicle)
    return _nominal_pilot(vehicle, (st.st_mtime_ns, st.st_size))


def forget_pilots() -> None:
    """Drop the pilots :func:`nominal_pilot` designed (the next call designs again)."""
    _nominal_pilot.cache_clear()


def warm(draw: Draw) -> None:
    """Design the pilot and load the simulator's compiled kernels in this process: the draw's
    first run flown for 1 s (the same code path as the runs)."""
    run_chunk(dataclasses.replace(draw, duration=1.0), [0])


def run_chunk(draw: Draw, runs: Sequence[int], pilot: tuple[Any, Any] | None = None
              ) -> list[dict[str, Any]]:
    """Fly runs ``runs`` of ``draw`` one after the other; one output dict per run.

    ``pilot``: the nominal vehicle and its designed pilot (:func:`nominal_pilot`), when
    designed elsewhere (scattered by the client); designed here otherwise."""
    from auv_depth_lqr.closed_loop import run_closed_loop
    from auv_depth_lqr.errors import AuvLqrError
    from auv_depth_lqr.metrics import step_metrics
    from auv_sim.environment import parse_environment
    from auv_sim.errors import AuvSimError, DivergenceError

    nominal, template = pilot if pilot is not None else nominal_pilot(draw.vehicle)
    settings = template.settings
    tumble = draw.tumble_angle
    out = []
    for i in runs:
        d = draw_run(draw, i)
        rec: dict[str, Any] = {**d, 'status': 'ok', 'reason': None, 'steps': 0}
        t0 = time.perf_counter()
        try:
            vehicle = nominal.replace(**{k: nominal.values[k] * f
                                         for k, f in d['factors'].items()})
            env = parse_environment({'effects': d['effects']}) if d['effects'] else None
            fresh = copy.deepcopy(template)  # a fresh pilot: no state from another run
            run = run_closed_loop(vehicle, [(0.0, d['z_target'])], draw.duration, z0=draw.z0,
                                  u0=draw.u0, environment=env, settings=settings,
                                  pilot=fresh)
        except DivergenceError as exc:
            rec.update(tumbled=True, settling_time=math.nan, peak_pitch_deg=math.nan,
                       final_error=math.nan, reason=str(exc).splitlines()[0],
                       elapsed_s=time.perf_counter() - t0)
            out.append(rec)
            continue
        except (AuvSimError, AuvLqrError, ValueError) as exc:
            # the draw is not a vehicle (validation) or has no trim: a failed run, said so
            rec.update(status='failed', reason=str(exc).splitlines()[0],
                       elapsed_s=time.perf_counter() - t0)
            out.append(rec)
            continue
        r = run.record
        x = r.x
        m = step_metrics(r.t, x[:, 2], x[:, 4], x[:, 10], r.cmd[:, 0], d['z_target'],
                         band=draw.band, bar_max=nominal.bar_max, u0=draw.u0)
        rec.update(settling_time=m.settling_time, peak_pitch_deg=math.degrees(m.peak_pitch),
                   final_error=abs(float(x[-1, 2]) - d['z_target']),
                   tumbled=bool(np.max(np.abs(x[:, 4])) > tumble
                                or np.max(np.abs(x[:, 3])) > tumble),
                   steps=int(round(float(r.t[-1]) / vehicle.dt)),
                   elapsed_s=time.perf_counter() - t0)
        out.append(rec)
    return out


def summarise(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Counts and quantiles (5, 50, 95 %) of the outputs over the runs that flew."""
    flown = [r for r in runs if r['status'] == 'ok']
    out: dict[str, Any] = {
        'runs': len(runs), 'flown': len(flown), 'failed': len(runs) - len(flown),
        'tumbled': sum(1 for r in flown if r.get('tumbled')),
        'not_settled': sum(1 for r in flown if not r.get('tumbled')
                           and not math.isfinite(r['settling_time'])),
        'vehicle_steps': int(sum(r.get('steps', 0) for r in flown)),
    }
    for key in ('settling_time', 'peak_pitch_deg', 'final_error'):
        vals = np.array([r[key] for r in flown if not r.get('tumbled')], dtype=float)
        vals = vals[np.isfinite(vals)]
        out[key] = ({f'p{q}': float(np.percentile(vals, q)) for q in (5, 50, 95)}
                    if vals.size else None)
    return out
