"""voxel_hash: sparse cell index (cell coordinates, hash buckets, counting sort) at 0.25 m cells.

Anchor numpy: the same cells, one int64 key per cell, a stable argsort and the run boundaries.
"""
STAGE = "voxel_hash"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"cell_size": 0.25}}]
TARGETS = {"numpy": 1.0}


def roadx_ti(scene, cell_size):
    from roadx_ti.kernels.grid import build_grid

    xyz = scene.xyz
    return lambda: build_grid(xyz, cell_size)


def numpy_sort(scene, cell_size):
    import numpy as np

    xyz = scene.xyz

    def run():
        lo = xyz.min(axis=0)
        cell = np.floor((xyz - lo) / np.float32(cell_size)).astype(np.int64)
        dims = cell.max(axis=0) + 1
        key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
        order = np.argsort(key, kind="stable")
        sorted_key = key[order]
        starts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
        return order, starts
    return run


IMPLS = {"roadx_ti": roadx_ti, "numpy": numpy_sort}
