"""Bag I/O, hydrodynamic coefficient identification, sim-to-real gap diagnosis, and the
identification node."""
