"""R3 iterative RANSAC removal of non-road planes (kernel: roadx_ti.kernels.ransac).

Reading of METHODS.md R3: repeatedly find the best plane among the unmatched points (many
hypotheses scored in parallel, least-squares refit); stop when it has fewer than ``min_inliers``
points, when fewer than 3 unmatched points remain, or after ``max_planes`` planes. Each accepted
plane is classified: tilted more than ``max_tilt_deg`` from horizontal -> Z class (walls, poles),
removed; near-horizontal with the median height of its inliers above the local ground reference
greater than ``dh_max`` -> XY class (roofs, terraces), removed (with ``xy_removal: part``, each
connected part of its inliers is classed by its own median height: an infinite plane's slab at
roof height also takes a band of a street that climbs to that height, apart from the roof);
otherwise ground-level, kept. Its points are marked matched either way, so it is not found again.
The ground reference under a point is the lowest point of the 3 x 3 coarse grid cells
(``ground_cell``) around its cell, so a roof point still sees the ground beside its building;
with ``ground_slope`` a neighbouring cell's lowest point counts raised by that grade over the
distance between the cells, so that on steep terrain the reference follows the slope instead of
lying metres under the street (a cone-limited lower envelope, as morphological ground filters
bound the terrain's slope). With ``at_grade_share``, a part that is high by that reference stays
when that share of its outline (sides of its 1 m plan cells, holes filled, towards occupied cells
beyond) goes on at grade or up: the lowest point beyond lies at most ``at_grade_drop`` under the
part's own there. A roof's outline drops a storey all round; a street cut into a hillside has a
wall or slope rising along one side and a shoulder at grade, while its reference lies down the
bank below it.
"""
from __future__ import annotations

import inspect
import math
from typing import Literal

import numpy as np
from pydantic import Field

from roadx_ti import isolation
from roadx_ti.cloud import Cloud
from roadx_ti.kernels.ransac import SAMPLE_SIZE, fit_plane
from roadx_ti.segments import segment_medians
from roadx_ti.sorted_keys import find
from roadx_ti.stages.base import MIN_CELL, Stage, StageContext, StageOptions, StageResult

MAX_FOOTPRINT_CELLS = 1 << 24    # a plane's plan raster for filling its holes (larger: holes count as outline)
MAX_HYPOTHESES = 100_000    # 100 times the paper's 1000: about a second per plane search here


class RansacOptions(StageOptions):
    distance_threshold: float = Field(0.1, gt=0, description="R_t: inlier distance to the plane (m); the "
                                      "paper's '10' has no unit and cannot be metres")
    min_inliers: int = Field(100, ge=3, description="R_n: a plane needs more than this many points")
    hypotheses: int = Field(inspect.signature(fit_plane).parameters["hypotheses"].default, ge=1, le=MAX_HYPOTHESES,
                            description="R_m: plane hypotheses tried per plane search (at most "
                            f"{MAX_HYPOTHESES:,}: each costs a pass over a {SAMPLE_SIZE:,}-point sample, and a "
                            "kernel cannot be interrupted)")
    max_planes: int = Field(50, ge=1, description="at most this many planes are extracted")
    max_tilt_deg: float = Field(45.0, gt=0, lt=90, description="a plane whose normal tilts more than this "
                                "from vertical is Z class (walls) and removed (degrees)")
    dh_max: float = Field(1.0, gt=0, description="a near-horizontal plane whose inliers lie higher than this "
                          "above the ground reference is XY class and removed (m)")
    ground_cell: float = Field(10.0, ge=MIN_CELL, description="cell edge of the ground reference grid (m); the "
                               "reference is the minimum over the 3 x 3 cells around a point's cell")
    ground_slope: float = Field(0.0, ge=0, le=1, description="terrain grade (rise / run) the ground reference "
                                "follows: a neighbouring cell's minimum counts raised by this grade times the "
                                "distance between the cell centres (0: the plain 3 x 3 minimum). On a street "
                                "climbing at 15 % the plain minimum of a 30 m window lies up to 3 m under the "
                                "ground, and the street's own plane was removed as an XY (roof) plane")
    xy_removal: Literal["plane", "part"] = Field(
        "plane", description="plane: every inlier of an XY plane is removed (METHODS.md R3); part: the "
        "plane's inliers are split into connected parts (plan cells of part_cell) and each part is "
        "classed by its own median height above the ground reference (the slab of a horizontal roof "
        "plane also crosses a sloped street where the street climbs to the roof's height)")
    part_cell: float = Field(1.0, ge=MIN_CELL, description="m: inliers in touching plan cells of this edge are one "
                             "part of their plane (xy_removal: part)")
    at_grade_share: float | None = Field(None, gt=0, le=1, description="with xy_removal part: a part high "
                                         "above the ground reference stays when at least this share of its outline "
                                         "goes on at grade or up (the lowest point of the plan cell beyond lies at most "
                                         "at_grade_drop under the part's own there): a street on a hillside, whose "
                                         "reference lies down the bank below it, against a roof, whose edges drop a "
                                         "storey (None: height alone, METHODS.md R3)")
    at_grade_drop: float = Field(1.0, gt=0, description="m: the drop across a part's outline up to which its "
                                 "surface goes on at grade (kerbs, shoulders, a bank's first metre)")


def _height_above_local_minimum(xyz, cell_size, ctx=None, slope=0.0):
    """z minus the lowest z of the 3 x 3 cells around each point's cell, a neighbour's minimum raised
    by ``slope`` times the distance between the cell centres (per-cell minima from the grid-min
    kernel; the 3 x 3 minimum over the occupied cells on the host, found by their keys, so a
    bounding box inflated by far points costs nothing)."""
    from roadx_ti.kernels.grid_min import cell_minimum, dense_fits, sparse_cell_minimum

    origin = isolation.corner_without_isolated(xyz, ctx)       # far strays move no cell of the others
    if dense_fits(xyz, cell_size, origin):
        cell, cell_lowest, n_cols = cell_minimum(xyz, cell_size, origin)
        occupied = np.flatnonzero(cell_lowest >= 0)
        col, row = occupied % n_cols, occupied // n_cols
        lowest = cell_lowest[occupied]
        slot = np.full(len(cell_lowest), -1, np.int64)
        slot[occupied] = np.arange(len(occupied))
        cell = slot[cell]
    else:
        cell, lowest, col_row = sparse_cell_minimum(xyz, cell_size, origin)
        col, row = col_row[:, 0], col_row[:, 1]
    cell_min_z = xyz[lowest, 2].astype(np.float32)
    local_min = _neighbourhood_minimum(col.astype(np.int64), row.astype(np.int64), cell_min_z, slope * cell_size)
    return xyz[:, 2] - local_min[cell]


def _neighbourhood_minimum(col, row, value, rise=0.0):
    """Per occupied cell, the minimum of ``value`` over the occupied cells of its 3 x 3 block, a
    neighbour's value raised by ``rise`` per cell of distance between the centres (1 or sqrt 2)."""
    col, row = col - col.min(), row - row.min()
    span = int(row.max()) + 3
    key = (col + 1) * span + (row + 1)
    order = np.argsort(key)
    sorted_key = key[order]
    best = value.copy()
    for dc in (-1, 0, 1):
        for dr in (-1, 0, 1):
            if dc == dr == 0:
                continue
            j, hit = find(sorted_key, key + dc * span + dr)
            raised = value[order[j[hit]]] + np.float32(rise * math.hypot(dc, dr))
            best[hit] = np.minimum(best[hit], raised)
    return best


class PlanCells:
    """The lowest point of every occupied plan cell (edge ``cell``) of a cloud (the grid-min
    kernel's sparse cells: strays far away cost nothing), by sorted cell keys, for the at-grade
    test of high XY parts."""

    def __init__(self, xyz, cell: float):
        from roadx_ti.kernels.grid_min import sparse_cell_minimum

        self.xyz = xyz
        cell_of_point, lowest, col_row = sparse_cell_minimum(xyz, cell, xyz[:, :2].min(axis=0))
        # cells come in (col, row) order, so their keys are sorted; a margin of one cell keeps the
        # keys of cells one beyond the edge distinct
        self.span = int(col_row[:, 1].max()) + 3
        self.keys = (col_row[:, 0] + 1) * self.span + (col_row[:, 1] + 1)
        self.key = self.keys[cell_of_point]
        self.lowest = xyz[lowest, 2].astype(np.float64)

    def at_grade_share(self, inliers, part, n_parts: int, drop: float) -> np.ndarray:
        """Per part of a plane's inliers: the share of its outline (sides between a cell of the
        plane and an occupied cell outside its footprint, holes filled) where the cell beyond has
        its lowest point at most ``drop`` under the part's lowest point in the cell beside it."""
        key = self.key[inliers]
        order = np.lexsort((self.xyz[inliers, 2], key))
        sorted_key = key[order]
        first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
        own_keys = sorted_key[first]
        own_lowest = self.xyz[inliers[order[first]], 2].astype(np.float64)
        own_part = part[order[first]]
        # the plane's footprint with its holes filled: rooftop units, skylights and parapets
        # inside a roof are no outline
        col, row = own_keys // self.span, own_keys % self.span
        c0, r0 = col.min() - 1, row.min() - 1
        shape = (int(col.max() - c0) + 2, int(row.max() - r0) + 2)
        filled = None
        if shape[0] * shape[1] <= MAX_FOOTPRINT_CELLS:
            from scipy import ndimage
            grid = np.zeros(shape, bool)
            grid[col - c0, row - r0] = True
            filled = ndimage.binary_fill_holes(grid)
        at_grade = np.zeros(n_parts)
        sides = np.zeros(n_parts)
        for dc, dr in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            beyond = own_keys + dc * self.span + dr
            if filled is not None:
                outside = ~filled[col + dc - c0, row + dr - r0]
            else:
                outside = ~find(own_keys, beyond)[1]
            j, occupied = find(self.keys, beyond)
            side = outside & occupied
            level = side & (self.lowest[j] >= own_lowest - drop)
            sides += np.bincount(own_part[side], minlength=n_parts)
            at_grade += np.bincount(own_part[level], minlength=n_parts)
        return at_grade / np.maximum(sides, 1.0)


class RansacPlanes(Stage):
    name = "ransac_planes"
    Options = RansacOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return float(options.ground_cell)    # the ground reference: 3 x 3 cells around a point's cell

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        o = self.options
        xyz = cloud.xyz
        height_above_ground = _height_above_local_minimum(xyz, o.ground_cell, ctx, o.ground_slope)
        keep = np.ones(cloud.n, bool)
        planes = []
        cos_tilt = math.cos(math.radians(o.max_tilt_deg))
        # the search runs on the unmatched points alone (ascending indices, their coordinates
        # shrinking with them): the same hypotheses, sample and inliers as a search over all
        # points with the matched ones inactive, which draws from them in the same order
        unmatched = np.arange(cloud.n)
        unmatched_xyz = xyz
        cells = None            # the plan cells' lowest points, made when a part needs them
        for number in range(o.max_planes):
            if len(unmatched) < 3:
                break
            fit = fit_plane(unmatched_xyz, o.distance_threshold, hypotheses=o.hypotheses,
                            seed=ctx.seed + number)
            hit = np.asarray(fit.inliers, bool)
            inliers = unmatched[hit]
            if len(inliers) <= o.min_inliers:
                break
            normal_z = abs(float(fit.plane[2]))
            median_height = float(np.median(height_above_ground[inliers]))
            if normal_z < cos_tilt:
                kind = "Z"
            elif median_height > o.dh_max:
                kind = "XY"
            else:
                kind = "ground"
            removed = len(inliers) if kind != "ground" else 0
            if kind == "XY" and o.xy_removal == "part":
                # connected parts: touching plan cells of part_cell (isolation's block parts)
                found = isolation.parts(xyz[inliers, :2], o.part_cell)
                part = np.zeros(len(inliers), np.int64) if found.label is None else found.label
                high = segment_medians(part, height_above_ground[inliers], found.count) > o.dh_max
                if o.at_grade_share is not None and high.any():
                    if cells is None:
                        cells = PlanCells(xyz, o.part_cell)
                    high &= cells.at_grade_share(inliers, part, found.count, o.at_grade_drop) < o.at_grade_share
                removed = int(high[part].sum())
                keep[inliers[high[part]]] = False
            elif kind != "ground":
                keep[inliers] = False
            unmatched, unmatched_xyz = unmatched[~hit], unmatched_xyz[~hit]
            planes.append({"plane": [round(float(v), 6) for v in fit.plane], "points": int(len(inliers)),
                           "removed": int(removed), "class": kind, "median_height": round(median_height, 3)})
        info = {"planes": len(planes), "removed": int((~keep).sum()),
                "by_class": {c: sum(p["points"] for p in planes if p["class"] == c) for c in ("Z", "XY", "ground")},
                "plane_list": planes}
        return StageResult(keep=keep, info=info)
