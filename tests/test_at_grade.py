"""Terrain the cloth stays off is not roof (roof_filter's at-grade test): a railway or road
embankment, a dike with banks steeper than about 1:2, is a ridge too narrow for the cloth to
follow into in its inverted frame, so its crown and banks stand metres over the cloth, planar and
wide, like a roof. A roof stands on walls: its outline is its eaves, a storey over the ground; the
embankment meets the ground along its feet."""
from __future__ import annotations

import numpy as np
import pytest

from roadx_ti import config, metrics, pipelines
from roadx_ti.cloud import Cloud
from roadx_ti.stages.base import StageContext
from roadx_ti.stages.roof_filter import at_grade_shares
from tests.conftest import REPO, switch_backend


def test_at_grade_shares_read_the_outline():
    rng = np.random.default_rng(0)
    xy = rng.random((40_000, 2)) * 20.0
    # segment 0: a flat roof 6 m up (its outline too); segment 1: a bank rising from the ground
    segment = np.where(xy[:, 0] < 10, 0, 1).astype(np.int32)
    height = np.where(segment == 0, 6.0, 0.6 + 0.5 * (20.0 - xy[:, 0])).astype(np.float32)
    xyz = np.column_stack([xy, height]).astype(np.float32)
    normal_z = np.full(len(xy), 0.9, np.float32)
    share = at_grade_shares(segment, xyz, height, normal_z, 2, 1.0, 1.0)
    assert share[0] == 0.0
    assert 0.2 < share[1] < 0.4          # its low column of cells of the 4 sides' outline
    # walls (vertical points) do not count: a wall's foot is at grade
    assert at_grade_shares(segment, xyz, height, np.zeros(len(xy), np.float32), 2, 1.0, 1.0).tolist() == [0, 0]


def _embankment(top, height, bank, density=10.0, side=200.0, seed=0):
    rng = np.random.default_rng(seed)
    n = int(side * side * density)
    xy = rng.random((n, 2)) * side
    across = np.abs(xy[:, 1] - side / 2)
    z = np.clip(height - np.maximum(across - top / 2, 0) / bank, 0, None) + rng.normal(0, 0.03, n)
    house = (np.abs(xy[:, 0] - 50) < 6) & (np.abs(xy[:, 1] - 30) < 5)      # 12 x 10 m, 6 m high
    z[house] = 6 + rng.normal(0, 0.03, int(house.sum()))
    cloud = Cloud(xyz=np.column_stack([xy, z]).astype(np.float32), origin=np.array([500000.0, 5000000.0, 0.0]),
                  classification=np.where(house, 6, 2).astype(np.uint8))
    return cloud, house, across < top / 2 + height * bank


@pytest.mark.slow
@pytest.mark.parametrize("top, height, bank", [(10.0, 7.0, 1.5), (3.0, 5.0, 1.0)])
def test_an_embankment_is_not_a_roof(top, height, bank):
    """Measured when the test came: 0 of 61,915 / 25,931 embankment points taken as roof (before:
    55,829 / 22,855, the scene's kappa 0.035 / 0.088); the house stays whole."""
    switch_backend("cpu")
    cloud, house, embankment = _embankment(top, height, bank)
    cfg = config.load(REPO / "configs" / "roof_als.yaml")
    result = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0))
    roof = result.classification == 6
    assert roof[embankment].mean() < 0.01
    assert metrics.scores(house, roof)["kappa"] > 0.98
