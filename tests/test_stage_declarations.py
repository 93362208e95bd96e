"""What a stage declares about itself (stages/base.py): its reach for tile buffers, what it
requires and provides (checked when the pipeline is built, in one line, before any input is read),
its options built once, and the ground surface a ground stage exports."""
from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from roadx_ti import config, pipelines, tiling
from roadx_ti.stages import REGISTRY, stage_class
from roadx_ti.stages.base import MIN_BUFFER, GroundSurface, Stage, StageOrderError, check_order

# the tile buffer of each stage at its default options, as the tiling's per-name table gave it
# before the stages declared their reach (the tile plans must not change)
DEFAULT_REACH = {
    "cloth_ground": 30.0, "cloth_smooth": 30.0, "grid_slope": MIN_BUFFER, "ransac_planes": 10.0,
    "color_growing": 10.0, "roof_seeds": 6.0, "roof_filter": round(2 * math.sqrt(10.0), 3),
    "uniform_downsample": MIN_BUFFER, "voxel_downsample": MIN_BUFFER, "sor": MIN_BUFFER,
    "road_regions": MIN_BUFFER, "roof_growing": MIN_BUFFER,
}
REQUIRED_OPTIONS = {"uniform_downsample": {"ratio": 0.5}, "voxel_downsample": {"voxel_size": 0.1}}


def test_every_registered_stage_declares_its_reach():
    for name in REGISTRY:
        cls = stage_class(name)
        assert cls.reach.__func__ is not Stage.reach.__func__, f"{name} declares no reach"
    with pytest.raises(NotImplementedError, match="declares no reach"):
        type("Bare", (Stage,), {"name": "bare"}).reach(None)


def test_reach_at_default_options_is_the_former_table():
    for name, expected in DEFAULT_REACH.items():
        options = stage_class(name).Options(**REQUIRED_OPTIONS.get(name, {}))
        assert round(tiling.stage_reach(name, options), 3) == expected, name


def test_reach_follows_the_options():
    Cloth, Seeds, Filter = (stage_class(n) for n in ("cloth_ground", "roof_seeds", "roof_filter"))
    assert Cloth.reach(Cloth.Options(cloth_resolution=3.0)) == 45.0
    assert stage_class("grid_slope").reach(stage_class("grid_slope").Options(step=2.0)) == 8.0
    # r_max 'auto' or off: the option's default until the estimates are known
    assert Seeds.reach(Seeds.Options(r_max="auto")) == Seeds.reach(Seeds.Options(r_max=None)) == 6.0
    auto = Seeds.reach(Seeds.Options(r_max="auto"), {"point_spacing_m": 0.5})
    from roadx_ti.stages.seeds import auto_r_max
    assert auto == pytest.approx(4.0 * auto_r_max(0.5, 10, 4.0))
    assert Filter.reach(Filter.Options(min_roof_area=0.0)) == Filter.reach(Filter.Options())


def test_a_stage_needing_data_no_earlier_stage_provides_fails_in_one_line():
    check_order(stage_class(n) for n in pipelines.DEFAULT_STAGES["roof"])
    with pytest.raises(StageOrderError) as err:
        pipelines.build_stages([(n, stage_class(n).Options()) for n in ("cloth_ground", "roof_growing")])
    message = str(err.value)
    assert "\n" not in message
    assert "stages[1] roof_growing needs 'normal', 'curvature', 'roof_seed'" in message
    assert "from roof_seeds)" in message
    with pytest.raises(config.ConfigError, match=r"^config error: stages\[0\] roof_filter needs 'roof_segment'"):
        config.from_mapping({"pipeline": "roof", "stages": [{"roof_filter": {}}, {"roof_growing": {}}]})


def test_a_stage_that_must_follow_another_directly_fails_in_one_line_when_it_does_not():
    """roof_growing grows over roof_seeds' kNN graph of the same working points: a stage between
    them (cloth_ground drops the ground) made it fail mid-run as an 'unexpected error' after the
    input was read and the earlier stages ran."""
    with pytest.raises(config.ConfigError, match=r"^config error: stages\[2\] roof_growing must follow roof_seeds "
                                                 r"directly"):
        config.from_mapping({"pipeline": "roof", "stages": [{"roof_seeds": {}}, {"cloth_ground": {}},
                                                            {"roof_growing": {}}, {"roof_filter": {}}]})
    check_order(stage_class(n) for n in ("cloth_ground", "roof_seeds", "roof_growing", "roof_filter"))


def test_wrong_stage_order_stops_the_cli_before_reading_the_input(tmp_path, capsys):
    from roadx_ti import cli

    path = tmp_path / "bad.yaml"
    path.write_text(textwrap.dedent("""\
        pipeline: roof
        input: {paths: [does_not_exist.laz]}
        stages: [{cloth_ground: {}}, {roof_filter: {}}]
        """))
    assert cli.main(["run", str(path), "--output", str(tmp_path / "x.laz")]) == cli.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "roof_filter needs 'roof_segment'" in err
    assert not (tmp_path / "x.laz").exists()


def test_stage_options_are_built_once():
    cfg = config.from_mapping({"pipeline": "road", "stages": [{"sor": {"k": 30}}, {"grid_slope": {}}]})
    first, second = cfg.stage_list(), cfg.stage_list()
    assert all(a is b for (_, a), (_, b) in zip(first, second))
    assert first[0][1].k == 30
    # a run uses those objects (the CLI and the tiling through pipeline_stages)
    assert all(a is b for (_, a), (_, b) in zip(cfg.pipeline_stages(), first))
    defaults = config.from_mapping({"pipeline": "roof"}).pipeline_stages()
    assert [name for name, _ in defaults] == pipelines.DEFAULT_STAGES["roof"]


def test_limits_and_defaults_have_one_home():
    import inspect

    from roadx_ti.kernels.cloth import csf
    from roadx_ti.kernels.neighbors import MAX_K
    from roadx_ti.kernels.outliers import sor_keep
    from roadx_ti.kernels.ransac import fit_plane
    from roadx_ti.kernels.regions import MAX_ROW

    sor = stage_class("sor").Options
    sor(k=MAX_K)
    with pytest.raises(ValueError):
        sor(k=MAX_K + 1)
    assert sor().mode == inspect.signature(sor_keep).parameters["mode"].default
    regions = stage_class("road_regions").Options
    regions(k=MAX_ROW - 1)
    with pytest.raises(ValueError):
        regions(k=MAX_ROW)
    cloth = stage_class("cloth_ground").Options()
    for name, parameter in inspect.signature(csf).parameters.items():
        if name in type(cloth).model_fields:
            assert getattr(cloth, name) == parameter.default, name
    assert stage_class("ransac_planes").Options().hypotheses == \
        inspect.signature(fit_plane).parameters["hypotheses"].default


class _Grid:
    """A flat grid at height ``z`` over [x0, x0 + (cols - 1) res] x [y0, y0 + (rows - 1) res]."""

    def __init__(self, x0, y0, z, rows=3, cols=3, resolution=1.0):
        self.x0, self.y0, self.resolution = x0, y0, resolution
        self.cloth_z = np.full((rows, cols), z, np.float32)

    def height_above(self, xyz):
        return (np.asarray(xyz)[:, 2] - self.cloth_z[0, 0]).astype(np.float32)


def test_ground_surface_of_several_parts():
    a, b = _Grid(0.0, 0.0, 1.0), _Grid(200.0, 0.0, 5.0)
    surface = GroundSurface(a, np.zeros(3), [a, b])
    xyz = np.array([[1.0, 1.0, 3.0], [201.0, 1.0, 7.5], [100.0, 1.0, 0.0]], np.float32)
    got = surface.height_above(xyz)
    np.testing.assert_array_equal(got[:2], [2.0, 2.5])
    assert np.isnan(got[2])                       # under no part's grid
    one = GroundSurface(a, np.zeros(3), [a]).height_above(xyz)
    assert one[0] == 2.0 and np.isnan(one[1:]).all()


def test_declared_point_data_reaches_the_output_per_input_point():
    from roadx_ti.cloud import Cloud
    from roadx_ti.stages.base import StageResult

    class Thin(Stage):
        name = "thin"

        def run(self, cloud, ctx):
            return StageResult(keep=np.arange(cloud.n) % 2 == 0)

    class Writer(Stage):
        name = "writer"
        writes = ("z_copy",)

        def run(self, cloud, ctx):
            return StageResult(point_data={"z_copy": cloud.xyz[:, 2].copy(), "not_written": cloud.xyz[:, 0]})

    rng = np.random.default_rng(0)
    xyz = rng.uniform(0, 50, (2000, 3)).astype(np.float32)
    result = pipelines.run(Cloud(xyz=xyz, origin=np.zeros(3)), [Thin(), Writer()])
    assert set(result.extra_dims) == {"z_copy"}
    z = result.extra_dims["z_copy"]
    seen = result.decided_by == 0
    np.testing.assert_array_equal(z[seen], xyz[seen, 2])
    assert np.isnan(z[~seen]).all() and seen.sum() == 1000
