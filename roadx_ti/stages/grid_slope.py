"""R4 grid min-height slope / height-difference filter (kernel: roadx_ti.kernels.grid_min).

The grid's corner is the points' minimum without isolated points (roadx_ti.isolation), so that
far strays neither move the cells of the others nor size the grid (the kernel's cells are sparse
when a dense grid would not fit)."""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from roadx_ti import isolation
from roadx_ti.cloud import Cloud
from roadx_ti.kernels.grid_min import slope_filter
from roadx_ti.stages.base import MIN_CELL, Stage, StageContext, StageOptions, StageResult, estimate


class GridSlopeOptions(StageOptions):
    step: float = Field(0.5, ge=MIN_CELL, description="grid cell edge (m); paper Step = 0.5")
    slope_max: float = Field(0.1, gt=0, description="S_t: max slope dh / horizontal distance to the "
                             "cell's lowest point (dimensionless); paper 0.1")
    dh_max: float = Field(1.0, gt=0, description="dh_t: max height above the cell's lowest point (m); paper 1")
    noise_allowance: float | Literal["auto"] | None = Field(
        None, description="a point less than this above its cell's lowest point is never removed for "
        "its slope (m): near the lowest point, noise alone makes S large. 'auto': 4 x the survey's "
        "height noise; None: off (the paper's test)")
    cell_reference: Literal["lowest", "supported"] = Field(
        "lowest", description="lowest: the cell's lowest point (METHODS.md R4); supported: the second "
        "lowest when the lowest lies more than the noise allowance under it and the third follows the "
        "second within it, so that a single low outlier (matching errors leave points 0.3-2 m under "
        "the surface that SOR keeps) does not make every point of its cell high; needs noise_allowance")

    @model_validator(mode="after")
    def _supported_needs_allowance(self):
        if isinstance(self.noise_allowance, float) and self.noise_allowance < 0:
            raise ValueError("noise_allowance must be >= 0 m (0: off), 'auto' or null")
        if self.cell_reference == "supported" and not self.noise_allowance:
            raise ValueError("cell_reference 'supported' needs noise_allowance (a height in m or 'auto')")
        return self


class GridSlope(Stage):
    name = "grid_slope"
    Options = GridSlopeOptions
    provides = ("height_above_cell_min",)

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return 4.0 * float(options.step)     # the cell's lowest point, cells a few steps around

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        if cloud.n == 0:
            return StageResult()
        o = self.options
        allowance = o.noise_allowance
        if allowance == "auto":
            allowance = 4.0 * float(estimate(ctx, "height_noise_m", 0.0))
        gap = float(allowance) if o.cell_reference == "supported" and allowance else None
        if o.cell_reference == "supported" and gap is None:
            ctx.log.warning("grid_slope: no height noise measured; the cells' lowest points are the references")
        keep, height = slope_filter(cloud.xyz, o.step, o.slope_max, o.dh_max,
                                    origin=isolation.corner_without_isolated(cloud.xyz, ctx), outlier_gap=gap)
        keep = keep.astype(bool)
        info = {} if gap is None else {"outlier_gap_m": round(gap, 4)}
        if allowance:
            dh = np.asarray(height)
            keep |= (dh < allowance) & (dh < o.dh_max)
            info["noise_allowance_m"] = round(float(allowance), 4)
        # height_above_cell_min is negative for a low outlier the supported reference skipped
        return StageResult(keep=keep, point_data={"height_above_cell_min": height},
                           info={"removed": int((~keep).sum()), **info})
