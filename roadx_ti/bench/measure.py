"""One worker subprocess: the jobs of a spec file measured one by one (first call, timed repeats,
peak RSS), one JSON line per row. The anchors' worker never imports Taichi."""
from __future__ import annotations

import ctypes
import gc
import json
import os
import statistics
import time
import traceback
from pathlib import Path

from roadx_ti import jsonio
from roadx_ti.bench.cases import load_case, make_scene

ANCHORS_BACKEND = "cpu"          # anchors are CPU libraries; their rows carry this backend
_ANCHORS_WORKER = "anchors"      # the pseudo-backend of the worker that runs them (no Taichi)
_UNAVAILABLE = "backend not available: "
SLOW_ANCHOR_BUDGETS = 5   # an anchor call longer than 5 repeat budgets is timed once (its warm-up)


def _row_backend(worker_backend: str) -> str:
    return ANCHORS_BACKEND if worker_backend == _ANCHORS_WORKER else worker_backend


def _blank_row(job: dict, backend: str) -> dict:
    return {"stage": job["stage"], "variant": job["variant"], "params": job["params"], "points": job["points"],
            "scene": job["scene"], "backend": backend, "impl": job["impl"], "status": "ok", "error": None,
            "median_s": None, "min_s": None, "repeats": 0, "times_s": [], "first_call_s": None,
            "mpts_per_s": None, "peak_rss_mb": None, "base_rss_mb": None, "bytes_per_point": None,
            "threads": None, "os_threads": None}



def worker_main(spec_path: str) -> int:
    """Entry point of one worker subprocess: run the jobs of a spec file, one JSON line per row."""
    spec = json.loads(Path(spec_path).read_text())
    backend = spec["backend"]
    out = open(spec["rows_path"], "a", buffering=1)

    def emit(record):
        out.write(jsonio.dumps(record) + "\n")
        out.flush()

    row_backend = _row_backend(backend)
    threads = None
    if backend != _ANCHORS_WORKER:
        from roadx_ti import backend as be
        try:
            be.init(backend, threads=spec.get("threads"))
        except Exception as exc:  # BackendError, or Taichi's own
            for job in spec["jobs"]:
                emit(_blank_row(job, row_backend) | {"status": "missing",
                                                      "error": f"{_UNAVAILABLE}{backend}: {exc}"[:300]})
            return 0
        threads = _taichi_threads(backend)
    scenes: dict = {}
    for job in spec["jobs"]:
        emit({"event": "begin", "job": [job["stage"], job["variant"], job["impl"]]})
        row = _blank_row(job, row_backend)
        if job.get("max_points") and job["points"] > job["max_points"]:
            emit(row | {"status": "skipped", "error": f"variant limited to {job['max_points']} points"})
            continue
        try:
            key = (job["scene"], job["points"])
            if key not in scenes:
                scenes.clear()   # one scene in memory at a time
                gc.collect()
                scenes[key] = make_scene(job["scene"], job["points"], spec["seed"])
            row |= _measure(job, scenes[key], spec, backend)
        except ImportError as exc:
            row |= {"status": "missing", "error": f"{type(exc).__name__}: {exc}"[:300]}
        except Exception as exc:  # reported, never dropped
            tb = traceback.extract_tb(exc.__traceback__)[-1]
            # Taichi's compile errors span many lines and underline code with carets
            text = " ".join(w for w in str(exc).split() if w.strip("^~"))
            if len(text) > 320:
                text = "..." + text[-320:]
            row |= {"status": "error", "error": f"{type(exc).__name__}: {text} ({Path(tb.filename).name}:{tb.lineno})"}
        row["threads"] = threads if job["impl"] == "roadx_ti" else _anchor_threads(job["impl"])
        row["os_threads"] = _proc_status_kb("Threads")
        emit(row)
    out.close()
    return 0


def _measure(job, scene, spec, backend) -> dict:
    case = load_case(job["stage"])
    setup = case.IMPLS[job["impl"]]
    call = setup(scene, **job["params"])
    sync = _sync if backend != _ANCHORS_WORKER else (lambda: None)
    gc.collect()
    _malloc_trim()
    base_kb = _proc_status_kb("VmRSS")
    _reset_peak_rss()
    t0 = time.perf_counter()
    result = call()
    sync()
    first = time.perf_counter() - t0
    del result
    if spec["first_call_only"]:
        return {"first_call_s": round(first, 5), "status": "ok"}
    times: list[float] = []
    budget, lo, hi = spec["budget"], spec["min_repeats"], spec["max_repeats"]
    # an anchor compiles nothing: when one call costs this much, its warm-up is the sample
    warmup_is_sample = job["impl"] != "roadx_ti" and first >= SLOW_ANCHOR_BUDGETS * budget
    done = warmup_is_sample
    if done:
        times.append(first)
    while not done:
        t0 = time.perf_counter()
        result = call()
        sync()
        times.append(time.perf_counter() - t0)
        del result
        total = sum(times)
        # stop: enough repeats and budget spent, or the cap, or a slow case past twice its budget
        done = len(times) >= hi or (len(times) >= lo and total >= budget) or total >= 2 * budget
    peak_kb = _proc_status_kb("VmHWM")
    median = statistics.median(times)
    n = job["points"]
    row = {"median_s": round(median, 6), "min_s": round(min(times), 6), "repeats": len(times),
           "times_s": [round(t, 6) for t in times], "first_call_s": round(first, 5),
           "warmup_is_sample": warmup_is_sample,
           "mpts_per_s": round(n / median / 1e6, 4) if median > 0 else None,
           "peak_rss_mb": round(peak_kb / 1024, 1) if peak_kb else None,
           "base_rss_mb": round(base_kb / 1024, 1) if base_kb else None,
           "bytes_per_point": round(max(peak_kb - base_kb, 0) * 1024 / n, 1) if peak_kb and base_kb else None,
           "status": "ok"}
    if job["impl"] == "roadx_ti":
        row["compile_s"] = round(max(first - median, 0.0), 5)
    return row



def _sync():
    from roadx_ti.kernels.taichi_compat import ti
    ti.sync()


def _taichi_threads(backend: str):
    if backend == "cpu":
        from roadx_ti.kernels.taichi_compat import cpu_threads
        return cpu_threads()
    if backend == "vulkan":   # lavapipe runs compute on LP_NUM_THREADS threads (default: all cores)
        return int(os.environ.get("LP_NUM_THREADS") or os.cpu_count() or 1)
    return None


def _anchor_threads(impl: str):
    # nominal: numpy is single-threaded; Open3D (OpenMP), scipy (workers=-1), CSF (OpenMP) use all cores
    if impl == "numpy":
        return 1
    return int(os.environ.get("OMP_NUM_THREADS") or os.cpu_count() or 1)


def _proc_status_kb(field: str):
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    if field == "VmHWM":
        import resource
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return None


def _reset_peak_rss():
    # Linux: writing 5 resets the high-water mark (VmHWM) to the current RSS
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        pass


def _malloc_trim():
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass

