"""Machine-readable output is strict JSON everywhere (issue 18): every JSON the CLI prints or
writes parses with NaN / Infinity refused (json.loads(..., parse_constant=...) raising), and
undefined measures are null, not NaN."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import bumpy_ground, run_cli, write_las, write_tiny_config


def strict_loads(text: str):
    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")
    return json.loads(text, parse_constant=refuse)


def test_strict_loads_refuses_nan():
    with pytest.raises(ValueError):
        strict_loads('{"kappa": NaN}')


@pytest.fixture(scope="module")
def all_ground(tmp_path_factory):
    folder = tmp_path_factory.mktemp("json")
    src = write_las(folder / "ground.laz", bumpy_ground(400), classification=np.full(400, 2))
    return folder, src


def test_eval_prints_null_where_a_measure_is_undefined(all_ground):
    # (a truth class the file does not hold: tests/test_bad_inputs.py case_eval_truth_class_absent)
    folder, src = all_ground
    both = run_cli("eval", "--pred", src, "--truth", src, "--truth-classes", "2")
    assert both.returncode == 0, both.stderr
    result = strict_loads(both.stdout)
    assert result["type2"] is None and result["type1"] == 0.0     # no non-target point


def test_every_json_a_run_writes_is_strict(all_ground):
    folder, src = all_ground
    out = folder / "out" / "run.laz"
    config = write_tiny_config(folder, """\
        pipeline: ground
        output: {report_png: false}
        stages:
          - cloth_ground: {cloth_resolution: 1.0, iterations: 60}
        """)
    # every point is truth (class 2): type II and kappa are undefined
    proc = run_cli("run", config, "--backend", "cpu", "--quiet", "--input", src, "--output", out,
                   "--set", "evaluate.truth_classes=[2]", "--set", f"output.dtm={folder / 'out' / 'dtm.npy'}")
    assert proc.returncode == 0, proc.stderr
    summary = strict_loads(out.with_suffix(".summary.json").read_text())
    assert summary["accuracy"]["type2"] is None and summary["accuracy"]["kappa"] is None
    tiled_out = folder / "tiled" / "run.laz"
    proc = run_cli("run", config, "--backend", "cpu", "--quiet", "--input", src, "--output", tiled_out,
                   "--tile-size", "10", "--set", "evaluate.truth_classes=[2]")
    assert proc.returncode == 0, proc.stderr
    tiled = strict_loads(tiled_out.with_suffix(".summary.json").read_text())
    assert tiled["accuracy"]["type2"] is None and tiled["tiling"]["tiles"] > 1
    written = sorted(Path(folder).rglob("*.json"))
    assert len(written) == 3                                     # two summaries, the DTM sidecar
    for path in written:
        strict_loads(path.read_text())
    info = run_cli("info", src)
    assert info.returncode == 0 and strict_loads(info.stdout)["point_count"] == 400


def test_accuracy_report_json_is_strict(tmp_path, monkeypatch, capsys):
    import argparse

    from roadx_ti import accuracy
    row = {"dataset": "scene", "config": "roof_als.yaml", "points": 10, "seconds": 0.1, "type1": float("nan"),
           "type2": 0.0, "total": 0.0, "kappa": float("nan"), "stages": []}
    monkeypatch.setattr(accuracy, "evaluate", lambda task, out, rows=None: [dict(row)])
    parser = argparse.ArgumentParser()
    accuracy.add_arguments(parser)
    args = parser.parse_args(["--task", "roof", "--out", str(tmp_path), "--roof-sizes", "300k", "--roof-seeds", "0"])
    assert accuracy.main(args) == 0
    saved = strict_loads((tmp_path / "accuracy.json").read_text())
    assert saved["results"]["roof"][0]["kappa"] is None
    strict_loads(capsys.readouterr().out)
