"""The road pipeline's steps (METHODS.md R1-R6) assembled from existing tools, as a user without
roadx_ti would: laspy (lazrs) in and out, Open3D uniform downsampling, statistical outlier removal
and segment_plane, a numpy grid min-height filter, the CSF package, Open3D DBSCAN. It imports
nothing from roadx_ti, so that its process pays only its own start-up.

    python benchmarks/road_anchor/anchor.py INPUT.laz OUTPUT.laz

Parameters are configs/road_uav.yaml's where the tools take them (the rest are the tools'
defaults). The road is the largest DBSCAN cluster of the cloth's ground points (Open3D's DBSCAN
clusters positions only: the paper's colour growing has no counterpart in these libraries).
Prints one JSON line: seconds per step and the points each step kept; classification 11 marks road,
1 the rest.
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np

TARGET_DENSITY = 60.0             # R1: points per m2 of occupied plan area
SOR_K, SOR_STD = 20, 2.0          # R2
PLANE_DISTANCE, PLANE_MIN, PLANE_ITERATIONS, MAX_PLANES = 0.1, 100, 1000, 30   # R3
MAX_TILT_DEG, PLANE_DH_MAX, GROUND_CELL = 45.0, 2.5, 10.0
GRID_STEP, SLOPE_MAX, GRID_DH_MAX = 0.5, 2.0, 0.5                              # R4
CLOTH_RESOLUTION, RIGIDNESS, CLASS_THRESHOLD, ITERATIONS = 1.0, 3, 0.3, 500    # R5
CLASS_ROAD, CLASS_OTHER = 11, 1


def cell_keys(xy, cell):
    """Per point: its plan cell's flat key and (column, row)."""
    ij = np.floor((xy - xy.min(axis=0)) / cell).astype(np.int64)
    return ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1], ij


def height_above_lowest(xyz, cell, around):
    """Per point: height above the lowest point of its cell, or (around) of the 3 x 3 cells
    about it (a dense numpy grid, scipy.ndimage's minimum filter)."""
    from scipy.ndimage import minimum_filter

    _, ij = cell_keys(xyz[:, :2], cell)
    lowest = np.full(tuple(ij.max(axis=0) + 1), np.inf)
    np.minimum.at(lowest, (ij[:, 0], ij[:, 1]), xyz[:, 2])
    if around:
        lowest = minimum_filter(lowest, size=3, mode="constant", cval=np.inf)
    return xyz[:, 2] - lowest[ij[:, 0], ij[:, 1]]


def main(src: str, dst: str) -> int:
    import CSF
    import laspy
    import open3d as o3d

    seconds, kept = {}, {}
    t = time.perf_counter()
    las = laspy.read(src)
    origin = np.array([las.header.mins[0], las.header.mins[1], 0.0])
    xyz = np.column_stack([las.x - origin[0], las.y - origin[1], las.z - origin[2]])
    n = len(xyz)
    seconds["read"] = time.perf_counter() - t

    t = time.perf_counter()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
    occupied = len(np.unique(cell_keys(xyz[:, :2], 1.0)[0]))
    every = max(1, int(round(n / occupied / TARGET_DENSITY)))
    index = np.arange(n)[::every]
    cloud = cloud.uniform_down_sample(every)
    seconds["downsample"], kept["downsample"] = time.perf_counter() - t, len(index)

    t = time.perf_counter()
    cloud, inliers = cloud.remove_statistical_outlier(SOR_K, SOR_STD)
    index = index[np.asarray(inliers)]
    seconds["sor"], kept["sor"] = time.perf_counter() - t, len(index)

    t = time.perf_counter()
    points = np.asarray(cloud.points)
    above_ground = height_above_lowest(points, GROUND_CELL, True)
    remaining = np.ones(len(points), bool)
    removed = np.zeros(len(points), bool)
    cos_tilt = np.cos(np.radians(MAX_TILT_DEG))
    for _ in range(MAX_PLANES):
        left = np.flatnonzero(remaining)
        if len(left) < 3:
            break
        plane, members = cloud.select_by_index(left.tolist()).segment_plane(PLANE_DISTANCE, 3, PLANE_ITERATIONS)
        members = left[np.asarray(members, np.int64)]
        if len(members) <= PLANE_MIN:
            break
        remaining[members] = False
        tilted = abs(plane[2]) / np.linalg.norm(plane[:3]) < cos_tilt
        if tilted or np.median(above_ground[members]) > PLANE_DH_MAX:
            removed[members] = True
    index, points = index[~removed], points[~removed]
    seconds["ransac_planes"], kept["ransac_planes"] = time.perf_counter() - t, len(index)

    t = time.perf_counter()
    dh = height_above_lowest(points, GRID_STEP, False)
    cell = np.unique(cell_keys(points[:, :2], GRID_STEP)[0], return_inverse=True)[1]
    order = np.lexsort([points[:, 2], cell])
    first = np.ones(len(order), bool)
    first[1:] = cell[order][1:] != cell[order][:-1]
    lowest = np.empty(cell.max() + 1, np.int64)
    lowest[cell[order][first]] = order[first]
    dist = np.linalg.norm(points[:, :2] - points[lowest[cell], :2], axis=1)
    slope = np.divide(dh, dist, out=np.zeros_like(dh), where=dist > 0)
    keep = (slope <= SLOPE_MAX) & (dh <= GRID_DH_MAX)
    index, points = index[keep], points[keep]
    seconds["grid_slope"], kept["grid_slope"] = time.perf_counter() - t, len(index)

    t = time.perf_counter()
    csf = CSF.CSF()
    csf.params.bSloopSmooth = True       # sic: the package's spelling
    csf.params.cloth_resolution = CLOTH_RESOLUTION
    csf.params.rigidness = RIGIDNESS
    csf.params.class_threshold = CLASS_THRESHOLD
    csf.params.interations = ITERATIONS  # sic
    csf.setPointCloud(points)
    ground, off_ground = CSF.VecInt(), CSF.VecInt()
    csf.do_filtering(ground, off_ground, False)
    ground = np.asarray(ground, np.int64)
    index, points = index[ground], points[ground]
    seconds["cloth"], kept["cloth"] = time.perf_counter() - t, len(index)

    t = time.perf_counter()
    occupied = len(np.unique(cell_keys(points[:, :2], 1.0)[0]))
    eps = 2.0 / np.sqrt(len(points) / max(occupied, 1))       # two point spacings
    ground_cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cluster = np.asarray(ground_cloud.cluster_dbscan(eps, 10))
    road = np.zeros(0, np.int64)
    if (cluster >= 0).any():
        road = index[cluster == np.bincount(cluster[cluster >= 0]).argmax()]
    seconds["clusters"], kept["clusters"] = time.perf_counter() - t, len(road)

    t = time.perf_counter()
    classification = np.full(n, CLASS_OTHER, np.uint8)
    classification[road] = CLASS_ROAD
    las.classification = classification
    las.write(dst)
    seconds["write"] = time.perf_counter() - t
    print(json.dumps({"points": n, "seconds": {k: round(v, 3) for k, v in seconds.items()}, "kept": kept}))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
