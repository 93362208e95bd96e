"""Raised plateaus (roadx_ti.plateaus): a flat roof wider than the cloth can span sinks the cloth
onto it and becomes ground; the roof pipeline puts it back under the terrain. Terrain that steps
(a terrace above a retaining wall, a cutting, a hill) must stay as the cloth left it."""
from __future__ import annotations

import numpy as np
import pytest

from roadx_ti import config, metrics, pipelines, plateaus
from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import StageContext
from tests.conftest import REPO, switch_backend

STEP, REACH = 2.0, 30.0


def _grid(rows=200, cols=260, slope=0.0):
    r, c = np.mgrid[0:rows, 0:cols].astype(np.float64)
    return r, c, (slope * c).astype(np.float32)


def _building(z, r, c, box, height, ring=2):
    """A flat roof over ``box`` (r0, r1, c0, c1) that the cloth sank onto: supported cells on the
    roof and on the terrain, none on the ``ring`` of cells under the cloth hanging from its eaves."""
    r0, r1, c0, c1 = box
    roof = (r >= r0) & (r < r1) & (c >= c0) & (c < c1)
    hang = (r >= r0 - ring) & (r < r1 + ring) & (c >= c0 - ring) & (c < c1 + ring) & ~roof
    z = z.copy()
    z[roof] = height
    return z, roof, hang


def test_a_sunk_flat_roof_is_lowered_to_the_sloping_terrain_around_it():
    r, c, terrain = _grid(slope=0.05)
    z, roof, hang = _building(terrain, r, c, (50, 150, 40, 210), 12.0 + 0.05 * 40)
    # the ring under the hanging cloth holds points (the roof's edge, walls), only no ground
    patched, found = plateaus.find(z, ~hang, 1.0, STEP, REACH, occupied=np.ones(z.shape, bool))
    assert len(found) == 1 and found[0].cells == roof.sum() and found[0].outline_share == 1.0
    # under the roof and the hanging ring the cloth now follows the terrain's plane
    np.testing.assert_allclose(patched[roof | hang], terrain[roof | hang], atol=1e-3)
    np.testing.assert_array_equal(patched[~(roof | hang)], z[~(roof | hang)])


@pytest.mark.parametrize("case", ["terrace", "cutting", "hill", "courtyard", "staircase"])
def test_terrain_that_steps_is_left_as_it_is(case):
    r, c, z = _grid()
    supported = np.ones(z.shape, bool)
    if case == "terrace":     # a third of the scene 4 m up behind a retaining wall, side to side
        z = np.where(c >= 170, 4.0, 0.0).astype(np.float32)
        supported[:, 169:171] = False
    elif case == "cutting":   # a road 6 m down in a 20 m cutting across the scene
        z = np.where((c >= 120) & (c < 140), -6.0, 0.0).astype(np.float32)
        supported[:, 119:121] = supported[:, 139:141] = False
    elif case == "hill":      # 20 m high, 120 m across: slopes join it to the plain
        z = (20.0 * np.exp(-((r - 100) ** 2 + (c - 130) ** 2) / (2 * 30.0 ** 2))).astype(np.float32)
    elif case == "staircase":  # terraces 2.5 m up every 12 m: the top one, at the survey's edge, steps
        # down on every side that has data beside it (measured: it was lowered, and taken for roof)
        z = (2.5 * (c // 12)).astype(np.float32)
        supported[:, 11::12] = False
    else:                     # a sunken courtyard: ground lower than all around it is not raised
        z, _, hang = _building(z, r, c, (80, 120, 100, 160), -3.0)
        supported &= ~hang
    patched, found = plateaus.find(z, supported, 1.0, STEP, REACH, occupied=np.ones(z.shape, bool))
    assert found == [] and patched is None


def test_a_roof_at_the_data_edge_is_not_judged_on_its_missing_side():
    """Most of the roof's outline has no ground beside it (the survey ends there): it is not
    a plateau for want of evidence (left as the cloth made it)."""
    r, c, terrain = _grid()
    z, roof, hang = _building(terrain, r, c, (0, 200, 0, 150), 12.0)
    patched, found = plateaus.find(z, ~hang, 1.0, STEP, REACH)
    assert found == [] and patched is None


@pytest.mark.slow
def test_the_roof_pipeline_keeps_a_roof_wider_than_the_cloth_spans():
    """A 250 x 150 m flat building, 12 m high, in a 400 m square of gently rolling terrain
    (4 points/m2, a few wall points). Before raised plateaus the cloth sank onto the roof: kappa
    0.035, 97.5 % of the roof classed ground (the 150 x 100 m building of the same scene: 0.9997)."""
    switch_backend("cpu")
    rng = np.random.default_rng(0)
    side, (bw, bh) = 400.0, (250.0, 150.0)
    n = int(side * side * 4)
    xy = rng.random((n, 2)) * side
    x0, y0 = (side - bw) / 2, (side - bh) / 2
    inside = (xy[:, 0] > x0) & (xy[:, 0] < x0 + bw) & (xy[:, 1] > y0) & (xy[:, 1] < y0 + bh)
    z = rng.normal(0, 0.03, n) + 0.5 * np.sin(xy[:, 0] / 50.0)
    z[inside] = 12.0 + rng.normal(0, 0.03, int(inside.sum()))
    m = 2000
    t, face, wz = rng.random(m), rng.integers(0, 4, m), rng.random(m) * 12
    wx = np.where(face < 2, x0 + t * bw, np.where(face == 2, x0, x0 + bw))
    wy = np.where(face >= 2, y0 + t * bh, np.where(face == 0, y0, y0 + bh))
    xyz = np.vstack([np.column_stack([xy, z]), np.column_stack([wx, wy, wz])]).astype(np.float32)
    truth = np.concatenate([inside, np.ones(m, bool)])
    cloud = Cloud(xyz=xyz, origin=np.array([500000.0, 5000000.0, 0.0]),
                  classification=np.where(truth, 6, 2).astype(np.uint8))
    cfg = config.load(REPO / "configs" / "roof_als.yaml")
    result = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0))
    cloth = next(row for row in result.stages if row["stage"] == "cloth_ground")
    assert cloth["info"]["raised_plateaus"] == 1
    kappa = metrics.scores(truth, result.classification == 6)["kappa"]
    assert kappa >= 0.99, kappa
    assert np.mean(result.classification[inside.nonzero()[0]] == 2) < 0.01
