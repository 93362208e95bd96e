"""Covariance features against numpy (eigh) and Open3D's estimate_normals."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadx_ti.kernels import features, neighbors


def _numpy_reference(xyz, nbr):
    hood = np.concatenate([np.arange(len(xyz))[:, None], nbr], 1)
    pts = xyz.astype(np.float64)[hood]                      # (n, k+1, 3)
    centred = pts - pts.mean(1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", centred, centred) / pts.shape[1]
    w, v = np.linalg.eigh(cov)
    normal = v[:, :, 0]
    normal *= np.where(normal[:, 2:3] < 0, -1, 1)
    extent = pts.max(1) - pts.min(1)
    far = np.linalg.norm(pts[:, 1:] - pts[:, :1], axis=2).max(1)
    return w, normal, extent, far


def test_features_match_numpy(ti_arch):
    rng = np.random.default_rng(4)
    n = 1500 if ti_arch != "cpu" else 6000
    # a tilted plane with noise, a line, and an isotropic blob: flat, linear and full-rank hoods
    a = rng.random((n // 3, 2)) * 10
    plane = np.c_[a, 0.3 * a[:, 0] - 0.2 * a[:, 1] + rng.normal(0, 0.001, n // 3)]
    line = np.c_[np.linspace(0, 10, n // 3), np.zeros(n // 3) + 50, np.zeros(n // 3)]
    blob = rng.normal(0, 1, (n - 2 * (n // 3), 3)) + [100, 0, 0]
    xyz = np.concatenate([plane, line, blob]) + [651000, 6860000, 120]
    xyz = (xyz - xyz.min(0)).astype(np.float32)     # local float32 coordinates, as Cloud holds them
    k = 12
    nbr, _ = neighbors.knn(xyz, k)
    f = features.covariance_features(xyz, nbr)
    w, normal, extent, far = _numpy_reference(xyz, nbr)
    assert f["normal"].shape == (len(xyz), 3) and f["normal"].dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(f["normal"], axis=1), 1, atol=1e-5)
    assert (f["normal"][:, 2] >= 0).all()
    assert (np.diff(f["eigenvalues"], axis=1) >= 0).all()
    np.testing.assert_allclose(f["eigenvalues"], w, rtol=1e-3, atol=1e-5 * w[:, 2:].max())
    np.testing.assert_allclose(f["extent"], extent, atol=1e-5)
    np.testing.assert_allclose(f["max_distance"], far, rtol=1e-5, atol=1e-5)
    total = w.sum(1)
    expected_curv = np.where(total > 0, w[:, 0] / np.where(total > 0, total, 1), 0)
    np.testing.assert_allclose(f["curvature"], expected_curv, atol=1e-4)
    # the curvature-only kernel (survey estimates) gives the same values bit for bit
    assert np.array_equal(features.curvature(xyz, nbr), f["curvature"])
    # normals of the plane: where the two smallest eigenvalues are well separated
    well_posed = (w[:, 1] - w[:, 0]) > 1e-3 * w[:, 2]
    dots = np.abs((f["normal"] * normal).sum(1))
    assert (dots[well_posed] > np.cos(np.radians(1.0))).all()
    plane_normal = np.array([-0.3, 0.2, 1.0]) / np.linalg.norm([-0.3, 0.2, 1.0])
    assert (np.abs(f["normal"][: n // 3] @ plane_normal) > np.cos(np.radians(5))).mean() > 0.99


def test_degenerate_neighbourhoods(ti_arch):
    xyz = np.zeros((20, 3), np.float32)          # all coincident: zero covariance
    nbr = np.tile(np.arange(1, 5, dtype=np.int32), (20, 1))
    f = features.covariance_features(xyz, nbr)
    assert np.isfinite(f["normal"]).all() and (f["curvature"] == 0).all()
    assert (f["eigenvalues"] == 0).all() and (f["max_distance"] == 0).all()


@pytest.mark.parametrize("tile", ["roof/ign_870000_6618000.las", "road/ahn3_2386_9702_roads.laz"])
def test_normals_match_open3d_on_real_tiles(ti_arch, shared_data, tile):
    laspy = pytest.importorskip("laspy")
    o3d = pytest.importorskip("open3d")
    las = laspy.read(shared_data / tile)
    xyz = np.stack([las.x, las.y, las.z], 1)
    xyz = (xyz - xyz.min(0)).astype(np.float32)
    if ti_arch != "cpu":
        xyz = xyz[:5000]
    k = 20
    nbr, _ = neighbors.knn(xyz, k)
    f = features.covariance_features(xyz, nbr)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.astype(np.float64)))
    # Open3D's KNN neighbourhood contains p itself: k+1 there is p plus our k neighbours
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(k + 1))
    ref = np.asarray(pcd.normals)
    dots = np.abs((f["normal"] * ref).sum(1))
    w = f["eigenvalues"]
    degenerate = (w[:, 1] - w[:, 0]) <= 1e-3 * np.maximum(w[:, 2], 1e-12)
    # neighbourhoods tied at the k-th distance may differ from Open3D's: recount them exactly
    kth = np.linalg.norm(xyz[nbr[:, -1]] - xyz, axis=1)
    d_next = cKDTree(xyz).query(xyz, k + 2)[0][:, -1]
    tied = np.abs(d_next - kth) < 1e-6
    bad = (dots < np.cos(np.radians(1.0))) & ~degenerate & ~tied
    print(f"{tile}: {degenerate.sum()} degenerate, {tied.sum()} tied at the k-th distance, "
          f"{bad.sum()} of {len(xyz)} beyond 1 degree")
    assert bad.sum() == 0


def test_written_out_rotations_equal_full_products(ti_arch):
    """sym_eigen3 applies each Jacobi rotation on rows and columns p, q only: the same bits as the
    full products R^T m R and v R (the dropped terms are exact zeros and ones), on full-rank, flat,
    linear, diagonal, repeated-eigenvalue and zero matrices over seven decades of scale."""
    from roadx_ti.kernels.taichi_compat import ti

    @ti.func
    def full_products_eigen(a: ti.math.mat3):
        scale = ti.max(ti.abs(a).max(), 1e-30)
        m = a / scale
        v = ti.math.mat3([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        sweep = 0
        while sweep < features._JACOBI_SWEEPS:
            if features._jacobi_converged(m):
                break
            sweep += 1
            for pair in ti.static(range(3)):
                p = ti.static((0, 0, 1)[pair])
                q = ti.static((1, 2, 2)[pair])
                if ti.abs(m[p, q]) > 1e-30:
                    cs = features._jacobi_angle(m, p, q)
                    c = cs[0]
                    s = cs[1]
                    rot = ti.math.mat3([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
                    rot[p, p] = c
                    rot[q, q] = c
                    rot[p, q] = s
                    rot[q, p] = -s
                    m = rot.transpose() @ m @ rot
                    m[p, q] = 0.0
                    m[q, p] = 0.0
                    v = v @ rot
        return features._sorted_eigen(m, v, scale, True)

    @ti.kernel
    def both(cov: ti.types.ndarray(dtype=ti.f32, ndim=3), w: ti.types.ndarray(dtype=ti.f32, ndim=3),
             v: ti.types.ndarray(dtype=ti.f32, ndim=4)):
        for i in range(cov.shape[0]):
            a = ti.math.mat3(0.0)
            for r, c in ti.static(ti.ndrange(3, 3)):
                a[r, c] = cov[i, r, c]
            e0, u0 = features.sym_eigen3(a)
            e1, u1 = full_products_eigen(a)
            for r in ti.static(range(3)):
                w[i, 0, r] = e0[r]
                w[i, 1, r] = e1[r]
                for c in ti.static(range(3)):
                    v[i, 0, r, c] = u0[r, c]
                    v[i, 1, r, c] = u1[r, c]

    rng = np.random.default_rng(9)
    full = rng.normal(size=(400, 3, 3))
    full = full @ full.transpose(0, 2, 1)
    flat = rng.normal(size=(200, 3, 2)) @ rng.normal(size=(200, 2, 3))
    flat = flat @ flat.transpose(0, 2, 1)
    line = rng.normal(size=(200, 3, 1))
    line = line @ line.transpose(0, 2, 1)
    special = np.stack([np.diag([3.0, 1.0, 2.0]), np.eye(3), np.zeros((3, 3)), np.diag([1.0, 1.0, 1e-9])] * 25)
    cov = np.concatenate([full, flat, line, special])
    cov = (cov * 10.0 ** rng.integers(-4, 3, (len(cov), 1, 1))).astype(np.float32)
    w, v = np.zeros((len(cov), 2, 3), np.float32), np.zeros((len(cov), 2, 3, 3), np.float32)
    both(cov, w, v)
    np.testing.assert_array_equal(w[:, 0], w[:, 1])
    np.testing.assert_array_equal(v[:, 0], v[:, 1])
    scale = np.maximum(np.abs(cov).max(axis=(1, 2)), 1e-30)[:, None].astype(np.float64)
    np.testing.assert_allclose(w[:, 0] / scale, np.linalg.eigvalsh(cov.astype(np.float64)) / scale, atol=1e-5)
