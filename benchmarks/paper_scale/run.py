"""The paper's scale: a synthetic UAV survey of 137,397,655 points as a folder of LAZ tiles, then the
road pipeline over it as a catalog, through the real CLI, in-process and on a local Dask cluster.

    python benchmarks/paper_scale/run.py [--points 137397655] [--files 9] [--workers 2]
                                         [--executors in-process,workers] [--memory-limit 8G] [--cache DIR]

The survey is ``--files`` uav-road scenes (seeds 0..files-1, ``points / files`` points each) side
by side along x, written once to ``--cache`` (default ~/.cache/roadx_ti/paper_scale/<points>-<files>,
reused while its manifest matches; generation time reported apart). Each executor runs
``python -m roadx_ti run configs/road_uav.yaml --input CACHE --output OUT/road.laz --memory-limit 8G``
(the tiles' size follows the budget: an 8 GB laptop) in a child
process: wall time, peak RSS (the largest process, ru_maxrss, and the process tree's summed RSS
polled every 0.25 s: with --workers the workers are separate processes), points per second,
points written against the survey's count (every point once: the merge checks each file's
count and each tile's core points), the split and merge times and the accuracy of the whole survey
from the summary JSON. Writes ``paper_scale-<points>.json`` beside this file.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
GAP_M = 5.0          # between neighbouring scenes


def build_survey(folder: Path, points: int, files: int) -> dict:
    """The cached survey folder (its manifest: parameters, per-file counts, generation seconds)."""
    from roadx_ti import io, synthetic

    manifest = folder / "manifest.json"
    wanted = {"kind": "uav-road", "points": points, "files": files}
    if manifest.exists():
        saved = json.loads(manifest.read_text())
        if {k: saved.get(k) for k in wanted} == wanted:
            return saved
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.laz"):
        old.unlink()
    t0 = time.perf_counter()
    counts, x_next = [], None
    for seed in range(files):
        n = points // files + (1 if seed < points % files else 0)
        cloud = synthetic.generate("uav-road", n, seed)
        lo = cloud.xyz[:, 0].min() + cloud.origin[0]
        hi = cloud.xyz[:, 0].max() + cloud.origin[0]
        if x_next is not None:          # shift the scene so that it starts GAP_M after the last
            cloud.origin = cloud.origin + [x_next - lo, 0.0, 0.0]
            hi += x_next - lo
        x_next = float(hi) + GAP_M
        io.write(folder / f"survey_{seed:02d}.laz", cloud, classification=cloud.classification)
        counts.append(n)
        print(f"scene {seed}: {n:,} points", file=sys.stderr, flush=True)
    saved = wanted | {"counts": counts, "generation_seconds": round(time.perf_counter() - t0, 1)}
    manifest.write_text(json.dumps(saved, indent=1) + "\n")
    return saved


def run_cli(args: list[str], summary_path: Path) -> dict:
    """One CLI run in a child process: wall, peak RSS (largest process, polled tree sum)."""
    import psutil

    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "roadx_ti", *args], cwd=REPO,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    parent, tree_peak = psutil.Process(proc.pid), 0
    while proc.poll() is None:
        try:
            rss = parent.memory_info().rss + sum(c.memory_info().rss for c in parent.children(recursive=True))
            tree_peak = max(tree_peak, rss)
        except psutil.Error:
            pass
        time.sleep(0.25)
    wall = time.perf_counter() - t0
    err = proc.stderr.read()
    if proc.returncode != 0:
        raise SystemExit(f"run failed (exit {proc.returncode}): {err.strip().splitlines()[-1:]}")
    summary = json.loads(summary_path.read_text())
    return {"wall_seconds": round(wall, 1), "tree_peak_rss_mb": round(tree_peak / 2**20),
            "summary": summary}


def main(argv=None) -> int:
    sys.path.insert(0, str(REPO))
    from roadx_ti.config import parse_point_count

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--points", default="137397655")
    p.add_argument("--files", type=int, default=9)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--executors", default="in-process,workers")
    p.add_argument("--memory-limit", default="8G", help="the runs' --memory-limit (tile size follows it)")
    p.add_argument("--cache", default=None)
    p.add_argument("--out", default=str(REPO / "benchmarks" / "paper_scale"))
    args = p.parse_args(argv)
    points = parse_point_count(args.points)
    cache = Path(args.cache or Path.home() / ".cache" / "roadx_ti" / "paper_scale" / f"{points}-{args.files}")
    survey = build_survey(cache, points, args.files)
    runs = []
    for executor in args.executors.split(","):
        with tempfile.TemporaryDirectory(prefix="roadx_paper_") as tmp:
            out = Path(tmp) / "road.laz"
            cli = ["run", "configs/road_uav.yaml", "--input", str(cache), "--output", str(out), "--quiet",
                   "--memory-limit", args.memory_limit, "--set", "evaluate.truth_classes=[11]"]
            if executor == "workers":
                cli += ["--workers", str(args.workers)]
            before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            got = run_cli(cli, Path(tmp) / "road.summary.json")
            largest = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            s = got.pop("summary")
            import laspy
            with laspy.open(out) as reader:
                written = int(reader.header.point_count)
        tiles = s["tiles"]
        row = {"executor": executor if executor == "in-process" else f"--workers {args.workers}",
               "wall_seconds": got["wall_seconds"], "points_per_second": round(points / got["wall_seconds"]),
               "largest_process_peak_rss_mb": round(max(largest, before) / 1024) if largest > before else None,
               "tree_peak_rss_mb": got["tree_peak_rss_mb"], "points": s["points"], "points_written": written,
               "every_point_once": written == s["points"] == points == sum(t["points_core"] for t in tiles),
               "tiles": len(tiles), "tile_size_m": s["tiling"].get("tile_size"), "buffer_m": s["tiling"].get("buffer"),
               "points_read": sum(t["points_read"] for t in tiles),
               "read_per_core_point": round(sum(t["points_read"] for t in tiles) / points, 3),
               "seconds": s["seconds"], "tile_read_seconds": round(sum(t["read_seconds"] for t in tiles), 1),
               "tile_pipeline_seconds": round(sum(t["pipeline_seconds"] for t in tiles), 1),
               "split": s.get("split"), "accuracy": {k: s.get("accuracy", {}).get(k) for k in ("type1", "type2", "kappa")}}
        runs.append(row)
        print(json.dumps(row), flush=True)
    record = {"command": "python benchmarks/paper_scale/run.py " + " ".join(argv if argv is not None else sys.argv[1:]),
              "survey": {k: survey[k] for k in ("kind", "points", "files", "counts", "generation_seconds")},
              "cpus": os.cpu_count(), "runs": runs}
    dest = Path(args.out)
    dest.mkdir(parents=True, exist_ok=True)
    (dest / f"paper_scale-{points}.json").write_text(json.dumps(record, indent=1) + "\n")
    for r in runs:
        print(f"| {r['executor']} | {points:,} | {r['wall_seconds']:.0f} s | {r['points_per_second'] / 1e6:.3f} M/s | "
              f"{r['tree_peak_rss_mb']:,} MB | {r['tiles']} x {r['tile_size_m']} m | {r['read_per_core_point']} | "
              f"{'yes' if r['every_point_once'] else 'NO'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
