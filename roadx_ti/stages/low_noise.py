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
from pydantic import Field

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


class LowNoise(Stage):
    name = "low_noise"
    Options = LowNoiseOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        # a point's verdict reads only its own (world-aligned) cell
        return max(MIN_BUFFER, float(options.cell))

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
        return StageResult(keep=~noise, removed_class=CLASS_LOW_NOISE,
                           info={"removed": int(noise.sum()), "cell_m": o.cell, "threshold_m": o.threshold})
