"""Nonlinear 6-DOF AUV model (pure library) and the simulator node."""
