"""The benchmark harness (`python -m roadx_ti bench`): a tiny --quick run end to end, the JSON rows
and the results page, and the rows of cases that are missing, fail or crash their worker."""
from __future__ import annotations

import argparse
import json
import math
import textwrap

import pytest

from roadx_ti.config import parse_point_count

from roadx_ti import bench
from roadx_ti.bench import render

REQUIRED = {"stage", "points", "backend", "impl", "median_s", "first_call_s", "peak_rss_mb", "mpts_per_s",
            "ratio", "status", "bytes_per_point", "threads"}


def _args(*argv):
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    return parser.parse_args(list(argv))


def _run(tmp_path, *argv):
    out = tmp_path / "out"
    code = bench.main(_args(*argv, "--out", str(out), "--results", str(tmp_path / "RESULTS.md")))
    assert code == 0
    (json_path,) = out.glob("bench-*.json")
    return json.loads(json_path.read_text(), parse_constant=_refuse)   # strict JSON (issue 18)


def _refuse(constant):
    raise ValueError(f"the bench JSON holds {constant}, which is not JSON")


def test_quick_run_rows_and_results_page(tmp_path):
    run = _run(tmp_path, "--quick", "--sizes", "10k", "--stages", "grid_min,knn", "--backends", "cpu")
    rows = run["rows"]
    got = {(r["stage"], r["impl"], r["backend"]) for r in rows}
    assert got == {("grid_min", "roadx_ti", "cpu"), ("grid_min", "numpy", "cpu"),
                   ("knn", "roadx_ti", "cpu"), ("knn", "scipy", "cpu"), ("knn", "pykdtree", "cpu")}
    for r in rows:
        assert REQUIRED <= set(r), REQUIRED - set(r)
        assert r["points"] == 10_000
        assert r["status"] == "ok", r["error"]
        assert r["median_s"] > 0 and r["first_call_s"] > 0 and r["repeats"] >= 1
        assert math.isclose(r["mpts_per_s"], 10_000 / r["median_s"] / 1e6, rel_tol=1e-3)
        assert r["median_s"] == pytest.approx(sorted(r["times_s"])[len(r["times_s"]) // 2], rel=0.5)
        assert r["peak_rss_mb"] > 0 and r["bytes_per_point"] >= 0
    by = {(r["stage"], r["impl"]): r for r in rows}
    for stage, anchor in (("grid_min", "numpy"), ("knn", "scipy")):
        mine, theirs = by[(stage, "roadx_ti")], by[(stage, anchor)]
        expected = theirs["median_s"] / mine["median_s"]
        assert mine["ratio"][anchor] == pytest.approx(expected, rel=1e-2)
        assert theirs["ratio"]["cpu"] == pytest.approx(expected, rel=1e-2)
    assert by[("knn", "roadx_ti")]["threads"] >= 1
    meta = run["meta"]
    assert meta["machine"]["cpu_model"] and meta["machine"]["logical_cores"] >= 1
    assert "taichi" in meta["machine"]["versions"]

    page = (tmp_path / "RESULTS.md").read_text()
    assert meta["command"] in page and "--quick" in meta["command"]
    assert meta["machine"]["cpu_model"] in page
    summary = page.split("## Summary")[1].split("##")[0]
    knn_line = next(line for line in summary.splitlines() if line.startswith("| knn "))
    assert f"{by[('knn', 'roadx_ti')]['ratio']['scipy']:.3g}x scipy" in knn_line
    assert "### grid_min" in page and "### knn" in page
    assert (tmp_path / "throughput.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    # the page regenerates from the JSON alone
    again = tmp_path / "again" / "RESULTS.md"
    assert bench.main(_args("--render", *map(str, (tmp_path / "out").glob("bench-*.json")),
                            "--results", str(again))) == 0
    assert "### knn" in again.read_text() and (again.parent / "throughput.png").exists()


def test_rounds_alternate_workers_and_pool_their_repeats(tmp_path):
    run = _run(tmp_path, "--quick", "--sizes", "10k", "--stages", "grid_min", "--backends", "cpu", "--rounds", "2")
    order = [(w["backend"], w["first_call_only"]) for w in run["meta"]["workers"]]
    assert order == [("cpu", False), ("anchors", False), ("cpu", False), ("anchors", False)]
    assert run["meta"]["rounds"] == 2 and "--rounds 2" in run["meta"]["command"]
    for r in run["rows"]:
        assert r["rounds"] == 2 and r["repeats"] == len(r["times_s"]) >= 2
        assert r["median_s"] == pytest.approx(sorted(r["times_s"])[len(r["times_s"]) // 2], rel=0.5)
    mine, numpy_row = sorted(run["rows"], key=lambda r: r["impl"] != "roadx_ti")
    assert mine["ratio"]["numpy"] == pytest.approx(numpy_row["median_s"] / mine["median_s"], rel=1e-2)
    # the existing separate section of a results page survives a re-render
    page = tmp_path / "RESULTS.md"
    page.write_text(page.read_text() + "\n## Measured separately\n\nby hand\n")
    assert bench.main(_args("--render", *map(str, (tmp_path / "out").glob("bench-*.json")),
                            "--results", str(page))) == 0
    assert page.read_text().endswith("## Measured separately\n\nby hand\n") and "### grid_min" in page.read_text()


def test_missing_failing_and_crashing_cases_are_reported(tmp_path, monkeypatch):
    cases = tmp_path / "cases"
    cases.mkdir()
    (cases / "knn.py").write_text(textwrap.dedent('''
        STAGE = "knn"
        SCENE = "uav-road"
        VARIANTS = [{"name": "", "params": {"k": 4}}]
        TARGETS = {"numpy": 1.0}

        def roadx_ti(scene, k):
            from roadx_ti.kernels import no_such_kernel   # not written yet
            return lambda: no_such_kernel(scene.xyz, k)

        def absent(scene, k):
            import no_such_package   # an anchor that is not installed
            return lambda: no_such_package.run(scene.xyz)

        def numpy_sort(scene, k):
            import numpy as np
            return lambda: np.sort(scene.xyz[:, 0])

        def broken(scene, k):
            def run():
                raise RuntimeError("anchor blew up")
            return run

        def crashing(scene, k):
            import os
            return lambda: os._exit(3)

        IMPLS = {"roadx_ti": roadx_ti, "absent": absent, "crashing": crashing, "broken": broken,
                 "numpy": numpy_sort}
    '''))
    monkeypatch.setenv(bench.CASES_ENV, str(cases))
    # the anchors only: their worker starts no Taichi runtime, which keeps this test fast
    run = _run(tmp_path, "--quick", "--sizes", "5k", "--stages", "knn", "--backends", "cpu",
               "--impls", "absent,crashing,broken,numpy")
    status = {r["impl"]: r for r in run["rows"]}
    assert set(status) == {"absent", "crashing", "broken", "numpy"}
    assert status["absent"]["status"] == "missing" and "no_such_package" in status["absent"]["error"]
    assert status["broken"]["status"] == "error" and "anchor blew up" in status["broken"]["error"]
    assert status["crashing"]["status"] == "error" and "status 3" in status["crashing"]["error"]
    # the worker restarted after the crash and ran the case after it
    assert status["numpy"]["status"] == "ok" and status["numpy"]["median_s"] > 0
    page = (tmp_path / "RESULTS.md").read_text()
    assert "Missing, skipped and failed cases" in page
    for impl in ("absent", "broken", "crashing"):
        assert f"| {impl} | {status[impl]['status']} |" in page


def test_unknown_stage_is_a_usage_error(tmp_path):
    assert bench.main(_args("--stages", "nope", "--out", str(tmp_path))) == 2


def test_point_counts():
    assert parse_point_count("1M") == 1_000_000 and parse_point_count("250k") == 250_000 and parse_point_count("1200") == 1200
    for text in ("lots", "inf", "1e400", "-inf", "nan"):     # inf / 1e400 were an OverflowError traceback
        with pytest.raises(argparse.ArgumentTypeError):
            parse_point_count(text)


def test_a_later_run_replaces_the_rows_it_remeasured():
    """Rendering several runs: a case measured again by a later run is shown from that run only."""
    import copy
    from pathlib import Path

    runs_dir = Path(__file__).resolve().parents[1] / "benchmarks" / "runs"
    first = json.loads(sorted(runs_dir.glob("bench-*.json"))[0].read_text())
    row = next(r for r in first["rows"] if r["impl"] == "roadx_ti" and r["status"] == "ok")
    later = copy.deepcopy(first)
    later["meta"]["run_id"] = "later"
    later["rows"] = [dict(row, median_s=123.456, mpts_per_s=0.00789)]
    page = bench.render_markdown([first, later])
    assert "## Run later" in page
    details = page[page.index("## Details"):]
    section = details[details.index(f"### {render._stage_label(row['stage'], row['variant'])}\n"):]
    section = section.split("\n### ")[0]
    prefix = f"| {render._fmt_points(row['points'])} | {row['backend']} | roadx_ti |"
    mine = [line for line in section.splitlines() if line.startswith(prefix)]
    assert len(mine) == 1 and "| 123 |" in mine[0] and "0.00789" in mine[0]


def _floor_script():
    import importlib.util

    from roadx_ti.bench.cases import BENCH_DIR

    spec = importlib.util.spec_from_file_location("roadx_bench_floor", BENCH_DIR / "floor" / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_floor_counts_the_cube_candidates_of_the_knn_grid():
    """benchmarks/floor/run.py's work count: points in the 3 x 3 x 3 cells around each query on the
    grid knn() builds, against a brute-force count over every pair of points."""
    import numpy as np

    from roadx_ti.kernels.common import to_numpy
    from roadx_ti.kernels.grid import build_grid_into
    from roadx_ti.kernels.neighbors import default_points_per_cell

    floor = _floor_script()
    rng = np.random.default_rng(3)
    xyz = np.concatenate([rng.random((1500, 3)) * [20, 20, 0.3],          # a surface
                          rng.random((300, 3)) * [20, 20, 8]]).astype(np.float32)   # and a volume
    counted = floor.cube_candidates(xyz, 16)
    grid = build_grid_into(xyz, None, default_points_per_cell(16), private=True)
    cells = to_numpy(grid.sorted_cell).astype(np.int64)
    near = (np.abs(cells[:, None, :] - cells[None, :, :]) <= 1).all(axis=2)
    assert counted == pytest.approx(near.sum(axis=1).mean(), rel=1e-12)
    assert floor.returned_bytes((np.zeros(4, np.int32), [np.zeros(3, np.uint8)], None)) == 19
