"""Per-cell minimum height on a 2D grid, and the R4 slope / height-difference test.

METHODS.md R4: col = floor((x - x_min) / step), row = floor((y - y_min) / step),
cell = row * n_cols + col, n_cols = floor((x_max - x_min) / step) + 1. The lowest point g of every
cell is found with integer atomics on an order-preserving encoding of z (ties: lowest index), so
the result does not depend on thread timing and needs no float atomics.

Cells are dense ids over the bounding box when that grid holds at most DENSE_CELLS_PER_POINT
cells per point (plus DENSE_MIN_CELLS); otherwise (far stray points, a few areas far apart) the
occupied cells get compact ids from their sorted (col, row) keys (``sparse_cell_minimum``), so
memory follows the points, not the extent. Both give every point the same lowest point of its
cell, so ``slope_filter`` returns the same result either way.
"""
import numpy as np
from .taichi_compat import ti

from .common import (INT32_MAX, f32_from_order_key, f32_order_key, is_ndarray, kernel_array, like_input, ndarray,
                     output_array, points_array)

DENSE_CELLS_PER_POINT = 4
DENSE_MIN_CELLS = 1 << 20
_MAX_COORD = 2**30              # sparse cell columns and rows are clipped to +-2^30

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
def _cell_min_z_key_except(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                           first: ti.types.ndarray(dtype=ti.i32, ndim=1), second: ti.types.ndarray(dtype=ti.i32, ndim=1),
                           cell_min_z_key: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in cell:
        c = cell[i]
        if i != first[c] and i != second[c]:
            ti.atomic_min(cell_min_z_key[c], f32_order_key(xyz[i, 2]))


@ti.kernel
def _cell_lowest_point_except(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                              first: ti.types.ndarray(dtype=ti.i32, ndim=1), second: ti.types.ndarray(dtype=ti.i32, ndim=1),
                              cell_min_z_key: ti.types.ndarray(dtype=ti.i32, ndim=1),
                              cell_lowest: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in cell:
        c = cell[i]
        if i != first[c] and i != second[c] and f32_order_key(xyz[i, 2]) == cell_min_z_key[c]:
            ti.atomic_min(cell_lowest[c], i)


@ti.kernel
def _supported_lowest(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), first: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      second: ti.types.ndarray(dtype=ti.i32, ndim=1), third: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      gap: ti.f32, out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for c in out:
        g = first[c]
        if third[c] != INT32_MAX:
            z2 = xyz[second[c], 2]
            if z2 - xyz[first[c], 2] > gap and xyz[third[c], 2] - z2 <= gap:
                g = second[c]
        out[c] = g


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


def _grid_shape(xyz_np_min_max, step, origin=None):
    (x_min, y_min), (x_max, y_max) = xyz_np_min_max
    if origin is not None:
        x_min, y_min = (np.float32(v) for v in origin)
    n_cols = int(np.floor((x_max - x_min) / step)) + 1
    n_rows = int(np.floor((y_max - y_min) / step)) + 1
    return x_min, y_min, n_cols, n_rows


def _xy_bounds(xyz):
    # bounds on the host: two reductions over an array the caller already has
    arr = xyz.to_numpy() if hasattr(xyz, "to_numpy") else np.asarray(xyz)
    return (arr[:, 0].min(), arr[:, 1].min()), (arr[:, 0].max(), arr[:, 1].max())


def dense_fits(xyz, step: float, origin=None) -> bool:
    """Whether the dense grid over the points' bounding box (from ``origin``, which no point may
    lie below) stays within DENSE_CELLS_PER_POINT cells per point (plus DENSE_MIN_CELLS)."""
    n = int(xyz.shape[0])
    bounds = _xy_bounds(xyz)
    if origin is not None and (bounds[0][0] < np.float32(origin[0]) or bounds[0][1] < np.float32(origin[1])):
        return False
    _, _, n_cols, n_rows = _grid_shape(bounds, step, origin)
    return n_cols * n_rows <= DENSE_CELLS_PER_POINT * n + DENSE_MIN_CELLS


def _lowest_per_cell(pts, cell, n_cells, reference):
    cell_min_z_key = ndarray(ti.i32, (n_cells,))
    cell_lowest = output_array(ti.i32, (n_cells,), reference)
    _fill_i32(cell_min_z_key, INT32_MAX)
    _fill_i32(cell_lowest, INT32_MAX)
    _cell_min_z_key(pts, cell, cell_min_z_key)
    _cell_lowest_point(pts, cell, cell_min_z_key, cell_lowest)
    return _empty_as_minus_one(like_input(cell_lowest, reference))


def _supported_lowest_per_cell(pts, cell, cell_lowest, gap: float):
    """Per cell, its lowest point unless that point lies more than ``gap`` m under the second
    lowest while the third follows the second within ``gap``: a single low outlier under the
    surface is skipped (the second lowest is the reference). Anything else keeps the lowest: in
    cells of fewer than three points, two points cannot say which is the outlier, and three that
    do not agree (ground, a car's side, a wall) say nothing about the ground; a pair of low
    outliers agrees with itself and stays. -1 for empty cells."""
    n_cells = int(cell_lowest.shape[0])
    first = kernel_array(cell_lowest, "int32")        # -1 for an empty cell: no point has that index
    second = _lowest_except(pts, cell, n_cells, first, first)
    third = _lowest_except(pts, cell, n_cells, first, second)
    out = output_array(ti.i32, (n_cells,), cell_lowest)
    _supported_lowest(pts, first, second, third, float(gap), out)
    return _empty_as_minus_one(like_input(out, cell_lowest))


def _lowest_except(pts, cell, n_cells, first, second):
    """Per cell, the lowest point other than ``first`` and ``second`` (ties to the lowest index;
    INT32_MAX where none is left)."""
    key = ndarray(ti.i32, (n_cells,))
    lowest = ndarray(ti.i32, (n_cells,))
    _fill_i32(key, INT32_MAX)
    _fill_i32(lowest, INT32_MAX)
    _cell_min_z_key_except(pts, cell, first, second, key)
    _cell_lowest_point_except(pts, cell, first, second, key, lowest)
    return lowest


def cell_minimum(xyz, step: float, origin=None):
    """Lowest point of every 2D cell of edge ``step`` of the dense grid over the bounding box
    (from ``origin`` = (x_min, y_min) when given: the grid's corner, no point below it).

    Returns ``(cell_of_point, cell_lowest, n_cols)``: the cell id of every point (int32) and, per
    cell id, the index of its lowest point (ties to the lowest index; -1 for empty cells).
    """
    if step <= 0:
        raise ValueError(f"grid step must be > 0, got {step}")
    pts = points_array(xyz)
    n = int(pts.shape[0])
    if n == 0:      # numpy either way: Taichi has no empty ndarray
        return np.zeros(0, np.int32), np.zeros(0, np.int32), 0
    bounds = _xy_bounds(pts)
    x_min, y_min, n_cols, n_rows = _grid_shape(bounds, step, origin)
    if bounds[0][0] < x_min or bounds[0][1] < y_min:
        raise ValueError(f"points lie below the grid origin {origin}; use sparse_cell_minimum")
    n_cells = n_cols * n_rows
    if n_cells >= INT32_MAX:
        raise ValueError(f"a {n_cols} x {n_rows} grid at step {step} m exceeds 32-bit indexing; tile the input")
    cell = output_array(ti.i32, (n,), xyz)
    _cell_of_point(pts, cell, float(x_min), float(y_min), float(step), n_cols)
    return like_input(cell, xyz), _lowest_per_cell(pts, cell, n_cells, xyz), n_cols


def sparse_cell_minimum(xyz, step: float, origin=None):
    """Lowest point of every occupied 2D cell of edge ``step``, cells numbered compactly in
    (col, row) order; col and row as in ``cell_minimum`` (the same float32 arithmetic; from
    ``origin`` when given, points below it in negative columns and rows).

    Returns ``(cell_of_point, cell_lowest, col_row)``: compact cell id of every point (int32), the
    index of each cell's lowest point (ties to the lowest index), and each cell's (col, row)
    (int64 (cells, 2)). Memory is O(points) whatever the extent.
    """
    if step <= 0:
        raise ValueError(f"grid step must be > 0, got {step}")
    pts = points_array(xyz)
    cell, col_row = _sparse_cells(pts, step, origin, xyz)
    return cell, _lowest_per_cell(pts, cell, len(col_row), xyz), col_row


def _sparse_cells(pts, step: float, origin, reference):
    """(compact cell id per point in (col, row) order, int32 like ``reference``; each cell's
    (col, row), int64 (cells, 2)): the occupied cells of edge ``step`` (sparse_cell_minimum)."""
    host = pts.to_numpy() if is_ndarray(pts) else np.asarray(pts)
    x_min, y_min, _, _ = _grid_shape(_xy_bounds(host), step, origin)
    step32 = np.float32(step)
    col = np.floor((host[:, 0] - np.float32(x_min)) / step32)
    row = np.floor((host[:, 1] - np.float32(y_min)) / step32)
    col = np.clip(col, -_MAX_COORD, _MAX_COORD).astype(np.int64)
    row = np.clip(row, -_MAX_COORD, _MAX_COORD).astype(np.int64)
    span = 2 * _MAX_COORD + 1
    keys, inverse = np.unique((col + _MAX_COORD) * span + (row + _MAX_COORD), return_inverse=True)
    cell_np = inverse.astype(np.int32).reshape(-1)
    cell = cell_np
    if is_ndarray(reference):
        cell = ndarray(ti.i32, (len(cell_np),))
        cell.from_numpy(cell_np)
    return cell, np.column_stack([keys // span - _MAX_COORD, keys % span - _MAX_COORD])


def plan_cells(xyz, step: float, origin=None):
    """(cell id per point, int32 like the input; number of cell ids) of the 2D cells of edge
    ``step``: the dense grid's ids over the bounding box (from ``origin``) when it fits
    (dense_fits), else sparse_cell_minimum's compact ids of the occupied cells. For kernels that
    reduce per cell themselves (no lowest point computed)."""
    if step <= 0:
        raise ValueError(f"grid step must be > 0, got {step}")
    pts = points_array(xyz)
    n = int(pts.shape[0])
    if n and dense_fits(pts, step, origin):
        x_min, y_min, n_cols, n_rows = _grid_shape(_xy_bounds(pts), step, origin)
        cell = output_array(ti.i32, (n,), xyz)
        _cell_of_point(pts, cell, float(x_min), float(y_min), float(step), n_cols)
        return like_input(cell, xyz), n_cols * n_rows
    cell, col_row = _sparse_cells(pts, step, origin, xyz)
    return cell, len(col_row)


def _empty_as_minus_one(cell_lowest):
    if isinstance(cell_lowest, np.ndarray):
        cell_lowest[cell_lowest == INT32_MAX] = -1
    return cell_lowest


def slope_filter(xyz, step: float, slope_max: float, dh_max: float, origin=None, outlier_gap: float | None = None):
    """METHODS.md R4: keep a point when its slope to its cell's lowest point is below
    ``slope_max`` and its height above that point is below ``dh_max`` (metres). Dense or sparse
    cells (module docstring): the same result. ``origin`` (x_min, y_min): the grid's corner
    instead of the points' minimum (the stage passes the minimum without far stray points).
    ``outlier_gap`` (m): a cell's lowest point is skipped as its reference when it lies more than
    the gap under the second lowest and the third follows the second within the gap (a single low
    outlier under the surface would make every point of its cell "high"; points under the
    reference are kept).

    Returns ``(keep, height_above_cell_min)``: uint8 keep flags and float32 dh per point.
    """
    pts = points_array(xyz)
    n = int(pts.shape[0])
    if n == 0:      # numpy either way: Taichi has no empty ndarray
        return np.zeros(0, np.uint8), np.zeros(0, np.float32)
    if not dense_fits(pts, step, origin):
        cell, cell_lowest, _ = sparse_cell_minimum(pts, step, origin)
    else:
        cell, cell_lowest, _ = cell_minimum(pts, step, origin)
    if outlier_gap is not None:
        cell_lowest = _supported_lowest_per_cell(pts, kernel_array(cell, "int32"), cell_lowest, outlier_gap)
    height = output_array(ti.f32, (n,), xyz)
    keep = output_array(ti.u8, (n,), xyz)
    _slope_test(pts, cell, cell_lowest, height, keep, float(slope_max), float(dh_max))
    return like_input(keep, xyz), like_input(height, xyz)


@ti.kernel
def _cell_max_z_key(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    cell_max_z_key: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in cell:
        ti.atomic_max(cell_max_z_key[cell[i]], f32_order_key(xyz[i, 2]))


@ti.kernel
def _overtopped(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), cell: ti.types.ndarray(dtype=ti.i32, ndim=1),
                cell_max_z_key: ti.types.ndarray(dtype=ti.i32, ndim=1), clearance: ti.f32,
                out: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in cell:
        out[i] = ti.u8(f32_from_order_key(cell_max_z_key[cell[i]]) > xyz[i, 2] + clearance)


def overtopped(xyz, step: float, clearance: float, origin=None):
    """uint8 (n,): 1 where the highest point of the point's 2D cell of edge ``step`` (plan_cells:
    dense or sparse ids, the same cells) stands more than ``clearance`` (m) above it: something
    (a crown, an overhang) covers the point in a view from above. Integer atomics on the
    order-preserving encoding of z: independent of point order and thread timing."""
    pts = points_array(xyz)
    n = int(pts.shape[0])
    out = output_array(ti.u8, (n,), xyz)
    if n:
        cell, n_cells = plan_cells(pts, step, origin)
        cell = kernel_array(cell, "int32")
        top = ndarray(ti.i32, (n_cells,))
        _fill_i32(top, -INT32_MAX - 1)
        _cell_max_z_key(pts, cell, top)
        _overtopped(pts, cell, top, float(clearance), out)
    return like_input(out, xyz)
