"""Elementwise host (numpy) work in cache-sized chunks, on a thread per core.

numpy's ufuncs release the GIL, so the chunks of a long elementwise expression run in parallel,
and their temporaries stay in cache instead of each being a full-length array (which on a fresh
process also means fewer new pages to fault in). Each chunk writes its own slice of the outputs:
the values are those of one whole-array pass, bit for bit.

Python's cyclic garbage collector is paused while the pool runs. A collection runs in whichever
thread crosses the allocation threshold, and one in a pool thread can free a Taichi ndarray held
in a reference cycle: on CUDA that thread has no device context, and the free aborts the process
(``CUDA_ERROR_INVALID_CONTEXT ... cuMemFreeAsync``, seen on the road pipeline at 4 M points on an
H200). Paused, collections happen in the calling thread once the pool is done.
"""
from __future__ import annotations

import gc
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

CHUNK = 1 << 16

_gc_lock = threading.Lock()
_gc_pauses = 0            # pools running now (over_chunks may be called from several threads)
_gc_was_enabled = False


@contextmanager
def cyclic_gc_paused():
    """No cyclic garbage collection, in any thread, inside the block (nests; thread-safe)."""
    global _gc_pauses, _gc_was_enabled
    with _gc_lock:
        if _gc_pauses == 0:
            _gc_was_enabled = gc.isenabled()
            gc.disable()
        _gc_pauses += 1
    try:
        yield
    finally:
        with _gc_lock:
            _gc_pauses -= 1
            if _gc_pauses == 0 and _gc_was_enabled:
                gc.enable()


def over_chunks(part, n: int, chunk: int = CHUNK) -> None:
    """Call ``part(start, stop)`` for consecutive slices covering range(n); in parallel threads
    when there are enough of them to pay for the pool."""
    bounds = [(start, min(start + chunk, n)) for start in range(0, n, chunk)]
    if len(bounds) > 4 and (os.cpu_count() or 1) > 1:
        with cyclic_gc_paused(), ThreadPoolExecutor(max_workers=os.cpu_count()) as pool:
            list(pool.map(lambda b: part(*b), bounds))
    else:
        for b in bounds:
            part(*b)
