"""Neighbourhood averaging of per-point values over a neighbour graph (colour denoising).

Each point's new value is the mean of its own value and those of its neighbours (the valid
entries, >= 0, of its row of ``neighbors``). Every thread sums its own row in slot order, so the
result is bit-identical from run to run (no atomics).
"""

import numpy as np
from .taichi_compat import ti

from .common import as_ndarray, index_array, is_ndarray, like_input, ndarray, to_numpy


@ti.kernel
def _neighbor_mean(neighbors: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   src: ti.types.ndarray(dtype=ti.f32, ndim=2),
                   dst: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    for i, c in ti.ndrange(src.shape[0], src.shape[1]):
        total = src[i, c]
        count = 1
        for s in range(neighbors.shape[1]):
            j = neighbors[i, s]
            if j >= 0:
                total += src[j, c]
                count += 1
        dst[i, c] = total / ti.f32(count)


def neighbor_mean(values, neighbors, passes: int = 1):
    """Mean of each point's value and its neighbours' values, repeated ``passes`` times.

    values: float (n, c) (or (n,), treated as one channel); neighbors: int32 (n, k), -1 =
    padding or a dropped edge. Returns float32 of the shape of ``values`` (numpy or ndarray, as
    ``values``); passes = 0 returns a float32 copy. The input is never modified.
    """
    shape = tuple(values.shape)
    n = shape[0]
    if n == 0 or (len(shape) > 1 and 0 in shape[1:]):
        return np.zeros(shape, np.float32)       # (reshape(0, -1) of no value failed)
    host = to_numpy(values).astype(np.float32).reshape(n, -1) if (len(shape) == 1 or not is_ndarray(values)) else None
    a = ndarray(ti.f32, (n, host.shape[1] if host is not None else shape[1]))
    if host is not None:
        a.from_numpy(np.ascontiguousarray(host))
    else:
        a.copy_from(values)
    if int(neighbors.shape[1]) > 0 and passes > 0:
        nbr = index_array(neighbors, n)
        b = ndarray(ti.f32, tuple(a.shape))
        for _ in range(passes):
            _neighbor_mean(nbr, a, b)
            a, b = b, a
    if len(shape) == 1:
        a = as_ndarray(a.to_numpy().reshape(shape))
    return like_input(a, values)
