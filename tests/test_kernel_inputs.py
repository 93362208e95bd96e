"""Every kernel wrapper that takes points checks them before a kernel reads them (probe 16): an
(n, 2) or (n, 4) array, NaN or infinity, float64 world coordinates that float32 would round, a
k that is not a whole number, an infinite radius. Before, (n, 2) arrays were read past their end
(random results), one -inf z moved CSF's ground from 1,698 points to none, a NaN query was given
neighbour 0 at distance 0, and UTM coordinates gave wrong neighbours on 1,989 of 2,000 rows."""
import numpy as np
import pytest

from roadx_ti.kernels import cloth, downsample, features, grid_min, neighbors, outliers, ransac, regions
from roadx_ti.kernels.common import MAX_LOCAL_COORD


def _points(n=400, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.random((n, 3)) * [20.0, 20.0, 2.0]).astype(np.float32)


CALLS = {
    "knn": lambda xyz: neighbors.knn(xyz, 4),
    "nearest": lambda xyz: neighbors.nearest(_points(), xyz),
    "radius_search": lambda xyz: neighbors.radius_search(xyz, 0.5),
    "uniform_sample": lambda xyz: downsample.uniform_sample(xyz, 10),
    "csf": lambda xyz: cloth.csf(xyz, cloth_resolution=1.0, iterations=20),
    "low_noise": lambda xyz: outliers.low_noise(xyz),
    "sor_keep": lambda xyz: outliers.sor_keep(xyz, 4, 1.0),
    "cell_minimum": lambda xyz: grid_min.cell_minimum(xyz, 1.0),
    "slope_filter": lambda xyz: grid_min.slope_filter(xyz, 1.0, 0.3, 0.5),
    "fit_plane": lambda xyz: ransac.fit_plane(xyz, 0.1, hypotheses=20),
    "plane_distances": lambda xyz: ransac.plane_distances(xyz, (0.0, 0.0, 1.0, 0.0)),
    "mode_heights": lambda xyz: regions.mode_heights(xyz, np.full((len(xyz), 4), -1, np.int32),
                                                     np.zeros((len(xyz), 2), np.float32), 0.05),
    "covariance_features": lambda xyz: features.covariance_features(xyz, 8),
}


@pytest.mark.parametrize("call", list(CALLS))
@pytest.mark.parametrize("columns", [2, 4])
def test_points_of_other_than_three_columns_are_refused(call, columns):
    xyz = np.ascontiguousarray(_points()[:, :2] if columns == 2 else np.column_stack([_points(), _points()[:, :1]]))
    with pytest.raises(ValueError, match=r"must have shape \([nm], 3\)"):
        CALLS[call](xyz)


@pytest.mark.parametrize("call", list(CALLS))
@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_non_finite_points_are_refused(call, bad):
    xyz = _points()
    xyz[7, 2] = bad
    before = xyz.copy()
    with pytest.raises(ValueError, match="non-finite"):
        CALLS[call](xyz)
    np.testing.assert_array_equal(xyz, before)        # the caller's array is left as it was


@pytest.mark.parametrize("call", ["knn", "csf", "slope_filter", "uniform_sample"])
def test_world_coordinates_wider_than_float32_are_refused(call):
    world = _points().astype(np.float64) + [870_000.0, 6_618_000.0, 40.0]
    with pytest.raises(ValueError, match="subtract a local origin"):
        CALLS[call](world)
    # the same points as local float64 coordinates run (float32 keeps them to well under a mm)
    local = world - world.min(axis=0)
    assert float(np.abs(local).max()) < MAX_LOCAL_COORD
    CALLS[call](local)


def test_local_float64_points_give_the_float32_rows():
    xyz = _points()
    idx64, dist64 = neighbors.knn(xyz.astype(np.float64), 6)
    idx32, dist32 = neighbors.knn(xyz, 6)
    np.testing.assert_array_equal(idx64, idx32)
    np.testing.assert_array_equal(dist64, dist32)


@pytest.mark.parametrize("k", [2.7, True, "3", None])
def test_k_must_be_a_whole_number(k):
    with pytest.raises(TypeError, match="whole number"):
        neighbors.knn(_points(), k)
    assert neighbors.knn(_points(), np.int64(3))[0].shape == (400, 3)


def test_infinite_radius_is_refused():
    with pytest.raises(ValueError, match="finite distance"):
        neighbors.radius_search(_points(), np.inf)


def test_empty_points_give_empty_grid_results():
    empty = np.zeros((0, 3), np.float32)
    cell, lowest, cols = grid_min.cell_minimum(empty, 1.0)
    assert cell.shape == (0,) and lowest.shape == (0,) and cols == 0
    keep, height = grid_min.slope_filter(empty, 1.0, 0.3, 0.5)
    assert keep.shape == (0,) and height.shape == (0,)


def test_a_cloth_larger_than_the_machine_is_refused_before_allocation():
    """One point 10,000 km off stretched the cloth over 3e8 particles: 13 GB and minutes before."""
    xyz = _points(3000)
    # about 1.8e9 particles at 1 m (under Taichi's 2^31 limit): 115 GB of simulation arrays
    xyz = np.concatenate([xyz, [[7.5e7, 0.0, 0.0]]]).astype(np.float32)
    with pytest.raises(cloth.LatticeTooLarge, match="particles allowed") as caught:
        cloth.csf(xyz, cloth_resolution=1.0, iterations=10)
    assert caught.value.particles < 2**31 - 1 and caught.value.limit < caught.value.particles
