"""Covariance features of each point's neighbourhood: normal, eigenvalues, curvature, extents.

The neighbourhood of point p is p itself plus its k neighbours (as Open3D's estimate_normals,
whose KNN result contains p). The covariance is taken about the neighbourhood centroid, with
coordinates relative to p, so float32 keeps its precision far from the origin. Eigenvalues come
from a cyclic Jacobi solver on the scaled 3x3 matrix: robust for flat and linear (degenerate)
neighbourhoods, where closed-form cubic solutions lose the small eigenvalue.
"""

import numpy as np
from .taichi_compat import ti

from .common import index_array, length, like_input, output_array, points_array

_JACOBI_SWEEPS = 8


@ti.func
def _jacobi_converged(m: ti.math.mat3) -> ti.i32:
    """The off-diagonal part is below float32 resolution of the diagonal."""
    off = ti.abs(m[0, 1]) + ti.abs(m[0, 2]) + ti.abs(m[1, 2])
    return ti.cast(off <= 1e-9 * (ti.abs(m[0, 0]) + ti.abs(m[1, 1]) + ti.abs(m[2, 2])), ti.i32)


@ti.func
def _jacobi_angle(m: ti.math.mat3, p: ti.template(), q: ti.template()) -> ti.math.vec2:
    """(cos, sin) of the Jacobi rotation that zeroes m[p, q] (not zero), the smaller of the two angles."""
    theta = (m[q, q] - m[p, p]) / (2.0 * m[p, q])
    t = ti.math.sign(theta) / (ti.abs(theta) + ti.sqrt(theta * theta + 1.0))
    if theta == 0:
        t = 1.0
    c = 1.0 / ti.sqrt(t * t + 1.0)
    return ti.math.vec2(c, t * c)


@ti.func
def _jacobi_rotate(m: ti.math.mat3, v: ti.math.mat3, p: ti.template(), q: ti.template(), vectors: ti.template()):
    """One Jacobi rotation R zeroing m[p, q] (m scaled to its largest entry): (R^T m R, v R), or
    (m, v) when m[p, q] is already (numerically) zero. Only rows and columns p and q change:
    written out, each entry is the same two products and one sum as in the full 3x3 products
    (their other terms are exact zeros and ones; Taichi's float flags let LLVM drop none of
    them), at a quarter of the multiplications."""
    if ti.abs(m[p, q]) > 1e-30:
        cs = _jacobi_angle(m, p, q)
        c = cs[0]
        s = cs[1]
        rows = m                     # R^T m: rows p and q
        for j in ti.static(range(3)):
            rows[p, j] = c * m[p, j] - s * m[q, j]
            rows[q, j] = s * m[p, j] + c * m[q, j]
        m = rows                     # (R^T m) R: columns p and q
        for i in ti.static(range(3)):
            rp = rows[i, p]
            rq = rows[i, q]
            m[i, p] = rp * c - rq * s
            m[i, q] = rp * s + rq * c
        m[p, q] = 0.0
        m[q, p] = 0.0
        if ti.static(vectors):
            for i in ti.static(range(3)):
                vp = v[i, p]
                vq = v[i, q]
                v[i, p] = vp * c - vq * s
                v[i, q] = vp * s + vq * c
    return m, v


@ti.func
def _sorted_eigen(m: ti.math.mat3, v: ti.math.mat3, scale: ti.f32, vectors: ti.template()):
    """The diagonal of a converged m (times ``scale``) ascending, carrying the eigenvector
    columns (three compare-swaps)."""
    w = ti.math.vec3(m[0, 0], m[1, 1], m[2, 2]) * scale
    for pair in ti.static(range(3)):
        i = ti.static((0, 1, 0)[pair])
        j = ti.static((1, 2, 1)[pair])
        if w[j] < w[i]:
            tmp = w[i]
            w[i] = w[j]
            w[j] = tmp
            if ti.static(vectors):
                for r in ti.static(range(3)):
                    tv = v[r, i]
                    v[r, i] = v[r, j]
                    v[r, j] = tv
    return w, v


@ti.func
def sym_eigen3(a: ti.math.mat3, vectors: ti.template() = True):
    """Eigen-decomposition of a symmetric 3x3 matrix: (eigenvalues ascending, eigenvectors as
    columns in the same order). ``vectors`` False skips the eigenvectors (identity returned):
    the same eigenvalues, bit for bit, from a smaller kernel."""
    scale = ti.max(ti.abs(a).max(), 1e-30)
    m = a / scale
    v = ti.math.mat3([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    sweep = 0
    while sweep < _JACOBI_SWEEPS:
        if _jacobi_converged(m):
            break
        sweep += 1
        for pair in ti.static(range(3)):
            m, v = _jacobi_rotate(m, v, ti.static((0, 0, 1)[pair]), ti.static((1, 2, 2)[pair]), vectors)
    return _sorted_eigen(m, v, scale, vectors)


@ti.func
def _neighbourhood_covariance(xyz: ti.template(), nbr: ti.template(), i: ti.i32):
    """Covariance of point i and its neighbours about their centroid (coordinates relative to the
    point), with the per-axis extent of the offsets, the largest squared distance and the
    centroid (relative to the point)."""
    k = nbr.shape[1]
    p = ti.math.vec3(xyz[i, 0], xyz[i, 1], xyz[i, 2])
    total = ti.math.vec3(0.0)          # p's own offset is 0
    lo = ti.math.vec3(0.0)
    hi = ti.math.vec3(0.0)
    far2 = 0.0
    for r in range(k):
        j = nbr[i, r]
        d = ti.math.vec3(xyz[j, 0], xyz[j, 1], xyz[j, 2]) - p
        total += d
        lo = ti.min(lo, d)
        hi = ti.max(hi, d)
        far2 = ti.max(far2, d.dot(d))
    centre = total / ti.cast(k + 1, ti.f32)
    cov = ti.math.mat3(0.0)
    dp = -centre
    cov += dp.outer_product(dp)
    for r in range(k):
        j = nbr[i, r]
        d = ti.math.vec3(xyz[j, 0], xyz[j, 1], xyz[j, 2]) - p - centre
        cov += d.outer_product(d)
    cov /= ti.cast(k + 1, ti.f32)
    return cov, hi - lo, far2, centre


@ti.func
def _curvature_of(w: ti.math.vec3) -> ti.f32:
    out = 0.0
    wsum = w.sum()
    if wsum > 0:
        out = w[0] / wsum
    return out


@ti.kernel
def _covariance_features(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), nbr: ti.types.ndarray(dtype=ti.i32, ndim=2),
                         normal: ti.types.ndarray(dtype=ti.f32, ndim=2), eigval: ti.types.ndarray(dtype=ti.f32, ndim=2),
                         curvature: ti.types.ndarray(dtype=ti.f32, ndim=1),
                         max_distance: ti.types.ndarray(dtype=ti.f32, ndim=1),
                         extent: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    for i in range(xyz.shape[0]):
        cov, span, far2, _centre = _neighbourhood_covariance(xyz, nbr, i)
        w, v = sym_eigen3(cov)
        w = ti.max(w, 0.0)                  # rounding can leave a tiny negative l0
        nrm = ti.math.vec3(v[0, 0], v[1, 0], v[2, 0]).normalized()
        if nrm[2] < 0:
            nrm = -nrm
        for a in ti.static(range(3)):
            normal[i, a] = nrm[a]
            eigval[i, a] = w[a]
            extent[i, a] = span[a]
        curvature[i] = _curvature_of(w)
        max_distance[i] = ti.sqrt(far2)


@ti.kernel
def _curvature(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), nbr: ti.types.ndarray(dtype=ti.i32, ndim=2),
               curvature: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for i in range(xyz.shape[0]):
        cov, _span, _far2, _centre = _neighbourhood_covariance(xyz, nbr, i)
        w, _v = sym_eigen3(cov, False)
        curvature[i] = _curvature_of(ti.max(w, 0.0))


@ti.kernel
def _plane_heights(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), nbr: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   min_normal_z: ti.f32, out: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for i in range(xyz.shape[0]):
        cov, _span, _far2, centre = _neighbourhood_covariance(xyz, nbr, i)
        w, v = sym_eigen3(cov)
        nrm = ti.math.vec3(v[0, 0], v[1, 0], v[2, 0]).normalized()
        z = xyz[i, 2]
        if ti.abs(nrm[2]) >= min_normal_z:
            # the height of the neighbourhood's plane (through its centroid) at the point's x, y
            z = xyz[i, 2] + centre[2] + (nrm[0] * centre[0] + nrm[1] * centre[1]) / nrm[2]
        out[i] = z


def _check_rows(nbr, n):
    if len(nbr.shape) != 2 or int(nbr.shape[0]) != n:
        raise ValueError(f"knn_indices must have shape (n, k) with n={n}, got {tuple(nbr.shape)}")


def _per_point(kernel, xyz, knn_indices, *args):
    """float32 (n,) from ``kernel(points, rows, *args, out)`` over the points and their kNN rows."""
    pts = points_array(xyz)
    nbr = index_array(knn_indices, length(xyz))
    n = length(pts)
    _check_rows(nbr, n)
    out = output_array(ti.f32, (n,), xyz)
    if n:
        kernel(pts, nbr, *args, out)
    return like_input(out, xyz)


def curvature(xyz, knn_indices):
    """float32 (n,): covariance_features' 'curvature' alone (the same values, bit for bit), from a
    kernel without eigenvectors, normals and extents: less to compile where only it is needed
    (the survey estimates)."""
    return _per_point(_curvature, xyz, knn_indices)


def plane_heights(xyz, knn_indices, min_normal_z: float = 0.5):
    """float32 (n,): each point's height on the least-squares plane of itself and its k
    neighbours (``knn_indices`` (n, k) int32, every row full), at its own x, y; points whose plane
    is steeper than ``min_normal_z`` (|normal z| below it: walls) keep their height. A moving
    least-squares step of order one: the noise of a plane's heights falls as 1 / sqrt(k + 1)."""
    return _per_point(_plane_heights, xyz, knn_indices, float(min_normal_z))


def covariance_features(xyz, knn_indices) -> dict:
    """Per-point covariance features of p plus its k neighbours (``knn_indices`` (n, k) int32,
    e.g. from ``neighbors.knn``).

    Returns a dict of numpy arrays (Taichi ndarrays when ``xyz`` is one):
    'normal' (n, 3) unit eigenvector of the smallest eigenvalue, oriented so nz >= 0;
    'eigenvalues' (n, 3) ascending; 'curvature' (n,) l0 / (l0 + l1 + l2), 0 when the sum is 0;
    'max_distance' (n,) distance to the farthest of the k neighbours;
    'extent' (n, 3) per-axis max - min of the neighbourhood coordinates."""
    pts = points_array(xyz)
    nbr = index_array(knn_indices, length(xyz))
    n = length(pts)
    _check_rows(nbr, n)
    shapes = {"normal": (n, 3), "eigenvalues": (n, 3), "curvature": (n,), "max_distance": (n,),
              "extent": (n, 3)}
    out = {name: output_array(ti.f32, shape, xyz) for name, shape in shapes.items()}
    if n:
        _covariance_features(pts, nbr, out["normal"], out["eigenvalues"], out["curvature"],
                             out["max_distance"], out["extent"])
    return {name: like_input(a, xyz) for name, a in out.items()}
