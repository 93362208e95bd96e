"""Tiled against untiled: wall time, peak RSS and label agreement on one synthetic survey.

    python benchmarks/tiling/run.py [--points 16M] [--tile-size 370] [--kind als-roof]
                                    [--config configs/ground.yaml] [--out benchmarks/tiling]

The scene is written as two LAS files (west and east halves, a two-file catalog); the untiled run
(``tile_size=inf``) and the tiled one each run in a fresh child process, so that each peak RSS
(the child's own ``VmHWM``) is its own. Writes ``tiling-<points>.json`` and prints a markdown
row per run; benchmarks/RESULTS.md quotes them.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time

import numpy as np
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

_CHILD = """
import json, math, sys, time
from roadx_ti import config, tiling
cfg = config.load(sys.argv[1], ["backend=cpu"])
paths, out, tile = json.loads(sys.argv[2]), sys.argv[3], float(sys.argv[4])
t0 = time.perf_counter()
summary = tiling.run_catalog(cfg, paths, out, tile_size=tile, progress=False)
print(json.dumps({"seconds": time.perf_counter() - t0, "tiles": summary["tiling"]["tiles"],
                  "buffer": summary["tiling"]["buffer"],
                  # VmHWM: this process's own high-water mark (ru_maxrss would carry the parent's
                  # RSS at fork across the exec)
                  "peak_rss_mb": [round(int(l.split()[1]) / 1024, 1) for l in open("/proc/self/status")
                                  if l.startswith("VmHWM:")][0]}))
"""


def _child(cfg: str, paths: list[str], out: Path, tile_size: float) -> dict:
    proc = subprocess.run([sys.executable, "-c", _CHILD, cfg, json.dumps(paths), str(out), str(tile_size)],
                          cwd=REPO, capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    sys.path.insert(0, str(REPO))
    from roadx_ti import io, synthetic, tiling
    from roadx_ti.config import parse_point_count

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--points", default="16M")
    p.add_argument("--kind", default="als-roof")
    p.add_argument("--tile-size", type=float, default=370.0, help="core tile edge (m); 370 m holds ~2 M points")
    p.add_argument("--config", default="configs/ground.yaml")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(REPO / "benchmarks" / "tiling"))
    args = p.parse_args(argv)
    n = parse_point_count(args.points)

    with tempfile.TemporaryDirectory(prefix="roadx_tiling_") as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        cloud = synthetic.generate(args.kind, n, args.seed)
        half = cloud.xyz[:, 0] < np.median(cloud.xyz[:, 0])
        paths = [str(tmp / "west.las"), str(tmp / "east.las")]
        for path, part in zip(paths, (half, ~half)):
            io.write(path, cloud, classification=cloud.classification, subset=part)
        del cloud, half
        scene_s = time.perf_counter() - t0
        untiled = _child(args.config, paths, tmp / "untiled.las", math.inf)
        tiled = _child(args.config, paths, tmp / "tiled.las", args.tile_size)
        summary = json.loads((tmp / "tiled.summary.json").read_text())
        cmp = tiling.compare_outputs(summary, tmp / "tiled.las", tmp / "untiled.las")

    record = {"command": "python benchmarks/tiling/run.py " + " ".join(argv if argv is not None else sys.argv[1:]),
              "points": n, "kind": args.kind, "config": args.config, "tile_size_m": args.tile_size,
              "scene_seconds": round(scene_s, 1), "untiled": untiled, "tiled": tiled,
              "rss_ratio": round(tiled["peak_rss_mb"] / untiled["peak_rss_mb"], 3),
              "agreement": cmp["agreement"], "disagreements": cmp["disagreements"],
              "disagreements_by_border_distance_m": cmp["disagreements_by_border_distance_m"]}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"tiling-{args.points}.json").write_text(json.dumps(record, indent=1) + "\n")
    print(f"| untiled | {args.points} {args.kind} | {untiled['seconds']:.1f} s | {untiled['peak_rss_mb']:.0f} MB | - |")
    print(f"| {tiled['tiles']} tiles of {args.tile_size:g} m, buffer {tiled['buffer']:g} m | {args.points} {args.kind} | "
          f"{tiled['seconds']:.1f} s | {tiled['peak_rss_mb']:.0f} MB ({record['rss_ratio']:.2f} of untiled) | "
          f"{cmp['agreement']:.5f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
