"""P2 roof seed constraints against numpy references (random features and a small real geometry)."""
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadx_ti.kernels import seeds


def reference_constraints(knn, curvature, max_distance, extent, curvature_max, plane_coef, r_max, alpha):
    n, k = knn.shape
    ones = np.ones(n, bool)
    if curvature_max is None:
        planar = ones
    else:
        candidate = curvature < curvature_max
        nb_candidate = np.where(knn >= 0, candidate[np.clip(knn, 0, None)], False)
        needed = math.ceil(round(plane_coef * k, 9))
        planar = candidate & (nb_candidate.sum(axis=1) >= needed)
    compact = ones if r_max is None else max_distance < np.float32(r_max)
    if alpha is None:
        gradient = ones
    else:
        gradient = extent[:, 2] <= np.float32(alpha) * np.maximum(extent[:, 0], extent[:, 1])
    return {"planar": planar, "compact": compact, "gradient": gradient,
            "seed": planar & compact & gradient}


def numpy_features(xyz, knn):
    """Curvature, farthest neighbour distance and neighbourhood extent (p plus its k neighbours)."""
    hood = np.concatenate([xyz[:, None, :], xyz[knn]], axis=1).astype(np.float64)
    centred = hood - hood.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", centred, centred) / hood.shape[1]
    eig = np.linalg.eigvalsh(cov)
    curvature = (eig[:, 0] / np.maximum(eig.sum(axis=1), 1e-30)).astype(np.float32)
    max_distance = np.linalg.norm(xyz[knn] - xyz[:, None, :], axis=2).max(axis=1).astype(np.float32)
    extent = (hood.max(axis=1) - hood.min(axis=1)).astype(np.float32)
    return curvature, max_distance, extent


def roof_and_tree_cloud(seed=0):
    """A pitched roof plane, a wall and a random blob (tree), about 1 point per 0.3 m."""
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(0, 6, 300), rng.uniform(0, 4, 300)
    roof = np.column_stack([u, v, 5 + 0.5 * v + rng.normal(0, 0.01, 300)])
    w, h = rng.uniform(0, 6, 150), rng.uniform(0, 5, 150)
    wall = np.column_stack([w, np.full(150, -0.3) + rng.normal(0, 0.01, 150), h])
    tree = rng.normal([10, 2, 4], 1.0, (200, 3))
    return np.concatenate([roof, wall, tree]).astype(np.float32)


SETTINGS = [
    dict(curvature_max=0.05, plane_coef=0.8, r_max=1.2, alpha=1.0),
    dict(curvature_max=0.05, plane_coef=0.7, r_max=None, alpha=None),
    dict(curvature_max=None, plane_coef=0.8, r_max=0.9, alpha=None),
    dict(curvature_max=None, plane_coef=0.8, r_max=None, alpha=0.3),
    dict(curvature_max=None, plane_coef=0.8, r_max=None, alpha=None),
]


@pytest.mark.parametrize("settings", SETTINGS)
def test_constraints_match_numpy_on_random_features(ti_arch, settings):
    rng = np.random.default_rng(1)
    n, k = 500, 10
    knn = rng.integers(0, n, (n, k)).astype(np.int32)
    knn[rng.random((n, k)) < 0.05] = -1  # missing neighbours never count
    curvature = rng.uniform(0, 0.1, n).astype(np.float32)
    max_distance = rng.uniform(0.3, 2.0, n).astype(np.float32)
    extent = rng.uniform(0, 2, (n, 3)).astype(np.float32)
    got = seeds.seed_constraints(knn, curvature, max_distance, extent, **settings)
    want = reference_constraints(knn, curvature, max_distance, extent, **settings)
    for name in ("planar", "compact", "gradient", "seed"):
        assert got[name].dtype == np.uint8
        np.testing.assert_array_equal(got[name].astype(bool), want[name], err_msg=name)


def test_constraints_on_roof_wall_tree(ti_arch):
    xyz = roof_and_tree_cloud()
    k = 10
    _, idx = cKDTree(xyz).query(xyz, k=k + 1)
    knn = idx[:, 1:].astype(np.int32)
    curvature, max_distance, extent = numpy_features(xyz, knn)
    settings = dict(curvature_max=0.02, plane_coef=0.8, r_max=1.5, alpha=0.8)
    got = seeds.seed_constraints(knn, curvature, max_distance, extent, **settings)
    want = reference_constraints(knn, curvature, max_distance, extent, **settings)
    for name in ("planar", "compact", "gradient", "seed"):
        np.testing.assert_array_equal(got[name].astype(bool), want[name], err_msg=name)
    seed = got["seed"].astype(bool)
    # the geometry behaves as P2 intends: the roof seeds, the wall fails the gradient test, the
    # tree is not planar
    assert seed[:300].mean() > 0.9
    assert got["gradient"][300:450].mean() < 0.5
    assert seed[450:].mean() < 0.05


def test_required_planar_neighbours():
    assert seeds.required_planar_neighbours(0.7, 10) == 7
    assert seeds.required_planar_neighbours(0.75, 10) == 8
    assert seeds.required_planar_neighbours(1.0, 12) == 12


def test_constraints_on_taichi_ndarrays(ti_arch):
    from roadx_ti.kernels.common import as_ndarray, is_ndarray
    rng = np.random.default_rng(2)
    n, k = 64, 6
    knn = rng.integers(0, n, (n, k)).astype(np.int32)
    curvature = rng.uniform(0, 0.1, n).astype(np.float32)
    max_distance = rng.uniform(0.3, 2.0, n).astype(np.float32)
    extent = rng.uniform(0, 2, (n, 3)).astype(np.float32)
    settings = SETTINGS[0]
    got = seeds.seed_constraints(as_ndarray(knn), as_ndarray(curvature), as_ndarray(max_distance),
                                 as_ndarray(extent), **settings)
    assert is_ndarray(got["seed"])
    want = reference_constraints(knn, curvature, max_distance, extent, **settings)
    np.testing.assert_array_equal(got["seed"].to_numpy().astype(bool), want["seed"])


def flat_roof(density, seed=0, size=30.0):
    """A flat 30 x 30 m roof at 6 m, Poisson sampled at ``density`` points per m2, 2 cm noise."""
    rng = np.random.default_rng(seed)
    m = rng.poisson(density * size * size)
    return np.column_stack([rng.uniform(0, size, m), rng.uniform(0, size, m),
                            6 + rng.normal(0, 0.02, m)])


@pytest.mark.parametrize("density", [1.0, 30.0])
def test_auto_r_max_follows_the_measured_spacing(ti_arch, density):
    """r_max 'auto' is r_max_radii k-neighbourhood radii at the measured spacing: at 30 points/m2
    about 0.8 m, at 1 point/m2 about 4.3 m, where the fixed 2 m of the old config fails most of the
    roof's compact test (k = 10 neighbours span 1.8 m there)."""
    from roadx_ti import estimates
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import ESTIMATES, StageContext
    from roadx_ti.stages.seeds import RoofSeeds, auto_r_max

    cloud = Cloud.from_world(flat_roof(density), origin=np.zeros(3))
    measured = estimates.measure(cloud)
    assert "pulse_spacing_m" not in measured          # no return numbers
    # the Poisson relation auto_r_max relies on: median plan NN distance <-> density
    expected = 4.0 * np.sqrt(10 / (np.pi * density))
    assert auto_r_max(measured["point_spacing_m"], 10, 4.0) == pytest.approx(expected, rel=0.08)
    compact = {}
    for r_max in ("auto", 2.0):
        ctx = StageContext(facts={ESTIMATES: dict(measured)})
        result = RoofSeeds({"r_max": r_max}).run(cloud, ctx)
        assert result.info["r_max_source"] == ("auto" if r_max == "auto" else "option")
        if r_max == "auto":
            assert result.info["r_max"] == pytest.approx(auto_r_max(measured["point_spacing_m"], 10, 4.0), abs=1e-4)
        compact[r_max] = 1 - result.info["removed_by"]["compact"] / cloud.n
    assert compact["auto"] > 0.99
    if density < 2:
        assert compact[2.0] < 0.8              # 72 % pass measured here


def test_pulse_spacing_counts_first_returns_only(ti_arch):
    """Where the file has return numbers, pulse_spacing_m is the spacing of the first returns: a
    canopy's later returns make point_spacing_m smaller than a roof's spacing."""
    from roadx_ti import estimates
    from roadx_ti.cloud import Cloud

    roof = flat_roof(4.0, seed=1)
    rng = np.random.default_rng(2)
    # a wood beside it: pulses of 3 returns at the same plan position (plus a little spread)
    top = np.column_stack([rng.uniform(40, 70, 3600), rng.uniform(0, 30, 3600), rng.uniform(8, 12, 3600)])
    wood = np.concatenate([top, top + rng.normal(0, 0.05, top.shape) - [0, 0, 3],
                           top + rng.normal(0, 0.05, top.shape) - [0, 0, 6]])
    returns = np.concatenate([np.tile([1, 1], (len(roof), 1)), np.tile([1, 3], (len(top), 1)),
                              np.tile([2, 3], (len(top), 1)), np.tile([3, 3], (len(top), 1))]).astype(np.uint8)
    cloud = Cloud.from_world(np.concatenate([roof, wood]), origin=np.zeros(3), returns=returns)
    measured = estimates.measure(cloud)
    alone = estimates.measure(Cloud.from_world(np.concatenate([roof, top]), origin=np.zeros(3)))
    assert measured["point_spacing_m"] < 0.5 * measured["pulse_spacing_m"]
    assert measured["pulse_spacing_m"] == pytest.approx(alone["point_spacing_m"], rel=0.02)
