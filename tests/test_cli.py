"""The real CLI end to end: synth -> run -> eval -> info, and the demo config on a small scene."""
import json
import subprocess
import sys
from pathlib import Path

import laspy
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def run_cli(*args, cwd=None, timeout=600):
    return subprocess.run([sys.executable, "-m", "roadx_ti", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


@pytest.fixture(scope="module")
def road_scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene") / "road.laz"
    proc = run_cli("synth", "--kind", "uav-road", "--points", "60k", "--seed", "3", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    return out


def test_synth_writes_truth(road_scene):
    las = laspy.read(road_scene)
    assert len(las.points) == 60_000
    assert (np.asarray(las.classification) == 11).any()


def test_run_demo_config_end_to_end(tmp_path, road_scene):
    out = tmp_path / "result.laz"
    before = road_scene.read_bytes()
    proc = run_cli("run", str(REPO / "configs" / "demo.yaml"), "--input", str(road_scene),
                   "--output", str(out), "--backend", "cpu", "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert "[Taichi]" not in proc.stderr and not proc.stdout   # --quiet: Taichi's start banner too
    assert road_scene.read_bytes() == before          # input untouched
    las = laspy.read(out)
    src = laspy.read(road_scene)
    assert len(las.points) == len(src.points)
    np.testing.assert_array_equal(las.X, src.X)        # coordinates bit-exact, input order
    assert {"roadx_label", "segment_id"} <= set(las.point_format.extra_dimension_names)
    classes = set(np.unique(np.asarray(las.classification)).tolist())
    assert 11 in classes and classes <= {1, 2, 6, 11}
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert [s["stage"] for s in summary["stages"]] == ["uniform_downsample", "sor", "ransac_planes",
                                                       "grid_slope", "cloth_smooth", "road_regions"]
    assert {"density_per_m2", "height_noise_m", "colour_noise"} <= set(summary["estimates"])
    assert summary["points"] == 60_000 and summary["accuracy"]["points"] == 60_000
    # accuracy proper is measured by `roadx_ti accuracy` on larger scenes; here: better than chance
    assert summary["accuracy"]["kappa"] > 0.2
    assert (tmp_path / "result.config.yaml").is_file() and (tmp_path / "result.png").is_file()
    # eval on the written prediction against the synthetic truth gives the summary's numbers
    proc = run_cli("eval", "--pred", str(out), "--truth", str(road_scene), "--truth-classes", "11")
    assert proc.returncode == 0, proc.stderr
    scores = json.loads(proc.stdout)
    assert scores["confusion"] == summary["accuracy"]["confusion"]
    assert abs(scores["kappa"] - summary["accuracy"]["kappa"]) < 1e-12


def test_eval_count_mismatch_is_data_error(tmp_path, road_scene):
    small = tmp_path / "small.laz"
    assert run_cli("synth", "--kind", "uav-road", "--points", "5k", "-o", str(small)).returncode == 0
    proc = run_cli("eval", "--pred", str(small), "--truth", str(road_scene), "--truth-classes", "11")
    assert proc.returncode == 1
    assert "counts must be equal" in proc.stderr and "Traceback" not in proc.stderr
    proc = run_cli("eval", "--pred", str(small), "--truth", str(small), "--truth-classes", "x")
    assert proc.returncode == 2 and "--truth-classes" in proc.stderr
    # an empty --pred-classes fell back to the truth classes silently
    proc = run_cli("eval", "--pred", str(small), "--truth", str(small), "--truth-classes", "11", "--pred-classes", "")
    assert proc.returncode == 2 and "--pred-classes '': names no class" in proc.stderr
    table = tmp_path / "classes.csv"
    table.write_text("x,y,z,classification\n0,0,0,2\n1,1,1,300\n")
    proc = run_cli("eval", "--pred", str(table), "--truth", str(table), "--truth-classes", "2")
    assert proc.returncode == 1 and "not classes 0..255" in proc.stderr     # was "has no classification"
    proc = run_cli("eval", "--pred", str(tmp_path), "--truth", str(small), "--truth-classes", "11")
    assert proc.returncode == 2 and "is a folder" in proc.stderr      # was "unknown extension '(none)'"
    proc = run_cli("synth", "--kind", "uav-road", "--points", "5k", "--seed", "-1", "-o", str(tmp_path / "n.laz"))
    assert proc.returncode == 2 and "seed must be >= 0" in proc.stderr and not (tmp_path / "n.laz").exists()


@pytest.mark.parametrize("args, option", [(("--road-large", "none", "--road-sizes", "1x"), "--road-sizes"),
                                          (("--road-seeds", "1-b"), "--road-seeds"),
                                          (("--roof-seeds", "a,b"), "--roof-seeds"),
                                          (("--road-large", "0"), "--road-large"),
                                          (("--roof-seeds", "5-1"), "--roof-seeds"),        # was an empty matrix
                                          (("--road-seeds", "0,0"), "names one seed twice"),  # ran each scene twice
                                          (("--road-large", "none", "--road-sizes", "1k,1k"), "names one size twice"),
                                          (("--road-sizes", "1k", "--road-seeds", "0", "--road-large", "1k"), "--road-large"),
                                          (("--road-sizes", "inf"), "--road-sizes")])     # was an OverflowError
def test_accuracy_bad_matrix_is_usage_error(tmp_path, args, option):
    """A typo in the accuracy matrix is a one-line usage error before any scene is built."""
    proc = run_cli("accuracy", "--out", str(tmp_path / "acc"), *args, timeout=120)
    assert proc.returncode == 2 and option in proc.stderr
    assert "Traceback" not in proc.stderr and "unexpected error" not in proc.stderr
    assert not (tmp_path / "acc").exists()


def test_info(road_scene):
    proc = run_cli("info", str(road_scene))
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    text = json.dumps(info)
    assert "60000" in text and "11" in text


def test_a_backend_this_machine_lacks_is_one_line_without_taichis_fallback(tmp_path):
    """Taichi warns that it falls back to the CPU and announces the CPU it started; neither may
    precede the one-line error (stderr holds that line and nothing else)."""
    from cli_helpers import bumpy_ground, write_las, write_tiny_config

    name = "cuda" if sys.platform == "darwin" else "metal"
    src = write_las(tmp_path / "ground.laz", bumpy_ground(500))
    proc = subprocess.run([sys.executable, "-m", "roadx_ti", "run", str(write_tiny_config(tmp_path)), "--input",
                           str(src), "--output", str(tmp_path / "out.laz"), "--backend", name, "--quiet"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"roadx_ti: backend '{name}' is not available on this machine "
                                                f"(tried {name})"], proc.stderr


def test_input_wildcard_pattern_reads_the_files_it_matches(tmp_path):
    """--input 'tiles/*.laz' (quoted, so no shell expands it) runs over every matching file, in
    sorted order, as a catalog; a pattern matching nothing is a one-line error, exit 2."""
    sys.path.insert(0, str(REPO / "tests"))
    from cli_helpers import bumpy_ground, write_las

    tiles = tmp_path / "tiles"
    tiles.mkdir()
    ground = bumpy_ground(4000, seed=2)
    write_las(tiles / "b.laz", ground + [30.0, 0.0, 0.0])
    write_las(tiles / "a.laz", ground)
    (tiles / "notes.txt").write_text("not a point file")
    out = tmp_path / "out" / "ground.laz"
    proc = run_cli("run", str(REPO / "configs" / "ground.yaml"), "--input", str(tiles / "*.laz"),
                   "--output", str(out), "--backend", "cpu", "--quiet", "--set", "output.dtm=false")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    assert [Path(f["path"]).name for f in summary["inputs"]] == ["a.laz", "b.laz"]
    assert len(laspy.read(out).points) == 8000
    proc = run_cli("run", str(REPO / "configs" / "ground.yaml"), "--input", str(tiles / "*.ply"),
                   "--output", str(out), "--backend", "cpu", "--quiet")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"roadx_ti: config error: input.paths = "
                                                f"'{tiles / '*.ply'}': no file matches the pattern"]


@pytest.mark.parametrize("args, said", [(["synth", "--kind", "uav-road", "--points", "1.5", "-o", "x.laz"],
                                         "a point count is a whole number"),
                                        (["run"], "the following arguments are required: config"),
                                        (["frobnicate"], "invalid choice: 'frobnicate'")])
def test_command_line_mistakes_are_one_line(tmp_path, args, said):
    """argparse's usage text (several lines) is for --help; a mistake is one line and exit 2."""
    from cli_helpers import error_line
    proc = run_cli(*args, cwd=tmp_path)
    line = error_line(proc, 2)
    assert said in line and "--help" in line


@pytest.mark.parametrize("args, said", [
    (["bench", "--quick", "--impls", "foo"], "unknown implementation(s) foo"),     # ran, 0 rows, exit 0
    (["bench", "--quick", "--threads", "0"], "--threads must be >= 1"),            # was accepted
    (["bench", "--quick", "--budget", "-1"], "--budget must be a number of seconds > 0"),
    (["bench", "--quick", "--timeout", "0"], "--timeout must be a number of seconds > 0"),  # every row an error
    (["bench", "--quick", "--sizes", ","], "--sizes names no size"),              # fell back to the defaults
    (["bench", "--quick", "--anchor-sizes", "7M"], "--anchor-sizes 7M not among the sizes"),
    (["bench", "--quick", "--out", "a_file"], "--out a_file: is a file"),         # failed after every case
    (["bench", "--quick", "--results", "."], "--results .: is a folder"),
    (["bench", "--render", "missing.json"], "--render missing.json: not a bench JSON record"),
    (["bench", "--render", "a_file"], "--render a_file: not a bench JSON record"),   # UnicodeDecodeError
    (["accuracy", "--task", "roof", "--out", "a_file"], "a_file: is a file; the accuracy report"),  # FileExistsError
    (["accuracy", "--task", "road", "--road-sizes", "1", "--out", "acc"],
     "a synthetic scene holds at least 1000 points, got '1'"),                     # skipped the row, exit 0
    (["accuracy", "--task", "road", "--backend", "bogus", "--out", "acc"],
     "backend 'bogus' is not one of"),                                             # left an empty folder acc
    (["bench", "--quick", "--sizes", "1"], "a synthetic scene holds at least 1000 points"),  # an error row, exit 0
    (["bench", "--render", "empty.json"], "--render empty.json: not a bench JSON record (no 'meta' and 'rows')"),
    (["bench", "--render", "list.json"], "not a bench JSON record (a JSON list, not an object)"),  # TypeError
    (["bench", "--render", "partial.json"], "not a complete bench JSON record (KeyError: 'machine')"),  # KeyError
    (["synth", "--kind", "uav-road", "--points", "1000", "--density", "1e-9", "-o", "x.laz"],
     "would be a scene 1,000.0 km across"),                                        # laid out for minutes
    (["run", str(REPO / "configs" / "ground.yaml"), "--input", "x.laz", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
     "config error: executor: give workers (a local cluster) or scheduler"),       # the whole config was printed
    (["synth", "--kind", "uav-road", "--points", "100", "-o", "made/deeper/x.laz"],
     "--points 100: a synthetic scene has at least 1000 points"),                  # 'n_points', left made/deeper
    (["synth", "--kind", "uav-road", "--points", "5000", "--density", "1e-9", "-o", "made/x.laz"],
     "would be a scene 2,236.1 km across"),                                        # left the folder made
    (["run", str(REPO / "configs" / "ground.yaml"), "--input", "x.laz", "--output", "a.laz", "--output", "b.laz"],
     "--output given twice; give it once"),                                        # wrote b.laz alone
    (["info", "nope.laz"], "nope.laz: no such file"),                              # exit 1, run's exit 2
    (["eval", "--pred", "nope.laz", "--truth", "nope.laz", "--truth-classes", "11"], "--pred nope.laz: no such file"),
    (["eval", "--pred", "a.laz", "--truth", "a.laz", "--truth-classes", "11", "--truth-classes", "2"],
     "--truth-classes given twice; give it once"),                                 # scored class 2 alone
    (["synth", "--kind", "uav-road", "--points", "2000", "--seed", "1", "--seed", "2", "-o", "x.laz"],
     "--seed given twice"),
    (["eval", "--pred", "a_file", "--truth", "tiles/*.laz", "--truth-classes", "11"],
     "--truth tiles/*.laz: a pattern; eval compares two files point by point"),    # 'no such file'
])
def test_mistakes_in_the_other_commands_are_one_line_before_any_work(tmp_path, args, said):
    """The bench, accuracy and synth options (and rules over several config keys) checked before any
    case, scene or run: one line, exit 2 (these were tracebacks as 'unexpected error ... please
    report it', silent exits 0 or runs of minutes). Nothing is written."""
    from cli_helpers import error_line
    (tmp_path / "a_file").write_bytes(b"\xea\x00 not json")
    (tmp_path / "empty.json").write_text("{}")
    (tmp_path / "list.json").write_text("[]")
    (tmp_path / "partial.json").write_text('{"meta": {}, "rows": []}')
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = run_cli(*args, cwd=tmp_path, timeout=120)
    line = error_line(proc, 2)
    assert said in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_eval_of_the_same_points_in_another_order_is_refused(tmp_path, road_scene):
    """eval matches points by order: a truth file holding the scene's points shuffled gave kappa
    near 0 without a word; the points' positions are compared first."""
    las = laspy.read(road_scene)
    las.points = las.points[np.random.default_rng(0).permutation(len(las.points))]
    las.write(tmp_path / "shuffled.laz")
    proc = run_cli("eval", "--pred", str(road_scene), "--truth", str(tmp_path / "shuffled.laz"), "--truth-classes", "11")
    from cli_helpers import error_line
    assert "both files must hold the same points in the same order" in error_line(proc, 1)


def test_repeated_input_takes_every_path():
    """--input given twice takes the paths of both (argparse kept the last: a file dropped unsaid)."""
    from roadx_ti.cli import _parser

    args = _parser().parse_args(["run", "c.yaml", "--input", "a.laz", "--input", "b.laz", "c.laz"])
    assert args.input == ["a.laz", "b.laz", "c.laz"]


def _tiny_las(path):
    from cli_helpers import bumpy_ground, write_las
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_las(path, bumpy_ground(400))


def test_double_star_pattern_reaches_every_depth(tmp_path):
    """'**' in a pattern matches any depth of folders, none included (it matched one level: half of
    the files, the run going on silently)."""
    for name in ("mix/t1.las", "mix/sub/t2.las", "mix/sub/deeper/t3.las"):
        _tiny_las(tmp_path / name)
    proc = run_cli("info", "mix/**/*.las", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert sorted(info["path"] for info in json.loads(proc.stdout)) == \
        ["mix/sub/deeper/t3.las", "mix/sub/t2.las", "mix/t1.las"]


def test_per_file_output_of_one_untiled_file_is_a_usage_error(tmp_path):
    """One file untiled has no per-file output (it said "unknown output format '(no extension)'");
    a pattern that matches several files is a catalog, whose per-file output goes on."""
    from cli_helpers import error_line
    src = _tiny_las(tmp_path / "one.las")
    proc = run_cli("run", str(REPO / "configs" / "ground.yaml"), "--input", str(src), "--output",
                   str(tmp_path / "pf"), "--output-mode", "per-file", "--backend", "cpu")
    assert "per-file writes one file per input of a catalog or tiled run" in error_line(proc, 2)
    assert not (tmp_path / "pf").exists()
    _tiny_las(tmp_path / "two.las")
    proc = run_cli("run", str(REPO / "configs" / "ground.yaml"), "--input", str(tmp_path / "*.las"), "--output",
                   str(tmp_path / "pf"), "--output-mode", "per-file", "--backend", "cpu", "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert {"one.las", "two.las"} <= {p.name for p in (tmp_path / "pf").iterdir()}


def test_environment_oddities(tmp_path):
    """HOME unset (Taichi's import aborted every command, even --version, with SIGABRT), TI_ARCH
    (it overrode --backend cpu: lavapipe's labels; an unknown name aborted), an ASCII-only output
    encoding (info --text of a non-ASCII name: 'unexpected error: UnicodeEncodeError')."""
    import os
    src = _tiny_las(tmp_path / "n\u00e4me.las")
    env = {k: v for k, v in os.environ.items() if k not in ("HOME", "TI_ARCH")}
    proc = subprocess.run([sys.executable, "-m", "roadx_ti", "--version"], capture_output=True, text=True, env=env)
    assert proc.returncode == 0 and "roadx_ti" in proc.stdout, proc.stderr
    env = dict(os.environ, TI_ARCH="bogus")
    proc = subprocess.run([sys.executable, "-m", "roadx_ti", "run", str(REPO / "configs" / "ground.yaml"), "--input",
                           str(src), "--output", str(tmp_path / "g.laz"), "--backend", "cpu"],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "TI_ARCH=bogus in the environment is ignored" in proc.stderr
    assert json.loads((tmp_path / "g.summary.json").read_text())["backend"] == "cpu"
    env = dict(os.environ, PYTHONIOENCODING="ascii")
    env.pop("TI_ARCH", None)
    proc = subprocess.run([sys.executable, "-m", "roadx_ti", "info", str(src), "--text"], capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 0 and "n\\xe4me.las" in proc.stdout, proc.stderr


def test_a_stopped_run_shuts_down_without_tracebacks():
    """After the one line of a stop, the shutdown prints nothing more: a Dask cluster stopped while it
    started printed tracebacks from its atexit close (an exception in an atexit callback) and
    tornado's log."""
    code = ("import atexit, logging, sys\n"
            "from roadx_ti import cli\n"
            "logging.basicConfig()\n"
            "def close_clusters():\n    raise AssertionError('Status.init')\n"
            "atexit.register(close_clusters)\n"
            "print(cli._left_behind(), file=sys.stderr)\n"
            "logging.getLogger('tornado.application').error('cannot access free variable')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stderr.strip() == "no partial output was left", proc.stderr


def test_eval_of_files_without_points_says_so(tmp_path):
    """Two files of no point: every measure null, and a warning saying why (it was silent)."""
    laspy.LasData(laspy.LasHeader(point_format=6, version="1.4")).write(tmp_path / "e.las")
    proc = run_cli("eval", "--pred", "e.las", "--truth", "e.las", "--truth-classes", "11", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["kappa"] is None
    assert "e.las and e.las hold no points; every measure is null" in proc.stderr


def test_closed_streams_and_a_full_disk(tmp_path):
    """stderr closed ('2>&-'): the run goes on (its banner write failed after the work, and the
    error went to stdout); stdout closed for a command whose results are its output: exit 2 in one
    line (exit 0, nothing); a full stdout (/dev/full): one line, exit 1 (it was 'unexpected error')."""
    import shlex
    src = _tiny_las(tmp_path / "g.las")
    cli = " ".join(shlex.quote(str(a)) for a in (sys.executable, "-m", "roadx_ti"))
    ground = shlex.quote(str(REPO / "configs" / "ground.yaml"))
    proc = subprocess.run(["bash", "-c", f"{cli} run {ground} --input g.las --output o.laz --backend cpu 2>&-"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0 and proc.stdout == "" and (tmp_path / "o.laz").is_file(), proc.stdout
    proc = subprocess.run(["bash", "-c", f"{cli} info g.las >&-"], capture_output=True, text=True, cwd=tmp_path,
                          timeout=120)
    assert proc.returncode == 2 and "standard output is closed" in proc.stderr, proc.stderr
    if Path("/dev/full").exists():
        proc = subprocess.run(["bash", "-c", f"{cli} info g.las > /dev/full"], capture_output=True, text=True,
                              cwd=tmp_path, timeout=120)
        assert proc.returncode == 1 and proc.stderr.strip() == "roadx_ti: no space left on device", proc.stderr


def test_config_copy_names_the_input_absolutely_and_tiled_summary_has_the_legend(tmp_path):
    """The written config names its input by absolute path (run again from its own folder, a relative
    'g.las' read another file); a tiled run's summary carries the backend, the roadx_label legend and
    the stages summed over the tiles, as the untiled one does; a .npy DTM's sidecar has no z_offset
    (its heights are world heights: the field said 20 m untiled and 0 tiled)."""
    import yaml
    src = _tiny_las(tmp_path / "g.las")
    proc = run_cli("run", str(REPO / "configs" / "ground.yaml"), "--input", "g.las", "--output", "out/t.laz",
                   "--tile-size", "10", "--backend", "cpu", "--quiet", "--set", "output.dtm=out/t.npy", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    written = yaml.safe_load((tmp_path / "out" / "t.config.yaml").read_text())
    assert written["input"]["paths"] == [str(src.resolve())]
    summary = json.loads((tmp_path / "out" / "t.summary.json").read_text())
    assert summary["backend"] == "cpu" and summary["roadx_label"] == {"0": "reached the last stage",
                                                                      "1": "removed by low_noise",
                                                                      "2": "removed by cloth_ground"}
    assert [s["stage"] for s in summary["stages"]] == ["low_noise", "cloth_ground"]
    assert summary["stages"][1]["points_in"] >= 400
    assert "z_offset" not in json.loads((tmp_path / "out" / "t.json").read_text())


def test_no_accuracy_without_truth_class_points_says_so(tmp_path):
    """A truth class no input point carries: the run gives no accuracy, and says why in its log
    (it had said nothing, so a mistyped class read as a missing feature)."""
    from cli_helpers import bumpy_ground, write_las, write_tiny_config

    src = write_las(tmp_path / "ground.laz", bumpy_ground(500))
    out = tmp_path / "out.laz"
    proc = run_cli("run", str(write_tiny_config(tmp_path)), "--input", str(src), "--output", str(out),
                   "--backend", "cpu", "--set", "evaluate.truth_classes=[17]")
    assert proc.returncode == 0, proc.stderr
    assert "no accuracy: no input point carries class 17" in proc.stderr
    assert "accuracy" not in json.loads(out.with_suffix(".summary.json").read_text())
