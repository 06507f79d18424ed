"""Exceptions of auv_sim: one family, subclassing built-ins."""


class AuvSimError(Exception):
    """Root of the simulator's errors."""


class ParameterError(AuvSimError, ValueError):
    """A vehicle, effect or node parameter is missing, malformed or out of range."""


class CommandError(ParameterError):
    """A command is NaN, infinite or outside the actuator's range; it was not applied."""


class DivergenceError(AuvSimError, FloatingPointError):
    """The integrated state turned non-finite."""


class TrimError(AuvSimError, ArithmeticError):
    """No trim (equilibrium) point could be found."""


class GraphConflictError(AuvSimError, RuntimeError):
    """Another node publishes the simulator's state topic: a second graph on one namespace."""
