"""Work and memory bounded by the points, never by their extent (issue 18).

A cloud with a few stray points kilometres away must be processed as fast as the cloud without
them, its other points labelled exactly as without them: the isolation helper (parts of a cloud),
the kNN grid's cell size, the grid minima (dense vs sparse cells), the RANSAC ground reference, the
footprint grid (dense vs blocks), SOR, downsampling and the cloth. The CLI runs of the three
pipelines on such inputs are cases of tests/test_bad_inputs.py.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from roadx_ti import isolation
from roadx_ti.cloud import Cloud
from roadx_ti.errors import DataError
from roadx_ti.stages.base import StageContext
from tests.conftest import REPO

STRAYS = np.array([[20_000.0, 3.0, 0.5], [5.0, -20_000.0, -400.0]], np.float32)


def ground_points(n, seed=0, side=40.0):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, side, (n, 2))
    z = 0.1 * np.sin(xy[:, 0] / 3) + 0.02 * xy[:, 1] + rng.normal(0, 0.02, n)
    return np.column_stack([xy, z]).astype(np.float32)


def with_strays(xyz):
    """xyz with STRAYS inserted at a third and two thirds; returns (points, mask of the others)."""
    at = [len(xyz) // 3, 2 * len(xyz) // 3]
    out = np.insert(xyz, at, STRAYS, axis=0)
    others = np.ones(len(out), bool)
    others[np.array(at) + np.arange(2)] = False
    return out, others


# ------------------------------------------------------------------------------------ parts

def brute_parts(points, gap):
    """Reference: union of points closer than gap, checked against the part contract."""
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial.distance import cdist
    return connected_components(cdist(points, points) < gap, directed=False)[1]


@pytest.mark.parametrize("dense", [True, False])
def test_parts_contract(monkeypatch, dense):
    if not dense:
        monkeypatch.setattr(isolation, "DENSE_BLOCKS", 0)
    rng = np.random.default_rng(3)
    centres = rng.uniform(0, 5000, (12, 3)) * [1, 1, 0.1]
    pts = np.concatenate([c + rng.normal(0, 30, (40, 3)) for c in centres] + [rng.uniform(0, 5000, (30, 3))])
    p = isolation.parts(pts, 100.0)
    label = p.label
    assert label is not None and p.count > 1 and p.sizes.sum() == len(pts)
    close = brute_parts(pts, 100.0)
    # points closer than the gap share a part; points of different parts are at least gap apart
    for c in np.unique(close):
        assert len(np.unique(label[close == c])) == 1
    from scipy.spatial.distance import cdist
    d = cdist(pts, pts)
    assert (d[label[:, None] != label[None, :]] >= 100.0).all()
    assert np.array_equal(np.unique(label, return_index=True)[1], np.sort(np.unique(label, return_index=True)[1]))
    assert [int(m[0]) for m in p.members()] == sorted(int(m[0]) for m in p.members())


def test_dense_and_sparse_parts_agree(monkeypatch):
    rng = np.random.default_rng(5)
    pts = np.concatenate([rng.uniform(0, 900, (3000, 3)) * [1, 1, 0.05], STRAYS.astype(np.float64) * 0.01])
    dense = isolation.parts(pts, 50.0)
    monkeypatch.setattr(isolation, "DENSE_BLOCKS", 0)
    sparse = isolation.parts(pts, 50.0)
    assert dense.count == sparse.count
    assert np.array_equal(dense.label, sparse.label)


def test_isolated_points_and_origin():
    xyz, others = with_strays(ground_points(5000))
    far = isolation.isolated(xyz, isolation.SMALL_PART)
    assert np.array_equal(far, ~others)
    assert isolation.isolated(ground_points(5000), isolation.SMALL_PART) is None
    # no part larger than the limit: nothing is isolated (a small cloud is not isolated from itself)
    assert isolation.isolated(STRAYS, 5) is None
    world = xyz.astype(np.float64) + [600_000.0, 5_000_000.0, 100.0]
    assert np.array_equal(isolation.local_origin(world), np.floor(world[others].min(axis=0)))
    cloud = Cloud.from_world(world)
    assert np.array_equal(cloud.origin, np.floor(world[others].min(axis=0)))


# ------------------------------------------------------------------------------- kNN grid

def test_knn_with_strays_is_fast_and_unchanged():
    from roadx_ti.kernels.neighbors import knn
    xyz = ground_points(100_000, side=100.0)
    stray_xyz, others = with_strays(xyz)
    knn(xyz[:2000], 10)                                   # compile outside the timing
    t0 = time.perf_counter()
    plain_idx, plain_d = knn(xyz, 10)
    plain_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    idx, d = knn(stray_xyz, 10)
    stray_s = time.perf_counter() - t0
    remap = np.flatnonzero(others)          # stray-cloud index of every plain point
    np.testing.assert_array_equal(idx[others], remap[plain_idx])
    np.testing.assert_array_equal(d[others], plain_d)
    # before: cells sized by the 20 km box held every point (about 40 s at 300 k points here)
    assert stray_s < 10 * plain_s + 2.0, (stray_s, plain_s)


# ------------------------------------------------------------------------------- grid minima

def test_sparse_cell_minimum_equals_dense():
    from roadx_ti.kernels import grid_min
    xyz = ground_points(20_000, seed=1, side=30.0)
    xyz[:40, 2] += 3.0
    cell, lowest, n_cols = grid_min.cell_minimum(xyz, 0.5)
    s_cell, s_lowest, col_row = grid_min.sparse_cell_minimum(xyz, 0.5)
    np.testing.assert_array_equal(s_lowest[s_cell], lowest[cell])
    occupied = np.flatnonzero(lowest >= 0)
    np.testing.assert_array_equal(col_row[:, 0] * 10**9 + col_row[:, 1],
                                  np.sort((occupied % n_cols) * 10**9 + occupied // n_cols))
    # with the strays the dense grid would be 80000 x 80000 cells: the sparse one is used, and every
    # other point keeps its cell's lowest point and its keep flag
    # with the strays the dense grid would be 80000 x 80000 cells: the stage uses sparse cells
    # from the others' corner, and every other point keeps its keep flag and height
    from roadx_ti.stages.grid_slope import GridSlope
    stray_xyz, others = with_strays(xyz)
    assert not grid_min.dense_fits(stray_xyz, 0.5)
    stage = GridSlope({"step": 0.5, "slope_max": 0.1, "dh_max": 1.0})
    plain = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext())
    got = stage.run(Cloud(xyz=stray_xyz, origin=np.zeros(3)), StageContext())
    np.testing.assert_array_equal(got.keep[others], plain.keep)
    np.testing.assert_array_equal(got.point_data["height_above_cell_min"][others],
                                  plain.point_data["height_above_cell_min"])
    assert got.keep[~others].all()          # alone in its cell: its own minimum


def test_ransac_ground_reference_dense_equals_sparse(monkeypatch):
    from roadx_ti.kernels import grid_min
    from roadx_ti.stages import planes
    xyz = ground_points(20_000, seed=2, side=120.0)
    xyz[::7, 2] += np.float32(4.0)
    dense = planes._height_above_local_minimum(xyz, 10.0)
    monkeypatch.setattr(grid_min, "DENSE_MIN_CELLS", 0)
    monkeypatch.setattr(grid_min, "DENSE_CELLS_PER_POINT", 0)
    sparse = planes._height_above_local_minimum(xyz, 10.0)
    np.testing.assert_array_equal(dense, sparse)
    monkeypatch.undo()
    stray_xyz, others = with_strays(xyz)
    np.testing.assert_array_equal(planes._height_above_local_minimum(stray_xyz, 10.0)[others], dense)


# --------------------------------------------------------------------------- footprint grid

def footprint_scene(seed=0, far=0.0):
    """Two flat roofs (segments 0, 1; a third one ``far`` m away when far > 0) with walls, ground,
    points under the roofs and above them; returns xyz, segment, off_surface_ok, eligible."""
    rng = np.random.default_rng(seed)
    parts, seg = [], []
    for s, (x0, y0) in enumerate([(0, 0), (30, 5)] + ([(far, far / 3)] if far else [])):
        roof = np.column_stack([rng.uniform(x0, x0 + 15, 1500), rng.uniform(y0, y0 + 10, 1500),
                                6.0 + rng.normal(0, 0.05, 1500)])
        wall = np.column_stack([np.full(200, x0 - 0.3), rng.uniform(y0, y0 + 10, 200), rng.uniform(1, 5.5, 200)])
        inner = np.column_stack([rng.uniform(x0 + 2, x0 + 13, 150), rng.uniform(y0 + 2, y0 + 8, 150),
                                 rng.uniform(2, 7, 150)])
        parts += [roof, wall, inner]
        seg += [np.full(1500, s), np.full(350, -1)]
    ground = np.column_stack([rng.uniform(-20, 70, 3000), rng.uniform(-20, 40, 3000), rng.normal(0, 0.05, 3000)])
    xyz = np.concatenate(parts + [ground]).astype(np.float32)
    segment = np.concatenate(seg + [np.full(3000, -1)]).astype(np.int32)
    ok = (rng.uniform(size=len(xyz)) > 0.3).astype(np.uint8)
    eligible = (xyz[:, 2] > 1.0).astype(np.uint8)
    return xyz, segment, ok, eligible


def test_footprint_blocks_equal_the_dense_grid(monkeypatch):
    from roadx_ti.kernels import seeds
    xyz, segment, ok, eligible = footprint_scene(far=3000.0)
    dense = seeds.attach_to_footprints(xyz, segment, ok, eligible, cell=1.0, inside_reach=3.0, wall_reach=1.0)
    assert (dense >= 0).sum() > (segment >= 0).sum() + 300        # walls and inner points joined
    monkeypatch.setattr(seeds, "FOOTPRINT_CELLS_PER_POINT", 0)
    monkeypatch.setattr(seeds, "FOOTPRINT_MIN_CELLS", 0)
    monkeypatch.setattr(seeds, "FOOTPRINT_BLOCK", 16)             # many blocks, roofs cut by blocks
    blocked = seeds.attach_to_footprints(xyz, segment, ok, eligible, cell=1.0, inside_reach=3.0, wall_reach=1.0)
    np.testing.assert_array_equal(blocked, dense)


# --------------------------------------------------------------------------------- stages

def test_sor_drops_strays_without_changing_the_others():
    from roadx_ti.stages.outliers import StatisticalOutlierRemoval
    xyz = ground_points(20_000)
    xyz[:30, 2] += 2.0                                 # real outliers the statistics must still find
    stray_xyz, others = with_strays(xyz)
    stage = StatisticalOutlierRemoval({"k": 20, "std_ratio": 2.0})
    plain = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext())
    strays = stage.run(Cloud(xyz=stray_xyz, origin=np.zeros(3)), StageContext())
    assert 30 <= (~plain.keep).sum() < 1000
    np.testing.assert_array_equal(strays.keep[others], plain.keep)
    assert not strays.keep[~others].any() and strays.info["isolated"] == 2


def test_uniform_downsampling_keeps_strays_and_samples_the_others_as_without():
    from roadx_ti.stages.downsample import UniformDownsample
    xyz = ground_points(9_999)
    stray_xyz, others = with_strays(xyz)
    stage = UniformDownsample({"ratio": 0.3})
    plain = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext())
    strays = stage.run(Cloud(xyz=stray_xyz, origin=np.zeros(3)), StageContext())
    np.testing.assert_array_equal(strays.keep[others], plain.keep)
    assert strays.keep[~others].all()


@pytest.mark.parametrize("stage_name", ["cloth_ground", "cloth_smooth"])
def test_cloth_over_occupied_space_only(stage_name):
    from roadx_ti.stages import stage_class
    xyz = ground_points(20_000)
    xyz[5000:5400, 2] += 6.0                            # something standing on the ground
    second = ground_points(3000, seed=9, side=20.0) + np.float32([3000.0, 0.0, 1.0])   # an area 3 km off
    stray_xyz, others = with_strays(np.concatenate([xyz, second]))
    stage = stage_class(stage_name)({"cloth_resolution": 1.0})
    t0 = time.perf_counter()
    plain = stage.run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext())
    plain_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    got = stage.run(Cloud(xyz=stray_xyz, origin=np.zeros(3)), StageContext())
    assert time.perf_counter() - t0 < 5 * plain_s + 2.0
    first = np.flatnonzero(others)[:len(xyz)]
    np.testing.assert_array_equal(got.keep[first], plain.keep)
    ground = ~got.keep if stage_name == "cloth_ground" else got.keep
    assert not ground[~others].any()                  # strays: no cloth under them, not ground
    assert ground[np.flatnonzero(others)[len(xyz):]].mean() > 0.9     # the far area got its own cloth
    assert got.info["parts"] == 2 and got.info["isolated"] == 2
    assert got.info["cloth_shape"] == plain.info["cloth_shape"]
    if stage_name == "cloth_ground":
        height = got.point_data["height_above_ground"]
        np.testing.assert_array_equal(height[first], plain.point_data["height_above_ground"])
        assert np.isnan(height[~others]).all()


def test_a_cloth_larger_than_its_points_justify_is_refused_in_one_line():
    from roadx_ti.stages.cloth import ClothGround
    rng = np.random.default_rng(0)
    # 4000 points along a 40 km diagonal, 10 m apart: one part, a 28 x 28 km bounding box
    t = np.sort(rng.uniform(0, 28_000, 4000))
    xyz = np.column_stack([t, t + rng.normal(0, 5, 4000), rng.normal(0, 0.1, 4000)]).astype(np.float32)
    with pytest.raises(DataError) as err:
        ClothGround({"cloth_resolution": 1.0}).run(Cloud(xyz=xyz, origin=np.zeros(3)), StageContext())
    message = str(err.value)
    assert "\n" not in message and "cloth_ground" in message
    assert "27983 x 27994 m" in message and "stages.cloth_ground.cloth_resolution" in message and "--tile-size" in message


# ----------------------------------------------------------------------------------- tiling

def test_plan_allocates_nothing_per_grid_cell():
    from roadx_ti import tiling
    # a header box of 10^6 km at 10 m tiles: 10^8 x 10^8 cells; only the two scanned ones are tiles
    files = [tiling.CatalogFile("a.las", (0.0, 0.0, 1e9, 1e9), 1000)]
    occupied = lambda f, grid: grid.key(np.array([0, grid.cols - 1]), np.array([0, grid.rows - 1]))  # noqa: E731
    plan = tiling.plan_tiles(files, 10.0, 5.0, scan=occupied)
    assert plan.grid.cols == plan.grid.rows == 10**8 + 1
    assert len(plan.tiles) == 2 and plan.tiles[1].core[0] == 1e9
    assert plan.describe()["x_edges"] is None                     # not listed: 10^8 grid lines
    assert list(plan.tile_index(np.array([5.0, 1e9 + 1, 500.0]), np.array([5.0, 1e9 + 1, 5.0]))) == [0, 1, -1]
    with pytest.raises(ValueError, match="larger --tile-size"):
        tiling.plan_tiles(files, 10.0, 5.0)                        # unscanned: refused, not allocated


def test_tiled_run_with_strays_tiles_only_occupied_space(tmp_path):
    import laspy

    from cli_helpers import bumpy_ground, write_las
    from roadx_ti import config, tiling
    cfg = config.from_mapping({"pipeline": "ground", "backend": "cpu",
                               "stages": [{"cloth_ground": {"cloth_resolution": 1.0}}]})
    plain_xyz = bumpy_ground(3000, side=40.0)
    stray_xyz, others = with_strays(plain_xyz - plain_xyz.min(axis=0))
    stray_xyz = stray_xyz + plain_xyz.min(axis=0)
    offset = np.floor(plain_xyz.min(axis=0))
    runs = {}
    for name, xyz in (("plain", plain_xyz), ("stray", stray_xyz)):
        src = write_las(tmp_path / f"{name}.laz", xyz, offset=offset)
        t0 = time.perf_counter()
        summary = tiling.run_catalog(cfg, [src], tmp_path / f"{name}_out.laz", tile_size=20.0, progress=False)
        runs[name] = (summary, time.perf_counter() - t0,
                      np.asarray(laspy.read(tmp_path / f"{name}_out.laz").classification))
    plain, stray = runs["plain"], runs["stray"]
    assert stray[0]["tiling"]["columns"] > 1000                    # the header box spans 20 km
    assert stray[0]["tiling"]["tiles"] <= plain[0]["tiling"]["tiles"] + 2   # occupied cores only
    assert stray[1] < 3 * plain[1] + 10
    assert (stray[2][others] == plain[2]).mean() >= 0.999
    assert (stray[2][~others] == 1).all()                          # alone in their tiles: not ground


def test_roof_pipeline_labels_the_others_as_without_strays():
    """The roof pipeline on a synthetic als-roof scene with three points 20-50 km off: every other
    point gets the label it gets without them (the non-ground density counted the strays' cells,
    and the covered test's and over-roof grids were anchored at their corner: 21 of 40,000 labels
    moved)."""
    from roadx_ti import config, pipelines, synthetic

    scene = synthetic.generate("als-roof", 40_000, seed=1)
    far = scene.xyz[:3].copy()
    far[:, 0] += np.array([20_000.0, 35_000.0, 50_000.0], np.float32)
    keep = np.concatenate([np.arange(scene.n), np.arange(3)])
    stray = scene.subset(keep)
    stray.xyz[scene.n:] = far
    cfg = config.load(REPO / "configs" / "roof_als.yaml")

    def labels(cloud):
        return pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()),
                             ctx=StageContext(seed=cfg.seed)).classification
    np.testing.assert_array_equal(labels(stray)[:scene.n], labels(scene))
