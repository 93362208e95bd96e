"""Config validation: every mistake is one line naming the key, through the real CLI, exit 2."""
import subprocess
import sys
import textwrap

import pytest

from roadx_ti import config
from tests.cli_helpers import REPO

GOOD = {
    "pipeline": "road",
    "input": {"synthetic": {"kind": "uav-road", "points": 20000, "seed": 1}},
    "stages": [{"uniform_downsample": {"ratio": 0.5}}, {"grid_slope": {"step": 0.5}}],
}


def test_good_config_and_overrides():
    cfg = config.from_mapping(GOOD, ["stages.grid_slope.step=0.25", "seed=7", "output.path=x/y.laz",
                                     "stages.0.ratio=0.25", "stages.1.grid_slope.slope_max=0.2"])
    specs = dict(cfg.stage_list())
    assert specs["grid_slope"].step == 0.25
    assert specs["uniform_downsample"].ratio == 0.25
    assert specs["grid_slope"].slope_max == 0.2          # position and name of the same stage
    assert cfg.seed == 7 and cfg.output.path == "x/y.laz"
    assert cfg.truth_classes == [11]
    assert "grid_slope" in config.dump(cfg)
    assert config.from_mapping(GOOD, ["evaluate.truth_classes=6"]).truth_classes == [6]   # one class


def test_written_config_lists_what_ran_and_runs_the_same(tmp_path):
    """The config written beside an output names every stage that ran with all its options: a
    config that left 'stages' out gets the pipeline's defaults written, and loading the file
    again gives the same stages and options."""
    from roadx_ti import pipelines

    cfg = config.from_mapping({"pipeline": "road"})
    assert cfg.stage_list() == []
    path = tmp_path / "ran.yaml"
    path.write_text(config.dump(cfg))
    again = config.load(path)
    names = [name for name, _ in again.stage_list()]
    assert names == list(pipelines.DEFAULT_STAGES["road"])
    assert [(n, o.model_dump()) for n, o in again.stage_list()] == \
        [(n, o.model_dump()) for n, o in cfg.pipeline_stages()]
    tuned = config.from_mapping(GOOD, ["stages.grid_slope.step=0.25"])
    path.write_text(config.dump(tuned))
    assert [(n, o.model_dump()) for n, o in config.load(path).stage_list()] == \
        [(n, o.model_dump()) for n, o in tuned.stage_list()]


def test_memory_limit_in_bytes_as_a_number():
    """memory_limit=8000000000 (a number: YAML and --set give numbers) is 8 GB of bytes, like '8000000000'
    (it was refused as 'Input should be a valid string')."""
    assert config.from_mapping(GOOD, ["memory_limit=8000000000"]).memory_limit == "8000000000"
    assert config.from_mapping(GOOD, ["memory_limit=8G"]).memory_limit == "8G"


@pytest.mark.parametrize("mapping, overrides, expected", [
    ({"pipeline": "road", "colour": 1}, [], "colour = 1: unknown key"),
    ({"pipeline": "rod"}, [], "pipeline = 'rod'"),
    ({"threads": "many"}, [], "threads = 'many'"),
    ({"threads": 0}, [], "threads = 0"),
    ({"stages": [{"nope": {}}]}, [], "unknown stage 'nope'"),
    (GOOD, ["stages.grid_slope.step=0"], "stages[1].grid_slope.step = 0"),
    (GOOD, ["stages.grid_slope.step=-1"], "greater than or equal to 0.001"),
    (GOOD, ["stages.grid_slope.stepp=1"], "stages[1].grid_slope.stepp = 1: unknown key"),
    (GOOD, ["stages.grid_slope.step=abc"], "stages[1].grid_slope.step = 'abc'"),
    (GOOD, ["stages.sor.k=3"], "no stage 'sor'"),
    (GOOD, ["stages.1.uniform_downsample.ratio=0.5"], "stage 1 of this config is grid_slope, not uniform_downsample"),
    (GOOD, ["seed"], "expected KEY=VALUE"),
    ({"stages": [{"uniform_downsample": {}}]}, [], "exactly one of target_points, ratio or target_density"),
    ({"pipeline": "ground", "stages": []}, [], "stages: the list is empty"),
    (GOOD, ["memory_limit=0"], "must be more than 0 bytes"),
    (GOOD, ["memory_limit=lots"], "not a memory size"),
    (GOOD, ["evaluate.truth_classes=[999]"], "classes are integers 0..255"),
    # two stages of one name: the first changed silently
    ({"pipeline": "road", "stages": [{"sor": {"k": 20}}, {"sor": {"k": 10}}, {"road_regions": {}}]},
     ["stages.sor.k=7"], "has 2 sor stages (stages 0, 1); name one by its position, e.g. stages.0.sor.k"),
    # a filter after the labelling stage removed labelled points: exit 0 and no road at all
    ({"pipeline": "road", "stages": [{"road_regions": {}}, {"cloth_smooth": {}}, {"sor": {}}]}, [],
     "stages[1] cloth_smooth, stages[2] sor after stages[0] road_regions, which labels class 11, would remove"),
    # probe 16: a negative r_max ran and found no roof (kappa 0, exit 0); a negative height in metres
    # and output.dtm = 1 (read as true) were taken too
    ({"pipeline": "roof", "stages": [{"roof_seeds": {}}, {"roof_growing": {}}]}, ["stages.roof_seeds.r_max=-1"],
     "stages[0].roof_seeds.r_max = -1: Input should be greater than 0"),
    ({"pipeline": "roof", "stages": [{"roof_seeds": {}}, {"roof_growing": {}}]}, ["stages.roof_seeds.r_max=0"],
     "stages[0].roof_seeds.r_max = 0"),
    ({"pipeline": "roof", "stages": [{"roof_seeds": {}}, {"roof_growing": {}}, {"roof_filter": {}}]},
     ["stages.roof_filter.min_roof_height=-5"], "min_roof_height = -5: Input should be greater than or equal to 0"),
    (GOOD, ["output.dtm=1"], "output.dtm = 1"),
])
def test_config_errors_are_one_line(mapping, overrides, expected):
    with pytest.raises(config.ConfigError) as info:
        config.from_mapping(mapping, overrides)
    message = str(info.value)
    assert expected in message
    assert "\n" not in message


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "roadx_ti", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


@pytest.mark.parametrize("body, expected", [
    ("pipeline: road\nbogus: 1\n", "bogus = 1: unknown key"),
    ("pipeline: road\nstages:\n  - grid_slope: {step: -2}\n", "stages[0].grid_slope.step = -2"),
    ("pipeline: [unclosed\n", "is not valid YAML at line"),
    ("- a\n- b\n", "must hold a mapping"),
    ("pipeline: road\ninput: {paths: [does/not/exist.laz]}\n", "no such file"),
    ("pipeline: road\n", "give input.paths, input.synthetic or --input"),
    ("pipeline: road\nseed: 1\nseed: 2\n", "key 'seed' given twice (line 3)"),
    ("pipeline: road\nstages:\n  - sor: {k: 10, k: 12}\n", "key 'k' given twice (line 3)"),
])
def test_cli_config_errors_exit_2(tmp_path, body, expected):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(textwrap.dedent(body))
    proc = run_cli("run", str(cfg), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["road_uav.yaml", "roof_als.yaml"])
def test_a_refused_run_does_not_import_scipy(tmp_path, name):
    """A run its config check refuses stops before the stages' scipy work: the imports are the
    cost of most refusals (about 0.3 s of 1.6 s per CLI process at 2026-12-07)."""
    code = ("import sys\nfrom roadx_ti.cli import main\n"
            f"code = main(['run', {str(REPO / 'configs' / name)!r}, '--input', {str(tmp_path / 'none.laz')!r}, "
            f"'--output', {str(tmp_path / 'o.laz')!r}, '--quiet'])\n"
            "print(code, sorted({m.split('.')[0] for m in sys.modules} & {'scipy'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert out.stdout.strip() == "2 []", out.stdout + out.stderr


def test_cli_missing_config_and_usage(tmp_path):
    proc = run_cli("run", str(tmp_path / "none.yaml"))
    assert proc.returncode == 2 and "does not exist" in proc.stderr
    proc = run_cli()
    assert proc.returncode == 2
    proc = run_cli("--version")
    assert proc.returncode == 0 and "roadx_ti" in proc.stdout


def test_the_demo_runs_the_stages_of_road_uav():
    """configs/demo.yaml says it runs road_uav.yaml's stages: the resolved stage lists are equal."""
    from tests.conftest import REPO

    demo = config.load(REPO / "configs" / "demo.yaml").stage_list()
    road = config.load(REPO / "configs" / "road_uav.yaml").stage_list()
    assert [(n, o.model_dump()) for n, o in demo] == [(n, o.model_dump()) for n, o in road]


def test_a_stage_that_keeps_every_point_may_follow_the_labelling_stage():
    """height_above_ground after cloth_ground (README's example) computes and narrows nothing: taken."""
    cfg = config.from_mapping({"pipeline": "ground", "stages": [{"cloth_ground": {}},
                                                                {"height_above_ground": {"clamp_negative": False}}]})
    assert [name for name, _ in cfg.stage_list()] == ["cloth_ground", "height_above_ground"]
