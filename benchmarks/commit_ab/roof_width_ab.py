"""python benchmarks/commit_ab/roof_width_ab.py POINTS ROUNDS

A/B of roof_filter.width_measure (issue 16, commit d195abd) on the bench's roof_pipeline case:
configs/roof_als.yaml on the als-roof scene (seed 0), width_measure bent (new: inscribed widths of
curved and angled low segments) against covariance (the stage before that commit), in one process,
alternating rounds; prints per round the whole pipeline call and roof_filter's own seconds, then
the medians."""
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from roadx_ti import backend, config, pipelines, synthetic  # noqa: E402
from roadx_ti.stages.base import StageContext  # noqa: E402

backend.init("cpu")
n, rounds = int(float(sys.argv[1])), int(sys.argv[2])
scene = synthetic.generate("als-roof", n, 0)
times = {}
for _ in range(rounds):
    for measure in ("covariance", "bent"):
        cfg = config.load(REPO / "configs" / "roof_als.yaml", [f"stages.roof_filter.width_measure={measure}"])
        t0 = time.perf_counter()
        out = pipelines.run(scene, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0))
        seconds = time.perf_counter() - t0
        own = next(s["seconds"] for s in out.stages if s["stage"] == "roof_filter")
        times.setdefault(measure, []).append((seconds, own))
        print(f"{measure}: pipeline {seconds:.2f} s, roof_filter {own:.3f} s", flush=True)
for measure, rows in times.items():
    print(f"{measure}: median pipeline {np.median([a for a, _ in rows]):.2f} s, "
          f"roof_filter {np.median([b for _, b in rows]):.3f} s")
