"""The canonical point order (roadx_ti.ordering): the pipelines' results do not depend on the
order in which the input delivers its points."""
import numpy as np

from roadx_ti import config, pipelines, synthetic
from roadx_ti.cloud import Cloud
from roadx_ti.ordering import canonical_order
from roadx_ti.stages.base import StageContext
from tests.conftest import REPO


def _canonical(cloud):
    order = canonical_order(cloud)
    return cloud if order is None else cloud.subset(order)


def test_any_permutation_gives_the_same_sequence_ties_included():
    rng = np.random.default_rng(0)
    xyz = (rng.random((5000, 3)) * [30, 30, 2]).astype(np.float32)
    xyz[1000:1100] = xyz[:100]                    # exact duplicates in position ...
    rgb = rng.integers(0, 65535, (5000, 3)).astype(np.uint16)
    rgb[1000:1050] = rgb[:50]                     # ... some with the same colour too, told apart
    nir = rng.integers(0, 65535, 5000).astype(np.uint16)   # by their NIR or another dimension
    cloud = Cloud(xyz=xyz, origin=np.zeros(3), rgb=rgb, intensity=np.zeros(5000, np.uint16), nir=nir,
                  attributes={"gps_time": rng.random(5000)})
    first = _canonical(cloud)
    for seed in (1, 2):
        again = _canonical(cloud.subset(np.random.default_rng(seed).permutation(cloud.n)))
        np.testing.assert_array_equal(again.xyz, first.xyz)
        np.testing.assert_array_equal(again.rgb, first.rgb)          # ... ordered by their attributes
        np.testing.assert_array_equal(again.nir, first.nir)
        np.testing.assert_array_equal(again.attributes["gps_time"], first.attributes["gps_time"])
    assert canonical_order(first) is None                            # canonical stays canonical


def test_order_is_one_sort_by_block_x_y_z_and_attributes():
    # coordinates on a 1 cm lattice: many points share x, some x and y, a few all three
    rng = np.random.default_rng(3)
    n = 20000
    xyz = (np.round(rng.random((n, 3)) * [8, 8, 0.05], 2)).astype(np.float32)
    xyz[500:900] = xyz[:400]
    intensity = rng.integers(0, 3, n).astype(np.uint16)
    cloud = Cloud(xyz=xyz, origin=np.zeros(3), intensity=intensity)
    from roadx_ti.ordering import BLOCK, _sortable

    cell = np.floor(xyz[:, :2].astype(np.float64) / BLOCK).astype(np.int64)
    block = cell[:, 0] * (int(cell[:, 1].max()) + 1) + cell[:, 1]
    # the definition (module docstring): block, x, y, z, then attributes, then input order
    expected = np.lexsort((intensity, _sortable(xyz[:, 2]), _sortable(xyz[:, 1]), _sortable(xyz[:, 0]), block))
    np.testing.assert_array_equal(canonical_order(cloud), expected)


def test_road_and_roof_labels_do_not_depend_on_the_point_order():
    for kind, cfg_name, points in (("uav-road", "road_uav.yaml", 60_000), ("als-roof", "roof_als.yaml", 60_000)):
        scene = synthetic.generate(kind, points, seed=1)
        cfg = config.load(REPO / "configs" / cfg_name)
        perm = np.random.default_rng(7).permutation(scene.n)

        def labels(cloud):
            r = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=cfg.seed))
            return r.classification, r.segment_id >= 0
        cls, seg = labels(scene)
        cls_p, seg_p = labels(scene.subset(perm))
        assert (cls == 11).any() or (cls == 6).any()
        np.testing.assert_array_equal(cls_p, cls[perm], err_msg=kind)
        np.testing.assert_array_equal(seg_p, seg[perm], err_msg=kind)
