"""COPC output (NAME.copc.laz, copclib): every point and attribute of the LAZ output, read back
with laspy's COPC reader; formats 0-5 converted to 6-8 with every value carried over."""
import json
import logging

import laspy
import numpy as np
import pytest

from roadx_ti import io
from roadx_ti.io import copc
from tests.cli_helpers import error_line, message_lines, run_cli, write_las, write_tiny_config

pytest.importorskip("copclib", reason="COPC output needs copclib (the copc extra)")
WKT_2154 = ('PROJCS["RGF93 v1 / Lambert-93",GEOGCS["RGF93 v1",DATUM["Reseau_Geodesique_Francais_1993_v1",'
            'SPHEROID["GRS 1980",6378137,298.257222101]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],'
            'PROJECTION["Lambert_Conformal_Conic_2SP"],PARAMETER["latitude_of_origin",46.5],'
            'PARAMETER["central_meridian",3],PARAMETER["standard_parallel_1",49],'
            'PARAMETER["standard_parallel_2",44],PARAMETER["false_easting",700000],'
            'PARAMETER["false_northing",6600000],UNIT["metre",1],AUTHORITY["EPSG","2154"]]')


def legacy_las(path, n=30_000, seed=0):
    """A LAS 1.2 point format 3 file with every legacy field set, and a unique id per point."""
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales, header.offsets = np.full(3, 0.01), np.array([770000.0, 6277000.0, 0.0])
    header.add_extra_dims([laspy.ExtraBytesParams("pid", np.uint32), laspy.ExtraBytesParams("h", np.float32)])
    las = laspy.LasData(header)
    las.x = 770000 + rng.uniform(0, 60, n)
    las.y = 6277000 + rng.uniform(0, 40, n)
    las.z = 30 + rng.uniform(0, 15, n)
    las.intensity = rng.integers(0, 65535, n)
    las.return_number = rng.integers(1, 6, n)
    las.number_of_returns = np.maximum(las.return_number, rng.integers(1, 6, n))
    for name in ("scan_direction_flag", "edge_of_flight_line", "synthetic", "key_point", "withheld"):
        las[name] = rng.integers(0, 2, n)
    las.classification = rng.integers(0, 32, n)
    las.scan_angle_rank = rng.integers(-90, 91, n)
    las.user_data = rng.integers(0, 256, n)
    las.point_source_id = rng.integers(0, 65535, n)
    las.gps_time = rng.uniform(0, 1e6, n)
    las.red, las.green, las.blue = (rng.integers(0, 65535, n) for _ in range(3))
    las.pid = np.arange(n)
    las.h = rng.normal(size=n).astype(np.float32)
    las.write(str(path))
    return path


def by_pid(las):
    return np.argsort(np.asarray(las.pid))


def test_copc_keeps_every_point_and_value_of_the_laz_output(tmp_path, monkeypatch, caplog):
    monkeypatch.setattr(copc, "LEAF_POINTS", 2000)       # a small file still gets an octree
    cloud = io.read(legacy_las(tmp_path / "in.las"))
    labels = {"roadx_label": (np.arange(cloud.n) % 5).astype(np.uint8),
              "segment_id": (np.arange(cloud.n) % 300 - 1).astype(np.int32)}
    classes = cloud.classification.copy()
    io.write(tmp_path / "r.laz", cloud, classification=classes, extra_dims=labels)
    with caplog.at_level(logging.WARNING, logger="roadx_ti"):
        io.write(tmp_path / "r.copc.laz", cloud, classification=classes, extra_dims=labels)
    said = [r.getMessage() for r in caplog.records if "COPC" in r.getMessage()]
    assert len(said) == 1 and "point format 3 written as 7" in said[0]
    laz, out = laspy.read(tmp_path / "r.laz"), laspy.read(tmp_path / "r.copc.laz")
    assert (laz.point_format.id, out.point_format.id) == (3, 7) and str(out.header.version) == "1.4"
    assert out.header.point_count == laz.header.point_count == cloud.n
    assert list(out.point_format.extra_dimension_names) == ["pid", "h", "roadx_label", "segment_id"]
    a, b = by_pid(laz), by_pid(out)
    for name in laz.point_format.dimension_names:
        if name == "scan_angle_rank":      # 1.4's scan angle counts 0.006 degree steps
            np.testing.assert_array_equal(np.round(np.asarray(out.scan_angle)[b] * 0.006),
                                          np.asarray(laz.scan_angle_rank)[a])
        else:
            np.testing.assert_array_equal(np.asarray(out[name])[b], np.asarray(laz[name])[a], err_msg=name)
    assert list(out.header.number_of_points_by_return[:5]) == list(np.bincount(laz.return_number, minlength=6)[1:6])


def test_copc_octree_answers_bounds_queries_with_the_right_points(tmp_path, monkeypatch):
    monkeypatch.setattr(copc, "LEAF_POINTS", 2000)
    path = write_las(tmp_path / "in.las", np.column_stack([
        770000 + np.random.default_rng(1).uniform(0, 60, 40_000),
        6277000 + np.random.default_rng(2).uniform(0, 40, 40_000),
        30 + np.random.default_rng(3).uniform(0, 2, 40_000)]), crs_wkt=WKT_2154)
    cloud = io.read(path)
    pid = np.arange(cloud.n, dtype=np.int32)
    io.write(tmp_path / "r.copc.laz", cloud, extra_dims={"segment_id": pid})
    assert io.info(tmp_path / "r.copc.laz")["format"] == "copc"
    world = cloud.world_xyz()
    assert "EPSG:2154" in io.info(tmp_path / "r.copc.laz")["crs"]     # a WKT record (copclib: an EVLR)
    with laspy.CopcReader.open(str(tmp_path / "r.copc.laz")) as reader:
        everything = reader.query()
        assert len(everything) == cloud.n
        coarse = reader.query(level=0)
        assert 0 < len(coarse) < cloud.n                 # the root holds a thinned sample only
        lo, hi = np.array([770010.0, 6277005.0]), np.array([770025.5, 6277021.0])
        got = reader.query(bounds=laspy.copc.Bounds(mins=lo, maxs=hi))
    inside = np.flatnonzero((world[:, 0] >= lo[0]) & (world[:, 0] <= hi[0])
                            & (world[:, 1] >= lo[1]) & (world[:, 1] <= hi[1]))
    ids = np.asarray(got.segment_id)
    x, y = np.asarray(got.x), np.asarray(got.y)
    in_window = (x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1])
    # the query returns every point of the window (and parts of the nodes that meet it, no more)
    assert set(ids[in_window]) == set(inside)
    assert len(ids) < cloud.n / 2
    # the points come back with their own coordinates
    np.testing.assert_allclose(np.column_stack([x, y])[in_window], world[ids[in_window], :2], atol=0.006)


def test_run_writes_copc_with_the_crs_and_says_when_the_format_changes(tmp_path):
    rng = np.random.default_rng(4)
    xyz = np.column_stack([770000 + rng.uniform(0, 30, 5000), 6277000 + rng.uniform(0, 30, 5000),
                           30 + rng.normal(0, 0.02, 5000)])
    write_las(tmp_path / "in.las", xyz, point_format=3, version="1.2")
    cfg = write_tiny_config(tmp_path)
    proc = run_cli("run", cfg, "--backend", "cpu", "--input", tmp_path / "in.las",
                   "--output", tmp_path / "out" / "r.copc.laz")
    assert proc.returncode == 0, proc.stderr
    said = [line for line in message_lines(proc.stderr) if "point format 3 written as 7" in line]
    assert len(said) == 1
    info = io.info(tmp_path / "out" / "r.copc.laz")
    assert info["format"] == "copc" and info["point_count"] == 5000 and info["point_format"] == 7
    assert {"roadx_label", "segment_id"} <= set(info["extra_dimensions"])
    summary = json.loads((tmp_path / "out" / "r.summary.json").read_text())   # not r.copc.summary.json
    assert summary["output"].endswith("r.copc.laz")


def test_copc_without_copclib_or_in_tiles_is_a_one_line_error(tmp_path):
    fake = tmp_path / "fake"
    (fake / "copclib").mkdir(parents=True)
    (fake / "copclib" / "__init__.py").write_text("raise ImportError('no copclib here')\n")
    write_las(tmp_path / "in.las", np.random.default_rng(5).uniform(0, 10, (500, 3)) + [500000, 4500000, 0])
    cfg = write_tiny_config(tmp_path)
    import os
    import subprocess
    import sys
    env = dict(os.environ, PYTHONPATH=f"{fake}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    proc = subprocess.run([sys.executable, "-m", "roadx_ti", "run", str(cfg), "--input", str(tmp_path / "in.las"),
                           "--output", str(tmp_path / "out" / "r.copc.laz")], capture_output=True, text=True, env=env)
    line = error_line(proc, 2)
    assert "copclib" in line and "roadx_ti[copc]" in line
    line = error_line(run_cli("run", cfg, "--input", tmp_path / "in.las", "--tile-size", "5",
                              "--output", tmp_path / "out" / "t.copc.laz"), 2)
    assert "COPC" in line
    assert not (tmp_path / "out" / "r.copc.laz").exists() and not (tmp_path / "out" / "t.copc.laz").exists()


class _FullDiskWriter:
    """copclib.FileWriter as it behaves on a full disk: a chunk fails, and so does every close (its
    destructor closes again, and a throwing destructor aborts the process)."""
    closes = 0

    def __init__(self, path, cfg):
        self.path = path

    def AddNode(self, key, data):
        raise RuntimeError("BaseWriter::WriteChunk: Chunk is too large!")

    def Close(self):
        type(self).closes += 1
        raise RuntimeError("WriterInternal::WriteHeader: LasHeader + VLRs are bigger than offset to point data.")


def test_a_copc_write_that_fails_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    """A full disk while copclib writes: the run's one-line write failure (it was 'unexpected error
    ... please report it', then the process aborted in copclib's destructor, exit 134)."""
    import copclib
    monkeypatch.setattr(copclib, "FileWriter", _FullDiskWriter)
    cloud = io.read(legacy_las(tmp_path / "in.las", n=2000))
    with pytest.raises(io.InputError, match="writing failed .*Chunk is too large.*the output was not changed"):
        io.write(tmp_path / "out.copc.laz", cloud)
    assert _FullDiskWriter.closes >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.las"]


def test_copc_output_names_the_records_it_leaves_out(tmp_path, caplog):
    """COPC carries the CRS and the extra dimensions' records only (copclib writes no others): a
    warning names the rest (they went silently)."""
    path = legacy_las(tmp_path / "in.las", n=2000)
    las = laspy.read(path)
    las.header.vlrs.append(laspy.VLR("someorg", 7, "kept in LAS", b"abc"))
    las.write(path)
    with caplog.at_level(logging.WARNING, logger="roadx_ti"):
        io.write(tmp_path / "out.copc.laz", io.read(path))
    assert "left out: someorg/7" in caplog.text


def test_per_file_output_of_a_copc_input_is_named_laz(tmp_path):
    """A catalog of a COPC file and a LAZ file run per-file: the COPC file's output is s.laz, a
    plain LAZ, with a warning (it was s.copc.laz holding plain LAZ, which PDAL and QGIS take for
    COPC)."""
    from tests.cli_helpers import bumpy_ground

    folder = tmp_path / "tiles"
    folder.mkdir()
    xyz = bumpy_ground(4000, side=40.0)
    west = xyz[:, 0] < np.median(xyz[:, 0])
    copc.write(folder / "s.copc.laz", laspy.read(write_las(tmp_path / "west.laz", xyz[west])))
    write_las(folder / "b.laz", xyz[~west])
    out = tmp_path / "out"
    proc = run_cli("run", write_tiny_config(tmp_path), "--backend", "cpu", "--input", folder, "--output", out,
                   "--set", "output.mode=per-file", "--tile-size", "25")
    assert proc.returncode == 0, proc.stderr
    assert "its per-file output is s.laz, a plain LAZ" in proc.stderr
    assert sorted(p.name for p in out.iterdir() if p.suffix == ".laz") == ["b.laz", "s.laz"]
    assert io.info(out / "s.laz")["format"] == "laz"
    assert len(laspy.read(out / "s.laz").points) == int(west.sum())
