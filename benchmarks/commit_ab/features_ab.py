"""Neighbourhood features (kernels/features.py) at one commit against this checkout, in one process.

    python benchmarks/commit_ab/features_ab.py --base REV [--points 1M,4M] [--rounds 5]

Loads ``kernels/features.py`` as it is at REV beside this checkout's (knn_ab.load_base), then on
the bench's uav-road scene (seed 0), with the kNN rows found once outside the timing, times each
side's ``covariance_features`` (k 20, the normals bench case) and ``curvature`` (k 8, the survey
estimates) in alternating rounds after a warm-up call each, checks that both sides return the same
arrays bit for bit, and times this checkout's ``plane_heights`` (k 16; roof_seeds' denoising) where
the base has none. Prints medians and the base / new ratio per round.
"""
from __future__ import annotations

import numpy as np

from knn_ab import alternating, base_and_new


def main():
    args, base, new = base_and_new(__doc__, "features", "1M,4M", 5)
    from roadx_ti import synthetic
    from roadx_ti.config import parse_point_count
    from roadx_ti.kernels.neighbors import knn
    print("| points | call | base median | new median | base / new per round | identical |")
    print("|---|---|---:|---:|---|---|")
    for size in args.points.split(","):
        n = parse_point_count(size)
        xyz = np.ascontiguousarray(synthetic.generate("uav-road", n, 0).xyz, np.float32)
        rows = {k: np.asarray(knn(xyz, k)[0]) for k in (8, 16, 20)}
        calls = {"covariance_features k20": lambda m: m.covariance_features(xyz, rows[20]),
                 "curvature k8": lambda m: m.curvature(xyz, rows[8])}
        for name, call in calls.items():
            a, b = call(base), call(new)           # warm-up: compile, first touch
            pairs = zip(a.values(), b.values()) if isinstance(a, dict) else [(a, b)]
            same = all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in pairs)
            times = alternating(call, args.rounds, {"base": base, "new": new})
            ratios = ", ".join(f"{b / a:.3f}" for b, a in zip(times["base"], times["new"]))
            print(f"| {size} | {name} | {np.median(times['base']):.3f} s | {np.median(times['new']):.3f} s | "
                  f"{ratios} | {'yes' if same else 'NO'} |", flush=True)
        new.plane_heights(xyz, rows[16])
        spent = alternating(lambda module: module.plane_heights(xyz, rows[16]), args.rounds, {"new": new})["new"]
        print(f"| {size} | plane_heights k16 | - | {np.median(spent):.3f} s | - | - |", flush=True)


if __name__ == "__main__":
    main()
