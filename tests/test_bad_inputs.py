"""The bad-input catalogue: every case through the real CLI (python -m roadx_ti run ...).

Each case is a builder below: it writes its inputs into its own folder and says what the CLI must
do (its docstring documents the choice: an error, or a graceful result where an error would be
silly). For every case the test asserts the exit code, no traceback, the one-line message (or the
warning), that no output and no temporary file is left on failure (or that a previous output is
intact), and that no input file changed (sha256 before and after).

A `python -m roadx_ti` costs seconds before its work (imports, Taichi's start, loading its
kernels), so the module fixture runs the cases through the CLI's entry function, ``cli.main``, one
after another in one child process, and every SUBPROCESS_EVERY-th case (and those whose subject is
the process itself) through `python -m roadx_ti` beside it; each case is then checked by its own
test, the same checks whichever way it ran.
"""
from __future__ import annotations

import json
import os
import struct
import sys
import time
import subprocess
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import laspy
import numpy as np
import pytest

from cli_helpers import (CONFIGS, DEMO_FAST, bumpy_ground, error_line, partial_files, run_cli,
                         run_in_one_process, sha256, synth, write_las, write_tiny_config)

ROAD_CLASSES = {1, 2, 6, 11}
SUBPROCESS_EVERY = 16        # every 16th case (by name) runs through `python -m roadx_ti` instead
CALL_SECONDS = 300.0         # one case in the in-process driver (a cold kernel cache compiles in it)


@dataclass
class Case:
    args: list                      # arguments of `python -m roadx_ti`
    code: int                       # expected exit code
    message: str = ""               # failures: expected part of the one error line
    warning: str = ""               # graceful results: expected part of a stderr line
    output: Path | None = None      # the output the run would write
    previous: bytes | None = None   # an output that existed before the run and must survive
    check: Callable | None = None   # graceful results: check(case) on the written output
    hashes: dict = field(default_factory=dict)
    seconds: float = 0.0            # wall time of the CLI run (for tuning the suite's speed)
    proc: object = None             # the finished CLI run (for checks of stdout / stderr)
    reference: list | None = None   # arguments of a second CLI run the check compares with (run
    reference_proc: object = None   # alongside the cases), and its finished process
    max_seconds: float | None = None   # the run must finish within this (e.g. stray points far off)
    process: bool = False           # run through `python -m roadx_ti`: the case is about the process


def _run(config, folder: Path, *inputs, output=None, extra=(), code=1, **kw) -> Case:
    out = output if output is not None else folder / "out" / "result.laz"
    backend = [] if "--backend" in extra else ["--backend", "cpu"]     # an option is given once
    args = ["run", config, *backend, "--quiet", "--output", out, *extra]
    if inputs:
        args += ["--input", *inputs]
    return Case(args=args, code=code, output=Path(out), **kw)


def _tiny(folder: Path, *inputs, **kw) -> Case:
    return _run(write_tiny_config(folder), folder, *inputs, **kw)


def _demo(folder: Path, *inputs, extra=(), **kw) -> Case:
    return _run(CONFIGS / "demo.yaml", folder, *inputs, extra=[*DEMO_FAST, *extra], **kw)


def _las_result(case: Case, source: Path, classes=ROAD_CLASSES) -> laspy.LasData:
    """The written LAS/LAZ: every input point in input order, coordinates and header bit-exact."""
    out, src = laspy.read(case.output), laspy.read(source)
    assert len(out.points) == len(src.points)
    for dim in ("X", "Y", "Z"):
        np.testing.assert_array_equal(np.asarray(out[dim]), np.asarray(src[dim]))
    np.testing.assert_array_equal(out.header.scales, src.header.scales)
    np.testing.assert_array_equal(out.header.offsets, src.header.offsets)
    assert set(np.unique(np.asarray(out.classification)).tolist()) <= classes
    assert {"roadx_label", "segment_id"} <= set(out.point_format.extra_dimension_names)
    return out


# ------------------------------------------------------------------------------------- cases
def case_missing_file(d):
    """An input that does not exist: a usage/config error (exit 2) naming it, before any work."""
    return _tiny(d, d / "in" / "nope.laz", code=2, message="no such file")


def case_empty_file(d):
    """A 0-byte file: a data error (exit 1)."""
    (d / "in" / "empty.laz").write_bytes(b"")
    return _tiny(d, d / "in" / "empty.laz", message="empty file (0 bytes)")


def case_not_a_las_file(d):
    """Text bytes under a .laz name: a data error, 'not a LAS/LAZ file'."""
    (d / "in" / "notes.laz").write_text("these are not points\n" * 20)
    return _tiny(d, d / "in" / "notes.laz", message="not a LAS/LAZ file")


def case_zero_points(d):
    """A valid LAS file with 0 points: a data error ('holds no points'); an empty result file
    would only hide the mistake."""
    write_las(d / "in" / "zero.las", np.zeros((0, 3)))
    return _demo(d, d / "in" / "zero.las", message="holds no points")


def case_one_point(d):
    """1 point through the whole road pipeline: a graceful result, a valid output with that one
    point (every stage copes with n = 1: SOR is skipped, RANSAC finds no plane)."""
    src = write_las(d / "in" / "one.las", bumpy_ground(1))
    return _demo(d, src, code=0, check=lambda c: _las_result(c, src))


def case_two_points(d):
    """2 points through the whole road pipeline: a graceful, valid output."""
    src = write_las(d / "in" / "two.las", bumpy_ground(2))
    return _demo(d, src, code=0, check=lambda c: _las_result(c, src))


def _with_top_view(case: Case, src: Path) -> None:
    _las_result(case, src)
    assert case.output.with_suffix(".png").stat().st_size > 0


def case_three_points_with_the_top_view(d):
    """3 points without colour, the top-view PNG on (the catalogue's other runs leave it off): a
    picture a pixel or two across has no slope to shade, and is written all the same."""
    src = write_las(d / "in" / "three.las", bumpy_ground(3))
    return _demo(d, src, code=0, extra=["--set", "output.report_png=true"], check=lambda c: _with_top_view(c, src))


def case_a_line_of_points_with_the_top_view(d):
    """50 points on one line (a scan line, a profile), the top-view PNG on: a graceful result."""
    xyz = np.column_stack([500_000.0 + 0.3 * np.arange(50), np.full(50, 4_500_000.0), np.full(50, 100.0)])
    src = write_las(d / "in" / "line.las", xyz)
    return _demo(d, src, code=0, extra=["--set", "output.report_png=true"], check=lambda c: _with_top_view(c, src))


def _ground_laz(d, name="ground.laz", n=3000) -> Path:
    return write_las(d / "in" / name, bumpy_ground(n))


def case_truncated_laz(d):
    """A LAZ file cut in half: a data error; a previous output of the same name stays intact."""
    data = _ground_laz(d, "full.laz").read_bytes()
    (d / "in" / "full.laz").unlink()
    (d / "in" / "cut.laz").write_bytes(data[: len(data) // 2])
    (d / "out").mkdir()
    (d / "out" / "result.laz").write_bytes(b"previous result")
    return _tiny(d, d / "in" / "cut.laz", message="truncated or corrupt", previous=b"previous result")


def case_corrupt_laz(d):
    """Garbage bytes in the compressed point data (header intact): a data error."""
    src = _ground_laz(d, "bad.laz")
    with laspy.open(src) as reader:
        start = reader.header.offset_to_point_data
    data = bytearray(src.read_bytes())
    data[start + 200: start + 2200] = np.random.default_rng(1).integers(0, 256, 2000, dtype=np.uint8).tobytes()
    src.write_bytes(bytes(data))
    return _tiny(d, src, message="truncated or corrupt")


def case_nan_coordinates(d):
    """A NaN coordinate in a text file (LAS cannot hold NaN): a data error counting the points."""
    xyz = bumpy_ground(500)
    xyz[17, 2] = np.nan
    np.savetxt(d / "in" / "nan.xyz", xyz, fmt="%.3f")
    return _tiny(d, d / "in" / "nan.xyz", message="1 of 500 points have NaN or infinite coordinates")


def case_infinite_coordinates(d):
    """+inf and -inf coordinates in an NPZ file: a data error counting the points."""
    xyz = bumpy_ground(500)
    xyz[3, 0], xyz[4, 1] = np.inf, -np.inf
    np.savez(d / "in" / "inf.npz", xyz=xyz)
    return _tiny(d, d / "in" / "inf.npz", message="2 of 500 points have NaN or infinite coordinates")


def case_all_points_identical(d):
    """500 copies of one point through the whole road pipeline: a graceful, valid output in which
    all points (being the same point) get the same class and roadx_label."""
    src = write_las(d / "in" / "same.las", np.repeat(bumpy_ground(1), 500, axis=0))

    def check(c):
        out = _las_result(c, src)
        assert len(np.unique(np.asarray(out.classification))) == 1
        assert len(np.unique(np.asarray(out["roadx_label"]))) == 1
    return _demo(d, src, code=0, check=check)


def case_many_duplicates(d):
    """300 distinct points, each 10 times, through the whole road pipeline: a graceful result in
    which the copies of a point all get the same class (every test is on coordinates only)."""
    base = bumpy_ground(300, side=6.0)
    src = write_las(d / "in" / "dups.laz", np.tile(base, (10, 1)))

    def check(c):
        classes = np.asarray(_las_result(c, src).classification).reshape(10, 300)
        assert (classes == classes[0]).all()
    return _demo(d, src, code=0, check=check)


def case_utm_1e7_las(d):
    """Coordinates near 10^7 m at 1 cm scale: the output's X/Y/Z integers (and header scale and
    offset) equal the input's; a flat ground keeps nearly every point through grid_slope, which
    float32 world coordinates (7 digits) could not do."""
    xyz = bumpy_ground(2000, seed=3) + [9_400_000.0, 5_400_000.0, 0.0]
    src = write_las(d / "in" / "far.laz", np.round(xyz, 2), scale=0.01, offset=np.zeros(3))

    def check(c):
        out = _las_result(c, src)
        assert (np.asarray(out["roadx_label"]) == 0).mean() > 0.9   # grid_slope removed < 10 %
    return _tiny(d, src, code=0, check=check)


def case_utm_1e7_text(d):
    """The same 10^7 m cloud with centimetre detail as text (no scale in the file): the output LAZ
    (1 mm scale) holds every input coordinate exactly to the centimetre."""
    xyz = np.round(bumpy_ground(2000, seed=4) + [9_400_000.0, 5_400_000.0, 0.0], 2)
    np.savetxt(d / "in" / "far.xyz", xyz, fmt="%.2f")

    def check(c):
        out = laspy.read(c.output)
        world = np.column_stack([out.x, out.y, out.z])
        assert np.abs(world - xyz).max() < 1e-6
    return _tiny(d, d / "in" / "far.xyz", code=0, check=check)


def _colour_config(d, source="auto") -> Path:
    return write_tiny_config(d, f"""\
        pipeline: road
        output: {{report_png: false}}
        stages:
          - color_growing: {{k: 12, point_threshold: 10, region_threshold: 60, min_region_size: 20,
                             target: largest, color_source: {source}}}
        """)


def _patch(seed=0, n=3000):
    """Two colour patches (grey road, green verge) on a flat ground."""
    xyz = bumpy_ground(n, seed=seed, side=15.0)
    road = (xyz[:, 0] - 500_000.0) < 9.0
    rgb = np.where(road[:, None], [[110, 110, 112]], [[60, 140, 50]])
    rgb = rgb + np.random.default_rng(seed).integers(-2, 3, rgb.shape)
    return xyz, rgb.astype(np.uint16), road


def case_colour_stage_without_colour(d):
    """color_growing on a cloud with neither colour nor intensity: a warning, then growing on
    geometry; a valid output."""
    src = write_las(d / "in" / "grey.laz", bumpy_ground(1500, side=8.0))
    return _run(_colour_config(d), d, src, code=0, warning="no colour and no intensity",
                check=lambda c: _las_result(c, src))


def case_road_without_colour_or_intensity(d):
    """The road pipeline on points with neither colour nor intensity: a warning that the road is chosen
    by kerbs and shape alone (it switched silently, finding much less road), then a valid output."""
    src = write_las(d / "in" / "grey.laz", bumpy_ground(3000, side=30.0))
    return _demo(d, src, code=0, warning="no colour and no intensity: the road",
                 check=lambda c: _las_result(c, src))


def case_road_with_one_colour_for_every_point(d):
    """The road pipeline on colour fields holding one grey for every point (a writer's placeholder):
    a warning that says so (it said the points carry no colour)."""
    src = write_las(d / "in" / "grey.laz", bumpy_ground(3000, side=30.0), rgb=np.full((3000, 3), 128 * 256))
    return _demo(d, src, code=0, warning="one colour for every point and no intensity: the road",
                 check=lambda c: _las_result(c, src))


def case_colour_8_and_16_bit(d):
    """The same colours stored 8-bit (0-255) and 16-bit (x 257): identical labels (thresholds are
    in 8-bit units), the colours written back bit-exact, and the grey road patch found."""
    xyz, rgb, road = _patch()
    src8 = write_las(d / "in" / "c8.laz", xyz, rgb=rgb)
    src16 = write_las(d / "in" / "c16.laz", xyz, rgb=rgb * 257)
    out16 = d / "out" / "result16.laz"

    def check(c):
        out8 = _las_result(c, src8)
        proc = run_cli("run", _colour_config(d), "--backend", "cpu", "--quiet", "--input", src16,
                       "--output", out16)
        assert proc.returncode == 0, proc.stderr
        c16 = Case(args=[], code=0, output=out16)
        out16_las = _las_result(c16, src16)
        np.testing.assert_array_equal(np.asarray(out8.classification), np.asarray(out16_las.classification))
        for name, src, o in (("8", src8, out8), ("16", src16, out16_las)):
            s = laspy.read(src)
            for ch in ("red", "green", "blue"):
                np.testing.assert_array_equal(np.asarray(o[ch]), np.asarray(s[ch]), err_msg=name)
        target = np.asarray(out8.classification) == 11
        assert (target == road).mean() > 0.9    # the largest region is the grey road
    return _run(_colour_config(d), d, src8, code=0, check=check)


def case_wrong_typed_key(d):
    """A wrong-typed value given with --set: exit 2, the key and the value named."""
    src = _ground_laz(d)
    return _tiny(d, src, extra=["--set", "stages.grid_slope.slope_max=steep"], code=2,
                 message="stages[1].grid_slope.slope_max = 'steep'")


def case_unknown_key(d):
    """An unknown top-level key given with --set: exit 2, 'unknown key'."""
    src = _ground_laz(d)
    return _tiny(d, src, extra=["--set", "colour=true"], code=2, message="colour = True: unknown key")


def case_empty_stage_list(d):
    """'stages: []' in the config: exit 2 before any work, not the pipeline's defaults run in its
    place (leaving the key out is how to ask for those)."""
    src = _ground_laz(d)
    config = d / "empty_stages.yaml"
    config.write_text("pipeline: ground\nstages: []\n")
    return _run(config, d, src, code=2, message="stages: the list is empty")


def case_empty_config(d):
    """An empty config file (or one truncated to nothing) is a mistake, not "every default": exit 2."""
    config = d / "in" / "empty.yaml"
    config.write_text("")
    return _run(config, d, write_las(d / "in" / "ground.las", bumpy_ground(500)), code=2, message="is empty")


def case_config_is_a_folder(d):
    """A folder where the config goes (a path typed one level short): exit 2, 'is a folder' (it said
    the config 'does not exist', which it does)."""
    config = d / "in" / "configs"
    config.mkdir()
    return _run(config, d, write_las(d / "in" / "ground.las", bumpy_ground(500)), code=2, message="is a folder")


def case_config_not_utf8(d):
    """A config saved in Latin-1 (a comment with 'café'): exit 2 in one line saying it is not UTF-8
    (it was 'unexpected error: UnicodeDecodeError', exit 1)."""
    config = d / "in" / "latin1.yaml"
    config.write_bytes(b"pipeline: ground\n# caf\xe9\n")
    return _run(config, d, write_las(d / "in" / "ground.las", bumpy_ground(500)), code=2, message="is not UTF-8")


def case_config_with_a_list_as_a_key(d):
    """YAML's complex key ('? [a, b]'): exit 2, 'not a name' (it was 'unexpected error: TypeError')."""
    config = d / "in" / "listkey.yaml"
    config.write_text("pipeline: ground\n? [a, b]\n: 1\n")
    return _run(config, d, write_las(d / "in" / "ground.las", bumpy_ground(500)), code=2, message="is not a name")


def case_output_name_too_long(d):
    """An output name of 200 bytes (its temporary file and sidecars would pass the file system's 255):
    exit 1 before any work, with the longest name allowed (it was 'unexpected error: OSError' after
    the run)."""
    return _tiny(d, _ground_laz(d), output=d / "out" / ("r" * 200 + ".laz"), message="the file name is too long")


def case_text_reflectance_into_las(d):
    """A text table X Y Z and a float reflectance 0-1 (read as the intensity column, which LAS holds as
    integers) written to .laz: exit 1 naming the column before the pipeline runs (it failed only at
    the write, after the whole run)."""
    rng = np.random.default_rng(4)
    src = d / "in" / "scan.txt"
    np.savetxt(src, np.column_stack([bumpy_ground(800), rng.uniform(0, 1, 800)]), fmt="%.4f")
    return _tiny(d, src, message="does not fit the LAS intensity field")


def case_a_folder_where_the_config_copy_goes(d):
    """A folder named like the run's copy of its config (out/result.config.yaml/): exit 1 before any
    work, and no output (result.laz and its DTM were written first, then the sidecar failed)."""
    (d / "out" / "result.config.yaml").mkdir(parents=True)
    return _tiny(d, _ground_laz(d), message="is a folder where the run writes its config file")


def case_input_from_standard_input(d):
    """``--input -`` (standard input, as some tools take it) is not supported: exit 2, saying so."""
    return _tiny(d, "-", code=2, message="standard input is not supported")


def case_per_file_output_named_like_a_file(d):
    """``output.mode per-file`` with ``--output result.laz``: one file per input goes into a folder, so
    a file name is refused (it was made a folder called result.laz): exit 2, nothing made."""
    tiles = _tiles_folder(d)
    return _tiny(d, tiles, extra=["--set", "output.mode=per-file"], code=2, message="give a folder")


def case_synth_beyond_memory(d):
    """``synth --points 1e12`` (meant: 1e7) is refused at once with the memory the scene would need,
    instead of laying out a city for minutes and then failing: exit 2, nothing written."""
    out = d / "out" / "scene.laz"
    return Case(args=["synth", "--kind", "uav-road", "--points", "1e12", "-o", out], code=2,
                message="needs about", output=out, max_seconds=60)


def case_zero_cell_size(d):
    """grid_slope.step = 0: exit 2 before any work, the key named."""
    src = _ground_laz(d)
    return _tiny(d, src, extra=["--set", "stages.grid_slope.step=0"], code=2,
                 message="stages[1].grid_slope.step = 0")


def case_negative_cloth_resolution(d):
    """cloth_smooth.cloth_resolution = -1 in the demo config: exit 2, the key named."""
    src = _ground_laz(d)
    return _demo(d, src, extra=["--set", "stages.cloth_smooth.cloth_resolution=-1"], code=2,
                 message="stages[4].cloth_smooth.cloth_resolution = -1")


def _option_refused(d, config, assignment: str, message: str) -> Case:
    """``--set assignment`` on ``config`` (a file name in configs/): exit 2 with ``message``."""
    return _run(CONFIGS / config, d, _ground_laz(d), extra=["--set", assignment, "--set", "output.report_png=false"], code=2,
                message=message)


def case_misspelt_road_weight(d):
    """A misspelt road selection weight (road_regions.weights.colr): exit 2 before the input is
    read, the key named and the known ones listed (it was a TypeError at the road stage)."""
    return _option_refused(d, "demo.yaml", "stages.road_regions.weights.colr=1",
                           "stages[5].road_regions.weights = {'colr': 1}: unknown weight 'colr'")


def case_a_tile_size_of_1e_300(d):
    """--tile-size 1e-300: exit 2 with the tile count and a size to use (an OverflowError of the
    tile plan's cell indices)."""
    return _tiny(d, _ground_laz(d), extra=["--tile-size", "1e-300"], code=2,
                 message="--tile-size 1e-300 gives about", max_seconds=60)


def case_yaml_merge_key(d):
    """A config whose stage options merge an anchor (<<: *sor, YAML's merge key): it runs, the
    stage's own keys over the merged ones (it was 'not valid YAML'); a float written without a
    point (5e-1) is a number (YAML 1.2; PyYAML read it as text)."""
    config = d / "merge.yaml"
    config.write_text("pipeline: road\noutput: {path: out/result.laz, report_png: false}\nstages:\n"
                      "  - uniform_downsample: &sample {ratio: 1.0}\n"
                      "  - grid_slope: {step: 5e-1, slope_max: 0.1, dh_max: 1.0}\n"
                      "  - uniform_downsample: {<<: *sample, ratio: 0.5}\n")
    src = _ground_laz(d)

    def check(c):
        assert len(laspy.read(c.output).points) == 3000
        echoed = (c.output.parent / "result.config.yaml").read_text()
        assert "ratio: 0.5" in echoed and "step: 0.5" in echoed, echoed
    return _run(config, d, src, code=0, check=check)


# Options refused in one line, exit 2, before the input is read: (assignment, message, what it
# was). Numbers are numbers (roadx_ti.option_rules), cells at least 1 mm, the pipeline that of its
# labelling stage.
REFUSED_OPTIONS = {
    "a_boolean_for_a_count": ("stages.sor.k=true", "stages[1].sor.k = True: must be a number, not True",
                              "ran SOR with k = 1"),
    "a_text_for_a_count": ("stages.sor.k='20'", "stages[1].sor.k = '20': must be a number, not '20'",
                           "ran as the number 20"),
    "booleans_for_classes": ("evaluate.truth_classes=[true]", "must be numbers, not True", "scored class 1"),
    "nan_for_a_threshold": ("stages.sor.std_ratio=.nan", "stages[1].sor.std_ratio = nan: Input should be a finite "
                            "number", "passed gt=0's check unseen"),
    "infinite_cloth_resolution": ("stages.cloth_smooth.cloth_resolution=.inf", "cloth_resolution = inf: Input "
                                  "should be a finite number", "a NaN-to-integer error in the cloth kernel"),
    "a_cell_of_1e_300": ("stages.grid_slope.step=1e-300", "stages[3].grid_slope.step = 1e-300: Input should be "
                         "greater than or equal to 0.001", "an OverflowError of the cell keys"),
    "pipeline_unlike_its_stages": ("pipeline=roof", "pipeline = 'roof', but stages[5] road_regions labels class 11 "
                                   "(road), not 6", "wrote class 11, scored class 6: no accuracy"),
    "a_boolean_for_a_number_or_auto": ("stages.grid_slope.noise_allowance=true", "noise_allowance = True: must be a "
                                       "number, not True", "took it as 1.0"),
    "a_text_for_a_number_or_auto": ("stages.grid_slope.noise_allowance=autox", "noise_allowance = 'autox': must be "
                                    "a number or 'auto', not 'autox'", "was refused only for its type"),
    "a_boolean_for_a_buffer": ("tiling.buffer=true", "tiling.buffer = True: must be a number, not True",
                               "took it as a 1 m buffer"),
    "no_truth_class": ("evaluate.truth_classes=[]", "evaluate.truth_classes = []: names no class",
                       "fell back to the pipeline's class silently"),
}


def _refused_option_case(assignment: str, message: str, was: str):
    def case(d):
        return _option_refused(d, "demo.yaml", assignment, message)
    case.__doc__ = f"--set {assignment} on the demo config: exit 2 (it {was})."
    return case


for _name, _spec in REFUSED_OPTIONS.items():
    globals()["case_" + _name] = _refused_option_case(*_spec)


def case_road_weight_not_a_number(d):
    """road_regions.weights.colour = 'abc': exit 2, the weight named (it was a numpy error)."""
    return _option_refused(d, "demo.yaml", "stages.road_regions.weights.colour=abc",
                           "weight 'colour' must be a finite number, not 'abc'")


def case_colour_levels_descending(d):
    """road_regions.colour_levels [3, 2] (the merge's thresholds must ascend): exit 2."""
    return _option_refused(d, "demo.yaml", "stages.road_regions.colour_levels=[3,2]",
                           "colour_levels must be positive and ascending, not [3.0, 2.0]")


def case_roof_reach_beyond_any_building(d):
    """roof_filter.annex_reach = 1e9 m: exit 2 before the input is read (the annex rule spanned
    reach / cell cells around every point and the run was killed for memory)."""
    return _option_refused(d, "roof_als.yaml", "stages.roof_filter.annex_reach=1e9",
                           "stages[5].roof_filter.annex_reach = 1000000000.0: Input should be less than or equal to 100")


def case_roof_covered_cell_zero(d):
    """roof_growing.covered_cell = 0 (a number or 'auto'): exit 2, both choices named (it was a
    ValueError from the grid)."""
    return _option_refused(d, "roof_als.yaml", "stages.roof_growing.covered_cell=0",
                           "stages[4].roof_growing.covered_cell = 0: Input should be greater than or equal to "
                           "0.001, or Input should be 'auto'")


def case_k_larger_than_cloud(d):
    """sor.k = 500 and road_regions.k = 32 on 60 points: a graceful result; SOR says it uses
    k = n - 1 (a warning) and the output is valid."""
    xyz, rgb, _ = _patch(n=60)
    src = write_las(d / "in" / "few.laz", xyz, rgb=rgb)
    return _demo(d, src, extra=["--set", "stages.sor.k=500", "--set", "stages.road_regions.k=32",
                                "--set", "stages.uniform_downsample.target_density=null",
                                "--set", "stages.uniform_downsample.ratio=1.0"],
                 code=0, warning="sor: k = 500 but only 60 points", check=lambda c: _las_result(c, src))


def case_output_under_a_file(d):
    """An output 'folder' that is a regular file (chmod cannot stop root, this can): exit 1."""
    src = _ground_laz(d)
    (d / "out").mkdir()
    (d / "out" / "plain").write_text("a file, not a folder")
    return _tiny(d, src, output=d / "out" / "plain" / "result.laz", message="cannot create the output folder")


def case_output_is_a_folder(d):
    """--output naming an existing folder (a file was meant): exit 1, a file name suggested; it
    was 'unknown output format' for a single input."""
    src = _ground_laz(d)
    (d / "out").mkdir()
    return _tiny(d, src, output=d / "out", message="is a folder, expected an output file name")


def case_output_in_proc(d):
    """An output in /proc, where no file can be created even by root: exit 1 with one line; the
    pipeline runs, then the atomic writer cannot create its temporary file."""
    src = _ground_laz(d)
    return _tiny(d, src, output=Path("/proc") / f"roadx_ti_test_{os.getpid()}.laz",
                 message="cannot create a file in the output folder /proc")


def case_output_is_input(d):
    """--output naming the input file itself: exit 1, refused before any work."""
    src = _ground_laz(d)
    return _tiny(d, src, output=src, message="refusing to write over the input file")


def case_output_is_input_through_link(d):
    """--output a symbolic link to the input: exit 1, refused (same file)."""
    src = _ground_laz(d)
    (d / "out").mkdir()
    (d / "out" / "link.laz").symlink_to(src)
    return _tiny(d, src, output=d / "out" / "link.laz", message="refusing to write over the input file")


def case_unknown_output_format(d):
    """An output name with no point-cloud extension: exit 2 before any work (not after the run)."""
    src = _ground_laz(d)
    return _tiny(d, src, output=d / "out" / "result.las.bak", code=2, message="unknown output format '.bak'")


def case_more_points_than_an_array_holds(d):
    """A LAS 1.4 header claiming 2^31 + 5 points (more than 32-bit indices address): exit 1 with
    a message pointing to tiling, from the header alone (nothing is allocated)."""
    src = write_las(d / "in" / "huge.las", bumpy_ground(10))
    data = bytearray(src.read_bytes())
    struct.pack_into("<Q", data, 247, 2**31 + 5)     # LAS 1.4 64-bit point count
    src.write_bytes(bytes(data))
    return _tiny(d, src, message="split it into tiles")


def case_text_with_two_columns(d):
    """A text table of 2 columns: exit 1, 'expected X Y Z'."""
    np.savetxt(d / "in" / "xy.txt", bumpy_ground(50)[:, :2], fmt="%.2f")
    return _tiny(d, d / "in" / "xy.txt", message="expected X Y Z")


def case_backend_not_on_this_machine(d):
    """--backend metal off macOS (cuda on macOS: neither can exist there): exit 2, one line
    naming the backend."""
    name = "cuda" if sys.platform == "darwin" else "metal"
    src = _ground_laz(d)
    # a process whose Taichi is started already uses that (an embedding host's choice)
    return _tiny(d, src, extra=["--backend", name], code=2, message=f"backend '{name}' is not available",
                 process=True)


# ------------------------------------------------------------- issue 18: real survey files
# A stray point kilometres away sized the cloth, the grids and the tile plan by its extent (the
# roof pipeline ran > 3 min on 20,000 points + 2 strays). Now such a run takes seconds, every other
# point gets the label it gets without the strays, and the strays are class 1.
STRAY_OFFSETS = np.array([[20_000.0, 0.0, 0.0], [0.0, -20_000.0, -300.0]])


def _stray_case(d, xyz, config, extra=(), rgb=None, classes=ROAD_CLASSES):
    """``xyz`` with two strays 20 km away inserted among them; the check runs the same config on
    the points without the strays and compares labels."""
    at = [len(xyz) // 3, 2 * len(xyz) // 3]
    strays = xyz[at[0]] + STRAY_OFFSETS
    offset = np.floor(xyz.min(axis=0))
    plain = write_las(d / "in" / "plain.laz", xyz, rgb=rgb, offset=offset)
    src = write_las(d / "in" / "strays.laz", np.insert(xyz, at, strays, axis=0), offset=offset,
                    rgb=None if rgb is None else np.insert(rgb, at, rgb[at], axis=0))
    others = np.ones(len(xyz) + 2, bool)
    others[np.array(at) + np.arange(2)] = False

    reference = d / "reference" / "plain.laz"

    def check(c):
        out = _las_result(c, src, classes)
        assert c.reference_proc.returncode == 0, c.reference_proc.stderr
        got, want = np.asarray(out.classification), np.asarray(laspy.read(reference).classification)
        assert (got[others] == want).mean() >= 0.999
        assert (got[~others] == 1).all()
    case = _run(config, d, src, extra=extra, code=0, check=check, max_seconds=90.0)
    case.reference = ["run", config, "--backend", "cpu", "--quiet", "--input", plain, "--output", reference, *extra]
    return case


def case_strays_roof_pipeline(d):
    """The issue's case: a roof scene of 20,000 points and two strays 20 km away (one also 300 m
    down), configs/roof_als.yaml: a valid output in seconds, the others labelled as without them."""
    cloud = _synthetic(d, "als-roof", 20_000)
    return _stray_case(d, cloud[0], CONFIGS / "roof_als.yaml", rgb=cloud[1], classes={1, 2, 6, 7})   # 7: low noise


def case_strays_road_pipeline(d):
    """The road pipeline (downsampling 0.5, SOR, RANSAC, grid, cloth, growing) on a UAV scene of
    10,000 points with two strays: SOR drops them, the others' labels do not change."""
    cloud = _synthetic(d, "uav-road", 10_000)
    return _stray_case(d, cloud[0], CONFIGS / "demo.yaml", extra=DEMO_FAST, rgb=cloud[1])


def case_strays_ground_pipeline(d):
    """20,000 ground points and two strays through the ground pipeline (configs/ground.yaml: low
    noise, then the cloth): the strays get no cloth (class 1; each is alone in its cell, so low
    noise takes neither), the ground stays ground."""
    return _stray_case(d, bumpy_ground(20_000, side=40.0), CONFIGS / "ground.yaml", classes={1, 2})


def case_strays_grid_stages(d):
    """The tiny config (grid_slope over 0.5 m cells) with two strays: a sparse grid instead of
    80000 x 80000 cells."""
    return _stray_case(d, bumpy_ground(5000), write_tiny_config(d))


def case_strays_tiled(d):
    """A tiled run (--tile-size 20) of a file whose header box the strays stretch to 20 km: only the
    occupied tiles run (not 10^6 of them), each stray alone in its tile is class 1."""
    return _stray_case(d, bumpy_ground(4000), CONFIGS / "ground.yaml", extra=["--tile-size", "20"],
                       classes={1, 2})


def _synthetic(d, kind, n):
    path = synth(d / "in" / f"{kind}.laz", str(n), kind=kind)
    las = laspy.read(path)
    path.unlink()
    xyz = np.column_stack([las.x, las.y, las.z])
    return xyz, np.column_stack([las.red, las.green, las.blue]).astype(np.uint16)


def case_cloth_larger_than_its_points(d):
    """4,000 points 10 m apart along a 28 km diagonal: one part, whose cloth would hold 7.8 * 10^8
    particles at 1 m. Exit 1 before allocating, one line naming the extent and the option."""
    t = np.sort(np.random.default_rng(0).uniform(0, 28_000, 4000))
    xyz = np.column_stack([t + 500_000.0, t + 4_500_000.0, np.full(4000, 100.0)])
    src = write_las(d / "in" / "diagonal.laz", xyz)
    return _run(CONFIGS / "ground.yaml", d, src, message="raise stages.cloth_ground.cloth_resolution")


def case_memory_estimate_over_the_limit(d):
    """--memory-limit 340M for 200,000 points through the ground pipeline (estimate 351 MB with its
    margin): exit 1 before reading the points, one line suggesting a tile size."""
    src = write_las(d / "in" / "big.laz", bumpy_ground(200_000, side=150.0))
    # (the memory limits are of a process, which counts what it holds already: cases of their own)
    return _run(CONFIGS / "ground.yaml", d, src, extra=["--memory-limit", "340M"],
                message="run in tiles (--tile-size", process=True)


def case_memory_estimate_runs_in_tiles(d):
    """The same with tiling.auto: a warning and a tiled run, every point written."""
    src = write_las(d / "in" / "big.laz", bumpy_ground(200_000, side=150.0))

    def check(c):
        _las_result(c, src, {1, 2})
        summary = json.loads(c.output.with_suffix(".summary.json").read_text())
        assert summary["tiling"]["tiles"] > 1
    return _run(CONFIGS / "ground.yaml", d, src, extra=["--memory-limit", "340M", "--set", "tiling.auto=true"],
                code=0, warning="running in tiles of", check=check, process=True)


def case_unreachable_scheduler(d):
    """--scheduler tcp://127.0.0.1:9 (nothing listens): exit 1 within seconds, one line."""
    src = _ground_laz(d)
    return _run(CONFIGS / "ground.yaml", d, src, extra=["--scheduler", "tcp://127.0.0.1:9"],
                message="cannot reach the Dask scheduler at tcp://127.0.0.1:9", max_seconds=30.0)


def case_eval_truth_class_absent(d):
    """eval against a truth class the file does not hold: exit 0 and strict JSON, null where a
    measure is undefined (it printed NaN)."""
    src = write_las(d / "in" / "ground.las", bumpy_ground(300), classification=np.full(300, 2))

    def check(c):
        result = json.loads(c.proc.stdout, parse_constant=lambda v: pytest.fail(f"{v} is not JSON"))
        assert result["type1"] is None and result["kappa"] is None and result["truth_positive"] == 0
    return Case(args=["eval", "--pred", src, "--truth", src, "--truth-classes", "11"], code=0, output=src,
                check=check)


def _tiles_folder(d, names=("a.laz", "b.laz")):
    folder = d / "in" / "tiles"
    folder.mkdir()
    for k, name in enumerate(names):
        write_las(folder / name, bumpy_ground(1500, seed=k) + [25.0 * k, 0.0, 0.0])
    return folder


def case_catalog_folder_with_readme(d):
    """A folder of LAS tiles with a readme.txt and a notes.pdf beside them (it failed as 'text
    header names no x y z columns'): the LAS files are the catalog, the others skipped in one
    warning line."""
    folder = _tiles_folder(d)
    (folder / "readme.txt").write_text("Survey of 2026, EPSG:2154\n")
    (folder / "notes.pdf").write_bytes(b"%PDF-1.4 not points")

    def check(c):
        assert len(laspy.read(c.output).points) == 3000
    return _run(CONFIGS / "ground.yaml", d, folder, code=0, warning="skipped 2 other file(s): notes.pdf, readme.txt",
                check=check)


def case_catalog_folder_with_a_killed_runs_partial_file(d):
    """A catalog folder that holds a hidden partial LAZ a killed run left there: not an input."""
    folder = _tiles_folder(d)
    (folder / ".a.p99999-host-x1y2z3.partial.laz").write_bytes(b"LASF" + bytes(100))

    def check(c):
        assert len(laspy.read(c.output).points) == 3000
    return _run(CONFIGS / "ground.yaml", d, folder, code=0, check=check)


def case_catalog_folder_of_text_tiles_with_readme(d):
    """A folder without LAS/LAZ: its point-cloud format in the majority (.xyz) forms the catalog,
    the readme.txt beside the tiles is skipped with a warning."""
    folder = d / "in" / "xyz"
    folder.mkdir()
    for k in range(2):
        np.savetxt(folder / f"t{k}.xyz", bumpy_ground(800, seed=k) + [25.0 * k, 0, 0], fmt="%.3f")
    (folder / "readme.txt").write_text("columns: x y z\n")

    def check(c):
        assert len(laspy.read(c.output).points) == 1600
    return _run(CONFIGS / "ground.yaml", d, folder, code=0, warning="skipped 1 other file(s): readme.txt",
                check=check)


def _crs_wkt(epsg: int) -> str:
    from rasterio.crs import CRS
    return CRS.from_epsg(epsg).to_wkt()


def case_catalog_of_two_coordinate_systems(d):
    """A catalog folder whose two files name different CRSs (EPSG:32631 and EPSG:2154: their
    coordinates share no frame): exit 1 before any work, both files and CRSs named. It was merged
    without a word, labelled as the first file's CRS."""
    folder = d / "in" / "tiles"
    folder.mkdir()
    write_las(folder / "a.laz", bumpy_ground(1500), crs_wkt=_crs_wkt(32631))
    write_las(folder / "b.laz", bumpy_ground(1500, seed=1) + [25.0, 0, 0], crs_wkt=_crs_wkt(2154))
    return _run(CONFIGS / "ground.yaml", d, folder, message="different coordinate systems")


def case_catalog_with_and_without_a_coordinate_system(d):
    """A catalog of a file naming EPSG:32631 and one naming none: taken as one survey, with a
    warning naming the file without a CRS."""
    folder = d / "in" / "tiles"
    folder.mkdir()
    write_las(folder / "a.laz", bumpy_ground(1500), crs_wkt=_crs_wkt(32631))
    write_las(folder / "b.laz", bumpy_ground(1500, seed=1) + [25.0, 0, 0])

    def check(c):
        assert len(laspy.read(c.output).points) == 3000
    return _run(CONFIGS / "ground.yaml", d, folder, code=0, warning="name no coordinate system", check=check)


def case_catalog_of_two_scales_merged(d):
    """A catalog of a 1 cm and a 0.1 mm file merged into one output: the merged file takes the
    first file's scale, so the second's coordinates are rounded; said in a warning (it was silent)."""
    folder = d / "in" / "tiles"
    folder.mkdir()
    write_las(folder / "a.laz", bumpy_ground(1500))
    write_las(folder / "b.laz", bumpy_ground(1500, seed=1) + [25.0, 0, 0], scale=0.0001)

    def check(c):
        assert len(laspy.read(c.output).points) == 3000
    return _run(CONFIGS / "ground.yaml", d, folder, code=0, warning="other scales or offsets than", check=check)


def case_catalog_with_a_truncated_file(d):
    """A catalog folder of two good files and one cut short: exit 1 naming the broken file (the
    survey estimates' pass over the files raised lazrs' own error, 'unexpected error')."""
    folder = _tiles_folder(d)
    data = (folder / "b.laz").read_bytes()
    (folder / "c.laz").write_bytes(data[: len(data) // 3])
    def check(c):     # said once (it was wrapped in itself: 'c.laz: truncated ... (c.laz: truncated ...)')
        assert c.proc.stderr.count("truncated or corrupt") == 1, c.proc.stderr
    return _run(CONFIGS / "ground.yaml", d, folder, message="c.laz: truncated or corrupt", check=check)


def case_tile_size_far_too_small(d):
    """--tile-size 0.1 on a 20 m scene (tens of thousands of tiles, each reading the whole scene
    through its 30 m buffer): refused at once in one line (the tile plan ran for minutes)."""
    return _run(CONFIGS / "ground.yaml", d, _ground_laz(d), extra=["--tile-size", "0.1"], code=2,
                message="use a larger tile size", max_seconds=60)


def case_stale_partial_file_of_a_killed_run(d):
    """The output folder holds the temporary file of a run that was killed (its pid gone): the
    run removes it (the catalogue then finds no partial file), and says so."""
    import subprocess
    from roadx_ti.io.atomic import host_tag as _host
    src = _ground_laz(d)
    done = subprocess.Popen([sys.executable, "-c", "pass"])
    done.wait()
    (d / "out").mkdir()
    (d / "out" / f".result.p{done.pid}-{_host()}-dead01.partial.laz").write_bytes(b"half a file")
    return _tiny(d, src, code=0, extra=["--set", "output.report_png=false"], check=lambda c: _las_result(c, src))


def _header_field(d, name, offset, fmt, value, n=500):
    src = write_las(d / "in" / name, bumpy_ground(n))
    data = bytearray(src.read_bytes())
    struct.pack_into(fmt, data, offset, value)
    src.write_bytes(bytes(data))
    return src


def case_scale_zero(d):
    """A header whose x scale is 0: exit 1, 'invalid header' (every x would be the offset)."""
    return _tiny(d, _header_field(d, "scale0.las", 131, "<d", 0.0), message="invalid header")


def case_scale_negative(d):
    """A header whose x scale is -0.01 (probe 19): exit 1, 'invalid header' (it ran, and the output's
    header box had min x > max x)."""
    return _tiny(d, _header_field(d, "scale_neg.las", 131, "<d", -0.01),
                 message="invalid header: scales [-0.01, 0.01, 0.01]: a negative scale")


def case_offset_at_the_float64_limit(d):
    """An x offset of 1.7976931348623157e308 (every x collapses onto it; it ran and wrote
    meaningless labels): exit 1, the header named as wrong."""
    return _tiny(d, _header_field(d, "offset.las", 155, "<d", 1.7976931348623157e308),
                 message="invalid header: scales [0.01, 0.01, 0.01] offsets [1.79769e+308, 4.5e+06, 99]")


def case_scale_at_the_float64_limit(d):
    """An x scale of 1e308 (x overflowed to inf): exit 1, the header's scales named."""
    return _tiny(d, _header_field(d, "scale.las", 131, "<d", 1e308), message="invalid header: scales [1e+308, 0.01")


def case_point_count_two_beyond_the_records_before_an_evlr(d):
    """A LAS 1.4 file with an EVLR after its 500 points whose header counts 502 (probe 19): exit 1,
    'truncated', naming the 500 records it holds (it said 502: the EVLR's bytes counted as points;
    with a count whose records end inside the EVLR it read the EVLR as points)."""
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales, header.offsets = np.full(3, 0.01), np.array([500000.0, 4500000.0, 0.0])
    las = laspy.LasData(header)
    world = bumpy_ground(500)
    las.x, las.y, las.z = world[:, 0], world[:, 1], world[:, 2]
    las.header.evlrs = laspy.vlrs.vlrlist.VLRList([laspy.VLR(user_id="surveyor", record_id=1, description="note",
                                                             record_data=bytes(200))])
    src = d / "in" / "evlr.las"
    las.write(src)
    data = bytearray(src.read_bytes())
    struct.pack_into("<Q", data, 247, 502)
    src.write_bytes(bytes(data))
    return _tiny(d, src, message="the header says 502 points, the file holds 500")


def case_vlr_count_beyond_the_header(d):
    """A header claiming 2^31 - 1 VLRs (laspy read VLRs until the machine ran out of memory):
    exit 1 from the header alone."""
    return _tiny(d, _header_field(d, "vlrs.las", 100, "<I", 2**31 - 1), message="VLRs cannot fit")


def case_point_count_beyond_the_data(d):
    """A LAS 1.4 header claiming ten times the points it holds: exit 1, 'truncated', from the
    header (no allocation for the claimed points)."""
    return _tiny(d, _header_field(d, "count.las", 247, "<Q", 5000), message="the header says 5000 points")


def case_laz_points_offset_one_byte_off(d):
    """A LAZ whose offset to the points is one byte too large, so the chunk table's offset read
    there is garbage (lazrs allocated gigabytes, 10 s of a 19 kB file's read, before failing): exit 1,
    'corrupt', from the header and those 8 bytes."""
    src = write_las(d / "in" / "shifted.laz", bumpy_ground(1500))
    data = bytearray(src.read_bytes())
    offset = struct.unpack_from("<I", data, 96)[0]
    struct.pack_into("<I", data, 96, offset + 1)
    src.write_bytes(bytes(data))
    return _tiny(d, src, message="chunk table offset")


def case_longitude_latitude_degrees(d):
    """A file in EPSG:4326 whose coordinates are degrees (every length of the configs is metres: a
    1 m cell would be 100 km wide): exit 1 naming the degrees and a reprojection, before any work."""
    from rasterio.crs import CRS
    xyz = bumpy_ground(800)
    xyz[:, 0] = 2.35 + (xyz[:, 0] - xyz[:, 0].min()) * 1e-5
    xyz[:, 1] = 48.85 + (xyz[:, 1] - xyz[:, 1].min()) * 1e-5
    src = write_las(d / "in" / "lonlat.las", xyz, scale=1e-7, crs_wkt=CRS.from_epsg(4326).to_wkt())
    return _tiny(d, src, message="longitude / latitude degrees")



def case_longitude_latitude_degrees_in_tiles(d):
    """The same degrees run in tiles: exit 1 naming the degrees (the tiled run went on silently,
    its DTM georeferenced in degrees)."""
    from rasterio.crs import CRS
    xyz = bumpy_ground(800)
    xyz[:, 0] = 2.35 + (xyz[:, 0] - xyz[:, 0].min()) * 1e-5
    xyz[:, 1] = 48.85 + (xyz[:, 1] - xyz[:, 1].min()) * 1e-5
    src = write_las(d / "in" / "lonlat.las", xyz, scale=1e-7, crs_wkt=CRS.from_epsg(4326).to_wkt())
    return _tiny(d, src, extra=["--tile-size", "30"], message="longitude / latitude degrees")


def _geographic_record_over_metres(d, tiled):
    from rasterio.crs import CRS
    src = write_las(d / "in" / "wrongcrs.las", bumpy_ground(800), crs_wkt=CRS.from_epsg(4326).to_wkt())
    return _tiny(d, src, extra=["--tile-size", "30"] if tiled else [],
                 message="its CRS is geographic (EPSG:4326), but its coordinates are not longitude / latitude degrees")


def case_geographic_crs_over_projected_coordinates(d):
    """A file whose CRS record says EPSG:4326 over UTM-sized coordinates (500,000 / 4,500,000): exit 1
    saying the record is wrong (it ran and wrote a GeoTIFF claiming impossible longitudes / latitudes)."""
    return _geographic_record_over_metres(d, False)


def case_geographic_crs_over_projected_coordinates_in_tiles(d):
    """The same in tiles: exit 1 before any tile."""
    return _geographic_record_over_metres(d, True)

def case_feet_survey_in_tiles(d):
    """A survey in US survey feet run in tiles (windows and buffers would be planned in feet):
    exit 2 saying tiled runs need metres (a whole-file run converts)."""
    from rasterio.crs import CRS
    src = write_las(d / "in" / "feet.las", bumpy_ground(800) / 0.3048006, scale=0.001,
                    crs_wkt=CRS.from_epsg(2263).to_wkt())
    return _tiny(d, src, code=2, extra=["--tile-size", "30"], message="tiled runs work in the files' units")


def case_longitude_latitude_without_a_crs(d):
    """Degrees in a file that names no CRS (the degrees check above needs one): the run goes on
    (it cannot know), with a warning naming the likely degrees and the reprojection."""
    xyz = bumpy_ground(800)
    xyz[:, 0] = 2.35 + (xyz[:, 0] - xyz[:, 0].min()) * 1e-5
    xyz[:, 1] = 48.85 + (xyz[:, 1] - xyz[:, 1].min()) * 1e-5
    src = write_las(d / "in" / "lonlat_nocrs.las", xyz, scale=1e-7)
    return _tiny(d, src, code=0, warning="read as longitude / latitude degrees", check=lambda c: None)


def case_header_counts_fewer_points_than_the_file_holds(d):
    """A LAS 1.2 file whose point count says 1000 of its 3000 records (a writer that did not
    update it): the 1000 are read, as every reader does, with a warning that more records follow."""
    src = write_las(d / "in" / "short_count.las", bumpy_ground(3000), point_format=3, version="1.2")
    data = bytearray(src.read_bytes())
    struct.pack_into("<I", data, 107, 1000)
    src.write_bytes(bytes(data))

    def check(c):
        assert len(laspy.read(c.output).points) == 1000
    return _tiny(d, src, code=0, warning="the header counts 1000 points but the file holds 2000 more", check=check)


def case_las14_count_only_in_the_legacy_field(d):
    """LAS 1.4 whose 64-bit point count is 0 while the legacy field says 3000: exit 1 naming both
    counts (it had read as 'the input holds no points')."""
    src = write_las(d / "in" / "legacy_only.las", bumpy_ground(3000), point_format=1, version="1.4")
    data = bytearray(src.read_bytes())
    struct.pack_into("<I", data, 107, 3000)
    struct.pack_into("<Q", data, 247, 0)
    src.write_bytes(bytes(data))
    return _tiny(d, src, message="its LAS 1.4 point count is 0 but its legacy point count says 3000")


def _two_tiles(d, earlier_output: bool = False):
    """(folder in/tiles holding a.laz and b.laz, the west and east halves of one bumpy ground, and
    a check that the output holds its points once); with ``earlier_output`` also merged.laz, an
    earlier run's output (all the points, carrying roadx_label)."""
    folder = d / "in" / "tiles"
    folder.mkdir(parents=True)
    xyz = bumpy_ground(4000, side=40.0)
    west = xyz[:, 0] < np.median(xyz[:, 0])
    write_las(folder / "a.laz", xyz[west])
    write_las(folder / "b.laz", xyz[~west])
    if earlier_output:
        earlier = laspy.read(write_las(folder / "merged.laz", xyz))
        earlier.add_extra_dim(laspy.ExtraBytesParams(name="roadx_label", type=np.uint8))
        earlier.write(folder / "merged.laz")

    def check(c):
        assert len(laspy.read(c.output).points) == len(xyz)
    return folder, check


def case_an_earlier_output_in_the_input_folder(d):
    """A catalog folder that holds an earlier run's merged output (--output tiles/merged.laz): the
    next run of the folder leaves it out with a warning (it would have joined as a tile, every point
    twice); the output holds the tiles' points once."""
    folder, check = _two_tiles(d, earlier_output=True)
    return _tiny(d, folder, code=0, extra=["--tile-size", "25"], warning="skipped 1 file(s) that roadx_ti wrote",
                 check=check)


def case_an_earlier_output_matched_by_the_pattern(d):
    """--input 'tiles/*.laz' where an earlier run wrote its merged output beside the tiles: the
    pattern's matches follow the folder's rule (the output left out with a warning; it joined as a
    tile, every point twice); the output holds the tiles' points once."""
    folder, check = _two_tiles(d, earlier_output=True)
    return _tiny(d, folder / "*.laz", code=0, extra=["--tile-size", "25"],
                 warning="skipped 1 file(s) that roadx_ti wrote", check=check)


def case_a_pattern_matching_sidecars(d):
    """--input 'tiles/*' where a run left its summary JSON, config YAML and picture beside the
    tiles: the point-cloud files are the catalog, the rest skipped with one warning (they were read
    as point clouds: the run stopped on the JSON)."""
    folder, check = _two_tiles(d)
    for name in ("road.summary.json", "road.config.yaml", "road.png"):
        (folder / name).write_text("{}")
    return _tiny(d, folder / "*", code=0, warning="skipped 3 other file(s)", check=check)


def case_output_name_over_255_bytes(d):
    """An output file name of 300 bytes: exit 2, the name shortened in the message (an 'unexpected
    error' from the first look at it)."""
    return _tiny(d, _ground_laz(d), output=d / "out" / ("n" * 300 + ".laz"), code=2,
                 message="file name too long; use a shorter path")


def case_config_copy_over_the_config(d):
    """run out/k.config.yaml --output out/k.laz: the run's config copy would replace the config it
    runs (its comments lost): exit 2 before any work, the config unchanged."""
    (d / "out").mkdir()
    config = d / "out" / "k.config.yaml"
    config.write_text(write_tiny_config(d).read_text() + "# a comment the copy would lose\n")
    before = config.read_bytes()

    def check(c):
        assert config.read_bytes() == before
    return _run(config, d, _ground_laz(d), output=d / "out" / "k.laz", code=2,
                message="the run writes its config file there, over the config file it runs", check=check)


def case_input_name_not_utf8(d):
    """An input whose file name is not UTF-8 (bytes 0xff 0xfe) with the picture on: it runs and
    writes the picture (its title failed in the renderer after the whole pipeline had run)."""
    src = _ground_laz(d)
    odd = src.with_name("bad\udcff\udcfe.laz")
    src.rename(odd)

    def check(c):
        assert c.output.with_suffix(".png").stat().st_size > 0
    # the name reaches main() as the interpreter decodes argv (surrogate escapes)
    return _tiny(d, odd, code=0, extra=["--set", "output.report_png=true"], check=check, process=True)


def _two_channel_waves(d) -> Path:
    """A point format 9 LAS whose wave packets come from two scanner channels."""
    src = write_las(d / "in" / "waves.las", bumpy_ground(3000), point_format=9)
    las = laspy.read(src)
    n = len(las.points)
    las.wavepacket_index = np.ones(n, np.uint8)
    las.wavepacket_offset = np.arange(n, dtype=np.uint64) * 256
    las.wavepacket_size = np.full(n, 256, np.uint32)
    las.x_t = np.linspace(-1.0, 1.0, n).astype(np.float32)
    las.scanner_channel = (np.arange(n) % 2).astype(np.uint8)
    las.write(src)
    return src


def case_laz_of_wave_packets_from_two_channels(d):
    """Point format 9 with wave packets from two scanner channels into LAZ: exit 1 before the
    stages, .las named (lazrs wrote the packets' offsets and x_t of 99.9 % of the points wrong, exit 0)."""
    return _tiny(d, _two_channel_waves(d), message="LAZ cannot keep these points' wave packet fields", max_seconds=30)


def case_laz_of_wave_packets_tiled(d):
    """The same in tiles: refused before the tiles run (it was refused at the merge, after them)."""
    return _tiny(d, _two_channel_waves(d), extra=["--tile-size", "10"], max_seconds=30,
                 message="LAZ cannot keep these points' wave packet fields")


def case_header_scale_of_a_million(d):
    """A header whose scales say 1e6 m per step: exit 1, the header named wrong (an 'unexpected
    error' from the isolation test over points 1e15 m apart; at 1e3 the run took minutes)."""
    src = write_las(d / "in" / "scaled.las", bumpy_ground(3000), scale=1e6)
    return _tiny(d, src, message="invalid header: scales [1e+06, 1e+06, 1e+06]")


def case_an_earlier_picture_beside_the_output(d):
    """result.png of an earlier run beside --output result.laz of a run that writes no picture: a
    warning names it (it was left beside results it does not show, silently)."""
    (d / "out").mkdir()
    (d / "out" / "result.png").write_bytes(b"an earlier run's picture")
    src = _ground_laz(d)
    return _tiny(d, src, code=0, warning="result.png: an earlier run's file, which this run does not write",
                 check=lambda c: _las_result(c, src))


def _undocumented_extra_bytes(d) -> Path:
    import struct

    base = write_las(d / "base.las", bumpy_ground(3000))
    raw = base.read_bytes()
    start, length = struct.unpack_from("<I", raw, 96)[0], struct.unpack_from("<H", raw, 105)[0]
    records = np.frombuffer(raw[start:], np.uint8).reshape(3000, length)
    longer = np.hstack([records, np.tile(np.arange(59, dtype=np.uint8), (3000, 1))])
    header = bytearray(raw[:start])
    struct.pack_into("<H", header, 105, length + 59)
    src = d / "in" / "undocumented.las"
    src.write_bytes(bytes(header) + longer.tobytes())
    return src


def case_undocumented_extra_bytes(d):
    """Point records 59 bytes longer than their format with no Extra Bytes record (undocumented
    extra bytes, valid LAS) into LAZ: exit 1 before the stages, the way out named (the write failed
    after the whole pipeline with laspy's 'len(offsets) (3) is not the same as ...')."""
    return _tiny(d, _undocumented_extra_bytes(d), message="its point records carry 59 undocumented extra bytes",
                 max_seconds=30)


def case_undocumented_extra_bytes_in_tiles(d):
    """The same file in 20 m tiles: the same line before the tiles (tiled runs did not check it:
    the write failed after every tile with laspy's 'len(offsets) (3) is not the same as ...')."""
    return _tiny(d, _undocumented_extra_bytes(d), extra=["--tile-size", "20"],
                 message="its point records carry 59 undocumented extra bytes", max_seconds=30)


def case_one_colour_for_every_point_in_the_roof_pipeline(d):
    """RGB fields holding one colour for every point (30000, 30000, 30000) through the roof
    pipeline: no colour, as the road pipeline reads it, with its warning (it took the placeholder
    for colour: vegetation cue rgb_com)."""
    from roadx_ti import io, synthetic

    scene = synthetic.generate("als-roof", 20_000, seed=1)
    src = d / "in" / "grey.las"
    io.write(src, replace(scene, rgb=np.full((scene.n, 3), 30000, np.uint16), color_depth=16),
             classification=scene.classification)
    return _run(CONFIGS / "roof_als.yaml", d, src, code=0, extra=["--set", "output.report_png=false"],
                warning="roof_growing: the input has no colour", check=lambda c: c.output.is_file())


def case_dtm_placement_over_the_config(d):
    """run e.json with output.dtm=e.npy: the DTM's placement file e.json would replace the config
    it runs: exit 2, the config unchanged (it was overwritten, exit 0)."""
    config = d / "e.json"
    config.write_text((CONFIGS / "ground.yaml").read_text())
    before = config.read_bytes()

    def check(c):
        assert config.read_bytes() == before
    return _run(config, d, _ground_laz(d), extra=["--set", f"output.dtm={d / 'e.npy'}"], code=2,
                message="the run writes its DTM placement file there, over the config file it runs", check=check)


def case_ground_config_run_as_roof(d):
    """The ground config (cloth_ground labels class 2) with pipeline = roof: exit 2 (it wrote class
    2 and scored class 6: type I 100 %)."""
    return _run(CONFIGS / "ground.yaml", d, _ground_laz(d), extra=["--set", "pipeline=roof"], code=2,
                message="pipeline = 'roof', but stages[1] cloth_ground labels class 2 (ground), not 6")


def case_withheld_points(d):
    """Half the points flagged withheld (LAS: to be treated as deleted): processed like the others,
    as PDAL does, with a warning naming how many (they went unsaid)."""
    src = write_las(d / "in" / "withheld.las", bumpy_ground(3000))
    las = laspy.read(src)
    las.withheld = (np.arange(3000) % 2).astype(np.uint8)
    las.write(src)
    return _tiny(d, src, code=0, warning="1500 of 3000 points are flagged withheld",
                 check=lambda c: _las_result(c, src))


def case_merged_catalog_led_by_an_empty_file(d):
    """A catalog whose first file is empty with a default header (scales 0.001, offsets 0) merged
    into one LAZ: the output takes the first file with points' header, every record bit-exact
    (the empty file's grid had put y = 4.5e6 m beyond int32: every point at y -2147483.648, exit 0)."""
    folder = d / "in" / "tiles"
    folder.mkdir(parents=True)
    xyz = bumpy_ground(4000)
    write_las(folder / "a_empty.laz", np.zeros((0, 3)), scale=0.001, offset=np.zeros(3))
    src = write_las(folder / "b.laz", xyz)
    return _tiny(d, folder, code=0, check=lambda c: _las_result(c, src))


def case_merged_catalog_beyond_int32(d):
    """A merged catalog whose second file lies 300 km from the first, whose 0.1 mm scale reaches
    only 214 km from its offset: exit 1 before any tile runs, naming the file and per-file mode
    (its points were clipped onto one x, exit 0)."""
    folder = d / "in" / "tiles"
    folder.mkdir(parents=True)
    xyz = bumpy_ground(4000)
    write_las(folder / "a.laz", xyz, scale=0.0001)
    write_las(folder / "c.laz", xyz + [300_000.0, 0.0, 0.0])
    return _tiny(d, folder, message="c.laz: its x coordinates (800000.")


def case_catalog_of_two_point_formats_merged(d):
    """A catalog of a point format 3 and a point format 6 file into one merged LAZ: exit 1 before
    any tile runs (it failed at the merge, after every tile), naming both formats and per-file."""
    folder = d / "in" / "mixed"
    folder.mkdir(parents=True)
    xyz = bumpy_ground(4000, side=40.0)
    west = xyz[:, 0] < np.median(xyz[:, 0])
    write_las(folder / "a.las", xyz[west], point_format=3, version="1.2")
    write_las(folder / "b.laz", xyz[~west], point_format=6)
    case = _tiny(d, folder, extra=["--tile-size", "25"], message="point format 3 against 6", max_seconds=30.0)
    return case


def case_text_colour_beyond_16_bits(d):
    """A text file whose red / green / blue columns hold 70000 and -5: exit 1 naming the range (the
    values were clamped to 65535 and 0, made-up colours passed off as the file's)."""
    xyz = bumpy_ground(500)
    rgb = np.tile([[70000, 120, -5]], (len(xyz), 1))
    path = d / "in" / "colour.txt"
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.column_stack([xyz, rgb]), fmt="%.3f", header="x y z red green blue", comments="")
    return _tiny(d, path, message="colour values must be 0-65535")


def case_dtm_named_over_the_summary(d):
    """output.dtm=result.summary.npy: its placement file result.summary.json is the run's summary;
    exit 2 before any work (the summary had silently overwritten the DTM's placement)."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(2000))
    out = d / "out" / "result.laz"
    return _run(CONFIGS / "ground.yaml", d, src, code=2, extra=["--set", f"output.dtm={d / 'out' / 'result.summary.npy'}"],
                message="would be the run's summary file")


def case_dtm_over_the_summary_through_a_linked_folder(d):
    """The same through a link to the output's folder: the check compared path strings, and the
    DTM's placement replaced the run's summary."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(2000))
    (d / "out").mkdir(parents=True, exist_ok=True)
    (d / "alias").symlink_to(d / "out", target_is_directory=True)
    return _run(CONFIGS / "ground.yaml", d, src, code=2,
                extra=["--set", f"output.dtm={d / 'alias' / 'result.summary.npy'}"],
                message="would be the run's summary file")


def case_catalog_extra_dimensions_described_apart_merged(d):
    """Two files of one point format whose extra dimension 'amp' (float32) is described apart:
    laspy refuses to write them into one file, so the run says so before any tile."""
    folder = d / "in" / "described"
    folder.mkdir(parents=True)
    xyz = bumpy_ground(4000, side=40.0)
    west = xyz[:, 0] < np.median(xyz[:, 0])
    for name, part, text in (("a.laz", xyz[west], "amplitude"), ("b.laz", xyz[~west], "echo amplitude dB")):
        las = laspy.read(write_las(folder / name, part))
        las.add_extra_dim(laspy.ExtraBytesParams(name="amp", type=np.float32, description=text))
        las.write(folder / name)
    return _tiny(d, folder, extra=["--tile-size", "25"], message="other extra dimensions", max_seconds=30.0)


def case_every_point_written_twice(d):
    """Every record twice (a delivery merged with itself), shuffled, through the road demo: the
    same classes as the points once (repeats take their first's labels; the estimates of spacing
    and noise would read 0 on twins)."""
    once = synth(d / "in" / "once.laz", "20k", seed=4)
    las = laspy.read(once)
    order = np.random.default_rng(0).permutation(np.repeat(np.arange(len(las.points)), 2))
    twice = laspy.LasData(las.header)
    twice.points = las.points[order]
    src = d / "in" / "twice.laz"
    twice.write(src)
    reference_out = d / "reference" / "once_result.laz"
    reference_out.parent.mkdir(parents=True, exist_ok=True)

    def check(c):
        got = np.asarray(laspy.read(c.output).classification)
        want = np.asarray(laspy.read(reference_out).classification)[order]
        np.testing.assert_array_equal(got, want)
        assert "records repeat the x, y, z of another" in c.proc.stderr
    case = _demo(d, src, code=0, check=check)
    case.args = [a for a in case.args if a != "--quiet"]
    case.reference = ["run", CONFIGS / "demo.yaml", "--backend", "cpu", "--quiet", *DEMO_FAST, "--input", once,
                      "--output", reference_out]
    return case


def case_las14_crs_and_records_in_evlrs(d):
    """A LAS 1.4 file whose WKT CRS and a custom record are extended VLRs (after the points, as
    COPC and large WKTs put them): both are in the output (the streamed writer dropped every EVLR,
    and with it the CRS, silently)."""
    src = write_las(d / "in" / "evlr.las", bumpy_ground(2000))
    las = laspy.read(src)
    las.header.global_encoding.wkt = True
    las.header.evlrs = laspy.vlrs.vlrlist.VLRList([laspy.vlrs.known.WktCoordinateSystemVlr(_crs_wkt(32631)),
                                                   laspy.VLR("someorg", 43, "kept", b"abc")])
    las.write(src)

    def check(c):
        with laspy.open(c.output) as reader:
            records = [(v.user_id, v.record_id) for v in reader.header.evlrs]
        assert ("someorg", 43) in records and ("LASF_Projection", 2112) in records, records
    return _run(CONFIGS / "ground.yaml", d, src, code=0, check=check)


def case_pcd_with_one_normal_field(d):
    """A PCD declaring normal_x without normal_y / normal_z: one line (Open3D's reader crashed the
    process, exit 139, no message)."""
    path = d / "in" / "normal_x.pcd"
    rows = "".join(f"{i % 5} {i // 5} 1 0\n" for i in range(10))
    path.write_text("VERSION 0.7\nFIELDS x y z normal_x\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 10\n"
                    "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 10\nDATA ascii\n" + rows)
    return _tiny(d, path, message="but not all of normal_x normal_y normal_z")


def case_the_same_file_twice_through_a_hard_link(d):
    """A file and a hard link to it as two inputs: refused as the same file named twice (every
    point was taken twice; the same path, ./ spellings and symbolic links were refused already)."""
    src = write_las(d / "in" / "a.laz", bumpy_ground(1500))
    link = d / "in" / "b.laz"
    os.link(src, link)
    return _run(CONFIGS / "ground.yaml", d, src, link, message="the same input file is named twice")


def case_npz_classes_that_are_not_whole_numbers(d):
    """An NPZ whose classification holds 2.7: one line (it was cut to class 2 silently)."""
    path = d / "in" / "classes.npz"
    xyz = bumpy_ground(500)
    np.savez(path, xyz=xyz, classification=np.full(len(xyz), 2.7))
    return _tiny(d, path, message="'classification' must hold whole numbers 0-255")


def case_scattered_points_over_100_km(d):
    """1000 points scattered over 100 x 100 km through the ground pipeline with its DTM: every
    point labelled and a DTM of the largest part (the raster's window was empty: 'writing failed
    (Attempt to create 0x0 dataset ...)' and no output at all)."""
    rng = np.random.default_rng(3)
    xyz = np.column_stack([rng.uniform(0, 1e5, 1000) + 500_000.0, rng.uniform(0, 1e5, 1000) + 4_500_000.0,
                           rng.uniform(0, 50, 1000)])
    src = write_las(d / "in" / "scattered.las", xyz)

    def check(c):
        assert len(laspy.read(c.output).points) == 1000
        assert c.output.with_suffix(".dtm.tif").is_file()
    return _run(CONFIGS / "ground.yaml", d, src, code=0, warning="parts more than 100 m apart", check=check)


def case_more_local_workers_than_the_machine_runs(d):
    """--workers 100000: one line before any work (the run waited for minutes starting a cluster
    of 100000 processes)."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(1500))
    return _run(CONFIGS / "ground.yaml", d, src, code=2, extra=["--workers", "100000"],
                message="a local cluster of more than")


def case_catalog_whose_first_file_is_empty(d):
    """A catalog folder whose first file (by name) holds no point: the run goes on with the others
    (the survey estimates stopped at it: 'need at least one array to concatenate', exit 2, and
    only when the empty file sorted first)."""
    folder = d / "in" / "tiles"
    folder.mkdir()
    write_las(folder / "a_empty.laz", np.zeros((0, 3)), offset=np.array([500000.0, 4500000.0, 0.0]))
    write_las(folder / "b.laz", bumpy_ground(1500))
    write_las(folder / "c.laz", bumpy_ground(1500, seed=1) + [25.0, 0, 0])

    def check(c):
        assert len(laspy.read(c.output).points) == 3000
    return _run(CONFIGS / "ground.yaml", d, folder, code=0, check=check)


def case_catalog_file_with_points_beyond_its_header_box(d):
    """Two files of a catalog, one whose header box is 8 m short of its points: one line naming the
    file (the merge said 'tiles 5 and 10 disagree on the points they share', naming none)."""
    folder = d / "in" / "tiles"
    folder.mkdir()
    a = write_las(folder / "a.las", bumpy_ground(3000, side=40.0))
    write_las(folder / "b.las", bumpy_ground(3000, seed=1, side=40.0) + [40.0, 0, 0])
    data = bytearray(a.read_bytes())
    for at in (179, 195):                      # max x, max y of the LAS header
        value, = struct.unpack_from("<d", data, at)
        struct.pack_into("<d", data, at, value - 8.0)
    a.write_bytes(bytes(data))
    return _run(CONFIGS / "ground.yaml", d, folder, extra=["--tile-size", "20"],
                message="lie outside the header bounds")


def case_output_path_that_names_a_folder(d):
    """--output . (or a path ending in '..'): one line (was 'unexpected error: ValueError:
    PosixPath('.') has an empty name')."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(1500))
    case = _run(CONFIGS / "ground.yaml", d, src, code=2, message="names a folder, not an output file")
    case.args[case.args.index("--output") + 1] = str(d / "out" / "..")
    return case


def case_per_file_output_onto_an_existing_file(d):
    """output.mode per-file into a path that is an existing file: one line (was 'unexpected error:
    FileExistsError'); the file is left as it was."""
    folder = _tiles_folder(d)
    out = d / "out" / "afile"
    out.parent.mkdir()
    out.write_bytes(b"keep me")
    case = _run(CONFIGS / "ground.yaml", d, folder, output=out, code=2, extra=["--output-mode", "per-file"],
                message="is a file; output.mode per-file")
    case.previous = b"keep me"
    return case


def case_memory_limit_below_one_tile(d):
    """A tiled run under --memory-limit 200M, less than one tile's process needs: one line naming
    the limit, before any work (every tile failed in its cloth stage with 'more than the 1
    particles allowed')."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(3000, side=60.0))
    return _run(CONFIGS / "ground.yaml", d, src, code=2, extra=["--memory-limit", "200M", "--tile-size", "30"],
                message="--memory-limit 200.0 MB: a tile's process needs at least", process=True)


def case_tile_size_inf_is_the_untiled_run(d):
    """--tile-size inf (the help's 'untiled') on one file gives the untiled run's labels (it went
    through the tiling engine, whose cloth lies on a world lattice: other labels)."""
    src = synth(d / "in" / "road.laz", "30k", seed=4)
    reference_out = d / "ref" / "untiled.laz"

    def check(c):
        got = np.asarray(laspy.read(c.output).classification)
        np.testing.assert_array_equal(got, np.asarray(laspy.read(reference_out).classification))
    case = _demo(d, src, code=0, extra=["--tile-size", "inf"], check=check)
    case.reference = ["run", CONFIGS / "demo.yaml", "--backend", "cpu", "--quiet", *DEMO_FAST, "--input", src,
                      "--output", reference_out]
    return case


def case_buffer_narrower_than_the_stages_reach(d):
    """--buffer 5 with 30 m tiles: the cloth reaches 30 m, so labels near the borders can differ from
    the untiled run's; said in a warning (it was accepted silently)."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(3000, side=60.0))
    return _run(CONFIGS / "ground.yaml", d, src, code=0, extra=["--tile-size", "30", "--buffer", "5"],
                warning="buffer 5 m is less than the stages' reach (30 m, cloth_ground)",
                check=lambda c: _las_result(c, src, classes={1, 2}))


def case_buffer_of_an_untiled_run(d):
    """--buffer without tiles (one file, no --tile-size): a warning that it does nothing (it was
    ignored silently)."""
    src = write_las(d / "in" / "ground.laz", bumpy_ground(1500))
    return _run(CONFIGS / "ground.yaml", d, src, code=0, extra=["--buffer", "5"],
                warning="--buffer is the tiles' buffer; this run is untiled", check=lambda c: _las_result(c, src, classes={1, 2}))



def case_extra_dimension_named_x(d):
    """An extra dimension named 'x' (lowercase; laspy's scaled X): exit 1 naming it before any work
    (the whole pipeline ran, then 'unexpected error: IndexError' at the write)."""
    import laspy

    src = d / "in" / "xdim.las"
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales, header.offsets = np.full(3, 0.01), np.zeros(3)
    header.add_extra_dims([laspy.ExtraBytesParams(name="zzzzzzzz", type=np.float64)])
    las = laspy.LasData(header)
    xyz = bumpy_ground(500)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.write(src)
    data = bytearray(src.read_bytes())
    at = data.find(b"zzzzzzzz")
    data[at:at + 32] = b"x".ljust(32, b"\0")
    src.write_bytes(bytes(data))
    return _tiny(d, src, message="its extra dimension 'x' has the name of the standard dimension 'X'")

CASES = {name[len("case_"):]: fn for name, fn in sorted(globals().items()) if name.startswith("case_")}


@pytest.fixture(scope="module")
def catalogue(request, tmp_path_factory):
    """{case name: (Case, CompletedProcess)}: the selected cases built, then run (module docstring)."""
    selected = {item.callspec.params["name"] for item in request.session.items
                if item.module is request.module and "name" in getattr(getattr(item, "callspec", None),
                                                                       "params", {})}
    cases = {}
    for name, build in CASES.items():
        if name not in selected:
            continue
        folder = tmp_path_factory.mktemp(name)
        (folder / "in").mkdir()
        case = build(folder)
        case.hashes = {p.resolve(): sha256(p) for p in (folder / "in").rglob("*") if p.is_file()}
        cases[name] = case
    # by the case's place in the whole catalogue: a case selected alone (-k) runs as in the suite
    everywhere = list(CASES)
    by_process = {name for name in cases if cases[name].process or everywhere.index(name) % SUBPROCESS_EVERY == 0}
    calls = [{"id": name, "argv": [str(a) for a in case.args]} for name, case in cases.items()
             if name not in by_process]
    calls += [{"id": f"reference {name}", "argv": [str(a) for a in case.reference]}
              for name, case in cases.items() if case.reference]

    def through_the_cli(name):
        t0 = time.perf_counter()
        proc = run_cli(*cases[name].args)
        cases[name].seconds = time.perf_counter() - t0
        return proc

    with ThreadPoolExecutor(1) as pool:            # beside the driver: the suite's other process has a core too
        by_cli = {name: pool.submit(through_the_cli, name) for name in sorted(by_process)}
        results = run_in_one_process(calls, call_seconds=CALL_SECONDS, total_seconds=1200.0)
        procs = {name: done.result() for name, done in by_cli.items()}
    for call in calls:
        r = results[call["id"]]
        stderr = r["stderr"] + (f"Traceback (in the driver process): {r['raised']}" if r["raised"] else "")
        proc = subprocess.CompletedProcess(call["argv"], r["code"], r["stdout"], stderr)
        if call["id"].startswith("reference "):
            cases[call["id"][len("reference "):]].reference_proc = proc
        else:
            cases[call["id"]].seconds, procs[call["id"]] = r["seconds"], proc
    return {name: (cases[name], procs[name]) for name in cases}


def test_catalogue_size(catalogue):
    assert len(CASES) > 40
    slowest = sorted(((c.seconds, name) for name, (c, _) in catalogue.items()), reverse=True)[:8]
    print("slowest catalogue runs:", ", ".join(f"{name} {s:.1f} s" for s, name in slowest))


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input(name, catalogue):
    case, proc = catalogue[name]
    case.proc = proc
    assert "Traceback" not in proc.stderr, proc.stderr
    if case.max_seconds is not None:
        assert case.seconds < case.max_seconds, f"{case.seconds:.1f} s"
    assert proc.returncode == case.code, f"exit {proc.returncode}, expected {case.code}: {proc.stderr}"
    if case.code != 0:
        line = error_line(proc, case.code)
        assert case.message in line, line
        if case.previous is not None:
            assert case.output.read_bytes() == case.previous
        elif case.output.is_dir():
            assert not any(case.output.iterdir())           # a folder given as the output: untouched
        elif case.output.exists() or case.output.is_symlink():
            assert case.output.resolve() in case.hashes     # only 'output is input' cases
        else:
            assert not case.output.with_suffix(".summary.json").exists()
        if case.check is not None:     # what else a refusal must leave as it was, or say
            case.check(case)
    else:
        assert case.warning in proc.stderr, proc.stderr
        assert case.output.is_file()
        case.check(case)
    if case.output.parent.is_dir() and str(case.output.parent) != "/proc":
        assert partial_files(case.output.parent) == []
    for path, digest in case.hashes.items():
        assert sha256(path) == digest, f"{path} changed"
