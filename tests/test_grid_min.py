"""The grid min-reduction kernel (METHODS.md R4) against a numpy reference, exactly."""
import numpy as np
import pytest

from roadx_ti.kernels import grid_min


def numpy_reference(xyz, step, slope_max, dh_max, outlier_gap=None):
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
    if outlier_gap is not None:
        # a single low point under two that agree is skipped: the second lowest is the reference
        starts = np.flatnonzero(first)
        stops = np.append(starts[1:], len(order))
        gap = np.float32(outlier_gap)
        for a, b in zip(starts, stops):
            if b - a >= 3:
                p1, p2, p3 = order[a:a + 3]
                z1, z2, z3 = xyz[[p1, p2, p3], 2]
                if z2 - z1 > gap and z3 - z2 <= gap:
                    lowest_of_cell[cell[p1]] = int(p2)
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


@pytest.mark.parametrize("seed", [0, 1])
def test_supported_reference_equals_numpy(ti_arch, seed):
    """slope_filter's outlier_gap: a cell's lowest point is skipped when it lies more than the gap
    under the second lowest and the third follows the second within the gap (a single low
    outlier); pairs of low points, and cells whose three lowest disagree, keep their lowest."""
    rng = np.random.default_rng(seed)
    n = 20000
    xyz = np.column_stack([rng.uniform(0, 30, n), rng.uniform(-5, 12, n), rng.normal(0, 0.03, n)]).astype(np.float32)
    xyz[:60, 2] -= rng.uniform(0.3, 2.0, 60).astype(np.float32)     # low outliers ...
    xyz[60:80] = xyz[:20] + np.float32([0.01, 0.0, 0.05])            # ... some in pairs
    # ties in z among a cell's lowest points (different places in the cell): resolved by index
    low = int(np.argmin(xyz[100:, 2])) + 100
    xyz[90:93, :2] = xyz[low, :2] + np.float32([[0.01, 0.0], [0.0, 0.01], [0.01, 0.01]])
    xyz[90:93, 2] = xyz[low, 2]
    cell, g, keep, dh = numpy_reference(xyz, 0.5, 2.0, 0.5, outlier_gap=0.12)
    got_keep, got_dh = grid_min.slope_filter(xyz, 0.5, 2.0, 0.5, outlier_gap=0.12)
    np.testing.assert_array_equal(got_dh, dh.astype(np.float32))
    np.testing.assert_array_equal(got_keep.astype(bool), keep)
    plain_keep, _ = grid_min.slope_filter(xyz, 0.5, 2.0, 0.5)
    # with the lowest point as reference, an outlier's cell loses its surface points
    assert keep[80:].sum() > plain_keep[80:].sum() + 100
    # three points of a cell that do not agree (ground, 1 cm above it, 1 m up: a car's side)
    # keep the lowest as reference, so the high one goes as in the plain test
    three = np.float32([[0.1, 0.1, 0.0], [0.2, 0.2, 0.01], [0.3, 0.3, 1.0]])
    keep3, dh3 = grid_min.slope_filter(three, 0.5, 2.0, 0.5, outlier_gap=0.12)
    np.testing.assert_array_equal(keep3, [1, 1, 0])
    np.testing.assert_array_equal(dh3, three[:, 2])


def test_empty_cells_are_minus_one(ti_arch):
    xyz = np.array([[0, 0, 1], [2.9, 0, 2], [2.9, 2.9, 0.5]], np.float32)
    _, cell_lowest, n_cols = grid_min.cell_minimum(xyz, 1.0)
    assert n_cols == 3
    assert (cell_lowest == -1).sum() == 9 - 3


def test_bad_step_is_refused(ti_arch):
    with pytest.raises(ValueError, match="step"):
        grid_min.cell_minimum(np.zeros((3, 3), np.float32), 0.0)


def test_supported_reference_is_the_same_on_sparse_cells(ti_arch):
    """A stray point 500 km away makes the grid sparse (compact cell ids): the other points get
    the same reference heights and keep flags as on the dense grid."""
    rng = np.random.default_rng(5)
    n = 5000
    xyz = np.column_stack([rng.uniform(0, 20, n), rng.uniform(0, 20, n), rng.normal(0, 0.03, n)]).astype(np.float32)
    xyz[:30, 2] -= 1.0
    far = np.concatenate([xyz, np.float32([[5e5, 5e5, 0.0]])])
    assert grid_min.dense_fits(xyz, 0.5) and not grid_min.dense_fits(far, 0.5)
    keep, dh = grid_min.slope_filter(xyz, 0.5, 2.0, 0.5, outlier_gap=0.12)
    far_keep, far_dh = grid_min.slope_filter(far, 0.5, 2.0, 0.5, outlier_gap=0.12)
    np.testing.assert_array_equal(far_dh[:n], dh)
    np.testing.assert_array_equal(far_keep[:n], keep)


@pytest.mark.parametrize("seed", [0, 1])
def test_overtopped_equals_numpy_on_dense_and_sparse_cells(ti_arch, seed):
    """A point is overtopped when its 2D cell's highest point stands more than the clearance above
    it: equal to a numpy reference, the same with a stray point 500 km away (sparse cell ids) and
    with the points shuffled."""
    rng = np.random.default_rng(seed)
    n = 4000
    xyz = np.column_stack([rng.uniform(0, 20, n), rng.uniform(0, 20, n), rng.uniform(0, 4, n)]).astype(np.float32)
    step, clearance = 0.7, 1.0
    col = np.floor((xyz[:, 0] - xyz[:, 0].min()) / np.float32(step)).astype(np.int64)
    row = np.floor((xyz[:, 1] - xyz[:, 1].min()) / np.float32(step)).astype(np.int64)
    cell = row * (col.max() + 1) + col
    top = np.full(cell.max() + 1, -np.inf, np.float32)
    np.maximum.at(top, cell, xyz[:, 2])
    expected = top[cell] > xyz[:, 2] + np.float32(clearance)
    got = np.asarray(grid_min.overtopped(xyz, step, clearance)) != 0
    np.testing.assert_array_equal(got, expected)
    assert 0.2 < got.mean() < 0.8
    far = np.concatenate([xyz, np.float32([[5e5, 5e5, 0.0]])])
    assert not grid_min.dense_fits(far, step)
    np.testing.assert_array_equal(np.asarray(grid_min.overtopped(far, step, clearance))[:n] != 0, expected)
    order = rng.permutation(n)
    np.testing.assert_array_equal(np.asarray(grid_min.overtopped(xyz[order], step, clearance)) != 0, expected[order])
