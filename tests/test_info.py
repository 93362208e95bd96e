"""`info`: what a user checks first (CRS, density and spacing over occupied cells, colour /
intensity / NIR / returns present and varying, classes), as strict JSON or --text."""
import json

import numpy as np
import pytest

from tests.cli_helpers import run_cli, write_las


def strict_json(text: str) -> dict:
    def refuse(name):
        raise AssertionError(f"not strict JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def info(*args) -> dict:
    proc = run_cli("info", *args)
    assert proc.returncode == 0, proc.stderr
    return strict_json(proc.stdout)


def test_density_is_over_occupied_cells_not_the_bounding_box(tmp_path):
    rng = np.random.default_rng(0)
    xyz = np.column_stack([rng.uniform(0, 40, 20_000) + 500_000, rng.uniform(0, 40, 20_000) + 4_500_000,
                           rng.uniform(0, 1, 20_000)])
    xyz[0, :2] += 1000.0                                 # a stray point 1.4 km away: the box is 1000 x 1000 m
    classes = np.where(np.arange(len(xyz)) % 4 == 0, 2, 1)
    rgb = np.zeros((len(xyz), 3), np.uint16)
    write_las(tmp_path / "a.las", xyz, rgb=rgb, classification=classes)
    got = info(tmp_path / "a.las")
    assert got["point_density"] == pytest.approx(20_000 / 1600, rel=0.1)
    assert got["point_spacing"] == pytest.approx(1 / np.sqrt(20_000 / 1600), rel=0.1)
    assert got["crs"] is None
    assert got["fields"]["rgb"] == {"present": True, "varies": False, "min": 0, "max": 0}
    assert got["color"] == "all-zero"
    assert got["fields"]["intensity"]["present"] and not got["fields"]["intensity"]["varies"]
    assert got["classes"] == [{"class": 1, "name": "unclassified", "points": 15_000},
                              {"class": 2, "name": "ground", "points": 5_000}]
    text = run_cli("info", "--text", tmp_path / "a.las").stdout
    assert "20,000" in text and "all zero (no colour)" in text and "2 ground: 5,000" in text
    assert "none (the file names no coordinate reference system)" in text


def test_empty_file_is_strict_json(tmp_path):
    write_las(tmp_path / "e.las", np.zeros((0, 3)))
    got = info(tmp_path / "e.las")
    assert got["point_count"] == 0 and got["point_density"] is None and got["bounds"] is None


def test_real_ign_tile_crs_zero_colour_nir_and_returns(shared_data):
    path = sorted((shared_data / "tiles").glob("*.laz"))[0]
    got = info(path)
    assert "EPSG:2154" in got["crs"]
    f = got["fields"]
    assert f["rgb"]["present"] and not f["rgb"]["varies"]            # IGN: colour fields all zero
    assert f["nir"]["present"] and not f["nir"]["varies"]
    assert f["intensity"]["varies"] and f["return_number"]["max"] > 1
    assert 0 < f["return_number"]["multiple_returns"] < got["point_count"]
    assert 15 < got["point_density"] < 50                            # the data README: 22-35 / m2
    assert sum(c["points"] for c in got["classes"]) == got["point_count"]
    text = run_cli("info", "--text", path).stdout
    assert "EPSG:2154" in text and "RGB fields present, all zero" in text and "NIR        present, all zero" in text


def test_several_files_a_folder_and_a_pattern(tmp_path):
    """info over several paths, a folder (its point-cloud files, as a catalog takes them) or a
    quoted wildcard pattern: one JSON object per file, in sorted order, as a list; a pattern that
    matches nothing is one line, exit 1."""
    rng = np.random.default_rng(1)
    for name, n in (("b.laz", 300), ("a.las", 200)):
        xyz = np.column_stack([rng.uniform(0, 10, n) + 1000, rng.uniform(0, 10, n) + 2000, rng.uniform(0, 1, n)])
        write_las(tmp_path / name, xyz)
    (tmp_path / "readme.txt").write_text("not points")
    for given in ([str(tmp_path)], [str(tmp_path / "*.la?")], [str(tmp_path / "a.las"), str(tmp_path / "b.laz")]):
        listed = info(*given)
        assert [(d["path"].rsplit("/", 1)[-1], d["point_count"]) for d in listed] == [("a.las", 200), ("b.laz", 300)]
    assert info(str(tmp_path / "b.*"))["point_count"] == 300           # one file: the object itself
    proc = run_cli("info", str(tmp_path / "*.ply"))
    assert proc.returncode == 2          # a usage mistake, as run says it
    assert proc.stderr.strip().splitlines() == [f"roadx_ti: {tmp_path / '*.ply'}: no file matches the pattern"]


def test_a_folder_with_a_bad_file_describes_every_file(tmp_path):
    """info over a folder holding a truncated file: every file is described, the bad one by its
    error, which is also one stderr line; exit 1 (it stopped at the bad file, describing none)."""
    rng = np.random.default_rng(2)
    for name in ("a.las", "c.las"):
        write_las(tmp_path / name, np.column_stack([rng.uniform(0, 10, 100) + 1000, rng.uniform(0, 10, 100), rng.uniform(0, 1, 100)]))
    (tmp_path / "b.las").write_bytes((tmp_path / "a.las").read_bytes()[:300])
    proc = run_cli("info", str(tmp_path))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    listed = json.loads(proc.stdout)
    assert [d["path"].rsplit("/", 1)[-1] for d in listed] == ["a.las", "b.las", "c.las"]
    assert listed[0]["point_count"] == 100 and listed[2]["point_count"] == 100 and "error" in listed[1]
    lines = [line for line in proc.stderr.splitlines() if line.startswith("roadx_ti: ")]
    assert len(lines) == 1 and "b.las" in lines[0], proc.stderr
    text = run_cli("info", "--text", str(tmp_path))
    assert text.returncode == 1 and "error" in text.stdout and text.stdout.count("file") >= 3
