"""Synthetic labelled scenes: the demo's default input, the scale benchmarks' data and the accuracy
test bed of the road (METHODS.md R) and roof (METHODS.md P) pipelines.

Pure numpy, deterministic from ``seed``; one module per scene kind on a shared base (``base``):

- ``uav-road`` (``streets``): UAV photogrammetric streets whose look is drawn per seed: density
  50-300 points/m2 (the point count then sets the area), height noise 1.5-5 cm, curved roads of
  several widths with parking lanes, light or dark asphalt, sidewalks within 6-15 grey levels of it
  behind 8-16 cm kerbs with lowered kerbs at crossings, shadows, cars, canopies over the road.
- ``uav-road-v1`` (``uav_road_v1``): the straight-road scene of earlier releases, bit for bit.
- ``als-roof`` (``als_roof``): airborne LiDAR suburb with orthophoto colour; its garden sheds
  (under 10.3 m2) are "other" (1), not building, as in IGN Lidar HD's truth.
- ``als-roof-v1``: the same scenes with the sheds labelled building (6), as earlier releases, bit for bit.

Surfaces are sampled by area, thinned by a density field and by occlusion, then trimmed to exactly
``n_points``; a fraction of outliers is added last. Truth is the ASPRS class of every point:

    1 other (cars, lamp posts; als-roof's garden sheds)   2 ground (sidewalks, kerbs, grass, hillside, yards)
    3/4/5 low / medium / high vegetation (flower beds, bushes and hedges, trees)
    6 building (roofs, walls, chimneys, roof superstructures, annexes)
    7 low noise, 18 high noise, 11 road surface (carriageway and parking lanes with their markings)

Coordinates: ``xyz`` is local float32 in [0, side] x [0, side] (plus heights), ``origin`` the
scene kind's float64 projected-CRS corner. Colour is 8-bit scaled by 257 into 16 bits
(``color_depth`` 16), as photogrammetry exports do. Intensity: UAV scenes carry the colour
luminance (x 257; photogrammetry has no sensor intensity); als-roof a per-material LiDAR intensity.
"""
from __future__ import annotations

import logging
import math

import numpy as np

from roadx_ti.cloud import Cloud
from roadx_ti.synthetic.als_roof import AlsRoofScene, AlsRoofV1Scene
from roadx_ti.synthetic.base import (
    CLASS_BUILDING,
    CLASS_GROUND,
    CLASS_HIGH_NOISE,
    CLASS_HIGH_VEG,
    CLASS_LOW_NOISE,
    CLASS_LOW_VEG,
    CLASS_MED_VEG,
    CLASS_OTHER,
    CLASS_ROAD,
)
from roadx_ti.synthetic.streets import StreetScene
from roadx_ti.synthetic.uav_road_v1 import UavRoadV1Scene

SCENES = {cls.KIND: cls for cls in (StreetScene, UavRoadV1Scene, AlsRoofScene, AlsRoofV1Scene)}
KINDS = tuple(SCENES)
ORIGINS = {kind: cls.ORIGIN for kind, cls in SCENES.items()}
MIN_POINTS = 1000

__all__ = ["KINDS", "ORIGINS", "MIN_POINTS", "SCENES", "generate", "CLASS_OTHER", "CLASS_GROUND",
           "CLASS_LOW_VEG", "CLASS_MED_VEG", "CLASS_HIGH_VEG", "CLASS_BUILDING", "CLASS_LOW_NOISE",
           "CLASS_ROAD", "CLASS_HIGH_NOISE"]


MAX_SIDE = 2000.0   # m: the largest scene laid out (the layout's time and memory grow with its area)


def generate(kind: str, n_points: int, seed: int = 0, density: float | None = None) -> Cloud:
    """A synthetic labelled scene of exactly ``n_points`` points (see the module docstring).
    ``density``: points per m2 of the scene's square (its side sqrt(n_points / density), never under
    one block, so the layout of a seed is the same at any density that gives the same side); None:
    the kind's own (als-roof 15, uav-road drawn per seed)."""
    if kind not in SCENES:
        raise ValueError(f"unknown synthetic scene kind {kind!r}; allowed: {', '.join(KINDS)}")
    if isinstance(n_points, bool) or int(n_points) != n_points or int(n_points) < MIN_POINTS:
        raise ValueError(f"n_points must be an integer >= {MIN_POINTS}, got {n_points!r}")
    if density is not None and not (isinstance(density, (int, float)) and math.isfinite(density) and density > 0):
        raise ValueError(f"density must be a number of points per m2 > 0, got {density!r}")
    n, seed = int(n_points), int(seed)
    scene_cls = SCENES[kind]
    side = scene_cls.side_for(n, seed) if density is None else max(math.sqrt(n / float(density)), scene_cls.BLOCK)
    if density is not None and side > math.sqrt(n / float(density)):
        # the smallest scene is one block: fewer points than the density asks over it are sparser
        logging.getLogger("roadx_ti").warning(
            "--density %g: %s points cover the smallest %s scene (%g m across) at %.3g points per m2; give at "
            "least %s points for that density", float(density), f"{n:,}", kind, scene_cls.BLOCK, n / side ** 2,
            f"{math.ceil(float(density) * scene_cls.BLOCK ** 2):,}")
    if density is not None and side > MAX_SIDE:
        raise ValueError(f"{n:,} points at {density:g} points per m2 would be a scene {side / 1000:,.1f} km across, "
                         f"more than the {MAX_SIDE / 1000:g} km laid out at most (its streets and houses are laid "
                         f"out whole): give a density of at least {n / MAX_SIDE ** 2:.3g} points per m2")
    scene = scene_cls(side, seed)
    xyz, rgb8, intensity, cls = scene.sample_exact(n, scene_cls.OUTLIER_FRACTION)
    rgb16 = (np.clip(np.rint(rgb8), 0, 255).astype(np.uint16) * np.uint16(257))
    return Cloud(xyz=xyz, origin=np.array(scene_cls.ORIGIN, dtype=np.float64), rgb=rgb16,
                 color_depth=16, intensity=intensity, classification=cls,
                 source=f"synthetic:{kind}:n={n}:seed={seed}")
