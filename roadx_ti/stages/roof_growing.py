"""P3 classified region growing from the roof seeds (kernels: vegetation.vegetation_mask,
seeds.roof_growth_edges, seeds.grow_roof_segments, labels.relabel_compact).

Needs roof_seeds before it (point_data 'normal', 'curvature', 'roof_seed'; ctx.facts['knn']).
Semantics (order independent; see kernels/seeds.py): a growth edge joins kNN neighbours whose
normals are within angle_max_deg, and, when either is vegetation-coloured (COM > com_threshold),
whose 8-bit RGB distance is below color_max (a point with curvature below color_exempt_curvature
counts as not vegetation-coloured for this rule: planar roof under overhanging foliage); growth
passes only through seeds and points with curvature below expand_curvature_max (below
low_expand_curvature_max for points lower than low_height above the ground: hedges and shrubs
against a house reach its eaves, and a roof grown through them took them in); connected pieces holding a seed are roof segments, other
points touching them by a growth edge join as leaves. Without colour the colour rule is off (a
warning says so). LiDAR returns (when the input has them): an earlier return of a multi-return
pulse whose curvature is not below returns_exempt_curvature (foliage: the laser went on through
it; roof interiors return once, roof edges are planar) joins no growth edge; this is the
vegetation cue of inputs without colour (on the six IGN Lidar HD tiles without colour it raised
the mean kappa from 0.82 to 0.88, five tiles up and one 0.949 -> 0.941; benchmarks/accuracy).
Isolated points (roadx_ti.isolation: a part of at most k points, more than 100 m from the rest)
join no growth edge: their k neighbours lie across the gap, so neither their normal nor their edges
say anything about a roof (a cloud without them grows exactly as before).
NIR (use_nir): where the cloud has colour and a NIR field whose values vary (LAS formats 8 and
10; IGN Lidar HD tiles carry all-zero NIR), NDVI > ndvi_threshold marks a point vegetation-coloured
too. info 'vegetation_cue' says which cues ran: 'rgb_com', 'ndvi', 'returns' joined by '+', or
'none'.
Writes point_data 'roof_segment' (int32, compact ids, -1 = none), 'edge_may_join' (uint8: no
foliage return (and, with edge_colour_cue, no vegetation colour) and not isolated: the points
roof_filter's edge completion may add; with edge_colour_cue the colour cue does not count for a covered
point, one the highest point of its plan cell overtops by more than covered_clearance: its
orthophoto colour is that of the crown over it, and a roof under a crown is roof), 'edge_may_join_all' (the same without the returns rule) and, with the colour rule or returns on, 'vegetation' (uint8 bits: 1 COM >
com_threshold or NDVI, 2 such a foliage return) for roof_filter's annex and footprint tests.
"""
from __future__ import annotations

import numpy as np
from pydantic import Field

from roadx_ti import isolation
from roadx_ti.cloud import Cloud
from roadx_ti.kernels.vegetation import DEFAULT_COM_THRESHOLD

# point_data 'vegetation' bits: the colour cue (COM or NDVI) and the foliage-returns cue
VEGETATION_BY_COLOUR = 1
VEGETATION_BY_RETURNS = 2
from roadx_ti.stages.base import MIN_BUFFER, PositiveOrAuto, Stage, StageContext, StageOptions, StageResult


class RoofGrowingOptions(StageOptions):
    angle_max_deg: float = Field(15.0, gt=0, le=90, description="largest angle between the normals "
                                 "of two neighbours that grow together (degrees)")
    expand_curvature_max: float | None = Field(
        0.05, gt=0, description="points with curvature at or above this (unitless) join a roof but "
        "do not pass growth on; null = every point passes it on")
    low_expand_curvature_max: float | None = Field(
        0.02, gt=0, description="points lower than low_height above the ground pass growth on only "
        "below this curvature (unitless): hedges and shrubs against a house reach its eaves and are "
        "smooth at a metre, rough at the point spacing, so a roof grown through them takes them in; "
        "null = expand_curvature_max everywhere")
    low_height: float = Field(4.5, ge=0, description="height above ground (m) under which "
                              "low_expand_curvature_max applies: the band of hedges, shrubs and "
                              "vehicles (roof_filter's narrow_max_height)")
    use_color: bool = Field(True, description="apply the vegetation colour rule when the cloud has RGB")
    com_threshold: float = Field(DEFAULT_COM_THRESHOLD, description="points with COM vegetation index above this are "
                                 "vegetation-coloured (COM is unitless; grey = 6.2815)")
    color_exempt_curvature: float | None = Field(
        0.02, gt=0, description="points with curvature below this (unitless) are exempt from the "
        "colour rule: roof under overhanging foliage is planar but carries the tree's orthophoto "
        "colour, foliage itself is rough; null = no exemption")
    color_max: float = Field(30.0, gt=0, description="a vegetation-coloured point joins only a "
                             "neighbour closer than this in RGB (8-bit units)")
    use_nir: bool = Field(True, description="when the cloud has colour and a NIR field whose values "
                          "vary (LAS point formats 8 and 10): a point with NDVI above ndvi_threshold "
                          "is vegetation-coloured too (beside the COM index)")
    ndvi_threshold: float = Field(0.25, ge=-1, le=1, description="NDVI (NIR - red) / (NIR + red) above "
                                  "which a point is vegetation (unitless; the usual 0.2-0.3 split between "
                                  "vegetation and bare surfaces, not fitted to a tile)")
    use_returns: bool = Field(True, description="when the cloud has LiDAR return numbers: an "
                              "earlier return of a multi-return pulse (the laser went on through: "
                              "foliage) that is not planar (curvature at or above "
                              "returns_exempt_curvature) joins no roof")
    returns_exempt_curvature: float = Field(0.005, gt=0, description="points with curvature below this "
                                            "(unitless) are exempt from the returns rule (roof edges)")
    edge_colour_cue: bool = Field(False, description="the colour cue keeps points off roof_filter's edge "
                              "completion. Off by default: an orthophoto that is not a true one shows each "
                              "roof displaced by the building's lean, so a rim's points take the colour of "
                              "the ground or crown beside it; the completion's plane test (a point on the "
                              "roof's own plane within the height noise) keeps crowns off without it. "
                              "Foliage returns and isolation still count (edge_may_join)")
    covered_clearance: float = Field(1.0, ge=0, description="with edge_colour_cue: a point that the highest point "
                                     "of its plan cell (covered_cell) overtops by more than this (m, at least "
                                     "one cell edge: a roof of up to 45 degrees rises that much within a cell) "
                                     "is covered, and its orthophoto colour is that of what covers it (a crown "
                                     "over a roof): the colour cue does not keep it off roof_filter's edge "
                                     "completion, whose plane and support tests still decide; 0 = off")
    covered_cell: PositiveOrAuto = Field("auto", description="plan cell of the covered test (m); "
                                                  "'auto': 3 survey pulse spacings, at least 0.5 m "
                                                  "(roof_filter's footprint cell)")


class RoofGrowing(Stage):
    name = "roof_growing"
    narrows = False
    Options = RoofGrowingOptions
    requires = ("normal", "curvature", "roof_seed")
    # and 'vegetation' when its colour rule or the returns rule ran
    provides = ("roof_segment",)
    right_after = "roof_seeds"

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        # MIN_BUFFER, as before stages declared their reach: a segment grows across a whole roof, but
        # roof_filter's reach (whole roofs) already covers that in the roof pipeline
        return MIN_BUFFER

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels.labels import relabel_compact
        from roadx_ti.kernels.seeds import grow_roof_segments, roof_growth_edges
        from roadx_ti.kernels.vegetation import vegetation_mask

        o = self.options
        n = cloud.n
        knn = ctx.facts.get("knn")
        needed = ("normal", "curvature", "roof_seed")
        if knn is None or len(knn) != n or any(name not in ctx.point_data for name in needed):
            raise ValueError("roof_growing needs roof_seeds right before it (kNN graph, normals, seeds)")
        if n == 0 or knn.shape[1] == 0:
            return StageResult(point_data={"roof_segment": np.full(n, -1, np.int32)},
                               info={"segments": 0, "roof_points": 0})
        colour = {}
        vegetation_points = None
        penetrated = cloud.penetrated() if o.use_returns else None
        problem = cloud.returns_problem() if o.use_returns else None
        if problem is not None:
            ctx.log.warning("roof_growing: the input's return numbers are not used as a vegetation cue: %s", problem)
        cues = []
        ndvi_points = None
        if o.use_color and cloud.has_color:
            rgb = cloud.rgb8()
            vegetation = vegetation_mask(rgb, o.com_threshold)
            cues.append("rgb_com")
            ndvi = cloud.ndvi() if o.use_nir else None
            if ndvi is not None:
                by_ndvi = ndvi > o.ndvi_threshold
                ndvi_points = int(np.count_nonzero(by_ndvi))
                vegetation = (np.asarray(vegetation) != 0) | by_ndvi
                cues.append("ndvi")
            vegetation = np.asarray(vegetation, np.uint8)
            vegetation_points = int(np.count_nonzero(vegetation))
            colour = dict(rgb=rgb, vegetation=vegetation, color_max=o.color_max)
        elif o.use_color:
            cue = "LiDAR returns are the vegetation cue" if penetrated is not None else "no vegetation cue"
            ctx.log.warning("roof_growing: the input has no colour; the vegetation colour rule is off (%s)", cue)
        growth_colour = dict(colour)
        if colour and o.color_exempt_curvature is not None:
            # a planar point is roof surface under foliage (orthophoto colour), not foliage itself
            growth_colour["vegetation"] = ((np.asarray(colour["vegetation"]) != 0) &
                                         (np.asarray(ctx.point_data["curvature"]) >= o.color_exempt_curvature)
                                         ).astype(np.uint8)
        active = None
        foliage_returns = None
        if penetrated is not None:
            rough = np.asarray(ctx.point_data["curvature"]) >= o.returns_exempt_curvature
            foliage_returns = penetrated & rough
            active = (~foliage_returns).astype(np.uint8)
        isolated = isolation.isolated_in(cloud.xyz, int(knn.shape[1]), ctx)
        if isolated is not None:
            active = ~isolated if active is None else (active != 0) & ~isolated
            active = active.astype(np.uint8)
        edge_ok = roof_growth_edges(knn, ctx.point_data["normal"], angle_max_deg=o.angle_max_deg,
                                    active=active, **growth_colour)
        segment = grow_roof_segments(knn, edge_ok, ctx.point_data["roof_seed"],
                                     curvature=ctx.point_data["curvature"],
                                     expand_curvature_max=self._expand_limit(ctx),
                                     active=None if isolated is None else (~isolated).astype(np.uint8))
        segment, count = relabel_compact(np.asarray(segment))
        if penetrated is not None:
            cues.append("returns")
        info = {"segments": int(count), "roof_points": int(np.count_nonzero(segment >= 0)),
                "color_rule": bool(colour), "vegetation_cue": "+".join(cues) or "none"}
        if ndvi_points is not None:
            info["ndvi_vegetation"] = ndvi_points
        if vegetation_points is not None:
            info["vegetation_coloured"] = vegetation_points
        # roof_filter's edge completion: points no vegetation cue or isolation keeps off a roof
        may_join = np.ones(n, bool)
        if o.edge_colour_cue and "vegetation" in growth_colour:
            coloured = np.asarray(growth_colour["vegetation"]) != 0
            if o.covered_clearance > 0 and coloured.any():
                # the colour of a covered point is its cover's (a crown over a roof)
                covered = coloured & self._covered(cloud, ctx)
                info["covered_coloured_points"] = int(np.count_nonzero(covered))
                coloured &= ~covered
            may_join &= ~coloured
        may_join_all = may_join.copy() if isolated is None else may_join & ~isolated   # returns too
        if active is not None:
            may_join &= np.asarray(active) != 0
        point_data = {"roof_segment": segment, "edge_may_join": may_join.astype(np.uint8),
                      "edge_may_join_all": np.asarray(may_join_all, np.uint8)}
        if colour:
            point_data["vegetation"] = (np.asarray(colour["vegetation"]) != 0).astype(np.uint8) * np.uint8(VEGETATION_BY_COLOUR)
        if foliage_returns is not None:
            # roof_filter's annex and footprint tests treat these like vegetation-coloured points
            point_data["vegetation"] = (point_data.get("vegetation", np.zeros(n, np.uint8)) |
                                        (foliage_returns.astype(np.uint8) * VEGETATION_BY_RETURNS)).astype(np.uint8)
            info["foliage_returns"] = int(np.count_nonzero(foliage_returns))
        return StageResult(point_data=point_data, segment_id=segment, info=info)

    def _expand_limit(self, ctx: StageContext):
        """expand_curvature_max, or per point the stricter low_expand_curvature_max under low_height
        (float32 array) when that is set and cloth_ground left heights above ground."""
        o = self.options
        height = ctx.point_data.get("height_above_ground")
        if o.expand_curvature_max is None or o.low_expand_curvature_max is None or height is None:
            return o.expand_curvature_max
        low = min(o.low_expand_curvature_max, o.expand_curvature_max)
        return np.where(np.asarray(height) < o.low_height, low, o.expand_curvature_max).astype(np.float32)

    def _covered(self, cloud: Cloud, ctx: StageContext) -> np.ndarray:
        """bool per point: overtopped in its plan cell by more than the clearance (kernels
        grid_min.overtopped)."""
        from roadx_ti.kernels.grid_min import overtopped
        from roadx_ti.stages.roof_filter import default_footprint_cell

        o = self.options
        cell = default_footprint_cell(ctx) if o.covered_cell == "auto" else float(o.covered_cell)
        from roadx_ti.isolation import corner_without_isolated

        # cells from the corner of the points less the isolated ones (a stray moved every border)
        return np.asarray(overtopped(cloud.xyz, cell, max(o.covered_clearance, cell),
                                     origin=corner_without_isolated(cloud.xyz, ctx))) != 0
