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
    "covariance_features": lambda xyz: features.covariance_features(xyz, np.zeros((len(xyz), 4), np.int32)),
    "knn_mean_distance": lambda xyz: neighbors.knn_mean_distance(xyz, 1, include_self=True),
}


@pytest.mark.parametrize("call", list(CALLS))
@pytest.mark.parametrize("columns", [2, 4])
def test_points_of_other_than_three_columns_are_refused(ti_arch, call, columns):
    xyz = np.ascontiguousarray(_points()[:, :2] if columns == 2 else np.column_stack([_points(), _points()[:, :1]]))
    with pytest.raises(ValueError, match=r"must have shape \([nm], 3\)"):
        CALLS[call](xyz)


@pytest.mark.parametrize("call", list(CALLS))
@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_non_finite_points_are_refused(ti_arch, call, bad):
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
@pytest.mark.parametrize("call", [neighbors.knn, neighbors.knn_mean_distance,
                                  lambda xyz, k: outliers.sor_keep(xyz, k, 1.0)])
def test_k_must_be_a_whole_number(call, k):
    with pytest.raises(TypeError, match="whole number"):
        call(_points(), k)
    result = call(_points(), np.int64(3))          # numpy's integers are whole numbers
    assert (result[0] if isinstance(result, tuple) else result).shape[0] == 400


def test_infinite_radius_is_refused():
    with pytest.raises(ValueError, match="finite distance"):
        neighbors.radius_search(_points(), np.inf)


def test_empty_points_give_empty_grid_results(ti_arch):
    """As numpy arrays on every backend (Taichi has no empty ndarray: on Vulkan an empty result
    array was a TaichiRuntimeError)."""
    empty = np.zeros((0, 3), np.float32)
    cell, lowest, cols = grid_min.cell_minimum(empty, 1.0)
    assert cell.shape == (0,) and lowest.shape == (0,) and cols == 0
    keep, height = grid_min.slope_filter(empty, 1.0, 0.3, 0.5)
    assert keep.shape == (0,) and height.shape == (0,)


def test_a_cloth_larger_than_the_machine_is_refused_before_allocation(monkeypatch):
    """One point 10,000 km off stretched the cloth over 3e8 particles: 13 GB and minutes before.
    The default bound is what half the machine's memory holds (here fixed at 1e8 particles, so
    that the test does not depend on the machine)."""
    limit = cloth._memory_particles()
    assert limit is None or limit >= 2**20      # any machine that runs the suite holds a million
    monkeypatch.setattr(cloth, "_memory_particles", lambda: 100_000_000)
    xyz = np.concatenate([_points(3000), [[1e7, 0.0, 0.0]]]).astype(np.float32)   # 3e8 particles at 1 m
    with pytest.raises(cloth.LatticeTooLarge, match="half this machine's memory") as caught:
        cloth.csf(xyz, cloth_resolution=1.0, iterations=10)
    assert caught.value.limit == 100_000_000 and caught.value.particles > 100_000_000
    # an explicit bound replaces the default
    with pytest.raises(cloth.LatticeTooLarge, match="by max_particles"):
        cloth.csf(_points(3000), cloth_resolution=1.0, iterations=10, max_particles=10)
    assert cloth.csf(_points(3000), cloth_resolution=1.0, iterations=10).ground.shape == (3000,)
