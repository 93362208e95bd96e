"""R5 cloth smoothing and P1 cloth ground filter (kernel: roadx_ti.kernels.cloth.csf).

Both run the cloth simulation filter with the `cloth-simulation-filter` package's parameters;
they differ in which side of the cloth they keep.

The cloth is laid over occupied space only (roadx_ti.isolation): isolated points (a part of at most
SMALL_PART points more than 100 m from the rest, in 3D: also a low-noise point far below) get no
cloth and are not ground; the other points are split into their plan-view parts, and each part
gets its own cloth over its own bounding box (on the same world lattice, starting above its own
lowest point). A cloud that is one part without isolated points runs one cloth, as before. A
cloth that would still hold more particles than the points justify (memory.dense_limit) stops the
run with one line naming its extent and cloth_resolution.
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field

from roadx_ti import isolation, memory, plateaus, terrain_trend
from roadx_ti.cloud import Cloud
from roadx_ti.errors import DataError
from roadx_ti.estimates import TERRAIN_CELL, TERRAIN_REACH
from roadx_ti.kernels.cloth import LATTICE_PERIOD, PARTICLE_BYTES, ClothResult, LatticeTooLarge, csf
from roadx_ti.stages.base import (CLASS_GROUND, MIN_CELL, GROUND_NOISE, GROUND_SURFACE, SURVEY_Z_MIN, GroundSurface, Stage,
                                  StageContext, StageOptions, StageResult, estimate)

# In a tile, the cloth starts above the survey's lowest point (as the whole run's does), but never
# more than this far below the tile's own lowest point: an archive's lowest point says nothing about
# a mountain tile, and a longer fall costs iterations.
MAX_START_DROP = 100.0   # m
# m: least reach of a cloth (half the widest building it hangs over): a building cut by a tile
# window's edge loses the terrain around it that holds the cloth up
CLOTH_SPAN = 30.0
CLOTH_STIFFNESS_PARTICLES = 15   # the cloth's stiffness carries its shape this many particles
# m: the ground's own noise is measured (GROUND_NOISE) only where the survey's height_noise_m
# estimate, an upper bound of it (foliage inflates it), exceeds this; below, the estimate stands
# for it (under roof_seeds' denoise_above, 3.5 cm)
GROUND_NOISE_CHECK = 0.03
# the terrain trend under steep surveys (roadx_ti.terrain_trend): the terrain_grade estimate's cells
# and reach (buildings and crowns up to 4 cells across stand above it), cell minima smoothed over
# about 1.5 cells
TREND_SIGMA_CELLS = 1.5


# the `cloth-simulation-filter` package's defaults, defined once: the kernel's signature
_CSF = {name: p.default for name, p in inspect.signature(csf).parameters.items()}


class ClothOptions(StageOptions):
    cloth_resolution: float = Field(_CSF["cloth_resolution"], ge=MIN_CELL, description="C_r: particle spacing "
                                    "of the cloth (m)")
    rigidness: Literal[1, 2, 3, "auto"] = Field(_CSF["rigidness"], description="cloth stiffness, 1 (steep "
                                                "terrain) .. 3 (flat, urban) (constraint passes as in the CSF "
                                                "package); 'auto': 1 where the survey's terrain_grade estimate "
                                                "(roadx_ti.estimates) exceeds steep_grade, else 3")
    steep_grade: float = Field(0.15, gt=0, description="rigidness 'auto': terrain steeper than this median "
                               "grade (rise over run) gets the steep-terrain cloth (unitless)")
    time_step: float = Field(_CSF["time_step"], gt=0, description="simulation time step (dimensionless, "
                             "the package's default)")
    iterations: int = Field(_CSF["iterations"], ge=1, description="C_n: maximum simulation iterations (count)")
    class_threshold: float = Field(_CSF["class_threshold"], gt=0, description="C_t: a point within this "
                                   "distance of the cloth is ground (m)")
    slope_smooth: bool = Field(_CSF["slope_smooth"], description="the package's bSloopSmooth "
                               "post-processing of steep slopes")


    align_to_world: bool = Field(True, description="lay the particles and the simulation's bands on "
                                 "world multiples of cloth_resolution, and in a tile start the cloth "
                                 "at the survey's lowest point, so tiled and whole runs share one "
                                 "cloth (false: the package's layout from the bounding box)")


class ClothGroundOptions(ClothOptions):
    detrend: Literal["auto"] | bool = Field("auto", description="run the cloth on heights above the "
                                            "terrain's smooth trend (roadx_ti.terrain_trend), so that a "
                                            "hillside is level to it: true, false, or 'auto' where the "
                                            "survey's terrain_grade exceeds detrend_grade")
    detrend_grade: float = Field(0.15, gt=0, description="detrend 'auto': terrain steeper than this median "
                                 "grade (unitless). The trend is opened over 50 m: a flat roof wider than "
                                 "that raises it (a 250 x 150 m hall on a 20 % grade: kappa 0.9993 without "
                                 "the trend, 0.4688 with it), while valleys and bowls whose median grade is "
                                 "15-30 % need it (0.10-0.92 without, 0.94-0.97 with: ACCURACY.md's notes)")
    raised_plateaus: bool = Field(True, description="put back under the terrain the flat roofs the "
                                  "cloth sank into (ground cut off from the ground around it by a step "
                                  "down of plateau_step or more on nearly all its outline: roadx_ti.plateaus)")
    plateau_step: float = Field(2.0, gt=0, description="least wall height of a raised plateau (m)")


class ClothSmoothOptions(ClothOptions):
    # METHODS.md R5 values (paper Table 1): C_r = 2, C_n = 500, C_t = 0.3
    cloth_resolution: float = Field(2.0, ge=MIN_CELL, description="C_r: particle spacing of the cloth (m); paper 2")
    class_threshold: float = Field(0.3, gt=0, description="C_t: a point within this distance of "
                                   "the cloth is kept (m); paper 0.3")


def world_lattice(origin, resolution: float):
    """Local coordinates of a particle whose world x, y are multiples of LATTICE_PERIOD x
    ``resolution`` (float64 math on the cloud's origin, so tiles with different origins agree on
    the particles and on the simulation's bands)."""
    period = resolution * LATTICE_PERIOD
    return tuple(float((-float(o)) % period) for o in origin[:2])


def start_z(points, ctx: StageContext):
    """Local z the cloth over ``points`` (a Cloud or its (n, 3) xyz) starts above: the survey's
    lowest point in a tile (ctx fact set by the tiling), capped at MAX_START_DROP below the
    points' own; None (the points' own) otherwise."""
    xyz = getattr(points, "xyz", points)
    survey = ctx.facts.get(SURVEY_Z_MIN)
    if survey is None or len(xyz) == 0:
        return None
    return max(float(survey), float(xyz[:, 2].min()) - MAX_START_DROP)


@dataclass
class Cloths:
    """The cloths of a cloud's parts: ground and height above the cloth per point (NaN for
    isolated points, which no cloth lies under), and the largest part's cloth (for the DTM)."""
    ground: np.ndarray
    largest: ClothResult | None  # None when every point is isolated
    parts: list                  # (point indices, ClothResult) per simulated part
    isolated: int = 0
    plateaus: list = field(default_factory=list)   # roadx_ti.plateaus.Plateau lowered

    def height_above(self, xyz) -> np.ndarray:
        if self.largest is not None and len(self.parts) == 1 and len(self.parts[0][0]) == len(xyz):
            return self.largest.height_above(xyz)
        out = np.full(len(xyz), np.nan, np.float32)
        for index, result in self.parts:
            out[index] = result.height_above(xyz[index])
        return out

    @property
    def iterations(self) -> int:
        return max((int(r.iterations) for _, r in self.parts), default=0)


def rigidness_for(options: ClothOptions, ctx: StageContext) -> int:
    """The cloth's rigidness: the option's, or for 'auto' 1 on terrain steeper than steep_grade
    (the survey's terrain_grade estimate; every tile of a run gets the same), else 3. On a 30 %
    hillside a rigid cloth stays off the ground and planar hillside passes for roof (ACCURACY.md's
    notes); on flat towns the stiff cloth keeps out of large flat roofs."""
    if options.rigidness != "auto":
        return int(options.rigidness)
    grade = estimate(ctx, "terrain_grade")
    return 1 if grade is not None and float(grade) > options.steep_grade else 3


def detrended(options: ClothOptions, ctx: StageContext) -> bool:
    """Whether the cloth runs on heights above the terrain's trend (option detrend)."""
    mode = getattr(options, "detrend", False)
    if mode != "auto":
        return bool(mode)
    grade = estimate(ctx, "terrain_grade")
    return grade is not None and float(grade) > options.detrend_grade


def _simulate(options: ClothOptions, xyz: np.ndarray, origin, ctx: StageContext, stage: str) -> ClothResult:
    lattice = world_lattice(origin, options.cloth_resolution) if options.align_to_world else None
    trend = None
    points = xyz
    if detrended(options, ctx):
        trend = terrain_trend.fit(xyz, TERRAIN_CELL, 2 * TERRAIN_REACH + 1, TREND_SIGMA_CELLS, origin[:2])
        points = xyz.copy()
        points[:, 2] -= trend.at(xyz[:, :2]).astype(points.dtype)
    try:
        result = csf(points, cloth_resolution=options.cloth_resolution,
                     rigidness=rigidness_for(options, ctx), time_step=options.time_step,
                     iterations=options.iterations, class_threshold=options.class_threshold,
                     slope_smooth=options.slope_smooth, lattice_origin=lattice,
                     # a survey's lowest point says nothing of heights above the trend
                     start_z=start_z(xyz, ctx) if options.align_to_world and trend is None else None,
                     max_particles=memory.dense_limit(len(xyz), PARTICLE_BYTES))
    except LatticeTooLarge as exc:
        extent = xyz[:, :2].max(axis=0) - xyz[:, :2].min(axis=0)
        raise DataError(
            f"{stage}: a cloth over {extent[0]:.0f} x {extent[1]:.0f} m would hold {exc.particles:,} particles "
            f"at cloth_resolution {options.cloth_resolution:g} m "
            f"({memory.format_size(exc.particles * PARTICLE_BYTES)}) for {len(xyz):,} points, more than "
            f"the {exc.limit:,} allowed: raise stages.{stage}.cloth_resolution or run in tiles "
            "(--tile-size)") from None
    if trend is not None:
        # the cloth back on the terrain: its particles raised by the trend under them, and the
        # points classified against it
        rows, cols = result.cloth_z.shape
        px = result.x0 + np.arange(cols) * result.resolution
        py = result.y0 + np.arange(rows) * result.resolution
        grid = np.column_stack([np.tile(px, rows), np.repeat(py, cols)])
        result.cloth_z = (result.cloth_z + trend.at(grid).reshape(rows, cols)).astype(np.float32)
        result.ground = np.abs(result.height_above(xyz)) < options.class_threshold
    return result


def _run_cloth(options: ClothOptions, cloud: Cloud, ctx: StageContext, stage: str) -> Cloths:
    xyz = cloud.xyz
    isolated = isolation.isolated_in(xyz, isolation.SMALL_PART, ctx)
    kept = np.arange(cloud.n) if isolated is None else np.flatnonzero(~isolated)
    split = isolation.parts(xyz[kept, :2] if isolated is not None else xyz[:, :2])
    ground = np.zeros(cloud.n, bool)
    results = []
    raised = []
    for members in split.members():
        index = kept[members]
        whole = len(index) == cloud.n
        part = xyz if whole else xyz[index]
        result = _simulate(options, part, cloud.origin, ctx, stage)
        if getattr(options, "raised_plateaus", False):
            raised += _lower_plateaus(result, part, options)
        ground[index] = result.ground
        results.append((index, result))
    largest = max(results, key=lambda r: len(r[0]))[1] if results else None
    return Cloths(ground, largest, results, 0 if isolated is None else int(isolated.sum()), raised)


def _lower_plateaus(result: ClothResult, xyz: np.ndarray, options: ClothOptions) -> list:
    """Lower the cloth over raised plateaus (flat roofs it sank into) to the terrain around
    them, and classify the points against the lowered cloth (result changed in place); returns
    the plateaus found."""
    supported = plateaus.supported_cells(result, xyz, result.ground)
    occupied = plateaus.supported_cells(result, xyz, np.ones(len(xyz), bool))
    patched, found = plateaus.find(result.cloth_z, supported, result.resolution, options.plateau_step,
                                   _ClothStage.reach(options), occupied)
    if patched is not None:
        result.cloth_z = patched
        result.ground = np.abs(result.height_above(xyz)) < options.class_threshold
    return found


def _export_ground(result: Cloths, cloud: Cloud, ctx: StageContext) -> None:
    """The cloths as the ground surface (GROUND_SURFACE): the DTM export (output.dtm) writes the
    largest part's (a raster over all parts would be sized by their extent)."""
    if result.largest is not None:
        Stage.export_ground(ctx, GroundSurface(result.largest, cloud.origin, [r for _, r in result.parts]))


class _ClothStage(Stage):
    provides = (GROUND_SURFACE,)

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        """The larger of CLOTH_SPAN and CLOTH_STIFFNESS_PARTICLES x cloth_resolution: the buffer
        covers buildings up to 2 x CLOTH_SPAN across."""
        return max(CLOTH_SPAN, CLOTH_STIFFNESS_PARTICLES * float(options.cloth_resolution))


def _info(result: Cloths, options: ClothOptions, ctx: StageContext) -> dict:
    shape = list(result.largest.cloth_z.shape) if result.largest is not None else [0, 0]
    info = {"ground": int(result.ground.sum()), "cloth_shape": shape,
            "iterations": result.iterations, "rigidness": rigidness_for(options, ctx)}
    if options.rigidness == "auto" or getattr(options, "detrend", False) == "auto":
        info["terrain_grade"] = estimate(ctx, "terrain_grade")
    if hasattr(options, "detrend"):
        info["detrended"] = detrended(options, ctx)
    if len(result.parts) > 1:
        info["parts"] = len(result.parts)
    if result.isolated:
        info["isolated"] = result.isolated
    if getattr(options, "raised_plateaus", False):
        info["raised_plateaus"] = len(result.plateaus)
        if result.plateaus:
            info["raised_plateau_cells"] = int(sum(p.cells for p in result.plateaus))
    return info


class ClothSmooth(_ClothStage):
    """R5: keep the points within class_threshold of the cloth (the road surface candidates)."""
    name = "cloth_smooth"
    Options = ClothSmoothOptions

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        if cloud.n == 0:
            return StageResult()
        result = _run_cloth(self.options, cloud, ctx, self.name)
        _export_ground(result, cloud, ctx)
        return StageResult(keep=result.ground, info=_info(result, self.options, ctx))


class ClothGround(_ClothStage):
    """P1: ground leaves the working set as class 2; the rest keeps its height above the cloth."""
    name = "cloth_ground"
    labels = CLASS_GROUND
    Options = ClothGroundOptions
    provides = (GROUND_SURFACE, "height_above_ground")

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        if cloud.n == 0:
            return StageResult()
        result = _run_cloth(self.options, cloud, ctx, self.name)
        _export_ground(result, cloud, ctx)
        keep = ~result.ground
        # aligned with the working points; the pipeline narrows it to the kept ones
        height = result.height_above(cloud.xyz)
        info = _info(result, self.options, ctx)
        noise = estimate(ctx, "height_noise_m")
        if noise is not None and float(noise) > GROUND_NOISE_CHECK:
            from roadx_ti.estimates import height_noise
            ground_noise = height_noise(cloud.xyz[result.ground])
            noise = float(noise) if ground_noise is None else min(float(noise), ground_noise)
        if noise is not None:
            ctx.facts[GROUND_NOISE] = float(noise)
            info["ground_noise_m"] = round(float(noise), 4)
        return StageResult(keep=keep, removed_class=CLASS_GROUND,
                           point_data={"height_above_ground": height}, info=info)
