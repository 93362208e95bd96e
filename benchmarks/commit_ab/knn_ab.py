"""kNN (kernels/neighbors.py) at one commit against this checkout, in one process.

    python benchmarks/commit_ab/knn_ab.py --base REV [--points 1M,4M] [--k 16] [--rounds 5]

Loads ``kernels/neighbors.py`` as it is at REV beside this checkout's (as a sibling module of
``roadx_ti.kernels``, so both use this checkout's grid, scan and common modules: for a change
confined to neighbors.py), then on the bench's uav-road scene (seed 0) times ``knn(xyz, k)`` of
each in alternating rounds after one warm-up call each, and checks that both return the same
indices and distances bit for bit. Prints medians and the base / new ratio per round.
"""
from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))


def load_base(rev: str, name: str = "neighbors"):
    """kernels/NAME.py at ``rev`` as module roadx_ti.kernels._NAME_base."""
    source = subprocess.run(["git", "-C", str(REPO), "show", f"{rev}:kernels/{name}.py"],
                            capture_output=True, text=True, check=True).stdout
    # Taichi reads a kernel's source through inspect: the module must live in a real file
    path = Path(tempfile.mkdtemp(prefix=f"{name}_ab_")) / f"_{name}_base.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location(f"roadx_ti.kernels._{name}_base", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def describe() -> str:
    """This checkout's commit (``-dirty`` with uncommitted changes)."""
    return subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"], capture_output=True,
                          text=True, check=True).stdout.strip()


def alternating(call, rounds: int, sides: dict) -> dict:
    """{side: [seconds per round]}: ``call(module)`` for each of ``sides`` ({name: module}) in turn,
    ``rounds`` times, so that the shared machine's load drifts over every side alike."""
    times = {tag: [] for tag in sides}
    for _ in range(rounds):
        for tag, module in sides.items():
            t0 = time.perf_counter()
            call(module)
            times[tag].append(time.perf_counter() - t0)
    return times


def base_and_new(doc: str, name: str, points: str, rounds: int, extra=()):
    """The command line of an A/B script over kernels/NAME.py (--base, --points, --rounds and
    ``extra`` (flag, keywords) options), Taichi started on the CPU, and (args, base module, this
    checkout's module); prints the title line."""
    import importlib

    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--base", required=True, help=f"git revision of the base kernels/{name}.py")
    ap.add_argument("--points", default=points)
    ap.add_argument("--rounds", type=int, default=rounds)
    for flag, options in extra:
        ap.add_argument(flag, **options)
    args = ap.parse_args()
    from roadx_ti import backend
    backend.init("cpu")
    new = importlib.import_module(f"roadx_ti.kernels.{name}")
    base = load_base(args.base, name)
    print(f"kernels/{name}.py, base {args.base} against {describe()}, {args.rounds} alternating rounds (base, new)")
    return args, base, new


def main():
    from roadx_ti import synthetic
    from roadx_ti.config import parse_point_count
    args, base, new = base_and_new(__doc__, "neighbors", "1M,4M", 5, [("--k", {"type": int, "default": 16})])
    print(f"kNN k={args.k}")
    print("| points | base median | new median | base / new per round | identical |")
    print("|---|---:|---:|---|---|")
    for size in args.points.split(","):
        n = parse_point_count(size)
        xyz = np.ascontiguousarray(synthetic.generate("uav-road", n, 0).xyz, np.float32)
        results = {}
        for tag, module in (("base", base), ("new", new)):
            results[tag] = module.knn(xyz, args.k)              # warm-up: compile, first touch
        same = all(np.array_equal(a, b) for a, b in zip(results["base"], results["new"]))
        del results
        times = alternating(lambda module: module.knn(xyz, args.k), args.rounds, {"base": base, "new": new})
        ratios = ", ".join(f"{b / a:.3f}" for b, a in zip(times["base"], times["new"]))
        print(f"| {size} | {np.median(times['base']):.3f} s | {np.median(times['new']):.3f} s | {ratios} | "
              f"{'yes' if same else 'NO'} |", flush=True)


if __name__ == "__main__":
    main()
