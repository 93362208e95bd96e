"""Low noise before a ground filter: extended local minimum (kernel: roadx_ti.kernels.outliers.low_noise).

Airborne LiDAR carries returns far below the terrain (multipath, the laser's echo off wet or
glassy surfaces). A cloth simulation takes the lowest points as the ground's collision heights, so
a handful of them holds the cloth metres under a whole block: the ground there is then "above
ground" and roof growing takes it for a flat roof (synthetic als-roof 300 k seed 6: kappa 0.866
with, 0.951 without the generator's low outliers). PDAL runs filters.elm before its ground filters
for this; this stage is that rule: in every plan cell (world-aligned, so tiles agree), the lowest
point (or a pair: max_cluster) is noise while the next point of its cell lies more than ``threshold``
above it. On the shared real tiles it flags 0-15 points a tile (ground, foliage and a wall point in
cells at a tile's edge, the reviewed tile's unlabelled points), on that synthetic scene 93 of its 126
low returns (those within 1 m of the terrain stay, and do not matter to the cloth). Flagged
points get class 7 (ASPRS low point / noise) and leave the working set.

The deep rule (deep_threshold, deep_cluster) extends it: a run of up to deep_cluster points under
a gap of more than deep_threshold in its cell is noise when it, and every such run chained to it
within deep_threshold across cells, lies that much under every other point of the 3 x 3 cells
around it (three returns 24 m under an IGN tile, chained within 1 m, had held the cloth under the
whole tile). A chain that reaches the terrain's level somewhere (an alley's ground leading to a
street) stays; on the shared files the rule takes no point.
"""
from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from roadx_ti.cloud import Cloud
from roadx_ti.kernels.outliers import MAX_CLUSTER, low_noise
from roadx_ti.sorted_keys import find
from roadx_ti.stages.base import MIN_BUFFER, MIN_CELL, Stage, StageContext, StageOptions, StageResult

CLASS_LOW_NOISE = 7     # ASPRS: low point (noise)


class LowNoiseOptions(StageOptions):
    cell: float = Field(10.0, ge=MIN_CELL, description="plan cell edge (m); PDAL filters.elm's default")
    threshold: float = Field(1.0, ge=0, description="a cell's lowest point is noise when the next "
                             "lowest lies more than this above it (m); PDAL filters.elm's default")
    max_cluster: int = Field(2, ge=1, le=MAX_CLUSTER, description="at most this many low points "
                             "under one gap are noise together (low returns come in pairs under one "
                             "spot; filters.elm: 1)")
    max_rounds: int = Field(16, ge=1, le=256, description="rounds: at most this many runs of low "
                            "points, one under another, are flagged in one cell")
    deep_threshold: float = Field(5.0, ge=0, description="a run of up to deep_cluster points under a gap "
                                  "of more than this (m) in its cell (at least threshold) is noise too when "
                                  "it, and every such run joined to it within this distance, lies this much "
                                  "under every other point of the 3 x 3 cells around: three low returns 24 m "
                                  "under an IGN tile, chained within 1 m, held the cloth under the whole tile "
                                  "(95 % of it roof)")
    deep_cluster: int = Field(4, ge=0, le=MAX_CLUSTER, description="see deep_threshold (0, or not above "
                              "max_cluster: no such rule)")

    @model_validator(mode="after")
    def _deep_within_a_cell(self):
        # the points around a deep run are read in its cell and the 8 around it
        if self.deep_cluster > self.max_cluster and self.deep_threshold > self.cell:
            raise ValueError(f"deep_threshold ({self.deep_threshold:g} m) must not exceed cell ({self.cell:g} m)")
        return self


class LowNoise(Stage):
    name = "low_noise"
    Options = LowNoiseOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        # a point's verdict reads its own (world-aligned) cell; with the deep rule, the cells
        # around it and the deep runs chained to it (a chain reaching past the buffer, a rare
        # thing, may read differently in a tile)
        cells = 2.0 if options.deep_cluster > options.max_cluster else 1.0
        return max(MIN_BUFFER, cells * float(options.cell))

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        o = self.options
        if cloud.n == 0:
            return StageResult(info={"removed": 0})
        # cells on the world lattice of edge `cell`: the local corner of the cell holding the
        # lowest local x / y, in float64 before the kernel's float32 arithmetic
        lo = cloud.xyz[:, :2].min(axis=0).astype(np.float64) + cloud.origin[:2]
        corner = np.floor(lo / o.cell) * o.cell - cloud.origin[:2]
        noise = np.asarray(low_noise(cloud.xyz, o.cell, o.threshold, o.max_cluster, o.max_rounds,
                                     origin=tuple(corner))) != 0
        deep = 0
        if o.deep_cluster > o.max_cluster:
            deep_threshold = max(o.deep_threshold, o.threshold)    # (a larger threshold raises it)
            wider = np.asarray(low_noise(cloud.xyz, o.cell, o.threshold, o.max_cluster, o.max_rounds,
                                         origin=tuple(corner), deep_cluster=o.deep_cluster,
                                         deep_threshold=deep_threshold)) != 0
            under = under_the_terrain(cloud.xyz, wider & ~noise, noise, corner, o.cell, deep_threshold)
            deep = int(under.sum())
            noise |= under
        return StageResult(keep=~noise, removed_class=CLASS_LOW_NOISE,
                           info={"removed": int(noise.sum()), "deep": deep, "cell_m": o.cell, "threshold_m": o.threshold})


def under_the_terrain(xyz, candidates, noise, corner, cell: float, depth: float) -> np.ndarray:
    """bool (n,): the ``candidates`` (runs the kernel's deep rule took: under a gap of more than
    ``depth`` in their cell) in groups (joined within ``depth``, across cells, with the points the
    single-cell rule took, ``noise``) whose every candidate lies more than ``depth`` under every
    other point of its cell and of the 8 around it (``noise`` counts as no point). A courtyard's
    ground under roofs is such a run, but the street in a cell beside it lies at its level; an
    alley's ground, a few points a cell, joins its cells into a chain that reaches a street."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    out = np.zeros(len(xyz), bool)
    idx = np.flatnonzero(candidates)
    if not len(idx):
        return out
    # the kernel's cells (float32 arithmetic from the same corner); keys of rows -1 .. max + 1
    col = np.floor((xyz[:, 0] - np.float32(corner[0])) / np.float32(cell)).astype(np.int64)
    row = np.floor((xyz[:, 1] - np.float32(corner[1])) / np.float32(cell)).astype(np.int64)
    width = int(row.max()) + 3
    key = (col + 1) * width + (row + 1)
    steps = (np.arange(-1, 2)[:, None] * width + np.arange(-1, 2)).ravel()
    # the lowest other point of each cell, then of the cells around each candidate
    kept = ~candidates & ~noise
    cells, inverse = np.unique(key[kept], return_inverse=True)
    floor = np.full(len(cells), np.inf)
    np.minimum.at(floor, inverse, xyz[kept, 2].astype(np.float64))
    around = np.full(len(idx), np.inf)
    for step in steps:
        at, hit = find(cells, key[idx] + step)
        around[hit] = np.minimum(around[hit], floor[at[hit]])
    under = xyz[idx, 2] < around - depth
    # groups over the candidates and the single-cell rule's points near them
    near = np.unique((key[idx][:, None] + steps).ravel())
    low = np.concatenate([idx, np.flatnonzero(noise & np.isin(key, near))])
    pts = xyz[low].astype(np.float64)
    pairs = cKDTree(pts).query_pairs(depth, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(low), len(low)))
    count, group = connected_components(graph, directed=False)
    # a group is under the terrain when all its runs are: one at the terrain's level (an alley's
    # cell beside the street it leads to) keeps the whole chain
    level = np.bincount(group[: len(idx)], weights=~under, minlength=count) > 0
    out[idx] = ~level[group[: len(idx)]]
    return out
