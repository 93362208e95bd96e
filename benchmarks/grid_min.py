"""grid_min: METHODS.md R4 grid minimum filter (lowest point per 2D cell, then slope and height
tests against it).

Anchor numpy: the same filter with a lexsort by (cell, z, index) for the lowest point per cell.
"""
STAGE = "grid_min"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"step": 0.5, "slope_max": 0.1, "dh_max": 1.0}}]
TARGETS = {"numpy": 1.0}


def roadx_ti(scene, step, slope_max, dh_max):
    from roadx_ti.kernels.grid_min import slope_filter

    xyz = scene.xyz
    return lambda: slope_filter(xyz, step, slope_max, dh_max)


def numpy_lexsort(scene, step, slope_max, dh_max):
    import numpy as np

    xyz = scene.xyz

    def run():
        x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        col = np.floor((x - x.min()) / np.float32(step)).astype(np.int64)
        row = np.floor((y - y.min()) / np.float32(step)).astype(np.int64)
        cell = row * (col.max() + 1) + col
        order = np.lexsort((np.arange(len(z)), z, cell))
        sorted_cell = cell[order]
        first = order[np.r_[True, sorted_cell[1:] != sorted_cell[:-1]]]
        lowest = np.empty(int(cell.max()) + 1, np.int64)
        lowest[cell[first]] = first
        low = lowest[cell]
        dh = z - z[low]
        horizontal = np.hypot(x - x[low], y - y[low])
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = np.where(horizontal > 0, dh / horizontal, np.where(dh > 0, np.inf, 0.0))
        return (slope < slope_max) & (dh < dh_max), dh
    return run


IMPLS = {"roadx_ti": roadx_ti, "numpy": numpy_lexsort}
