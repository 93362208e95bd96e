"""roadx_ti.chunks: chunked host work on a thread pool."""
import gc
import os
import threading
from contextlib import contextmanager

import numpy as np

from roadx_ti.chunks import CHUNK, cyclic_gc_paused, over_chunks


def test_over_chunks_covers_every_element_once():
    n = 5 * CHUNK + 123
    hits = np.zeros(n, np.int64)

    def part(start, stop):
        hits[start:stop] += 1
    over_chunks(part, n)
    assert (hits == 1).all()


@contextmanager
def collecting_threads():
    """The set of thread idents in which a cyclic collection starts inside the block."""
    threads = set()

    def record(phase, info):
        if phase == "start":
            threads.add(threading.get_ident())
    gc.callbacks.append(record)
    try:
        yield threads
    finally:
        gc.callbacks.remove(record)


def test_no_cyclic_collection_runs_in_a_pool_thread(monkeypatch):
    # A collection in a pool thread can free a Taichi ndarray held in a cycle, and on CUDA that
    # thread has no device context (the free aborts the process): collections stay in the caller.
    def part(start, stop):
        for _ in range(20_000):       # cycles, many times gen0's threshold per chunk
            a = []
            a.append(a)

    monkeypatch.setattr(os, "cpu_count", lambda: 4)     # a pool even on a one-core machine
    assert gc.isenabled()
    with collecting_threads() as threads:
        over_chunks(part, 12 * CHUNK)
    assert set(threads) <= {threading.get_ident()}
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


def test_gpu_work_off_the_main_thread_collects_in_its_own_thread(monkeypatch):
    # A Dask worker's task thread on CUDA: collections wait for the block's end and run there,
    # not in the worker's event loop thread (which has no CUDA context).
    from roadx_ti import backend

    monkeypatch.setattr(backend, "current_arch", lambda: "cuda")
    seen = {}

    def task():
        seen["task"] = threading.get_ident()
        with backend.collect_in_this_thread():
            seen["enabled_inside"] = gc.isenabled()
            a = []
            a.append(a)              # cyclic garbage left for the collection at the block's end
            del a
            threads.clear()          # only the collections from here on
        seen["enabled_after"] = gc.isenabled()

    with collecting_threads() as threads:
        worker = threading.Thread(target=task)
        worker.start()
        worker.join()
    seen["threads"] = threads
    assert seen["enabled_inside"] is False and seen["enabled_after"] is True
    assert seen["task"] in seen["threads"]            # the block's end collected, in the task thread

    with backend.collect_in_this_thread():            # the main thread: nothing changes
        assert gc.isenabled()
