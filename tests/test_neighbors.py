"""kNN and radius search against scipy's cKDTree (an independent exact reference)."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadx_ti.kernels import neighbors
from roadx_ti.kernels.grid import build_grid
from tests.conftest import KERNEL_BACKENDS


def _clouds(small):
    rng = np.random.default_rng(7)
    n = 1500 if small else 4000
    uniform = rng.random((n, 3)) * [40, 30, 4]
    centres = rng.random((12, 3)) * 50
    clustered = centres[rng.integers(0, 12, n)] + rng.normal(0, 0.3, (n, 3))
    base = rng.random((n // 4, 3)) * 10
    duplicated = np.concatenate([base, base, base[: n // 8], base[: n // 8] + 1e-3, rng.random((n // 4, 3))])
    grid_pts = np.stack(np.meshgrid(np.arange(12), np.arange(12), np.arange(8)), -1).reshape(-1, 3) * 0.5
    return {"uniform": uniform, "clustered": clustered, "duplicated": duplicated, "lattice": grid_pts}


def _real_cloud(shared_data, n_max):
    laspy = pytest.importorskip("laspy")
    las = laspy.read(shared_data / "roof" / "ign_870000_6618000.las")
    xyz = np.stack([las.x, las.y, las.z], 1)
    xyz = (xyz - xyz.min(0)).astype(np.float32)
    return xyz[:n_max]


def assert_knn_matches_kdtree(xyz, k, idx, dist):
    """Exact up to ties: rows agree on the k-th distance, and every neighbour strictly closer
    than it is the same; members at the k-th distance may differ only among equidistant points.
    Returns the number of rows whose set differs from cKDTree's (ties at the k-th distance)."""
    xyz64 = xyz.astype(np.float64)
    ref_d, ref_i = cKDTree(xyz64).query(xyz64, k + 1)
    n = len(xyz)
    # our own distances, recomputed in float64, for the indices we return
    own = np.linalg.norm(xyz64[idx] - xyz64[:, None, :], axis=2)
    assert (idx != np.arange(n)[:, None]).all(), "self must be excluded"
    assert (np.diff(dist, axis=1) >= 0).all(), "rows must be sorted by distance"
    np.testing.assert_allclose(dist, own, rtol=1e-5, atol=1e-5)
    # reference k-th distance excluding self: drop self from the k+1 list
    ref_wo_self = np.where(ref_i == np.arange(n)[:, None], np.inf, ref_d)
    ref_sorted = np.sort(ref_wo_self, axis=1)[:, :k]
    tol = 1e-5 * (1 + np.abs(xyz64).max())
    np.testing.assert_allclose(own.max(1), ref_sorted[:, -1], atol=tol)
    ties = 0
    same = (np.sort(idx, 1) == np.sort(np.where(ref_i == np.arange(n)[:, None], -1, ref_i), 1)[:, -k:]).all(1)
    for i in np.flatnonzero(~same):
        kth = ref_sorted[i, -1]
        ref_set = set(ref_i[i][(ref_i[i] != i) & (ref_d[i] < kth - tol)].tolist())
        got_set = set(idx[i][own[i] < kth - tol].tolist())
        assert ref_set == got_set, f"row {i}: strictly closer neighbours differ"
        if set(idx[i].tolist()) != set(ref_i[i][ref_i[i] != i][:k].tolist()):
            ties += 1     # differs from cKDTree only among points at the k-th distance
    return ties


@pytest.mark.parametrize("kind", ["uniform", "clustered", "duplicated", "lattice"])
@pytest.mark.parametrize("k", [1, 16, 100])
def test_knn_matches_kdtree(ti_arch, kind, k):
    small = ti_arch != "cpu"
    xyz = _clouds(small)[kind].astype(np.float32)
    idx, dist = neighbors.knn(xyz, k)
    assert idx.shape == (len(xyz), k) and idx.dtype == np.int32 and dist.dtype == np.float32
    ties = assert_knn_matches_kdtree(xyz, k, idx, dist)
    print(f"{kind} k={k}: {ties} rows differ from cKDTree, all by ties at the k-th distance")
    # ties are broken by index: equal distances appear in ascending index order
    same = (dist[:, 1:] == dist[:, :-1])
    assert (idx[:, 1:][same] > idx[:, :-1][same]).all()


@pytest.mark.parametrize("k", [16, 64])
def test_knn_real_cloud(ti_arch, shared_data, k):
    xyz = _real_cloud(shared_data, 4000 if ti_arch != "cpu" else 70840)
    idx, dist = neighbors.knn(xyz, k)
    ties = assert_knn_matches_kdtree(xyz, k, idx, dist)
    print(f"real k={k}: {ties} rows differ from cKDTree, all by ties at the k-th distance")


def test_knn_deterministic_and_grid_reuse(ti_arch):
    xyz = _clouds(True)["duplicated"].astype(np.float32)
    a = neighbors.knn(xyz, 12)
    g = build_grid(xyz, 0.37)
    b = neighbors.knn(xyz, 12, grid=g)
    c = neighbors.knn(xyz, 12, cell_size=5.0)
    for other in (b, c):
        np.testing.assert_array_equal(a[0], other[0])
        np.testing.assert_array_equal(a[1], other[1])


def test_knn_far_outliers_use_fallback(ti_arch):
    rng = np.random.default_rng(3)
    xyz = np.concatenate([rng.random((800, 3)) * [10, 10, 0.1], [[5000, 5000, 300], [-4000, 20, 0]]])
    xyz = xyz.astype(np.float32)
    idx, dist = neighbors.knn(xyz, 5, cell_size=0.2)
    assert_knn_matches_kdtree(xyz, 5, idx, dist)
    m = neighbors.knn_mean_distance(xyz, 40, cell_size=0.2)
    ref_d, _ = cKDTree(xyz.astype(np.float64)).query(xyz.astype(np.float64), 41)
    np.testing.assert_allclose(m, ref_d[:, 1:].mean(1), rtol=2e-5, atol=1e-5)


def test_knn_neighbourhoods_wider_than_the_cell_cube(ti_arch):
    """Cells smaller than the neighbourhoods (the k-th neighbour 2-4 cells away: a crown's or a
    wall's density against the grid's): queries the cell kernel's rings 1-2 do not settle go to
    the block search; every row exact, and the same bits as with the default cells, rows and
    means."""
    rng = np.random.default_rng(11)
    plane = rng.random((2000, 3)) * [10, 10, 0.05]
    above = rng.random((300, 3)) * [10, 10, 2] + [0, 0, 1]
    xyz = np.concatenate([plane, above]).astype(np.float32)
    cell = 0.2
    idx, dist = neighbors.knn(xyz, 16, cell_size=cell)
    assert_knn_matches_kdtree(xyz, 16, idx, dist)
    reach = dist[:, -1] / cell
    assert np.mean((reach > 2) & (reach < 4)) > 0.5, np.percentile(reach, [10, 50, 90])
    default = neighbors.knn(xyz, 16)
    np.testing.assert_array_equal(idx, default[0])
    np.testing.assert_array_equal(dist, default[1])
    np.testing.assert_array_equal(neighbors.knn_mean_distance(xyz, 16, cell_size=cell),
                                  neighbors.knn_mean_distance(xyz, 16))


def test_knn_rejects_bad_k(ti_arch):
    xyz = np.zeros((5, 3), np.float32)
    with pytest.raises(ValueError, match="at least k\\+1 points"):
        neighbors.knn(xyz, 5)
    with pytest.raises(ValueError):
        neighbors.knn(np.zeros((600, 3), np.float32), 513)


@pytest.mark.parametrize("k", [1, 20, 100])
@pytest.mark.parametrize("include_self", [False, True])
def test_knn_mean_distance(ti_arch, k, include_self):
    xyz = _clouds(ti_arch != "cpu")["clustered"].astype(np.float32)
    got = neighbors.knn_mean_distance(xyz, k, include_self=include_self)
    ref_d, _ = cKDTree(xyz.astype(np.float64)).query(xyz.astype(np.float64), k + (0 if include_self else 1))
    ref_d = ref_d.reshape(len(xyz), -1)
    expected = ref_d.mean(1) if include_self else ref_d[:, 1:].mean(1)
    np.testing.assert_allclose(got, expected, rtol=2e-5, atol=1e-6)


@pytest.mark.parametrize("kind", ["uniform", "duplicated", "lattice"])
def test_radius_search_matches_kdtree(ti_arch, kind):
    xyz = _clouds(ti_arch != "cpu")[kind].astype(np.float32)
    radius = 0.5 if kind == "lattice" else 1.1
    offsets, idx = neighbors.radius_search(xyz, radius)
    xyz64 = xyz.astype(np.float64)
    tree = cKDTree(xyz64)
    ref = tree.query_ball_point(xyz64, radius)
    assert offsets[0] == 0 and offsets[-1] == len(idx)
    boundary = 0
    for i in range(len(xyz)):
        row = idx[offsets[i]:offsets[i + 1]]
        d = np.linalg.norm(xyz64[row] - xyz64[i], axis=1)
        assert (np.diff(d) >= -1e-6).all()
        want = {j for j in ref[i] if j != i}
        diff = set(row.tolist()) ^ want
        # only points within float32 rounding of the sphere may differ
        for j in diff:
            assert abs(np.linalg.norm(xyz64[j] - xyz64[i]) - radius) < 1e-5
            boundary += 1
    print(f"{kind}: {boundary} boundary disagreements")
    # max_neighbors keeps the nearest prefix of every row
    off2, idx2 = neighbors.radius_search(xyz, radius, max_neighbors=3)
    counts = np.minimum(np.diff(offsets), 3)
    np.testing.assert_array_equal(np.diff(off2), counts)
    for i in range(0, len(xyz), 97):
        np.testing.assert_array_equal(idx2[off2[i]:off2[i + 1]], idx[offsets[i]:offsets[i] + counts[i]])


def assert_nearest_matches_kdtree(reference, queries, idx, dist):
    """Exact: every query's distance equals cKDTree's nearest distance; among reference points
    at the same coordinates (equidistant in any arithmetic) the lowest index is returned.
    Returns how many queries hit such a duplicated point."""
    ref64, qry64 = reference.astype(np.float64), queries.astype(np.float64)
    ref_d, _ = cKDTree(ref64).query(qry64, 1)
    own = np.linalg.norm(ref64[idx] - qry64, axis=1)
    tol = 1e-5 * (1 + np.abs(ref64).max())
    np.testing.assert_allclose(own, ref_d, atol=tol)
    np.testing.assert_allclose(dist, own, rtol=1e-5, atol=1e-5)
    _, first, inverse = np.unique(reference, axis=0, return_index=True, return_inverse=True)
    lowest_same = first[inverse.ravel()]
    np.testing.assert_array_equal(lowest_same[idx], idx)
    copies = np.bincount(inverse.ravel())[inverse.ravel()]
    return int((copies[idx] > 1).sum())


@pytest.mark.parametrize("kind", ["uniform", "clustered", "duplicated", "lattice"])
def test_nearest_matches_kdtree(ti_arch, kind):
    xyz = _clouds(ti_arch != "cpu")[kind].astype(np.float32)
    rng = np.random.default_rng(11)
    reference = xyz[::2]
    # queries: the other half, copies of reference points (exact ties at distance 0 when the
    # reference holds duplicates), and points off the cloud's extent
    queries = np.concatenate([xyz[1::2], reference[:50], rng.random((20, 3)).astype(np.float32) * 200 - 100])
    idx, dist = neighbors.nearest(reference, queries)
    assert idx.shape == (len(queries),) and idx.dtype == np.int32 and dist.dtype == np.float32
    ties = assert_nearest_matches_kdtree(reference, queries, idx, dist)
    print(f"{kind}: {ties} queries whose nearest point is duplicated (lowest index returned)")
    if kind == "duplicated":
        assert ties > 0
    # repeated calls and another cell size give the same answer
    again = neighbors.nearest(reference, queries, cell_size=3.0)
    np.testing.assert_array_equal(idx, again[0])


def test_nearest_real_cloud(ti_arch, shared_data):
    xyz = _real_cloud(shared_data, 8000 if ti_arch != "cpu" else 70840)
    idx, dist = neighbors.nearest(xyz[::3], xyz[1::3])
    assert_nearest_matches_kdtree(xyz[::3], xyz[1::3], idx, dist)


def test_nearest_ndarrays_and_empty(ti_arch):
    from roadx_ti.kernels.taichi_compat import ti

    xyz = _clouds(True)["uniform"].astype(np.float32)
    ref, qry = ti.ndarray(ti.f32, (750, 3)), ti.ndarray(ti.f32, (750, 3))
    ref.from_numpy(np.ascontiguousarray(xyz[:750]))
    qry.from_numpy(np.ascontiguousarray(xyz[750:1500]))
    idx, dist = neighbors.nearest(ref, qry)
    assert isinstance(idx, ti.Ndarray) and isinstance(dist, ti.Ndarray)
    np.testing.assert_array_equal(idx.to_numpy(), neighbors.nearest(xyz[:750], xyz[750:1500])[0])
    empty = neighbors.nearest(xyz, np.zeros((0, 3), np.float32))
    assert empty[0].shape == (0,) and empty[1].shape == (0,)
    with pytest.raises(ValueError, match="reference point set is empty"):
        neighbors.nearest(np.zeros((0, 3), np.float32), xyz)
    with pytest.raises(ValueError, match="queries must have shape"):
        neighbors.nearest(xyz, xyz[:, :2])


LAVAPIPE_KNN_DEFECT = pytest.mark.xfail(
    reason="known defect: on lavapipe the GPU block search returns wrong rows for a few isolated points, "
           "depending on the other queries of the dispatch (tests/test_determinism.py)", strict=False)


_GPU_BACKENDS = [pytest.param(b, marks=LAVAPIPE_KNN_DEFECT) if b == "vulkan" else b
                 for b in KERNEL_BACKENDS if b != "cpu"] or \
                [pytest.param("none", marks=pytest.mark.skip(reason="no GPU backend in ROADX_TI_TEST_BACKENDS"))]


@pytest.mark.kernel
@pytest.mark.parametrize("arch", _GPU_BACKENDS)
def test_knn_isolated_points_of_a_street_scene_on_gpu(arch, tmp_path):
    """The 20 k-point street scene of tests/test_determinism.py in canonical order: its isolated high
    points (neighbours 4-7 m away) against cKDTree on each GPU backend under test (Vulkan on
    lavapipe in CI, measured: 2 rows wrong; right when the same queries are dispatched alone; the
    CPU path is right; ROADX_TI_TEST_BACKENDS=cuda runs it on CUDA)."""
    from scipy.spatial import cKDTree

    from cli_helpers import synth
    from roadx_ti import io
    from roadx_ti.kernels.neighbors import knn
    from roadx_ti.ordering import canonical_order
    from tests.conftest import switch_backend

    switch_backend(arch)
    cloud = io.read(synth(tmp_path / "road.laz", points="20k", seed=5))
    cloud = cloud.subset(canonical_order(cloud))
    want, _ = cKDTree(cloud.xyz.astype(np.float64)).query(cloud.xyz.astype(np.float64), 21)
    _, dist = knn(cloud.xyz, 20)
    wrong = np.flatnonzero((np.abs(np.asarray(dist) - want[:, 1:]) > 1e-4).any(axis=1))
    assert len(wrong) == 0, f"{len(wrong)} rows wrong: {wrong[:10]}"
