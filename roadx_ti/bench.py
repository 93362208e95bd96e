"""`python -m roadx_ti bench`: every kernel stage and both pipelines against their anchors.

The cases live in ``benchmarks/`` at the repository root, one module per stage (``knn.py``,
``sor.py``, ...). A case module declares

    STAGE = "knn"                     # row name in the JSON and the table
    SCENE = "uav-road"                # synthetic scene kind it runs on
    VARIANTS = [{"name": "k16", "params": {"k": 16}}]   # optional "impls", "max_points"
    TARGETS = {"scipy": 5.0}          # speed-up over each anchor the issues ask for (optional)
    IMPLS = {"roadx_ti": setup_fn, "scipy": setup_fn, ...}

where ``setup_fn(scene, **params)`` does the untimed preparation (imports, inputs built from the
scene) and returns the zero-argument callable that is timed. An ImportError anywhere in a setup
or a call marks the row ``missing``; any other exception marks it ``error``; neither is dropped.

Method: every (backend, size) runs in its own subprocess (the anchors in one more, without Taichi),
so the peak RSS and first-call times of one backend never leak into another. In a worker, each
case is set up, called once (``first_call_s``: compile or offline-cache load plus one run), then
called again until the repeat budget is spent (median reported, ``median_s``). The peak RSS is
the process high-water mark during the timed calls (reset per case through
/proc/self/clear_refs), ``bytes_per_point`` its growth over the RSS before the first call.
With ``--cache fresh`` (the default of a full run) the workers share a new empty Taichi offline
cache: the smallest size pays the compile (``offline_cache: cold``), and one more worker at that
size, started with the cache then warm, records ``first_call_cached_s``.
"""
from __future__ import annotations

import argparse
import ctypes
import datetime as _dt
import gc
import importlib.util
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

from roadx_ti import jsonio

REPO_ROOT = Path(__file__).resolve().parents[1]
BENCH_DIR = REPO_ROOT / "benchmarks"        # the cases, RESULTS.md and throughput.png
DEFAULT_OUT = BENCH_DIR / "out"
CASES_ENV = "ROADX_BENCH_CASES"              # another folder of cases (tests of the harness)
# Order of the table and of a run: kernel stages in pipeline order, then the pipelines.
STAGES = ("voxel_hash", "knn", "uniform_downsample", "voxel_downsample", "sor", "normals", "ransac",
          "grid_min", "csf", "label_propagation", "road_pipeline", "roof_pipeline")
ANCHORS_BACKEND = "cpu"          # anchors are CPU libraries; their rows carry this backend
_ANCHORS_WORKER = "anchors"      # the pseudo-backend of the worker that runs them (no Taichi)
_UNAVAILABLE = "backend not available: "
SLOW_ANCHOR_BUDGETS = 5   # an anchor call longer than 5 repeat budgets is timed once (its warm-up)
FULL_SIZES = (1_000_000, 4_000_000, 16_000_000)
QUICK_SIZES = (50_000, 200_000)


# ------------------------------------------------------------------------------ command line
def _point_count(text: str) -> int:
    # imported here: anchor workers import this module and must not pay for Taichi's import
    from roadx_ti.config import parse_point_count

    return parse_point_count(text)



def _list(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of the `bench` subcommand (the CLI adds them to its subparser)."""
    p.add_argument("--quick", action="store_true",
                   help=f"tiny sizes ({', '.join(map(_fmt_points, QUICK_SIZES))}), CPU (+ Vulkan at the smallest "
                        "size when present), few repeats: a smoke run of the harness")
    p.add_argument("--backends", type=_list, metavar="B[,B..]",
                   help="Taichi backends (default: cpu,vulkan,cuda; unavailable ones are reported missing)")
    p.add_argument("--sizes", type=lambda s: [_point_count(v) for v in _list(s)], metavar="N[,N..]",
                   help="scene sizes in points, e.g. 1M,4M,16M (the default)")
    p.add_argument("--anchor-sizes", type=lambda s: [_point_count(v) for v in _list(s)], metavar="N[,N..]",
                   help="run the anchors at these sizes only (default: every size), e.g. 1M,4M to spare "
                        "minutes of single-threaded reference code at 16M")
    p.add_argument("--stages", type=_list, metavar="S[,S..]", help=f"stages (default: all): {', '.join(STAGES)}")
    p.add_argument("--impls", type=_list, metavar="I[,I..]",
                   help="only these implementations, e.g. roadx_ti or roadx_ti,open3d (default: all)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR", help=f"JSON output folder (default {DEFAULT_OUT})")
    p.add_argument("--results", type=Path, default=None, metavar="PATH",
                   help="results page to write (default: benchmarks/RESULTS.md for a full run, DIR/RESULTS.md "
                        "for --quick)")
    p.add_argument("--plot", type=Path, default=None, metavar="PATH",
                   help="throughput PNG (default: next to the results page, throughput.png)")
    p.add_argument("--render", nargs="+", type=Path, metavar="JSON",
                   help="only regenerate the results page and plot from these run files (e.g. a CPU and a CUDA run)")
    p.add_argument("--cache", choices=["fresh", "default"], default=None,
                   help="Taichi offline cache: 'fresh' = a new empty one (first call = compile) plus a warm-cache "
                        "rerun; 'default' = Taichi's own, as it is (default: fresh, default with --quick)")
    p.add_argument("--threads", type=int, default=None, help="CPU threads for Taichi (default: all)")
    p.add_argument("--budget", type=float, default=None, metavar="S",
                   help="seconds of timed repeats per case (default 4, 0.3 with --quick)")
    p.add_argument("--rounds", type=int, default=None, metavar="R",
                   help="alternate the CPU (and CUDA) workers with the anchors' worker R times per size and pool "
                        "their timed repeats, so that load drifting on a shared machine hits both sides alike "
                        "(default 2; 1 with --quick)")
    p.add_argument("--seed", type=int, default=0, help="synthetic scene seed")
    p.add_argument("--timeout", type=float, default=None, metavar="S",
                   help="give up on a worker after S seconds (its unfinished cases become error rows)")


def main(args) -> int:
    """Run the `bench` subcommand from parsed ``args``; returns the exit code."""
    if args.render:
        runs = [json.loads(Path(p).read_text()) for p in args.render]
        results = args.results or BENCH_DIR / "RESULTS.md"
        plot = args.plot or results.with_name("throughput.png")
        write_results(runs, results, plot)
        print(f"wrote {results} and {plot}", file=sys.stderr)
        return 0
    plan = _plan(args)
    if isinstance(plan, str):
        print(f"roadx_ti: {plan}", file=sys.stderr)
        return 2
    run = execute(plan)
    out_dir = plan["out"]
    out_dir.mkdir(parents=True, exist_ok=True)
    json_path = out_dir / f"bench-{run['meta']['run_id']}.json"
    json_path.write_text(jsonio.dumps(run, indent=1))
    results = args.results or (out_dir / "RESULTS.md" if args.quick else BENCH_DIR / "RESULTS.md")
    plot = args.plot or results.with_name("throughput.png")
    write_results([run], results, plot)
    bad = [r for r in run["rows"] if r["status"] == "error"]
    print(f"roadx_ti bench: {len(run['rows'])} rows ({len(bad)} errors) in {run['meta']['seconds']:.0f} s; "
          f"wrote {json_path}, {results}, {plot}", file=sys.stderr)
    return 0


def _plan(args) -> dict | str:
    quick = bool(args.quick)
    sizes = args.sizes or list(QUICK_SIZES if quick else FULL_SIZES)
    stages = args.stages or list(STAGES)
    unknown = [s for s in stages if s not in STAGES]
    if unknown:
        return f"unknown stage(s) {', '.join(unknown)}; known: {', '.join(STAGES)}"
    backends = args.backends or (["cpu", "vulkan"] if quick else ["cpu", "vulkan", "cuda"])
    bad = [b for b in backends if b not in ("cpu", "vulkan", "cuda", "metal")]
    if bad:
        return f"unknown backend(s) {', '.join(bad)}; known: cpu, vulkan, cuda, metal"
    cache = args.cache or ("default" if quick else "fresh")
    budget = args.budget if args.budget is not None else (0.3 if quick else 4.0)
    rounds = args.rounds if args.rounds is not None else (1 if quick else 2)
    if rounds < 1:
        return f"--rounds must be >= 1, got {rounds}"
    return {
        "rounds": rounds,
        "quick": quick, "sizes": sorted(set(sizes)), "stages": stages, "backends": backends,
        "impls": args.impls, "anchor_sizes": args.anchor_sizes, "cache": cache, "threads": args.threads, "seed": args.seed,
        "budget": budget, "min_repeats": 2 if quick else 3, "max_repeats": 5 if quick else 9,
        "timeout": args.timeout, "out": args.out or DEFAULT_OUT,
        "command": _command_line(args, sizes, stages, backends),
    }


def _command_line(args, sizes, stages, backends) -> str:
    """The command that reproduces this run (the options that change what is measured)."""
    parts = ["python -m roadx_ti bench"] + (["--quick"] if args.quick else [])
    parts += ["--backends", ",".join(backends), "--sizes", ",".join(_fmt_points(n) for n in sizes)]
    if args.stages:
        parts += ["--stages", ",".join(stages)]
    anchor_sizes = ",".join(_fmt_points(n) for n in args.anchor_sizes or [])
    for flag, value in (("--impls", ",".join(args.impls or [])), ("--anchor-sizes", anchor_sizes),
                        ("--cache", args.cache),
                        ("--threads", args.threads), ("--budget", args.budget), ("--rounds", args.rounds),
                        ("--seed", args.seed if args.seed else None)):
        if value:
            parts += [flag, str(value)]
    return " ".join(parts)


# -------------------------------------------------------------------------------- the cases
def load_case(stage: str):
    """The case module benchmarks/<stage>.py, loaded by path (benchmarks/ is not a package)."""
    path = Path(os.environ.get(CASES_ENV) or BENCH_DIR) / f"{stage}.py"
    spec = importlib.util.spec_from_file_location(f"roadx_bench_case_{stage}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _jobs(stage: str, points: int, impls_filter, *, anchors: bool, quick: bool = False) -> list[dict]:
    """(stage, variant, impl) jobs of one case at one size: the roadx_ti impl, or the anchors.
    A variant marked ``"quick": False`` (seconds even on tiny scenes) is left out of --quick, and so
    are the pipelines above the smallest quick size."""
    case = load_case(stage)
    jobs = []
    for variant in getattr(case, "VARIANTS", [{"name": "", "params": {}}]):
        if quick and not variant.get("quick", True):
            continue
        if quick and stage.endswith("_pipeline") and points > QUICK_SIZES[0]:
            continue   # --quick: the pipelines at the smallest size only
        names = variant.get("impls") or list(case.IMPLS)
        for impl in names:
            if (impl == "roadx_ti") == anchors:
                continue
            if impls_filter and impl not in impls_filter:
                continue
            jobs.append({"stage": stage, "variant": variant["name"], "impl": impl, "points": points,
                         "params": variant.get("params", {}), "scene": getattr(case, "SCENE", "uav-road"),
                         "max_points": variant.get("max_points")})
    return jobs


# ------------------------------------------------------------------------------- the runner
def execute(plan: dict) -> dict:
    """Run every worker of ``plan``; return the run record {"meta": ..., "rows": [...]}."""
    t_start = time.perf_counter()
    run_id = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    tmp = Path(tempfile.mkdtemp(prefix="roadx_bench_"))
    cache_dir = tmp / "ticache" if plan["cache"] == "fresh" else None
    rows: list[dict] = []
    plan["workers"] = []
    unavailable: dict[str, str] = {}   # backend -> why (found by its first worker; not retried)
    try:
        for size_index, points in enumerate(plan["sizes"]):
            for backend in plan["backends"]:
                if plan["quick"] and backend != "cpu" and size_index > 0:
                    continue   # --quick: the GPU-style backends at the smallest size only
                jobs = [j for s in plan["stages"] for j in _jobs(s, points, plan["impls"], anchors=False,
                                                                        quick=plan["quick"])]
                if not jobs:
                    continue
                if backend in unavailable:
                    rows += [_blank_row(j, backend) | {"status": "missing", "error": unavailable[backend]}
                             for j in jobs]
                    continue
                cache_state = "default" if cache_dir is None else ("cold" if size_index == 0 else "warm")
                got = _run_worker(plan, backend, jobs, tmp, cache_dir, extra={"offline_cache": cache_state})
                rows += got
                if got and all((r["error"] or "").startswith(_UNAVAILABLE) for r in got):
                    unavailable[backend] = got[0]["error"]
                    continue
                if cache_dir is not None and size_index == 0:
                    # the offline-cache effect: a fresh process, same size, cache now warm
                    cached = _run_worker(plan, backend, jobs, tmp, cache_dir, first_call_only=True)
                    by_key = {_key(r): r for r in cached if r["status"] == "ok"}
                    for r in got:
                        if r["status"] == "ok" and _key(r) in by_key:
                            r["first_call_cached_s"] = by_key[_key(r)]["first_call_s"]
            if plan["anchor_sizes"] and points not in plan["anchor_sizes"]:
                continue
            anchor_jobs = [j for s in plan["stages"] for j in _jobs(s, points, plan["impls"], anchors=True,
                                                                          quick=plan["quick"])]
            if not anchor_jobs:
                continue
            rows += _run_worker(plan, _ANCHORS_WORKER, anchor_jobs, tmp, None)
            compared = {(j["stage"], j["variant"]) for j in anchor_jobs}
            for _ in range(plan["rounds"] - 1):
                # ABAB: more repeats of the CPU-side workers and of the anchors, alternating (only
                # the cases that have an anchor: a ratio is what the rounds protect)
                for backend in (b for b in plan["backends"] if b in ROUND_BACKENDS and b not in unavailable):
                    jobs = [j for s in plan["stages"] for j in _jobs(s, points, plan["impls"], anchors=False,
                                                                            quick=plan["quick"])
                            if (j["stage"], j["variant"]) in compared]
                    pool_round(rows, _run_worker(plan, backend, jobs, tmp, cache_dir))
                pool_round(rows, _run_worker(plan, _ANCHORS_WORKER, anchor_jobs, tmp, None))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    add_ratios(rows)
    meta = {"run_id": run_id, "command": plan["command"], "machine": machine_facts(plan["backends"]),
            "sizes": plan["sizes"], "backends": plan["backends"], "stages": plan["stages"],
            "quick": plan["quick"], "cache": plan["cache"], "budget_s": plan["budget"], "rounds": plan["rounds"],
            "seconds": round(time.perf_counter() - t_start, 1), "workers": plan["workers"]}
    for r in rows:
        r["run_id"] = run_id
    return {"meta": meta, "rows": rows}


ROUND_BACKENDS = ("cpu", "cuda")   # the workers --rounds repeats beside the anchors


def pool_round(rows: list[dict], extra: list[dict]) -> None:
    """Pool the timed repeats of a later round into the first round's rows (same case); the
    median and min are recomputed over all repeats, the peak RSS is the larger."""
    by_key = {_key(r): r for r in rows if r["status"] == "ok" and r["times_s"]}
    for new in extra:
        row = by_key.get(_key(new))
        if row is None or new["status"] != "ok" or not new["times_s"]:
            continue
        row["times_s"] = row["times_s"] + new["times_s"]
        row["repeats"] = len(row["times_s"])
        row["rounds"] = row.get("rounds", 1) + 1
        median = statistics.median(row["times_s"])
        row["median_s"], row["min_s"] = round(median, 6), round(min(row["times_s"]), 6)
        row["mpts_per_s"] = round(row["points"] / median / 1e6, 4) if median > 0 else None
        if new.get("peak_rss_mb") and (row.get("peak_rss_mb") or 0) < new["peak_rss_mb"]:
            row["peak_rss_mb"], row["bytes_per_point"] = new["peak_rss_mb"], new.get("bytes_per_point")
        if row["impl"] == "roadx_ti" and row.get("first_call_s") is not None:
            row["compile_s"] = round(max(row["first_call_s"] - median, 0.0), 5)


def _key(row) -> tuple:
    return (row["stage"], row["variant"], row["impl"], row["points"], row["backend"])


def _run_worker(plan, backend, jobs, tmp: Path, cache_dir, *, first_call_only=False, extra=None) -> list[dict]:
    """Run ``jobs`` in worker subprocesses (restarted after a crash); return their rows."""
    rows: list[dict] = []
    remaining = list(jobs)
    attempt = 0
    while remaining:
        attempt += 1
        # a fresh row file per worker (a later round of the same backend and size must not read
        # the rows of the earlier one)
        stem = tmp / f"{len(plan['workers'])}-{backend}-{remaining[0]['points']}-{attempt}-{int(first_call_only)}"
        spec = {"backend": backend, "jobs": remaining, "rows_path": str(stem) + ".jsonl",
                "first_call_only": first_call_only, "threads": plan["threads"], "seed": plan["seed"],
                "budget": plan["budget"], "min_repeats": plan["min_repeats"],
                "max_repeats": plan["max_repeats"]}
        Path(str(stem) + ".json").write_text(json.dumps(spec))
        env = dict(os.environ)
        if cache_dir is not None:
            env["TI_OFFLINE_CACHE_FILE_PATH"] = str(cache_dir)
        cmd = [sys.executable, "-c", "import sys; from roadx_ti.bench import worker_main; "
               "sys.exit(worker_main(sys.argv[1]))", str(stem) + ".json"]
        label = f"{backend} {_fmt_points(remaining[0]['points'])}{' (cached first call)' if first_call_only else ''}"
        print(f"roadx_ti bench: {label}: {len(remaining)} case(s)", file=sys.stderr, flush=True)
        failure = None
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, env=env, cwd=str(REPO_ROOT), timeout=plan["timeout"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if proc.returncode != 0:
                tail = (proc.stderr or "").strip().splitlines()[-3:]
                failure = f"worker exited with status {proc.returncode}: {' | '.join(tail)}"[:400]
        except subprocess.TimeoutExpired:
            failure = f"worker timed out after {plan['timeout']} s"
        plan["workers"].append({"backend": backend, "points": remaining[0]["points"], "cases": len(remaining),
                                "first_call_only": first_call_only,
                                "seconds": round(time.perf_counter() - t0, 1)})
        got, started = _read_rows(Path(spec["rows_path"]))
        for r in got:
            r.update(extra or {})
        rows += got
        done = {(r["stage"], r["variant"], r["impl"]) for r in got}
        remaining = [j for j in remaining if (j["stage"], j["variant"], j["impl"]) not in done]
        if failure is None and remaining:
            failure = "worker ended without running this case"
        if remaining:
            # the case in progress when the worker died gets the error; the rest are retried
            victim = next((j for j in remaining if (j["stage"], j["variant"], j["impl"]) == started),
                          remaining[0])
            rows.append(_blank_row(victim, _row_backend(backend)) | {"status": "error", "error": failure})
            remaining.remove(victim)
    return rows


def _read_rows(path: Path):
    rows, started = [], None
    if not path.exists():
        return rows, started
    for line in path.read_text().splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            continue   # a line cut short by a crash
        if record.get("event") == "begin":
            started = tuple(record["job"])
        else:
            rows.append(record)
    return rows, started


def _row_backend(worker_backend: str) -> str:
    return ANCHORS_BACKEND if worker_backend == _ANCHORS_WORKER else worker_backend


def _blank_row(job: dict, backend: str) -> dict:
    return {"stage": job["stage"], "variant": job["variant"], "params": job["params"], "points": job["points"],
            "scene": job["scene"], "backend": backend, "impl": job["impl"], "status": "ok", "error": None,
            "median_s": None, "min_s": None, "repeats": 0, "times_s": [], "first_call_s": None,
            "mpts_per_s": None, "peak_rss_mb": None, "base_rss_mb": None, "bytes_per_point": None,
            "threads": None, "os_threads": None}


def add_ratios(rows: list[dict]) -> None:
    """ratio = anchor median / roadx_ti median (a speed-up; > 1: roadx_ti is faster), both ways:
    a roadx_ti row gets {anchor: ratio}, an anchor row gets {backend: ratio}."""
    ok = [r for r in rows if r["status"] == "ok" and r["median_s"]]
    for r in rows:
        r["ratio"] = {}
    for mine in (r for r in ok if r["impl"] == "roadx_ti"):
        for other in ok:
            if other["impl"] == "roadx_ti" or (other["stage"], other["variant"], other["points"]) != \
                    (mine["stage"], mine["variant"], mine["points"]):
                continue
            ratio = round(other["median_s"] / mine["median_s"], 3)
            mine["ratio"][other["impl"]] = ratio
            other["ratio"][mine["backend"]] = ratio


# ------------------------------------------------------------------------------- the worker
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


def open3d_cloud(xyz):
    """An Open3D PointCloud of (n, 3) points (built outside the timing of the Open3D anchors)."""
    import numpy as np
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(xyz, np.float64)))


def pipeline_call(scene, config: str, pipeline: str):
    """The timed call of a pipeline case: the stages of ``config`` (relative to the repository),
    or the pipeline's default stages while that file does not exist."""
    from roadx_ti import config as cfg_mod
    from roadx_ti import pipelines

    path = REPO_ROOT / config
    specs = cfg_mod.load(path).stage_list() if path.is_file() else pipelines.default_stage_specs(pipeline)
    stages = pipelines.build_stages(specs)
    return lambda: pipelines.run(scene, stages)


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


# ------------------------------------------------------------------------------ the scenes
def make_scene(kind: str, points: int, seed: int):
    """The synthetic scene of the pipelines (roadx_ti.synthetic), or a stand-in while it is absent."""
    try:
        from roadx_ti import synthetic
    except ImportError:
        return _standin_scene(kind, points, seed)
    return synthetic.generate(kind, points, seed)


def _standin_scene(kind: str, n: int, seed: int):
    """Terrain + road strip + boxes + trees + a few outliers at a constant density (so that time
    should grow linearly with n): only for developing the harness before roadx_ti.synthetic."""
    import numpy as np

    from roadx_ti.cloud import Cloud

    rng = np.random.default_rng(seed)
    density = 100.0 if kind == "uav-road" else 20.0   # points per m^2
    side = float(np.sqrt(n / density))
    n_box, n_tree, n_out = int(0.15 * n), int(0.10 * n), max(1, int(0.002 * n))
    n_ground = n - n_box - n_tree - n_out
    xy = rng.uniform(0, side, (n, 2))
    z = 0.02 * xy[:, 0] + 0.5 * np.sin(xy[:, 1] / 37.0) + rng.normal(0, 0.02, n)
    cls = np.full(n, 2, np.uint8)
    rgb = np.empty((n, 3), np.float64)
    rgb[:] = (80, 130, 60)
    road = np.abs(xy[:, 1] - side / 2) < min(5.0, side / 8)
    road[n_ground:] = False
    cls[road] = 11
    rgb[road] = (120, 120, 125)
    # boxes: 20 m squares on a lattice, flat or gabled roofs 4..12 m up
    b = slice(n_ground, n_ground + n_box)
    cell = np.floor(xy[b] / 40.0)
    h = 4.0 + 8.0 * ((cell[:, 0] * 7 + cell[:, 1] * 3) % 5) / 4.0
    xy[b] = cell * 40.0 + 10.0 + rng.uniform(0, 20.0, (n_box, 2))
    z[b] = z[b] + h + 0.2 * np.abs(xy[b, 0] % 40.0 - 20.0) * (cell[:, 1] % 2)
    cls[b] = 6
    rgb[b] = (150, 60, 50)
    t = slice(n_ground + n_box, n_ground + n_box + n_tree)
    centre = rng.uniform(0, side, (max(1, n_tree // 400), 2))
    which = rng.integers(0, len(centre), n_tree)
    xy[t] = centre[which] + rng.normal(0, 1.5, (n_tree, 2))
    z[t] = z[t] + 3.0 + np.abs(rng.normal(0, 2.0, n_tree))
    cls[t] = 5
    rgb[t] = (40, 110, 40)
    o = slice(n - n_out, n)
    z[o] = z[o] + rng.uniform(-20, 40, n_out)
    cls[o] = 7
    rgb += rng.normal(0, 6, (n, 3))
    xyz = np.column_stack([xy, z - z.min()]).astype(np.float32)
    rgb16 = (np.clip(rgb, 0, 255) * 257).astype(np.uint16)
    return Cloud(xyz=xyz, origin=np.zeros(3), rgb=rgb16, color_depth=16, classification=cls,
                 source=f"stand-in {kind} scene ({n} points, seed {seed})")


# ---------------------------------------------------------------------------- machine facts
def machine_facts(backends) -> dict:
    facts = {"cpu_model": _cpu_model(), "logical_cores": os.cpu_count(),
             "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
             "memory_gb": _mem_total_gb(), "os": platform.platform(), "python": platform.python_version(),
             "versions": _versions(), "synthetic": _synthetic_source()}
    if "vulkan" in backends:
        facts["vulkan"] = _vulkan_device()
    if "cuda" in backends:
        facts["cuda"] = _cuda_device()
    return facts


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _mem_total_gb():
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        return None


def _versions() -> dict:
    from importlib import metadata

    out = {}
    for dist in ("roadx_ti", "taichi", "numpy", "scipy", "open3d-cpu", "open3d", "cloth-simulation-filter"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


def _synthetic_source() -> str:
    return "roadx_ti.synthetic" if importlib.util.find_spec("roadx_ti.synthetic") else \
        "stand-in generator of roadx_ti.bench (roadx_ti.synthetic absent)"


def _vulkan_device():
    exe = shutil.which("vulkaninfo")
    if not exe:
        return {"note": "vulkaninfo not installed"}
    try:
        text = subprocess.run([exe, "--summary"], capture_output=True, text=True, timeout=20).stdout
    except (subprocess.SubprocessError, OSError) as exc:
        return {"note": f"vulkaninfo failed: {exc}"}
    devices, current = [], None
    for line in text.splitlines():
        key, _, value = (s.strip() for s in line.partition("="))
        if key == "apiVersion":
            current = {"api": value}
            devices.append(current)
        elif current is not None and key in ("deviceName", "driverName", "driverInfo", "deviceType"):
            current[key] = value
    return devices


def _cuda_device():
    exe = shutil.which("nvidia-smi")
    if not exe:
        return {"note": "no nvidia-smi: no CUDA device"}
    try:
        text = subprocess.run([exe, "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                              capture_output=True, text=True, timeout=20).stdout.strip()
    except (subprocess.SubprocessError, OSError) as exc:
        return {"note": f"nvidia-smi failed: {exc}"}
    return [dict(zip(("name", "driver", "memory"), (s.strip() for s in line.split(","))))
            for line in text.splitlines() if line.strip()]


# ------------------------------------------------------------------------- the results page
def _fmt_points(n: int) -> str:
    if n >= 1_000_000 and n % 1_000_000 == 0:
        return f"{n // 1_000_000}M"
    if n >= 1_000 and n % 1_000 == 0:
        return f"{n // 1_000}k"
    return str(n)


def _fmt(value, digits=3):
    if value is None:
        return "-"
    if isinstance(value, float):
        if value == 0:
            return "0"
        if abs(value) >= 100:
            return f"{value:.0f}"
        return f"{value:.{digits}g}"
    return str(value)


def _stage_label(stage, variant):
    return f"{stage} ({variant})" if variant else stage


def _targets():
    out = {}
    for stage in STAGES:
        try:
            case = load_case(stage)
        except (OSError, ImportError, SyntaxError):
            continue
        out[stage] = getattr(case, "TARGETS", {})
        for variant in getattr(case, "VARIANTS", []):
            impls = variant.get("impls") or list(case.IMPLS)
            want = variant.get("targets", out[stage])
            out[(stage, variant["name"])] = {a: t for a, t in want.items() if a in impls}
    return out


def render_markdown(runs: list[dict]) -> str:
    """The results page of one or more runs (e.g. a CPU/Vulkan run and a CUDA run). A case
    (stage, variant, size, backend, implementation) measured by several runs is shown from the
    last run given that has it, so a re-measured stage replaces its older rows."""
    latest = {}
    for run in runs:
        for r in run["rows"]:
            latest[(r["stage"], r["variant"], r["points"], r["backend"], r["impl"])] = r
    rows = list(latest.values())
    targets = _targets()
    lines = ["# Benchmark results", "",
             "Generated by `python -m roadx_ti bench` from the run file(s) listed below; do not edit by hand "
             "(regenerate with `python -m roadx_ti bench --render RUN.json [RUN.json ..]`).", "",
             "Throughput is points per second of input (Mpts/s) from the **median** of the timed repeats after a "
             "warm-up call; **ratio** = anchor median / roadx_ti median (a speed-up: above 1, roadx_ti is "
             "faster). The machine is shared, so only medians and ratios are shown. `first call` is the first "
             "call in a fresh process (kernel compile, or offline-cache load, plus one run); `cached` is the "
             "same first call in a new process once the offline cache is warm. Stages run in the order of the "
             "tables, one process per backend and size, so a kernel shared by two stages compiles in the "
             "first. `peak MB` is the process RSS high-water mark during the timed calls, `B/pt` its growth "
             "over the RSS before them per input point. Anchors are timed on the same points and parameters; "
             "Open3D clouds are built outside the timing, roadx_ti's numpy-to-Taichi copies are inside it. "
             f"An anchor whose warm-up call takes over {SLOW_ANCHOR_BUDGETS} repeat budgets is timed by that "
             "call alone (it compiles nothing). With rounds > 1 the CPU-side workers and the anchors' worker "
             "alternate that many times per size (ABAB) and the medians pool every round's repeats, so a load "
             "change on the shared machine falls on both sides of a ratio.", ""]
    for run in runs:
        m = run["meta"]
        mach = m["machine"]
        lines += [f"## Run {m['run_id']}", "",
                  f"- command: `{m['command']}`",
                  f"- sizes: {', '.join(map(_fmt_points, m['sizes']))}; backends: {', '.join(m['backends'])}; "
                  f"offline cache: {m['cache']}; repeat budget {m['budget_s']} s per case"
                  f"{_rounds_text(m)}; "
                  f"wall time {m['seconds']:.0f} s",
                  f"- CPU: {mach.get('cpu_model')}, {mach.get('logical_cores')} logical cores "
                  f"({mach.get('usable_cores')} usable), {mach.get('memory_gb')} GB RAM; {mach.get('os')}",
                  f"- versions: " + ", ".join(f"{k} {v}" for k, v in mach.get("versions", {}).items()),
                  f"- scenes: {mach.get('synthetic')}"]
        if "vulkan" in mach:
            lines.append(f"- Vulkan: {_device_text(mach['vulkan'])}")
        if "cuda" in mach:
            lines.append(f"- CUDA: {_device_text(mach['cuda'])}")
        lines.append("")
    lines += _summary_section(rows, targets)
    lines += _acceptance_section(rows, targets)
    lines += _detail_sections(rows)
    lines += _problem_section(rows)
    return "\n".join(lines).rstrip() + "\n"


def _rounds_text(meta) -> str:
    rounds = meta.get("rounds", 1)
    return f", {rounds} alternating rounds (CPU-side and anchors)" if rounds > 1 else ""


def _device_text(info) -> str:
    if isinstance(info, dict):
        return info.get("note", json.dumps(info))
    return "; ".join(", ".join(f"{k} {v}" for k, v in d.items()) for d in info) or "none found"


def _ok(rows):
    return [r for r in rows if r["status"] == "ok" and r.get("mpts_per_s")]


def _summary_section(rows, targets):
    mine = _ok([r for r in rows if r["impl"] == "roadx_ti"])
    if not mine:
        return ["## Summary", "", "No roadx_ti row completed.", ""]
    sizes = sorted({r["points"] for r in mine})
    backends = [b for b in ("cpu", "vulkan", "cuda", "metal") if any(r["backend"] == b for r in mine)]
    present = {(r["points"], r["backend"]) for r in mine}
    cols = [(p, b) for p in sizes for b in backends if (p, b) in present]
    lines = ["## Summary: roadx_ti Mpts/s (ratio to the anchors)", "",
             "| stage | " + " | ".join(f"{_fmt_points(p)} {b}" for p, b in cols) + " |",
             "|---|" + "---|" * len(cols)]
    index = {(r["stage"], r["variant"], r["points"], r["backend"]): r for r in mine}
    for stage, variant in _stage_variants(rows):
        cells = []
        for p, b in cols:
            r = index.get((stage, variant, p, b))
            if r is None:
                cells.append("-")
                continue
            ratios = ", ".join(f"{_fmt(v)}x {k}" for k, v in sorted(r["ratio"].items()))
            cells.append(f"{_fmt(r['mpts_per_s'])}" + (f" ({ratios})" if ratios else ""))
        lines.append(f"| {_stage_label(stage, variant)} | " + " | ".join(cells) + " |")
    return lines + [""]


def _stage_variants(rows):
    seen = []
    for stage in STAGES:
        for r in rows:
            if r["stage"] == stage and (stage, r["variant"]) not in seen:
                seen.append((stage, r["variant"]))
    return seen


def _acceptance_section(rows, targets):
    """The issues' speed-up targets, at the largest size measured on the CPU backend (4 M in the
    acceptance criteria when the full run has it)."""
    mine = _ok([r for r in rows if r["impl"] == "roadx_ti" and r["backend"] == "cpu"])
    if not mine:
        return []
    sizes = sorted({r["points"] for r in mine})
    at = 4_000_000 if 4_000_000 in sizes else sizes[-1]
    lines = [f"## Targets at {_fmt_points(at)} points, CPU backend", "",
             "| stage | anchor | target | ratio | met |", "|---|---|---|---|---|"]
    any_target = False
    for stage, variant in _stage_variants(rows):
        want = targets.get((stage, variant), targets.get(stage, {}))
        r = next((r for r in mine if (r["stage"], r["variant"], r["points"]) == (stage, variant, at)), None)
        for anchor, target in want.items():
            any_target = True
            ratio = r["ratio"].get(anchor) if r else None
            met = "-" if ratio is None else ("yes" if ratio >= target else "**no**")
            lines.append(f"| {_stage_label(stage, variant)} | {anchor} | {target:g}x | {_fmt(ratio)} | {met} |")
    pipes = [r for r in mine if r["stage"].endswith("_pipeline") and r["points"] == at]
    if pipes:
        lines += ["", "| pipeline | Mpts/s | median s | peak MB | B/pt |", "|---|---|---|---|---|"]
        for r in pipes:
            lines.append(f"| {r['stage']} | {_fmt(r['mpts_per_s'])} | {_fmt(r['median_s'])} | "
                         f"{_fmt(r['peak_rss_mb'])} | {_fmt(r['bytes_per_point'])} |")
    return lines + [""] if any_target or pipes else []


def _detail_sections(rows):
    lines = ["## Details", ""]
    for stage, variant in _stage_variants(rows):
        group = [r for r in rows if (r["stage"], r["variant"]) == (stage, variant)]
        params = next((r["params"] for r in group if r.get("params")), {})
        lines += [f"### {_stage_label(stage, variant)}", ""]
        if params:
            lines += ["parameters: " + ", ".join(f"{k}={v}" for k, v in params.items()), ""]
        lines += ["| points | backend | impl | Mpts/s | median s | first call s | cached s | peak MB | B/pt "
                  "| threads | ratio |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        order = {"roadx_ti": 0}
        for r in sorted(group, key=lambda r: (r["points"], order.get(r["impl"], 1), r["impl"], r["backend"])):
            if r["status"] != "ok":
                lines.append(f"| {_fmt_points(r['points'])} | {r['backend']} | {r['impl']} | {r['status']} "
                             f"| | | | | | | |")
                continue
            ratio = ", ".join(f"{k}: {_fmt(v)}x" for k, v in sorted(r["ratio"].items()))
            lines.append(f"| {_fmt_points(r['points'])} | {r['backend']} | {r['impl']} | {_fmt(r['mpts_per_s'])} "
                         f"| {_fmt(r['median_s'])} | {_first_call(r)} | {_fmt(r.get('first_call_cached_s'))} "
                         f"| {_fmt(r['peak_rss_mb'])} | {_fmt(r['bytes_per_point'])} | {_fmt(r['threads'])} "
                         f"| {ratio or '-'} |")
        lines.append("")
    return lines


def _first_call(row) -> str:
    state = row.get("offline_cache")
    text = _fmt(row["first_call_s"])
    return f"{text} ({state} cache)" if row["impl"] == "roadx_ti" and state in ("cold", "warm") else text


def _problem_section(rows):
    bad = [r for r in rows if r["status"] != "ok"]
    if not bad:
        return []
    lines = ["## Missing, skipped and failed cases", "", "| stage | points | backend | impl | status | reason |",
             "|---|---|---|---|---|---|"]
    seen = set()
    for r in bad:
        key = (r["stage"], r["variant"], r["backend"], r["impl"], r["status"], r["error"])
        if key in seen and r["status"] == "missing":
            continue   # one line per missing thing, not per size
        seen.add(key)
        reason = (r["error"] or "").replace("|", "/").replace("\n", " ")
        lines.append(f"| {_stage_label(r['stage'], r['variant'])} | {_fmt_points(r['points'])} | {r['backend']} "
                     f"| {r['impl']} | {r['status']} | {reason} |")
    return lines + [""]


# one colour per implementation in every panel
_COLOURS = {"roadx_ti cpu": "C0", "roadx_ti vulkan": "C1", "roadx_ti cuda": "C2", "roadx_ti metal": "C4",
            "numpy": "C7", "scipy": "C3", "open3d": "C5", "csf": "C6"}


def plot_throughput(runs: list[dict], path: Path) -> None:
    """Mpts/s against points per stage, log-log: a flat line is linear scaling."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _ok([r for run in runs for r in run["rows"]])
    groups = _stage_variants(rows)
    if not groups:
        groups = []
    cols = 4
    nrows = max(1, -(-len(groups) // cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.3 * nrows), squeeze=False)
    for ax, (stage, variant) in zip(axes.flat, groups):
        series = {}
        for r in rows:
            if (r["stage"], r["variant"]) == (stage, variant):
                label = r["impl"] if r["impl"] != "roadx_ti" else f"roadx_ti {r['backend']}"
                series.setdefault(label, []).append((r["points"], r["mpts_per_s"]))
        for label, pts in sorted(series.items()):
            pts.sort()
            ax.plot([p for p, _ in pts], [v for _, v in pts], marker="o", color=_COLOURS.get(label, "0.4"),
                    linestyle="-" if label.startswith("roadx_ti") else "--", label=label)
        ax.set_xscale("log")
        ax.set_yscale("log")
        values = [v for pts in series.values() for _, v in pts]
        lo, hi = min(values), max(values)
        if hi / lo < 10:   # at least a decade, so that small differences do not look like large ones
            mid = (hi * lo) ** 0.5
            ax.set_ylim(mid / 10 ** 0.5, mid * 10 ** 0.5)
        ax.set_title(_stage_label(stage, variant), fontsize=9)
        ax.set_xlabel("points", fontsize=8)
        ax.set_ylabel("Mpts/s", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[len(groups):]:
        ax.axis("off")
    fig.suptitle("Throughput against size (log-log; flat = linear scaling)", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


SEPARATE_SECTION = "## Measured separately"   # kept as it is when RESULTS.md is regenerated


def write_results(runs: list[dict], results: Path, plot: Path) -> None:
    results.parent.mkdir(parents=True, exist_ok=True)
    text = render_markdown(runs)
    text = text.replace("## Summary", f"![throughput against size]({os.path.relpath(plot, results.parent)})\n\n"
                                      "## Summary", 1)
    old = results.read_text() if results.exists() else ""
    if SEPARATE_SECTION in old:   # runs made outside the harness (CLI runs, the tiling benchmark)
        text = text.rstrip("\n") + "\n\n" + old[old.index(SEPARATE_SECTION):]
    results.write_text(text)
    plot_throughput(runs, plot)


if __name__ == "__main__":   # python -m roadx_ti.bench ... (the same as python -m roadx_ti bench ...)
    _p = argparse.ArgumentParser(prog="python -m roadx_ti.bench")
    add_arguments(_p)
    raise SystemExit(main(_p.parse_args()))
