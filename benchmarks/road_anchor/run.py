"""The whole road run as a process against the same steps assembled from existing tools
(anchor.py beside this file): start-up, LAZ read and write included on both sides.

    python benchmarks/road_anchor/run.py [--sizes 1M,4M] [--seed 0] [--rounds 3] [--cache DIR]

Per size, one uav-road scene is written as LAZ (cached in ``--cache``, default
~/.cache/roadx_ti/road_anchor; generation reported apart), then ``python -m roadx_ti run
configs/road_uav.yaml`` (without its top-view picture, which the anchor does not draw: the same
job on both sides; its summary JSON and config copy are still written) and ``python
benchmarks/road_anchor/anchor.py`` run on it as child
processes under GNU time, once each to warm up (roadx_ti's offline cache) and then in
alternating rounds (roadx_ti, anchor, roadx_ti, anchor ...) so that the shared machine's load
drifts over both alike. Recorded per run: wall, user + system CPU, peak RSS, the seconds of each
step (roadx_ti: its summary JSON; the anchor: its JSON line) and E1 / E2 of its output against
the scene's road truth. Writes ``road_anchor-<sizes>.json`` beside this file and prints the
medians and the per-round anchor / roadx_ti ratios (benchmarks/RESULTS.md quotes them).
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

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CONFIG = "configs/road_uav.yaml"
ROAD = 11
# roadx_ti's stages under the anchor's step names (the same R1-R6 step on both sides)
STEP_OF_STAGE = {"uniform_downsample": "downsample", "sor": "sor", "ransac_planes": "ransac_planes",
                 "grid_slope": "grid_slope", "cloth_smooth": "cloth", "road_regions": "clusters"}


def timed(argv: list) -> tuple[dict, str]:
    from roadx_ti.bench.child import timed_run

    return timed_run(argv, cwd=REPO)


def errors(truth: np.ndarray, output: Path) -> dict:
    import laspy

    from roadx_ti.metrics import scores

    s = scores(truth, np.asarray(laspy.read(output).classification) == ROAD)
    return {"E1_pct": round(100 * s["type1"], 2), "E2_pct": round(100 * s["type2"], 2)}


def run_roadx_ti(scene: Path, out: Path) -> dict:
    row, _ = timed([sys.executable, "-m", "roadx_ti", "run", CONFIG, "--input", str(scene), "--output", str(out),
                    "--set", "output.report_png=false", "--quiet"])
    summary = json.loads(out.with_name(out.stem + ".summary.json").read_text())
    steps = {"read": summary["read_seconds"], "write": summary["write_seconds"]}
    for stage in summary["stages"]:
        step = STEP_OF_STAGE.get(stage["stage"], stage["stage"])
        steps[step] = steps.get(step, 0.0) + stage["seconds"]
    return row | {"steps": {k: round(v, 3) for k, v in steps.items()}}


def run_anchor(scene: Path, out: Path) -> dict:
    row, stdout = timed([sys.executable, str(HERE / "anchor.py"), str(scene), str(out)])
    return row | {"steps": json.loads(stdout.strip().splitlines()[-1])["seconds"]}


def scene_file(cache: Path, points: int, seed: int) -> tuple[Path, float | None]:
    path = cache / f"uav-road-{points}-s{seed}.laz"
    if path.exists():
        return path, None
    cache.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "roadx_ti", "synth", "--kind", "uav-road", "--points", str(points),
                    "--seed", str(seed), "-o", str(path)], cwd=REPO, check=True, capture_output=True)
    return path, round(time.perf_counter() - t0, 1)


def main() -> int:
    sys.path.insert(0, str(REPO))
    import laspy

    from roadx_ti.config import parse_point_count

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", default="1M,4M")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "roadx_ti" / "road_anchor")
    a = p.parse_args()
    sides = {"roadx_ti": run_roadx_ti, "anchor": run_anchor}
    result = {"command": " ".join(["python", "benchmarks/road_anchor/run.py"] + sys.argv[1:]),
              "config": CONFIG, "seed": a.seed, "sizes": {}}
    for size in a.sizes.split(","):
        n = parse_point_count(size)
        scene, generation = scene_file(a.cache, n, a.seed)
        truth = np.asarray(laspy.read(scene).classification) == ROAD
        rows = {side: [] for side in sides}
        with tempfile.TemporaryDirectory() as tmp:
            outputs = {side: Path(tmp) / f"{side}.laz" for side in sides}
            for side, run in sides.items():         # warm-up: roadx_ti compiles into its offline cache
                run(scene, outputs[side])
            for _ in range(a.rounds):
                for side, run in sides.items():
                    rows[side].append(run(scene, outputs[side]))
            accuracy = {side: errors(truth, outputs[side]) for side in sides}
        ratio = [an["wall_s"] / rx["wall_s"] for rx, an in zip(rows["roadx_ti"], rows["anchor"])]
        median = {side: {m: float(np.median([r[m] for r in v])) for m in ("wall_s", "cpu_s", "peak_rss_mb")}
                  | {"steps": {s: float(np.median([r["steps"].get(s, 0.0) for r in v])) for s in v[0]["steps"]}}
                  for side, v in rows.items()}
        result["sizes"][size] = {"points": n, "generation_s": generation, "runs": rows, "median": median,
                                 "accuracy": accuracy,
                                 "anchor_over_roadx_ti_wall_per_round": [round(r, 2) for r in ratio]}
        print(f"{size}: wall roadx_ti {median['roadx_ti']['wall_s']:.1f} s, anchor {median['anchor']['wall_s']:.1f} s, "
              f"anchor / roadx_ti per round {[round(r, 2) for r in ratio]}", flush=True)
        for step in median["anchor"]["steps"]:
            print(f"  {step:14s} roadx_ti {median['roadx_ti']['steps'].get(step, 0.0):7.2f} s   "
                  f"anchor {median['anchor']['steps'][step]:7.2f} s")
        print(f"  E1 / E2: roadx_ti {accuracy['roadx_ti']}, anchor {accuracy['anchor']}")
    (HERE / f"road_anchor-{a.sizes.replace(',', '-')}.json").write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
