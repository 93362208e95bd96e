"""R1 uniform downsampling kernel against the formula of METHODS.md R1."""
import numpy as np
import pytest

from roadx_ti.kernels.common import as_ndarray
from roadx_ti.kernels.downsample import uniform_sample


@pytest.mark.parametrize("n, m", [(10, 3), (1000, 999), (1000, 1000), (12345, 100), (7, 0)])
def test_stride_matches_formula(ti_arch, n, m):
    xyz = np.random.default_rng(n).random((n, 3), dtype=np.float32)
    index, kept = uniform_sample(xyz, m)
    expected = (np.arange(m, dtype=np.int64) * n // max(m, 1)).astype(np.int32)
    np.testing.assert_array_equal(index, expected)
    np.testing.assert_array_equal(kept, xyz[expected])


def test_index_product_beyond_32_bits(ti_arch):
    # j * n exceeds 2^31 for n = 100 000 and j near m: the index must stay exact
    n, m = 100_000, 60_000
    xyz = np.zeros((n, 3), np.float32)
    xyz[:, 0] = np.arange(n)
    index, kept = uniform_sample(as_ndarray(xyz), m)
    expected = np.arange(m, dtype=np.int64) * n // m
    np.testing.assert_array_equal(index.to_numpy(), expected)
    np.testing.assert_array_equal(kept.to_numpy()[:, 0], expected.astype(np.float32))


def test_skipped_points_take_their_nearest_processed_points_result():
    """R1 label transfer: after a subsampling stage, every skipped point takes the class,
    deciding stage and segment of its nearest processed point (cKDTree as the reference)."""
    from scipy.spatial import cKDTree

    from roadx_ti import pipelines
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import Stage, StageResult
    from roadx_ti.stages.downsample import UniformDownsample

    class LabelByX(Stage):
        name = "label_by_x"

        def run(self, cloud, ctx):
            x = cloud.xyz[:, 0]
            labels = np.where(np.floor(x).astype(int) % 2 == 0, 11, 1).astype(np.uint8)
            return StageResult(labels=labels, segment_id=np.floor(x * 3).astype(np.int32))

    rng = np.random.default_rng(5)
    xyz = (rng.random((20000, 3)) * [20, 20, 1]).astype(np.float32)
    cloud = Cloud(xyz=xyz, origin=np.zeros(3))
    result = pipelines.run(cloud, [UniformDownsample({"ratio": 0.3}), LabelByX()])
    done, skipped = np.flatnonzero(result.processed), np.flatnonzero(~result.processed)
    assert 0 < len(done) < len(xyz)
    scale = np.array([1.0, 1.0, pipelines.TRANSFER_Z_SCALE])      # heights count TRANSFER_Z_SCALE x
    _, near = cKDTree(xyz[done].astype(np.float64) * scale).query(xyz[skipped].astype(np.float64) * scale, 1)
    donor = done[near]
    np.testing.assert_array_equal(result.classification[skipped], result.classification[donor])
    np.testing.assert_array_equal(result.segment_id[skipped], result.segment_id[donor])
    np.testing.assert_array_equal(result.decided_by[skipped], result.decided_by[donor])


@pytest.mark.parametrize("z_scale", [1.0, None])
def test_skipped_points_by_a_kerb_take_their_own_surfaces_result(monkeypatch, z_scale):
    """At a 12 cm kerb the processed point nearest in plan may lie on the other surface; with
    heights counted TRANSFER_Z_SCALE times every skipped point takes its own surface's label
    (plain 3D distance, z_scale 1, does not)."""
    from roadx_ti import pipelines
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import Stage, StageResult
    from roadx_ti.stages.downsample import UniformDownsample

    class LabelByHeight(Stage):
        name = "label_by_height"

        def run(self, cloud, ctx):
            return StageResult(labels=np.where(cloud.xyz[:, 2] < 0.06, 11, 1).astype(np.uint8))

    if z_scale is not None:
        monkeypatch.setattr(pipelines, "TRANSFER_Z_SCALE", z_scale)
    rng = np.random.default_rng(8)
    xy = rng.random((20000, 2)) * [20, 20] - [10, 0]
    z = np.where(xy[:, 0] < 0, 0.0, 0.12) + rng.normal(0, 0.005, len(xy))    # road | sidewalk
    cloud = Cloud(xyz=np.column_stack([xy, z]).astype(np.float32), origin=np.zeros(3))
    result = pipelines.run(cloud, [UniformDownsample({"ratio": 0.3}), LabelByHeight()])
    skipped = ~result.processed
    wrong = int(np.count_nonzero(skipped & (result.classification != np.where(xy[:, 0] < 0, 11, 1))))
    if z_scale is None:
        assert wrong == 0
    else:
        assert wrong > 0


def test_hashed_pattern_is_nested_order_free_and_keeps_its_share(ti_arch):
    from roadx_ti.kernels.downsample import hashed_sample
    from roadx_ti.stages.downsample import coordinate_cells

    rng = np.random.default_rng(3)
    xyz = (rng.random((50000, 3)) * [40, 40, 2]).astype(np.float32)
    origin = np.array([512000.0, 5403000.0, 100.0])
    cells = coordinate_cells(xyz, origin, 0.01)
    few, more = hashed_sample(cells, 0.2).astype(bool), hashed_sample(cells, 0.3).astype(bool)
    assert not (few & ~more).any()                      # a larger ratio keeps a superset
    for ratio, kept in ((0.2, few), (0.3, more)):       # a Bernoulli share: within 4 sigma
        assert abs(kept.mean() - ratio) < 4 * np.sqrt(ratio * (1 - ratio) / len(xyz))
    perm = rng.permutation(len(xyz))
    np.testing.assert_array_equal(hashed_sample(coordinate_cells(xyz[perm], origin, 0.01), 0.2).astype(bool),
                                  few[perm])


def test_hashed_pattern_keeps_the_same_points_at_another_origin_and_from_1mm_or_1cm_deliveries(ti_arch):
    from roadx_ti.kernels.downsample import hashed_sample
    from roadx_ti.stages.downsample import coordinate_cells

    rng = np.random.default_rng(4)
    world = np.array([512000.0, 5403000.0, 100.0]) + rng.random((40000, 3)) * [60, 60, 3]

    def kept(w, origin):
        return hashed_sample(coordinate_cells((w - origin).astype(np.float32), origin, 0.01), 0.25).astype(bool)
    exact = kept(world, np.floor(world.min(axis=0)))
    cm = np.round(world, 2)
    # the same cm-grid coordinates seen from two local origins: the same points
    np.testing.assert_array_equal(kept(cm, np.floor(cm.min(axis=0))), kept(cm, np.floor(cm.min(axis=0)) - [300, 20, 7]))
    # a 1 cm delivery keeps the points the exact coordinates keep, but for those within a quarter
    # millimetre of a cell boundary; a 1 mm delivery those within half a millimetre
    assert np.mean(kept(cm, np.floor(cm.min(axis=0))) == exact) > 0.97
    mm = np.round(world, 3)
    assert np.mean(kept(mm, np.floor(mm.min(axis=0))) == exact) > 0.97


def test_hashed_pattern_keeps_a_point_of_a_tiny_cloud():
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.downsample import UniformDownsample

    xyz = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]], np.float32)
    for ratio in (0.01, 0.05, 0.1):      # each point kept with this probability: often none
        keep = UniformDownsample({"ratio": ratio, "pattern": "hashed"}).run(
            Cloud(xyz=xyz, origin=np.zeros(3)), StageContext()).keep
        assert keep.sum() >= 1
