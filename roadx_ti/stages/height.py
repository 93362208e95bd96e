"""Height above ground: z normalised by the ground surface of a ground stage before it (PDAL's
filters.hag_*, lidR's normalize_height). Kernel: the cloth's bilinear height
(kernels.cloth.ClothResult.height_above, through stages.base.GroundSurface).

Needs a ground stage before it (cloth_ground or cloth_smooth: GROUND_SURFACE). Writes point_data
'height_above_ground' (float32, m; NaN under no part of the surface: isolated points), which later
stages read (roof_filter's height tests) and the output carries as an extra dimension (LAS/LAZ
extra bytes, a PLY property, an NPZ/PCD/text column; in tiled runs each point's from its core
tile). Points the stage does not see (removed or skipped by earlier stages, e.g. the ground
cloth_ground takes out) get NaN there. It narrows nothing and labels nothing, so a pipeline's
labels do not change when it is added.
"""
from __future__ import annotations

import numpy as np
from pydantic import Field

from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import GROUND_SURFACE, MIN_BUFFER, Stage, StageContext, StageOptions, StageResult


class HeightAboveGroundOptions(StageOptions):
    clamp_negative: bool = Field(False, description="heights below the surface (noise, points within "
                                 "the ground stage's class_threshold under it) become 0")


class HeightAboveGround(Stage):
    name = "height_above_ground"
    narrows = False
    Options = HeightAboveGroundOptions
    requires = (GROUND_SURFACE,)
    provides = ("height_above_ground",)
    writes = ("height_above_ground",)

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return MIN_BUFFER     # point-local: the surface under a point (the ground stage's reach covers it)

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        surface = ctx.facts.get(GROUND_SURFACE)
        if surface is None:       # the ground stage saw no point (or only isolated ones)
            height = np.full(cloud.n, np.nan, np.float32)
        else:
            height = surface.height_above(cloud.xyz)
        if self.options.clamp_negative:
            height = np.where(height < 0, np.float32(0), height)
        finite = height[np.isfinite(height)]
        info = {"points": int(cloud.n), "no_surface": int(cloud.n - len(finite))}
        if len(finite):
            info["median_m"] = round(float(np.median(finite)), 4)
            info["max_m"] = round(float(finite.max()), 4)
        return StageResult(point_data={"height_above_ground": height}, info=info)
