"""The whole road CLI at one commit against another: wall time, user CPU time and peak RSS of
``python -m roadx_ti run CONFIG`` on the same LAZ, the two checkouts in alternating rounds.

    python benchmarks/commit_ab/run.py --base-tree /work/old [--points 4M] [--seed 0] [--rounds 3]
                                       [--config configs/road_uav.yaml] [--kind uav-road]
                                       [--out benchmarks/commit_ab]

``--base-tree`` is a checkout of the base commit with its own environment (``./dev setup`` there:
``.venv`` inside it), so that each side imports its own code and kernels; this checkout is the
other side; a relative ``--config`` is each checkout's own file (each side runs its own
configuration of that name). The scene is generated once by this checkout (the same file for both). Each run is a
fresh child process under GNU time (its own first-call compile, warm offline cache); rounds alternate base, new,
base, new ... so that the shared machine's load drifts over both alike. Writes
``ab-<points>.json`` (``ab-<kind>-<points>.json`` for another scene kind) and prints medians and per-round ratios (benchmarks/RESULTS.md quotes them).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]


def _commit(tree: Path) -> str:
    # --dirty: a tree with uncommitted changes is not the commit it names
    return subprocess.run(["git", "-C", str(tree), "describe", "--always", "--dirty"], capture_output=True,
                          text=True, check=True).stdout.strip()


def run_cli(tree: Path, config: str, scene: Path, out: Path, env: dict | None = None) -> dict:
    """One CLI run in ``tree`` with its own .venv, under GNU time (roadx_ti.bench.child): wall,
    user + system CPU seconds and the child's own peak RSS (MB)."""
    from roadx_ti.bench.child import timed_run

    row, _ = timed_run([tree / ".venv" / "bin" / "python", "-m", "roadx_ti", "run", config, "--input", scene,
                        "--output", out, "--quiet"], cwd=tree, env=env)
    return row


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--base-tree", required=True, type=Path)
    p.add_argument("--points", default="4M")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--config", default="configs/road_uav.yaml")
    p.add_argument("--kind", default="uav-road", help="synthetic scene kind (als-roof for configs/roof_als.yaml)")
    p.add_argument("--out", type=Path, default=REPO / "benchmarks" / "commit_ab")
    a = p.parse_args()
    from roadx_ti.config import parse_point_count

    n = parse_point_count(a.points)
    trees = {"base": a.base_tree.resolve(), "new": REPO}
    commits = {k: _commit(t) for k, t in trees.items()}
    rows = {k: [] for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.laz"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "roadx_ti", "synth", "--kind", a.kind, "--points", str(n),
                        "--seed", str(a.seed), "-o", str(scene)], cwd=REPO, check=True, capture_output=True)
        generation = time.perf_counter() - t0
        for side, tree in trees.items():       # warm-up: compile into each side's offline cache
            run_cli(tree, a.config, scene, Path(tmp) / f"{side}.laz")
        for _ in range(a.rounds):
            for side, tree in trees.items():
                rows[side].append(run_cli(tree, a.config, scene, Path(tmp) / f"{side}.laz"))
    ratio = [b["wall_s"] / nw["wall_s"] for b, nw in zip(rows["base"], rows["new"])]
    cpu_ratio = [b["cpu_s"] / nw["cpu_s"] for b, nw in zip(rows["base"], rows["new"])]
    result = {"command": " ".join(["python", "benchmarks/commit_ab/run.py"] + sys.argv[1:]),
              "points": n, "seed": a.seed, "kind": a.kind, "config": a.config, "commits": commits,
              "generation_s": round(generation, 1), "runs": rows,
              "median": {k: {m: float(np.median([r[m] for r in v])) for m in ("wall_s", "cpu_s", "peak_rss_mb")}
                         for k, v in rows.items()},
              "base_over_new_wall_per_round": [round(r, 3) for r in ratio],
              "base_over_new_cpu_per_round": [round(r, 3) for r in cpu_ratio]}
    a.out.mkdir(parents=True, exist_ok=True)
    stem = f"ab-{a.points}" if a.kind == "uav-road" else f"ab-{a.kind}-{a.points}"
    (a.out / f"{stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    for side in trees:
        m = result["median"][side]
        print(f"| {side} {commits[side]} | {m['wall_s']:.1f} s | {m['cpu_s']:.1f} s | {m['peak_rss_mb']:.0f} MB |")
    print("base / new wall per round:", result["base_over_new_wall_per_round"],
          "cpu:", result["base_over_new_cpu_per_round"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
