"""The grid min-reduction kernel (METHODS.md R4) against a numpy reference, exactly."""
import numpy as np
import pytest

from roadx_ti.kernels import grid_min


def numpy_reference(xyz, step, slope_max, dh_max):
    x_min, y_min = xyz[:, 0].min(), xyz[:, 1].min()
    n_cols = int(np.floor((xyz[:, 0].max() - x_min) / step)) + 1
    col = np.floor((xyz[:, 0] - x_min) / np.float32(step)).astype(np.int64)
    row = np.floor((xyz[:, 1] - y_min) / np.float32(step)).astype(np.int64)
    cell = row * n_cols + col
    # lowest point per cell, ties to the lowest index: sort by (cell, z, index)
    order = np.lexsort((np.arange(len(xyz)), xyz[:, 2], cell))
    first = np.ones(len(order), bool)
    first[1:] = cell[order][1:] != cell[order][:-1]
    lowest_of_cell = dict(zip(cell[order][first].tolist(), order[first].tolist()))
    g = np.array([lowest_of_cell[c] for c in cell.tolist()])
    dh = xyz[:, 2] - xyz[g, 2]
    horizontal = np.sqrt((xyz[:, 0] - xyz[g, 0]) ** 2 + (xyz[:, 1] - xyz[g, 1]) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(horizontal > 0, dh / horizontal, np.where(dh > 0, np.inf, 0.0))
    slope[g == np.arange(len(xyz))] = 0.0
    keep = (slope < slope_max) & (dh < dh_max)
    return cell, g, keep, dh


@pytest.mark.parametrize("seed", [0, 1])
def test_slope_filter_equals_numpy(ti_arch, seed):
    rng = np.random.default_rng(seed)
    n = 20000
    xyz = np.column_stack([rng.uniform(0, 30, n), rng.uniform(-5, 12, n), rng.normal(0, 0.3, n)]).astype(np.float32)
    xyz[:50, 2] += 3.0                      # some points far above their cell minimum
    xyz[100:110] = xyz[99]                  # duplicates: ties in z, resolved by index
    cell, g, keep, dh = numpy_reference(xyz, 0.5, 0.1, 1.0)
    got_cell, cell_lowest, _ = grid_min.cell_minimum(xyz, 0.5)
    np.testing.assert_array_equal(got_cell, cell)
    np.testing.assert_array_equal(cell_lowest[got_cell], g)
    got_keep, got_dh = grid_min.slope_filter(xyz, 0.5, 0.1, 1.0)
    np.testing.assert_array_equal(got_keep.astype(bool), keep)
    np.testing.assert_array_equal(got_dh, dh.astype(np.float32))
    assert 0 < keep.sum() < n


def test_empty_cells_are_minus_one(ti_arch):
    xyz = np.array([[0, 0, 1], [2.9, 0, 2], [2.9, 2.9, 0.5]], np.float32)
    _, cell_lowest, n_cols = grid_min.cell_minimum(xyz, 1.0)
    assert n_cols == 3
    assert (cell_lowest == -1).sum() == 9 - 3


def test_bad_step_is_refused(ti_arch):
    with pytest.raises(ValueError, match="step"):
        grid_min.cell_minimum(np.zeros((3, 3), np.float32), 0.0)
