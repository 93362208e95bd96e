"""roadx_ti.chunks: chunked host work on a thread pool."""
import gc
import threading

import numpy as np

from roadx_ti.chunks import CHUNK, cyclic_gc_paused, over_chunks


def test_over_chunks_covers_every_element_once():
    n = 5 * CHUNK + 123
    hits = np.zeros(n, np.int64)

    def part(start, stop):
        hits[start:stop] += 1
    over_chunks(part, n)
    assert (hits == 1).all()


def test_no_cyclic_collection_runs_in_a_pool_thread():
    # A collection in a pool thread can free a Taichi ndarray held in a cycle, and on CUDA that
    # thread has no device context (the free aborts the process): collections stay in the caller.
    collecting_threads = []

    def record(phase, info):
        if phase == "start":
            collecting_threads.append(threading.get_ident())

    def part(start, stop):
        for _ in range(20_000):       # cycles, many times gen0's threshold per chunk
            a = []
            a.append(a)

    assert gc.isenabled()
    gc.callbacks.append(record)
    try:
        over_chunks(part, 12 * CHUNK)
    finally:
        gc.callbacks.remove(record)
    assert set(collecting_threads) <= {threading.get_ident()}
    assert gc.isenabled()


def test_gc_pause_nests_and_restores_the_callers_setting():
    assert gc.isenabled()
    with cyclic_gc_paused():
        with cyclic_gc_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()
    assert gc.isenabled()
    gc.disable()
    try:
        with cyclic_gc_paused():
            pass
        assert not gc.isenabled()     # a host that turned it off keeps it off
    finally:
        gc.enable()
