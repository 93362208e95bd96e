"""Region-level R6 kernels: filters against numpy, the edge list, and region merging equal to
its sequential reference (CPU and Vulkan)."""
from __future__ import annotations

import numpy as np
import pytest

from roadx_ti.kernels import regions
from roadx_ti.kernels.neighbors import knn
from tests.references import graph_edges_reference, merge_regions_reference


def _plane(n=3000, noise=0.01, seed=0, step=0.0):
    rng = np.random.default_rng(seed)
    xy = rng.random((n, 2)) * 20
    z = 0.02 * xy[:, 0] + 0.01 * xy[:, 1] + rng.normal(0, noise, n) + np.where(xy[:, 0] > 10, step, 0.0)
    return np.column_stack([xy, z]).astype(np.float32)


def test_neighbourhood_median_is_numpys(ti_arch):
    xyz = _plane(800)
    idx, _ = knn(xyz, 8)
    idx[::7, 3] = -1                                   # dropped entries are skipped
    values = np.random.default_rng(1).random((800, 3)).astype(np.float32) * 255
    got = regions.neighbourhood_median(values, idx)
    rows = [np.concatenate([[i], r[r >= 0]]) for i, r in enumerate(idx)]
    want = np.stack([np.median(values[r], axis=0) for r in rows]).astype(np.float32)
    assert np.allclose(got, want, atol=1e-4)


def test_mode_heights_keep_a_kerb_and_remove_noise(ti_arch):
    xyz = _plane(6000, noise=0.03, step=0.12)
    idx, dist = knn(xyz, 12)
    grad = regions.coarse_gradient(xyz, 2.5)
    grad[:] = (0.02, 0.01)                             # the true slope (cells straddling the kerb tilt)
    z = regions.mode_heights(xyz, idx, grad, 2.5 * 0.03)
    trend = 0.02 * xyz[:, 0] + 0.01 * xyz[:, 1]
    away = np.abs(xyz[:, 0] - 10) > 1.0
    residual = z - trend - np.where(xyz[:, 0] > 10, 0.12, 0.0)
    assert np.std(residual[away]) < 0.45 * 0.03        # noise drops ...
    near = (np.abs(xyz[:, 0] - 10) < 0.5) & (np.abs(xyz[:, 0] - 10) > 0.15)
    side = xyz[:, 0] > 10                              # ... and the step stays a step
    assert np.median(np.abs(residual[near])) < 0.03
    assert np.mean(np.abs(residual[near & side]) < 0.06) > 0.9



def test_mode_heights_take_one_window_per_point(ti_arch):
    """A window per point (noise that varies across a survey): the same heights as one window where
    all are equal; a point whose window is zero keeps its neighbourhood's median."""
    xyz = _plane(3000, noise=0.03, step=0.12)
    idx, _ = knn(xyz, 12)
    grad = regions.coarse_gradient(xyz, 2.5)
    one = regions.mode_heights(xyz, idx, grad, 0.075)
    assert np.array_equal(regions.mode_heights(xyz, idx, grad, np.full(len(xyz), 0.075, np.float32)), one)
    widths = np.full(len(xyz), 0.075, np.float32)
    widths[::2] = 0.0
    mixed = regions.mode_heights(xyz, idx, grad, widths)
    plain = regions.mode_heights(xyz, idx, grad, 0.075, steps=0)      # the neighbourhood medians
    assert np.array_equal(mixed[1::2], one[1::2])
    assert np.allclose(mixed[::2], plain[::2], atol=1e-6)


def test_block_spread_is_each_blocks_median_with_the_runs_value_for_small_blocks():
    from roadx_ti.stages.road_regions import MIN_BLOCK_EDGES, block_spread

    rng = np.random.default_rng(4)
    big = MIN_BLOCK_EDGES + 11
    values = np.concatenate([rng.normal(0, 0.02, big), rng.normal(0, 0.05, big), rng.normal(0, 1.0, 10)])
    block = np.concatenate([np.full(big, 7), np.full(big, -3), np.full(10, 5)]).astype(np.int64)
    order = rng.permutation(len(values))
    got = block_spread(values[order], block[order], 0.5, 2.0)
    for b, part in ((7, slice(0, big)), (-3, slice(big, 2 * big))):
        assert np.allclose(got[block[order] == b], 2.0 * np.median(np.abs(values[part])))
    assert np.all(got[block[order] == 5] == 0.5)       # too few edges: the run's value

def test_graph_edges_hold_each_undirected_edge_once():
    xyz = _plane(500)
    idx, dist = knn(xyz, 6)
    a, b = regions.graph_edges(idx, dist, np.inf)
    assert (a < b).all()
    pairs = set(zip(a.tolist(), b.tolist()))
    assert len(pairs) == len(a)
    want = {(min(i, j), max(i, j)) for i in range(500) for j in idx[i]}
    assert pairs == want


def test_graph_edges_equal_the_numpy_reference(ti_arch):
    # one-way neighbours, dropped entries, a length cap and a point far from the rest
    xyz = _plane(2000, seed=4)
    xyz[7] = (60.0, 60.0, 0.0)
    idx, dist = knn(xyz, 9)
    idx[::11, 2] = -1
    cap = float(np.median(dist[:, -1]))
    for limit in (cap, np.inf):
        a, b = regions.graph_edges(idx, dist, limit)
        want_a, want_b = graph_edges_reference(idx, dist, limit)
        assert a.dtype == np.int32 and b.dtype == np.int32
        assert np.array_equal(a, want_a) and np.array_equal(b, want_b)
    # a float64 limit between two float32 distances: the exact comparison
    d = np.unique(dist[dist > 0])[100:102].astype(np.float64)
    limit = float(d[0] + (d[1] - d[0]) / 3)
    assert np.array_equal(regions.graph_edges(idx, dist, limit)[1], graph_edges_reference(idx, dist, limit)[1])


def test_region_merging_is_the_same_whatever_the_edge_order():
    # graph_edges' sorted distinct list is used as it is in the first round, any other order goes
    # through the pair table; pairs the merges did not touch are carried between rounds
    n, a, b, up, down, colour = _merge_case(2, n=3000)
    args = ((1.5, 3.0, 6.0), 10.0, 0.1, 6)
    sorted_run = regions.merge_regions_by_colour(n, a, b, up, down, colour, *args)
    perm = np.random.default_rng(0).permutation(len(a))
    flipped = perm % 3 == 0                            # some edges (b, a), with their steps swapped
    ea, eb = np.where(flipped, b[perm], a[perm]), np.where(flipped, a[perm], b[perm])
    eu, ed = np.where(flipped, down[perm], up[perm]), np.where(flipped, up[perm], down[perm])
    shuffled = regions.merge_regions_by_colour(n, ea, eb, eu, ed, colour, *args)
    assert np.array_equal(sorted_run.label, shuffled.label)
    assert np.array_equal(sorted_run.colour_sum, shuffled.colour_sum)
    assert sorted_run.n_regions < n / 5


def test_final_pair_grouping_is_numpys_unique():
    # the region graph's pairs: a hash table in the kernels where 64-bit atomics are native
    keys = np.random.default_rng(3).integers(0, 5000, 200_000).astype(np.int64) * 7919
    keys[::5] = keys[0]                                # a heavy duplicate
    uk, inv = regions._group_keys(keys)
    want_uk, want_inv = np.unique(keys, return_inverse=True)
    assert np.array_equal(uk, want_uk) and np.array_equal(inv, want_inv.ravel())
    empty = regions._group_keys(np.zeros(0, np.int64))
    assert len(empty[0]) == 0 and len(empty[1]) == 0


def test_coarse_gradient_of_a_plane():
    xyz = _plane(5000, noise=0.0)
    g = regions.coarse_gradient(xyz, 2.5)
    assert np.allclose(g, (0.02, 0.01), atol=1e-4)


def _merge_case(seed, n=220):
    rng = np.random.default_rng(seed)
    xyz = _plane(n, seed=seed)
    idx, dist = knn(xyz, 6)
    a, b = regions.graph_edges(idx, dist, np.inf)
    # patches of colour with noise, quantised to 1/64 so that costs do not tie by rounding
    patch = (xyz[:, 0] // 7 + 3 * (xyz[:, 1] // 7)).astype(int)
    base = rng.random((patch.max() + 1, 3)) * 60 + 80
    colour = np.round((base[patch] + rng.normal(0, 1.5, (n, 3))) * 64) / 64
    steps = rng.random(len(a)) < 0.08
    up = np.where(steps & (rng.random(len(a)) < 0.5), 0.9, 0.0)
    down = np.where(steps & (up == 0), 0.9, 0.0)
    return n, a, b, up, down, colour.astype(np.float32)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_region_merging_equals_the_sequential_reference(ti_arch, seed):
    n, a, b, up, down, colour = _merge_case(seed)
    levels, chroma, veto, min_size = (2.0, 4.0, 8.0), 10.0, 0.1, 4
    graph = regions.merge_regions_by_colour(n, a, b, up, down, colour, levels, chroma, veto, min_size)
    ref = merge_regions_reference(n, a, b, up, down, colour, levels, chroma, veto, min_size)
    # the same partition: both labellings renumbered by first appearance
    def canonical(lab):
        _, first, inv = np.unique(lab, return_index=True, return_inverse=True)
        rank = np.empty(len(first), int)
        rank[np.argsort(first)] = np.arange(len(first))
        return rank[inv.ravel()]
    assert np.array_equal(canonical(graph.label), canonical(ref))
    assert graph.n_regions < n                         # something merged
    assert np.array_equal(graph.count, np.bincount(graph.label).astype(float))


@pytest.mark.parametrize("seed", [0, 3])
def test_region_merging_host_rounds_equal_the_kernel_rounds(seed):
    n, a, b, up, down, colour = _merge_case(seed, n=3000)
    args = (n, a, b, up, down, colour, (1.5, 3.0, 6.0), 10.0, 0.1, 6)
    device = regions.merge_regions_by_colour(*args, host=False)
    host = regions.merge_regions_by_colour(*args, host=True)
    assert np.array_equal(device.label, host.label)
    assert np.array_equal(device.count, host.count) and np.array_equal(device.colour_sum, host.colour_sum)
    assert device.n_regions < n / 5


# 2^10 / 2^12-slot tables: runs of the 128 partitions holding at most 716 / 2,867 of this graph's
# 18 k edges
@pytest.mark.parametrize("table_bits", [10, 12])
def test_region_merging_through_partition_tables_is_the_same(monkeypatch, table_bits):
    """The rounds re-key their pairs one run of hash partitions at a time when one table could
    exceed 2^MAX_TABLE_BITS slots, as many partitions in a run as the items re-keyed that round
    fill; tiny tables force many runs (and partitions larger than a table's share, whose table then
    grows) and must give the merge of one table and of the host rounds."""
    n, a, b, up, down, colour = _merge_case(1, n=3000)
    args = (n, a, b, up, down, colour, (1.5, 3.0, 6.0), 10.0, 0.1, 6)
    whole = regions.merge_regions_by_colour(*args, host=False)
    host = regions.merge_regions_by_colour(*args, host=True)
    monkeypatch.setattr(regions, "MAX_TABLE_BITS", table_bits)
    calls, runs = [], []
    real = regions._insert_pairs
    monkeypatch.setattr(regions, "_insert_pairs", lambda *a: (calls.append(a[7]), real(*a))[1])
    real_runs = regions._partition_runs
    monkeypatch.setattr(regions, "_partition_runs", lambda *a: (lambda r: (runs.append(len(r)), r)[1])(real_runs(*a)))
    parted = regions.merge_regions_by_colour(*args, host=False)
    assert max(calls) >= 2 and len(calls) > 20       # part_bits: partitions
    assert max(runs) >= 2 and min(runs) <= 1         # several runs in the first rounds, one later
    for other in (whole, host):
        assert np.array_equal(parted.label, other.label)
        assert np.array_equal(parted.count, other.count) and np.array_equal(parted.colour_sum, other.colour_sum)
        assert np.array_equal(parted.pa, other.pa) and np.array_equal(parted.edges, other.edges)


def test_region_merging_with_wide_step_sums_is_the_same(monkeypatch):
    """The rounds keep a pair list's step sums in int32 and switch that list to int64 when a sum
    would not fit (two regions sharing more than about 500 k edges); forcing the switch early
    (a limit of a few edges' steps) must give the same merge."""
    n, a, b, up, down, colour = _merge_case(1, n=3000)
    args = (n, a, b, up, down, colour, (1.5, 3.0, 6.0), 10.0, 0.1, 6)
    narrow = regions.merge_regions_by_colour(*args, host=False)
    monkeypatch.setattr(regions, "NARROW_STEPS_MAX", 3 * regions.STEP_SCALE)
    seen = []
    real = regions._compact_pairs
    monkeypatch.setattr(regions, "_compact_pairs", lambda *a: (seen.append(a[-1]), real(*a))[1])
    wide = regions.merge_regions_by_colour(*args, host=False)
    assert True in seen and False in seen          # both kinds of lists were made
    assert np.array_equal(wide.label, narrow.label) and np.array_equal(wide.count, narrow.count)
    assert np.array_equal(wide.pa, narrow.pa) and np.array_equal(wide.edges, narrow.edges)


@pytest.mark.parametrize("host", [False, True])
def test_region_merging_takes_the_kerb_evidence_as_a_function(host):
    """The stage hands the kerb probabilities over as a function of edge indices (no two full
    float64 arrays through the rounds): the same regions and pair table as with the arrays."""
    n, a, b, up, down, colour = _merge_case(1, n=3000)
    up = up * np.linspace(0.2, 1.0, len(a))            # distinct values per edge
    calls = []

    def evidence(index):
        calls.append(index)
        return up[index], down[index]
    args = (colour, (1.5, 3.0, 6.0), 10.0, 0.1, 6)
    arrays = regions.merge_regions_by_colour(n, a, b, up, down, *args, host=host)
    function = regions.merge_regions_by_colour(n, a, b, evidence, None, *args, host=host)
    for name in ("label", "count", "colour_sum", "pa", "pb", "edges", "up", "down"):
        assert np.array_equal(getattr(arrays, name), getattr(function, name)), name
    assert len(calls) >= 2 and isinstance(calls[-1], np.ndarray)   # chunks, then the final cross edges


def test_region_merging_respects_the_step_veto():
    n, a, b, up, down, colour = _merge_case(0)
    colour[:] = 100.0                                  # one colour everywhere: only steps separate
    cut = np.zeros(len(a))
    left = (np.arange(n) % 2)[a] != (np.arange(n) % 2)[b]
    xyz = _plane(n, seed=0)
    across = (xyz[a, 0] > 10) != (xyz[b, 0] > 10)      # every edge across x = 10 steps up
    cut[across] = 1.0
    graph = regions.merge_regions_by_colour(n, a, b, cut, np.zeros(len(a)), colour, (1.0,), 10.0, 0.1)
    side = xyz[:, 0] > 10
    for r in range(graph.n_regions):
        members = side[graph.label == r]
        assert members.all() or not members.any()
    assert left.any()


def test_points_above_the_road_surface_leave_the_road(ti_arch):
    """road_regions' surface test: on a sloped, noisy road (3 cm) the skirt of a parked car (points
    0.1-0.3 m above the road along the car's sides, as a photogrammetric cloud smears them) leaves
    the road and no road point within the noise does; the result does not depend on point order."""
    from roadx_ti.stages.road_regions import above_road_surface

    rng = np.random.default_rng(3)
    noise = 0.03
    road = _plane(12000, noise=noise, seed=5)
    # a car of 2 x 4.5 m at (8..10, 6..10.5): no road under it, its lowest 0.3 m along the outline
    # (its sides: a steep surface, about 10 points per metre where the road has 30 per m2)
    under = (road[:, 0] > 8) & (road[:, 0] < 10) & (road[:, 1] > 6) & (road[:, 1] < 10.5)
    road = road[~under]
    m = 130
    t = rng.random(m)
    outline = np.where(t[:, None] < 0.5, np.column_stack([np.where(t < 0.25, 8.0, 10.0), 6 + 4.5 * rng.random(m)]),
                       np.column_stack([8 + 2 * rng.random(m), np.where(t < 0.75, 6.0, 10.5)]))
    outline += rng.normal(0, 0.03, (m, 2))
    lift = 0.1 + 0.2 * rng.random(m)
    skirt = np.column_stack([outline, 0.02 * outline[:, 0] + 0.01 * outline[:, 1] + lift]).astype(np.float32)
    xyz = np.concatenate([road, skirt])
    gradient = regions.coarse_gradient(xyz, 2.5)
    is_road = np.ones(len(xyz), bool)
    kept, removed = above_road_surface(xyz, gradient, is_road, 32, 4 * noise)
    on_road = np.arange(len(xyz)) < len(road)
    residual = (xyz[:, 2] - 0.02 * xyz[:, 0] - 0.01 * xyz[:, 1]) / noise
    assert kept[on_road & (residual < 3.0)].all()          # nothing within the noise goes
    assert (~kept[on_road]).sum() <= 5                     # (Gaussian tails beyond 4 sigma may)
    high = lift > 1.5 * 4 * noise                          # most of the skirt clearly above it does (the
    assert np.mean(~kept[~on_road][high]) >= 0.8           # skirt's own points lift a corner's median)
    assert removed == int((~kept).sum())
    order = rng.permutation(len(xyz))
    again, _ = above_road_surface(xyz[order], regions.coarse_gradient(xyz[order], 2.5), is_road, 32, 4 * noise)
    assert (again == kept[order]).all()


def test_road_regions_with_its_rows_queried_again_after_the_merge_is_the_same(monkeypatch):
    """Above REQUERY_ROWS_ABOVE working points road_regions lets its kNN rows go before the merge
    and queries them again for the boundary vote (memory for time): the labels and regions must
    be those of the run that holds them."""
    from roadx_ti import config, pipelines, synthetic
    from roadx_ti.stages import road_regions
    from roadx_ti.stages.base import StageContext
    from tests.conftest import REPO

    cloud = synthetic.generate("uav-road", 40_000, seed=3)
    cfg = config.load(REPO / "configs" / "road_uav.yaml")
    stage = next(s for s in pipelines.build_stages(cfg.stage_list()) if s.name == "road_regions")
    held = stage.run(cloud, StageContext(seed=0))
    monkeypatch.setattr(road_regions, "REQUERY_ROWS_ABOVE", 0)
    queried = stage.run(cloud, StageContext(seed=0))
    assert (held.labels == 11).sum() > 1000                     # a road was found
    assert np.array_equal(held.labels, queried.labels) and np.array_equal(held.segment_id, queried.segment_id)


def test_road_regions_warns_when_the_noise_blurs_common_kerbs():
    """Kerbs lower than the edge-preserving filter's window (filter_width x the measured height
    noise) blur in the filtered heights; road_regions reports that height in its estimates and
    warns once it exceeds a common kerb's 10 cm (unseen scenes with such noise lost streets or took
    sidewalks: ACCURACY.md's notes)."""
    import logging

    from roadx_ti.cloud import Cloud
    from roadx_ti.stages import road_regions
    from roadx_ti.stages.base import StageContext

    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 20, (20_000, 2))
    rgb = np.full((len(xy), 3), 120 * 257, np.uint16)
    stage = road_regions.RoadRegions(road_regions.RoadRegionsOptions())
    for noise, warned in ((0.01, False), (0.06, True)):
        xyz = np.column_stack([xy, rng.normal(0, noise, len(xy))]).astype(np.float32)
        cloud = Cloud(xyz=xyz, origin=np.zeros(3), rgb=rgb, color_depth=16)
        records = []
        log = logging.getLogger(f"road_regions_test_{noise}")
        log.addHandler(type("Keep", (logging.Handler,), {"emit": lambda self, r: records.append(r)})())
        result = stage.run(cloud, StageContext(seed=0, log=log))
        resolved = result.info["estimates"]["kerbs_resolved_above_m"]
        measured = result.info["estimates"]["height_noise_m"]
        assert resolved == pytest.approx(2.5 * measured, rel=1e-3) and measured == pytest.approx(noise, rel=0.2)
        warnings = [r.getMessage() for r in records if r.levelno == logging.WARNING and "blur" in r.getMessage()]
        assert (len(warnings) == 1) == warned, warnings


@pytest.mark.parametrize("host", [False, True])
def test_region_merging_branches_equal_the_whole_schedule(host):
    """Branches continue from the regions the shared levels leave (on the host, over regions):
    shared levels [l1] then a branch [l2, l3] give the merge of levels [l1, l2, l3], pairs and
    step sums included; each branch of several gives its own schedule's merge."""
    n, a, b, up, down, colour = _merge_case(2, n=3000)
    tail = (10.0, 0.1, 6)
    branched = list(regions.merge_regions_by_colour(n, a, b, up, down, colour, (1.5,), *tail, host=host,
                                                    branches=[(3.0, 6.0), (2.0, 4.0), (4.5, 9.0)]))
    assert len(branched) == 3
    for graph, rest in zip(branched, [(3.0, 6.0), (2.0, 4.0), (4.5, 9.0)]):
        whole = regions.merge_regions_by_colour(n, a, b, up, down, colour, (1.5,) + rest, *tail, host=host)
        assert np.array_equal(graph.label, whole.label)
        assert np.array_equal(graph.count, whole.count) and np.array_equal(graph.colour_sum, whole.colour_sum)
        for name in ("pa", "pb", "edges", "up", "down"):
            assert np.array_equal(getattr(graph, name), getattr(whole, name)), name
    assert len({g.n_regions for g in branched}) == 3       # the branches differ


def test_road_regions_road_is_the_majority_of_its_segmentations():
    """road_regions' ensemble: one segmentation per scale of the later colour levels, each from
    the regions the first level leaves; a point is road when most of their road choices say so
    (before the boundary vote and the surface test, which then act on that road). Each member is
    the stage run with that scale alone."""
    from roadx_ti import synthetic
    from roadx_ti.stages import road_regions
    from roadx_ti.stages.base import StageContext

    cloud = synthetic.generate("uav-road", 60_000, seed=5)

    def road(scales):
        options = road_regions.RoadRegionsOptions(ensemble=scales, boundary_passes=0, surface_tol=0)
        result = road_regions.RoadRegions(options).run(cloud, StageContext(seed=0))
        return result.labels == 11, result.info
    members = [road((scale,))[0] for scale in (0.7, 1.0, 1.3)]
    voted, info = road((0.7, 1.0, 1.3))
    assert np.array_equal(voted, np.sum(members, axis=0) >= 2)
    split = ~np.all(np.array(members) == members[0], axis=0)
    assert split.any() and info["ensemble_split_points"] == int(split.sum())   # the members differ
    assert np.array_equal(road((1.3, 0.7, 1.0))[0], voted)                       # order of the scales


def test_road_regions_reads_one_varying_colour_channel_as_grey():
    """Colour of which only red varies (a grey or single-band image written into red, green and
    blue zero): read as that grey, with a warning (as RGB every point was saturated red and no
    region became road: 0 road points, exit 0)."""
    import logging

    from roadx_ti import config, pipelines, synthetic
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageContext
    from roadx_ti.stages.road_regions import colour_channels
    from tests.conftest import REPO

    scene = synthetic.generate("uav-road", 40_000, seed=3)
    red_only = scene.rgb.copy()
    red_only[:, 1:] = 0
    cloud = Cloud(xyz=scene.xyz, origin=scene.origin, rgb=red_only, color_depth=16)
    source, grey = colour_channels(cloud)
    assert source == "red as grey" and np.array_equal(grey[:, 0], grey[:, 2])
    assert np.array_equal(grey[:, 1], (scene.rgb[:, 0] / 257.0).astype(np.float32))
    cfg = config.load(REPO / "configs" / "road_uav.yaml")
    records = []
    log = logging.getLogger("road_regions_grey_test")
    log.addHandler(type("Keep", (logging.Handler,), {"emit": lambda self, r: records.append(r)})())
    truth = scene.classification == 11
    found = pipelines.run(cloud, pipelines.build_stages(cfg.stage_list()), ctx=StageContext(seed=0, log=log))
    road = found.classification == 11
    assert np.count_nonzero(road & truth) > 0.9 * np.count_nonzero(truth)
    assert any("only the red channel of the colour varies" in r.getMessage() for r in records)


def test_colour_mixing_8_and_16_bit_values_is_warned(tmp_path, caplog):
    """Every second point's colour in 8 bits beside 16-bit colour (a merged delivery) is warned
    (it cut the road to 5 % of itself, silently); genuine 16-bit colour, dark points included, is not."""
    import laspy

    from roadx_ti import io
    from tests.cli_helpers import bumpy_ground, write_las

    rng = np.random.default_rng(0)
    rgb = rng.integers(20, 240, (2000, 3)) * 257
    rgb[:40] = 0                                            # black points are no sign of a mix
    write_las(tmp_path / "deep.las", bumpy_ground(2000), rgb=rgb)
    rgb[::2] //= 257
    write_las(tmp_path / "mixed.las", bumpy_ground(2000), rgb=rgb)
    with caplog.at_level("WARNING"):
        io.read(tmp_path / "deep.las")
        assert "8-bit colour values beside 16-bit" not in caplog.text
        io.read(tmp_path / "mixed.las")
    assert "50 % of its coloured points have 8-bit colour values beside 16-bit ones" in caplog.text
    assert laspy.read(tmp_path / "mixed.las").header.point_count == 2000
