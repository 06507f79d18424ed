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
    Odometry, Imu = T['nav_msgs/msg/Odometry'], T['sensor_msgs/msg/Imu']
    V3, Q, Pt = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion'], \
        T['geometry_msgs/msg/Point']
    Pose, PoseC = T['geometry_msgs/msg/Pose'], T['geometry_msgs/msg/PoseWithCovariance']
    Twist, TwistC = T['geometry_msgs/msg/Twist'], T['geometry_msgs/msg/TwistWithCovariance']
    Press, F64, Fins = T['sensor_msgs/msg/FluidPressure'], T['std_msgs/msg/Float64'], T[FIN_TYPE]
    cov36, cov9 = np.zeros(36), np.zeros(9)
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
        events.append((t, '/imu/data', 'sensor_msgs/msg/Imu', Imu(
            header=header(t, 'imu_link'), orientation=quat, orientation_covariance=cov9,
            angular_velocity=V3(x=ang[0], y=ang[1], z=ang[2]),
            angular_velocity_covariance=cov9,
            linear_acceleration=V3(x=0.0, y=0.0, z=0.0), linear_acceleration_covariance=cov9)))
        events.append((t, '/pressure', 'sensor_msgs/msg/FluidPressure', Press(
            header=header(t, 'pressure'), fluid_pressure=P0 + RHO * G * meas[i, 2],
            variance=0.0)))
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
