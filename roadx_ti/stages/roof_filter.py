"""P4 roof post-filter and final labels (numpy on the host: segments are few).

Needs roof_growing before it (point_data 'roof_segment') and, for the height test, cloth_ground
(point_data 'height_above_ground'; without it the height test is skipped with a warning).
- density (points per m2): the `density` option when set; else ctx.facts['point_density'] when an
  earlier stage measured it on the whole cloud; else measured here on this stage's cloud (the
  non-ground points): their count / the area of the density_cell x density_cell cells they occupy
  in plan view. Multiple returns in trees make this a slight overestimate (a stricter area test).
  With local_density (default) and roof_seeds' point_data 'neighbour_distance' (farthest of the k
  neighbours, d_k), each segment uses its own density instead: the median over its points of
  k / (pi d_k^2) (points per m2 of the roof plane; the median ignores the sparse edge points). ALS
  density varies 2x between single and overlapping flight strips, so one global value over- or
  under-states a small roof's area by up to 2x.
- a segment with fewer than density * min_roof_area points is dropped;
- a segment whose median height above ground is below min_roof_height is dropped;
- a segment narrower than min_roof_width is dropped: width = sqrt(12 * smallest eigenvalue of the
  plan-view covariance of its points) (exact for a uniformly sampled rectangle). Vans and trucks
  (2-2.5 m wide) are as high and as large as small roofs; no building roof is that narrow.
  A curved or angled segment (a hedge along a bend, two hedges meeting at a corner) reads several
  times its width by covariance: with width_measure bent (default), where the inscribed width
  (inscribed_widths: twice the largest distance from the filled plan footprint to its outline, on
  cells of half the segment's own point spacing) is under BENT_RATIO of it, the inscribed width is
  the segment's width.
  A segment cut by the edge of the data (edge_cut; ctx.facts DATA_EDGE: a tile's or survey's
  boundary cuts buildings) has no observed width across the cut: with at least 3 points in the
  edge cells and at least a third of min_roof_width across, its width is the larger of its width
  and the length of its cut (the same measure over its points in edge cells).
- seen through (see_through_depth > 0, data with multi-return pulses only): a segment under which
  later returns (not the first of their pulse) in no segment lie more than see_through_depth below
  its top, in the interior of its footprint cells, numbering at least max_see_through of its own
  points there (and see_through_min_points), is dropped: pulses passed through it, as they pass a
  tree crown's flat patches to the branches below, and a roof stops them. The rim is left out
  (eaves split pulses onto walls and the ground beside them); see-through structures over roofs
  (pergolas, glass) about 2 m above a roof are kept (AHN3's).
- low and rough (low_min_planar): a segment lower than narrow_max_height (median) with fewer than
  low_min_planar of its points planar (curvature under a quarter of roof_seeds' curvature_max, or
  under the seeds' median curvature where that is higher: low_planar_bound) is
  neither a roof nor an annex: hedges and shrubs against houses reach the eaves and are smooth at a
  metre, rough at the point spacing. Judged only for segments of at least JUDGED_NEIGHBOURHOODS x k
  points (in fewer every neighbourhood straddles the rim). The share scales with the survey's own
  roofs: where the kept segments over narrow_max_height have fewer planar points than
  low_planar_reference (noisy sensors: every roof loses planar points), low_min_planar falls in
  proportion.
- at grade (max_at_grade_outline < 1): a segment whose outline cells (plan cells of its
  non-vertical points holding AT_GRADE_CELL_POINTS points on average, lacking a neighbour) have
  their lowest point under at_grade_height over the ground on more than max_at_grade_outline of
  them is terrain the cloth stayed off (embankments, dikes: their feet meet the ground), neither
  roof nor annex; a roof's outline is its eaves, a storey up (judged as low and rough);
- annexes (annex_reach > 0): a segment dropped only by the area or width test (it passes the
  height test) is kept when it holds at least density * annex_min_area points, at most
  annex_max_vegetation of them vegetation-coloured, and it lies along a kept roof: a point within
  annex_reach (+ ANNEX_GAP_SPACINGS pulse spacings, the sampling's gap) in plan of a kept roof's
  point, and, judged as above, annex_min_contact of its points so: garages, porches and annexes
  built against a house are building even when small or narrow; a hedge running away from a
  house's corner touches it at one end only. Decided from the kept roofs only (no chains), so the
  result is order independent.
- edge completion (edge_growth, kernels/seeds.grow_roof_edges): roof points whose neighbourhood
  straddles the roof's edge (eaves, gable ends, courtyard rims: wall, gutter or foliage points in
  their k neighbours) fail the seed and normal tests and are left out of every segment, or form
  small dropped ones. Each kept roof grows out to its boundary over the kNN graph: a point joins
  when a roof neighbour within edge_reach point spacings carries a plane (its own where it is
  planar, else its nearest planar roof neighbour's) the point lies on within edge_noise x sqrt 2
  x the height noise + edge_tilt x the distance from that plane's origin, at least
  edge_min_height above the ground, and no vegetation cue keeps it off (with roof_growing's
  edge_colour_cue colour, and with
  edge_foliage_returns false also foliage returns: point_data 'edge_may_join' / 'edge_may_join_all'
  from roof_growing; eaves split pulses, so by default returns do not keep a rim point off); joined points carry the plane on, so a chain
  of joins stays on one interior plane and does not creep down a wall (edge_rounds rounds). Only
  kept roofs grow (a plane patch in a tree that grew would pass the area test). Spacing: the
  survey estimate (roadx_ti.estimates); noise: the kept roofs' own plane noise (roof_plane_noise;
  the survey's height noise counts foliage on wooded tiles); both under info 'edges'. Footprint
  completion reads the roofs as they were before edge growth.
- covered completion (covered_clearance > 0, after edge growth): roof under a crown (its points
  overtopped in their footprint cell by more than covered_clearance) has crown points in its
  neighbourhoods, fails the seed tests and often lies beyond edge growth's reach; such points join
  a kept roof, round by round through the kNN graph, when they lie on the roof segment's fitted plane
  (least squares over its points before edge growth, edge_noise sigmas; a segment that is not one
  plane grows nothing), so the growth cannot creep along local planes into the crown.
- footprint completion (attach_footprint, kernels/seeds.attach_to_footprints): walls below a
  kept roof's edge, chimneys and roof units standing on it and roof points under overhanging
  foliage join it; off the roof surface only points that are not vegetation-coloured join
  (point_data 'vegetation' from roof_growing: colour or foliage returns; without either every
  point may); under a roof edge outside its cells, points lower than narrow_max_height join only
  on steep surfaces (|normal z| < wall_max_normal_z): walls stand vertical, the low level points
  there are the tops of bushes and hedges under the eaves. A point more than superstructure_height above the roof points of its footprint cell
  joins only within over_roof_reach (3D) of a roof point: higher than a storey over a roof stands
  another roof level or something on one; a crown hanging over a low roof is far from every roof
  point (over_roofs).
Labels: 6 (building) for points of kept segments, 1 (other) for the rest; segment_id compact over
the kept segments, -1 elsewhere.
"""
from __future__ import annotations

import math

import numpy as np
from typing import Annotated, Literal

from pydantic import Field

from roadx_ti.cloud import Cloud
from roadx_ti.estimates import MAD_TO_SIGMA
from roadx_ti.isolation import SMALL_PART, corner_without_isolated, isolated_in
from roadx_ti.segments import segment_covariance, segment_medians
from roadx_ti.sorted_keys import find
from roadx_ti.stages.base import (CLASS_BUILDING, CLASS_OTHER, DATA_EDGE, MIN_CELL, PositiveOrAuto, Stage, StageContext,
                                  StageOptions, StageResult, estimate, spacing_cell, survey_spacing)

# footprint_cell 'auto': FOOTPRINT_SPACINGS survey spacings, at least FOOTPRINT_MIN_CELL (m), and
# FALLBACK_FOOTPRINT_CELL without a spacing estimate (roof_growing's covered test uses the same cell)
FOOTPRINT_SPACINGS = 3.0
FOOTPRINT_MIN_CELL = 0.5
FALLBACK_FOOTPRINT_CELL = 1.0
# the planarity and contact tests judge a segment of at least this many kNN neighbourhoods (k
# points each) only: in fewer (a small roof of a sparse survey) every point's neighbours straddle
# its rim, and a share of its points is too few points to say anything
JUDGED_NEIGHBOURHOODS = 3
VERTICAL_NZ = 0.5    # |normal z| under this: a wall point (steeper than 60 degrees)
AT_GRADE_CELL_POINTS = 8.0   # points per cell of the at-grade test's outline (e^-8 of the cells empty)
# annex_reach is measured between sampled points: plus the gap of the sampling, in pulse spacings
ANNEX_GAP_SPACINGS = 2.0
# covered completion: at most this share of a point's k neighbours may lie under the roof's plane (a
# rim's gutter or wall; a roof hides what is under it, a crown's slab has half the crown beneath it)
COVERED_MAX_BELOW = 0.2
# m: largest reach of the footprint and annex rules (far beyond any eave, annex or storey; each reach
# spans reach / cell footprint cells around every point: 1e9 m ran out of memory)
MAX_REACH = 100.0


def default_footprint_cell(ctx: StageContext) -> float:
    """The footprint cell (m) of roof_filter's default options."""
    return spacing_cell(ctx, FOOTPRINT_SPACINGS, FOOTPRINT_MIN_CELL, FALLBACK_FOOTPRINT_CELL)


class RoofFilterOptions(StageOptions):
    min_roof_area: float = Field(10.0, ge=0, description="smallest roof segment area (m2); its "
                                 "point count threshold is density * min_roof_area")
    min_roof_height: float = Field(2.0, ge=0, description="smallest median height above ground of a "
                                   "roof segment (m)")
    density: float | None = Field(None, gt=0, description="point density (points/m2); null = measured")
    density_cell: float = Field(1.0, ge=MIN_CELL, description="cell size for measuring density (m)")
    local_density: bool = Field(True, description="per segment density from its points' neighbour "
                                "distances (flight-strip overlap doubles ALS density locally)")
    min_roof_width: float = Field(3.0, ge=0, description="smallest plan-view width of a roof "
                                  "segment (m); drops vehicles, which pass the height and area tests")
    narrow_max_height: float = Field(3.5, ge=0, description="the width test applies to segments "
                                     "lower than this (m, median height): vehicles are lower; "
                                     "higher narrow segments are walls or roof parts")
    low_min_planar: float = Field(0.15, ge=0, le=1, description="a segment lower than "
                                  "narrow_max_height (m, median height) is a roof or an annex only when "
                                  "at least this share of its points are planar (unitless; curvature "
                                  "under a quarter of roof_seeds' curvature_max, or the seeds' median "
                                  "curvature where higher, as on dense or noisy surveys): hedges and shrubs "
                                  "beside houses are as high as low roofs, their tops smooth at a metre "
                                  "but rough at the point spacing; 0 = off")
    low_planar_reference: float = Field(0.55, gt=0, le=1, description="the planar share of the survey's "
                                        "kept roofs over narrow_max_height (point-weighted) at which "
                                        "low_min_planar holds; a survey whose roofs are less planar (noisy "
                                        "sensors: all roofs lose planar points together) scales low_min_planar "
                                        "down in proportion (the IGN tiles merged: 0.55; every real file at "
                                        "hand 0.45-0.91)")
    max_at_grade_outline: float = Field(0.5, ge=0, le=1, description="a segment whose outline meets "
                                        "the ground (its lowest non-vertical point within at_grade_height of "
                                        "the ground) on more than this share of its outline cells is terrain "
                                        "the cloth stayed off (an embankment, a dike), not a roof, which stands "
                                        "on walls (unitless; 1 = off)")
    at_grade_height: float = Field(1.0, gt=0, description="an outline cell whose lowest non-vertical "
                                   "point is less than this over the ground is at grade (m)")
    width_measure: Literal["covariance", "inscribed", "bent"] = Field(
        "bent", description="how the width test measures a low segment: covariance (sqrt(12 x the smallest "
        "plan eigenvalue): exact for a straight strip, several times too wide for a curved or angled one), "
        "inscribed (twice the largest distance from its filled plan footprint to the outline), bent (the "
        "inscribed width where it is under BENT_RATIO (0.6) of the covariance width: curved and angled "
        "shapes; else the covariance width)")
    edge_cut: bool = Field(True, description="a segment cut by the edge of the data (tile or "
                           "survey boundary) is as wide as its cut is long: its width across the "
                           "cut is not observed")
    annex_reach: float = Field(1.0, ge=0, le=MAX_REACH, description="a segment dropped only by the area or width "
                               "test is kept when its plan-view cells lie within this distance (m) "
                               "of a kept roof's cells: annexes and garages built against a house "
                               "are building, often under 10 m2 or 3 m wide; 0 = off")
    annex_min_area: float = Field(1.0, ge=0, description="smallest annex segment (m2, same density "
                                  "as the area test): skips plane fragments of clutter by a wall")
    annex_min_contact: float = Field(0.2, ge=0, le=1, description="an annex lies along its roof: "
                                     "at least this share of its points within annex_reach of the "
                                     "roof's points (unitless; a side-attached annex up to about "
                                     "annex_reach / 0.2 = 5 m deep); a hedge from a house's corner "
                                     "touches it at one end only")
    annex_max_vegetation: float = Field(0.3, ge=0, le=1, description="largest fraction of "
                                        "vegetation-coloured points of an annex (unitless): small "
                                        "planar patches in trees beside a roof are not annexes")
    see_through_depth: float = Field(2.0, ge=0, description="with LiDAR returns: later returns in no "
                                     "segment more than this far (m) under a segment's interior were "
                                     "seen through it (pulses pass a tree crown's flat patches down to "
                                     "its branches; a roof stops them); 0 = off")
    max_see_through: float = Field(0.1, gt=0, description="a segment is not a roof when the later "
                                   "returns seen through it number at least this share of its "
                                   "interior points (unitless: pulses through per pulse on it)")
    see_through_min_points: int = Field(3, ge=1, description="... and at least this many (a vent or "
                                        "a skylight lets one or two through)")
    edge_growth: bool = Field(True, description="complete each kept roof out to its boundary: edge "
                              "and eave points whose neighbourhood straddles the roof edge (they fail "
                              "the seed and normal tests) join when they lie on the roof's plane")
    edge_reach: float = Field(4.0, gt=0, description="an edge point joins from a roof point at most "
                              "this many point spacings away (unitless; spacing = the measured median "
                              "nearest-neighbour distance in plan, about half of 1 / sqrt(density))")
    edge_rounds: int = Field(3, ge=0, le=16, description="rounds of edge growth: each extends a "
                             "roof by at most edge_reach spacings; 0 = off")
    edge_noise: float = Field(3.0, ge=0, description="plane distance tolerance of edge growth in "
                              "sigmas of the kept roofs' own plane noise (the robust spread of the "
                              "distances of planar roof points' neighbours to their plane)")
    edge_tilt: float = Field(0.1, ge=0, description="plane distance allowed per metre from the "
                             "plane's origin point (unitless: the uncertainty of its normal, ~6 degrees)")
    edge_support: float = Field(0.4, ge=0, le=1, description="an edge point joins only when at least "
                                "this fraction of its k neighbours lie on the roof's plane (unitless): "
                                "an eave point has its roof side there, foliage beside a roof little")
    edge_foliage_returns: bool = Field(True, description="foliage returns (roof_growing's returns "
                                       "rule: rough earlier returns of multi-return pulses) may join by "
                                       "edge growth too: an eave splits the pulse (roof, then the ground "
                                       "beside the wall), so a roof's rim is mostly such returns")
    edge_min_height: float = Field(1.0, ge=0, description="edge points lower than this above the ground "
                                   "(m) never join: the ground and low plants beside a wall")
    covered_clearance: float = Field(1.0, ge=0, description="covered completion, after edge growth: "
                                     "a point that the highest point of its footprint cell overtops by "
                                     "more than this (m, at least one cell) joins a kept roof through the "
                                     "kNN graph when it lies on the roof segment's fitted plane (edge_noise "
                                     "sigmas): roof under a crown, whose neighbourhoods hold crown points, "
                                     "fails the seed tests and lies beyond edge growth's reach; 0 = off")
    attach_footprint: bool = Field(True, description="add walls, chimneys, roof units and roof "
                                   "points under foliage inside or below a kept roof's footprint")
    attach_min_height: float = Field(1.0, ge=0, description="only points at least this high above "
                                     "ground (m) join a footprint: low returns beside a wall are "
                                     "mostly ground and low plants the cloth left as non-ground")
    footprint_cell: PositiveOrAuto = Field("auto", description="grid cell of the roof "
                                                    "footprints (m); 'auto': footprint_spacings x the "
                                                    "survey's measured pulse spacing (1 m without it)")
    footprint_spacings: float = Field(FOOTPRINT_SPACINGS, gt=0, description="footprint_cell 'auto' in measured pulse "
                                      "spacings (unitless): a roof's cells are then all occupied while "
                                      "its outline stays within about one cell of the true one (a 1 m "
                                      "cell with a 1 m wall reach on the six IGN tiles: hedges and bushes "
                                      "by the walls joined, mean kappa 0.876 against 0.897)")
    footprint_min_cell: float = Field(FOOTPRINT_MIN_CELL, ge=MIN_CELL, description="smallest 'auto' footprint cell (m): about "
                                      "the eaves' overhang, the distance of a wall inside its roof's outline")
    inside_reach: float = Field(3.0, ge=0, le=MAX_REACH, description="a point is inside a footprint when roof "
                                "cells lie this close (m) in all four axis directions; covers "
                                "holes left by roof units up to about 2 x inside_reach wide")
    wall_reach: Annotated[float, Field(ge=0, le=MAX_REACH)] | Literal["cell"] = Field("cell", description="a point below a roof edge joins "
                                                "when a roof cell this close (m) is above it; 'cell': one "
                                                "footprint cell, the uncertainty of the cells' outline "
                                                "(walls stand under the eaves, inside the roof's outline: "
                                                "what lies further out is a hedge or a bush by the wall)")
    wall_max_normal_z: float | None = Field(0.8, gt=0, le=1, description="under a roof edge outside "
                                            "its footprint cells, points lower than narrow_max_height "
                                            "join only on surfaces steeper than this (|normal z|, "
                                            "unitless; 0.8 is about 37 degrees): walls stand vertical, "
                                            "low level points there are the tops of bushes and hedges "
                                            "under the eaves (balconies stand higher); null = every point")
    surface_tol: float = Field(0.5, ge=0, description="a point within this height (m) of its roof "
                               "cell's z range lies on the roof surface and joins whatever its colour")
    over_roof_reach: float = Field(3.0, ge=0, le=MAX_REACH, description="footprint completion: a point more than "
                                   "superstructure_height above the roof points of its footprint cell "
                                   "joins only within this distance (m, 3D) of a roof point: what stands "
                                   "higher than a storey on a roof is another roof level or on one, a "
                                   "crown hanging over a low roof is far from every roof point; 0 = off")
    superstructure_height: float = Field(3.0, ge=0, description="a point inside a footprint within this "
                                         "height (m) of its roof cell's z range joins when only the returns "
                                         "cue calls it foliage (chimneys, vents, railings, roof units, stair "
                                         "and lift housings up to a storey high split pulses as foliage "
                                         "does; a colour cue still keeps it off)")


def occupied_density(xy: np.ndarray, cell: float) -> float:
    """Points per m2 of the plan-view area of the cells (side ``cell`` m) the points occupy."""
    if len(xy) == 0:
        return 0.0
    ij = np.floor((xy - xy.min(axis=0)) / cell).astype(np.int64)
    keys = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    return float(len(xy) / (len(np.unique(keys)) * cell * cell))


def _plan_extents(segment: np.ndarray, xy: np.ndarray, count: int, largest: bool = False) -> np.ndarray:
    """Per segment id 0..count-1: sqrt(12 * the smallest (or largest) eigenvalue of the plan-view
    covariance of its points) in m (a uniformly sampled w x l rectangle gives w, or l). float64."""
    _, _, cov = segment_covariance(segment, xy, count)
    sxx, syy, sxy = cov[:, 0, 0], cov[:, 1, 1], cov[:, 0, 1]
    spread = np.sqrt(((sxx - syy) / 2) ** 2 + sxy ** 2)
    eigen = (sxx + syy) / 2 + (spread if largest else -spread)
    return np.sqrt(12 * np.maximum(eigen, 0))


def segment_widths(segment: np.ndarray, xy: np.ndarray, count: int) -> np.ndarray:
    """Plan-view width per segment id 0..count-1 (m, float64)."""
    return _plan_extents(segment, xy, count)


# a straight strip's inscribed width reads 0.9-1.0 of its covariance width (the estimate's scatter
# at 2-17 points/m2 is 0.1-0.3 m on 2-6 m strips), a disc's 1.15; an L of two arms or a curved
# hedge reads far under it
BENT_RATIO = 0.6
INSCRIBED_MAX_CELLS = 4_000_000


def inscribed_widths(segment: np.ndarray, xy: np.ndarray, judged: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """Per segment id where ``judged``: twice the largest distance (m) from a point of its plan
    footprint to the footprint's outline; inf elsewhere. The footprint is the segment's cells of half
    the point ``spacing``, closed over a spacing (the sampling's gaps) and with its holes filled
    (chimneys, skylights); a cell's distance is to the nearest empty cell's centre, so a uniformly
    sampled strip w wide reads about w whatever its curvature or bends (the covariance width of
    an L-shaped or curved hedge reads several times its width)."""
    from scipy import ndimage

    out = np.full(len(judged), np.inf)
    ids = np.flatnonzero(judged)
    if not len(ids):
        return out
    pad = 4
    order = np.argsort(segment, kind="stable")
    starts = np.searchsorted(segment[order], ids)
    ends = np.searchsorted(segment[order], ids, side="right")
    for s, a, b in zip(ids, starts, ends):
        if b <= a:
            continue
        p = xy[order[a:b]].astype(np.float64)
        extent = p.max(axis=0) - p.min(axis=0)
        # a raster of at most INSCRIBED_MAX_CELLS (a 300 m low hall at UAV density would ask for
        # 10^8 cells): coarser cells for the largest segments, whose width is far from the test's
        cell = max(float(spacing[s]) / 2, float(np.sqrt((extent[0] + 1) * (extent[1] + 1) / INSCRIBED_MAX_CELLS)))
        ij = np.floor((p - p.min(axis=0)) / cell).astype(np.int64) + pad
        mask = np.zeros(tuple(ij.max(axis=0) + pad + 1), bool)
        mask[ij[:, 0], ij[:, 1]] = True
        mask = ndimage.binary_closing(mask, structure=np.ones((3, 3), bool), iterations=2)
        mask = ndimage.binary_fill_holes(mask)
        out[s] = 2 * float(ndimage.distance_transform_edt(mask).max()) * cell
    return out


def cut_lengths(segment: np.ndarray, xy: np.ndarray, count: int, at_edge: np.ndarray) -> np.ndarray:
    """Per segment: the length (m) of its points in the data's edge cells (``at_edge``) along their
    longest plan axis, where it has at least 3 there; else 0."""
    on = np.where(at_edge, segment, -1)
    length = _plan_extents(on, xy, count, largest=True)
    return np.where(np.bincount(on[on >= 0], minlength=count) >= 3, length, 0.0)


# most cell keys a window lists (int64: 32 MB); beyond, every point counts as in it (the window only
# preselects points for exact distances: a footprint_cell far under the reach made it hold billions)
WINDOW_CELLS = 4_000_000


def _in_window(keys: np.ndarray, around: np.ndarray, span: int, rows: int) -> np.ndarray:
    """bool per key of ``keys`` (cell keys column * rows + row): within ``span`` cells (square
    window) of one of the cells ``around``; all True where that window would list more than
    WINDOW_CELLS cells."""
    cells = np.unique(around)
    if (2 * span + 1) ** 2 * len(cells) > WINDOW_CELLS:
        return np.ones(len(keys), bool)
    window = np.array([dx * rows + dy for dx in range(-span, span + 1) for dy in range(-span, span + 1)], np.int64)
    return np.isin(keys, np.unique((cells[:, None] + window[None, :]).ravel()))


def over_roofs(xyz: np.ndarray, core: np.ndarray, grown: np.ndarray, cell: float, height: float,
               reach: float, origin=None) -> np.ndarray:
    """bool per point: footprint completion attached it (``grown`` >= 0, ``core`` < 0), it lies in
    a plan cell (side ``cell`` m) holding roof points of ``core``, more than ``height`` m above the
    highest of them, and no roof point lies within ``reach`` m of it in 3D (scipy cKDTree,
    float64)."""
    out = np.zeros(len(core), bool)
    roof = np.flatnonzero(core >= 0)
    new = np.flatnonzero((grown >= 0) & (core < 0))
    if not len(roof) or not len(new):
        return out
    pts = np.asarray(xyz, np.float64)
    # cells from the corner of the points less the isolated ones (origin): a stray far off moved
    # every cell border (isolation.corner_without_isolated)
    lo = pts[:, :2].min(axis=0) if origin is None else np.asarray(origin, np.float64)
    ij = np.floor((pts[:, :2] - lo) / cell).astype(np.int64)
    keys = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    order = np.argsort(keys[roof], kind="stable")
    roof_keys = keys[roof][order]
    cells, first = np.unique(roof_keys, return_index=True)
    top = np.maximum.reduceat(pts[roof, 2][order], first)
    at, in_roof_cell = find(cells, keys[new])
    high = new[in_roof_cell & (pts[new, 2] > top[at] + height)]
    if len(high):
        from scipy.spatial import cKDTree   # here: a run that stops at its config check does not import scipy

        # the roof points within reach in plan of a high point lie in its window of cells
        near = roof[_in_window(keys[roof], keys[high], int(np.ceil(round(reach / cell, 9))), int(ij[:, 1].max()) + 1)]
        distance, _ = cKDTree(pts[near]).query(pts[high], distance_upper_bound=reach)
        out[high[~np.isfinite(distance)]] = True
    return out


def segment_planes(xyz: np.ndarray, segment: np.ndarray, count: int, max_rms: float):
    """Per segment id 0..count-1: (centroid (count, 3), upward unit normal (count, 3), planar (count,) bool)
    of the least-squares plane of its points (float64); planar when it holds at least 10 points and
    their distances to the plane have an RMS of at most ``max_rms`` m (one plane, not a curved or
    multi-facet segment)."""
    sizes, centroid, cov = segment_covariance(segment, xyz, count)
    values, vectors = np.linalg.eigh(cov)
    normal = vectors[:, :, 0] * np.where(vectors[:, 2, 0] < 0, -1.0, 1.0)[:, None]   # upward
    planar = (sizes >= 10) & (np.sqrt(np.maximum(values[:, 0], 0)) <= max_rms)
    return centroid, normal, planar


def covered_completion(xyz: np.ndarray, knn: np.ndarray, core: np.ndarray, grown: np.ndarray,
                       eligible: np.ndarray, tol: float, noise: float, min_support: int = 0) -> tuple[np.ndarray, int]:
    """Roof under crowns: eligible points join, round by round through the kNN graph, the segment
    of a labelled neighbour (``grown`` >= 0) whose fitted plane (segment_planes over ``core``, the
    roofs before edge growth; RMS at most 2 ``noise``) they lie within ``tol`` m of, with at least
    ``min_support`` of their k neighbours on that plane too and at most COVERED_MAX_BELOW of them
    more than ``tol`` under it (a roof hides what is below it, a crown's slab does not); the smallest
    such segment id when
    several qualify, so the result does not depend on point order.
    (labels int32, points added)."""
    labels = np.asarray(grown, np.int32).copy()
    count = int(max(core.max(), labels.max())) + 1 if len(core) else 0
    if not count or not eligible.any():
        return labels, 0
    centroid, normal, planar = segment_planes(xyz, core, count, 2.0 * noise)
    offset = (centroid * normal).sum(axis=1)            # the planes as n . p = offset
    knn = np.asarray(knn)
    k = knn.shape[1]
    waiting = np.flatnonzero(eligible & (labels < 0))
    # reverse kNN edges of the waiting points (target -> owner, sorted by target): once a target is
    # labelled, its owners may qualify
    targets = knn[waiting].ravel()
    owners = np.repeat(waiting, k)
    valid = targets >= 0
    order = np.argsort(targets[valid], kind="stable")
    targets, owners = targets[valid][order], owners[valid][order]
    start = int(np.count_nonzero(labels >= 0))
    big = np.iinfo(np.int32).max
    frontier = waiting
    while len(frontier):
        frontier = frontier[labels[frontier] < 0]
        if not len(frontier):
            break
        nb = knn[frontier]
        cand = np.where(nb >= 0, labels[np.where(nb >= 0, nb, 0)], -1)
        touching = (cand >= 0).any(axis=1)      # most waiting points (crowns) touch no roof
        frontier, cand = frontier[touching], cand[touching]
        safe = np.maximum(cand, 0)
        p = np.asarray(xyz[frontier], np.float64)
        off = np.abs(np.einsum("mj,mkj->mk", p, normal[safe]) - offset[safe])
        ok = (cand >= 0) & planar[safe] & (off <= tol)
        if min_support:
            # the plane carries the point's neighbourhood, not a slab of a crown that crosses it
            nb = knn[frontier]
            q = np.asarray(xyz[np.where(nb >= 0, nb, 0)], np.float64)          # (m, k, 3)
            height = np.einsum("mij,mkj->mki", q, normal[safe]) - offset[safe][:, :, None]
            valid = (nb >= 0)[:, None, :]
            ok &= ((np.abs(height) <= tol) & valid).sum(axis=2) >= min_support
            # a roof hides what is under it; a crown's slab has the crown's lower half beneath it
            ok &= ((height < -tol) & valid).sum(axis=2) <= int(COVERED_MAX_BELOW * k)
        choice = np.where(ok, cand, big).min(axis=1)
        joins = choice < big
        labels[frontier[joins]] = choice[joins]      # one synchronous round
        changed = frontier[joins]
        lo = np.searchsorted(targets, changed, "left")
        hi = np.searchsorted(targets, changed, "right")
        lengths = hi - lo
        ends = np.cumsum(lengths)
        slots = np.repeat(lo - (ends - lengths), lengths) + np.arange(int(ends[-1]) if len(ends) else 0)
        frontier = np.unique(owners[slots])
    return labels, int(np.count_nonzero(labels >= 0)) - start


def low_planar_bound(ctx) -> float:
    """Curvature under which a point counts as planar for the low-and-rough test: a quarter of
    roof_seeds' curvature_max, or the median curvature of the seeds where that is higher. The
    curvature of a noisy plane over k neighbours grows as (noise / neighbourhood radius)^2, so on
    denser or noisier surveys most roof points lie over the fixed quarter (synthetic als-roof with
    3 cm noise at 30 points/m2: seeds' median 0.0076, low houses with 10-14 % of their points under
    0.005 were dropped as hedges); no survey's roofs are taken as rougher than its own seeds."""
    bound = float(ctx.facts.get("roof_curvature_max") or 0.02) / 4
    seed, curvature = ctx.point_data.get("roof_seed"), ctx.point_data.get("curvature")
    if seed is not None and curvature is not None:
        seeds = np.asarray(seed) == 1
        if seeds.any():
            bound = max(bound, float(np.median(np.asarray(curvature)[seeds])))
    return bound


def at_grade_shares(segment: np.ndarray, xyz: np.ndarray, height: np.ndarray, normal_z: np.ndarray,
                    count: int, cell: float, grade_height: float, vertical_nz: float = VERTICAL_NZ) -> np.ndarray:
    """Per segment id: the share of its outline cells that are at grade. A segment's cells are the
    plan cells of edge ``cell`` holding one of its non-vertical points (|normal z| >= vertical_nz:
    a wall's foot stands on the ground, its top is what counts); an outline cell lacks one of its
    four neighbours; it is at grade when its lowest point is under ``grade_height`` over the ground
    (``height``). A roof's outline is its eaves, a storey over the ground; an embankment the cloth
    stayed off meets the ground along its feet (0.84-0.94 on synthetic dikes, roofs of the real
    files at hand 0-0.13). float64, 0 for a segment without such cells."""
    flat = (segment >= 0) & (np.abs(np.asarray(normal_z)) >= vertical_nz) & np.isfinite(height)
    if not flat.any():
        return np.zeros(count)
    ix = np.floor(xyz[flat, 0] / cell).astype(np.int64)
    iy = np.floor(xyz[flat, 1] / cell).astype(np.int64)
    ix -= ix.min() - 1
    iy -= iy.min() - 1
    width = int(iy.max()) + 2
    plane = int(ix.max() + 2) * width
    key = segment[flat].astype(np.int64) * plane + ix * width + iy
    order = np.argsort(key)
    key = key[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    cells = key[start]
    lowest = np.minimum.reduceat(np.asarray(height, np.float64)[flat][order], start)
    inner = np.ones(len(cells), bool)
    for step in (width, -width, 1, -1):
        _, present = find(cells, cells + step)
        inner &= present
    owner = cells // plane
    outline = np.bincount(owner[~inner], minlength=count)
    grade = np.bincount(owner[~inner & (lowest < grade_height)], minlength=count)
    return grade / np.maximum(outline, 1)


def planar_shares(segment: np.ndarray, curvature: np.ndarray, count: int, planar_max: float) -> np.ndarray:
    """Per segment id 0..count-1: the share of its points with curvature below ``planar_max``
    (float64; 0 for an empty id)."""
    inside = segment >= 0
    planar = np.bincount(segment[inside], minlength=count,
                         weights=(np.asarray(curvature)[inside] < planar_max).astype(np.float64))
    return planar / np.maximum(np.bincount(segment[inside], minlength=count), 1)


def annex_segments(segment: np.ndarray, xy: np.ndarray, kept: np.ndarray, candidate: np.ndarray,
                   cell: float, reach: float, min_contact=0.0) -> np.ndarray:
    """Per segment id: a candidate segment with at least one point, and at least ``min_contact``
    (a share, scalar or per segment) of its points, within ``reach`` m in plan of a kept segment's
    point (exact distances; the grid of side ``cell`` m only preselects the points near each
    other). Reads only the kept segments, so the result is order independent (no chains of
    annexes). bool."""
    count = len(kept)
    inside = np.flatnonzero(segment >= 0)
    if not len(inside) or not candidate.any() or not kept.any():
        return np.zeros(count, bool)
    seg = segment[inside]
    ij = np.floor((xy[inside] - xy[inside].min(axis=0)) / cell).astype(np.int64)
    reach_cells = int(np.ceil(round(reach / cell, 9)))
    ij += reach_cells
    n_rows = int(ij[:, 1].max()) + reach_cells + 1
    keys = ij[:, 0] * n_rows + ij[:, 1]
    is_roof, is_candidate = kept[seg], candidate[seg]
    # the roof points in a candidate's window of cells, and the candidates' points with one of
    # those in theirs: both through windows around the fewer cells (the candidates' are few)
    roof = np.flatnonzero(is_roof & _in_window(keys, keys[is_candidate], reach_cells, n_rows))
    probe = np.flatnonzero(is_candidate)
    probe = probe[_in_window(keys[probe], keys[roof], reach_cells, n_rows)]
    if not len(probe) or not len(roof):
        return np.zeros(count, bool)
    from scipy.spatial import cKDTree
    distance, _ = cKDTree(xy[inside[roof]].astype(np.float64)).query(
        xy[inside[probe]].astype(np.float64), distance_upper_bound=float(reach))
    contact = np.bincount(seg[probe[np.isfinite(distance)]], minlength=count)
    sizes = np.bincount(seg, minlength=count)
    return (contact > 0) & (contact >= min_contact * sizes) & candidate


def seen_through(segment: np.ndarray, xyz: np.ndarray, count: int, cell: float, depth: float,
                 later: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per segment id 0..count-1: (its points in its interior cells, the later returns seen under
    it there). A segment's cells are the plan cells (side ``cell`` m) holding its points; interior
    ones have all 8 neighbours among them too (the rim is left out: an eave splits pulses onto the
    wall and the ground beside it). A later return (``later``, bool per point: not the first
    return of its pulse) in no segment more than ``depth`` m under the segment's highest point in
    its cell is seen under it: its pulse passed through the segment, which a roof does not let
    happen and a tree crown's flat patch does. A cell interior to several segments counts for the
    one highest there. int64 arrays."""
    interior_points = np.zeros(count, np.int64)
    seen = np.zeros(count, np.int64)
    segment = np.asarray(segment)
    in_segment = np.flatnonzero(segment >= 0)
    if not count or not len(in_segment):
        return interior_points, seen
    # only the segments' points and the later returns in no segment are read (memory: a few
    # per-point arrays of these, not of the whole cloud)
    free = np.flatnonzero((segment < 0) & np.asarray(later, bool))
    xyz = np.asarray(xyz)
    # cells of the segments' box, one cell of margin: every segment cell's neighbours lie inside it
    xy = xyz[in_segment, :2].astype(np.float64)
    lo = xy.min(axis=0)

    def cells(xy):
        return np.floor((xy - lo) / cell).astype(np.int64) + 1

    ij = cells(xy)
    del xy
    span = ij.max(axis=0) + 2
    n_cells = int(span[0] * span[1])
    seg = segment[in_segment].astype(np.int64)
    pairs, pair_of = np.unique(seg * n_cells + ij[:, 0] * span[1] + ij[:, 1], return_inverse=True)
    del ij
    pair_of = pair_of.reshape(-1)
    top = np.full(len(pairs), -np.inf)
    np.maximum.at(top, pair_of, xyz[in_segment, 2].astype(np.float64))
    pair_cell, pair_seg = pairs % n_cells, pairs // n_cells
    interior = np.ones(len(pairs), bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            if dx or dy:
                interior &= find(pairs, pairs + dx * span[1] + dy)[1]
    interior_points = np.bincount(seg[interior[pair_of]], minlength=count).astype(np.int64)
    candidates = np.flatnonzero(interior)
    if not len(candidates):
        return interior_points, seen
    # per cell the interior pair with the highest top, sorted by cell
    order = candidates[np.lexsort((-top[candidates], pair_cell[candidates]))]
    first = np.ones(len(order), bool)
    first[1:] = pair_cell[order][1:] != pair_cell[order][:-1]
    owner = order[first]
    owner_cell = pair_cell[owner]
    ij = cells(xyz[free, :2].astype(np.float64))
    in_box = (ij >= 0).all(axis=1) & (ij < span).all(axis=1)
    free, ij = free[in_box], ij[in_box]
    free_cell = ij[:, 0] * span[1] + ij[:, 1]
    at, hit = find(owner_cell, free_cell)
    under = hit & (xyz[free, 2].astype(np.float64) < top[owner[at]] - depth)
    seen = np.bincount(pair_seg[owner[at[under]]], minlength=count).astype(np.int64)
    return interior_points, seen


NOISE_SAMPLE = 20_000   # planar roof points the roofs' plane noise is measured on (at most)


def coordinate_hash(xyz: np.ndarray) -> np.ndarray:
    """uint64 per point from the bits of its float32 coordinates: a sample drawn by it does not
    depend on the points' order."""
    from roadx_ti.stages.downsample import hash_keys

    return hash_keys(np.ascontiguousarray(xyz, np.float32).view(np.uint32).astype(np.uint64))


def roof_plane_noise(xyz, knn, segment, normal, curvature, planar_max: float, min_pairs: int = 100,
                     sample: int = NOISE_SAMPLE):
    """Noise of a point pair on the roofs (m): MAD_TO_SIGMA x the median distance of the same-segment kNN
    neighbours of planar roof points (curvature < planar_max) to the plane of the point (its
    position and normal), on about ``sample`` of those points drawn by coordinate_hash. None with
    fewer than ``min_pairs`` such pairs. float64 arithmetic."""
    knn = np.asarray(knn)
    rows = np.flatnonzero((segment >= 0) & (np.asarray(curvature) < planar_max))
    if len(rows) > sample:
        keep = (coordinate_hash(np.asarray(xyz)[rows]) >> np.uint64(40)) < np.uint64((sample << 24) // len(rows))
        rows = rows[keep]
    if not len(rows):
        return None
    nb = knn[rows]
    ok = nb >= 0
    same = ok & (segment[np.where(ok, nb, 0)] == segment[rows][:, None])
    a = np.repeat(rows, knn.shape[1])[same.ravel()]
    b = nb.ravel()[same.ravel()]
    if len(a) < min_pairs:
        return None
    pts = np.asarray(xyz, np.float64)
    off = np.abs(((pts[b] - pts[a]) * np.asarray(normal, np.float64)[a]).sum(axis=1))
    return MAD_TO_SIGMA * float(np.median(off))


class RoofFilter(Stage):
    name = "roof_filter"
    labels = CLASS_BUILDING
    Options = RoofFilterOptions
    # and 'height_above_ground' (cloth_ground) when there: without it the height test is skipped
    requires = ("roof_segment",)

    @property
    def uses_data_edge(self) -> bool:
        """The run measures its points' edge only when edge_cut will read it."""
        return self.options.edge_cut and self.options.min_roof_width > 0

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        """2 x sqrt(min_roof_area): a roof must be whole to be measured (min_roof_area 0, the area
        test off, counts as the default area)."""
        area = options.min_roof_area or RoofFilterOptions.model_fields["min_roof_area"].default
        return 2.0 * math.sqrt(area)

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels.labels import relabel_compact

        o = self.options
        if "roof_segment" not in ctx.point_data:
            raise ValueError("roof_filter needs roof_growing before it (point_data 'roof_segment')")
        segment = np.asarray(ctx.point_data["roof_segment"], np.int32)
        count = int(segment.max()) + 1 if len(segment) and segment.max() >= 0 else 0
        # isolated points (strays far off): out of the density, and the cell grids' corner without them
        far = isolated_in(cloud.xyz, SMALL_PART, ctx) if cloud.n else None
        corner = corner_without_isolated(cloud.xyz, far=far)
        if o.density is not None:
            density, density_source = float(o.density), "option"
        elif ctx.facts.get("point_density"):
            density, density_source = float(ctx.facts["point_density"]), "facts"
        else:
            # isolated points (strays far off, roadx_ti.isolation) add occupied cells but no roof
            kept_xy = cloud.xyz[:, :2] if far is None else cloud.xyz[~far, :2]
            density, density_source = occupied_density(kept_xy, o.density_cell), "non_ground"
        min_points = density * o.min_roof_area
        cell, wall_reach = self.footprint_cell_and_wall_reach(ctx)
        sizes = np.bincount(segment[segment >= 0], minlength=count)
        distance = ctx.point_data.get("neighbour_distance")
        knn = ctx.facts.get("knn")
        if o.local_density and o.density is None and distance is not None and knn is not None and count:
            k = int(np.shape(knn)[1])
            local = k / (np.pi * np.maximum(np.asarray(distance, np.float64), 1e-3) ** 2)
            area_density = segment_medians(segment, local, count)
            density_source += "+local"
        else:
            area_density = np.full(count, density)
        keep_area = sizes >= area_density * o.min_roof_area
        keep_width = np.ones(count, bool)
        height = ctx.point_data.get("height_above_ground")
        if height is None:
            ctx.log.warning("roof_filter: no height above ground (run cloth_ground first); "
                            "the minimum roof height test is skipped")
            keep_height = np.ones(count, bool)
        else:
            median_height = segment_medians(segment, np.asarray(height), count)
            keep_height = median_height >= o.min_roof_height
        cut_segments = 0
        if count and o.min_roof_width > 0 and height is not None:
            width = segment_widths(segment, cloud.xyz[:, :2], count)
            if o.width_measure != "covariance":
                # only where the decision can change: low segments that pass the area and height tests
                judge = keep_area & keep_height & (median_height < o.narrow_max_height)
                if o.width_measure == "bent":     # bent only narrows: the narrow ones stay narrow
                    judge &= width >= o.min_roof_width
                # each segment's own spacing (its points' median neighbour density): the survey's
                # estimate misses flight-strip overlap and thinning
                inscribed = inscribed_widths(segment, cloud.xyz[:, :2], judge, 1 / np.sqrt(np.maximum(area_density, 1e-6)))
                bent = judge if o.width_measure == "inscribed" else judge & (inscribed < BENT_RATIO * width)
                width = np.where(bent, inscribed, width)
            edge = ctx.facts.get(DATA_EDGE)
            if o.edge_cut and edge is not None:
                # a third of the width across: a line of points along the edge (a fence, a wall's
                # top) is not a cut roof
                cut = cut_lengths(segment, cloud.xyz[:, :2], count, edge.contains(cloud.xyz[:, :2]))
                widened = (cut > width) & (width >= o.min_roof_width / 3)
                cut_segments = int(np.count_nonzero(widened & (width < o.min_roof_width) & (cut >= o.min_roof_width)))
                width = np.where(widened, cut, width)
            narrow = width < o.min_roof_width
            keep_width = ~(narrow & (median_height < o.narrow_max_height))
        judged = sizes >= JUDGED_NEIGHBOURHOODS * (int(np.shape(knn)[1]) if knn is not None else 0)
        opaque = np.ones(count, bool)
        later = cloud.later_returns() if o.see_through_depth > 0 and count else None
        if later is not None:
            # points per segment, not cells: both counts scale with the density alike
            interior, seen = seen_through(segment, cloud.xyz, count, cell, o.see_through_depth, later)
            opaque = ~((seen >= o.see_through_min_points) & (seen >= o.max_see_through * interior))
        smooth = np.ones(count, bool)
        planar_max = roof_planar_share = None
        if count and o.low_min_planar > 0 and height is not None and "curvature" in ctx.point_data:
            planar_max = low_planar_bound(ctx)
            shares = planar_shares(segment, ctx.point_data["curvature"], count, planar_max)
            # the survey's own roofs: kept segments over narrow_max_height (this test does not judge them)
            high = keep_area & keep_height & keep_width & opaque & judged & (median_height >= o.narrow_max_height)
            if high.any():
                roof_planar_share = float((shares[high] * sizes[high]).sum() / sizes[high].sum())
                low_min_planar = o.low_min_planar * min(1.0, roof_planar_share / o.low_planar_reference)
            else:
                roof_planar_share, low_min_planar = None, o.low_min_planar
            smooth = ~(judged & (median_height < o.narrow_max_height) & (shares < low_min_planar))
        walled = np.ones(count, bool)
        if count and o.max_at_grade_outline < 1 and height is not None and "normal" in ctx.point_data:
            # cells that hold AT_GRADE_CELL_POINTS points on average: holes of the sampling would be outline
            grade_cell = math.sqrt(AT_GRADE_CELL_POINTS / density) if density > 0 else cell
            grade = at_grade_shares(segment, cloud.xyz, np.asarray(height), np.asarray(ctx.point_data["normal"])[:, 2],
                                    count, grade_cell, o.at_grade_height)
            walled = ~(judged & (grade > o.max_at_grade_outline))
        smooth &= walled
        kept = keep_area & keep_height & keep_width & opaque & smooth
        annexes = 0
        if o.annex_reach > 0 and count and kept.any():
            # dropped by the area or width test only, large enough, not mostly foliage-coloured
            candidate = keep_height & opaque & smooth & ~kept & (sizes >= area_density * o.annex_min_area)
            vegetation = ctx.point_data.get("vegetation")
            if vegetation is not None:
                inside = segment >= 0
                coloured = np.bincount(segment[inside], minlength=count,
                                       weights=(np.asarray(vegetation)[inside] != 0).astype(np.float64))
                candidate &= coloured <= o.annex_max_vegetation * sizes
            gap = ANNEX_GAP_SPACINGS * float(survey_spacing(ctx) or 0.0)
            annex = annex_segments(segment, cloud.xyz[:, :2], kept, candidate, cell, o.annex_reach + gap,
                                   np.where(judged, o.annex_min_contact, 0.0))
            annexes = int(annex.sum())
            kept = kept | annex
        roof = np.zeros(len(segment), bool)
        roof[segment >= 0] = kept[segment[segment >= 0]]
        edges = None
        core = np.where(roof, segment, -1).astype(np.int32)   # the kept roofs before edge growth
        if o.edge_growth and o.edge_rounds and roof.any():
            segment, roof, edges = self._grow_edges(cloud, ctx, segment, roof, height, corner)
        attached = 0
        if o.attach_footprint and roof.any():
            from roadx_ti.kernels.seeds import INSIDE_ONLY, NEAR_SURFACE_ONLY, attach_to_footprints
            from roadx_ti.stages.roof_growing import VEGETATION_BY_RETURNS

            vegetation = ctx.point_data.get("vegetation")
            off_surface_ok = None
            if vegetation is not None:
                vegetation = np.asarray(vegetation)
                # not vegetation: anywhere; foliage returns only (no colour says so) with at least one
                # solid kNN neighbour: near the roof surface (chimneys, vents, railings split pulses
                # as foliage does and stand on or among solid returns; on a small vent most neighbours
                # are split too, so a majority test kept it off: ACCURACY.md's notes); colour, or
                # inside a canopy (every neighbour foliage): on the surface only
                near = (vegetation == VEGETATION_BY_RETURNS) & ~self._in_foliage(ctx, vegetation != 0)
                off_surface_ok = np.where(vegetation == 0, 1, np.where(near, NEAR_SURFACE_ONLY, 0)).astype(np.uint8)
            if o.wall_max_normal_z is not None and "normal" in ctx.point_data and height is not None:
                # level and low: bush and hedge tops under the eaves (balconies stand higher)
                level = (np.abs(np.asarray(ctx.point_data["normal"])[:, 2]) >= o.wall_max_normal_z) & \
                    (np.asarray(height) < o.narrow_max_height)
                ok = np.ones(cloud.n, np.uint8) if off_surface_ok is None else off_surface_ok
                off_surface_ok = np.where(level & (ok == 1), INSIDE_ONLY, ok).astype(np.uint8)
            eligible = None if height is None else \
                (np.asarray(height) >= o.attach_min_height).astype(np.uint8)
            # the footprints of the roofs as grown from their seeds: the rims edge growth added
            # would widen them over foliage beside a roof (its on-surface rule takes any colour)
            grown = np.asarray(attach_to_footprints(
                cloud.xyz, core, off_surface_ok, eligible,
                cell=cell, inside_reach=o.inside_reach, wall_reach=wall_reach,
                surface_tol=o.surface_tol, near_tol=o.superstructure_height))
            if o.over_roof_reach > 0:
                hovering = over_roofs(cloud.xyz, core, grown, cell, o.superstructure_height, o.over_roof_reach,
                                      origin=corner)
                grown = np.where(hovering, -1, grown)
            grown = np.where(roof, segment, grown)
            attached = int(np.count_nonzero(grown >= 0) - np.count_nonzero(roof))
            segment, roof = grown, grown >= 0
        segment_id, kept_count = relabel_compact(np.where(roof, segment, -1).astype(np.int32))
        labels = np.where(roof, CLASS_BUILDING, CLASS_OTHER).astype(np.uint8)
        info = {"density": round(density, 3), "density_source": density_source,
                "min_points": round(min_points, 1), "segments_in": count,
                "dropped_by_area": int((~keep_area).sum()),
                "dropped_by_height": int((keep_area & ~keep_height).sum()),
                "dropped_by_width": int((keep_area & keep_height & ~keep_width).sum()),
                "dropped_as_seen_through": int((keep_area & keep_height & keep_width & ~opaque).sum()),
                "dropped_at_grade": int((keep_area & keep_height & keep_width & opaque & ~walled).sum()),
                "cut_by_data_edge": cut_segments,
                "annexes_kept": annexes, "attached_points": attached,
                "low_planar_max": None if planar_max is None else round(planar_max, 5),
                "roof_planar_share": None if roof_planar_share is None else round(roof_planar_share, 4),
                "footprint_cell_m": round(cell, 4), "wall_reach_m": round(wall_reach, 4),
                "segments_kept": int(kept_count), "roof_points": int(roof.sum())}
        if edges is not None:
            info["edges"] = edges
        return StageResult(labels=labels, segment_id=segment_id, info=info)

    @staticmethod
    def _in_foliage(ctx: StageContext, flagged: np.ndarray) -> np.ndarray:
        """bool per point: every one of its kNN neighbours (roof_seeds' graph) is flagged
        vegetation (a point without neighbours is not); without the graph, every flagged point
        counts as in foliage."""
        knn = ctx.facts.get("knn")
        if knn is None or len(knn) != len(flagged):
            return flagged.copy()
        knn = np.asarray(knn)
        valid = knn >= 0
        hits = (flagged[np.where(valid, knn, 0)] & valid).sum(axis=1)
        return hits >= np.maximum(valid.sum(axis=1), 1)

    def footprint_cell_and_wall_reach(self, ctx: StageContext) -> tuple[float, float]:
        """(footprint cell, wall reach) in m, from the options and the survey's pulse spacing."""
        o = self.options
        cell = o.footprint_cell
        if cell == "auto":
            cell = spacing_cell(ctx, o.footprint_spacings, o.footprint_min_cell, FALLBACK_FOOTPRINT_CELL)
        cell = float(cell)
        wall = cell if o.wall_reach == "cell" else float(o.wall_reach)
        return cell, wall

    def _grow_edges(self, cloud: Cloud, ctx: StageContext, segment, roof, height, corner):
        """Edge completion of the kept roofs (kernels.seeds.grow_roof_edges) with its distances
        from the measured point spacing and height noise: (segment, roof, info); None for info
        when roof_seeds' kNN graph, normals and curvature are not there. ``corner``: the covered
        test's grid corner (isolation.corner_without_isolated)."""
        from roadx_ti.kernels.seeds import grow_roof_edges, required_planar_neighbours

        o = self.options
        knn = ctx.facts.get("knn")
        if knn is None or len(knn) != cloud.n or "normal" not in ctx.point_data or "curvature" not in ctx.point_data:
            return segment, roof, None
        spacing, source = survey_spacing(ctx), "estimates"
        if not spacing:
            # the nearest of the k neighbours' distances, median, as the plan nearest-neighbour
            # distance of a uniform sample of that density (0.5 / sqrt(density))
            distance = np.asarray(ctx.point_data.get("neighbour_distance", []), np.float64)
            finite = distance[np.isfinite(distance)]
            k = max(int(np.shape(knn)[1]), 1)
            spacing = 0.5 * float(np.median(finite)) * np.sqrt(np.pi / k) if len(finite) else 0.0
            source = "neighbour_distance"
        reach = o.edge_reach * float(spacing)
        planar_max = float(ctx.facts.get("roof_curvature_max") or 0.02)
        noise, noise_source = roof_plane_noise(cloud.xyz, knn, np.where(roof, segment, -1), ctx.point_data["normal"],
                                               ctx.point_data["curvature"], planar_max), "roof_planes"
        if noise is None:
            noise, noise_source = np.sqrt(2.0) * float(estimate(ctx, "height_noise_m", 0.0)), "estimates"
        tol = o.edge_noise * noise
        info = {"spacing_m": round(float(spacing), 4), "spacing_source": source,
                "pair_noise_m": round(float(noise), 4), "noise_source": noise_source,
                "reach_m": round(reach, 4), "plane_tol_m": round(float(tol), 4), "added_points": 0}
        if reach <= 0:
            return segment, roof, info
        eligible = ~roof
        may_join = ctx.point_data.get("edge_may_join_all" if o.edge_foliage_returns else "edge_may_join")
        if may_join is not None:
            eligible &= np.asarray(may_join) != 0
        if height is not None:
            eligible &= np.asarray(height) >= o.edge_min_height
        grown = np.asarray(grow_roof_edges(cloud.xyz, knn, np.where(roof, segment, -1).astype(np.int32),
                                           ctx.point_data["normal"], ctx.point_data["curvature"],
                                           eligible.astype(np.uint8), reach=reach, tol=float(tol),
                                           tilt=o.edge_tilt, planar_max=float(planar_max), rounds=o.edge_rounds,
                                           min_support=required_planar_neighbours(o.edge_support, int(np.shape(knn)[1]))))
        if o.covered_clearance > 0:
            from roadx_ti.kernels.grid_min import overtopped

            cell = self.footprint_cell_and_wall_reach(ctx)[0]
            covered = np.asarray(overtopped(cloud.xyz, cell, max(o.covered_clearance, cell), origin=corner)) != 0
            grown, info["covered_points"] = covered_completion(
                cloud.xyz, knn, np.where(roof, segment, -1), grown, eligible & covered, float(tol), float(noise),
                required_planar_neighbours(o.edge_support, int(np.shape(knn)[1])))
        added = grown >= 0
        info["added_points"] = int(np.count_nonzero(added) - np.count_nonzero(roof))
        return np.where(added, grown, segment).astype(np.int32), added, info
