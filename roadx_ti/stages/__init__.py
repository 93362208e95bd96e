"""Pipeline stages: one module per method step (options with defaults, units, validation; run).

The registry maps the stage names used in configs to their classes; modules are imported on
first use so that a config naming one stage does not pay for the others.
"""
from __future__ import annotations

import importlib

REGISTRY = {
    "uniform_downsample": "roadx_ti.stages.downsample:UniformDownsample",
    "voxel_downsample": "roadx_ti.stages.downsample:VoxelDownsample",
    "sor": "roadx_ti.stages.outliers:StatisticalOutlierRemoval",
    "low_noise": "roadx_ti.stages.low_noise:LowNoise",
    "ransac_planes": "roadx_ti.stages.planes:RansacPlanes",
    "grid_slope": "roadx_ti.stages.grid_slope:GridSlope",
    "cloth_smooth": "roadx_ti.stages.cloth:ClothSmooth",
    "cloth_ground": "roadx_ti.stages.cloth:ClothGround",
    "color_growing": "roadx_ti.stages.growing:ColorGrowing",
    "road_regions": "roadx_ti.stages.road_regions:RoadRegions",
    "roof_seeds": "roadx_ti.stages.seeds:RoofSeeds",
    "roof_growing": "roadx_ti.stages.roof_growing:RoofGrowing",
    "roof_filter": "roadx_ti.stages.roof_filter:RoofFilter",
    "height_above_ground": "roadx_ti.stages.height:HeightAboveGround",
}


def stage_class(name: str):
    """The Stage subclass registered under ``name`` (KeyError for an unknown name)."""
    module_name, _, class_name = REGISTRY[name].partition(":")
    return getattr(importlib.import_module(module_name), class_name)
