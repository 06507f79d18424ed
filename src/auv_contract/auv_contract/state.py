"""The vehicle state's layout and the actuator channels (docs/architecture.md, "Messages").

The state is Fossen's: position ``eta = (x, y, z)`` in the world frame NED [m] (z is depth,
positive down), ZYX Euler angles ``(phi, theta, psi)`` [rad] (theta positive nose up),
body-frame FRD velocities ``nu = (u, v, w)`` [m/s] and rates ``(p, q, r)`` [rad/s]: the fields
of ``auv_msgs/msg/VehicleState`` in this order.
"""
from __future__ import annotations

__all__ = ['CHANNELS', 'CHANNEL_UNITS', 'STATE_FIELDS', 'STATE_UNITS']

STATE_FIELDS = ('x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')
"""The 12 state fields, in the message's order."""
STATE_UNITS = {'x': 'm', 'y': 'm', 'z': 'm', 'phi': 'rad', 'theta': 'rad', 'psi': 'rad',
               'u': 'm/s', 'v': 'm/s', 'w': 'm/s', 'p': 'rad/s', 'q': 'rad/s', 'r': 'rad/s'}
"""SI unit of each state field."""
CHANNELS = ('bar', 'helm', 'thrust')
"""Actuator channels: dive-plane (BAR) angle [rad], rudder (helm) angle [rad], thrust [N]."""
CHANNEL_UNITS = {'bar': 'rad', 'helm': 'rad', 'thrust': 'N'}
"""SI unit of each actuator channel."""
