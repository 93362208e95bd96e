"""Survey-wide estimates (roadx_ti.estimates): a catalog streamed before tiling gives what the
whole survey in memory gives, whatever the files' point order."""
import numpy as np
import pytest

from roadx_ti import io, synthetic
from roadx_ti.estimates import measure, measure_catalog
from roadx_ti.tiling import catalog


def _files(tmp_path, scene, name, order):
    """The scene as two LAZ files (west and east halves), points in ``order`` within each."""
    x = scene.xyz[order, 0]
    west = order[x < np.median(x)]
    east = order[x >= np.median(x)]
    paths = []
    for part, idx in (("w", west), ("e", east)):
        path = tmp_path / f"{name}_{part}.laz"
        io.write(path, scene, subset=idx)
        paths.append(path)
    return catalog(paths)


def test_catalog_estimates_equal_the_whole_survey_and_ignore_point_order(tmp_path, monkeypatch):
    scene = synthetic.generate("uav-road", 120_000, seed=4)
    whole = measure(scene)
    # the generator writes object by object: runs of consecutive points are not a spatial sample
    files = _files(tmp_path, scene, "a", np.arange(scene.n))
    origin = np.floor(scene.world_xyz().min(axis=0))
    survey = measure_catalog(files, origin)
    assert survey["points"] == whole["points"]
    assert abs(survey["plan_area_m2"] - whole["plan_area_m2"]) <= 0.002 * whole["plan_area_m2"]
    assert abs(survey["density_per_m2"] / whole["density_per_m2"] - 1) < 0.002
    for key, tolerance in (("point_spacing_m", 0.05), ("height_noise_m", 0.1), ("colour_noise", 0.1)):
        assert abs(survey[key] / whole[key] - 1) < tolerance, (key, survey[key], whole[key])
    shuffled = _files(tmp_path, scene, "b", np.random.default_rng(2).permutation(scene.n))
    assert measure_catalog(shuffled, origin) == survey
    # a sample smaller than the survey (40 k of 120 k), and measure's own subsample of it (10 k
    # here; 200 k of a 400 k sample by default), do not follow the point order either
    from functools import partial

    from roadx_ti import estimates
    monkeypatch.setattr(estimates, "measure", partial(estimates.measure, sample_points=10_000))
    small = measure_catalog(files, origin, sample_points=40_000)
    assert measure_catalog(shuffled, origin, sample_points=40_000) == small


def test_a_copc_file_streams_like_its_laz(tmp_path):
    pytest.importorskip("copclib", reason="COPC output needs the copclib extra")
    scene = synthetic.generate("uav-road", 30_000, seed=6)
    io.write(tmp_path / "s.laz", scene)
    io.write(tmp_path / "s.copc.laz", scene)
    origin = np.floor(scene.world_xyz().min(axis=0))
    assert measure_catalog(catalog([tmp_path / "s.copc.laz"]), origin) == \
        measure_catalog(catalog([tmp_path / "s.laz"]), origin)


def test_terrain_grade_reads_the_hillside_not_the_buildings():
    """terrain_grade (the median grade of the lowest points of 10 m cells, bar the lowest 1 %,
    lowered to their 5 x 5 cells' lowest): a flat suburb reads near 0 though its houses fill
    cells, the same suburb tilted reads the tilt (its 82 low-noise points, spread over 5 x 5
    cells by the lowering, made it read 0.18-0.35 at 30 % before the 1 % was left out); far
    strays do not size a grid; a handful of points gives none."""
    from roadx_ti.accuracy import tilted
    from roadx_ti.estimates import terrain_grade

    scene = synthetic.generate("als-roof", 200_000, seed=3)
    assert terrain_grade(scene.xyz) < 0.05
    assert 0.27 < terrain_grade(tilted(scene, 0.3).xyz) < 0.33
    assert 0.36 < terrain_grade(tilted(scene, 0.4).xyz) < 0.44
    rng = np.random.default_rng(0)
    plane = np.column_stack([rng.random((50_000, 2)) * 200.0, np.zeros(50_000)]).astype(np.float32)
    plane[:, 2] = 0.25 * plane[:, 0]
    strays = np.array([[5e6, 5e6, 0.0], [-5e6, 2e6, 10.0]], np.float32)
    assert terrain_grade(np.concatenate([plane, strays])) == pytest.approx(0.25, abs=0.01)
    assert terrain_grade(plane[:20]) is None
    assert "terrain_grade" in measure(scene)
