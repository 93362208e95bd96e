"""R1 uniform downsampling: a deterministic stride or a nested pattern over the point order, or a
hash of each point's own coordinates.

Stride: point j of the output is input point floor(j * n / m) (METHODS.md R1). The product j * n
can pass 2^31, so the index is computed in 64-bit integers (CPU, CUDA and Vulkan with shaderInt64).

Nested: point i is kept when (i * 2654435769) mod 2^32 < ratio * 2^32, i.e. frac(i * 0.618...)
< ratio: a Weyl sequence over the input order, as even as the stride over any run of points, but
a slightly different ratio keeps nearly the same points (the stride re-draws almost all of them),
so a density estimate that moves by 0.1 % moves the processed set by about as much.

Hashed: point i is kept when a 32-bit hash of its quantised world coordinates is below ratio *
2^32: nested like the Weyl pattern, and independent of the point order (a shuffled or re-tiled
delivery keeps the same points; the host chooses the quantisation, roadx_ti.stages.downsample).
"""
import numpy as np
from .taichi_compat import ti

from .common import is_ndarray, length, ndarray, points_array


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
    points = points_array(xyz)
    n = length(points)
    m = max(0, min(int(target), n))
    if m == 0:
        empty = (np.zeros(0, np.int32), np.zeros((0, 3), np.float32))
        return empty if not is_ndarray(xyz) else (ndarray(ti.i32, (0,)), ndarray(ti.f32, (0, 3)))
    # numpy input on the CPU backend is passed in place (no copy); outputs are allocated to match
    if is_ndarray(xyz):
        kept_index, kept_xyz = ndarray(ti.i32, (m,)), ndarray(ti.f32, (m, 3))
        _stride_gather(points, kept_xyz, kept_index, n, m, -(-m // BLOCK))
        return kept_index, kept_xyz
    kept_index, kept_xyz = np.empty(m, np.int32), np.empty((m, 3), np.float32)
    _stride_gather(points, kept_xyz, kept_index, n, m, -(-m // BLOCK))
    return kept_index, kept_xyz


WEYL = 2654435769          # round(2^32 / golden ratio)


@ti.kernel
def _weyl_keep(keep: ti.types.ndarray(dtype=ti.u8, ndim=1), threshold: ti.u32):
    for i in range(keep.shape[0]):
        key = ti.cast(i, ti.u32) * ti.u32(WEYL)      # wraps mod 2^32
        keep[i] = ti.cast(key < threshold, ti.u8)


def nested_sample(n: int, ratio: float):
    """uint8 (n,) keep flags of the nested pattern (module docstring); numpy."""
    keep = np.zeros(int(n), np.uint8)
    if n:
        threshold = int(min(max(ratio, 0.0), 1.0) * 4294967296.0)
        if threshold >= 4294967296:
            keep[:] = 1
        else:
            _weyl_keep(keep, threshold)
    return keep


@ti.func
def _fmix32(h: ti.u32) -> ti.u32:
    # murmur3's finaliser: every input bit flips each output bit with probability about 1/2
    h ^= h >> 16
    h *= ti.u32(0x85EBCA6B)
    h ^= h >> 13
    h *= ti.u32(0xC2B2AE35)
    h ^= h >> 16
    return h


@ti.kernel
def _hash_keep(cells: ti.types.ndarray(dtype=ti.u32, ndim=2), keep: ti.types.ndarray(dtype=ti.u8, ndim=1),
               threshold: ti.u32):
    for i in range(keep.shape[0]):
        h = _fmix32(cells[i, 0] ^ ti.u32(0x9E3779B9))
        h = _fmix32(h ^ cells[i, 1])
        h = _fmix32(h ^ cells[i, 2])
        keep[i] = ti.cast(h < threshold, ti.u8)


def hashed_sample(cells, ratio: float):
    """uint8 (n,) keep flags of the hashed pattern for (n, 3) uint32 quantised coordinates (the
    low 32 bits of each axis' cell number); numpy."""
    cells = np.ascontiguousarray(cells, dtype=np.uint32)
    keep = np.zeros(len(cells), np.uint8)
    if len(cells):
        threshold = int(min(max(ratio, 0.0), 1.0) * 4294967296.0)
        if threshold >= 4294967296:
            keep[:] = 1
        else:
            _hash_keep(cells, keep, threshold)
    return keep
