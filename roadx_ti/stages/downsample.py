"""R1 downsampling: uniform (deterministic stride) and voxel (a real point per voxel).

Both are 'subsample' stages: the skipped points are not decided here; after the pipeline they take
the label of their nearest processed point (METHODS.md R1, label transfer).

Uniform downsampling never skips an isolated point (roadx_ti.isolation: a part of at most
SMALL_PART points, more than 100 m from the rest): its nearest processed point would be that far
away, and its stride must not shift the sample of the other points (which are sampled exactly as
in a cloud without it).
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from roadx_ti import isolation
from roadx_ti.chunks import over_chunks
from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import (MIN_BUFFER, MIN_CELL, SAMPLED_SHARE, Stage, StageContext, StageOptions, StageResult,
                                  estimate)


class UniformOptions(StageOptions):
    target_points: int | None = Field(None, ge=1, description="keep this many points")
    ratio: float | None = Field(None, gt=0, le=1, description="keep this fraction of the points")
    target_density: float | None = Field(None, gt=0, description="keep this many points per m2 of "
                                         "occupied plan area (the survey's, see roadx_ti.estimates); "
                                         "sparser input is kept whole")
    pattern: Literal["stride", "nested", "hashed"] = Field(
        "stride", description="stride: point j of the output is input point floor(j n / m) (METHODS.md "
        "R1); nested: point i is kept when frac(0.618.. i) < ratio, so that a slightly different "
        "ratio keeps nearly the same points; hashed: a point is kept when a hash of its coordinates "
        "(in cells of `hash_cell`) is below the ratio: nested too, and the same points whatever "
        "their order or tiling; the count kept is a draw around the target (kernels/downsample.py)")
    hash_cell: float = Field(0.01, ge=MIN_CELL, description="m: coordinate quantum of the hashed pattern; cell "
                             "boundaries sit a quarter millimetre off the half-cell so that deliveries at "
                             "1 cm and at 1 mm keep nearly all the same points")

    @model_validator(mode="after")
    def _one_of(self):
        if sum(v is not None for v in (self.target_points, self.ratio, self.target_density)) != 1:
            raise ValueError("give exactly one of target_points, ratio or target_density")
        return self

    def kept_share(self, points: int | None = None, density: float | None = None) -> float:
        """Share of ``points`` the stage keeps: its ratio, its target density against the data's
        ``density`` (points per m2; everything when not denser), or its target count; 1 when the
        count or density it needs is unknown (the most it can keep)."""
        if self.ratio is not None:
            return self.ratio
        if self.target_density is not None:
            return min(1.0, self.target_density / density) if density and density > 0 else 1.0
        return min(1.0, self.target_points / points) if points else 1.0


class UniformDownsample(Stage):
    name = "uniform_downsample"
    Options = UniformOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return MIN_BUFFER     # point-local: a stride or a hash per point (the 'hashed' pattern is tile-free)

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels.downsample import hashed_sample, nested_sample, uniform_sample

        o = self.options
        ratio = o.ratio
        if o.target_density is not None:
            # the survey's density (a tile keeps the survey-wide share of its points), of distinct
            # positions: the pipeline leaves repeated records out before the stages (pipelines._run)
            ratio = o.kept_share(density=estimate(ctx, "distinct_density_per_m2") or estimate(ctx, "density_per_m2"))
        if ratio is not None and ratio < 1.0:
            # later stages' spacings follow the kept density (stages.base.survey_spacing)
            ctx.facts[SAMPLED_SHARE] = float(ctx.facts.get(SAMPLED_SHARE) or 1.0) * ratio
        if o.target_points is None and ratio == 1.0:
            # every point kept (a survey not denser than the target): each pattern keeps them all
            return StageResult(keep=np.ones(cloud.n, bool), mode="subsample",
                               info={"target_points": int(cloud.n), "ratio": 1.0})
        isolated = None if not cloud.n else isolation.isolated_in(cloud.xyz, isolation.SMALL_PART, ctx)
        rest = None if isolated is None else np.flatnonzero(~isolated)
        n = cloud.n if rest is None else len(rest)
        # a ratio > 0 keeps at least one point: rounding must not leave a tiny cloud unprocessed
        target = o.target_points or max(int(round(n * ratio)), min(n, 1))
        keep = np.zeros(cloud.n, bool)
        info = {"ratio": round(min(target, n) / max(n, 1), 5)}

        def sample(xyz):
            if o.pattern == "hashed":
                kept = np.flatnonzero(hashed_sample(coordinate_cells(xyz, cloud.origin, o.hash_cell),
                                                    min(target, n) / max(n, 1)))
                # the count is a draw: a few points at a small ratio may all miss; keep the first
                # (the canonical order's: roadx_ti.ordering) rather than none
                return kept if len(kept) or not len(xyz) else np.zeros(1, np.int64)
            if o.pattern == "nested":
                return np.flatnonzero(nested_sample(len(xyz), min(target, n) / max(n, 1)))
            return uniform_sample(xyz, min(target, n))[0]
        if rest is None:
            keep[sample(cloud.xyz)] = True
            return StageResult(keep=keep, mode="subsample", info={"target_points": int(keep.sum()), **info})
        keep[rest[sample(cloud.xyz[rest])]] = True
        keep[isolated] = True
        return StageResult(keep=keep, mode="subsample", info={"target_points": int(keep.sum()),
                                                              "isolated": int(isolated.sum()), **info})


HASH_OFFSET = 0.00025   # m: boundaries this far below each half cell, off any 1 mm or 1 cm grid


def coordinate_cells(xyz: np.ndarray, origin: np.ndarray, cell: float) -> np.ndarray:
    """(n, 3) uint32: the low 32 bits of each world coordinate's cell number, cells of ``cell`` m
    centred on its multiples (boundaries HASH_OFFSET below the half cell): float64 world
    coordinates from the float32 local ones, whose error (< 0.1 mm within 2 km of the origin,
    < 0.25 mm within 8 km) stays inside the offset for coordinates delivered on a 1 mm or coarser
    grid; farther from the local origin some points fall on the other side of a cell boundary.
    Exact world coordinates (float64 ``xyz`` with a zero origin) are exact at any distance."""
    xyz = np.asarray(xyz)
    origin = np.asarray(origin, np.float64)
    out = np.empty(xyz.shape, np.uint32)

    def part(start, stop):
        world = xyz[start:stop].astype(np.float64) + origin
        number = np.floor(world / cell + (0.5 + HASH_OFFSET / cell))
        out[start:stop] = (number.astype(np.int64) & 0xFFFFFFFF).astype(np.uint32)
    over_chunks(part, len(xyz))
    return out


def hash_keys(keys: np.ndarray) -> np.ndarray:
    """uint64 per row of three uint64 keys (a point's integer coordinates or their bits), mixed so
    that a threshold on it draws a spatially uniform sample that does not depend on point order
    (the host-side counterpart of the hashed pattern's kernel hash)."""
    h = keys[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ keys[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F) \
        ^ keys[:, 2] * np.uint64(0x165667B19E3779F9)
    h ^= h >> np.uint64(29)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    return h ^ (h >> np.uint64(32))


class VoxelOptions(StageOptions):
    voxel_size: float = Field(..., gt=0, description="voxel edge (m)")


class VoxelDownsample(Stage):
    name = "voxel_downsample"
    Options = VoxelOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return MIN_BUFFER     # one voxel's points decide its representative (voxels are small)

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels.grid import voxel_downsample

        keep = np.zeros(cloud.n, bool)
        if cloud.n:
            keep[voxel_downsample(cloud.xyz, self.options.voxel_size)] = True
        return StageResult(keep=keep, mode="subsample", info={"voxels": int(keep.sum())})
