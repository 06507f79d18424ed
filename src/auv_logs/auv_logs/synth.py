"""Third-party-style logs written from a simulated run (for tests, examples and benchmarks).

The simulator's measured state (NED/FRD, :class:`auv_sim.simulator.Record`) and applied
commands are written the way other vehicles log them, with rosbags' own writers (not this
project's :class:`auv_bag.BagWriter`):

* :func:`write_ros2` -- a rosbag2 bag (``mcap`` or ``sqlite3`` storage) or, with
  ``ros1=True``, a ROS 1 bag: ``nav_msgs/Odometry`` on ``/odom`` (REP-105: pose ENU, twist
  FLU), ``sensor_msgs/Imu`` on ``/imu/data`` (orientation ENU/FLU, rates FLU),
  ``sensor_msgs/FluidPressure`` on ``/pressure`` (Pa, ``P = p0 + rho g z``), the fins and the
  propeller as ``std_msgs/Float64`` (``/fins/port``, ``/fins/starboard`` elevators and
  ``/fins/rudder`` in degrees, ``/thruster/rpm``) or, with ``custom_fins=True``, one vendor
  message ``lab_msgs/msg/FinAngles`` (``port_elevator``, ``starboard_elevator``,
  ``upper_rudder``, ``lower_rudder`` [deg]) whose definition travels in the bag.
* :func:`write_text` -- a whitespace text log with a header line: time [s], depth [cm],
  roll, pitch, heading (0-360) [deg], surge speed [cm/s], two elevators and a rudder [deg],
  propeller speed [rpm].

Fin conventions of these "vendors": the port elevator logs the BAR angle, the starboard
elevator its negative (mirrored servo), the rudder (and the upper rudder) the helm angle, the
lower rudder its negative. Propeller speed from thrust by ``T = k n |n|`` (``k`` N/(rev/s)^2).
"""
from __future__ import annotations

import dataclasses
import math
import os
import pathlib
from typing import Any

import numpy as np

from auv_sim.frames import state_to_odometry
from auv_sim.simulator import Record

#: Vendor fin message (ROS 2 .msg text), registered from its definition.
FIN_MSG = """std_msgs/Header header
float64 port_elevator     # deg, positive = BAR
float64 starboard_elevator  # deg, positive = -BAR (mirrored)
float64 upper_rudder      # deg, positive = helm
float64 lower_rudder      # deg, positive = -helm
"""
FIN_TYPE = 'lab_msgs/msg/FinAngles'
RHO = 1025.0      # kg/m^3, sea water (assumed)
P0 = 101325.0     # Pa, standard atmosphere at the surface
G = 9.80665       # m/s^2
#: Thrust law of the synthetic propeller: T = K_RPM n |n|, n [rev/s] (assumed).
K_RPM = 0.05


def rpm_of_thrust(thrust: np.ndarray) -> np.ndarray:
    """Propeller speed [rpm] giving ``thrust`` [N] by ``T = K_RPM n |n|``."""
    t = np.asarray(thrust, float)
    out: np.ndarray = 60.0 * np.sign(t) * np.sqrt(np.abs(t) / K_RPM)
    return out


def _state(rec: Record, noise: np.ndarray | None) -> np.ndarray:
    meas = rec.measured[:, :12].copy()
    if noise is not None:
        meas += noise
    return meas


def _imu_and_pressure(T: Any, t: float, imu_header: Any, pressure_header: Any, q: np.ndarray,
                      rates: np.ndarray, depth: float) -> list[tuple[float, str, str, Any]]:
    """The ``sensor_msgs/Imu`` (orientation ``q`` x y z w, angular velocity ``rates`` as
    given) and ``sensor_msgs/FluidPressure`` (``P0 + rho g depth`` [Pa]) events of one sample
    at ``t`` [s]; ``T`` the typestore's types."""
    V3, cov9 = T['geometry_msgs/msg/Vector3'], np.zeros(9)
    return [
        (t, '/imu/data', 'sensor_msgs/msg/Imu', T['sensor_msgs/msg/Imu'](
            header=imu_header,
            orientation=T['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3]),
            orientation_covariance=cov9,
            angular_velocity=V3(x=rates[0], y=rates[1], z=rates[2]),
            angular_velocity_covariance=cov9,
            linear_acceleration=V3(x=0.0, y=0.0, z=0.0), linear_acceleration_covariance=cov9)),
        (t, '/pressure', 'sensor_msgs/msg/FluidPressure', T['sensor_msgs/msg/FluidPressure'](
            header=pressure_header, fluid_pressure=P0 + RHO * G * depth, variance=0.0))]


def write_ros2(path: str | os.PathLike[str], rec: Record, *, storage: str = 'mcap',
               ros1: bool = False, every: int = 1, custom_fins: bool = False,
               noise: np.ndarray | None = None, t0: float = 1.7e9) -> int:
    """Write ``rec`` as a third-party bag (see the module docstring); returns messages written.

    ``every`` keeps every n-th state sample (rate = sample rate / every); ``noise`` (N x 12)
    is added to the measured state; stamps are ``t0 + t`` [s] (an epoch-like clock).
    """
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.LATEST)
    store.register(get_types_from_msg(FIN_MSG, FIN_TYPE))
    T = store.types
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    Odometry = T['nav_msgs/msg/Odometry']
    V3, Q, Pt = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion'], \
        T['geometry_msgs/msg/Point']
    Pose, PoseC = T['geometry_msgs/msg/Pose'], T['geometry_msgs/msg/PoseWithCovariance']
    Twist, TwistC = T['geometry_msgs/msg/Twist'], T['geometry_msgs/msg/TwistWithCovariance']
    F64, Fins = T['std_msgs/msg/Float64'], T[FIN_TYPE]
    cov36 = np.zeros(36)
    meas = _state(rec, noise)
    idx = np.arange(0, len(rec.t), every)
    odom = state_to_odometry(meas[idx])

    def header(t: float, frame: str) -> Any:
        ns = int(round((t0 + t) * 1e9))
        kw = {'seq': 0} if ros1 else {}
        return Header(**kw, stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    events: list[tuple[float, str, str, Any]] = []
    for k, i in enumerate(idx):
        t = float(rec.t[i])
        pos, q, lin, ang = (odom.position[k], odom.orientation[k], odom.linear[k],
                            odom.angular[k])
        quat = Q(x=q[0], y=q[1], z=q[2], w=q[3])
        events.append((t, '/odom', 'nav_msgs/msg/Odometry', Odometry(
            header=header(t, 'odom'), child_frame_id='base_link',
            pose=PoseC(pose=Pose(position=Pt(x=pos[0], y=pos[1], z=pos[2]), orientation=quat),
                       covariance=cov36),
            twist=TwistC(twist=Twist(linear=V3(x=lin[0], y=lin[1], z=lin[2]),
                                     angular=V3(x=ang[0], y=ang[1], z=ang[2])),
                         covariance=cov36))))
        events += _imu_and_pressure(T, t, header(t, 'imu_link'), header(t, 'pressure'), q,
                                    ang, float(meas[i, 2]))
    change = np.flatnonzero(np.any(np.diff(rec.cmd, axis=0, prepend=np.nan) != 0, axis=1))
    for i in change:
        t = float(rec.t[i])
        bar, helm, thrust = (float(v) for v in rec.cmd[i])
        bd, hd = math.degrees(bar), math.degrees(helm)
        if custom_fins:
            events.append((t, '/fins', FIN_TYPE, Fins(
                header=header(t, 'fins'), port_elevator=bd, starboard_elevator=-bd,
                upper_rudder=hd, lower_rudder=-hd)))
        else:
            events.append((t, '/fins/port', 'std_msgs/msg/Float64', F64(data=bd)))
            events.append((t, '/fins/starboard', 'std_msgs/msg/Float64', F64(data=-bd)))
            events.append((t, '/fins/rudder', 'std_msgs/msg/Float64', F64(data=hd)))
        events.append((t, '/thruster/rpm', 'std_msgs/msg/Float64',
                       F64(data=float(rpm_of_thrust(np.array(thrust))))))
    events.sort(key=lambda e: e[0])
    p = pathlib.Path(path)
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        with Writer1(p) as w1:
            conns1: dict[str, Any] = {}
            for t, topic, msgtype, msg in events:
                if topic not in conns1:
                    conns1[topic] = w1.add_connection(topic, msgtype, typestore=store)
                w1.write(conns1[topic], int(round((t0 + t) * 1e9)),
                         store.serialize_ros1(msg, msgtype))
        return len(events)
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    with Writer(p, version=9, storage_plugin=plugin) as w2:
        conns2: dict[str, Any] = {}
        for t, topic, msgtype, msg in events:
            if topic not in conns2:
                conns2[topic] = w2.add_connection(topic, msgtype, typestore=store)
            w2.write(conns2[topic], int(round((t0 + t) * 1e9)), store.serialize_cdr(msg, msgtype))
    return len(events)


TEXT_COLUMNS = ('time', 'depth_cm', 'roll_deg', 'pitch_deg', 'heading_deg', 'speed_cms',
                'elev_port_deg', 'elev_stbd_deg', 'rudder_deg', 'rpm')


def write_text(path: str | os.PathLike[str], rec: Record, *, every: int = 25,
               noise: np.ndarray | None = None, rows: np.ndarray | None = None) -> int:
    """Write ``rec`` as a vendor text log (whitespace, header) every ``every`` samples (or
    at the sample indices ``rows``: irregular logging); returns the rows written. Commands are
    the ones applied at each row's time."""
    meas = _state(rec, noise)
    idx = np.arange(0, len(rec.t), every) if rows is None else np.asarray(rows)
    lines = [' '.join(TEXT_COLUMNS)]
    for i in idx:
        bar, helm, thrust = rec.cmd[i]
        vals = (rec.t[i], 100.0 * meas[i, 2], math.degrees(meas[i, 3]),
                math.degrees(meas[i, 4]), math.degrees(meas[i, 5]) % 360.0, 100.0 * meas[i, 6],
                math.degrees(bar), -math.degrees(bar), math.degrees(helm),
                float(rpm_of_thrust(np.array(thrust))))
        lines.append(' '.join(f'{v:.10g}' for v in vals))
    pathlib.Path(path).write_text('\n'.join(lines) + '\n')
    return len(idx)


def record_of(t: np.ndarray, state: np.ndarray,
              commands: dict[str, tuple[np.ndarray, np.ndarray]]) -> Record:
    """A :class:`Record` of a logged run given as arrays (e.g. a
    :class:`auv_gap.synth.SyntheticLog`): stamps ``t`` [s] (N), measured state
    ``state`` (N x 12, NED/FRD), and per channel ``bar helm thrust`` the commands as sent
    ``(stamps [s], values [rad or N])``, held until the next (the applied command at each
    sample is the latest at or before it; before the first, the first). The true state and
    the wrenches are not known: NaN. Feeds :func:`write_text` and :func:`write_ros2`."""
    n = len(t)
    cmd = np.empty((n, 3))
    for c, ch in enumerate(('bar', 'helm', 'thrust')):
        st, va = commands[ch]
        i = np.searchsorted(np.asarray(st), t + 1e-9, side='right') - 1
        cmd[:, c] = np.asarray(va)[np.clip(i, 0, len(va) - 1)]
    measured = np.full((n, 15), np.nan)
    measured[:, :12] = state
    return Record(np.asarray(t, float), np.full((n, 15), np.nan), measured, cmd,
                  np.full((n, 4, 6), np.nan))


# --------------------------------------------------------------------------------------------
# a vendor's text log as real loggers write them

@dataclasses.dataclass(frozen=True)
class VendorText:
    """How a vendor's text logger writes a flight (see :func:`write_vendor_text`).

    ``steps``: the row spacing [s], a pattern repeated over the log (``(0.39, 0.61)``: rows
    alternating 0.39 and 0.61 s apart, 2 Hz on average); ``depth_unit`` ``m`` or ``cm`` and
    ``depth_resolution`` [m] (0.1: depth printed in 0.1 m steps; 0: full precision);
    ``speed_period`` [s]: the DVL's update period (1.0 on 2 Hz rows: each value on two rows;
    0: a new value on every row); ``thrust`` ``rpm`` (``T = K_RPM n |n|``) or ``percent``
    (of ``thrust_full_scale`` [N]); ``fins`` ``pair`` (port and starboard elevators, the
    starboard mirrored, an upper and a lower rudder, the lower mirrored) or ``y`` (a top
    rudder and two lower fins at +-120 deg from the top, each deflected by ``bar /
    cos(30 deg)`` so that their vertical forces sum to a pair's); ``roll_rudders`` [rad]: the
    two rudders also move together (not mirrored) by this amplitude, a roll command that
    cancels in the helm; ``cut_last_row``: the last row stops mid-line (a logger switched off
    while writing); ``nan_rows``: row indices whose speed field reads ``nan``; ``t0`` [s]:
    the clock at the first sample (an epoch time, or 0 for a log timed from its start).
    """

    steps: tuple[float, ...] = (0.5,)
    depth_unit: str = 'cm'
    depth_resolution: float = 0.0
    speed_period: float = 0.0
    thrust: str = 'rpm'
    thrust_full_scale: float = 0.0
    fins: str = 'pair'
    roll_rudders: float = 0.0
    cut_last_row: bool = False
    nan_rows: tuple[int, ...] = ()
    t0: float = 0.0

    def columns(self) -> tuple[str, ...]:
        """The header line's column names."""
        depth = 'depth_m' if self.depth_unit == 'm' else 'depth_cm'
        fins = (('fin_top_deg', 'fin_port_deg', 'fin_stbd_deg') if self.fins == 'y' else
                ('elev_port_deg', 'elev_stbd_deg', 'rudder_up_deg', 'rudder_low_deg'))
        thrust = 'thrust_pct' if self.thrust == 'percent' else 'rpm'
        return ('time', depth, 'roll_deg', 'pitch_deg', 'heading_deg', 'speed_ms', *fins,
                thrust)


#: Cosine of the angle between a lower fin of a Y (at 120 deg from the top) and the
#: horizontal: the share of its lift that acts vertically.
COS_30 = math.cos(math.radians(30.0))


def vendor_rows(t: np.ndarray, steps: tuple[float, ...]) -> np.ndarray:
    """Indices into sample times ``t`` [s] (uniform) of rows spaced by the repeated pattern
    ``steps`` [s] from ``t[0]`` (each row at the sample nearest its time)."""
    dt = float(t[1] - t[0])
    span = float(t[-1] - t[0])
    pattern = np.asarray(steps, float)
    n = int(span / pattern.mean()) + len(pattern) + 1
    times = np.r_[0.0, np.cumsum(np.resize(pattern, n))]
    times = times[times <= span + 1e-9]
    out: np.ndarray = np.unique(np.clip(np.round(times / dt).astype(np.int64), 0, t.size - 1))
    return out


def write_vendor_text(path: str | os.PathLike[str], rec: Record, fmt: VendorText,
                      noise: np.ndarray | None = None) -> int:
    """Write ``rec`` as the vendor text log ``fmt`` describes (whitespace, header line; the
    measured state plus ``noise`` (N x 12) at the rows, the commands applied at each row);
    returns the rows written (a cut-off last row included)."""
    meas = _state(rec, noise)
    rows = vendor_rows(rec.t, fmt.steps)
    # the DVL's value at each row: its latest update at or before the row
    if fmt.speed_period > 0.0:
        k = np.floor((rec.t[rows] - rec.t[0]) / fmt.speed_period + 1e-9)
        first = np.r_[True, np.diff(k) > 0]
        src = rows[np.maximum.accumulate(np.where(first, np.arange(rows.size), 0))]
        speed_rows = meas[src, 6]
    else:
        speed_rows = meas[rows, 6]
    depth = meas[rows, 2]
    if fmt.depth_resolution > 0.0:
        depth = np.round(depth / fmt.depth_resolution) * fmt.depth_resolution
    depth = depth * (100.0 if fmt.depth_unit == 'cm' else 1.0)
    lines = [' '.join(fmt.columns())]
    for j, i in enumerate(rows):
        bar, helm, thrust = rec.cmd[i]
        bd, hd = math.degrees(bar), math.degrees(helm)
        roll = math.degrees(fmt.roll_rudders) * math.sin(2 * math.pi * rec.t[i] / 20.0)
        if fmt.fins == 'y':
            fins: tuple[float, ...] = (hd, bd / COS_30, bd / COS_30)
        else:
            fins = (bd, -bd, hd + roll, -hd + roll)
        thr = (100.0 * thrust / fmt.thrust_full_scale if fmt.thrust == 'percent'
               else float(rpm_of_thrust(np.array(thrust))))
        vals = (fmt.t0 + rec.t[i], depth[j], math.degrees(meas[i, 3]),
                math.degrees(meas[i, 4]), math.degrees(meas[i, 5]) % 360.0, speed_rows[j],
                *fins, thr)
        text = [f'{vals[0]:.3f}', *(f'{v:.10g}' for v in vals[1:])]
        if fmt.depth_resolution > 0.0:
            digits = max(0, -int(math.floor(math.log10(fmt.depth_resolution * (
                100.0 if fmt.depth_unit == 'cm' else 1.0)) + 1e-9)))
            text[1] = f'{vals[1]:.{digits}f}'
        if j in fmt.nan_rows:
            text[5] = 'nan'
        lines.append(' '.join(text))
    if fmt.cut_last_row and len(lines) > 2:
        lines[-1] = lines[-1][:len(lines[-1]) // 2].rstrip()
    text_out = '\n'.join(lines) + ('' if fmt.cut_last_row else '\n')
    pathlib.Path(path).write_text(text_out)
    return len(rows)


#: Raw counts of a MEMS gyro per deg/s (the +-250 deg/s range of common parts).
GYRO_COUNTS_PER_DEG_S = 131.0


def write_ybag(path: str | os.PathLike[str], rec: Record, *, t0: float = 1.744e9,
               thrust_full_scale: float = 10.0, every: int = 5, dvl_every: int = 10,
               zero_imu_stamps: bool = True, noise: np.ndarray | None = None) -> int:
    """Write ``rec`` as a small vehicle's rosbag2 MCAP bag with three fins in a Y (see the
    module docstring for the vendor conventions) and returns the messages written:

    * ``/imu/data`` ``sensor_msgs/Imu``: orientation ENU/FLU, angular velocity FLU in raw
      gyro counts (:data:`GYRO_COUNTS_PER_DEG_S` per deg/s); header stamps all zero when
      ``zero_imu_stamps`` (a driver that does not stamp);
    * ``/pressure`` ``sensor_msgs/FluidPressure`` [Pa] and ``/dvl/twist``
      ``geometry_msgs/TwistStamped`` (FLU, every ``dvl_every``-th sample), stamped;
    * ``/fins/top``, ``/fins/port``, ``/fins/stbd`` ``std_msgs/Float64`` [deg] (no header:
      receive times): the top fin is the rudder, the lower fins at +-120 deg from the top
      are each deflected by ``bar / cos(30 deg)``;
    * ``/thruster/percent`` ``std_msgs/Float64``: thrust in per cent of
      ``thrust_full_scale`` [N].

    State messages every ``every``-th sample; receive times ``t0 + t`` [s] plus 2 ms.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    T = store.types
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    V3 = T['geometry_msgs/msg/Vector3']
    Twist, TwistS, F64 = (T['geometry_msgs/msg/Twist'], T['geometry_msgs/msg/TwistStamped'],
                          T['std_msgs/msg/Float64'])
    meas = _state(rec, noise)
    idx = np.arange(0, len(rec.t), every)
    odom = state_to_odometry(meas[idx])

    def header(t: float | None, frame: str) -> Any:
        ns = 0 if t is None else int(round((t0 + t) * 1e9))
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    events: list[tuple[float, str, str, Any]] = []
    for k, i in enumerate(idx):
        t = float(rec.t[i])
        q, lin, ang = odom.orientation[k], odom.linear[k], odom.angular[k]
        counts = np.degrees(ang) * GYRO_COUNTS_PER_DEG_S
        events += _imu_and_pressure(T, t, header(None if zero_imu_stamps else t, 'imu'),
                                    header(t, 'pressure'), q, counts, float(meas[i, 2]))
        if k % max(1, dvl_every // every) == 0:
            events.append((t, '/dvl/twist', 'geometry_msgs/msg/TwistStamped', TwistS(
                header=header(t, 'dvl'),
                twist=Twist(linear=V3(x=lin[0], y=lin[1], z=lin[2]),
                            angular=V3(x=0.0, y=0.0, z=0.0)))))
    change = np.flatnonzero(np.any(np.diff(rec.cmd, axis=0, prepend=np.nan) != 0, axis=1))
    for i in change:
        t = float(rec.t[i])
        bar, helm, thrust = (float(v) for v in rec.cmd[i])
        lower = math.degrees(bar) / COS_30
        for topic, value in (('/fins/top', math.degrees(helm)), ('/fins/port', lower),
                             ('/fins/stbd', lower),
                             ('/thruster/percent', 100.0 * thrust / thrust_full_scale)):
            events.append((t, topic, 'std_msgs/msg/Float64', F64(data=value)))
    events.sort(key=lambda e: e[0])
    with Writer(pathlib.Path(path), version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns: dict[str, Any] = {}
        for t, topic, msgtype, msg in events:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=store)
            w.write(conns[topic], int(round((t0 + t + 0.002) * 1e9)),
                    store.serialize_cdr(msg, msgtype))
    return len(events)
