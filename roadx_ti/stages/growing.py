"""R6 colour region growing and target road selection (kernels: neighbors.knn, smoothing, labels.*).

Semantics of PCL's RegionGrowingRGB as a data-parallel partition: an edge of the kNN graph joins
two points whose colour distance is below ``point_threshold`` (Q_t); regions are the connected
components (union-find with pointer jumping, the same partition as a sequential flood fill);
adjacent regions whose mean colours differ by less than ``region_threshold`` (Q_h) are merged;
regions smaller than ``min_region_size`` are dropped. The road is the target region(s):
``largest``, the region nearest to ``seed_xy``, or ``road_like`` (every region of at least
``min_target_size`` points whose mean colour is a grey within ``road_brightness`` and with
saturation below ``road_max_saturation``).

Options a real cloud needs (each off or neutral at its default unless stated, so the paper's
literal config keeps the paper's semantics):
- graph edges longer than ``max_edge_distance`` or across a height step above ``max_edge_dz``
  are cut (kerbs separate road from sidewalk where their colours are alike);
- ``smoothing_passes``: colours are averaged over each point and its graph neighbours before
  growing (photogrammetric per-point colour noise otherwise fragments the road at Q_t);
- ``target_color_tolerance``: road pieces split off the main target (by markings, shadow edges)
  join it when their mean colour is close to the target's;
- ``absorb_enclosed``: a non-target region, or a connected group of dropped points, whose graph
  boundary leads mostly into the target joins it (markings, shadow patches, small gaps).
Colour source: RGB when the cloud has it; else LiDAR intensity used as a grey (r = g = b =
intensity / scale); else geometry only (normal angle and height continuity), with a warning.
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
    max_edge_dz: float | None = Field(None, gt=0, description="graph edges across a larger height step "
                                      "are cut (m); kerbs then separate road from sidewalk. None = off")
    max_curvature: float | None = Field(None, gt=0, le=1, description="points whose neighbourhood "
                                        "curvature l0/(l0+l1+l2) exceeds this do not take part in growing "
                                        "(PCL's curvature test; kerb faces and steps then cannot bridge road "
                                        "and sidewalk); they can rejoin by absorption. None = off")
    smoothing_passes: int = Field(0, ge=0, le=10, description="colour denoising: passes of averaging each "
                                  "point's colour with its graph neighbours' before growing (0 = off)")
    point_threshold: float = Field(10.0, gt=0, description="Q_t: colour distance between neighbours "
                                   "(8-bit RGB units; intensity is used as a grey, see intensity_scale)")
    region_threshold: float = Field(60.0, ge=0, description="Q_h: merge adjacent regions whose mean "
                                    "colours differ by less than this (0 = no merging)")
    min_region_size: int = Field(50, ge=1, description="regions with fewer points are dropped")
    color_source: Literal["auto", "rgb", "intensity", "geometry"] = "auto"
    intensity_scale: float | Literal["auto"] = Field(
        "auto", description="intensity units per grey level; 'auto': 257 when the 99th percentile of the "
        "intensity exceeds 255 (16-bit sensors), else 1")
    angle_max_deg: float = Field(15.0, gt=0, le=90, description="geometry edges: normal angle (degrees)")
    dz_max: float = Field(0.1, gt=0, description="geometry edges: height step between neighbours (m)")
    target: Literal["largest", "seed", "road_like"] = "largest"
    seed_xy: tuple[float, float] | None = Field(None, description="target=seed: a point on the road, in "
                                                "the input's world coordinates (m)")
    min_target_size: int = Field(1000, ge=1, description="smallest region (points) that target=road_like "
                                 "or target_color_tolerance may add")
    road_brightness: tuple[float, float] = Field((30.0, 170.0), description="target=road_like: mean grey range")
    road_max_saturation: float = Field(25.0, ge=0, description="target=road_like: max(r,g,b) - min(r,g,b)")
    target_color_tolerance: float = Field(0.0, ge=0, description="also take every region of at least "
                                          "min_target_size points whose mean colour lies within this "
                                          "distance of the target's mean colour (colour units; 0 = off)")
    absorb_enclosed: float | None = Field(None, gt=0, le=1, description="a non-target region or connected "
                                          "group of dropped points joins the target when at least this "
                                          "fraction of its boundary graph edges lead into it (None = off)")
    absorb_max_size: int | None = Field(None, ge=1, description="largest group absorb_enclosed may add "
                                        "(points; None = any)")
    absorb_rounds: int = Field(3, ge=1, le=20, description="absorption repeats until nothing changes or "
                               "this many rounds")

    @model_validator(mode="after")
    def _seed_given(self):
        if self.target == "seed" and self.seed_xy is None:
            raise ValueError("target 'seed' needs seed_xy: [x, y]")
        return self


def _channels(cloud: Cloud, o: GrowingOptions, ctx: StageContext):
    source = o.color_source
    if source in ("auto", "rgb") and cloud.has_color:
        return "rgb", cloud.rgb8().astype(np.float32)
    if source == "rgb":
        ctx.log.warning("color_growing: the input has no colour; using %s",
                        "intensity" if cloud.intensity is not None else "geometry")
    if source in ("auto", "rgb", "intensity") and cloud.intensity is not None and cloud.intensity.any():
        value = cloud.intensity.astype(np.float32)
        scale = o.intensity_scale
        if scale == "auto":
            scale = 257.0 if float(np.percentile(value, 99)) > 255.0 else 1.0
        # intensity as a grey colour, so that Q_t and Q_h compare it like RGB
        return "intensity", np.repeat((value / np.float32(scale))[:, None], 3, axis=1)
    if source != "geometry":
        ctx.log.warning("color_growing: no colour and no intensity: growing on geometry only "
                        "(normal angle and height continuity)")
    return "geometry", None


class ColorGrowing(Stage):
    name = "color_growing"
    labels = CLASS_ROAD
    Options = GrowingOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        return 20.0 * float(options.max_edge_distance)   # regions grow and merge over many graph edges

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels import labels as lab
        from roadx_ti.kernels.neighbors import knn
        from roadx_ti.kernels.smoothing import neighbor_mean

        o = self.options
        k = min(o.k, cloud.n - 1)
        if k < 1:
            return StageResult(labels=np.full(cloud.n, CLASS_OTHER, np.uint8))
        knn_indices, distances = knn(cloud.xyz, k)
        edge = distances <= o.max_edge_distance
        if o.max_edge_dz is not None:
            z = cloud.xyz[:, 2]
            edge &= np.abs(z[np.maximum(knn_indices, 0)] - z[:, None]) <= o.max_edge_dz
        neighbors = np.where(edge & (knn_indices >= 0), knn_indices, -1).astype(np.int32)
        source, colour = _channels(cloud, o, ctx)
        if colour is not None:
            if o.smoothing_passes:
                colour = neighbor_mean(colour, neighbors, o.smoothing_passes)
            edge_ok = lab.color_edges(neighbors, colour, o.point_threshold)
        else:
            edge_ok = _geometry_edges(cloud, knn_indices, neighbors, o)
            colour = np.repeat(cloud.xyz[:, 2:3], 3, axis=1)  # merge on mean height instead
        active = None
        if o.max_curvature is not None:
            from roadx_ti.kernels.features import covariance_features
            curvature = np.asarray(covariance_features(cloud.xyz, knn_indices)["curvature"])
            active = (curvature <= o.max_curvature).astype(np.uint8)
        regions = lab.connected_components(neighbors, edge_ok, active)
        threshold = o.region_threshold if source != "geometry" else o.dz_max
        regions = lab.merge_regions(regions, neighbors, colour, threshold, o.min_region_size)
        regions, n_regions = lab.relabel_compact(regions)
        target = self._select(cloud, regions, n_regions, colour, source)
        is_road = np.isin(regions, target) & (regions >= 0)
        absorbed = 0
        if o.absorb_enclosed is not None and is_road.any():
            before = int(is_road.sum())
            is_road = _absorb_enclosed(is_road, regions, neighbors, o)
            absorbed = int(is_road.sum()) - before
        labels = np.where(is_road, CLASS_ROAD, CLASS_OTHER).astype(np.uint8)
        sizes = np.bincount(regions[regions >= 0], minlength=n_regions) if n_regions else np.zeros(0, int)
        return StageResult(labels=labels, segment_id=regions.astype(np.int32),
                           info={"color_source": source, "regions": int(n_regions),
                                 "target_regions": [int(t) for t in target],
                                 "target_points": int(is_road.sum()), "absorbed_points": absorbed,
                                 "largest_regions": sorted(sizes.tolist(), reverse=True)[:5]})

    def _select(self, cloud, regions, n_regions, colour, source):
        o = self.options
        if n_regions == 0:
            return np.zeros(0, np.int64)
        valid = regions >= 0
        sizes = np.bincount(regions[valid], minlength=n_regions)
        means = np.stack([np.bincount(regions[valid], weights=colour[valid, c], minlength=n_regions)
                          for c in range(3)], axis=1) / np.maximum(sizes, 1)[:, None]
        if o.target == "largest":
            target = np.array([int(np.argmax(sizes))])
        elif o.target == "seed":
            world = cloud.world_xyz()[:, :2]
            d = np.linalg.norm(world[valid] - np.asarray(o.seed_xy), axis=1)
            target = np.array([int(regions[valid][np.argmin(d)])])
        else:
            grey = means.mean(axis=1)
            saturation = means.max(axis=1) - means.min(axis=1)
            lo, hi = o.road_brightness
            road_like = (sizes >= o.min_target_size) & (grey >= lo) & (grey <= hi)
            if source == "rgb":
                road_like &= saturation <= o.road_max_saturation
            target = np.flatnonzero(road_like)
        if o.target_color_tolerance > 0 and len(target):
            # size-weighted mean colour of the target, then every big region close to it
            w = sizes[target].astype(np.float64)
            reference = (means[target] * w[:, None]).sum(axis=0) / max(w.sum(), 1.0)
            close = (sizes >= o.min_target_size) & \
                (np.linalg.norm(means - reference, axis=1) < o.target_color_tolerance)
            target = np.union1d(target, np.flatnonzero(close))
        return target


def _absorb_enclosed(is_road, regions, neighbors, o):
    """Grow the target by whole groups: each non-target region, and each connected group of
    dropped points, joins when at least ``absorb_enclosed`` of its boundary edges (graph edges
    to points of another group) end in the target. Repeats for ``absorb_rounds`` rounds."""
    from roadx_ti.kernels import labels as lab

    n = len(is_road)
    dropped = regions < 0
    group = regions.astype(np.int64)
    if dropped.any():
        pieces = lab.connected_components(neighbors, active=dropped.astype(np.uint8))
        group = np.where(dropped, n + pieces.astype(np.int64), group)
    group = np.unique(group, return_inverse=True)[1].ravel().astype(np.int32)
    n_groups = int(group.max()) + 1
    size = np.bincount(group, minlength=n_groups)
    # boundary edges (graph edges between two groups): (group of the point, neighbour index)
    row_group, cols = lab.boundary_edges(group, neighbors)
    total = np.bincount(row_group, minlength=n_groups)
    limit = o.absorb_max_size if o.absorb_max_size is not None else n
    is_road = is_road.copy()
    for _ in range(o.absorb_rounds):
        group_road = np.zeros(n_groups, bool)
        group_road[group[is_road]] = True
        into = np.bincount(row_group, weights=is_road[cols], minlength=n_groups)
        take = ~group_road & (total > 0) & (into >= o.absorb_enclosed * total) & (size <= limit)
        if not take.any():
            break
        is_road |= take[group]
    return is_road


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
