"""R6 colour growing stage on small clouds: colour, intensity and geometry paths, target modes,
kerb cut, absorption, determinism; and the neighbour-mean smoothing kernel against numpy."""
from __future__ import annotations

import logging

import numpy as np
import pytest

from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import CLASS_ROAD, StageContext
from roadx_ti.stages.growing import ColorGrowing


def _ctx():
    return StageContext(log=logging.getLogger("test_growing"))


def _street(rng, spacing=0.1, kerb=0.12):
    """A 6 m road strip (x < 6, grey 84) beside a 2 m sidewalk (x >= 6, grey 104, kerb higher), a white
    marking on the road (2.9 <= x < 3.1, 1 <= y < 3), per-point colour noise sd 6."""
    g = np.arange(0, 8, spacing, dtype=np.float32)
    x, y = np.meshgrid(g, np.arange(0, 4, spacing, dtype=np.float32))
    x, y = x.ravel(), y.ravel()
    road = x < 6
    z = np.where(road, 0.0, kerb).astype(np.float32) + rng.normal(0, 0.005, x.size).astype(np.float32)
    grey = np.where(road, 84.0, 104.0)
    marking = road & (x >= 2.9) & (x < 3.1) & (y >= 1.0) & (y < 3.0)
    grey[marking] = 218.0
    rgb = np.clip(grey[:, None] + rng.normal(0, 6, (x.size, 3)), 0, 255).astype(np.uint16) * 257
    xyz = np.stack([x, y, z], 1)
    return xyz, rgb, road


def _options(**over):
    o = dict(k=12, max_edge_distance=0.3, max_edge_dz=0.05, smoothing_passes=1, point_threshold=10,
             region_threshold=5, min_region_size=20, target="largest")
    o.update(over)
    return o


def test_neighbor_mean_matches_numpy(ti_arch):
    from roadx_ti.kernels.smoothing import neighbor_mean

    rng = np.random.default_rng(0)
    values = rng.random((300, 3)).astype(np.float32)
    nbr = rng.integers(-1, 300, (300, 6)).astype(np.int32)

    def once(v):
        out = np.empty_like(v)
        for i in range(len(v)):
            js = [i] + [j for j in nbr[i] if j >= 0]
            out[i] = v[js].mean(axis=0)
        return out

    np.testing.assert_allclose(neighbor_mean(values, nbr, 2), once(once(values)), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(neighbor_mean(values[:, 0], nbr, 1), once(values)[:, 0], rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(neighbor_mean(values, nbr, 0), values)


def test_kerb_cut_and_absorbed_marking(ti_arch):
    rng = np.random.default_rng(1)
    xyz, rgb, road = _street(rng)
    cloud = Cloud(xyz=xyz, origin=np.zeros(3), rgb=rgb, color_depth=16)
    # without the kerb cut and smoothing, raw noise fragments or leaks; with them the road is one
    # region apart from the marking, which absorption puts back
    res = ColorGrowing(_options(absorb_enclosed=0.5)).run(cloud, _ctx())
    pred = res.labels == CLASS_ROAD
    assert (pred & ~road).sum() == 0
    assert (pred & road).sum() >= 0.97 * road.sum()
    no_absorb = ColorGrowing(_options()).run(cloud, _ctx()).labels == CLASS_ROAD
    marking = road & (xyz[:, 0] >= 2.95) & (xyz[:, 0] < 3.05) & (xyz[:, 1] >= 1.05) & (xyz[:, 1] < 2.95)
    assert not no_absorb[marking].any() and pred[marking].all()


def test_target_modes_and_determinism(ti_arch):
    rng = np.random.default_rng(2)
    xyz, rgb, road = _street(rng)
    cloud = Cloud(xyz=xyz, origin=np.array([1000.0, 2000.0, 0.0]), rgb=rgb, color_depth=16)
    seed_side = ColorGrowing(_options(target="seed", seed_xy=(1007.0, 2002.0))).run(cloud, _ctx())
    assert (seed_side.labels == CLASS_ROAD)[~road].mean() > 0.9     # the seed picks the sidewalk
    road_like = ColorGrowing(_options(target="road_like", min_target_size=100, road_brightness=(60, 95),
                                      road_max_saturation=15, absorb_enclosed=0.5)).run(cloud, _ctx())
    assert ((road_like.labels == CLASS_ROAD) == road).mean() > 0.95
    a = ColorGrowing(_options(absorb_enclosed=0.5)).run(cloud, _ctx())
    b = ColorGrowing(_options(absorb_enclosed=0.5)).run(cloud, _ctx())
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.segment_id, b.segment_id)


def test_intensity_and_geometry_fallback(ti_arch, caplog):
    rng = np.random.default_rng(3)
    xyz, rgb, road = _street(rng, kerb=0.0)
    # intensity: the road dark (30), the rest bright (60), 16-bit scaled -> 'auto' divides by 257
    inten = (np.where(road, 30.0, 60.0) + rng.normal(0, 4, len(road))).clip(0) * 257
    cloud = Cloud(xyz=xyz, origin=np.zeros(3), intensity=inten.astype(np.uint16))
    res = ColorGrowing(_options(point_threshold=8, max_curvature=0.05)).run(cloud, _ctx())
    assert res.info["color_source"] == "intensity"
    assert ((res.labels == CLASS_ROAD) == road).mean() > 0.9
    # geometry only: a flat road and a raised step; growing follows height continuity
    xyz2, _, road2 = _street(rng, kerb=0.3)
    bare = Cloud(xyz=xyz2, origin=np.zeros(3))
    with caplog.at_level(logging.WARNING, logger="test_growing"):
        geo = ColorGrowing(_options(min_region_size=20, dz_max=0.05)).run(bare, _ctx())
    assert geo.info["color_source"] == "geometry"
    assert "geometry only" in caplog.text
    pred = geo.labels == CLASS_ROAD
    assert (pred == road2).mean() > 0.95 or (pred == ~road2).mean() > 0.95
