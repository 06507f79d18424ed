"""An exponentially weighted mean normalised by its weights.

From the first sample on it is the weighted mean of the samples so far (not the first
sample decayed towards the rest); once the weights have settled, the exponential low-pass
of time constant ``-Ts / ln(decay)``. Units: those of the samples (its spread: squared).
"""
from __future__ import annotations

import numpy as np

from auv_depth_lqr.schedule import Matrix

__all__ = ['ExponentialMean']


class ExponentialMean:
    """Exponentially weighted mean and spread of samples of ``size`` values.

    Parameters
    ----------
    size : int
        Values per sample.
    """

    def __init__(self, size: int) -> None:
        self.total: Matrix = np.zeros(size)
        """Weighted sum of the samples."""
        self.square: Matrix = np.zeros(size)
        """Weighted sum of their squares."""
        self.weight = 0.0
        """Sum of the weights [-] (0: no sample yet; it tends to 1)."""

    def add(self, sample: Matrix, decay: float) -> None:
        """Add ``sample``, the earlier ones weighted down by ``decay`` (0 < decay < 1)."""
        self.total = decay * self.total + (1.0 - decay) * sample
        self.square = decay * self.square + (1.0 - decay) * sample ** 2
        self.weight = decay * self.weight + (1.0 - decay)

    @property
    def mean(self) -> Matrix:
        """The weighted mean (nan before the first sample)."""
        with np.errstate(invalid='ignore', divide='ignore'):
            out: Matrix = self.total / self.weight
        return out

    @property
    def spread(self) -> Matrix:
        """The weighted variance of the samples about their mean (at least 0)."""
        mean = self.mean
        out: Matrix = np.maximum(self.square / self.weight - mean ** 2, 0.0)
        return out
