"""Statistical outlier removal (METHODS.md R2) and low noise by extended local minimum (ELM).

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

import math

import numpy as np

from .common import (INT32_MAX, f32_order_key, is_ndarray, kernel_array, length, like_input, ndarray, points_array,
                     to_numpy, zeros)
from .grid_min import _fill_i32, plan_cells
from .neighbors import knn_mean_distance
from .taichi_compat import ti

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


# ------------------------------------------------------------------------------------------------
# Low noise (extended local minimum, after PDAL's filters.elm): in every plan cell, the lowest points
# are noise when a gap of more than ``threshold`` separates them from the next point of their cell
# (filters.elm: the lowest one point; here a run of up to ``max_cluster`` points, since low returns
# come in pairs and triples under one spot); repeated on the points left. Low outliers (multipath,
# echoes off wet or glassy surfaces) hold a ground filter's cloth metres under the terrain.
MAX_CLUSTER = 8


@ti.kernel
def _lowest_key(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                members: ti.types.ndarray(dtype=ti.i32, ndim=1), noise: ti.types.ndarray(dtype=ti.u8, ndim=1),
                picked: ti.types.ndarray(dtype=ti.i32, ndim=2), rank: ti.i32,
                key: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """key[c] = min of the z order keys of cell c's member points that are not noise and not
    picked yet."""
    for t in members:
        i = members[t]
        c = cell[i]
        if noise[i] == 0 and not _is_picked(picked, c, rank, i):
            ti.atomic_min(key[c], f32_order_key(xyz[i, 2]))


@ti.kernel
def _pick_lowest(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 members: ti.types.ndarray(dtype=ti.i32, ndim=1), noise: ti.types.ndarray(dtype=ti.u8, ndim=1),
                 picked: ti.types.ndarray(dtype=ti.i32, ndim=2), rank: ti.i32,
                 key: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """picked[c, rank] = the lowest index among those points whose z has key[c] (ties by index)."""
    for t in members:
        i = members[t]
        c = cell[i]
        if noise[i] == 0 and not _is_picked(picked, c, rank, i) and f32_order_key(xyz[i, 2]) == key[c]:
            ti.atomic_min(picked[c, rank], i)


@ti.func
def _is_picked(picked: ti.template(), c: ti.i32, rank: ti.i32, i: ti.i32) -> ti.i32:
    found = 0
    for r in range(rank):
        if picked[c, r] == i:
            found = 1
    return found


@ti.kernel
def _flag_low_runs(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), picked: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   max_cluster: ti.i32, threshold: ti.f32, deep_threshold: ti.f32,
                   noise: ti.types.ndarray(dtype=ti.u8, ndim=1),
                   active: ti.types.ndarray(dtype=ti.u8, ndim=1)) -> ti.i32:
    """Per cell: the first gap above threshold among its lowest picked points flags the points
    below it when they are at most max_cluster, or, when the gap is above deep_threshold, at most
    as many as were picked less one; active[c] = whether it did (only such cells can flag more)."""
    flagged = 0
    for c in range(picked.shape[0]):
        active[c] = ti.u8(0)
        run = -1
        gap = 0.0
        for j in range(picked.shape[1] - 1):
            if run < 0 and picked[c, j + 1] != INT32_MAX:
                step = xyz[picked[c, j + 1], 2] - xyz[picked[c, j], 2]
                if step > threshold:
                    run = j
                    gap = step
        if run >= max_cluster and gap <= deep_threshold:
            run = -1
        if run >= 0:
            for j in range(run + 1):
                noise[picked[c, j]] = ti.u8(1)
            active[c] = ti.u8(1)
            flagged += run + 1
    return flagged


def low_noise(xyz, cell: float = 10.0, threshold: float = 1.0, max_cluster: int = 1, max_rounds: int = 16,
              origin=None, deep_cluster: int = 0, deep_threshold: float = math.inf):
    """Low-noise flags (uint8 (n,), 1 = noise) by extended local minimum over plan cells of edge
    ``cell`` m (from ``origin`` = (x0, y0) when given, so that cells can follow a world lattice):
    at most ``max_rounds`` rounds, each flagging per cell its lowest remaining points, at most
    ``max_cluster`` of them, when more than ``threshold`` m separate them from the next one (the
    first such gap from below; max_cluster 1 is filters.elm's rule); under a gap of more than
    ``deep_threshold`` m, up to ``deep_cluster`` of them (0: no such rule). A cell needs a point above
    the gap, so one with a single point left flags nothing. Ties in z go to the lowest index: the
    flags do not depend on thread timing or point order beyond that. numpy in, numpy out; a Taichi
    ndarray in, an ndarray out."""
    if cell <= 0:
        raise ValueError(f"cell must be > 0, got {cell}")
    if threshold < 0:
        raise ValueError(f"threshold must be >= 0, got {threshold}")
    if not 1 <= max_cluster <= MAX_CLUSTER:
        raise ValueError(f"max_cluster must be in 1..{MAX_CLUSTER}, got {max_cluster}")
    if not (isinstance(deep_cluster, (int, np.integer)) and 0 <= deep_cluster <= MAX_CLUSTER):
        raise ValueError(f"deep_cluster must be a whole number in 0..{MAX_CLUSTER}, got {deep_cluster!r}")
    if not deep_threshold >= threshold:
        raise ValueError(f"deep_threshold must be >= threshold ({threshold}), got {deep_threshold}")
    pts = points_array(xyz)
    n = length(pts)
    if n == 0:
        return np.zeros(0, np.uint8)
    noise = zeros(ti.u8, (n,))
    cell_of, cells = plan_cells(pts, cell, origin)
    cell_of = kernel_array(cell_of, "int32")
    key = ndarray(ti.i32, (cells,))
    width = max(max_cluster, deep_cluster) + 1       # the lowest points of a cell that are read
    picked = ndarray(ti.i32, (cells, width))
    active = ndarray(ti.u8, (cells,))
    members = kernel_array(np.arange(n, dtype=np.int32), "int32")
    for _ in range(max_rounds):
        picked.fill(INT32_MAX)
        for rank in range(width):
            _fill_i32(key, INT32_MAX)
            _lowest_key(pts, cell_of, members, noise, picked, rank, key)
            _pick_lowest(pts, cell_of, members, noise, picked, rank, key)
        deep = min(float(deep_threshold), 3.0e38) if deep_cluster > max_cluster else 3.0e38
        if _flag_low_runs(pts, picked, max_cluster, float(threshold), deep, noise, active) == 0:
            break
        # the next round reads only the points of cells that flagged (the others' verdict is final)
        in_active = to_numpy(active)[to_numpy(cell_of)] != 0
        members = kernel_array(np.flatnonzero(in_active).astype(np.int32), "int32")
        if length(members) == 0:
            break
    return like_input(noise, xyz)

