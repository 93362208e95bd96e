"""R5 cloth smoothing and P1 cloth ground filter (kernel: roadx_ti.kernels.cloth.csf).

Both run the cloth simulation filter with the `cloth-simulation-filter` package's parameters;
they differ in which side of the cloth they keep.
"""
from __future__ import annotations

from pydantic import Field

from roadx_ti.cloud import Cloud
from roadx_ti.kernels.cloth import LATTICE_PERIOD, ClothResult, csf
from roadx_ti.stages.base import CLASS_GROUND, SURVEY_Z_MIN, Stage, StageContext, StageOptions, StageResult

# In a tile, the cloth starts above the survey's lowest point (as the whole run's does), but never
# more than this far below the tile's own lowest point: an archive's lowest point says nothing about
# a mountain tile, and a longer fall costs iterations.
MAX_START_DROP = 100.0   # m


class ClothOptions(StageOptions):
    cloth_resolution: float = Field(0.5, gt=0, description="C_r: particle spacing of the cloth (m)")
    rigidness: int = Field(3, ge=1, le=3, description="cloth stiffness, 1 (steep terrain) .. "
                           "3 (flat, urban) (constraint passes as in the CSF package)")
    time_step: float = Field(0.65, gt=0, description="simulation time step (dimensionless, "
                             "the package's default 0.65)")
    iterations: int = Field(500, ge=1, description="C_n: maximum simulation iterations (count)")
    class_threshold: float = Field(0.5, gt=0, description="C_t: a point within this distance of "
                                   "the cloth is ground (m)")
    slope_smooth: bool = Field(False, description="the package's bSloopSmooth post-processing of "
                               "steep slopes")


    align_to_world: bool = Field(True, description="lay the particles and the simulation's bands on "
                                 "world multiples of cloth_resolution, and in a tile start the cloth "
                                 "at the survey's lowest point, so tiled and whole runs share one "
                                 "cloth (false: the package's layout from the bounding box)")


class ClothSmoothOptions(ClothOptions):
    # METHODS.md R5 values (paper Table 1): C_r = 2, C_n = 500, C_t = 0.3
    cloth_resolution: float = Field(2.0, gt=0, description="C_r: particle spacing of the cloth (m); paper 2")
    class_threshold: float = Field(0.3, gt=0, description="C_t: a point within this distance of "
                                   "the cloth is kept (m); paper 0.3")


def world_lattice(origin, resolution: float):
    """Local coordinates of a particle whose world x, y are multiples of LATTICE_PERIOD x
    ``resolution`` (float64 math on the cloud's origin, so tiles with different origins agree on
    the particles and on the simulation's bands)."""
    period = resolution * LATTICE_PERIOD
    return tuple(float((-float(o)) % period) for o in origin[:2])


def start_z(cloud: Cloud, ctx: StageContext):
    """Local z the cloth starts above: the survey's lowest point in a tile (ctx fact set by the
    tiling), capped at MAX_START_DROP below the cloud's own; None (the cloud's own) otherwise."""
    survey = ctx.facts.get(SURVEY_Z_MIN)
    if survey is None or cloud.n == 0:
        return None
    return max(float(survey), float(cloud.xyz[:, 2].min()) - MAX_START_DROP)


def _run_cloth(options: ClothOptions, cloud: Cloud, ctx: StageContext) -> ClothResult:
    lattice = world_lattice(cloud.origin, options.cloth_resolution) if options.align_to_world else None
    return csf(cloud.xyz, cloth_resolution=options.cloth_resolution,
               rigidness=options.rigidness, time_step=options.time_step,
               iterations=options.iterations, class_threshold=options.class_threshold,
               slope_smooth=options.slope_smooth, lattice_origin=lattice,
               start_z=start_z(cloud, ctx) if options.align_to_world else None)


def _info(result: ClothResult) -> dict:
    return {"ground": int(result.ground.sum()), "cloth_shape": list(result.cloth_z.shape),
            "iterations": int(result.iterations)}


class ClothSmooth(Stage):
    """R5: keep the points within class_threshold of the cloth (the road surface candidates)."""
    name = "cloth_smooth"
    Options = ClothSmoothOptions

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        if cloud.n == 0:
            return StageResult()
        result = _run_cloth(self.options, cloud, ctx)
        ctx.facts["cloth"] = (result, cloud.origin)   # for a DTM export (output.dtm)
        return StageResult(keep=result.ground, info=_info(result))


class ClothGround(Stage):
    """P1: ground leaves the working set as class 2; the rest keeps its height above the cloth."""
    name = "cloth_ground"
    Options = ClothOptions

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        if cloud.n == 0:
            return StageResult()
        result = _run_cloth(self.options, cloud, ctx)
        ctx.facts["cloth"] = (result, cloud.origin)   # for a DTM export (output.dtm)
        keep = ~result.ground
        # aligned with the working points; the pipeline narrows it to the kept ones
        height = result.height_above(cloud.xyz)
        return StageResult(keep=keep, removed_class=CLASS_GROUND,
                           point_data={"height_above_ground": height}, info=_info(result))
