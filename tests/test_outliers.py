"""Statistical outlier removal against Open3D (open3d convention) and a numpy/scipy reference
(paper convention)."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadx_ti.kernels import outliers


def _noisy_surface(n, seed=0):
    rng = np.random.default_rng(seed)
    xy = rng.random((n, 2)) * 30
    z = 0.2 * np.sin(xy[:, 0]) + rng.normal(0, 0.02, n)
    xyz = np.c_[xy, z]
    noise = rng.random((n // 50, 3)) * [30, 30, 6] - [0, 0, 3]
    return np.concatenate([xyz, noise]).astype(np.float32)


def _open3d_keep(xyz, k, ratio):
    o3d = pytest.importorskip("open3d")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.astype(np.float64)))
    _, kept = pcd.remove_statistical_outlier(nb_neighbors=k, std_ratio=ratio)
    mask = np.zeros(len(xyz), bool)
    mask[np.asarray(kept, int)] = True
    return mask


def _report_differences(xyz, k, ratio, keep, ref, convention):
    """Differences are allowed only for points whose d lies within float rounding of the
    threshold (counted and shown)."""
    d, _ = cKDTree(xyz.astype(np.float64)).query(xyz.astype(np.float64), k)
    mean_d = d.mean(1)
    lower, upper = outliers.sor_thresholds(mean_d, ratio, convention)
    diff = np.flatnonzero(keep != ref)
    assert (np.abs(mean_d[diff] - upper) < 1e-5 * max(1.0, upper)).all(), "a difference away from the threshold"
    return len(diff)


@pytest.mark.parametrize("k,ratio", [(20, 2.0), (50, 1.0), (8, 0.5)])
def test_sor_upper_open3d_matches_open3d(ti_arch, k, ratio):
    xyz = _noisy_surface(2000 if ti_arch != "cpu" else 20000, seed=k)
    xyz[:30] = xyz[30]                # a stack of coincident points: d = 0, dropped by Open3D
    keep = outliers.sor_keep(xyz, k, ratio, mode="upper", convention="open3d")
    ref = _open3d_keep(xyz, k, ratio)
    assert keep.dtype == bool and keep.shape == (len(xyz),)
    n_diff = _report_differences(xyz, k, ratio, keep, ref, "open3d")
    print(f"k={k} ratio={ratio}: kept {keep.sum()} of {len(xyz)}, {n_diff} threshold ties vs Open3D")
    if k <= 31:                       # all k neighbours (p included) coincide: d = 0, dropped
        assert not keep[:31].any()


@pytest.mark.parametrize("mode", ["upper", "two_sided"])
def test_sor_paper_convention(ti_arch, mode):
    xyz = _noisy_surface(1500 if ti_arch != "cpu" else 8000, seed=3)
    k, ratio = 30, 1.0
    keep = outliers.sor_keep(xyz, k, ratio, mode=mode, convention="paper")
    d, _ = cKDTree(xyz.astype(np.float64)).query(xyz.astype(np.float64), k + 1)
    mean_d = d[:, 1:].mean(1)
    mu, sigma = mean_d.mean(), mean_d.std()
    ref = mean_d < mu + ratio * sigma
    if mode == "two_sided":
        ref &= mean_d > mu - ratio * sigma
        assert (~keep).sum() > (~outliers.sor_keep(xyz, k, ratio, mode="upper", convention="paper")).sum()
    diff = np.flatnonzero(keep != ref)
    bound = np.minimum(np.abs(mean_d - (mu + ratio * sigma)), np.abs(mean_d - (mu - ratio * sigma)))
    assert (bound[diff] < 1e-5).all()


def test_sor_rejects_bad_options(ti_arch):
    xyz = _noisy_surface(200)
    with pytest.raises(ValueError):
        outliers.sor_keep(xyz, 5, 1.0, mode="lower")
    with pytest.raises(ValueError):
        outliers.sor_keep(xyz, 5, 1.0, convention="pcl")
