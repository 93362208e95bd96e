"""Determinism through the real CLI: the demo pipeline twice on the CPU gives byte-identical LAZ
(and the same summary apart from timings); the CPU and Vulkan backends give identical labels.

Vulkan runs on Mesa's lavapipe in CI (a CPU Vulkan driver); where no Vulkan driver exists the
Vulkan test is skipped, unless CI or ROADX_TI_REQUIRE_BACKENDS says it must run (as conftest does).
"""
from __future__ import annotations

import json
import os

import laspy
import numpy as np
import pytest

from cli_helpers import CONFIGS, message_lines, run_cli, sha256, synth

RESULT_DIMS = ("classification", "roadx_label", "segment_id")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return synth(tmp_path_factory.mktemp("scene") / "road.laz", points="20k", seed=5)


def _demo(scene, out, backend="cpu", *extra):
    return run_cli("run", CONFIGS / "demo.yaml", "--input", scene, "--output", out, "--backend", backend,
                   "--quiet", "--set", "output.report_png=false", *extra)


def _without_timings(value):
    if isinstance(value, dict):
        return {k: _without_timings(v) for k, v in value.items() if not k.endswith("seconds")
                and k not in ("output", "backend")}
    if isinstance(value, list):
        return [_without_timings(v) for v in value]
    return value


@pytest.fixture(scope="module")
def cpu_result(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("cpu") / "first.laz"
    proc = _demo(scene, out)
    assert proc.returncode == 0, proc.stderr
    return out


def test_two_cpu_runs_are_byte_identical(scene, cpu_result, tmp_path):
    second = tmp_path / "second.laz"
    proc = _demo(scene, second)
    assert proc.returncode == 0, proc.stderr
    assert sha256(second) == sha256(cpu_result)
    first_summary = json.loads(cpu_result.with_suffix(".summary.json").read_text())
    second_summary = json.loads(second.with_suffix(".summary.json").read_text())
    assert _without_timings(first_summary) == _without_timings(second_summary)
    # not vacuous: several stages removed points
    las = laspy.read(second)
    assert len(np.unique(np.asarray(las["roadx_label"]))) >= 4


def _vulkan_required() -> bool:
    return bool(os.environ.get("CI") or os.environ.get("ROADX_TI_REQUIRE_BACKENDS"))


COLOUR_GROWING = """\
pipeline: road
output: {report_png: false}
stages:
  - color_growing: {k: 12, point_threshold: 10, region_threshold: 60, target: largest}
"""


@pytest.fixture(scope="module")
def roof_scene(tmp_path_factory):
    return synth(tmp_path_factory.mktemp("roof") / "roof.laz", points="20k", seed=5, kind="als-roof")


# Known defect of lavapipe, not of the kernels (measured 2026-12-01, cause found 2026-12-07): Mesa's
# gallivm (llvmpipe / lavapipe) ends every loop of a shader invocation once all of its loops together
# have run 65,535 iterations (LP_MAX_TGSI_LOOP_ITERATIONS, one counter per invocation, shared by its
# loops, and counted for the SIMD group of lanes that run together), silently. The GPU kNN block
# search of a few isolated high points runs that long: this scene, k = 20: 2 of 20,000 rows miss
# neighbours (a trace of one such query: the CPU visits 125 blocks, lavapipe stops at the 41st, inside
# a block's points loop, and the row is written from that state); which rows depends on the queries
# that share the SIMD group. The same kernel on the CPU backend (every query through the block
# search) gives every row right, as cKDTree does. In the canonical point order one of them moves
# SOR's decision for one point, and RANSAC's random samples then differ: 9 of 20,000
# classifications. Real GPU drivers have no such cap. Not a tolerance: the test still runs and
# reports the differences.
VULKAN_KNN_DEFECT = pytest.mark.xfail(reason="lavapipe ends loops after 65,535 iterations per invocation: "
                                             "a few outliers' GPU kNN rows (see above)",
                                      strict=False)


@pytest.mark.parametrize("pipeline", [pytest.param("road_demo", marks=VULKAN_KNN_DEFECT), "colour_growing", "roof"])
def test_cpu_and_vulkan_labels_are_identical(pipeline, scene, roof_scene, tmp_path):
    """The road demo (whatever its early stages leave), the colour growing alone on the whole
    scene (so its regions are compared even when the demo leaves it few points) and the roof
    pipeline on an ALS scene, each on both backends."""
    source = roof_scene if pipeline == "roof" else scene
    config = {"road_demo": CONFIGS / "demo.yaml", "roof": CONFIGS / "roof_als.yaml"}.get(pipeline)
    if config is None:
        config = tmp_path / "colour.yaml"
        config.write_text(COLOUR_GROWING)
    runs = {}
    for backend in ("vulkan", "cpu"):
        out = tmp_path / f"{backend}.laz"
        proc = run_cli("run", config, "--input", source, "--output", out, "--backend", backend, "--quiet",
                       "--set", "output.report_png=false")
        if proc.returncode == 2 and "not available" in proc.stderr and not _vulkan_required():
            pytest.skip(f"no Vulkan here: {message_lines(proc.stderr)}")
        assert proc.returncode == 0, proc.stderr
        summary = json.loads(out.with_suffix(".summary.json").read_text())
        assert summary["backend"] == backend
        runs[backend] = laspy.read(out)
    cpu, gpu = runs["cpu"], runs["vulkan"]
    decided_by = np.asarray(cpu["roadx_label"])
    assert len(np.unique(decided_by)) >= 2 or len(np.unique(np.asarray(cpu["segment_id"]))) >= 2  # not vacuous
    stage_names = {0: "reached the end"} | {s["index"]: s["stage"] for s in summary["stages"]}
    report = []
    for dim in RESULT_DIMS:
        a, b = np.asarray(cpu[dim]), np.asarray(gpu[dim])
        differ = np.flatnonzero(a != b)
        if len(differ):
            where = {stage_names.get(int(k), k): int(v) for k, v in
                     zip(*np.unique(decided_by[differ], return_counts=True))}
            report.append(f"{dim}: {len(differ)} of {len(a)} points differ (by the CPU run's "
                          f"deciding stage: {where})")
    assert not report, f"{pipeline}: CPU and Vulkan results differ: " + "; ".join(report)
