"""Pipelines: an ordered list of stages run over a Cloud, with timing, counts and label transfer.

Each stage sees the working set (the points every earlier stage kept). A 'filter' stage decides
the points it removes (they get its removed class, non-target); a 'subsample' stage only skips
points for speed, and those take the result of their nearest processed point at the end
(METHODS.md R1; heights counted TRANSFER_Z_SCALE times, see there). The last labelling stage's
labels hold for the points that reached it; points that reach the end with no label get the
pipeline's default class.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np

from roadx_ti.cloud import Cloud
from roadx_ti.estimates import RETURNS_VERDICT
from roadx_ti.ordering import canonical_order
from roadx_ti.stages import stage_class
from roadx_ti.stages.base import CLASS_OTHER, DATA_EDGE, ESTIMATES, SAMPLED_SHARE, StageContext, check_order

log = logging.getLogger("roadx_ti")

# What a pipeline runs when a config lists no stages (defaults of each stage's options).
DEFAULT_STAGES = {
    "road": ["uniform_downsample", "sor", "ransac_planes", "grid_slope", "cloth_smooth", "color_growing"],
    "roof": ["low_noise", "cloth_ground", "roof_seeds", "roof_growing", "roof_filter"],
    "ground": ["cloth_ground"],
}
DEFAULT_OPTIONS = {"uniform_downsample": {"ratio": 1.0}}


@dataclass
class PipelineResult:
    classification: np.ndarray        # uint8 per input point
    decided_by: np.ndarray            # uint8 per input point: 0 = reached the end, i = stage i removed it
    segment_id: np.ndarray            # int32 per input point, -1 for none
    processed: np.ndarray             # bool per input point: not skipped by downsampling (nor a repeat)
    stages: list = field(default_factory=list)   # per-stage summary rows
    seconds: float = 0.0
    estimates: dict = field(default_factory=dict)   # survey-wide estimates the stages used
    # per input point, the point data the stages declare in Stage.writes (float32, NaN where the
    # stage did not see the point), for the output's extra dimensions
    extra_dims: dict = field(default_factory=dict)
    repeated: int = 0                 # records at the x, y, z of an earlier one: they take its labels


def repeated_positions(xyz: np.ndarray) -> np.ndarray:
    """bool per point of ``xyz`` in canonical order (roadx_ti.ordering: equal x, y, z lie next to
    each other): its x, y and z are those of the point before it."""
    out = np.zeros(len(xyz), bool)
    if len(xyz) > 1:
        x = xyz[:, 0]
        same = np.flatnonzero(x[1:] == x[:-1])        # few: y and z compared there only
        same = same[(xyz[same + 1, 1] == xyz[same, 1]) & (xyz[same + 1, 2] == xyz[same, 2])]
        out[same + 1] = True
    return out


def build_stages(stage_specs):
    """[(name, options)] -> stage objects; raises StageOrderError (one line) when a stage requires
    data no earlier stage provides (Stage.requires / provides), before any work."""
    classes = [stage_class(name) for name, _ in stage_specs]
    check_order(classes)
    return [cls(options) for cls, (_, options) in zip(classes, stage_specs)]


def default_stage_specs(pipeline: str):
    return [(name, stage_class(name).Options(**DEFAULT_OPTIONS.get(name, {})))
            for name in DEFAULT_STAGES[pipeline]]


def run(cloud: Cloud, stages, *, ctx: StageContext | None = None, truth: np.ndarray | None = None,
        default_class: int = CLASS_OTHER, progress=None, target_class: int | None = None) -> PipelineResult:
    """Run ``stages`` over ``cloud``. ``truth`` (bool per point, optional) adds per-stage counts of
    target and non-target points removed, for accuracy reports; with ``target_class`` also, for a
    labelling stage, how many target points of its working set it leaves without that class
    (``unlabelled_target``) and how many others it gives it (``labelled_other``); for a stage that
    only segments, the same counts with "in a segment" for "given the class".

    The stages see the points in canonical order (roadx_ti.ordering), so the result does not
    depend on the input's point order; the arrays returned are in the input's order."""
    from roadx_ti.stages.base import Stage

    if not isinstance(cloud, Cloud):
        raise TypeError(f"cloud must be a roadx_ti.cloud.Cloud (e.g. roadx_ti.io.read), got {type(cloud).__name__}")
    if stages is None or isinstance(stages, (str, bytes)) or not all(isinstance(s, Stage) for s in stages):
        raise TypeError("stages must be a list of stage objects, e.g. pipelines.build_stages(config.stage_list())")
    order = canonical_order(cloud)
    if order is None:
        return _run(cloud, None, stages, ctx, truth, default_class, progress, target_class)
    if cloud.n < 2**31:
        order = order.astype(np.int32)
    result = _run(cloud, order, stages, ctx, None if truth is None else np.asarray(truth)[order],
                  default_class, progress, target_class)
    def back(ordered):
        out = np.empty_like(ordered)
        out[order] = ordered
        return out
    for name in ("classification", "decided_by", "segment_id", "processed"):
        setattr(result, name, back(getattr(result, name)))
    result.extra_dims = {name: back(values) for name, values in result.extra_dims.items()}
    return result


def _run(cloud, order, stages, ctx, truth, default_class, progress, target_class) -> PipelineResult:
    """The stages over ``cloud`` taken in ``order`` (canonical positions; None: as it is). Every
    index here is a canonical position; a stage's points are gathered from ``cloud`` through
    ``order`` directly, so the canonical copy of the whole cloud lives only while the stages take
    every point (at 16 M points its 370 MB had stayed through the pipeline's peak)."""
    ctx = ctx or StageContext()
    whole = cloud if order is None else cloud.subset(order)

    def points(index):
        return cloud.subset(index if order is None else order[index])

    # every run starts on all of its points (a context handed to a second run keeps its estimates,
    # not the share an earlier run's downsampling kept)
    ctx.facts.pop(SAMPLED_SHARE, None)
    # records repeating a point's x, y and z (merged deliveries, a strip written twice) would be each
    # other's nearest neighbour at 0 m in every stage and in the estimates: they stay out and take
    # their first's labels at the end, as points skipped by downsampling do
    repeated = repeated_positions(whole.xyz)
    if ESTIMATES not in ctx.facts:
        # measured on the whole input before any stage (a tiled run hands in the survey's)
        from roadx_ti.estimates import measure
        ctx.facts[ESTIMATES] = measure(whole if not repeated.any() else whole.subset(np.flatnonzero(~repeated)),
                                       distinct=True)
    verdict = ctx.facts[ESTIMATES].get(RETURNS_VERDICT)
    if verdict is not None and cloud.returns is not None:
        # the survey's verdict on its return numbers, for every stage's points (and every tile)
        cloud, whole = replace(cloud, returns_verdict=verdict), replace(whole, returns_verdict=verdict)
    if any(getattr(stage, "uses_data_edge", False) for stage in stages):
        # the edge of this run's points (a tile's own window), not the survey's
        from roadx_ti.footprint import data_edge
        ctx.facts[DATA_EDGE] = data_edge(whole.xyz)
    n = cloud.n
    classification = np.full(n, default_class, np.uint8)
    decided_by = np.zeros(n, np.uint8)
    segment_id = None            # made when a stage first segments (after the road stage's peak)
    processed = np.ones(n, bool)
    working = np.arange(n, dtype=np.int32 if n < 2**31 else np.int64)
    if repeated.any():
        processed &= ~repeated
        working = working[~repeated]
        log.info("%d records repeat the x, y, z of another; they take its labels", int(repeated.sum()))
    extra_dims = {}
    rows = []
    t_start = time.perf_counter()
    for number, stage in enumerate(stages, start=1):
        if len(working) < n:
            whole = None
        sub = whole if len(working) == n else points(working)
        t0 = time.perf_counter()
        if len(working):
            result = stage.run(sub, ctx)
        else:
            from roadx_ti.stages.base import StageResult
            result = StageResult()
        seconds = time.perf_counter() - t0
        row = {"stage": stage.name, "index": number, "points_in": int(len(working)),
               "seconds": round(seconds, 4), "info": result.info}
        if result.labels is not None:
            classification[working] = result.labels
        if result.segment_id is not None:
            if segment_id is None:
                segment_id = np.full(n, -1, np.int32)
            segment_id[working] = result.segment_id
        if truth is not None and target_class is not None:
            # a labelling stage: the points it gives the target class; a stage that only segments
            # (roof growing): the points it puts in a segment
            given = None
            if result.labels is not None:
                given = np.asarray(result.labels) == target_class
            elif result.segment_id is not None:
                given = np.asarray(result.segment_id) >= 0
            if given is not None:
                working_truth = truth[working]
                row["unlabelled_target"] = int((working_truth & ~given).sum())
                row["labelled_other"] = int((~working_truth & given).sum())
        for key, values in result.point_data.items():
            ctx.point_data[key] = values
        for key in getattr(stage, "writes", ()):
            if key in result.point_data:
                extra_dims.setdefault(key, np.full(n, np.nan, np.float32))[working] = result.point_data[key]
        if result.keep is not None:
            keep = np.asarray(result.keep, bool)
            removed = working[~keep]
            if result.mode == "subsample":
                processed[removed] = False
            else:
                classification[removed] = result.removed_class
                decided_by[removed] = number
            if truth is not None:
                row["removed_target"] = int(truth[removed].sum())
                row["removed_other"] = int(len(removed) - row["removed_target"])
            working = working[keep]
            ctx.point_data = {k: v[keep] for k, v in ctx.point_data.items()}
        row["points_out"] = int(len(working))
        rows.append(row)
        log.info("[%d/%d] %s: %d -> %d points in %.2f s", number, len(stages), stage.name,
                 row["points_in"], row["points_out"], seconds)
        if progress is not None:
            progress(stage.name, number, len(stages))
    del whole
    if segment_id is None:
        segment_id = np.full(n, -1, np.int32)
    skipped = ~processed & ~repeated
    if skipped.any():
        _transfer_labels(lambda index: np.take(cloud.xyz, index if order is None else order[index], axis=0),
                         processed, skipped, classification, decided_by, segment_id)
    if repeated.any():
        # a repeat is the same point: every result of its first (the first of its run in canonical
        # order), with no neighbour query
        first = np.maximum.accumulate(np.where(repeated, 0, np.arange(n)))[repeated]
        for values in (classification, decided_by, segment_id, *extra_dims.values()):
            values[repeated] = values[first]
    return PipelineResult(classification, decided_by, segment_id, processed, rows,
                          time.perf_counter() - t_start, dict(ctx.facts[ESTIMATES]), extra_dims,
                          int(repeated.sum()))


# label transfer measures height differences this many times over: at a kerb (8-16 cm, about one
# processed spacing wide) the processed point nearest in plan may lie on the other surface, the one
# nearest on the same surface is nearer in height. A power of two: the scaled float32 heights are
# exact. Against 1 (2026-12-05, road_uav.yaml, in memory): uav-road 300 k / 1 M seeds 0-9 E1 lower
# on 17 of 20 scenes (mean -0.03 points), E2 lower on 17 and higher on none (mean -0.04); held-out
# streets E1 mean -0.03, E2 -0.01 points; labels agree with the 1 mm / 1 cm / half-density
# deliveries 0.03-0.15 points more often; 8 measured within 0.01 points of 4.
TRANSFER_Z_SCALE = 4.0


def _transfer_labels(xyz_of, processed, skipped, classification, decided_by, segment_id):
    """Points ``skipped`` by downsampling take the result of their nearest ``processed`` point,
    heights counted TRANSFER_Z_SCALE times (ties to the lower index). ``xyz_of(index)``: the
    coordinates of those positions (a new array)."""
    from roadx_ti.kernels.neighbors import nearest

    source = np.flatnonzero(processed)
    target = np.flatnonzero(skipped)
    if len(source) == 0:
        return

    def scaled(index):
        xyz = xyz_of(index)             # a new float32 array: scaled in place
        xyz[:, 2] *= np.float32(TRANSFER_Z_SCALE)
        return xyz
    donor = source[nearest(scaled(source), scaled(target))[0]]
    classification[target] = classification[donor]
    decided_by[target] = decided_by[donor]
    segment_id[target] = segment_id[donor]
