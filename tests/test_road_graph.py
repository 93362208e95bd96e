"""Road selection over a region graph (roadx_ti.road_graph): the vegetation cue that holds in shadow."""
from __future__ import annotations

import numpy as np
import pytest

from roadx_ti.kernels.regions import RegionGraph
from roadx_ti.road_graph import Weights, excess_green, label_road


def _street(lawn_rgb):
    """Regions: 0 road (grey 80), 1 and 3 sidewalks on either side (grey 95, above kerbs),
    2 a lawn continuous with the road (no kerb between them) of colour ``lawn_rgb``."""
    count = np.array([2000.0, 800.0, 400.0, 800.0])
    mean = np.array([[80, 80, 82], [95, 95, 97], lawn_rgb, [95, 95, 97]], np.float64)
    pa, pb = np.array([0, 0, 0]), np.array([1, 2, 3])
    edges = np.array([120.0, 60.0, 120.0])
    up = np.array([110.0, 0.0, 110.0])        # road -> sidewalk: most boundary edges step up
    down = np.zeros(3)
    return RegionGraph(np.zeros(0, np.int32), count, mean * count[:, None], pa, pb, edges, up, down)


def test_excess_green_is_the_same_in_shadow_and_in_sun():
    sun = np.array([[64.0, 86.0, 50.0], [80.0, 80.0, 82.0]])
    shade = 0.45 * sun
    assert np.allclose(excess_green(sun), excess_green(shade))
    assert excess_green(sun)[0] > 0.25 and abs(excess_green(sun)[1]) < 0.02


def test_lawn_in_shadow_is_not_road_where_its_absolute_chroma_fades():
    shaded_lawn = [30.0, 45.0, 22.0]           # chroma |rgb - grey| 16.6 < max_chroma 20, ExG 0.39
    graph = _street(shaded_lawn)
    road, _ = label_road(graph, 60.0)
    assert road.tolist() == [True, False, False, False]
    # the cue is what keeps it out: without it the lawn, continuous with the road, joins it
    road_without, _ = label_road(graph, 60.0, Weights(green_cost=0.0))
    assert road_without.tolist() == [True, False, True, False]


def test_a_grey_patch_continuous_with_the_road_still_joins_it():
    road, _ = label_road(_street([70.0, 70.0, 73.0]), 60.0)     # a shadow on the asphalt
    assert road.tolist() == [True, False, True, False]


def _two_streets():
    """Street A (regions 0-2): asphalt grey 80 below sidewalks of 66, many kerb edges. Street B
    (regions 3-5), 280 m away: its own darker asphalt, 67 (the shade of A's sidewalks), below
    sidewalks of 55."""
    count = np.array([4000.0, 1500.0, 1500.0, 1500.0, 600.0, 600.0])
    grey = np.array([80.0, 66.0, 66.0, 67.0, 55.0, 55.0])
    mean = np.repeat(grey[:, None], 3, axis=1)
    pa, pb = np.array([0, 0, 3, 3]), np.array([1, 2, 4, 5])
    edges = np.array([200.0, 200.0, 60.0, 60.0])
    up = 0.9 * edges                          # each road steps up to its sidewalks
    graph = RegionGraph(np.zeros(0, np.int32), count, mean * count[:, None], pa, pb, edges, up, np.zeros(4))
    centroid = np.array([[20.0, 20.0]] * 3 + [[300.0, 20.0]] * 3)
    return graph, centroid


def test_a_street_of_its_own_asphalt_shade_learns_its_own_road_colour():
    graph, centroid = _two_streets()
    # one colour model for the scene: street B's asphalt looks like A's sidewalks
    road, _ = label_road(graph, 60.0, Weights(colour_block=0.0), centroid=centroid)
    assert road.tolist() == [True, False, False, False, False, False]
    # learnt block by block: B's road is the lower side of B's own kerbs
    road, _ = label_road(graph, 60.0, Weights(colour_block=40.0), centroid=centroid)
    assert road.tolist() == [True, False, False, True, False, False]


def _street_and_yard():
    """Regions: 0 road (grey 80) below kerbs to its sidewalks 1 and 2 (grey 95); 3 a paved yard
    of the road's grey (333 m2 at 60 points/m2) that touches only 4, a lot (grey 140) continuous
    with sidewalk 1: no kerb anywhere along the yard."""
    count = np.array([40000.0, 3000.0, 3000.0, 20000.0, 6000.0])
    grey = np.array([80.0, 95.0, 95.0, 81.0, 140.0])
    mean = np.repeat(grey[:, None], 3, axis=1)
    pa, pb = np.array([0, 0, 3, 1]), np.array([1, 2, 4, 4])
    edges = np.array([400.0, 400.0, 300.0, 200.0])
    up = np.array([360.0, 360.0, 0.0, 0.0])
    return RegionGraph(np.zeros(0, np.int32), count, mean * count[:, None], pa, pb, edges, up, np.zeros(4))


def test_a_large_component_without_kerbs_apart_from_the_street_is_not_road():
    graph = _street_and_yard()
    road, _ = label_road(graph, 60.0)
    assert road.tolist() == [True, False, False, False, False]
    # the cut takes the yard with the lot it touches; without the kerb share, their area keeps them
    road, _ = label_road(graph, 60.0, Weights(keep_area_kerb=0.0))
    assert road.tolist() == [True, False, False, True, True]


def _kerbless_lane(seed=0, density=12.0):
    """A country lane with no kerb: a 6 m grey carriageway curving across 120 x 80 m of ground, green
    verges of 2 m, tan fields, and a yard of the same grey 38 x 26 m apart from the lane (all flat
    ground at one height, as the cloth leaves it). Returns the cloud and the truth (lane points)."""
    from roadx_ti.cloud import Cloud
    rng = np.random.default_rng(seed)
    n = int(density * 120 * 80)
    xy = rng.random((n, 2)) * [120.0, 80.0]
    off = xy[:, 1] - (40.0 + 8.0 * np.sin(xy[:, 0] / 25.0))
    lane = np.abs(off) < 3.0
    verge = ~lane & (np.abs(off) < 5.0)
    yard = (xy[:, 0] > 62) & (xy[:, 0] < 100) & (xy[:, 1] < 26)
    rgb = np.where(lane[:, None] | yard[:, None], [95.0, 95.0, 98.0],
                   np.where(verge[:, None], [70.0, 100.0, 50.0], [175.0, 155.0, 110.0]))
    rgb = np.clip(rgb + rng.normal(0, 4.0, (n, 3)), 0, 255).astype(np.uint16)
    z = 0.01 * xy[:, 0] + rng.normal(0, 0.02, n)
    xyz = np.column_stack([xy, z]).astype(np.float32)
    return Cloud(xyz=xyz, origin=np.zeros(3), rgb=rgb, color_depth=8), lane, yard


@pytest.mark.parametrize("strays", [0, 3])
def test_a_lane_without_kerbs_is_found_by_its_ribbon_and_a_yard_of_its_grey_is_not(ti_arch, strays):
    """No kerb anywhere: the kerb cut keeps no road, and road_regions takes the ribbon of plain
    (not chromatic, not green) ground of a carriageway's width; the yard of the same grey, wider
    than any carriageway, stays out. A few stray points 20 km away do not stop it."""
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages import stage_class
    from roadx_ti.stages.base import StageContext
    cloud, lane, yard = _kerbless_lane()
    if strays:
        far = np.array([[20_000.0, 0.0, 0.5], [0.0, -20_000.0, 0.3], [20_000.0, 20_000.0, 0.0]], np.float32)[:strays]
        cloud = Cloud(xyz=np.vstack([cloud.xyz, far]), origin=cloud.origin, color_depth=8,
                      rgb=np.vstack([cloud.rgb, np.full((strays, 3), 95, np.uint16)]))
        lane, yard = np.append(lane, np.zeros(strays, bool)), np.append(yard, np.zeros(strays, bool))
    stage = stage_class("road_regions")(stage_class("road_regions").Options())
    result = stage.run(cloud, StageContext(seed=0))
    road = result.labels == 11
    assert result.info["kerbless_road_points"] > 0
    assert np.sum(road & lane) / np.sum(road | lane) > 0.9, np.sum(road & lane) / np.sum(road | lane)
    assert np.mean(road[yard]) < 0.02


def _log_ratio_whole_grid(query, lo_mean, lo_w, up_mean, up_w, bandwidth):
    """The colour log ratio with the density grids filtered whole (road_graph filters only the
    samples' box and the filter's radius)."""
    from scipy.ndimage import gaussian_filter
    cell = bandwidth / 2.0
    bins = int(np.ceil(256.0 / cell)) + 1

    def cells(m):
        return tuple(np.clip(np.floor(np.asarray(m, np.float64) / cell).astype(np.int64), 0, bins - 1).T)

    def density(m, wt):
        if len(m) == 0 or wt.sum() <= 0:
            return np.zeros(len(query))
        grid = np.zeros((bins, bins, bins))
        np.add.at(grid, cells(m), wt)
        return (gaussian_filter(grid, sigma=2.0, mode="constant") / wt.sum())[cells(query)]
    floor = 1e-4 * (2.0 * np.pi * 4.0) ** -1.5
    return np.clip(np.log((density(lo_mean, lo_w) + floor) / (density(up_mean, up_w) + floor)), -3.0, 3.0)


@pytest.mark.parametrize("case", range(6))
def test_colour_log_ratio_equals_the_whole_grid_filter(case):
    from roadx_ti.road_graph import _log_ratio_at
    rng = np.random.default_rng(case)
    centre, spread = rng.uniform(0, 255, 3), [2.0, 10.0, 60.0][case % 3]
    query = np.clip(centre + rng.normal(0, 2 * spread, (2000, 3)), -5, 300)
    lower = np.clip(centre + rng.normal(0, spread, (300, 3)), -5, 300)
    upper = np.clip(centre + 12 + rng.normal(0, spread, (200 * (case != 4), 3)), -5, 300)
    if case == 5:
        lower = np.array([[0.0, 0.0, 0.0], [255.0, 255.0, 255.0]])      # samples at the grid's corners
    lo_w, up_w = rng.uniform(0, 5, len(lower)), rng.uniform(0, 5, len(upper))
    expected = _log_ratio_whole_grid(query, lower, lo_w, upper, up_w, 6.0)
    assert np.array_equal(_log_ratio_at(query, lower, lo_w, upper, up_w, 6.0), expected)


def test_road_kerb_share_is_the_share_of_the_road_outline_on_kerbs_it_lies_below():
    from roadx_ti.road_graph import kerb_relations, road_kerb_share
    graph = _street([70.0, 70.0, 73.0])         # road 0 below kerbs to 1 and 3, continuous with 2
    kerb, _, b_upper = kerb_relations(graph, Weights())
    road = np.array([True, False, False, False])
    assert road_kerb_share(graph, road, kerb, b_upper) == pytest.approx(240.0 / 300.0)
    # the sidewalks as "road": they lie above their kerbs, so none of their outline counts
    assert road_kerb_share(graph, ~road, kerb, b_upper) == 0.0
    # a road no kerb bounds (the graph of a kerbless lane): 0, and the stage's fallback runs
    flat = RegionGraph(graph.label, graph.count, graph.colour_sum, graph.pa, graph.pb, graph.edges,
                       np.zeros(3), np.zeros(3))
    kerb, _, b_upper = kerb_relations(flat, Weights())
    assert road_kerb_share(flat, road, kerb, b_upper) == 0.0


def _enclosed_patch(patch_rgb, patch_points=300.0):
    """Regions: 0 road (grey 80) below a kerb to its sidewalk 1 (grey 95); 2 a patch of colour
    ``patch_rgb`` that only the road surrounds (no kerb between them)."""
    count = np.array([6000.0, 1500.0, patch_points])
    mean = np.array([[80, 80, 82], [95, 95, 97], patch_rgb], np.float64)
    pa, pb = np.array([0, 0]), np.array([1, 2])
    edges = np.array([300.0, 80.0])
    up = np.array([280.0, 0.0])
    return RegionGraph(np.zeros(0, np.int32), count, mean * count[:, None], pa, pb, edges, up, np.zeros(2))


@pytest.mark.parametrize("paint, absorbed", [([225.0, 205.0, 45.0], True),     # yellow marking
                                             ([230.0, 230.0, 228.0], True),    # white marking
                                             ([34.0, 54.0, 28.0], False),      # lawn
                                             ([22.0, 33.0, 17.0], False)])     # lawn in shadow
def test_enclosed_markings_join_the_road_and_vegetation_does_not(paint, absorbed):
    from roadx_ti.road_graph import _absorb_enclosed, green_dominant
    graph = _enclosed_patch(paint)
    road, facts = label_road(graph, 60.0)
    assert road.tolist() == [True, False, absorbed]
    # green dominance tells paint from vegetation where excess green alone calls yellow green
    assert green_dominant(graph.mean_colour()[2:]).tolist() == [not absorbed]
    if paint[2] < 100 and absorbed:
        assert excess_green(graph.mean_colour()[2:])[0] > 0.1       # yellow
    if not absorbed:
        # the cut leaves the patch out; absorbing without the vegetation test would take it
        cut = np.array([True, False, False])
        kerb = graph.up.copy()
        assert _absorb_enclosed(graph, cut, kerb, Weights())[0].tolist() == [True, False, True]
