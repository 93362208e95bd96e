"""python benchmarks/commit_ab/roof_option_ab.py POINTS ROUNDS OLD NEW [STAGE]

A/B of one roof setting on the bench's roof_pipeline case: configs/roof_als.yaml on the als-roof
scene (seed 0) with the override OLD (e.g. stages.roof_filter.width_measure=covariance: the stage as
before a change) against NEW, in one process, alternating rounds after a warm-up each; prints the
medians of the whole pipeline call (and of STAGE's own seconds when named) and the new / old ratio
per round. roof_covered_ab.py is this with roof_growing's covered test."""
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from roadx_ti import backend, config, pipelines, synthetic  # noqa: E402


def main(argv) -> None:
    n, rounds, old, new = config.parse_point_count(argv[0]), int(argv[1]), argv[2], argv[3]
    stage = argv[4] if len(argv) > 4 else None
    backend.init("cpu")
    scene = synthetic.generate("als-roof", n, 0)
    stages = {}
    for tag, setting in (("old", old), ("new", new)):
        cfg = config.load(REPO / "configs" / "roof_als.yaml", overrides=[setting])
        stages[tag] = pipelines.build_stages(cfg.stage_list())
        pipelines.run(scene, stages[tag])                       # warm-up (compile, caches)
    times = {"old": [], "new": []}
    own = {"old": [], "new": []}
    for _ in range(rounds):
        for tag in ("old", "new"):
            t0 = time.perf_counter()
            out = pipelines.run(scene, stages[tag])
            times[tag].append(time.perf_counter() - t0)
            if stage:
                own[tag].append(next(s["seconds"] for s in out.stages if s["stage"] == stage))
    a, b = np.median(times["old"]), np.median(times["new"])
    print(f"{n} points, {rounds} alternating rounds: {old} {a:.3f} s, {new} {b:.3f} s, new / old {b / a:.3f}; "
          f"per round {[round(y / x, 3) for x, y in zip(times['old'], times['new'])]}")
    if stage:
        print(f"{stage}: {np.median(own['old']):.3f} s against {np.median(own['new']):.3f} s "
              f"(per round {own['old']} / {own['new']})")


if __name__ == "__main__":
    main(sys.argv[1:])
