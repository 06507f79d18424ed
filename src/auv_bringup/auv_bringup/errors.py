"""Exceptions of auv_bringup: one family, subclassing built-ins."""


class AuvBringupError(Exception):
    """Root of the bring-up errors (launch, runs, demo)."""


class LaunchError(AuvBringupError, RuntimeError):
    """A node of the graph failed to start, died, or did not stop."""


class RunError(AuvBringupError, ValueError):
    """An offline run or the demo was given bad input."""


class BridgeError(AuvBringupError, ValueError):
    """A message the Foxglove bridge cannot turn into what it serves (e.g. a non-unit
    quaternion)."""
