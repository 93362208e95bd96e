"""P4 roof post-filter and final labels (numpy on the host: segments are few).

Needs roof_growing before it (point_data 'roof_segment') and, for the height test, cloth_ground
(point_data 'height_above_ground'; without it the height test is skipped with a warning).
- density (points per m2): the `density` option when set; else ctx.facts['point_density'] when an
  earlier stage measured it on the whole cloud; else measured here on this stage's cloud (the
  non-ground points): their count / the area of the density_cell x density_cell cells they occupy
  in plan view. Multiple returns in trees make this a slight overestimate (a stricter area test).
- a segment with fewer than density * min_roof_area points is dropped;
- a segment whose median height above ground is below min_roof_height is dropped.
Labels: 6 (building) for points of kept segments, 1 (other) for the rest; segment_id compact over
the kept segments, -1 elsewhere.
"""
from __future__ import annotations

import numpy as np
from pydantic import Field

from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import CLASS_BUILDING, CLASS_OTHER, Stage, StageContext, StageOptions, StageResult


class RoofFilterOptions(StageOptions):
    min_roof_area: float = Field(10.0, ge=0, description="smallest roof segment area (m2); its "
                                 "point count threshold is density * min_roof_area")
    min_roof_height: float = Field(2.0, description="smallest median height above ground of a "
                                   "roof segment (m)")
    density: float | None = Field(None, gt=0, description="point density (points/m2); null = measured")
    density_cell: float = Field(1.0, gt=0, description="cell size for measuring density (m)")


def occupied_density(xy: np.ndarray, cell: float) -> float:
    """Points per m2 of the plan-view area of the cells (side ``cell`` m) the points occupy."""
    if len(xy) == 0:
        return 0.0
    ij = np.floor((xy - xy.min(axis=0)) / cell).astype(np.int64)
    keys = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    return float(len(xy) / (len(np.unique(keys)) * cell * cell))


def segment_medians(segment: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """Median of ``values`` per segment id 0..count-1 (segment -1 ignored), float64."""
    inside = segment >= 0
    seg, val = segment[inside], values[inside].astype(np.float64)
    order = np.lexsort((val, seg))
    seg, val = seg[order], val[order]
    starts = np.searchsorted(seg, np.arange(count))
    stops = np.searchsorted(seg, np.arange(count), side="right")
    lo = val[starts + (stops - starts - 1) // 2]
    hi = val[starts + (stops - starts) // 2]
    return (lo + hi) / 2


class RoofFilter(Stage):
    name = "roof_filter"
    Options = RoofFilterOptions

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels.labels import relabel_compact

        o = self.options
        if "roof_segment" not in ctx.point_data:
            raise ValueError("roof_filter needs roof_growing before it (point_data 'roof_segment')")
        segment = np.asarray(ctx.point_data["roof_segment"], np.int32)
        count = int(segment.max()) + 1 if len(segment) and segment.max() >= 0 else 0
        if o.density is not None:
            density, density_source = float(o.density), "option"
        elif ctx.facts.get("point_density"):
            density, density_source = float(ctx.facts["point_density"]), "facts"
        else:
            density, density_source = occupied_density(cloud.xyz[:, :2], o.density_cell), "non_ground"
        min_points = density * o.min_roof_area
        sizes = np.bincount(segment[segment >= 0], minlength=count)
        keep_area = sizes >= min_points
        height = ctx.point_data.get("height_above_ground")
        if height is None:
            ctx.log.warning("roof_filter: no height above ground (run cloth_ground first); "
                            "the minimum roof height test is skipped")
            keep_height = np.ones(count, bool)
        else:
            keep_height = segment_medians(segment, np.asarray(height), count) >= o.min_roof_height \
                if count else np.ones(0, bool)
        kept = keep_area & keep_height
        roof = np.zeros(len(segment), bool)
        roof[segment >= 0] = kept[segment[segment >= 0]]
        segment_id, kept_count = relabel_compact(np.where(roof, segment, -1).astype(np.int32))
        labels = np.where(roof, CLASS_BUILDING, CLASS_OTHER).astype(np.uint8)
        info = {"density": round(density, 3), "density_source": density_source,
                "min_points": round(min_points, 1), "segments_in": count,
                "dropped_by_area": int((~keep_area).sum()),
                "dropped_by_height": int((keep_area & ~keep_height).sum()),
                "segments_kept": int(kept_count), "roof_points": int(roof.sum())}
        return StageResult(labels=labels, segment_id=segment_id, info=info)
