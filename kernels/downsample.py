"""R1 uniform downsampling: a deterministic stride over the input order.

Point j of the output is input point floor(j * n / m) (METHODS.md R1). The product j * n can pass
2^31, so the index is computed in 64-bit integers (CPU, CUDA and Vulkan with shaderInt64).
"""
import numpy as np
from .taichi_compat import ti

from .common import as_ndarray, is_ndarray, like_input, ndarray


BLOCK = 1024  # outputs per thread: one 64-bit division per block, then exact integer steps


@ti.kernel
def _stride_gather(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), kept_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                   kept_index: ti.types.ndarray(dtype=ti.i32, ndim=1), n: ti.i64, m: ti.i64, n_blocks: ti.i32):
    # n_blocks comes from the host: Vulkan's SPIR-V codegen rejects a range computed from a shape
    for block in range(n_blocks):
        start = block * BLOCK
        product = ti.cast(start, ti.i64) * n
        quotient = product // m          # floor(j * n / m) for j = start ...
        remainder = product - quotient * m   # ... and its remainder, advanced exactly per j
        # (SPIR-V has no 64-bit %, hence the products)
        step_quotient = n // m
        step_remainder = n - step_quotient * m
        for j in range(start, ti.min(start + BLOCK, kept_index.shape[0])):
            i = ti.cast(quotient, ti.i32)
            kept_index[j] = i
            for c in ti.static(range(3)):
                kept_xyz[j, c] = xyz[i, c]
            quotient += step_quotient
            remainder += step_remainder
            if remainder >= m:
                remainder -= m
                quotient += 1


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
        _stride_gather(xyz, kept_xyz, kept_index, n, m, -(-m // BLOCK))
        return kept_index, kept_xyz
    points = np.ascontiguousarray(xyz, dtype=np.float32)
    kept_index, kept_xyz = np.empty(m, np.int32), np.empty((m, 3), np.float32)
    _stride_gather(points, kept_xyz, kept_index, n, m, -(-m // BLOCK))
    return kept_index, kept_xyz
