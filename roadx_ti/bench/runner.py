"""The runner: every (backend, size) in its own worker subprocess (the anchors in one more), the
warm-cache rerun, the alternating rounds pooled into the first round's rows, and the ratios."""
from __future__ import annotations

import datetime as _dt
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from roadx_ti.bench.cases import REPO_ROOT, _jobs
from roadx_ti.bench.machine import machine_facts
from roadx_ti.bench.measure import _ANCHORS_WORKER, _UNAVAILABLE, _blank_row, _row_backend
from roadx_ti.bench.render import _fmt_points


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
        cmd = [sys.executable, "-c", "import sys; from roadx_ti.bench.measure import worker_main; "
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

