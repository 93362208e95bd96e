"""Elementwise host (numpy) work in cache-sized chunks, on a thread per core.

numpy's ufuncs release the GIL, so the chunks of a long elementwise expression run in parallel,
and their temporaries stay in cache instead of each being a full-length array (which on a fresh
process also means fewer new pages to fault in). Each chunk writes its own slice of the outputs:
the values are those of one whole-array pass, bit for bit.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

CHUNK = 1 << 16


def over_chunks(part, n: int, chunk: int = CHUNK) -> None:
    """Call ``part(start, stop)`` for consecutive slices covering range(n); in parallel threads
    when there are enough of them to pay for the pool."""
    bounds = [(start, min(start + chunk, n)) for start in range(0, n, chunk)]
    if len(bounds) > 4 and (os.cpu_count() or 1) > 1:
        with ThreadPoolExecutor(max_workers=os.cpu_count()) as pool:
            list(pool.map(lambda b: part(*b), bounds))
    else:
        for b in bounds:
            part(*b)
