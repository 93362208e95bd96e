"""Tiles with buffers over multi-file catalogs (in-process executor): every input point is written
exactly once, in input order, bit-exact; tiled labels match the untiled run; segments cut by tile
borders keep one id; a failing tile is reported by its bounds and nothing is written."""
from __future__ import annotations

import json
import math
from pathlib import Path

import laspy
import numpy as np
import pytest

from roadx_ti import config, io, pipelines, synthetic, tiling
from conftest import switch_backend

REPO = Path(__file__).resolve().parents[1]


def ground_cfg():
    return config.load(REPO / "configs" / "ground.yaml", ["backend=cpu"])


def tile_files(shared_data) -> list[str]:
    return sorted(str(p) for p in (shared_data / "tiles").glob("*.laz"))


def records(paths) -> np.ndarray:
    """The raw point records of files, concatenated in order (independent reader: laspy)."""
    return np.concatenate([laspy.read(p).points.array for p in paths])


# ------------------------------------------------------------------------------- plan geometry

def test_every_point_has_exactly_one_core_and_windows_hold_their_neighbours():
    rng = np.random.default_rng(1)
    files = [tiling.CatalogFile("a.las", (1000.0, 2000.0, 1050.0, 2050.0), 10),
             tiling.CatalogFile("b.las", (1050.0, 2000.0, 1093.7, 2031.0), 10)]
    plan = tiling.plan_tiles(files, 7.3, 2.5)
    x = np.r_[rng.uniform(1000, 1093.7, 20000), plan.x_edges[1:-1], 1093.7, 1000.0]
    y = np.r_[rng.uniform(2000, 2050, 20000), np.full(len(plan.x_edges) - 2, 2031.0), 2050.0, 2000.0]
    x, y = x[(x <= 1050) | (y <= 2031)], y[(x <= 1050) | (y <= 2031)]
    owners = np.zeros(len(x), int)
    for t in plan.tiles:           # brute force over the half-open cores
        owners += tiling.tile._inside(x, y, t.core)
    assert np.all(owners == 1)
    index = plan.tile_index(x, y)
    assert np.all(index >= 0)
    for t in plan.tiles:
        assert np.array_equal(index == t.index, tiling.tile._inside(x, y, t.core))
        assert t.window == (t.core[0] - 2.5, t.core[1] - 2.5, t.core[2] + 2.5, t.core[3] + 2.5)
        near = {u.index for u in plan.tiles if u is not t and u.core[0] < t.window[2] and u.core[2] > t.window[0]
                and u.core[1] < t.window[3] and u.core[3] > t.window[1]}
        assert set(t.neighbours) == near
    # fixed origin: grid lines at multiples of the tile size
    assert np.allclose(plan.x_edges / 7.3, np.round(plan.x_edges / 7.3))


def _cells_of(x, y, cell=1.0):
    """estimates.CellCounts of world points (as measure_catalog counts them)."""
    from roadx_ti.estimates import CellCounts, _cell_keys

    keys, counts = np.unique(_cell_keys(np.column_stack([x, y]), cell), return_counts=True)
    return CellCounts.from_keys(keys, counts, cell)


def _occupied_scan(x, y):
    """plan_tiles' scan: the core cells the points occupy (what scan_cells reads from a file)."""
    def scan(f, grid):
        col, row = grid.cells(x, y)
        return np.unique(grid.key(col, row))
    return scan


def test_aligned_tiles_read_fewer_points_and_count_their_windows_exactly():
    """The default tiles are placed where the points are: two dense blocks that a grid anchored at
    multiples of the tile size cuts into slivers read far fewer window points on the aligned grid,
    no window over the cap; the planner's window counts equal the points the plan's windows hold."""
    from roadx_ti.tiling.plan import TILE_COST_POINTS, _window_points, align_tiles

    rng = np.random.default_rng(3)
    # two 250 x 230 m blocks, 5 m apart, starting 190 m past a multiple of 200 m (as the uav-road
    # survey lies on 200 m tiles), a stray point 3 km off
    blocks = [(500190.0, 4500190.0), (500445.0, 4500190.0)]
    x = np.concatenate([rng.uniform(bx, bx + 250.0, 60_000) for bx, _ in blocks] + [[503000.5]])
    y = np.concatenate([rng.uniform(by, by + 230.0, 60_000) for _, by in blocks] + [[4501000.5]])
    cells, buffer = _cells_of(x, y), 30.0
    files = [tiling.CatalogFile("a.laz", (x.min(), y.min(), x.max(), y.max()), len(x))]

    def read(size, anchor):
        plan = tiling.plan_tiles(files, size, buffer, scan=_occupied_scan(x, y), anchor=anchor)
        windows = [int(tiling.tile._inside(x, y, t.window).sum()) for t in plan.tiles]
        cores = sum(int(tiling.tile._inside(x, y, t.core).sum()) for t in plan.tiles)
        assert cores == len(x)           # every point in one core, whatever the anchor
        return plan, windows

    world, world_windows = read(200.0, (0.0, 0.0))
    size, anchor = align_tiles(cells, 200.0, buffer, window_cap=100_000)
    aligned, aligned_windows = read(size, anchor)
    # the planner's count is the plans' own (windows on whole 5 m cells: exact)
    for plan, windows in ((world, world_windows), (aligned, aligned_windows)):
        counted = _window_points(cells.ix, cells.iy, cells.counts, cells.cell, plan.tile_size,
                                 plan.grid.x0, plan.grid.y0, buffer)
        assert counted == (sum(windows), len(plan.tiles), max(windows))
    assert max(aligned_windows) <= 100_000
    assert sum(aligned_windows) + TILE_COST_POINTS * len(aligned.tiles) < \
        sum(world_windows) + TILE_COST_POINTS * len(world.tiles)
    assert sum(aligned_windows) < 0.8 * sum(world_windows)
    # a tighter cap: smaller windows, still within it
    small, small_anchor = align_tiles(cells, 200.0, buffer, window_cap=40_000)
    assert small < size
    assert _window_points(cells.ix, cells.iy, cells.counts, cells.cell, small, *small_anchor, buffer)[2] <= 40_000
    # the same cells give the same plan (deterministic); a cap no grid meets keeps the density's size
    assert align_tiles(cells, 200.0, buffer, window_cap=100_000) == (size, anchor)
    assert align_tiles(cells, 200.0, buffer, window_cap=10) == (200.0, (0.0, 0.0))


def test_default_buffer_follows_the_stages_reach():
    ground = config.load(REPO / "configs" / "ground.yaml").stage_list()
    assert tiling.default_buffer(ground)[0] == 30.0          # the cloth's least span (> 15 x 1 m)
    coarse = config.from_mapping({"pipeline": "ground", "stages": [{"cloth_ground": {"cloth_resolution": 3.0}}]})
    assert tiling.default_buffer(coarse.stage_list())[0] == 45.0   # 15 particles of 3 m
    road = pipelines.default_stage_specs("road")
    buffer, reach = tiling.default_buffer(road)
    assert buffer == max(reach.values()) == 30.0             # RANSAC ground cell, cloth span
    files = [tiling.CatalogFile("a.las", (0.0, 0.0, 100.0, 100.0), 200_000)]
    assert tiling.default_tile_size(files, target_points=2_000_000) == 320.0   # sqrt(2e6 / 20 /m2)


# ------------------------------------------------------------------------------ six real tiles

def test_default_tiles_are_as_large_as_the_memory_budget_allows(monkeypatch):
    """The default core: the largest whose window (core + buffer) fits the memory a tile may use,
    where the survey is densest, shared by the local workers, at most MAX_WINDOW_POINTS."""
    from cli_helpers import CONFIGS
    from roadx_ti import config, memory
    from roadx_ti.tiling.run import memory_tile_size

    cfg = config.load(CONFIGS / "road_uav.yaml")       # R1 keeps 60 points/m2
    files = [tiling.CatalogFile("a.laz", (0.0, 0.0, 5000.0, 5000.0), 200_000_000)]   # header box: 8 /m2
    survey, buffer = {"density_per_m2": 100.0}, 30.0

    def size(limit, workers=None, scheduler=None, files=files):
        monkeypatch.setenv(memory.LIMIT_VARIABLE, limit)
        return memory_tile_size(cfg, files, survey, buffer, workers, scheduler)

    def window_points(edge, density=100.0):
        return (edge + 2 * buffer) ** 2 * density

    def tile_bytes(points, density=100.0):
        kept = min(60.0 / density, 1.0)
        return memory.estimate("road", points * memory.TILE_OVERHEAD, kept) * memory.SAFETY

    small, shared, one, capped = size("3G"), size("6G", workers=2), size("6G"), size("96G")
    assert small == shared < one < capped
    for edge, limit in ((small, "3G"), (one, "6G")):     # the window fits, 10 m more would not
        budget = memory.parse_size(limit)
        assert tile_bytes(window_points(edge)) <= budget < tile_bytes(window_points(edge + tiling.TILE_SIZE_STEP))
    assert window_points(capped) <= tiling.MAX_WINDOW_POINTS < window_points(capped + tiling.TILE_SIZE_STEP)
    assert size("100M") ** 2 * 100.0 >= tiling.TARGET_TILE_POINTS      # never below a 2 M-point core
    # a dense file among sparse ones sizes the tiles: its windows must fit too
    dense = files + [tiling.CatalogFile("b.laz", (6000.0, 0.0, 6200.0, 200.0), 16_000_000)]   # 400 /m2
    edge = size("6G", files=dense)
    assert edge < one and tile_bytes(window_points(edge, 400.0), 400.0) <= memory.parse_size("6G")
    # a sparse survey (R1 keeps every point) gets smaller windows than its points alone would say
    survey["density_per_m2"] = 30.0
    sparse = size("6G", files=[tiling.CatalogFile("c.laz", (0.0, 0.0, 5000.0, 5000.0), 750_000_000)])
    assert tile_bytes(window_points(sparse, 30.0), 30.0) <= memory.parse_size("6G") \
        < tile_bytes(window_points(sparse + tiling.TILE_SIZE_STEP, 30.0), 30.0)
    survey["density_per_m2"] = 100.0
    # an existing cluster's workers: cores of about 2 M points at the header boxes' density
    assert size("96G", scheduler="tcp://host:8786") == tiling.default_tile_size(files)


@pytest.fixture(scope="module")
def six_runs(shared_data, tmp_path_factory):
    """Untiled and 40 m tiled ground runs over the six adjacent IGN tiles (a folder input); the
    40 m grid does not follow the 50 m files, so tiles read several files."""
    switch_backend("cpu")      # module scope: set up before conftest's per-test switch
    folder = shared_data / "tiles"
    out = tmp_path_factory.mktemp("six")
    cfg = ground_cfg()
    untiled = tiling.run_catalog(cfg, [folder], out / "untiled.laz", tile_size=math.inf, progress=False)
    tiled = tiling.run_catalog(cfg, [folder], out / "tiled.laz", tile_size=40.0, progress=False)
    return out, untiled, tiled


def test_six_tiles_every_point_once_in_input_order(shared_data, six_runs):
    out, untiled, tiled = six_runs
    paths = tile_files(shared_data)
    assert [i["path"] for i in tiled["inputs"]] == paths
    expected = records(paths)
    assert tiled["points"] == tiled["points_written"] == len(expected)
    got = laspy.read(out / "tiled.laz")
    for name in expected.dtype.names:     # every field bit-exact but the new classification
        if name != "classification":
            assert np.array_equal(got.points.array[name], expected[name]), name
    # cores partition the points: their counts add up to the catalog
    assert sum(t["points_core"] for t in tiled["tiles"]) == len(expected)
    assert tiled["tiling"]["tiles"] == len(tiled["tiles"]) > 6
    assert all(t["seconds"] >= t["pipeline_seconds"] >= 0 for t in tiled["tiles"])
    assert any(len(t["files"]) > 1 for t in tiled["tiles"])


def test_six_tiles_tiled_labels_equal_untiled(six_runs):
    out, untiled, tiled = six_runs
    cmp = tiling.compare_outputs(tiled, out / "tiled.laz", out / "untiled.laz",
                                 summary_path=out / "tiled.summary.json")
    assert cmp["points"] == tiled["points"]
    assert cmp["agreement"] >= 0.999, cmp
    assert sum(cmp["disagreements_by_border_distance_m"].values()) == cmp["disagreements"]
    saved = json.loads((out / "tiled.summary.json").read_text())
    assert saved["comparison"]["disagreements"] == cmp["disagreements"]
    # accuracy against the files' own ground class, from the streamed merge
    truth = np.isin(records(tile_files_from(tiled))["classification"], [2])
    pred = laspy.read(out / "tiled.laz").classification == 2
    assert tiled["accuracy"]["confusion"]["a"] == int((truth & pred).sum())


def tile_files_from(summary):
    return [i["path"] for i in summary["inputs"]]


def test_per_file_output_matches_the_merged_one(shared_data, six_runs, tmp_path):
    out, _, tiled = six_runs
    paths = tile_files(shared_data)
    summary = tiling.run_catalog(ground_cfg(), paths, tmp_path / "per_file", tile_size=40.0,
                                 output_mode="per-file", progress=False)
    assert summary["outputs"] == [str(tmp_path / "per_file" / Path(p).name) for p in paths]
    merged = laspy.read(out / "tiled.laz")
    start = 0
    for path, written in zip(paths, summary["outputs"]):
        src, got = laspy.read(path), laspy.read(written)
        n = len(src.points)
        assert np.array_equal(got.points.array["X"], src.points.array["X"])
        assert np.array_equal(got.points.array["gps_time"], src.points.array["gps_time"])
        assert np.array_equal(got.classification, merged.classification[start:start + n])
        assert np.array_equal(got["roadx_label"], merged["roadx_label"][start:start + n])
        start += n
    assert start == len(merged.points)
    assert (tmp_path / "per_file" / "summary.json").is_file()


# ------------------------------------------------------------------------------------ COPC

def test_copc_window_reads_only_the_nodes_it_meets(shared_data, tmp_path, monkeypatch):
    from copc_writer import write_copc
    src = tile_files(shared_data)[0]
    copc_path = tmp_path / "tile.copc.laz"
    write_copc(src, copc_path)
    whole = laspy.read(copc_path).points.array
    assert len(whole) == len(laspy.read(src).points)
    decompressed = []
    real = laspy.CopcReader._fetch_and_decompress_points_of_nodes

    def spy(self, nodes):
        points = real(self, nodes)
        decompressed.append(len(points))
        return points

    monkeypatch.setattr(laspy.CopcReader, "_fetch_and_decompress_points_of_nodes", spy)
    h = laspy.open(copc_path).header
    window = (h.mins[0] + 5.0, h.mins[1] + 5.0, h.mins[0] + 20.0, h.mins[1] + 20.0)
    got = io.read(copc_path, bounds=window)
    x, y = np.asarray(laspy.read(copc_path).x), np.asarray(laspy.read(copc_path).y)
    inside = (x >= window[0]) & (x < window[2]) & (y >= window[1]) & (y < window[3])
    assert 0 < inside.sum() < len(whole)
    assert np.array_equal(got.las.points.array, whole[inside])     # the window, in file order
    assert len(decompressed) == 1 and decompressed[0] < 0.7 * len(whole)   # not the whole file
    assert io.info(copc_path)["format"] == "copc"


def test_copc_catalog_labels_equal_the_laz_catalog(shared_data, tmp_path):
    from copc_writer import write_copc
    srcs = tile_files(shared_data)[:2]
    copcs = [tmp_path / f"{Path(p).stem}.copc.laz" for p in srcs]
    for s, d in zip(srcs, copcs):
        write_copc(s, d)
    cfg = config.from_mapping({"pipeline": "ground", "backend": "cpu",
                               "stages": [{"cloth_ground": {"cloth_resolution": 1.0}}]})
    a = tiling.run_catalog(cfg, copcs, tmp_path / "copc.laz", tile_size=40.0, progress=False)
    b = tiling.run_catalog(cfg, srcs, tmp_path / "laz.laz", tile_size=40.0, progress=False)
    got, ref = laspy.read(tmp_path / "copc.laz"), laspy.read(tmp_path / "laz.laz")
    assert a["points_written"] == b["points_written"] == len(records(srcs))
    # every COPC point once, in the COPC files' order
    assert np.array_equal(got.points.array["gps_time"], records(copcs)["gps_time"])

    def by_point(las):
        key = np.lexsort([np.asarray(las.points.array[f]) for f in ("gps_time", "Z", "Y", "X")])
        return np.asarray(las.classification)[key]
    assert np.array_equal(by_point(got), by_point(ref))


# --------------------------------------------------------------------- segments across borders

def test_reconciled_segment_ids_follow_shared_points_transitively():
    """Segments linked through shared points get one id, also through a third tile; the ids are
    compact, in order of first appearance (tiles in order, each tile's segments ascending); a
    tile with no segments keeps its -1s."""
    from types import SimpleNamespace as NS

    from roadx_ti.tiling.merge import reconcile_segments

    def tile(segments, seg_ids, buffer_in, core_in):
        return NS(segments=segments, parts={0: NS(segment_id=np.array(seg_ids, np.int32))},
                  buffer_in=buffer_in, core_in=core_in)
    i32 = lambda *v: np.array(v, np.int32)     # noqa: E731
    # buffer_in[u]: my ids of my buffer points in u's core; u's core_in[me]: u's ids of the same
    # points. Links: 0/2 = 1/0 (one of the two shared points unlabelled in tile 1); 1/1 = 2/0 = 0/1
    results = {
        0: tile(3, [2, 0, 1, -1, 2], buffer_in={1: i32(2, 2)}, core_in={1: i32(2), 2: i32(1)}),
        1: tile(2, [0, 1, 1], buffer_in={0: i32(0), 2: i32(1)}, core_in={0: i32(0, -1)}),
        2: tile(1, [0, 0], buffer_in={0: i32(0)}, core_in={1: i32(0)}),
        3: tile(0, [-1, -1], buffer_in={}, core_in={}),
    }
    info = reconcile_segments(NS(tiles=[0, 1, 2, 3]), results)
    assert info == {"local_segments": 6, "merges": 3, "segments": 3}
    ids = {t: results[t].parts[0].segment_id.tolist() for t in results}
    assert ids == {0: [2, 0, 1, -1, 2], 1: [2, 1, 1], 2: [1, 1], 3: [-1, -1]}


def test_segments_cut_by_tile_borders_keep_one_id(shared_data, tmp_path):
    """Roof segments (seeds + growing, no ground stage: cheap) over two files in 30 m tiles."""
    cfg = config.from_mapping({"pipeline": "roof", "backend": "cpu",
                               "stages": [{"roof_seeds": {}}, {"roof_growing": {}}]})
    paths = tile_files(shared_data)[:2]
    untiled = tiling.run_catalog(cfg, paths, tmp_path / "u.laz", tile_size=math.inf, progress=False)
    tiled = tiling.run_catalog(cfg, paths, tmp_path / "t.laz", tile_size=30.0, progress=False)
    cmp = tiling.compare_outputs(tiled, tmp_path / "t.laz", tmp_path / "u.laz")
    assert tiled["segments"]["merges"] > 0
    assert cmp["reference_segments_crossing_borders"] >= 10
    assert cmp["crossing_segments_kept_whole"] >= 0.9 * cmp["reference_segments_crossing_borders"], cmp
    assert cmp["segment_agreement"] >= 0.99, cmp
    seg = np.asarray(laspy.read(tmp_path / "t.laz")["segment_id"])
    ids = np.unique(seg[seg >= 0])
    assert np.array_equal(ids, np.arange(len(ids)))        # compact global ids
    assert len(ids) == tiled["segments"]["segments"]
    assert untiled["segments"]["merges"] == 0


# ------------------------------------------------------------------------ decode once (split)

def test_split_parts_read_back_as_the_windowed_read(shared_data):
    """Each file is decoded once for all tiles: a window's records read back give the Cloud a
    windowed read gives, field for field (overlapping windows, one meeting no point)."""
    path = tile_files(shared_data)[0]
    x0, y0, x1, y1 = io.read_headers([path])[0][1]
    xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
    windows = [(0, (x0 - 5, y0 - 5, xm + 3, ym + 3)), (1, (xm - 3, y0, x1 + 1, y1 + 1)),
               (2, (x1 + 10, y1 + 10, x1 + 20, y1 + 20))]
    got = {}
    io.split(path, windows, lambda key, rec: got.setdefault(key, []).append(rec.copy()))
    assert set(got) == {0, 1}
    origin = np.floor(np.array([x0, y0, 0.0]))
    for key, box in windows[:2]:
        want = io.read(path, bounds=box, origin=origin)
        part = io.read_part(path, np.concatenate(got[key]), origin)
        assert part.n == want.n > 0
        for name in ("xyz", "origin", "rgb", "intensity", "classification", "returns", "nir"):
            a, b = getattr(part, name), getattr(want, name)
            assert (a is None and b is None) or np.array_equal(a, b), name
        assert part.color_depth == want.color_depth
        assert np.array_equal(part.las.points.array, want.las.points.array)


def test_tiled_run_decodes_each_file_once_with_the_same_labels(shared_data, six_runs, tmp_path, monkeypatch):
    """The 40 m tiled run split its six files (each read by several tiles) and gives the labels
    of tiles that decode their files themselves; the scratch folder is gone after the run."""
    out, _, tiled = six_runs
    assert tiled["split"]["files"] == 6 and tiled["split"]["parts"] > 6 and tiled["split"]["bytes"] > 0
    assert not list(out.glob(tiling.split.FOLDER_PREFIX + "*"))
    decoded = []
    real = io.read

    def counting_read(path, **kw):
        decoded.append(path)
        return real(path, **kw)

    monkeypatch.setattr(tiling.run, "split_catalog", lambda *a, **k: tiling.split.Split(folder=None))
    monkeypatch.setattr(io, "read", counting_read)
    direct = tiling.run_catalog(ground_cfg(), [shared_data / "tiles"], tmp_path / "direct.laz", tile_size=40.0,
                                progress=False)
    assert direct["split"]["files"] == 0 and len(decoded) > 6     # each tile decoded its files
    a, b = laspy.read(out / "tiled.laz"), laspy.read(tmp_path / "direct.laz")
    assert np.array_equal(a.points.array, b.points.array)
    assert np.array_equal(a.segment_id, b.segment_id)


# ---------------------------------------------------------------------------- synthetic scene

@pytest.mark.parametrize("n_points", [4_000_000])
def test_synthetic_scene_every_point_once_and_labels_agree(tmp_path, n_points):
    """A synthetic ALS scene split into two files (ground pipeline, 100 m tiles, auto buffer)."""
    cloud = synthetic.generate("als-roof", n_points, 0)
    half = cloud.xyz[:, 0] < np.median(cloud.xyz[:, 0])
    paths = [tmp_path / "west.las", tmp_path / "east.las"]
    for p, part in zip(paths, (half, ~half)):
        io.write(p, cloud, classification=cloud.classification, subset=part)
    cfg = ground_cfg()
    untiled = tiling.run_catalog(cfg, paths, tmp_path / "u.las", tile_size=math.inf, progress=False)
    tiled = tiling.run_catalog(cfg, paths, tmp_path / "t.las", tile_size=100.0, progress=False)
    assert tiled["tiling"]["tiles"] >= 9
    expected = records(paths)
    got = laspy.read(tmp_path / "t.las").points.array
    assert len(got) == n_points and untiled["points_written"] == n_points
    for name in ("X", "Y", "Z", "intensity", "red"):
        assert np.array_equal(got[name], expected[name])
    cmp = tiling.compare_outputs(tiled, tmp_path / "t.las", tmp_path / "u.las",
                                 summary_path=tmp_path / "t.summary.json")
    # No seam: disagreements are not concentrated along the core borders (the 0-1 m band holds
    # about 4 % of the area of a 100 m core).
    near = cmp["disagreements_by_border_distance_m"]["0-1"]
    assert near <= 0.1 * max(cmp["disagreements"], 1), cmp
    # tiles and the whole run share the cloth's lattice and bands (cloth align_to_world) and its
    # start height (the survey's lowest point): from 0.989 to about 0.9999 here
    assert cmp["agreement"] >= 0.999, cmp


# ------------------------------------------------------------------------------------- failure

def test_failed_tile_is_reported_by_its_bounds_and_nothing_is_written(shared_data, tmp_path, monkeypatch):
    cfg = config.from_mapping({"pipeline": "ground", "backend": "cpu",
                               "stages": [{"grid_slope": {}}]})
    real = tiling.run_tile

    def flaky(job):
        if job.tile.index == 2:
            raise RuntimeError("disk on fire")
        return real(job)

    monkeypatch.setattr(tiling.executors, "run_tile", flaky)   # run_in_process's
    out = tmp_path / "out.laz"
    with pytest.raises(tiling.TileError, match=r"tile \(\d+, \d+\) with core bounds \(770[\d.]+, 6277[\d.]+, .*disk on fire"):
        tiling.run_catalog(cfg, [shared_data / "tiles"], out, tile_size=50.0, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_catalog_refuses_bad_inputs(tmp_path, shared_data):
    with pytest.raises(io.InputError, match="no point-cloud files"):
        tiling.catalog([tmp_path])
    one = tile_files(shared_data)[0]
    with pytest.raises(io.InputError, match="twice"):
        tiling.catalog([one, one])
    with pytest.raises(io.InputError, match="refusing to write over the input"):
        tiling.run_catalog(ground_cfg(), [one], one, progress=False)


def test_catalog_coordinate_systems_and_grids(tmp_path, caplog):
    """check_compatible: two horizontal CRSs refused; a compound CRS beside its own horizontal CRS (a tool
    dropped the vertical one) and a file without CRS warned of; scales that put points off the first
    file's grid warned of for a merged LAS/LAZ only (other formats are written in world coordinates),
    whole multiples and offsets whole steps apart not."""
    from rasterio.crs import CRS

    from cli_helpers import bumpy_ground, write_las
    from roadx_ti.tiling.catalogs import catalog, check_compatible

    def files(*specs):
        folder = tmp_path / f"c{len(list(tmp_path.iterdir()))}"
        folder.mkdir()
        for k, (crs, scale, offset) in enumerate(specs):
            write_las(folder / f"{k}.laz", bumpy_ground(200, seed=k) + [25.0 * k, 0, 0], scale=scale, offset=offset,
                      crs_wkt=None if crs is None else CRS.from_user_input(crs).to_wkt())
        return catalog(folder)

    with pytest.raises(io.InputError, match="different coordinate systems"):
        check_compatible(files(("EPSG:25832", 0.01, None), ("EPSG:2154", 0.01, None)), merged_las=True)
    caplog.clear()
    check_compatible(files(("EPSG:25832+5783", 0.01, None), ("EPSG:25832", 0.01, None)), merged_las=True)
    assert "the same horizontal CRS" in caplog.text
    caplog.clear()
    check_compatible(files(("EPSG:25832", 0.01, None), (None, 0.01, None)), merged_las=True)
    assert "name no coordinate system" in caplog.text
    fine = files((None, 0.001, [500000, 4500000, 0]), (None, 0.01, [500000.5, 4500000, 0]))
    caplog.clear()
    check_compatible(fine, merged_las=True)
    assert "other scales or offsets" not in caplog.text
    off_grid = files((None, 0.01, None), (None, 0.001, None))
    check_compatible(off_grid, merged_las=False)
    assert "other scales or offsets" not in caplog.text
    check_compatible(off_grid, merged_las=True)
    assert "other scales or offsets" in caplog.text
    # the merged file's header is the first file with a CRS (template_source): the first file's points
    # do not fit its 10 nm grid, which spans +-21 m of its offset (the checks took the first file's
    # grid, and the merge failed after every tile)
    fine_grid = files((None, 0.01, None), ("EPSG:25832", 1e-8, [500025, 4500000, 100]))
    with pytest.raises(io.InputError, match=r"0\.laz: its x coordinates .* with 1\.laz's scale 1e-08"):
        check_compatible(fine_grid, merged_las=True)


def test_a_warning_every_tile_repeats_is_logged_once(tmp_path, caplog):
    """The road pipeline on points without colour, in 9 tiles: road_regions' warning once, not per tile."""
    from cli_helpers import DEMO_FAST, bumpy_ground, write_las

    src = write_las(tmp_path / "grey.laz", bumpy_ground(3000, side=30.0))
    cfg = config.load(Path(__file__).resolve().parents[1] / "configs" / "demo.yaml",
                      ["backend=cpu"] + [a for a in DEMO_FAST if a != "--set"])
    caplog.set_level("WARNING", logger="roadx_ti")
    summary = tiling.run_catalog(cfg, [str(src)], tmp_path / "out.laz", tile_size=10.0, progress=False)
    assert len(summary["tiles"]) > 1
    assert caplog.text.count("no colour and no intensity") == 1


def test_scratch_folders_of_killed_runs_are_removed_and_no_other(tmp_path):
    """A run killed with SIGKILL leaves its split records (tens of MB per file); the next tiled
    run under the same folder removes those of dead processes on this host, never a running
    run's nor another host's (they stayed for good)."""
    import os
    import subprocess
    import sys

    from roadx_ti.io.atomic import host_tag
    from roadx_ti.tiling.split import FOLDER_PREFIX, remove_stale_folders
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    stale = tmp_path / f"{FOLDER_PREFIX}p{dead}-{host_tag()}-abc123"
    running = tmp_path / f"{FOLDER_PREFIX}p{os.getpid()}-{host_tag()}-def456"
    elsewhere = tmp_path / f"{FOLDER_PREFIX}p{dead}-otherhost-ghi789"
    for folder in (stale, running, elsewhere):
        folder.mkdir()
        (folder / "t0_f0.rec").write_bytes(b"\0" * 64)
    assert remove_stale_folders(tmp_path) == [stale]
    assert not stale.exists() and running.exists() and elsewhere.exists()



def test_an_empty_file_in_a_catalog_changes_nothing(tmp_path):
    """An empty LAS file among others: its default header box (0, 0, 0) - (0, 0, 0) no longer joins
    the catalog's extent (it put the shared origin millions of metres from the points: spacing
    estimates 0, 11 % of a roof run's labels changed, a DTM off by up to 0.64 m)."""
    from cli_helpers import bumpy_ground, write_las
    from roadx_ti.estimates import measure_catalog
    from roadx_ti.tiling.plan import catalog_origin, plan_tiles

    folder = tmp_path / "cat"
    folder.mkdir()
    write_las(folder / "a.las", bumpy_ground(3000))
    write_las(folder / "b.las", bumpy_ground(3000, seed=1) + [20.0, 0, 0])
    without = tiling.catalog([str(folder)])
    laspy.LasData(laspy.LasHeader(point_format=6, version="1.4")).write(folder / "c_empty.las")
    files = tiling.catalog([str(folder)])
    assert len(files) == 3 and min(f.count for f in files) == 0
    np.testing.assert_array_equal(catalog_origin(files), catalog_origin(without))
    assert catalog_origin(files)[0] > 499_000
    a, b = plan_tiles(files, 10.0, 5.0), plan_tiles(without, 10.0, 5.0)
    assert [t.core for t in a.tiles] == [t.core for t in b.tiles]
    switch_backend("cpu")
    spacing = measure_catalog(files, catalog_origin(files))["point_spacing_m"]
    assert spacing == measure_catalog(without, catalog_origin(without))["point_spacing_m"] and spacing > 0.05


def test_merged_output_takes_the_crs_of_the_files_that_name_one(tmp_path):
    """A catalog whose first file names no CRS and whose second does: the run takes the CRS for
    both, and so does the merged output's header (it copied the first file's: no CRS at all)."""
    from rasterio.crs import CRS

    from cli_helpers import bumpy_ground, write_las
    from roadx_ti.io.las_write import template_source

    a = write_las(tmp_path / "a.las", bumpy_ground(500))
    b = write_las(tmp_path / "b.las", bumpy_ground(500, seed=1) + [25.0, 0, 0], crs_wkt=CRS.from_epsg(32631).to_wkt())
    assert template_source([a, b]) == b and template_source([a]) == a


def test_tiled_text_output_of_las_files_carries_every_field_exactly(tmp_path):
    """A tiled run's merged CSV of LAS files: every LAS field as a column and the exact coordinates,
    as the untiled writer gives them (it held x, y, z from float32 offsets and the common columns)."""
    from cli_helpers import bumpy_ground, run_cli, write_las

    folder = tmp_path / "cat"
    folder.mkdir()
    for name, shift in (("a.las", 0.0), ("b.las", 20.0)):
        path = write_las(folder / name, bumpy_ground(1500, seed=int(shift)) + [shift, 0, 0], scale=0.001,
                         offset=np.array([500000.0, 4500000.0, 0.0]))
        las = laspy.read(path)
        las.gps_time = np.arange(len(las.points), dtype=np.float64) + 1e9 + shift
        las.write(path)
    proc = run_cli("run", str(Path(__file__).resolve().parents[1] / "configs" / "ground.yaml"), "--input", str(folder),
                   "--output", str(tmp_path / "t.csv"), "--tile-size", "10", "--backend", "cpu", "--quiet")
    assert proc.returncode == 0, proc.stderr
    table = np.genfromtxt(tmp_path / "t.csv", delimiter=",", names=True, comments=None, deletechars="")
    names = table.dtype.names
    assert "gps_time" in names and "point_source_id" in names
    both = [laspy.read(folder / n) for n in ("a.las", "b.las")]
    np.testing.assert_array_equal(table[names[0]], np.concatenate([np.asarray(x.x) for x in both]))
    np.testing.assert_array_equal(table["gps_time"], np.concatenate([np.asarray(x.gps_time) for x in both]))


@pytest.mark.parametrize("scale", [256, 257])
def test_a_window_of_8bit_and_16bit_files_reads_each_files_colour_as_alone(scale):
    """A window joining a file of raw 8-bit colour and one of 8-bit values stored x 256 (or x 257):
    the 8-bit file takes the other's scale, so every point reads its own 8-bit value (with x 257
    forced on the 8-bit file, the x 256 file had read 0.4 % darker in the joined window)."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.tiling.tile import concat_clouds

    rng = np.random.default_rng(0)
    values = rng.integers(0, 256, (2, 50, 3)).astype(np.uint16)
    xyz = rng.random((2, 50, 3)).astype(np.float32)
    origin = np.zeros(3)
    raw = Cloud(xyz=xyz[0], origin=origin, rgb=values[0], color_depth=8)
    wide = Cloud(xyz=xyz[1], origin=origin, rgb=values[1] * np.uint16(scale), color_depth=16)
    joined = concat_clouds([raw, wide], origin)
    assert np.array_equal(joined.rgb8(), np.concatenate([raw.rgb8(), wide.rgb8()]))
    assert np.array_equal(joined.rgb8(), np.concatenate(values).astype(np.float32))
