"""Identification of a vehicle's hydrodynamic coefficients from logs, the starting vehicle
file from main dimensions (``auv vehicle-init``), and the identification node."""
