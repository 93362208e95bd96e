"""Kerb lines found along lines (roadx_ti.kerb_lines) and their use by road_regions where the
height noise blurs kerbs in its per-point filter (issue: adaptive road extraction)."""
from __future__ import annotations

import numpy as np
import pytest

from roadx_ti import kerb_lines

NOISE = 0.046          # m: the noisiest scenes of the generator's range (1.5-5 cm)
KERB = 0.094           # m: a low kerb, about 2 noise sigmas
DENSITY = 45.0         # points / m2


def _surface(angle_deg: float, profile, seed: int = 0, size: float = 30.0):
    """Points on a plane with a straight line through the centre at ``angle_deg`` (its normal's
    direction), heights ``profile(signed distance across the line)`` plus Gaussian noise."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, size, (int(size * size * DENSITY), 2))
    normal = np.array([np.cos(np.deg2rad(angle_deg)), np.sin(np.deg2rad(angle_deg))])
    across = (xy - size / 2) @ normal
    return xy, profile(across) + rng.normal(0, NOISE, len(xy)), normal, across


def _line_cells(field, normal, size=30.0, near=0.3, half_length=10.0):
    """(steps, directions) of the field's line cells within ``near`` of the true line and
    ``half_length`` of the scene's centre along it, and the steps of the cells farther than 1 m
    from the line."""
    i, j = np.nonzero(field.steps > 0)
    centre = field.lo + (np.column_stack([i, j]) + 0.5) * field.cell - size / 2
    off = np.abs(centre @ normal)
    on = (off < near) & (np.abs(centre @ np.array([-normal[1], normal[0]])) < half_length)
    away = off > 1.0
    return field.steps[i[on], j[on]], field.direction[i[on], j[on]], field.steps[i[away], j[away]]


@pytest.mark.parametrize("angle", [0.0, 30.0, 75.0, 135.0])
def test_a_low_kerb_under_noise_reads_its_height_along_its_line(angle):
    """A 9.4 cm step under 4.6 cm of noise (per point it is 2 sigmas): along the line the step
    reads its height in any orientation, pointing up the step, well clear of what noise alone
    makes elsewhere; the field's spread is its own noise (far under the point noise)."""
    xy, z, normal, _ = _surface(angle, lambda d: KERB * (d > 0))
    field = kerb_lines.step_field(xy, z, 0.135, 0.2, 2.0, 2.0)
    on_line, direction, elsewhere = _line_cells(field, normal)
    assert len(on_line) > 100
    assert np.median(on_line) == pytest.approx(KERB, rel=0.15)
    assert np.median(direction @ normal) > np.cos(np.deg2rad(10.0))
    assert np.percentile(elsewhere, 99) < 0.05            # below a kerb's smallest height (kerb_min)
    assert 0.002 < field.spread < 0.012


def test_a_short_step_reads_less_than_a_long_kerb():
    """The filter's 2 m along the line: a step only as long as a sidewalk is wide (the 3 m side
    of a lowered crossing, where the sidewalk comes down to the road) reads about half its height,
    under a kerb's smallest (kerb_min 5 cm); at 1 m along such steps read as kerbs and the lowered
    crossings joined the road (ACCURACY.md's notes)."""
    def short_step(d, xy):
        return KERB * (d > 0) * (np.abs(xy[:, 1] - 15.0) < 1.5)
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 30, (int(30 * 30 * DENSITY), 2))
    z = short_step(xy[:, 0] - 15.0, xy) + rng.normal(0, NOISE, len(xy))
    field = kerb_lines.step_field(xy, z, 0.135, 0.2, 2.0, 2.0)
    on_line, _, _ = _line_cells(field, np.array([1.0, 0.0]), half_length=1.0)
    assert np.median(on_line) < 0.05
    long_field = kerb_lines.step_field(xy, z, 0.135, 0.2, 1.0, 2.0)
    assert np.median(_line_cells(long_field, np.array([1.0, 0.0]), half_length=1.0)[0]) > 0.05


def test_edges_across_a_line_take_its_step_and_the_others_none():
    xy, z, normal, across = _surface(0.0, lambda d: KERB * (d > 0), seed=2)
    field = kerb_lines.step_field(xy, z, 0.135, 0.2, 2.0, 2.0)
    xyz = np.column_stack([xy, z]).astype(np.float32)
    rng = np.random.default_rng(3)
    ea = rng.integers(0, len(xy), 20_000)
    # partners about 0.15 m away in a random direction
    target = xy[ea] + 0.15 * np.column_stack([np.cos(t := rng.uniform(0, 2 * np.pi, len(ea))), np.sin(t)])
    from scipy.spatial import cKDTree
    eb = cKDTree(xy).query(target)[1]
    steps = kerb_lines.edge_line_steps(xyz, ea, eb, field)
    middle = np.abs(0.5 * (across[ea] + across[eb])) < 8.0
    crossing = (np.sign(across[ea]) != np.sign(across[eb])) & middle
    far = np.minimum(np.abs(across[ea]), np.abs(across[eb])) > 0.5
    kerb = np.abs(steps) >= 0.05                          # a kerb's smallest height (kerb_min)
    assert np.mean(kerb[crossing]) > 0.8
    up = crossing & (across[eb] > 0) & kerb
    assert np.all(steps[up] > 0) and np.all(steps[crossing & (across[ea] > 0) & kerb] < 0)
    assert np.mean(kerb[far]) < 0.01                      # noise makes lines too, far lower


def test_line_pairs_join_the_regions_either_side_past_a_sliver_along_the_line():
    """Regions: 0 below the kerb, 1 above it, 2 a sliver 0.2 m wide along the line itself (the
    kerb face, apart from both): the pair is (0, 1), about as long as the line."""
    xy, z, normal, across = _surface(0.0, lambda d: KERB * (d > 0), seed=4)
    field = kerb_lines.step_field(xy, z, 0.135, 0.2, 2.0, 2.0)
    label = np.where(np.abs(across) < 0.1, 2, np.where(across > 0, 1, 0))
    xyz = np.column_stack([xy, z]).astype(np.float32)

    def probability(steps, spread):
        from roadx_ti.stages.road_regions import kerb_evidence
        return kerb_evidence(steps, spread, 0.05, 0.30, 0.02)[0]
    lower, upper, length = kerb_lines.line_pairs(field, xyz, label, 0.2 + 0.5 * 0.27, probability)
    pairs = dict(zip(zip(lower.tolist(), upper.tolist()), length.tolist()))
    assert max(pairs, key=pairs.get) == (0, 1)
    assert 15.0 < pairs[(0, 1)] < 35.0                    # the 30 m line, less its weak ends
    assert sum(v for k, v in pairs.items() if k != (0, 1)) < 0.2 * pairs[(0, 1)]


def _noisy_street(sidewalk_grey: float, seed: int, noise: float = NOISE):
    """A 60 x 30 m street: road grey 118 between sidewalks of ``sidewalk_grey`` 9.4 cm above it,
    lawns behind, ``noise`` of height noise, 45 points / m2."""
    from roadx_ti.cloud import Cloud

    rng = np.random.default_rng(seed)
    xy = rng.uniform([0, 0], [60.0, 30.0], (int(60 * 30 * DENSITY), 2))
    y = xy[:, 1]
    road = (y > 10) & (y < 18)
    walk = ((y > 7) & (y <= 10)) | ((y >= 18) & (y < 21))
    lawn = ~road & ~walk
    z = np.where(road, 0.0, KERB) + np.where(lawn, 0.03, 0.0) + rng.normal(0, noise, len(xy))
    grey = np.where(road, 118.0, sidewalk_grey)
    rgb = np.column_stack([grey, grey, grey + 2]) + rng.normal(0, 6, (len(xy), 3))
    rgb[lawn] = np.array([70.0, 110.0, 50.0]) + rng.normal(0, 6, (int(lawn.sum()), 3))
    rgb = (np.clip(rgb, 0, 255) * 257).astype(np.uint16)
    cloud = Cloud(xyz=np.column_stack([xy, z]).astype(np.float32), origin=np.zeros(3), rgb=rgb, color_depth=16)
    return cloud, road, walk


@pytest.mark.slow
def test_road_regions_keeps_a_sidewalk_of_the_roads_colour_off_behind_a_noisy_kerb():
    """The sidewalk has the road's colour (grey 119 against 118): only the kerb tells them apart,
    and at 2 noise sigmas the per-point filter blurs it (the stage warns). With kerb lines (the
    default) the sidewalk stays off the road; without, it joins it."""
    from roadx_ti.stages import road_regions
    from roadx_ti.stages.base import StageContext

    cloud, road, walk = _noisy_street(119.0, seed=0)
    found = {}
    for on in (True, False):
        stage = road_regions.RoadRegions(road_regions.RoadRegionsOptions(kerb_lines=on))
        result = stage.run(cloud, StageContext(seed=0))
        found[on] = result.labels == 11
        assert result.info["estimates"]["kerb_lines_weight"] == (1.0 if on else 0.0)
    assert found[True][road].mean() > 0.95 and found[True][walk].mean() < 0.05
    assert found[False][walk].mean() > 0.5


def test_road_regions_looks_for_kerb_lines_only_where_the_filter_blurs_kerbs():
    """At 1 cm of noise the filtered heights resolve kerbs: no kerb-line field is made, and the
    labels are those of kerb_lines: false."""
    from roadx_ti.stages import road_regions
    from roadx_ti.stages.base import StageContext

    cloud, road, walk = _noisy_street(119.0, seed=1, noise=0.01)
    runs = [road_regions.RoadRegions(road_regions.RoadRegionsOptions(kerb_lines=on)).run(cloud, StageContext(seed=0))
            for on in (True, False)]
    assert runs[0].info["estimates"]["kerb_lines_weight"] == 0.0
    assert np.array_equal(runs[0].labels, runs[1].labels)
    found = runs[0].labels == 11
    assert found[road].mean() > 0.95 and found[walk].mean() < 0.05
