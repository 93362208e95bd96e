"""Labels of one run on two backends, point by point: the road and roof CLIs on the same synthetic
scene with --backend cpu and --backend cuda (or any two), then the share of points whose
classification agrees, both runs' accuracy against the scene's truth, and their stage timings.

    python benchmarks/device/agreement.py --points 1M --backends cpu,cuda --out agreement.json

Each run is the real CLI in its own process (as a user starts it); the outputs are compared in
point order (the CLI writes points in input order).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
CASES = {   # pipeline: (config, scene kind, truth classes)
    "road": ("configs/road_uav.yaml", "uav-road", "[11]"),
    "roof": ("configs/roof_als.yaml", "als-roof", "[6]"),
}


def run_cli(pipeline: str, points: int, seed: int, backend: str, out: Path) -> dict:
    config, kind, truth = CASES[pipeline]
    cmd = [sys.executable, "-m", "roadx_ti", "run", config, "--backend", backend, "--quiet",
           "--output", str(out),
           "--set", "input.paths=[]", "--set", f"input.synthetic={{kind: {kind}, points: {points}, seed: {seed}}}",
           "--set", f"evaluate.truth_classes={truth}"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode:
        return {"backend": backend, "error": (proc.stderr or proc.stdout)[-600:], "wall_s": wall}
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    return {"backend": backend, "wall_s": round(wall, 2), "summary": summary}


def labels(path: Path) -> np.ndarray:
    import laspy

    return np.asarray(laspy.read(path).classification)


def main() -> int:
    from roadx_ti.config import parse_point_count

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", default="1M")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--backends", default="cpu,cuda")
    p.add_argument("--pipelines", default="road,roof")
    p.add_argument("--work", type=Path, default=Path("/tmp/roadx_agreement"))
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    points = parse_point_count(args.points)
    backends = args.backends.split(",")
    if len(backends) != 2:
        p.error(f"--backends takes two backends to compare, got {args.backends!r}")
    args.work.mkdir(parents=True, exist_ok=True)
    report = {"points": points, "seed": args.seed, "backends": backends, "pipelines": {}}
    for pipeline in args.pipelines.split(","):
        runs, outs = [], []
        for backend in backends:
            out = args.work / f"{pipeline}_{backend}.laz"
            runs.append(run_cli(pipeline, points, args.seed, backend, out))
            outs.append(out)
            print(f"{pipeline} {backend}: {runs[-1].get('wall_s')} s {runs[-1].get('error', '')}", file=sys.stderr)
        entry = {"runs": runs}
        if not any("error" in r for r in runs):
            a, b = labels(outs[0]), labels(outs[1])
            entry["agreement"] = float(np.mean(a == b)) if len(a) == len(b) else None
            entry["points_differing"] = int(np.sum(a != b)) if len(a) == len(b) else None
        report["pipelines"][pipeline] = entry
        args.out.write_text(json.dumps(report, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
