"""Per-segment statistics over point labels (host numpy, deterministic): shared by the road
pipeline's plane removal (R3, parts of an XY plane) and the roof post-filter (P4)."""
from __future__ import annotations

import numpy as np


def segment_medians(segment: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """Median of ``values`` per segment id 0..count-1 (segment -1 ignored), float64."""
    inside = segment >= 0
    seg, val = segment[inside], values[inside].astype(np.float64)
    order = np.lexsort((val, seg))
    seg, val = seg[order], val[order]
    starts = np.searchsorted(seg, np.arange(count))
    stops = np.searchsorted(seg, np.arange(count), side="right")
    lo = val[starts + (stops - starts - 1) // 2]
    hi = val[starts + (stops - starts) // 2]
    return (lo + hi) / 2


def segment_covariance(segment: np.ndarray, points: np.ndarray, count: int):
    """(sizes, mean, covariance) per segment id 0..count-1 of ``points`` (n, d), segment -1
    ignored: point counts (int64), means (count, d) and population covariances (count, d, d), all
    float64 sums by bincount (an empty id: mean and covariance 0)."""
    inside = segment >= 0
    seg = segment[inside]
    pts = np.asarray(points, np.float64)[inside]
    dims = pts.shape[1]
    sizes = np.bincount(seg, minlength=count)
    divisor = np.maximum(sizes, 1)
    mean = np.stack([np.bincount(seg, pts[:, a], minlength=count) for a in range(dims)], 1) / divisor[:, None]
    d = pts - mean[seg]
    cov = np.zeros((count, dims, dims))
    for a in range(dims):
        for b in range(a, dims):
            cov[:, a, b] = cov[:, b, a] = np.bincount(seg, d[:, a] * d[:, b], minlength=count) / divisor
    return sizes, mean, cov
