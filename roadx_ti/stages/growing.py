"""R6 colour region growing and target road selection (kernels: neighbors.knn, labels.*).

Semantics of PCL's RegionGrowingRGB as a data-parallel partition: an edge of the kNN graph
(no longer than ``max_edge_distance``) joins two points whose colour distance is below
``point_threshold`` (Q_t); regions are the connected components (union-find with pointer jumping,
the same partition as a sequential flood fill); adjacent regions whose mean colours differ by less
than ``region_threshold`` (Q_h) are merged; regions smaller than ``min_region_size`` are dropped.
The road is the target region(s): ``largest``, the region nearest to ``seed_xy``, or ``road_like``
(every region of at least ``min_target_size`` points whose mean colour is a grey within
``road_brightness`` and with saturation below ``road_max_saturation``).
Colour source: RGB when the cloud has it; else LiDAR intensity as a single channel (METHODS.md R6,
no-RGB note); else geometry only (normal angle and height continuity), with a warning.
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import CLASS_OTHER, CLASS_ROAD, Stage, StageContext, StageOptions, StageResult


class GrowingOptions(StageOptions):
    k: int = Field(12, ge=2, le=64, description="neighbours per point of the growing graph")
    max_edge_distance: float = Field(0.5, gt=0, description="longest graph edge (m)")
    point_threshold: float = Field(10.0, gt=0, description="Q_t: colour distance between neighbours "
                                   "(8-bit RGB units, or intensity units)")
    region_threshold: float = Field(60.0, ge=0, description="Q_h: merge adjacent regions whose mean "
                                    "colours differ by less than this")
    min_region_size: int = Field(50, ge=1, description="regions with fewer points are dropped")
    color_source: Literal["auto", "rgb", "intensity", "geometry"] = "auto"
    angle_max_deg: float = Field(15.0, gt=0, le=90, description="geometry edges: normal angle (degrees)")
    dz_max: float = Field(0.1, gt=0, description="geometry edges: height step between neighbours (m)")
    target: Literal["largest", "seed", "road_like"] = "largest"
    seed_xy: tuple[float, float] | None = Field(None, description="target=seed: a point on the road, in "
                                                "the input's world coordinates (m)")
    min_target_size: int = Field(1000, ge=1, description="target=road_like: smallest region (points)")
    road_brightness: tuple[float, float] = Field((30.0, 170.0), description="target=road_like: mean grey range")
    road_max_saturation: float = Field(25.0, ge=0, description="target=road_like: max(r,g,b) - min(r,g,b)")

    @model_validator(mode="after")
    def _seed_given(self):
        if self.target == "seed" and self.seed_xy is None:
            raise ValueError("target 'seed' needs seed_xy: [x, y]")
        return self


def _channels(cloud: Cloud, source: str, ctx: StageContext):
    if source in ("auto", "rgb") and cloud.has_color:
        return "rgb", cloud.rgb8()
    if source == "rgb":
        ctx.log.warning("color_growing: the input has no colour; using %s",
                        "intensity" if cloud.intensity is not None else "geometry")
    if source in ("auto", "rgb", "intensity") and cloud.intensity is not None and cloud.intensity.any():
        # one channel spread over three so that the RGB distance equals the intensity difference
        value = cloud.intensity.astype(np.float32) / np.float32(np.sqrt(3.0))
        return "intensity", np.repeat(value[:, None], 3, axis=1)
    if source != "geometry":
        ctx.log.warning("color_growing: no colour and no intensity: growing on geometry only "
                        "(normal angle and height continuity)")
    return "geometry", None


class ColorGrowing(Stage):
    name = "color_growing"
    Options = GrowingOptions

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels import labels as lab
        from roadx_ti.kernels.neighbors import knn

        o = self.options
        k = min(o.k, cloud.n - 1)
        if k < 1:
            return StageResult(labels=np.full(cloud.n, CLASS_OTHER, np.uint8))
        knn_indices, distances = knn(cloud.xyz, k)
        neighbors = np.where(distances <= o.max_edge_distance, knn_indices, -1).astype(np.int32)
        source, colour = _channels(cloud, o.color_source, ctx)
        if colour is not None:
            edge_ok = lab.color_edges(neighbors, colour, o.point_threshold)
        else:
            edge_ok = _geometry_edges(cloud, knn_indices, neighbors, o)
            colour = np.repeat(cloud.xyz[:, 2:3], 3, axis=1)  # merge on mean height instead
        regions = lab.connected_components(neighbors, edge_ok)
        threshold = o.region_threshold if source != "geometry" else o.dz_max
        regions = lab.merge_regions(regions, neighbors, colour, threshold, o.min_region_size)
        regions, n_regions = lab.relabel_compact(regions)
        target = self._select(cloud, regions, n_regions, colour, source)
        is_road = np.isin(regions, target) & (regions >= 0)
        labels = np.where(is_road, CLASS_ROAD, CLASS_OTHER).astype(np.uint8)
        sizes = np.bincount(regions[regions >= 0], minlength=n_regions) if n_regions else np.zeros(0, int)
        return StageResult(labels=labels, segment_id=regions.astype(np.int32),
                           info={"color_source": source, "regions": int(n_regions),
                                 "target_regions": [int(t) for t in target],
                                 "target_points": int(is_road.sum()),
                                 "largest_regions": sorted(sizes.tolist(), reverse=True)[:5]})

    def _select(self, cloud, regions, n_regions, colour, source):
        o = self.options
        if n_regions == 0:
            return np.zeros(0, np.int64)
        valid = regions >= 0
        sizes = np.bincount(regions[valid], minlength=n_regions)
        if o.target == "largest":
            return np.array([int(np.argmax(sizes))])
        if o.target == "seed":
            world = cloud.world_xyz()[:, :2]
            d = np.linalg.norm(world[valid] - np.asarray(o.seed_xy), axis=1)
            return np.array([int(regions[valid][np.argmin(d)])])
        means = np.stack([np.bincount(regions[valid], weights=colour[valid, c], minlength=n_regions)
                          for c in range(3)], axis=1) / np.maximum(sizes, 1)[:, None]
        grey = means.mean(axis=1)
        saturation = means.max(axis=1) - means.min(axis=1)
        lo, hi = o.road_brightness
        road_like = (sizes >= o.min_target_size) & (grey >= lo) & (grey <= hi)
        if source == "rgb":
            road_like &= saturation <= o.road_max_saturation
        return np.flatnonzero(road_like)


def _geometry_edges(cloud, knn_indices, neighbors, o):
    from roadx_ti.kernels.features import covariance_features

    feats = covariance_features(cloud.xyz, knn_indices)
    normal = np.asarray(feats["normal"])
    valid = neighbors >= 0
    j = np.where(valid, neighbors, 0)
    cos_angle = np.abs(np.einsum("nd,nkd->nk", normal, normal[j]))
    dz = np.abs(cloud.xyz[j, 2] - cloud.xyz[:, None, 2])
    ok = valid & (cos_angle >= np.cos(np.radians(o.angle_max_deg))) & (dz <= o.dz_max)
    return ok.astype(np.uint8)
