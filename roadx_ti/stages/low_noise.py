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
"""
from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from roadx_ti.cloud import Cloud
from roadx_ti.kernels.outliers import MAX_CLUSTER, low_noise
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
    deep_threshold: float = Field(5.0, ge=0, description="under a gap of more than this (m) below the "
                                  "rest of its cell, a run of up to deep_cluster points is noise too: "
                                  "three low returns 24 m under an IGN tile, chained within 1 m, held the "
                                  "cloth under the whole tile (95 % of it roof)")
    deep_cluster: int = Field(4, ge=0, le=MAX_CLUSTER, description="see deep_threshold (0: no "
                              "such rule)")

    @model_validator(mode="after")
    def _deep_below_threshold(self):
        if self.deep_threshold < self.threshold:
            raise ValueError(f"deep_threshold ({self.deep_threshold:g} m) must be at least threshold "
                             f"({self.threshold:g} m)")
        return self


class LowNoise(Stage):
    name = "low_noise"
    Options = LowNoiseOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        # a point's verdict reads its own (world-aligned) cell, and with the deep rule the cells
        # around it
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
            wider = np.asarray(low_noise(cloud.xyz, o.cell, o.threshold, o.max_cluster, o.max_rounds,
                                         origin=tuple(corner), deep_cluster=o.deep_cluster,
                                         deep_threshold=o.deep_threshold)) != 0
            under = under_the_terrain(cloud.xyz, wider & ~noise, ~wider, corner, o.cell, o.deep_threshold)
            deep = int(under.sum())
            noise |= under
        return StageResult(keep=~noise, removed_class=CLASS_LOW_NOISE,
                           info={"removed": int(noise.sum()), "deep": deep, "cell_m": o.cell, "threshold_m": o.threshold})


def under_the_terrain(xyz, candidates, kept, corner, cell: float, depth: float) -> np.ndarray:
    """bool (n,): the ``candidates`` more than ``depth`` under every ``kept`` point of their cell and
    of the 8 cells around it. A run of returns deep under its own cell may be a courtyard's or an
    alley's ground under roofs; deep under the cells around it too, it is under the terrain."""
    out = np.zeros(len(xyz), bool)
    if not candidates.any() or not kept.any():
        return out
    # the kernel's cells (float32 arithmetic from the same corner)
    col = np.floor((xyz[:, 0] - np.float32(corner[0])) / np.float32(cell)).astype(np.int64)
    row = np.floor((xyz[:, 1] - np.float32(corner[1])) / np.float32(cell)).astype(np.int64)
    width = int(row.max()) + 3                        # rows -1 .. max + 1 keyed without overlap
    key = (col + 1) * width + (row + 1)
    floors_of, inverse = np.unique(key[kept], return_inverse=True)
    floor = np.full(len(floors_of), np.inf)
    np.minimum.at(floor, inverse, xyz[kept, 2].astype(np.float64))
    idx = np.flatnonzero(candidates)
    around = np.full(len(idx), np.inf)
    for dc in (-1, 0, 1):
        for dr in (-1, 0, 1):
            k = key[idx] + dc * width + dr
            at = np.clip(np.searchsorted(floors_of, k), 0, len(floors_of) - 1)
            hit = floors_of[at] == k
            around[hit] = np.minimum(around[hit], floor[at[hit]])
    out[idx] = xyz[idx, 2] < around - depth
    return out
