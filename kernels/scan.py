"""Exclusive prefix sum over int32, on every backend.

``ti.algorithms.PrefixSumExecutor`` raises on the CPU backend, so this is a blocked scan of our
own: each block is summed serially by one thread, the block totals are scanned by one thread, and
every block then writes its exclusive prefix. Work O(n), three launches, no atomics.
"""

import math

import numpy as np

from .taichi_compat import ti

from .common import kernel_array, like_input, ndarray, output_array


@ti.kernel
def _block_totals(values: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  block_total: ti.types.ndarray(dtype=ti.i32, ndim=1), n: ti.i32, block: ti.i32):
    for b in block_total:
        start = b * block
        stop = ti.min(start + block, n)
        total = 0
        for i in range(start, stop):
            total += values[i]
        block_total[b] = total


@ti.kernel
def _scan_totals(block_total: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 total_out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    ti.loop_config(serialize=True)
    for _ in range(1):
        running = 0
        for b in range(block_total.shape[0]):
            t = block_total[b]
            block_total[b] = running
            running += t
        total_out[0] = running


@ti.kernel
def _block_scan(values: ti.types.ndarray(dtype=ti.i32, ndim=1),
                block_offset: ti.types.ndarray(dtype=ti.i32, ndim=1),
                out: ti.types.ndarray(dtype=ti.i32, ndim=1), n: ti.i32, block: ti.i32):
    for b in block_offset:
        start = b * block
        stop = ti.min(start + block, n)
        running = block_offset[b]
        for i in range(start, stop):
            v = values[i]
            out[i] = running
            running += v


def exclusive_scan_into(values, out) -> int:
    """out[i] = sum(values[:i]) for int32 ndarrays; returns the grand total (must fit in int32)."""
    n = int(values.shape[0])
    if n == 0:
        return 0
    n_blocks = max(1, min(65536, int(math.sqrt(n)) * 4))
    block = -(-n // n_blocks)
    n_blocks = -(-n // block)
    block_total = ndarray(ti.i32, (n_blocks,))
    total = ndarray(ti.i32, (1,))
    _block_totals(values, block_total, n, block)
    _scan_totals(block_total, total)
    _block_scan(values, block_total, out, n, block)
    return int(total[0])


def exclusive_scan(values):
    """Exclusive prefix sum of an int32 array (numpy or ndarray); returns (prefix, total)."""
    if int(values.shape[0]) == 0:
        return (np.zeros(0, np.int32) if not hasattr(values, "to_numpy") else values), 0
    src = kernel_array(values, "int32")
    out = output_array(ti.i32, (int(src.shape[0]),), values)
    total = exclusive_scan_into(src, out)
    return like_input(out, values), total
