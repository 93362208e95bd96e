"""Statistical outlier removal (METHODS.md R2).

The per-point mean neighbour distance d runs on the device (``neighbors.knn_mean_distance``);
the cloud statistics mu and sigma are two float64 sums on the host, in index order, so the
result is deterministic.

Conventions:
* ``paper``: k neighbours excluding p, population std; keep mu - s*sigma < d < mu + s*sigma
  (``two_sided``) or d < mu + s*sigma (``upper``).
* ``open3d``: Open3D's RemoveStatisticalOutliers: the k neighbours include p itself (distance 0),
  mu is the sum of the positive d over all n points, sigma the sample std over the positive d
  (divided by n - 1), and a point is kept when 0 < d < mu + s*sigma (``upper``); ``two_sided``
  adds d > mu - s*sigma.
"""

import numpy as np

from .common import is_ndarray, length, ndarray, to_numpy
from .neighbors import knn_mean_distance

MODES = ("upper", "two_sided")
CONVENTIONS = ("open3d", "paper")


def sor_thresholds(mean_distance, std_ratio: float, convention: str):
    """(lower, upper) bounds of d for the given convention, from the per-point d (numpy)."""
    d = np.asarray(mean_distance, np.float64)
    n = d.size
    if convention == "paper":
        mu = d.mean() if n else 0.0
        sigma = d.std() if n else 0.0
    else:
        positive = d > 0
        mu = d[positive].sum() / n if n else 0.0
        sigma = np.sqrt(((d[positive] - mu) ** 2).sum() / (n - 1)) if n > 1 else 0.0
    return mu - std_ratio * sigma, mu + std_ratio * sigma


def sor_keep(xyz, k: int, std_ratio: float, *, mode: str = "upper", convention: str = "open3d",
             grid=None):
    """Boolean keep-mask (n,) of statistical outlier removal with k neighbours and ``std_ratio``.

    numpy in -> numpy bool out; a Taichi ndarray in -> a uint8 ndarray out (1 = keep)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if convention not in CONVENTIONS:
        raise ValueError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    d = knn_mean_distance(xyz, k, include_self=(convention == "open3d"), grid=grid)
    d_host = to_numpy(d).astype(np.float64)
    lower, upper = sor_thresholds(d_host, float(std_ratio), convention)
    dd = to_numpy(d)          # compare the float32 values, promoted exactly
    keep = dd < upper
    if convention == "open3d":
        keep &= dd > 0
    if mode == "two_sided":
        keep &= dd > lower
    if is_ndarray(xyz):
        out = ndarray(np.uint8, (length(xyz),))
        out.from_numpy(keep.astype(np.uint8))
        return out
    return keep
