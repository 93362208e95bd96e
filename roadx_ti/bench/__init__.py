"""`python -m roadx_ti bench`: every kernel stage and both pipelines against their anchors.

The parts: ``cases`` (where the cases live, their order, the scenes), ``command`` (the subcommand's
arguments and plan), ``runner`` (the worker subprocesses, rounds, ratios), ``measure`` (one worker:
timing and RSS), ``machine`` (machine facts), ``render`` (results page and plot), ``child`` (a whole process under
GNU time, for the end-to-end scripts in ``benchmarks/``).

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

from roadx_ti.bench.cases import (BENCH_DIR, CASES_ENV, DEFAULT_OUT, FULL_SIZES, QUICK_SIZES, REPO_ROOT,
                                  STAGES, load_case, make_scene, open3d_cloud, pipeline_call)
from roadx_ti.bench.command import add_arguments, main
from roadx_ti.bench.machine import machine_facts
from roadx_ti.bench.measure import ANCHORS_BACKEND, SLOW_ANCHOR_BUDGETS, worker_main
from roadx_ti.bench.render import SEPARATE_SECTION, plot_throughput, render_markdown, write_results
from roadx_ti.bench.runner import ROUND_BACKENDS, add_ratios, execute, pool_round

__all__ = ["ANCHORS_BACKEND", "BENCH_DIR", "CASES_ENV", "DEFAULT_OUT", "FULL_SIZES", "QUICK_SIZES", "REPO_ROOT",
           "ROUND_BACKENDS", "SEPARATE_SECTION", "SLOW_ANCHOR_BUDGETS", "STAGES", "add_arguments", "add_ratios",
           "execute", "load_case", "machine_facts", "main", "make_scene", "open3d_cloud", "pipeline_call",
           "plot_throughput", "pool_round", "render_markdown", "worker_main", "write_results"]
