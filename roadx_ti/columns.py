"""Per-column reductions of point arrays ((n, d), d small).

numpy reduces an (n, 3) array along axis 0 about ten times slower than it reduces its three
columns one by one (4 M points: 118 ms against 10 ms for a min; nanmax of abs 351 against
~30 ms), and the read path, the ordering and the isolation test take such minima and maxima of
every cloud. Same results as ``a.min(axis=0)`` and friends, NaN propagation included.
"""
from __future__ import annotations

import numpy as np


def column_min(a) -> np.ndarray:
    a = np.asarray(a)
    return np.array([a[:, c].min() for c in range(a.shape[1])], a.dtype)


def column_max(a) -> np.ndarray:
    a = np.asarray(a)
    return np.array([a[:, c].max() for c in range(a.shape[1])], a.dtype)


def column_abs_nanmax(a) -> np.ndarray:
    """np.nanmax(np.abs(a), axis=0): NaN only where a column is all NaN (fmin / fmax skip NaN)."""
    a = np.asarray(a)
    lo = np.array([np.fmin.reduce(a[:, c]) for c in range(a.shape[1])], np.float64)
    hi = np.array([np.fmax.reduce(a[:, c]) for c in range(a.shape[1])], np.float64)
    return np.fmax(np.abs(lo), np.abs(hi))
