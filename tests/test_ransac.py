import numpy as np
import open3d as o3d
import pytest

from roadx_ti.kernels import ransac
from roadx_ti.kernels.common import as_ndarray, is_ndarray

THRESHOLD = 0.1
GROUND_NORMAL = np.array([0.05, -0.03, 1.0]) / np.linalg.norm([0.05, -0.03, 1.0])


def synthetic_scene(seed, n):
    """60 % noisy tilted ground plane, 15 % wall, 10 % roof plane, 15 % uniform clutter.
    Returns xyz float32 (n, 3) and the part each point came from (0 ground .. 3 clutter)."""
    rng = np.random.default_rng(seed)
    sizes = [int(0.6 * n), int(0.15 * n), int(0.1 * n)]
    sizes.append(n - sum(sizes))
    xy = rng.uniform(0, 100, (sizes[0], 2))
    z = (2.0 - GROUND_NORMAL[0] * xy[:, 0] - GROUND_NORMAL[1] * xy[:, 1]) / GROUND_NORMAL[2]
    ground = np.c_[xy, z + rng.normal(0, 0.02, sizes[0])]
    wall = np.c_[rng.uniform(0, 100, sizes[1]), 30.0 + rng.normal(0, 0.02, sizes[1]),
                 rng.uniform(0, 20, sizes[1])]
    roof = np.c_[rng.uniform(20, 60, sizes[2]), rng.uniform(40, 80, sizes[2]),
                 12.0 + rng.normal(0, 0.02, sizes[2])]
    clutter = rng.uniform([0, 0, 0], [100, 100, 25], (sizes[3], 3))
    xyz = np.r_[ground, wall, roof, clutter].astype(np.float32)
    part = np.repeat(np.arange(4), sizes)
    order = rng.permutation(n)
    return xyz[order], part[order]


def open3d_plane(xyz, seed):
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.astype(np.float64)))
    o3d.utility.random.seed(seed)
    plane, inliers = pcd.segment_plane(distance_threshold=THRESHOLD, ransac_n=3,
                                       num_iterations=1000)
    plane = np.asarray(plane, dtype=np.float64)
    return plane / np.linalg.norm(plane[:3]), len(inliers)


def angle_deg(n1, n2):
    cos = abs(np.dot(n1, n2)) / (np.linalg.norm(n1) * np.linalg.norm(n2))
    return np.degrees(np.arccos(min(1.0, cos)))


@pytest.mark.parametrize("seed, sample_size", [(0, None), (1, 8192)])
def test_dominant_plane_matches_open3d(ti_arch, seed, sample_size):
    xyz, _ = synthetic_scene(seed, 30_000)
    fit = ransac.fit_plane(xyz, THRESHOLD, seed=seed, sample_size=sample_size)
    o3d_plane, o3d_count = open3d_plane(xyz, seed)
    assert angle_deg(fit.plane[:3], o3d_plane[:3]) < 1.0
    assert abs(fit.n_inliers - o3d_count) <= 0.01 * o3d_count
    assert angle_deg(fit.plane[:3], GROUND_NORMAL) < 1.0
    assert fit.plane[2] >= 0 and np.isclose(np.linalg.norm(fit.plane[:3]), 1.0)
    assert fit.hypotheses_scored == 1000
    assert fit.inliers.dtype == bool and fit.inliers.shape == (len(xyz),)
    assert fit.n_inliers == int(fit.inliers.sum())


def test_inliers_are_points_within_threshold_of_plane(ti_arch):
    xyz, _ = synthetic_scene(2, 20_000)
    fit = ransac.fit_plane(xyz, THRESHOLD, seed=3, hypotheses=300)
    dist = np.abs(xyz.astype(np.float64) @ fit.plane[:3] + fit.plane[3])
    clear = np.abs(dist - THRESHOLD) > 1e-4  # float32 rounding decides the boundary itself
    np.testing.assert_array_equal(fit.inliers[clear], (dist < THRESHOLD)[clear])


def test_deterministic(ti_arch):
    xyz, _ = synthetic_scene(4, 20_000)
    first = ransac.fit_plane(xyz, THRESHOLD, seed=11, sample_size=4096)
    for _ in range(2):
        again = ransac.fit_plane(xyz, THRESHOLD, seed=11, sample_size=4096)
        assert again.plane.tobytes() == first.plane.tobytes()
        np.testing.assert_array_equal(again.inliers, first.inliers)
        assert again.n_inliers == first.n_inliers
    # ndarray input gives the very same fit
    nd = ransac.fit_plane(as_ndarray(xyz), THRESHOLD, seed=11, sample_size=4096)
    assert nd.plane.tobytes() == first.plane.tobytes()


def test_active_mask_respected(ti_arch):
    xyz, part = synthetic_scene(5, 30_000)
    active = (part != 0).astype(np.uint8)  # without the ground the wall (15 %) dominates
    fit = ransac.fit_plane(xyz, THRESHOLD, seed=5, active=active)
    assert not fit.inliers[active == 0].any()
    o3d_plane, o3d_count = open3d_plane(xyz[active == 1], 5)
    assert angle_deg(fit.plane[:3], o3d_plane[:3]) < 1.0
    assert abs(fit.n_inliers - o3d_count) <= 0.01 * o3d_count
    assert angle_deg(fit.plane[:3], [0.0, 1.0, 0.0]) < 1.0
    # too few active points: no plane
    few = np.zeros(len(xyz), np.uint8)
    few[:2] = 1
    none = ransac.fit_plane(xyz, THRESHOLD, active=few)
    assert none.n_inliers == 0 and not none.inliers.any()


def test_plane_distances_match_numpy(ti_arch):
    rng = np.random.default_rng(6)
    xyz = rng.uniform(-50, 50, (5000, 3)).astype(np.float32)
    plane = np.array([1.0, -2.0, 2.0, 3.0])  # normal of length 3: normalised by the wrapper
    got = ransac.plane_distances(xyz, plane)
    expected = np.abs(xyz.astype(np.float64) @ plane[:3] + plane[3]) / 3.0
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-4)
    nd = ransac.plane_distances(as_ndarray(xyz), plane)
    assert is_ndarray(nd)
    np.testing.assert_array_equal(nd.to_numpy(), got)


def test_search_on_the_active_points_alone_is_the_masked_search():
    """The R3 stage searches the unmatched points alone: the same plane and inliers as a search
    over all points with the others inactive (hypotheses and sample are drawn from the active
    points in index order either way)."""
    xyz, part = synthetic_scene(6, 30_000)
    active = part != 0
    masked = ransac.fit_plane(xyz, THRESHOLD, seed=3, active=active.astype(np.uint8), sample_size=4096)
    alone = ransac.fit_plane(xyz[active], THRESHOLD, seed=3, sample_size=4096)
    np.testing.assert_array_equal(masked.plane, alone.plane)
    np.testing.assert_array_equal(np.flatnonzero(masked.inliers), np.flatnonzero(active)[alone.inliers])


def test_stage_removes_walls_and_roofs_keeps_ground():
    """R3 plane classes: the wall (Z class) and the roof 10 m up (XY class) are removed, the
    ground plane is kept; clutter matches no plane."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.planes import RansacPlanes

    xyz, part = synthetic_scene(7, 40_000)
    stage = RansacPlanes({"distance_threshold": THRESHOLD, "min_inliers": 500, "max_planes": 5,
                          "dh_max": 2.5, "ground_cell": 10.0})
    result = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext(seed=0))
    classes = {p["class"] for p in result.info["plane_list"]}
    assert {"Z", "XY", "ground"} <= classes
    assert result.keep[part == 0].mean() > 0.99           # ground kept
    assert result.keep[part == 1].mean() < 0.02           # wall removed
    assert result.keep[part == 2].mean() < 0.02           # roof removed
    # deterministic: the same labels on a second run
    again = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext(seed=0))
    np.testing.assert_array_equal(result.keep, again.keep)


@pytest.mark.parametrize("xy_removal", ["plane", "part"])
def test_a_roof_plane_takes_no_road_uphill_by_parts(xy_removal):
    """A flat roof 3 m above a street that climbs 8 %: the roof plane's slab (+-0.1 m) also crosses
    the street about 37 m uphill. xy_removal 'plane' (METHODS.md R3 literally) removes that band
    of road with the roof; 'part' classes the band, a part of the plane apart from the roof, by
    its own height above the ground: the roof goes, the road stays."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.planes import RansacPlanes

    rng = np.random.default_rng(11)
    street = np.column_stack([rng.random(60_000) * 60, rng.random(60_000) * 12, np.zeros(60_000)])
    street[:, 2] = 0.08 * street[:, 0] + rng.normal(0, 0.02, len(street))
    # denser than the street, so that its plane is found first (the street is not yet matched)
    roof = np.column_stack([rng.random(80_000) * 10, 14 + rng.random(80_000) * 10, np.zeros(80_000)])
    roof[:, 2] = 0.4 + 3.0 + rng.normal(0, 0.02, len(roof))      # 3 m above the street below it
    xyz = np.concatenate([street, roof]).astype(np.float32)
    on_roof = np.arange(len(xyz)) >= len(street)
    band = ~on_roof & (np.abs(xyz[:, 2] - 3.4) < 0.1)             # street points in the roof's slab
    assert band.sum() > 1000
    stage = RansacPlanes({"distance_threshold": 0.1, "min_inliers": 500, "max_planes": 3, "dh_max": 2.5,
                          "ground_cell": 10.0, "xy_removal": xy_removal})
    result = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext(seed=0))
    assert result.info["plane_list"][0]["class"] == "XY"
    assert result.keep[on_roof].mean() < 0.02                    # the roof goes either way
    if xy_removal == "plane":
        assert result.keep[band].mean() < 0.5                     # with a band of road
    else:
        assert result.keep[band].all() and result.keep[~on_roof].all()
        assert result.info["plane_list"][0]["removed"] == int((~result.keep).sum())


def test_a_wide_roof_goes_whole_by_parts():
    """A 60 x 60 m flat roof 6 m up: its middle has no ground within the 3 x 3 reference cells
    of 10 m (its own height above that reference is about 0), but it is one part with its rim,
    and the part's median height says roof: xy_removal 'part' removes all of it."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.planes import RansacPlanes, _height_above_local_minimum

    rng = np.random.default_rng(12)
    ground = np.column_stack([rng.random(40_000) * 100, rng.random(40_000) * 100, rng.normal(0, 0.02, 40_000)])
    ground = ground[~((ground[:, 0] > 20) & (ground[:, 0] < 80) & (ground[:, 1] > 20) & (ground[:, 1] < 80))]
    roof = np.column_stack([20 + rng.random(50_000) * 60, 20 + rng.random(50_000) * 60, 6 + rng.normal(0, 0.02, 50_000)])
    xyz = np.concatenate([ground, roof]).astype(np.float32)
    on_roof = np.arange(len(xyz)) >= len(ground)
    hag = _height_above_local_minimum(xyz, 10.0)
    assert (hag[on_roof] < 2.5).mean() > 0.1                      # the middle sees no ground
    stage = RansacPlanes({"distance_threshold": 0.1, "min_inliers": 500, "max_planes": 3, "dh_max": 2.5,
                          "ground_cell": 10.0, "xy_removal": "part"})
    result = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext(seed=0))
    assert not result.keep[on_roof].any()
    assert result.keep[~on_roof].all()


def test_a_steep_street_stays_ground_with_a_sloped_reference():
    """A street climbing at 15 % (diagonally to the grid), with a 6 m flat-roofed building beside it. The plain
    3 x 3 minimum of 10 m cells lies up to ~3 m under the street (the lowest point 15-20 m
    downhill), so the street's plane came out above dh_max and was removed as an XY (roof) plane;
    with ground_slope 0.15 each neighbour's minimum counts raised along the grade: the street
    stays, the roof still goes."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.planes import RansacPlanes, _height_above_local_minimum

    rng = np.random.default_rng(5)
    n = 60_000
    street = np.column_stack([rng.random(n) * 100, rng.random(n) * 100, np.zeros(n)])
    grade = 0.15 / np.sqrt(2.0)
    street[:, 2] = grade * (street[:, 0] + street[:, 1]) + rng.normal(0, 0.02, n)
    building = (street[:, 0] > 40) & (street[:, 0] < 55) & (street[:, 1] > 40) & (street[:, 1] < 55)
    street = street[~building]
    roof = np.column_stack([40 + rng.random(8_000) * 15, 40 + rng.random(8_000) * 15, np.zeros(8_000)])
    roof[:, 2] = grade * 95.0 + 6.0 + rng.normal(0, 0.02, 8_000)
    xyz = np.concatenate([street, roof]).astype(np.float32)
    on_roof = np.arange(len(xyz)) >= len(street)
    plain = _height_above_local_minimum(xyz, 10.0)
    sloped = _height_above_local_minimum(xyz, 10.0, slope=0.15)
    assert np.median(plain[~on_roof]) > 2.5 > np.quantile(sloped[~on_roof], 0.99)
    assert np.all(sloped <= plain + 1e-5) and np.all(sloped >= -1e-5)     # a higher reference, never above a point's own cell minimum
    assert np.median(sloped[on_roof]) > 2.5
    options = {"distance_threshold": 0.1, "min_inliers": 500, "max_planes": 3, "dh_max": 2.5,
               "ground_cell": 10.0, "xy_removal": "part"}
    cloud = Cloud(xyz=xyz, origin=np.zeros(3))
    before = RansacPlanes(options).run(cloud, StageContext(seed=0))
    assert not before.keep[~on_roof].all()                       # the plain reference took street
    after = RansacPlanes({**options, "ground_slope": 0.15}).run(cloud, StageContext(seed=0))
    assert after.keep[~on_roof].all() and not after.keep[on_roof].any()


def test_a_street_on_a_hillside_stays_ground_by_its_outline_and_a_roof_still_goes():
    """A street cut into a hillside: a bank falls 6 m within 9 m below it and a retaining wall
    rises 2.8 m above it, so the lowest point of the 3 x 3 reference cells lies down the bank and
    the street's plane stands ~5 m over it, removed as XY (roof) even with the sloped reference.
    A roof's outline drops a storey all round; the street's goes on at grade or up the wall along
    its uphill side: with at_grade_share 0.5 the street stays and a flat roof 6 m up still goes,
    its rooftop unit (a hole in its plane) no outline."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.planes import RansacPlanes

    rng = np.random.default_rng(21)
    n = 120_000
    xy = rng.random((n, 2)) * [100.0, 60.0]
    y = xy[:, 1]
    # the bank below (y < 20) falls 6 m over 9 m, the street (20-27) is level across, the wall
    # at 27 rises 2.8 m, then the slope climbs at 30 %
    z = np.where(y < 11, -6.0 + 0.05 * (y - 11), np.where(y < 20, -6.0 + (y - 11) * 6.0 / 9.0, 0.0))
    z = np.where(y >= 27, 2.8 + 0.3 * (y - 27), z)
    z = z + rng.normal(0, 0.02, n)
    street = (y >= 20) & (y < 27)
    ground = np.column_stack([xy, z])
    # a flat-roofed building of 14 x 14 m on the bank's foot, 6 m up, with a rooftop unit
    inside = (xy[:, 0] > 70) & (xy[:, 0] < 84) & (y > 0) & (y < 9)
    ground = ground[~inside]
    street = street[~inside]
    roof = np.column_stack([70 + rng.random(12_000) * 14, rng.random(12_000) * 9, np.full(12_000, -6.0 + 6.0)])
    unit = (np.abs(roof[:, 0] - 77) < 1.5) & (np.abs(roof[:, 1] - 4.5) < 1.5)
    roof[unit, 2] += 1.2
    roof[:, 2] += rng.normal(0, 0.02, len(roof))
    xyz = np.concatenate([ground, roof]).astype(np.float32)
    on_roof = np.r_[np.zeros(len(ground), bool), ~unit]
    on_street = np.r_[street, np.zeros(len(roof), bool)]
    options = {"distance_threshold": 0.1, "min_inliers": 500, "max_planes": 4, "dh_max": 2.5,
               "ground_cell": 10.0, "xy_removal": "part", "ground_slope": 0.15}
    cloud = Cloud(xyz=xyz, origin=np.zeros(3))
    before = RansacPlanes(options).run(cloud, StageContext(seed=0))
    assert before.keep[on_street].mean() < 0.5                   # the street went as a roof
    after = RansacPlanes({**options, "at_grade_share": 0.5}).run(cloud, StageContext(seed=0))
    assert after.keep[on_street].mean() > 0.98
    assert after.keep[on_roof].mean() < 0.02
