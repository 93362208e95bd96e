"""The `bench` subcommand: its arguments, the plan of a run from them, and the entry point that
runs the plan and writes the JSON, the results page and the plot."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from roadx_ti import jsonio
from roadx_ti.bench.cases import BENCH_DIR, DEFAULT_OUT, FULL_SIZES, QUICK_SIZES, STAGES
from roadx_ti.bench.render import _fmt_points, write_results
from roadx_ti.bench.runner import execute


def _point_count(text: str) -> int:
    # imported here: anchor workers import this module and must not pay for Taichi's import
    from roadx_ti.config import parse_scene_size

    return parse_scene_size(text)



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
        why = _output_problem(args.results, args.plot)
        if why:
            print(f"roadx_ti: bench: {why}", file=sys.stderr)
            return 2
        runs = []
        for p in args.render:
            try:
                run = json.loads(Path(p).read_text())
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
                print(f"roadx_ti: bench: --render {p}: not a bench JSON record ({_reason(exc)})", file=sys.stderr)
                return 2
            why = _record_problem(run)
            if why:     # a run's summary JSON, {}, []: a KeyError at the rendering, after the results file
                print(f"roadx_ti: bench: --render {p}: not a bench JSON record ({why})", file=sys.stderr)
                return 2
            runs.append(run)
        results = args.results or BENCH_DIR / "RESULTS.md"
        plot = args.plot or results.with_name("throughput.png")
        try:
            write_results(runs, results, plot)
        except (KeyError, TypeError, AttributeError, ValueError) as exc:
            # a record with meta and rows but not a run's fields (a hand-edited or truncated one)
            print(f"roadx_ti: bench: --render: not a complete bench JSON record ({type(exc).__name__}: "
                  f"{_reason(exc)}); nothing written", file=sys.stderr)
            return 2
        print(f"wrote {results} and {plot}", file=sys.stderr)
        return 0
    plan = _plan(args)
    if isinstance(plan, str):
        print(f"roadx_ti: bench: {plan}", file=sys.stderr)
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
    if args.sizes is not None and not args.sizes:
        return "--sizes names no size"
    known = {impl for stage in stages for impl in _case_impls(stage)}
    unknown = [i for i in args.impls or [] if i not in known]
    if unknown:
        return f"unknown implementation(s) {', '.join(unknown)} of these stages; known: {', '.join(sorted(known))}"
    stray = [n for n in args.anchor_sizes or [] if n not in sizes]
    if stray:
        return f"--anchor-sizes {', '.join(_fmt_points(n) for n in stray)} not among the sizes measured"
    for flag, value, lowest in (("--threads", args.threads, 1), ("--seed", args.seed, 0)):
        if value is not None and value < lowest:
            return f"{flag} must be >= {lowest}, got {value}"
    for flag, value in (("--budget", budget), ("--timeout", args.timeout)):
        if value is not None and not (value > 0 and value != float("inf")):
            return f"{flag} must be a number of seconds > 0, got {value}"
    why = _output_problem(args.results, args.plot, args.out or DEFAULT_OUT)
    if why:
        return why
    return {
        "rounds": rounds,
        "quick": quick, "sizes": sorted(set(sizes)), "stages": stages, "backends": backends,
        "impls": args.impls, "anchor_sizes": args.anchor_sizes, "cache": cache, "threads": args.threads, "seed": args.seed,
        "budget": budget, "min_repeats": 2 if quick else 3, "max_repeats": 5 if quick else 9,
        "timeout": args.timeout, "out": args.out or DEFAULT_OUT,
        "command": _command_line(args, sizes, stages, backends),
    }


def _case_impls(stage: str) -> list[str]:
    from roadx_ti.bench.cases import load_case

    case = load_case(stage)
    return sorted(set(case.IMPLS) | {i for v in getattr(case, "VARIANTS", []) for i in v.get("impls") or []})


def _reason(exc: Exception) -> str:
    return getattr(exc, "strerror", None) or " ".join(str(exc).split())[:120] or type(exc).__name__


def _record_problem(run) -> str | None:
    """Why ``run`` (parsed JSON) is not a bench run record, or None: a mapping with 'meta' (a
    mapping) and 'rows' (a list of mappings)."""
    if not isinstance(run, dict):
        return f"a JSON {type(run).__name__}, not an object"
    if not isinstance(run.get("meta"), dict) or not isinstance(run.get("rows"), list):
        return "no 'meta' and 'rows'"
    if not all(isinstance(row, dict) for row in run["rows"]):
        return "its rows are not objects"
    return None


def _output_problem(results, plot, out_dir=None) -> str | None:
    """Why the bench could not write its outputs (checked before any case runs), or None."""
    import os

    if out_dir is not None and Path(out_dir).exists() and not Path(out_dir).is_dir():
        return f"--out {out_dir}: is a file; the JSON records go into a folder"
    for flag, path in (("--results", results), ("--plot", plot)):
        if path is not None and Path(path).is_dir():
            return f"{flag} {path}: is a folder; give a file name"
    for flag, path in (("--out", out_dir), ("--results", results), ("--plot", plot)):
        if path is None:
            continue
        folder = Path(path) if flag == "--out" else Path(path).parent
        while not folder.exists() and folder != folder.parent:
            folder = folder.parent
        if not folder.is_dir() and (flag != "--out" or folder != Path(path)):
            return f"{flag} {path}: {folder} is a file, not a folder"
        if not os.access(folder, os.W_OK):
            return f"{flag} {path}: cannot write in {folder}"
    return None


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

