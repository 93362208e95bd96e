"""R1 uniform downsampling: a deterministic stride over the input order.

Point j of the output is input point floor(j * n / m) (METHODS.md R1). The product j * n can pass
2^31, so the index is computed in 64-bit integers (CPU, CUDA and Vulkan with shaderInt64).
"""
import numpy as np
import taichi as ti

from .common import as_ndarray, is_ndarray, like_input, ndarray


@ti.kernel
def _stride_gather(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), kept_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                   kept_index: ti.types.ndarray(dtype=ti.i32, ndim=1), n: ti.i64, m: ti.i64):
    for j in kept_index:
        i = ti.cast(ti.cast(j, ti.i64) * n // m, ti.i32)
        kept_index[j] = i
        for c in ti.static(range(3)):
            kept_xyz[j, c] = xyz[i, c]


def uniform_sample(xyz, target: int):
    """Keep ``target`` of the n points by the R1 stride; returns (kept indices int32 ascending,
    kept coordinates (m, 3) float32), numpy or ndarrays like the input."""
    n = int(xyz.shape[0])
    m = max(0, min(int(target), n))
    if m == 0:
        empty = (np.zeros(0, np.int32), np.zeros((0, 3), np.float32))
        return empty if not is_ndarray(xyz) else (ndarray(ti.i32, (0,)), ndarray(ti.f32, (0, 3)))
    # numpy input on the CPU backend is passed in place (no copy); outputs are allocated to match
    if is_ndarray(xyz):
        kept_index, kept_xyz = ndarray(ti.i32, (m,)), ndarray(ti.f32, (m, 3))
        _stride_gather(xyz, kept_xyz, kept_index, n, m)
        return kept_index, kept_xyz
    points = np.ascontiguousarray(xyz, dtype=np.float32)
    kept_index, kept_xyz = np.empty(m, np.int32), np.empty((m, 3), np.float32)
    _stride_gather(points, kept_xyz, kept_index, n, m)
    return kept_index, kept_xyz
