"""Records that repeat another's x, y and z (merged deliveries, a flight strip written twice, every
point copied): each would be its twin's nearest neighbour at 0 m, so spacing, height and colour
noise read 0 and every threshold derived from them collapsed (road with every point twice: 54 % of
the labels right against 98 %). The pipeline leaves repeats out and gives them their first's
labels; the estimates of a sample count the copies per position from the twins drawn together."""
from __future__ import annotations

import numpy as np
import pytest

from roadx_ti import config, pipelines, synthetic
from roadx_ti.estimates import copies_per_position, distinct_rows, measure
from tests.conftest import REPO, switch_backend


@pytest.mark.parametrize("kind, config_name, copies", [("uav-road", "road_uav.yaml", 2), ("als-roof", "roof_als.yaml", 3)])
def test_repeated_records_take_the_labels_of_their_first(kind, config_name, copies):
    from roadx_ti.stages.base import StageContext
    switch_backend("cpu")
    cloud = synthetic.generate(kind, 40_000, seed=3)
    cfg = config.load(REPO / "configs" / config_name)

    def run(c):
        return pipelines.run(c, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0))
    base = run(cloud)
    index = np.random.default_rng(1).permutation(np.repeat(np.arange(cloud.n), copies))
    result = run(cloud.subset(index))
    assert result.repeated == (copies - 1) * cloud.n
    np.testing.assert_array_equal(result.classification, base.classification[index])
    np.testing.assert_array_equal(result.decided_by, base.decided_by[index])
    assert set(result.extra_dims) == set(base.extra_dims)
    for name, values in base.extra_dims.items():        # the stages' point outputs too (NaN where unseen)
        np.testing.assert_array_equal(result.extra_dims[name], values[index], err_msg=name)
    for key in ("point_spacing_m", "height_noise_m", "colour_noise", "points"):
        assert result.estimates[key] == base.estimates[key], key


def test_repeats_carry_their_firsts_stage_outputs():
    """A stage's point outputs (Stage.writes: height_above_ground) are the first's for a repeat,
    not NaN as for a point no stage saw."""
    from roadx_ti.stages import stage_class
    from roadx_ti.stages.base import StageContext
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 20_000, seed=3)
    specs = [(name, stage_class(name).Options()) for name in ("cloth_ground", "height_above_ground")]
    base = pipelines.run(cloud, pipelines.build_stages(specs), ctx=StageContext(seed=0))
    index = np.random.default_rng(2).permutation(np.repeat(np.arange(cloud.n), 2))
    result = pipelines.run(cloud.subset(index), pipelines.build_stages(specs), ctx=StageContext(seed=0))
    values = base.extra_dims["height_above_ground"]
    assert np.isfinite(values).mean() > 0.2
    np.testing.assert_array_equal(result.extra_dims["height_above_ground"], values[index])


def test_copies_per_position_from_a_draw():
    assert copies_per_position(100, 100, 0.1) == 1.0
    assert copies_per_position(300, 100, 1.0) == 3.0
    rng = np.random.default_rng(0)
    for m in (2, 3, 5):
        for f in (0.01, 0.2, 0.7):
            positions = 200_000
            drawn = rng.binomial(m, f, positions)          # copies of each position drawn
            estimate = copies_per_position(int(drawn.sum()), int((drawn > 0).sum()), f)
            assert estimate == pytest.approx(m, rel=0.1), (m, f)


def test_estimates_of_a_sample_with_repeats():
    """A sample of a catalog (measure with survey_points) whose records repeat: the distinct points,
    their density and spacing as measured on the distinct cloud itself."""
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 400_000, seed=1)
    distinct = measure(cloud)
    copies = 3
    total = copies * cloud.n
    # a uniform draw of 20 % of the records of the cloud with every point three times
    drawn = np.random.default_rng(2).binomial(copies, 0.2, cloud.n)
    sample = cloud.subset(np.repeat(np.arange(cloud.n), drawn))
    got = measure(sample, survey_points=total, area=distinct["plan_area_m2"])
    assert got["copies_per_position"] == pytest.approx(copies, rel=0.05)
    assert got["distinct_points"] == pytest.approx(cloud.n, rel=0.05)
    assert got["distinct_density_per_m2"] == pytest.approx(distinct["density_per_m2"], rel=0.05)
    assert got["point_spacing_m"] == pytest.approx(distinct["point_spacing_m"], rel=0.05)
    assert got["height_noise_m"] == pytest.approx(distinct["height_noise_m"], rel=0.1)
    assert len(distinct_rows(sample.xyz)) == int((drawn > 0).sum())


def test_catalog_estimates_of_a_file_with_every_point_twice(tmp_path):
    """measure_catalog draws its sample by a hash of the coordinates: a position comes with all of
    its copies, so the copies are counted, not solved for as for records drawn alone (which read
    32 copies instead of 2 at a 5 % draw)."""
    import laspy

    from roadx_ti.estimates import measure_catalog
    from roadx_ti.tiling import catalog
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 300_000, seed=1)
    distinct = measure(cloud)
    world = cloud.world_xyz()
    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales = [0.001] * 3
    header.offsets = np.floor(world.min(axis=0))
    las = laspy.LasData(header)
    twice = np.repeat(world, 2, axis=0)
    las.x, las.y, las.z = twice[:, 0], twice[:, 1], twice[:, 2]
    path = tmp_path / "twice.las"
    las.write(path)
    got = measure_catalog(catalog([path]), np.floor(world.min(axis=0)), sample_points=30_000)
    assert got["copies_per_position"] == pytest.approx(2.0, rel=0.02)
    assert got["distinct_points"] == pytest.approx(cloud.n, rel=0.02)
    assert got["point_spacing_m"] == pytest.approx(distinct["point_spacing_m"], rel=0.1)


def _with_near_copies(cloud, shifts):
    """``cloud`` followed by a copy of every point per (dx, dy) shift in metres (an overlap
    written twice after a re-projection: each point's nearest neighbour its own copy)."""
    n = cloud.n
    out = cloud.subset(np.tile(np.arange(n), len(shifts) + 1))
    xyz = np.array(out.xyz)
    for copy, (dx, dy) in enumerate(shifts, start=1):
        xyz[copy * n:(copy + 1) * n, :2] += np.float32([dx, dy])
    out.xyz = xyz
    return out


@pytest.mark.parametrize("shifts", [[(0.01, 0.0)], [(0.01, 0.0), (0.0, 0.001)]], ids=["twice_1cm", "thrice_1cm_1mm"])
def test_near_copies_do_not_set_the_spacing(shifts):
    """Copies 1 cm / 1 mm off their points (not repeats: their x differs) made the spacing their
    1 cm offset: 0.009 m for a survey of 0.126 m, and the roof pipeline found 55 % of the roofs."""
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 30_000, seed=5)
    alone = measure(cloud)
    copied = measure(_with_near_copies(cloud, shifts))
    assert copied["point_spacing_m"] == pytest.approx(alone["point_spacing_m"], rel=0.1)


def test_points_scattered_at_random_keep_their_nearest_neighbour():
    """About 4 % of points scattered at random have a neighbour five times closer than the next:
    below the share that says a survey holds copies, the spacing is the plain nearest neighbour's."""
    from roadx_ti.estimates import NEAR_COPY_NEIGHBOURS, nearest_past_copies
    from roadx_ti.kernels.neighbors import knn
    switch_backend("cpu")
    xy = np.random.default_rng(3).uniform(0, 100, (50_000, 2))
    flat = np.column_stack([xy, np.zeros(len(xy))]).astype(np.float32)
    distances = knn(flat, NEAR_COPY_NEIGHBOURS)[1]
    np.testing.assert_array_equal(nearest_past_copies(distances), distances[:, 0])
    twice = knn(np.concatenate([flat, flat + np.float32([0.005, 0, 0])]), NEAR_COPY_NEIGHBOURS)[1]
    assert np.median(nearest_past_copies(twice)) == pytest.approx(np.median(distances[:, 0]), rel=0.1)


def test_the_roof_pipeline_on_a_survey_holding_near_copies():
    """The roofs of a scene whose every point has a copy 1 cm off: those of the scene alone
    (the copies take part in the growing as the points of a denser survey would)."""
    from roadx_ti import metrics
    from roadx_ti.stages.base import StageContext
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 40_000, seed=5)
    cfg = config.load(REPO / "configs" / "roof_als.yaml")

    def kappa(c):
        result = pipelines.run(c, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0))
        truth = metrics.class_mask(c.classification, [6])
        return metrics.scores(truth, result.classification == 6)["kappa"]
    alone, copied = kappa(cloud), kappa(_with_near_copies(cloud, [(0.01, 0.0)]))
    assert alone > 0.9
    assert copied > alone - 0.03, (alone, copied)


def test_near_copies_of_a_survey_larger_than_the_sample():
    """A survey of more points than the estimates' sample: a uniform draw holds a copy with its
    twin rarely (at a 10 % draw the copies went unseen and the spacing read 0.075 m for 0.114 m);
    windows of every point count them."""
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 250_000, seed=6)
    alone = measure(cloud, sample_points=50_000)
    copied = measure(_with_near_copies(cloud, [(0.01, 0.0)]), sample_points=50_000)
    assert copied["point_spacing_m"] == pytest.approx(alone["point_spacing_m"], rel=0.1)
