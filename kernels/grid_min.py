"""Per-cell minimum height on a 2D grid, and the R4 slope / height-difference test.

METHODS.md R4: col = floor((x - x_min) / step), row = floor((y - y_min) / step),
cell = row * n_cols + col, n_cols = floor((x_max - x_min) / step) + 1. The lowest point g of every
cell is found with integer atomics on an order-preserving encoding of z (ties: lowest index), so
the result does not depend on thread timing and needs no float atomics.
"""
import numpy as np
from .taichi_compat import ti

from .common import INT32_MAX, f32_order_key, kernel_array, like_input, ndarray, output_array


@ti.kernel
def _cell_of_point(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   x_min: ti.f32, y_min: ti.f32, step: ti.f32, n_cols: ti.i32):
    for i in cell:
        col = ti.cast(ti.floor((xyz[i, 0] - x_min) / step), ti.i32)
        row = ti.cast(ti.floor((xyz[i, 1] - y_min) / step), ti.i32)
        cell[i] = row * n_cols + col


@ti.kernel
def _fill_i32(a: ti.types.ndarray(dtype=ti.i32, ndim=1), value: ti.i32):
    for i in a:
        a[i] = value


@ti.kernel
def _cell_min_z_key(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    cell_min_z_key: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in cell:
        ti.atomic_min(cell_min_z_key[cell[i]], f32_order_key(xyz[i, 2]))


@ti.kernel
def _cell_lowest_point(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                       cell_min_z_key: ti.types.ndarray(dtype=ti.i32, ndim=1),
                       cell_lowest: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in cell:
        c = cell[i]
        if f32_order_key(xyz[i, 2]) == cell_min_z_key[c]:
            ti.atomic_min(cell_lowest[c], i)


@ti.kernel
def _slope_test(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                cell_lowest: ti.types.ndarray(dtype=ti.i32, ndim=1),
                height_above_min: ti.types.ndarray(dtype=ti.f32, ndim=1),
                keep: ti.types.ndarray(dtype=ti.u8, ndim=1), slope_max: ti.f32, dh_max: ti.f32):
    for i in cell:
        g = cell_lowest[cell[i]]
        dh = xyz[i, 2] - xyz[g, 2]
        dx = xyz[i, 0] - xyz[g, 0]
        dy = xyz[i, 1] - xyz[g, 1]
        horizontal = ti.sqrt(dx * dx + dy * dy)
        slope = 0.0
        if i != g:
            # a point straight above the cell minimum has infinite slope
            slope = dh / horizontal if horizontal > 0.0 else ti.math.inf if dh > 0.0 else 0.0
        height_above_min[i] = dh
        keep[i] = ti.u8(1) if (slope < slope_max and dh < dh_max) else ti.u8(0)


def _grid_shape(xyz_np_min_max, step):
    (x_min, y_min), (x_max, y_max) = xyz_np_min_max
    n_cols = int(np.floor((x_max - x_min) / step)) + 1
    n_rows = int(np.floor((y_max - y_min) / step)) + 1
    return x_min, y_min, n_cols, n_rows


def _xy_bounds(xyz):
    # bounds on the host: two reductions over an array the caller already has
    arr = xyz.to_numpy() if hasattr(xyz, "to_numpy") else np.asarray(xyz)
    return (arr[:, 0].min(), arr[:, 1].min()), (arr[:, 0].max(), arr[:, 1].max())


def cell_minimum(xyz, step: float):
    """Lowest point of every occupied 2D cell of edge ``step``.

    Returns ``(cell_of_point, cell_lowest, n_cols)``: the cell id of every point (int32) and, per
    cell id, the index of its lowest point (ties to the lowest index; -1 for empty cells).
    """
    if step <= 0:
        raise ValueError(f"grid step must be > 0, got {step}")
    pts = kernel_array(xyz, "float32")
    n = int(pts.shape[0])
    x_min, y_min, n_cols, n_rows = _grid_shape(_xy_bounds(pts), step)
    n_cells = n_cols * n_rows
    if n_cells >= INT32_MAX:
        raise ValueError(f"a {n_cols} x {n_rows} grid at step {step} m exceeds 32-bit indexing; tile the input")
    cell = output_array(ti.i32, (n,), xyz)
    _cell_of_point(pts, cell, float(x_min), float(y_min), float(step), n_cols)
    cell_min_z_key = ndarray(ti.i32, (n_cells,))
    cell_lowest = output_array(ti.i32, (n_cells,), xyz)
    _fill_i32(cell_min_z_key, INT32_MAX)
    _fill_i32(cell_lowest, INT32_MAX)
    _cell_min_z_key(pts, cell, cell_min_z_key)
    _cell_lowest_point(pts, cell, cell_min_z_key, cell_lowest)
    return like_input(cell, xyz), _empty_as_minus_one(like_input(cell_lowest, xyz)), n_cols


def _empty_as_minus_one(cell_lowest):
    if isinstance(cell_lowest, np.ndarray):
        cell_lowest[cell_lowest == INT32_MAX] = -1
    return cell_lowest


def slope_filter(xyz, step: float, slope_max: float, dh_max: float):
    """METHODS.md R4: keep a point when its slope to its cell's lowest point is below
    ``slope_max`` and its height above that point is below ``dh_max`` (metres).

    Returns ``(keep, height_above_cell_min)``: uint8 keep flags and float32 dh per point.
    """
    pts = kernel_array(xyz, "float32")
    n = int(pts.shape[0])
    cell, cell_lowest, _ = cell_minimum(pts, step)
    height = output_array(ti.f32, (n,), xyz)
    keep = output_array(ti.u8, (n,), xyz)
    _slope_test(pts, cell, cell_lowest, height, keep, float(slope_max), float(dh_max))
    return like_input(keep, xyz), like_input(height, xyz)
