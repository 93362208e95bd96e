"""The height_above_ground stage: z normalised by the ground stage's surface, checked against the
cloth it comes from and against a known terrain, its declarations (a ground stage before it, in one
line), and its extra dimension in the output, with the labels unchanged."""
from __future__ import annotations

import textwrap

import laspy
import numpy as np
import pytest

from roadx_ti import cli, config, pipelines, synthetic, tiling
from roadx_ti.cloud import Cloud
from roadx_ti.stages import stage_class
from roadx_ti.stages.base import GROUND_SURFACE, MIN_BUFFER, StageContext

Height = stage_class("height_above_ground")


def test_declarations():
    assert Height.requires == (GROUND_SURFACE,)
    assert Height.provides == Height.writes == ("height_above_ground",)
    assert tiling.stage_reach("height_above_ground", Height.Options()) == MIN_BUFFER
    with pytest.raises(config.ConfigError, match=r"stages\[0\] height_above_ground needs 'ground_surface'"):
        config.from_mapping({"pipeline": "ground", "stages": [{"height_above_ground": {}}, {"cloth_ground": {}}]})


def test_heights_are_the_cloths():
    """After cloth_ground, the same heights as the cloth hands roof_filter (one cloth, one kernel)."""
    cloud = synthetic.generate("als-roof", 20_000, 1)
    specs = [(name, stage_class(name).Options()) for name in ("cloth_ground", "height_above_ground")]
    ctx = StageContext()
    result = pipelines.run(cloud, pipelines.build_stages(specs), ctx=ctx)
    height = result.extra_dims["height_above_ground"]
    ground = result.decided_by == 1
    assert np.isnan(height[ground]).all()           # removed by cloth_ground before the stage
    assert np.isfinite(height[~ground]).all()
    surface = ctx.facts[GROUND_SURFACE]
    order = np.flatnonzero(~ground)
    np.testing.assert_array_equal(height[order], surface.largest.height_above(cloud.xyz[order]))


def test_known_terrain():
    """A tilted plane with boxes on it: heights above the plane to a few cm, 0 on the ground."""
    rng = np.random.default_rng(4)
    n = 40_000
    xy = rng.uniform(0, 80, (n, 2))
    ground_z = 0.05 * xy[:, 0] + 0.02 * xy[:, 1]
    box = (np.abs(xy[:, 0] - 40) < 6) & (np.abs(xy[:, 1] - 40) < 6)
    z = ground_z + np.where(box, 5.0, 0.0) + rng.normal(0, 0.01, n)
    cloud = Cloud(xyz=np.column_stack([xy, z]).astype(np.float32), origin=np.zeros(3))
    stages = pipelines.build_stages([("cloth_smooth", stage_class("cloth_smooth").Options(cloth_resolution=1.0)),
                                     ("height_above_ground", Height.Options(clamp_negative=True))])
    result = pipelines.run(cloud, stages)
    height = result.extra_dims["height_above_ground"]
    kept = np.isfinite(height)                     # cloth_smooth keeps the ground only
    assert kept.sum() > 0.8 * (~box).sum()
    assert (height[kept] >= 0).all()
    assert np.abs(height[kept] - (z - ground_z)[kept]).max() < 0.1


def test_output_carries_the_dimension_and_labels_do_not_change(tmp_path):
    scene = tmp_path / "scene.laz"
    assert cli.main(["synth", "--kind", "als-roof", "--points", "20000", "--seed", "2", "-o", str(scene)]) == 0
    runs = {}
    for name, extra in (("plain", ""), ("hag", ", {height_above_ground: {}}")):
        path = tmp_path / f"{name}.yaml"
        path.write_text(textwrap.dedent(f"""\
            pipeline: roof
            backend: cpu
            output: {{report_png: false}}
            stages: [{{cloth_ground: {{}}}}, {{roof_seeds: {{}}}}, {{roof_growing: {{}}}}{extra}, {{roof_filter: {{}}}}]
            """))
        out = tmp_path / f"{name}.laz"
        assert cli.main(["run", str(path), "--input", str(scene), "--output", str(out)]) == 0
        runs[name] = laspy.read(out)
    assert "height_above_ground" not in runs["plain"].point_format.extra_dimension_names
    hag = np.asarray(runs["hag"]["height_above_ground"])
    assert hag.dtype == np.float32
    for dim in ("classification", "segment_id", "roadx_label"):
        np.testing.assert_array_equal(np.asarray(runs["plain"][dim]), np.asarray(runs["hag"][dim]))
    ground = np.asarray(runs["hag"].classification) == 2
    assert np.isnan(hag[ground]).all() and np.isfinite(hag[~ground]).mean() > 0.99
    building = np.asarray(runs["hag"].classification) == 6
    assert np.nanmedian(hag[building]) > 2.5       # roofs stand above the ground


def test_tiled_runs_carry_the_dimension_as_untiled_runs_do(tmp_path):
    """A tiled run writes the stage's heights too (each point's from its core tile), equal to the
    untiled run's where the two runs' cloths agree, and NaN where no tile's pipeline saw a point;
    in one merged LAZ and in per-file outputs."""
    scene = tmp_path / "scene.laz"
    assert cli.main(["synth", "--kind", "als-roof", "--points", "20000", "--seed", "2", "-o", str(scene)]) == 0
    path = tmp_path / "hag.yaml"
    path.write_text(textwrap.dedent("""\
        pipeline: roof
        backend: cpu
        output: {report_png: false}
        stages: [{cloth_ground: {}}, {roof_seeds: {}}, {roof_growing: {}}, {height_above_ground: {}}, {roof_filter: {}}]
        """))
    runs = {}
    for name, extra in (("untiled", []), ("tiled", ["--tile-size", "40"])):
        out = tmp_path / f"{name}.laz"
        assert cli.main(["run", str(path), "--input", str(scene), "--output", str(out), "--quiet", *extra]) == 0
        runs[name] = laspy.read(out)
    per_file = tmp_path / "per_file"
    assert cli.main(["run", str(path), "--input", str(scene), "--output", str(per_file), "--quiet",
                     "--tile-size", "40", "--set", "output.mode=per-file"]) == 0
    runs["per_file"] = laspy.read(per_file / "scene.laz")
    base = np.asarray(runs["untiled"]["height_above_ground"])
    for name in ("tiled", "per_file"):
        hag = np.asarray(runs[name]["height_above_ground"])
        assert hag.dtype == np.float32 and len(hag) == len(base)
        same_class = np.asarray(runs[name].classification) == np.asarray(runs["untiled"].classification)
        assert same_class.mean() > 0.99
        both = np.isfinite(hag) & np.isfinite(base)
        assert (np.isfinite(hag) == np.isfinite(base))[same_class].mean() > 0.99
        assert np.mean(np.abs(hag[both] - base[both]) < 0.01) > 0.99, name
    np.testing.assert_array_equal(np.asarray(runs["tiled"]["height_above_ground"]),
                                  np.asarray(runs["per_file"]["height_above_ground"]))
