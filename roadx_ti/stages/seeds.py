"""P2 roof seed points (kernels: neighbors.knn, features.covariance_features, seeds.seed_constraints).

Runs on the non-ground points (after cloth_ground). Computes the kNN graph and the neighbourhood
features once and hands them on: point_data 'normal', 'curvature', 'roof_seed' (uint8), and
ctx.facts['knn'] (int32 (n, k) indices into this stage's working set) for roof_growing. The stage
narrows nothing, so those indices stay valid for the next stage.
Isolated points (roadx_ti.isolation: a part of at most k points, more than 100 m from the rest)
are left out of the kNN graph: they get no neighbours (-1), no seed, curvature 1, so far strays
size no grid and no other point's neighbourhood changes.
"""
from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np

from pydantic import Field

from roadx_ti import isolation
from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import GROUND_NOISE, Stage, StageContext, StageOptions, StageResult, survey_spacing

MAX_PLANE_K = 31     # the denoising planes' neighbours (kNN rows of at most 32)


class RoofSeedsOptions(StageOptions):
    k: int = Field(10, ge=3, le=128, description="neighbours per point (p itself excluded)")
    curvature_max: float | None = Field(
        0.02, gt=0, le=1.0 / 3.0, description="c_t: planar candidates have curvature l0/(l0+l1+l2) "
        "below this (unitless); null switches the planarity constraint off")
    plane_coef: float = Field(0.8, ge=0.5, le=1.0, description="a candidate is planar when at least "
                              "ceil(plane_coef * k) of its k neighbours are candidates too")
    r_max: Annotated[float, Field(gt=0)] | Literal["auto"] | None = Field(
        1.5, description="farthest of the k neighbours must be closer than this (m); depends on k "
        "and density. 'auto': r_max_radii x the radius k neighbours span at the survey's measured "
        "density (sqrt(k / (pi rho)), rho = ln 2 / (pi s^2) from the median nearest-neighbour "
        "spacing s in plan, i.e. about 1.33 sqrt(k) s); null = off")
    r_max_radii: float = Field(4.0, gt=0, description="r_max 'auto' in k-neighbourhood radii "
                               "(unitless): a roof's rim point reaches about 2 radii (one-sided "
                               "neighbourhood), and ALS density varies 2x between single and "
                               "overlapping strips (radius x sqrt 2); hedges and wall tops reach farther "
                               "(3 radii measured: the densest IGN tile lost roof, E1 3.4 -> 4.7 %)")
    # configs/roof_als.yaml runs 'auto' (2026-12-06): a fixed 2 m lost the narrow roofs of sparse
    # surveys (AHN3 thinned to 5 points/m2: kappa 0.866 -> 0.905 with 'auto'); its price is one small
    # rejected candidate (34 points) that becomes roof on the reviewed IGN tile thinned to 2 points/m2
    # (0.992 -> 0.957): at those densities d_max cannot tell a 1-2 m wide hedge from a roof's rim
    # (2 or 3 radii, or a fixed 2.6 m, take it too).
    denoise: Literal["auto"] | bool = Field("auto", description="features (normals, curvature, seeds) on "
                                           "heights moved onto their neighbourhood's plane (kernels.features."
                                           "plane_heights): true, false, or 'auto' where the ground's noise "
                                           "(cloth_ground's ground_noise_m; without a ground stage, never) "
                                           "exceeds denoise_above. Curvature over k neighbours grows as (noise / "
                                           "their radius)^2: at 7-10 cm of noise roofs had no seeds")
    denoise_above: float = Field(0.035, gt=0, description="noise (m) above which 'auto' denoises; the real "
                                 "files at hand read 0.7-1.9 cm on their ground (sample_c, 2.3 points/m2, "
                                 "4.4 cm: its one roof the same either way), the synthetic scenes 2.1-2.5")
    denoise_target: float = Field(0.025, gt=0, description="noise (m) the planes' heights are brought to: "
                                  "a plane of k + 1 points has 1 / sqrt(k + 1) of the noise, so k = "
                                  "2 (noise / target)^2, within [k, 31]")
    alpha: float | None = Field(1.0, ge=0, description="gradient test G_z <= alpha * max(G_x, G_y) "
                                "over the neighbourhood extent (unitless; 1 admits pitches up to "
                                "about 45 degrees); null = off")


def auto_r_max(spacing: float, k: int, radii: float) -> float:
    """r_max (m) of ``radii`` k-neighbourhood radii at the density whose median plan
    nearest-neighbour distance is ``spacing`` (Poisson: median = sqrt(ln 2 / (pi rho)))."""
    density = np.log(2.0) / (np.pi * spacing * spacing)
    return float(radii * np.sqrt(k / (np.pi * density)))


def _seeds(xyz, k: int, o: RoofSeedsOptions, r_max=None, plane_k: int = 0):
    """(kNN indices, covariance features, seed constraint masks) of ``xyz``; with ``plane_k``, of
    ``xyz`` with its heights on the planes of their plane_k neighbours (denoised)."""
    from roadx_ti.kernels.features import covariance_features, plane_heights
    from roadx_ti.kernels.neighbors import knn
    from roadx_ti.kernels.seeds import seed_constraints

    if plane_k and len(xyz) > plane_k:
        rows, _ = knn(xyz, plane_k)
        smooth = np.array(xyz, np.float32, copy=True)
        smooth[:, 2] = np.asarray(plane_heights(xyz, rows))
        xyz = smooth
        del rows
    indices, _ = knn(xyz, k)
    features = covariance_features(xyz, indices)
    masks = seed_constraints(indices, features["curvature"], features["max_distance"], features["extent"],
                             curvature_max=o.curvature_max, plane_coef=o.plane_coef, r_max=r_max, alpha=o.alpha)
    return indices, features, masks


def _with_isolated(n, k, rest, found):
    """kNN rows, features and seed masks ``found`` for the ``rest`` points (None: none) spread
    over all n points, the isolated ones without neighbours (-1), seeds or planarity."""
    full_idx = np.full((n, k), -1, np.int32)
    fill = {"normal": np.zeros((n, 3), np.float32), "curvature": np.ones(n, np.float32),
            "max_distance": np.full(n, np.inf, np.float32), "extent": np.zeros((n, 3), np.float32)}
    full_masks = {name: np.zeros(n, np.uint8) for name in ("planar", "compact", "gradient", "seed")}
    if found is not None:
        indices, features, masks = found
        full_idx[rest] = rest[np.asarray(indices)].astype(np.int32)
        for name, values in fill.items():
            values[rest] = np.asarray(features[name])
        for name, values in full_masks.items():
            values[rest] = np.asarray(masks[name])
    return full_idx, fill, full_masks


def _spacing_of(xyz) -> float:
    """Median nearest-neighbour distance in plan of ``xyz`` (m), past near copies as the survey's
    spacing is (roadx_ti.estimates), 0 for fewer than 2 points."""
    from roadx_ti.estimates import NEAR_COPY_NEIGHBOURS, nearest_past_copies, plan_points
    from roadx_ti.kernels.neighbors import knn

    if len(xyz) < 2:
        return 0.0
    flat = plan_points(xyz)
    k = min(NEAR_COPY_NEIGHBOURS, len(xyz) - 1)
    return float(np.median(nearest_past_copies(np.asarray(knn(flat, k)[1]))))


class RoofSeeds(Stage):
    name = "roof_seeds"
    narrows = False
    Options = RoofSeedsOptions
    # and 'neighbour_distance' when it has 4 points or more; ctx.facts['knn'] for roof_growing
    provides = ("roof_seed", "normal", "curvature")

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        """4 x r_max. 'auto': r_max from the estimates' spacing when given (the tile plan is made
        before they are measured), else, like null, the option's default."""
        r_max = options.r_max
        if r_max == "auto" and estimates:
            spacing = estimates.get("pulse_spacing_m") or estimates.get("point_spacing_m")
            r_max = auto_r_max(float(spacing), options.k, options.r_max_radii) if spacing else None
        if not isinstance(r_max, (int, float)) or not r_max:
            r_max = RoofSeedsOptions.model_fields["r_max"].default
        return 4.0 * float(r_max)

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        o = self.options
        n = cloud.n
        if n < 4:
            seed = np.zeros(n, np.uint8)
            ctx.facts["knn"] = np.full((n, 0), -1, np.int32)
            return StageResult(point_data={"roof_seed": seed, "normal": np.zeros((n, 3), np.float32),
                                           "curvature": np.ones(n, np.float32)},
                               info={"skipped": "fewer than 4 points", "seeds": 0})
        k = min(o.k, n - 1)
        if k < o.k:
            ctx.log.warning("roof_seeds: k = %d but only %d points: using k = %d", o.k, n, k)
        r_max, r_max_source = o.r_max, "option"
        if r_max == "auto":
            spacing = survey_spacing(ctx)
            r_max_source = "auto"
            if not spacing:
                spacing = _spacing_of(cloud.xyz)
                r_max_source = "auto (spacing of this stage's points)"
            r_max = auto_r_max(float(spacing), k, o.r_max_radii) if spacing else None
        # the ground's noise only: the survey's estimate reads foliage as noise (wooded IGN tiles
        # 4-8 cm), and planes through foliage make seeds of it; no ground stage, no evidence
        noise = ctx.facts.get(GROUND_NOISE)
        plane_k = 0
        if o.denoise is True or (o.denoise == "auto" and noise is not None and float(noise) > o.denoise_above):
            ratio = float(noise or o.denoise_target) / o.denoise_target
            plane_k = int(min(MAX_PLANE_K, max(k, math.ceil(2.0 * ratio * ratio))))
        far = isolation.isolated_in(cloud.xyz, k, ctx)
        if far is None:
            indices, features, masks = _seeds(cloud.xyz, k, o, r_max, plane_k)
        else:
            rest = np.flatnonzero(~far)
            found = _seeds(cloud.xyz[rest], k, o, r_max, plane_k) if len(rest) > k else None
            indices, features, masks = _with_isolated(n, k, rest, found)
        ctx.facts["knn"] = indices
        ctx.facts["roof_curvature_max"] = o.curvature_max
        seed = np.asarray(masks["seed"], np.uint8)
        info = {"k": k, "r_max": None if r_max is None else round(float(r_max), 4), "r_max_source": r_max_source,
                "denoised_k": plane_k,
                "seeds": int(seed.sum()),
                "removed_by": {name: int(n - int(np.count_nonzero(masks[name])))
                               for name in ("planar", "compact", "gradient")}}
        return StageResult(point_data={"roof_seed": seed,
                                       "normal": np.asarray(features["normal"], np.float32),
                                       "curvature": np.asarray(features["curvature"], np.float32),
                                       "neighbour_distance": np.asarray(features["max_distance"], np.float32)},
                           info=info)
