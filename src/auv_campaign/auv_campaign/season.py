"""Stand-ins for a season of real vehicles' logs, as they come: short, slow, quantised, cut off.

Each log is a flight of the simulator (:func:`auv_gap.synth.simulate`: the project's
model with effects the diagnosis is not told, flown by the project's depth pilot with seeded
sensor noise), written the way vendors write logs (:mod:`auv_logs.synth`). The
properties the logs carry (each one a problem a real user met):

* a small AUV from ``auv vehicle-init`` (1.4 m x 0.15 m, 20 kg, scaled from the REMUS 100:
  open-loop unstable, +0.54 1/s at 1.5 m/s) porpoising between the surface and 2-5 m:
  submerged segments of 15-45 s; whitespace text at 2 Hz whose rows alternate 0.39 and 0.61 s
  apart; the DVL updated at 1 Hz (each value on two rows); depth in 0.1 m steps; two
  elevators and two rudders (moving together for roll on one day); thrust as motor rpm; the
  last row cut off mid-line in most logs, a ``nan`` in some; empty logs and logs holding only
  surface data; thruster-off coasts on which the vehicle, 2 N buoyant with its centre of
  gravity 5 mm forward of the file's, rises hanging nose down; a depth sensor that reads
  0.085 m at the surface; the mission's start in the file name or a header comment, the
  time column from 0 (:func:`write_season`);
* a 1.2 m AUV's rosbag2 MCAP bag with three fins in a Y, thrust in per cent, the IMU's header
  stamps all zero, its angular velocity in raw gyro counts, fins on topics without a header,
  a 10 deg fin zero error;
* the A18M, the REMUS 100 and the NPS AUV II with a fin zero error, a buoyancy error, a
  current, a forward centre of gravity (:func:`write_panel`).

Every case says what a hand analysis of its log would find (effect, parameter, sign), so a
benchmark can count what the tools name (``bench/bench_real_season.py``).
"""
from __future__ import annotations

import dataclasses
import datetime
import json
import math
import pathlib
from typing import Any

import numpy as np

from auv_contract import config_path
from auv_contract.jsonout import dumps
from auv_gap import synth
from auv_logs import synth as vendor
from auv_logs.simlog import SensorNoise
from auv_sim.params import VehicleParams, load_vehicle, save_vehicle
from auv_sim.trim import VerticalPlane

#: The season's first mission [s since the epoch]: 2025-04-10 08:00 UTC.
SEASON_START = datetime.datetime(2025, 4, 10, 8, 0, tzinfo=datetime.UTC).timestamp()
#: The small AUV's truth: what its file (``auv vehicle-init``, trimmed neutral) does not know.
SMALL_TRUTH: dict[str, dict[str, float]] = {
    'buoyancy_offset': {'dB': 2.0}, 'cg_offset': {'dxg': 0.005},
    'depth_sensor_bias': {'bias': 0.085}}
#: What a hand analysis of a small-AUV log finds: (effect, parameter, sign), for a log with a
#: coast and one with a surface pass.
COAST_HAND = (('buoyancy_offset', 'dB', 1), ('cg_offset', 'dxg', 1))
SURFACE_HAND = (('depth_sensor_bias', 'bias', 1),)
SPEED = 1.5        # m/s, the small AUV's cruise
SAMPLE = 0.01      # s, the simulation's sample period (rows 0.39 and 0.61 s apart)

def vendor_map(fmt: vendor.VendorText, rate: float | None = 1.0,
               resolution: float | None = 0.1, surface: float = 0.3) -> str:
    """The mapping file that reads the vendor text log ``fmt`` writes: its columns and units,
    the DVL's update ``rate`` [Hz] and the depth ``resolution`` [m] declared when given."""
    depth = ('{column: depth_m, unit: m' if fmt.depth_unit == 'm' else
             '{column: depth_cm, unit: cm') + ', frame: NED' + (
        f', resolution: {resolution:g}' if resolution else '') + '}'
    speed = '{column: speed_ms, unit: m/s, frame: FRD' + (
        f', rate: {rate:g}' if rate else '') + '}'
    return f"""# A vendor's text log: whitespace rows, time from the log's start, depth, roll,
# pitch, heading, the DVL's surge speed, two elevators and two rudders, propeller rpm.
format: auv-log-map/1
kind: text
text: {{delimiter: whitespace, header: true}}
time: {{column: time, unit: s}}
signals:
  z: {depth}
  phi: {{column: roll_deg, unit: deg, frame: NED/FRD}}
  theta: {{column: pitch_deg, unit: deg, frame: NED/FRD}}
  psi: {{column: heading_deg, unit: deg, frame: NED}}
  u: {speed}
  bar:
    unit: deg
    sum:
      - {{column: elev_port_deg, gain: 0.5}}
      - {{column: elev_stbd_deg, gain: -0.5}}
  helm:
    unit: deg
    sum:
      - {{column: rudder_up_deg, gain: 0.5}}
      - {{column: rudder_low_deg, gain: -0.5}}
  thrust: {{column: rpm, unit: rpm, law: {{coefficient: {vendor.K_RPM:g}}}}}
segments: {{surface_depth: {surface:g}, min_duration: 10}}
"""


@dataclasses.dataclass(frozen=True)
class Case:
    """One log (or a season of them) and what should come of it.

    ``vehicle``: the file the tools are given; ``map``: the mapping file (None: a contract
    bag); ``logs``: the log files; ``truth``: the effects the simulated vehicle flew with
    (``{effect: {param: value}}``); ``hand``: what a hand analysis of the log finds,
    ``(effect, parameter, sign)``; ``refusal``: the log should be refused with one line
    containing this text (None: diagnosed); ``properties``: what makes the log hard."""

    name: str
    vehicle: pathlib.Path
    map: pathlib.Path | None
    logs: tuple[pathlib.Path, ...]
    truth: dict[str, dict[str, float]]
    hand: tuple[tuple[str, str, int], ...]
    refusal: str | None
    properties: tuple[str, ...]


def small_auv(out: pathlib.Path, length: float = 1.4, diameter: float = 0.15,
              mass: float = 20.0, name: str = 'small_auv') -> tuple[pathlib.Path, VehicleParams]:
    """The small AUV's vehicle file, as ``auv vehicle-init`` writes it (scaled from the REMUS
    100), its buoyancy set equal to its weight (the user trimmed it neutral); written to
    ``out/<name>.yaml``."""
    from auv_ident.vehicle_init import estimate

    params, _ = estimate(length, diameter, mass, load_vehicle(config_path('remus100.yaml')),
                         name)
    params = params.replace(B=params.W)
    path = out / f'{name}.yaml'
    if not path.exists():
        save_vehicle(params, path)
    return path, load_vehicle(path)


def porpoise(params: VehicleParams, rng: np.random.Generator, dives: int, coasts: bool,
             surface_only: bool = False, speed: float = SPEED) -> synth.Scenario:
    """A porpoising flight: ``dives`` dives from the surface to 2-5 m held for 15-45 s, each
    back at the surface for 15-25 s; with ``coasts``, every other dive ends in a 25-35 s
    thruster-off coast before surfacing. ``surface_only``: 90 s at the surface."""
    thrust = VerticalPlane(params).trim(speed, z=0.5).thrust
    if surface_only:
        return synth.Scenario(duration=90.0, z0=0.0, u0=speed, depth=((0.0, 0.0),),
                              thrust=((0.0, thrust),), doublets=())
    t = 15.0
    depth: list[tuple[float, float]] = [(0.0, 0.0)]
    coast: list[tuple[float, float]] = []
    doublets = []
    for k in range(dives):
        hold = float(rng.uniform(15.0, 45.0))
        depth.append((t, float(rng.uniform(2.0, 5.0))))
        if hold > 25.0:
            doublets.append((t + hold * 0.5, 0.05, 2.0))
        t += hold + 6.0
        if coasts and k % 2 == 0:
            c = float(rng.uniform(25.0, 35.0))
            coast.append((t, t + c))
            t += c
        depth.append((t, 0.0))
        t += float(rng.uniform(15.0, 25.0))
    return synth.Scenario(duration=t, z0=0.0, u0=speed, depth=tuple(depth),
                          thrust=((0.0, thrust),), doublets=tuple(doublets),
                          coasts=tuple(coast))


#: Waves at the surface: the depth reading's spread while afloat [m] (assumed).
WAVES = 0.01


def float_at_surface(log: synth.SyntheticLog, sc: synth.Scenario, zero: float,
                     rng: np.random.Generator) -> None:
    """The rows at the surface of a porpoising flight as a floating vehicle logs them: the
    simulator has no free surface (its pilot holds the commanded 0 m, a little above or
    below), so while the depth command is 0 m and the true depth within 0.3 m of it, the
    measured depth is the depth sensor's reading afloat, its zero ``zero`` [m] plus
    :data:`WAVES` of waves (in place)."""
    t = log.t
    cmd = np.array([synth.held(sc.depth, float(tk)) for tk in t])
    afloat = (cmd == 0.0) & (np.abs(log.true_state[:, 2]) < 0.3)
    log.record.measured[afloat, 2] = zero + WAVES * rng.standard_normal(int(afloat.sum()))


def _stamp_name(start: float) -> str:
    d = datetime.datetime.fromtimestamp(start, datetime.UTC)
    return d.strftime('dive_%Y-%m-%d_%H-%M-%S')


def write_season(out: str | pathlib.Path, count: int = 26, seed: int = 0) -> Case:
    """The small AUV's season of ``count`` vendor text logs in ``out`` (see the module
    docstring): the vehicle file, the map and the logs, as one :class:`Case`. Of 26 logs,
    3 are empty, 5 hold surface data only, 11 of the 18 flights have thruster-off coasts, 15
    logs end in a row cut mid-line, 3 have a ``nan``; logs of the third day move the rudders
    together for roll; 4 logs carry their start in a header comment, the others in their
    name."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    vehicle_path, params = small_auv(out)
    (out / 'small_auv_map.yaml').write_text(vendor_map(vendor.VendorText(depth_unit='m')))
    rng = np.random.default_rng(seed)
    empty = {5 % count, 13 % count, 21 % count}
    surface = {2, 9, 16, 19, 24} - empty
    flights = [i for i in range(count) if i not in empty | surface]
    coasted = set(flights[::2][:11]) | set(flights[1::2][:max(0, 11 - len(flights[::2]))])
    cut = set(list(range(count))[1::2][:15]) - empty
    logs = []
    kinds: dict[str, str] = {}
    noise = SensorNoise.realistic()
    for i in range(count):
        start = SEASON_START + 86400.0 * (i // 4) + 3600.0 * (i % 4) + 17.0 * i
        named = i % 7 != 3           # a few logs state their start in a comment instead
        name = _stamp_name(start) if named else f'log{i:02d}'
        path = out / f'{name}.txt'
        logs.append(path)
        kinds[path.name] = ('empty' if i in empty else 'surface' if i in surface else
                            'coast' if i in coasted else 'flight')
        if i in empty:
            header = ' '.join(vendor.VendorText(depth_unit='m').columns())
            path.write_text(['', header + '\n', f'# empty log\n{header}\n'][sorted(empty)
                                                                             .index(i)])
            continue
        sc = porpoise(params, rng, dives=int(rng.integers(3, 6)), coasts=i in coasted,
                      surface_only=i in surface)
        log = synth.simulate(params, {'effects': SMALL_TRUTH}, sc, seed=seed * 1000 + i,
                             noise=noise, sample_period=SAMPLE)
        float_at_surface(log, sc, SMALL_TRUTH['depth_sensor_bias']['bias'], rng)
        fmt = vendor.VendorText(
            steps=(0.39, 0.61), depth_unit='m', depth_resolution=0.1, speed_period=1.0,
            cut_last_row=i in cut, nan_rows=(40 + i,) if i % 8 == 1 else (),
            roll_rudders=math.radians(5.0) if i // 4 == 2 else 0.0)
        vendor.write_vendor_text(path, log.record, fmt)
        if not named:
            text = path.read_text()
            iso = datetime.datetime.fromtimestamp(start, datetime.UTC).isoformat()
            path.write_text(f'# vendor logger v2.3, start {iso}\n' + text)
    (out / 'season.json').write_text(dumps(kinds, indent=1) + '\n')
    return Case('small_auv_season', vehicle_path, out / 'small_auv_map.yaml', tuple(logs),
                SMALL_TRUTH, COAST_HAND + SURFACE_HAND, None,
                ('jittered 2 Hz rows (0.39/0.61 s)', '1 Hz DVL repeated on rows',
                 'depth in 0.1 m steps', 'porpoising 15-45 s segments', 'cut-off rows',
                 'nan values', 'empty logs', 'surface-only logs',
                 'prop-off ascents hanging nose down', 'a forward CG', 'two elevators',
                 'rudders moving together for roll', 'thrust as rpm',
                 'start in file name or header'))


def season_expectations(case: Case) -> dict[str, dict[str, Any]]:
    """Per log of a season (``season.json`` beside the logs, written with them):
    ``refusal`` (a text the one-line refusal contains, or None) and ``hand`` (what a hand
    analysis of that log finds: a coast gives buoyancy and the centre of gravity, a surface
    pass the depth zero)."""
    kinds = json.loads((case.logs[0].parent / 'season.json').read_text())
    out: dict[str, dict[str, Any]] = {}
    for name, kind in kinds.items():
        if kind == 'empty':
            out[name] = {'refusal': 'no data rows', 'hand': ()}
        elif kind == 'surface':
            out[name] = {'refusal': 'no usable segment', 'hand': ()}
        else:
            out[name] = {'refusal': None,
                         'hand': (COAST_HAND if kind == 'coast' else ()) + SURFACE_HAND}
    return out


YBAG_MAP = """# A 1.2 m AUV's MCAP bag: IMU (ENU/FLU; its header stamps are zero, so its receive
# times; its angular velocity in raw gyro counts, 131 per deg/s), pressure depth, a DVL,
# three fins in a Y on Float64 topics (no header: receive times), thrust in per cent of 10 N.
format: auv-log-map/1
kind: bag
time: {stamp: header, stamps: {/imu/data: log}, base: /pressure, max_age: 0.15}
sources:
  - {preset: imu, topic: /imu/data, frame: ENU/FLU, use: [orientation]}
  - {preset: fluid_pressure, topic: /pressure, density: 1025, surface_pressure: 101325}
  - {preset: dvl_twist_stamped, topic: /dvl/twist, frame: ENU/FLU, rate: 5}
vectors:
  - kind: angular_velocity
    topic: /imu/data
    fields: [angular_velocity.x, angular_velocity.y, angular_velocity.z]
    frame: ENU/FLU
    unit: deg/s
    scale: SCALE
signals:
  bar:
    unit: deg
    sum:
      - {topic: /fins/port, field: data, gain: 0.4330127018922193}
      - {topic: /fins/stbd, field: data, gain: 0.4330127018922193}
  helm: {topic: /fins/top, field: data, unit: deg}
  thrust: {topic: /thruster/percent, field: data, unit: percent, full_scale: 10}
segments: {surface_depth: 0.3, min_duration: 10}
"""
#: The 1.2 m AUV's truth: a 10 deg fin zero error (a nose-down moment at speed), a little
#: positive buoyancy, a depth sensor reading 0.085 m at the surface.
YBAG_TRUTH: dict[str, dict[str, float]] = {
    'bar_bias': {'bias': math.radians(10.0)}, 'buoyancy_offset': {'dB': 0.4},
    'depth_sensor_bias': {'bias': 0.085}}


def write_panel(out: str | pathlib.Path, seed: int = 0) -> list[Case]:
    """The cases beyond the small AUV's season (see the module docstring), written to
    ``out``."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed + 7)
    noise = SensorNoise.realistic()
    cases = []
    # the 1.2 m AUV, Y fins, MCAP: three maps (zero stamps, raw counts, right)
    ypath, yparams = small_auv(out, 1.2, 0.12, 11.0, 'y_auv')
    sc = porpoise(yparams, rng, dives=4, coasts=True, speed=1.0)
    log = synth.simulate(yparams, {'effects': YBAG_TRUTH}, sc, seed=seed + 11, noise=noise)
    float_at_surface(log, sc, YBAG_TRUTH['depth_sensor_bias']['bias'], rng)
    bag = out / 'y_auv_bag'
    if not bag.exists():
        vendor.write_ybag(bag, log.record, t0=SEASON_START + 40 * 86400.0,
                          thrust_full_scale=10.0)
    right = YBAG_MAP.replace('SCALE', repr(1.0 / vendor.GYRO_COUNTS_PER_DEG_S))
    counts = YBAG_MAP.replace('unit: deg/s\n    scale: SCALE', 'unit: rad/s')
    stamped = right.replace('stamps: {/imu/data: log}, ', '')
    for name, text, refusal in (('y_auv_header_stamps', stamped, 'header stamps are zero'),
                                ('y_auv_raw_counts', counts, 'raw sensor counts'),
                                ('y_auv', right, None)):
        (out / f'{name}_map.yaml').write_text(text)
        cases.append(Case(name, ypath, out / f'{name}_map.yaml', (bag,), YBAG_TRUTH,
                          (('bar_bias', 'bias', 1), ('depth_sensor_bias', 'bias', 1),
                           ('buoyancy_offset', 'dB', 1)) if refusal is None else (),
                          refusal, ('MCAP bag', 'three fins in a Y', 'thrust as percent',
                                    'zero-stamped IMU headers', 'unstamped fin topics',
                                    'raw gyro counts', 'a 10 deg fin zero error',
                                    'prop-off ascent', 'surface passes')))
    jitter = vendor.VendorText(steps=(0.39, 0.61), depth_unit='cm', speed_period=1.0,
                               cut_last_row=True)
    text_map = out / 'vendor_2hz_map.yaml'
    text_map.write_text(vendor_map(jitter, resolution=None))
    a18m = config_path('a18m.yaml')
    flights = (
        ('a18m_fin_zero', a18m, {'bar_bias': {'bias': math.radians(10.0)}},
         (('bar_bias', 'bias', 1),), ('2 Hz jittered text', 'a 10 deg fin zero error')),
        ('a18m_buoyancy', a18m, {'buoyancy_offset': {'dB': 30.0}},
         (('buoyancy_offset', 'dB', 1),), ('2 Hz jittered text', 'a buoyancy error')),
        ('remus100_current', config_path('remus100.yaml'),
         {'current': {'north': 0.3, 'east': 0.0, 'down': 0.0}},
         (('current', 'north', 1),), ('2 Hz jittered text', 'open-loop unstable vehicle')),
    )
    for name, vfile, truth, hand, props in flights:
        params = load_vehicle(vfile)
        speed = 1.5 if 'remus' in name else 2.0
        sc = synth.Scenario(
            duration=300.0, z0=20.0, u0=speed,
            depth=((0.0, 20.0), (60.0, 30.0), (160.0, 22.0), (240.0, 28.0)),
            thrust=((0.0, VerticalPlane(params).trim(speed, z=20.0).thrust),
                    (120.0, VerticalPlane(params).trim(1.25 * speed, z=20.0).thrust),
                    (200.0, VerticalPlane(params).trim(0.8 * speed, z=20.0).thrust)),
            doublets=((30.0, 0.06, 3.0), (100.0, 0.08, 2.0), (180.0, 0.05, 5.0),
                      (260.0, 0.08, 3.0)))
        log = synth.simulate(params, {'effects': truth}, sc, seed=seed + len(cases),
                             noise=noise, sample_period=SAMPLE)
        path = out / f'{name}.txt'
        vendor.write_vendor_text(path, log.record, jitter)
        cases.append(Case(name, vfile, text_map, (path,), truth, hand, None, props))
    # NPS AUV II: coasts reveal a forward centre of gravity and positive buoyancy
    nps = config_path('npsauv2.yaml')
    params = load_vehicle(nps)
    truth = {'cg_offset': {'dxg': 0.03}, 'buoyancy_offset': {'dB': 0.004 * params.W}}
    thrust = VerticalPlane(params).trim(1.5, z=15.0).thrust
    sc = synth.Scenario(duration=420.0, z0=15.0, u0=1.5,
                        depth=((0.0, 15.0), (60.0, 25.0), (230.0, 15.0), (300.0, 20.0)),
                        thrust=((0.0, thrust),), doublets=((30.0, 0.06, 3.0), (260.0, 0.05, 4.0)),
                        coasts=((140.0, 200.0), (340.0, 400.0)))
    log = synth.simulate(params, {'effects': truth}, sc, seed=seed + 31, noise=noise,
                         sample_period=SAMPLE)
    path = out / 'npsauv2_coasts.txt'
    vendor.write_vendor_text(path, log.record, jitter)
    cases.append(Case('npsauv2_coasts', nps, text_map, (path,), truth,
                      (('buoyancy_offset', 'dB', 1), ('cg_offset', 'dxg', 1)), None,
                      ('2 Hz jittered text', 'prop-off coasts', 'a forward CG')))
    return cases


def named(report: dict[str, Any], effect: str, param: str) -> float | None:
    """The value a gap report names for ``effect.param``: a significant finding of the
    quiet stretches, or the named best candidate's value (verdict ``explained``,
    ``partly_explained`` or ``ambiguous``), or, with ``ambiguous``, a rival's that the
    statement names; None when it names none."""
    for f in report.get('findings') or []:
        if f['effect'] == effect and f['param'] == param and f['significant']:
            return float(f['value'])
    best = report.get('best')
    if not best or report.get('verdict') not in ('explained', 'partly_explained', 'ambiguous'):
        return None
    labels = [best] + [c['effect'] for c in report['candidates']
                       if report['verdict'] == 'ambiguous'
                       and set(c['effect'].split('+')) & set(report['ambiguous_with'])]
    for label in labels:
        if effect not in label.split('+') or label.split('+')[0] not in report['statement']:
            continue
        entry = next(c for c in report['candidates'] if c['effect'] == label)
        key = param if '+' not in label else f'{effect}.{param}'
        if key in entry['params']:
            return float(entry['params'][key])
    return None


def wrong_claims(report: dict[str, Any], truth: dict[str, dict[str, float]]) -> list[str]:
    """Confident wrong answers of a gap report against the ``truth``: ``explained`` naming an
    effect not in the truth or a value of the wrong sign; a significant quiet-stretch finding
    of an effect not in the truth or of the wrong sign."""
    out = []
    if report.get('verdict') == 'explained' and report.get('best'):
        for e in str(report['best']).split('+'):
            if e not in truth and e != 'coefficients':
                out.append(f'explained by {e}, not in the truth')
    for f in report.get('findings') or []:
        if not f['significant']:
            continue
        true = truth.get(f['effect'], {}).get(f['param'])
        if true is None or true == 0.0:
            out.append(f'finding {f["effect"]}.{f["param"]} = {f["value"]:.3g}, not in the '
                       'truth')
        elif np.sign(true) != np.sign(f['value']):
            out.append(f'finding {f["effect"]}.{f["param"]} of the wrong sign')
    return out


def all_cases(out: str | pathlib.Path, seed: int = 0, season_logs: int = 26
              ) -> tuple[Case, list[Case]]:
    """The season and the panel, written under ``out/season`` and ``out/panel``."""
    out = pathlib.Path(out)
    return (write_season(out / 'season', season_logs, seed),
            write_panel(out / 'panel', seed))


__all__ = ['Case', 'all_cases', 'named', 'porpoise', 'season_expectations', 'small_auv',
           'write_panel', 'write_season', 'wrong_claims']
