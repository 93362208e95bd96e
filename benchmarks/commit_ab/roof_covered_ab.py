"""python benchmarks/commit_ab/roof_covered_ab.py POINTS ROUNDS

A/B of roof_growing's covered test (issue 16, commit 30a3f4e) on the bench's roof_pipeline case:
configs/roof_als.yaml on the als-roof scene (seed 0), roof_growing.covered_clearance 1.0 (new) against
0 (off: the stage as before that commit), in one process, alternating rounds after a warm-up each;
prints the medians of the whole pipeline call and the new / old ratio per round."""
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from roadx_ti import backend, config, pipelines, synthetic  # noqa: E402

backend.init("cpu")
n, rounds = int(float(sys.argv[1])), int(sys.argv[2])
scene = synthetic.generate("als-roof", n, 0)
stages = {}
for tag, clearance in (("off", 0.0), ("on", 1.0)):
    cfg = config.load(REPO / "configs" / "roof_als.yaml",
                      overrides=[f"stages.roof_growing.covered_clearance={clearance}"])
    stages[tag] = pipelines.build_stages(cfg.stage_list())
    pipelines.run(scene, stages[tag])                       # warm-up (compile, caches)
times = {"off": [], "on": []}
for _ in range(rounds):
    for tag in ("off", "on"):
        t0 = time.perf_counter()
        pipelines.run(scene, stages[tag])
        times[tag].append(time.perf_counter() - t0)
off, on = np.median(times["off"]), np.median(times["on"])
print(f"{n} points, {rounds} alternating rounds: off {off:.3f} s, on {on:.3f} s, on / off {on / off:.3f}; "
      f"per round {[round(b / a, 3) for a, b in zip(times['off'], times['on'])]}")
