"""The road stage's region merge (kernels/regions.py) at one commit against this checkout, in one process.

    python benchmarks/commit_ab/regions_ab.py --base REV [--points 4M,16M] [--rounds 3]

Loads ``kernels/regions.py`` as it is at REV beside this checkout's (knn_ab.load_base), runs the
road pipeline (configs/road_uav.yaml) once on the bench's uav-road scene (seed 0) to capture the
arguments road_regions hands ``merge_regions_by_colour``, then times each side's merge on them in
alternating rounds after a warm-up call each and checks that both sides return the same region
graph (labels, pairs, edge and step sums) bit for bit. Prints medians and the base / new ratio
per round.
"""
from __future__ import annotations

import numpy as np

from knn_ab import REPO, alternating, base_and_new


def merge_arguments(n_points: int):
    """(args, kwargs) of road_regions' merge call on the uav-road scene of ``n_points`` (seed 0)."""
    from roadx_ti import config, pipelines, synthetic
    from roadx_ti.kernels import regions
    from roadx_ti.stages.base import StageContext

    seen = {}
    own = regions.merge_regions_by_colour

    def capture(n, ea, eb, steps_up, steps_down, *rest, **kwargs):
        if callable(steps_up):
            # the stage's evidence function reads arrays it lets go after the merge: its values
            # over every edge (elementwise, so the same numbers the merge reads through it)
            steps_up, steps_down = steps_up(slice(0, len(ea)))
        seen["call"] = ((n, ea, eb, steps_up, steps_down) + rest, kwargs)
        return own(n, ea, eb, steps_up, steps_down, *rest, **kwargs)
    regions.merge_regions_by_colour = capture
    try:
        cloud = synthetic.generate("uav-road", n_points, 0)
        cfg = config.load(REPO / "configs" / "road_uav.yaml")
        pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=cfg.seed))
    finally:
        regions.merge_regions_by_colour = own
    return seen["call"]


def graph_of(module, args, kwargs):
    out = module.merge_regions_by_colour(*args, **kwargs)
    return out if hasattr(out, "label") else next(iter(out))


def same_graph(a, b) -> bool:
    return all(np.array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)))
               for f in ("label", "count", "colour_sum", "pa", "pb", "edges", "up", "down"))


def main():
    args, base, new = base_and_new(__doc__, "regions", "4M", 3)
    from roadx_ti.config import parse_point_count
    print("| points | working points | graph edges | base median | new median | base / new per round | identical |")
    print("|---|---:|---:|---:|---:|---|---|")
    for size in args.points.split(","):
        call_args, call_kwargs = merge_arguments(parse_point_count(size))
        same = same_graph(graph_of(base, call_args, call_kwargs), graph_of(new, call_args, call_kwargs))
        times = alternating(lambda module: graph_of(module, call_args, call_kwargs), args.rounds,
                            {"base": base, "new": new})
        ratios = ", ".join(f"{b / a:.3f}" for b, a in zip(times["base"], times["new"]))
        print(f"| {size} | {int(call_args[0]):,} | {len(call_args[1]):,} | {np.median(times['base']):.3f} s | "
              f"{np.median(times['new']):.3f} s | {ratios} | {'yes' if same else 'NO'} |", flush=True)


if __name__ == "__main__":
    main()
