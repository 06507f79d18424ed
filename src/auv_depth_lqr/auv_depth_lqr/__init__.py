"""Trim, linearisation, discrete LQR design and the depth-pilot node."""
