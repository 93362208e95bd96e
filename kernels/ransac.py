"""Parallel RANSAC plane fitting with preemptive scoring (METHODS.md R3).

Hypotheses (3 distinct random active points each) come from ``numpy.random.default_rng(seed)`` on
the host, so a fit is reproducible. All hypotheses are scored at once against a fixed random
sample of the active points (one launch, parallel over sample blocks x hypotheses, integer
counts); the best few are then scored on all active points, the highest count wins (ties: lower
hypothesis index), and the winner is refit by least squares on its inliers (smallest eigenvector
of the inlier covariance, float64 on the host) before the inliers are recomputed. Counts are
integer atomics of per-thread partial counts, so every result is independent of thread timing.
"""

from dataclasses import dataclass

import numpy as np
from .taichi_compat import ti

from .common import as_ndarray, like_input, ndarray, output_array, points_array, to_numpy

SAMPLE_SIZE = 1 << 16   # points every hypothesis is scored on in the preemptive pass
FINALISTS = 8           # hypotheses scored on all points
_BLOCK = 4096           # points one thread counts before its single atomic_add
_DEGENERATE_D = 3.0e38  # plane offset given to collinear hypotheses: no point is ever that close


@dataclass
class PlaneFit:
    plane: np.ndarray       # float64 (4,): a, b, c, d with unit normal (a, b, c), c >= 0
    inliers: np.ndarray     # bool (n,)
    n_inliers: int
    hypotheses_scored: int


@ti.func
def _plane_distance(xyz: ti.template(), i: ti.i32, a: ti.f32, b: ti.f32, c: ti.f32, d: ti.f32) -> ti.f32:
    return ti.abs(a * xyz[i, 0] + b * xyz[i, 1] + c * xyz[i, 2] + d)


@ti.kernel
def _hypothesis_planes(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                       triples: ti.types.ndarray(dtype=ti.i32, ndim=2),
                       planes: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    for h in range(triples.shape[0]):
        p0 = ti.Vector([xyz[triples[h, 0], 0], xyz[triples[h, 0], 1], xyz[triples[h, 0], 2]])
        p1 = ti.Vector([xyz[triples[h, 1], 0], xyz[triples[h, 1], 1], xyz[triples[h, 1], 2]])
        p2 = ti.Vector([xyz[triples[h, 2], 0], xyz[triples[h, 2], 1], xyz[triples[h, 2], 2]])
        normal = (p1 - p0).cross(p2 - p0)
        length = normal.norm()
        if length > 1e-12:
            normal /= length
            if normal[2] < 0:
                normal = -normal
            planes[h, 0] = normal[0]
            planes[h, 1] = normal[1]
            planes[h, 2] = normal[2]
            planes[h, 3] = -normal.dot(p0)
        else:
            planes[h, 0] = 0.0
            planes[h, 1] = 0.0
            planes[h, 2] = 0.0
            planes[h, 3] = _DEGENERATE_D


@ti.kernel
def _gather_columns(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                    index: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    columns: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    # (3, m) layout: the scoring loops then read unit-stride rows and vectorise (~10x on CPU)
    for s in index:
        for c in ti.static(range(3)):
            columns[c, s] = xyz[index[s], c]


@ti.kernel
def _to_columns(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                columns: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    for i in range(xyz.shape[0]):
        for c in ti.static(range(3)):
            columns[c, i] = xyz[i, c]


@ti.kernel
def _count_inliers(columns: ti.types.ndarray(dtype=ti.f32, ndim=2),
                   active: ti.types.ndarray(dtype=ti.u8, ndim=1), use_active: ti.i32,
                   planes: ti.types.ndarray(dtype=ti.f32, ndim=2), threshold: ti.f32,
                   block: ti.i32, counts: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    n = columns.shape[1]
    n_blocks = (n + block - 1) // block
    # block-major order: the threads that run together share one block of points in cache
    for b, h in ti.ndrange(n_blocks, planes.shape[0]):
        a = planes[h, 0]
        bb = planes[h, 1]
        c = planes[h, 2]
        d = planes[h, 3]
        start = b * block
        stop = ti.min(n, start + block)
        count = 0
        if use_active == 0:
            for i in range(start, stop):
                dist = ti.abs(a * columns[0, i] + bb * columns[1, i] + c * columns[2, i] + d)
                count += ti.cast(dist < threshold, ti.i32)
        else:
            for i in range(start, stop):
                dist = ti.abs(a * columns[0, i] + bb * columns[1, i] + c * columns[2, i] + d)
                count += ti.cast(dist < threshold, ti.i32) * ti.cast(active[i] != 0, ti.i32)
        if count > 0:
            ti.atomic_add(counts[h], count)


@ti.kernel
def _distances(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), a: ti.f32, b: ti.f32, c: ti.f32,
               d: ti.f32, out: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for i in out:
        out[i] = _plane_distance(xyz, i, a, b, c, d)


@ti.kernel
def _inlier_mask(columns: ti.types.ndarray(dtype=ti.f32, ndim=2),
                 active: ti.types.ndarray(dtype=ti.u8, ndim=1), use_active: ti.i32,
                 a: ti.f32, b: ti.f32, c: ti.f32, d: ti.f32, threshold: ti.f32,
                 out: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in out:
        dist = ti.abs(a * columns[0, i] + b * columns[1, i] + c * columns[2, i] + d)
        inside = ti.u8(0)
        if dist < threshold:
            inside = ti.u8(1)
            if use_active != 0:
                inside = active[i]
        out[i] = inside


def _unit_plane(plane) -> np.ndarray:
    """float64 (4,) with unit normal and c >= 0 (for c == 0: b >= 0, then a >= 0)."""
    p = np.asarray(plane, dtype=np.float64).reshape(4)
    length = np.linalg.norm(p[:3])
    if length == 0:
        raise ValueError("plane normal is zero")
    p = p / length
    for axis in (2, 1, 0):
        if p[axis] != 0:
            return -p if p[axis] < 0 else p
    return p


def plane_distances(xyz, plane):
    """Absolute distances (float32 (n,)) of the points to ``plane`` (a, b, c, d; the normal is
    normalised here). numpy or ndarray, as ``xyz``."""
    points = points_array(xyz)
    n = int(xyz.shape[0])
    if n == 0:
        return np.zeros(0, np.float32)
    p = _unit_plane(plane)
    out = output_array(ti.f32, (n,), xyz)
    _distances(points, *(float(v) for v in p), out)
    return like_input(out, xyz)


def _draw_triples(rng, n_active, hypotheses):
    """(hypotheses, 3) indices into the active points, three distinct per row."""
    triples = rng.integers(0, n_active, (hypotheses, 3))
    while True:
        repeat = ((triples[:, 0] == triples[:, 1]) | (triples[:, 0] == triples[:, 2])
                  | (triples[:, 1] == triples[:, 2]))
        if not repeat.any():
            return triples
        triples[repeat] = rng.integers(0, n_active, (int(repeat.sum()), 3))


def _refit(points: np.ndarray) -> np.ndarray:
    """Least-squares plane of (3, m) float64 coordinates: normal = covariance eigenvector of the
    smallest eigenvalue (sums in a fixed order, so the result is deterministic)."""
    centroid = points.mean(axis=1)
    centred = points - centroid[:, None]
    cov = np.empty((3, 3))
    for r in range(3):
        for c in range(r, 3):
            cov[r, c] = cov[c, r] = np.dot(centred[r], centred[c])
    _, vectors = np.linalg.eigh(cov)
    normal = vectors[:, 0]
    return _unit_plane(np.append(normal, -normal @ centroid))


def fit_plane(xyz, distance_threshold, *, hypotheses=1000, seed=0, active=None, sample_size=None,
              refine=True) -> PlaneFit:
    """Find the plane with the most points within ``distance_threshold`` (strictly less).

    xyz: float32 (n, 3), numpy or ndarray; active: uint8/bool (n,) or None (all). Points outside
    ``active`` neither seed hypotheses nor count as inliers. sample_size: points of the
    preemptive pass (default SAMPLE_SIZE; all active points when there are fewer).
    """
    points = points_array(xyz)
    n = int(xyz.shape[0])
    act_host = None if active is None else (to_numpy(active) != 0)
    active_index = None if act_host is None else np.flatnonzero(act_host)
    n_active = n if act_host is None else len(active_index)
    if n_active < 3 or hypotheses < 1:
        return PlaneFit(np.array([0.0, 0.0, 1.0, 0.0]), np.zeros(n, bool), 0, 0)

    def point_index(k):  # k-th active point -> point index
        return (k if active_index is None else active_index[k]).astype(np.int32)

    rng = np.random.default_rng(seed)
    triples = point_index(_draw_triples(rng, n_active, hypotheses))
    sample_n = min(n_active, int(sample_size or SAMPLE_SIZE))
    if sample_n == n_active:
        sample = point_index(np.arange(n_active))
    else:
        sample = point_index(np.sort(rng.choice(n_active, sample_n, replace=False)))

    active_nd = as_ndarray(act_host.astype(np.uint8)) if act_host is not None else ndarray(ti.u8, (1,))
    use_active = int(act_host is not None)
    threshold = float(np.float32(distance_threshold))

    planes = ndarray(ti.f32, (hypotheses, 4))
    _hypothesis_planes(points, as_ndarray(triples), planes)
    sample_columns = ndarray(ti.f32, (3, sample_n))
    _gather_columns(points, as_ndarray(sample), sample_columns)
    sample_counts = ndarray(ti.i32, (hypotheses,))
    sample_counts.fill(0)
    _count_inliers(sample_columns, ndarray(ti.u8, (1,)), 0, planes, threshold, _BLOCK, sample_counts)

    counts = sample_counts.to_numpy()
    order = np.lexsort((np.arange(hypotheses), -counts.astype(np.int64)))
    finalists = order[:min(FINALISTS, hypotheses)]
    plane_host = planes.to_numpy()
    full_counts = ndarray(ti.i32, (len(finalists),))
    full_counts.fill(0)
    columns = ndarray(ti.f32, (3, n))
    _to_columns(points, columns)
    _count_inliers(columns, active_nd, use_active, as_ndarray(plane_host[finalists]), threshold,
                   _BLOCK, full_counts)
    full = full_counts.to_numpy().astype(np.int64)
    best = finalists[np.lexsort((finalists, -full))[0]]
    plane = plane_host[best].astype(np.float64)
    if not plane[:3].any():  # every hypothesis was collinear
        return PlaneFit(np.array([0.0, 0.0, 1.0, 0.0]), np.zeros(n, bool), 0, hypotheses)

    mask = ndarray(ti.u8, (n,))

    def inliers_of(p):
        _inlier_mask(columns, active_nd, use_active, *(float(v) for v in p), threshold, mask)
        return mask.to_numpy().astype(bool)

    inliers = inliers_of(plane)
    if refine and inliers.sum() >= 3:
        host_xyz = to_numpy(xyz)
        plane = _refit(np.ascontiguousarray(host_xyz[inliers].T, dtype=np.float64))
        inliers = inliers_of(plane)
    else:
        plane = _unit_plane(plane)
    return PlaneFit(plane, inliers, int(inliers.sum()), hypotheses)
