"""Roofs of denser surveys and of hilly towns (issue 16: held-out tiles of other densities and
terrain): configs/roof_als.yaml on one layout at the matrix's 15 points/m2 and at 80, the two
density-following pieces behind it (the low-and-rough test's planar bound, spacings after
downsampling), and a town on a 30 % grade."""
from __future__ import annotations

import logging

import numpy as np
import pytest

from roadx_ti import config, metrics, pipelines, synthetic
from roadx_ti.stages import stage_class
from roadx_ti.stages.base import ESTIMATES, SAMPLED_SHARE, StageContext, survey_spacing
from roadx_ti.stages.roof_filter import low_planar_bound
from tests.conftest import REPO, switch_backend


def _kappa(cloud) -> float:
    cfg = config.load(REPO / "configs" / "roof_als.yaml")
    result = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=cfg.seed))
    return metrics.scores(cloud.classification == 6, result.classification == 6)["kappa"]


@pytest.mark.slow
def test_dense_survey_finds_the_roofs_of_a_sparse_one():
    """One block of als-roof seed 0 at 15 and at 80 points/m2 (3 cm height noise). Measured at
    the commit that added the downsampling and the planar bound: 0.9751 / 0.9776; before them
    0.9751 / 0.8572 (at 80 points/m2 the seeds' curvature over 10 neighbours is mostly noise: low
    houses were dropped as hedges, roof parts lost their seeds)."""
    switch_backend("cpu")
    sparse = _kappa(synthetic.generate("als-roof", 150_000, seed=0, density=15.0))
    dense = _kappa(synthetic.generate("als-roof", 800_000, seed=0, density=80.0))
    assert dense >= 0.95, (sparse, dense)
    assert dense >= sparse - 0.02, (sparse, dense)


def _ctx(seed_curvatures, others=(), curvature_max=0.02):
    curvature = np.array(list(seed_curvatures) + list(others), np.float32)
    seed = np.array([1] * len(seed_curvatures) + [0] * len(others), np.uint8)
    return StageContext(log=logging.getLogger("test"), point_data={"roof_seed": seed, "curvature": curvature},
                        facts={"roof_curvature_max": curvature_max})


def test_low_planar_bound_is_a_quarter_of_c_t_unless_the_seeds_are_rougher():
    # seeds smoother than c_t / 4 (the real tiles at hand: medians 0.0002-0.0047): the fixed bound
    assert low_planar_bound(_ctx([0.001, 0.002, 0.003], others=[0.2, 0.3])) == pytest.approx(0.005)
    # rougher seeds (dense or noisy data): their median; points that are not seeds do not count
    assert low_planar_bound(_ctx([0.006, 0.008, 0.012], others=[0.0, 0.0, 0.0, 0.0])) == pytest.approx(0.008)
    assert low_planar_bound(_ctx([], others=[0.5])) == pytest.approx(0.005)      # no seeds
    assert low_planar_bound(_ctx([0.02], curvature_max=0.08)) == pytest.approx(0.02)


def test_spacings_follow_the_share_downsampling_keeps():
    ctx = StageContext(facts={ESTIMATES: {"point_spacing_m": 0.1, "pulse_spacing_m": 0.2}})
    assert survey_spacing(ctx) == pytest.approx(0.2)           # pulse spacing where measured
    ctx.facts[SAMPLED_SHARE] = 0.25                            # a quarter of the points kept
    assert survey_spacing(ctx) == pytest.approx(0.4)
    assert survey_spacing(StageContext()) is None


def test_roof_downsampling_keeps_sparser_surveys_whole_and_thins_denser_ones():
    """configs/roof_als.yaml's first stage: a survey at 15 points/m2 runs on every point (the
    pipeline's results there unchanged), one at 80 on about 30 per m2, and the sampled share
    is what later stages' spacings use."""
    switch_backend("cpu")
    cfg = config.load(REPO / "configs" / "roof_als.yaml")
    name, options = cfg.stage_list()[0]
    assert name == "uniform_downsample" and options.target_density == 30
    stage = pipelines.build_stages(cfg.stage_list()[:1])[0]
    for per_m2, share in ((15.0, 1.0), (80.0, 30.0 / 80.0)):
        cloud = synthetic.generate("als-roof", 20_000, seed=1, density=per_m2)
        ctx = StageContext(facts={ESTIMATES: {"density_per_m2": per_m2}})
        kept = stage.run(cloud, ctx).keep
        assert abs(kept.mean() - share) < 0.02, (per_m2, kept.mean())
        assert ctx.facts.get(SAMPLED_SHARE, 1.0) == pytest.approx(share)


def test_a_second_run_with_the_same_context_starts_on_every_point():
    """The sampled share belongs to one run: a context handed to a second run (the embedding API
    allows it; its survey estimates are reused) does not compound the downsampling's share."""
    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 40_000, seed=1)       # 4 points/m2: one 100 m block
    options = stage_class("uniform_downsample").Options(target_density=2, pattern="hashed")
    stages = pipelines.build_stages([("uniform_downsample", options)])
    ctx = StageContext()
    first = pipelines.run(cloud, stages, ctx=ctx)
    share = ctx.facts[SAMPLED_SHARE]
    second = pipelines.run(cloud, stages, ctx=ctx)
    assert ctx.facts[SAMPLED_SHARE] == pytest.approx(share)
    np.testing.assert_array_equal(first.processed, second.processed)


@pytest.mark.slow
@pytest.mark.parametrize("grade", [0.3, 0.4])
def test_roofs_of_a_town_on_a_hillside(grade):
    """The matrix's 300 k seed 0 tilted to a 30 / 40 % grade (accuracy.tilted): configs/roof_als.yaml's
    cloth (slope_smooth, rigidness auto: 1 on this terrain) follows the hillside. Measured: 0.9746
    flat; 0.9735 / 0.9643 tilted; with the rigid cloth (rigidness 3) and slope_smooth 0.9528 /
    0.3794, and at 30 % without slope_smooth 0.6756 (planar hillside the cloth stayed off became
    roof)."""
    from roadx_ti.accuracy import tilted

    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 300_000, seed=0)
    flat, hillside = _kappa(cloud), _kappa(tilted(cloud, grade))
    assert hillside >= 0.95, (flat, hillside)
    assert hillside >= flat - 0.02, (flat, hillside)


def test_cloth_rigidness_auto_follows_the_terrain_grade():
    from roadx_ti.stages.cloth import ClothOptions, rigidness_for

    auto = ClothOptions(rigidness="auto", steep_grade=0.15)
    assert rigidness_for(auto, StageContext(facts={ESTIMATES: {"terrain_grade": 0.02}})) == 3
    assert rigidness_for(auto, StageContext(facts={ESTIMATES: {"terrain_grade": 0.3}})) == 1
    assert rigidness_for(auto, StageContext()) == 3                  # not measured: the urban setting
    assert rigidness_for(ClothOptions(rigidness=2), StageContext(facts={ESTIMATES: {"terrain_grade": 0.3}})) == 2
    with pytest.raises(ValueError):
        ClothOptions(rigidness=4)


@pytest.mark.slow
def test_a_noisier_sensor_keeps_its_low_houses():
    """The matrix's 300 k seed 2 with 4 cm more height noise (about 5 cm in all): every roof loses
    planar points, so the low-and-rough test's share follows the survey's kept high roofs
    (roof_filter.low_planar_reference). Measured: 0.9699 as delivered, 0.9685 noisy; 0.9221 with
    the fixed 15 % (low houses dropped as hedges)."""
    from dataclasses import replace

    switch_backend("cpu")
    cloud = synthetic.generate("als-roof", 300_000, seed=2)
    xyz = cloud.xyz.copy()
    xyz[:, 2] += np.random.default_rng(5).normal(0, 0.04, cloud.n).astype(np.float32)
    assert _kappa(replace(cloud, xyz=xyz)) >= 0.96
