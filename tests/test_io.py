"""roadx_ti.io: LAS/LAZ, PLY, PCD, NPZ and text round trips, atomic writes and one-line errors.
References are laspy (raw point records), open3d and numpy; no Taichi here."""
from __future__ import annotations

import hashlib
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import laspy
import numpy as np
import pytest

from roadx_ti import io
from roadx_ti.cloud import Cloud
from roadx_ti.io import InputError
from roadx_ti.io.atomic import atomic_output

CLASSES = np.array([1, 2, 6, 11], dtype=np.uint8)


def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def one_line_error(path, fn, *args, **kw) -> str:
    with pytest.raises(InputError) as err:
        fn(*args, **kw)
    msg = str(err.value)
    assert "\n" not in msg and str(path) in msg, msg
    return msg


def leftovers(folder: Path) -> list:
    return sorted(p.name for p in folder.iterdir() if ".partial" in p.name)


def make_las(path, world, *, point_format=7, version="1.4", scale=0.01, rgb=None, classes=None,
             gps_time=None) -> laspy.LasData:
    header = laspy.LasHeader(point_format=point_format, version=version)
    header.scales = np.full(3, scale)
    header.offsets = np.zeros(3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = world[:, 0], world[:, 1], world[:, 2]
    if rgb is not None:
        las.red, las.green, las.blue = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    if classes is not None:
        las.classification = classes
    if gps_time is not None:
        las.gps_time = gps_time
    las.write(path)
    return las


def synthetic_cloud(n=500, seed=0, depth=8, base=(6_999_000.0, 9_999_000.0, 120.0)) -> tuple[Cloud, np.ndarray]:
    """A cloud near 10^7 m with centimetre detail; returns it and its float64 world coordinates."""
    rng = np.random.default_rng(seed)
    world = np.round(rng.uniform(0, 400, (n, 3)) * 100) / 100 + np.array(base)
    top = 255 if depth == 8 else 65535
    rgb = rng.integers(0, top + 1, (n, 3)).astype(np.uint16)
    rgb[0] = top   # make the depth unambiguous
    cloud = Cloud.from_world(world, rgb=rgb, color_depth=depth,
                             intensity=rng.integers(0, 65536, n).astype(np.uint16),
                             classification=rng.choice(CLASSES, n))
    return cloud, world


# ----------------------------------------------------------------------------- real LAS / LAZ

def real_files(shared_data) -> list[Path]:
    files = sorted(p for p in shared_data.rglob("*") if p.suffix.lower() in (".las", ".laz"))
    if not files:
        pytest.skip(f"no LAS/LAZ files under {shared_data}")
    return files


def vlr_bytes(header) -> list:
    return [(v.user_id, v.record_id, bytes(v.record_data_bytes())) for v in header.vlrs
            if type(v).__name__ != "ExtraBytesVlr"]


@pytest.mark.parametrize("keep_records", [True, False])
def test_las_round_trip_keeps_every_attribute_bit_exact(shared_data, tmp_path, keep_records):
    """With keep_records False the records are not held: the writer streams them from the input."""
    for src in real_files(shared_data):
        digest = sha256(src)
        cloud = io.read(src, keep_records=keep_records)
        ref = laspy.read(src)                          # independent reference: laspy's own record
        n = len(ref.points)
        assert cloud.n == n and (cloud.las is not None) == keep_records
        assert cloud.records_file == ("" if keep_records else str(src))
        rng = np.random.default_rng(n)
        classes = rng.choice(CLASSES, n)
        label = rng.integers(0, 5, n).astype(np.uint8)
        segment = rng.integers(-1, 10_000, n).astype(np.int32)
        out = tmp_path / src.name
        io.write(out, cloud, classification=classes, extra_dims={"roadx_label": label, "segment_id": segment})
        back = laspy.read(out)
        # header kept
        assert back.header.version == ref.header.version
        assert back.header.point_format.id == ref.header.point_format.id
        assert np.array_equal(back.header.scales, ref.header.scales)
        assert np.array_equal(back.header.offsets, ref.header.offsets)
        assert vlr_bytes(back.header) == vlr_bytes(ref.header), src.name
        # every input dimension, in order, then the new ones
        names = list(ref.point_format.dimension_names)
        assert list(back.point_format.dimension_names) == names + ["roadx_label", "segment_id"]
        for field in ref.points.array.dtype.names:
            a, b = ref.points.array[field], back.points.array[field]
            if field in ("classification", "raw_classification"):
                keep = np.uint8(0xE0) if field == "raw_classification" else np.uint8(0)
                assert np.array_equal(a & keep, b & keep), (src.name, field)   # legacy flag bits
            else:
                assert a.tobytes() == b.tobytes(), (src.name, field)
        assert np.array_equal(np.asarray(back.classification), classes)
        assert np.array_equal(np.asarray(back.roadx_label), label)
        assert np.array_equal(np.asarray(back.segment_id), segment)
        # read back through io: same local coordinates and origin
        again = io.read(out)
        assert np.array_equal(again.origin, cloud.origin)
        assert np.array_equal(again.xyz, cloud.xyz)
        assert np.array_equal(again.classification, classes)
        assert sha256(src) == digest, f"{src} was modified"


def test_real_las_cloud_fields_match_laspy(shared_data):
    for src in real_files(shared_data):
        cloud = io.read(src)
        ref = laspy.read(src)
        world = np.column_stack([ref.x, ref.y, ref.z])
        assert np.all(cloud.origin == np.floor(ref.header.mins))
        assert np.abs(cloud.xyz.astype(np.float64) + cloud.origin - world).max() < 1e-4
        assert np.array_equal(cloud.classification, np.asarray(ref.classification))
        assert np.array_equal(cloud.intensity, np.asarray(ref.intensity))
        assert np.array_equal(cloud.returns, np.column_stack([ref.return_number, ref.number_of_returns]))
        later = np.asarray(ref.return_number) < np.asarray(ref.number_of_returns)
        if (np.asarray(ref.number_of_returns) > 1).any():
            assert np.array_equal(cloud.penetrated(), later)
        else:
            assert cloud.penetrated() is None
        part = np.flatnonzero(np.arange(cloud.n) % 3 == 0)
        assert np.array_equal(cloud.subset(part).returns, cloud.returns[part])
        if "red" in ref.point_format.dimension_names and np.any(ref.red):
            assert cloud.color_depth == 16
            assert np.array_equal(cloud.rgb, np.column_stack([ref.red, ref.green, ref.blue]))
        else:   # the IGN tiles carry colour fields that are all zero
            assert cloud.rgb is None and cloud.color_depth == 0
        info = io.info(src)
        assert info["point_count"] == len(ref.points)
        hist = np.bincount(np.asarray(ref.classification), minlength=256)
        assert info["class_histogram"] == {c: int(k) for c, k in enumerate(hist) if k}
        assert np.allclose(info["bounds"]["min"], world.min(axis=0))
        assert np.allclose(info["bounds"]["max"], world.max(axis=0))
        assert info["extra_dimensions"] == list(ref.point_format.extra_dimension_names)
        if "tiles" in src.parts:
            assert info["color"] == "all-zero" and "EPSG:2154" in info["crs"]


def test_read_headers_match_laspy(shared_data):
    files = real_files(shared_data)
    for path, bounds, count, z_range in io.read_headers(files):
        h = laspy.open(path).header
        assert count == h.point_count
        assert bounds == (h.mins[0], h.mins[1], h.maxs[0], h.maxs[1])
        assert z_range == (h.mins[2], h.maxs[2])


def test_bounds_windows_partition_the_file(shared_data):
    src = shared_data / "roof" / "ign_870000_6618000.las"
    if not src.exists():
        pytest.skip(f"{src} is absent")
    full = io.read(src)
    world = full.world_xyz()
    xm, ym = np.median(world[:, 0]), np.median(world[:, 1])
    lo, hi = world.min(axis=0) - 1, world.max(axis=0) + 1
    windows = [(lo[0], lo[1], xm, ym), (xm, lo[1], hi[0], ym), (lo[0], ym, xm, hi[1]), (xm, ym, hi[0], hi[1])]
    gps = []
    for w in windows:
        part = io.read(src, bounds=w)
        assert np.array_equal(part.origin, full.origin)   # tiles of one file share the origin
        inside = (world[:, 0] >= w[0]) & (world[:, 0] < w[2]) & (world[:, 1] >= w[1]) & (world[:, 1] < w[3])
        assert np.array_equal(part.xyz, full.xyz[inside])
        assert np.array_equal(part.las.points.array, full.las.points.array[inside])
        gps.append(np.asarray(part.las.gps_time))
    assert sum(map(len, gps)) == full.n
    shared_origin = full.origin + [-100.0, 50.0, 3.0]
    moved = io.read(src, origin=shared_origin)
    assert np.array_equal(moved.xyz, (world - shared_origin).astype(np.float32))


def test_bounds_are_half_open(tmp_path):
    world = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [5.0, 5.0, 1.0]]) + [500000.0, 6e6, 0]
    src = tmp_path / "edges.laz"
    make_las(src, world, point_format=6)
    part = io.read(src, bounds=(500000.0, 6e6, 500010.0, 6e6 + 10))
    assert np.allclose(part.world_xyz()[:, :2], world[[0, 3], :2])
    assert io.read(src, bounds=(0, 0, 1, 1)).n == 0


# ------------------------------------------------------------------------- LAS special cases

def test_classes_above_31_upgrade_legacy_format(tmp_path):
    rng = np.random.default_rng(3)
    world = rng.uniform(0, 50, (200, 3)) + [600000, 5e6, 10]
    rgb = rng.integers(0, 65536, (200, 3))
    src = tmp_path / "legacy.las"
    make_las(src, world, point_format=3, version="1.2", rgb=rgb, classes=rng.integers(0, 31, 200),
             gps_time=rng.uniform(0, 1e5, 200))
    cloud = io.read(src)
    classes = np.full(200, 64, dtype=np.uint8)
    io.write(tmp_path / "wide.las", cloud, classification=classes)
    back = laspy.read(tmp_path / "wide.las")
    ref = laspy.read(src)
    assert back.header.point_format.id == 7 and str(back.header.version) == "1.4"
    assert np.array_equal(np.asarray(back.classification), classes)
    for name in ("X", "Y", "Z", "intensity", "red", "green", "blue", "gps_time", "return_number"):
        assert np.array_equal(np.asarray(back[name]), np.asarray(ref[name])), name
    # classes that fit keep the legacy format and its flag bits
    io.write(tmp_path / "same.las", cloud, classification=np.full(200, 11, dtype=np.uint8))
    assert laspy.read(tmp_path / "same.las").header.point_format.id == 3


@pytest.mark.parametrize("streamed", [False, True])
def test_extra_dims_keep_their_no_data_value(tmp_path, streamed):
    """An input extra dimension whose Extra Bytes record declares a no-data value (-9999) keeps it
    in the output when the result dimensions are added (laspy rebuilt the record without it: the
    sentinel became a plain value), whether the records are held or streamed from the input."""
    src = tmp_path / "nd.las"
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.add_extra_dims([laspy.ExtraBytesParams("reflectance", "f4", no_data=[-9999.0], description="dB")])
    las = laspy.LasData(header)
    las.x, las.y, las.z = np.random.default_rng(2).uniform(0, 20, (50, 3)).T
    las.reflectance = np.where(np.arange(50) % 5 == 0, -9999.0, -3.0).astype(np.float32)
    las.write(src)
    cloud = io.read(src, keep_records=not streamed)
    io.write(tmp_path / "out.laz", cloud, extra_dims={"roadx_label": np.ones(50, np.uint8)})
    structs = laspy.open(tmp_path / "out.laz").header.vlrs.get("ExtraBytesVlr")[0].extra_bytes_structs
    declared = {s.format_name(): s.no_data for s in structs}
    assert declared["reflectance"].tolist() == [-9999.0] and declared["roadx_label"] is None
    assert np.array_equal(np.asarray(laspy.read(tmp_path / "out.laz").reflectance), np.asarray(las.reflectance))


def test_extra_dims_replace_existing_ones(tmp_path):
    world = np.random.default_rng(1).uniform(0, 20, (100, 3))
    src = tmp_path / "eb.laz"
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.add_extra_dims([laspy.ExtraBytesParams("keep_me", "f4"), laspy.ExtraBytesParams("roadx_label", "u1"),
                           laspy.ExtraBytesParams("segment_id", "u2")])
    las = laspy.LasData(header)
    las.x, las.y, las.z = world.T
    las.keep_me = np.arange(100, dtype=np.float32) / 7
    las.roadx_label = np.ones(100, np.uint8)
    las.write(src)
    cloud = io.read(src)
    label, seg = np.arange(100, dtype=np.uint8) % 3, np.arange(100, dtype=np.int32) - 50
    io.write(tmp_path / "out.laz", cloud, extra_dims={"roadx_label": label, "segment_id": seg})
    back = laspy.read(tmp_path / "out.laz")
    names = list(back.point_format.extra_dimension_names)
    assert names.count("roadx_label") == 1 and names.count("segment_id") == 1 and names[0] == "keep_me"
    assert np.asarray(back.segment_id).dtype == np.int32          # re-declared with the new type
    assert np.array_equal(np.asarray(back.keep_me), np.asarray(las.keep_me))
    assert np.array_equal(np.asarray(back.roadx_label), label)
    assert np.array_equal(np.asarray(back.segment_id), seg)
    with pytest.raises(InputError, match="standard"):
        io.write(tmp_path / "bad.laz", cloud, extra_dims={"intensity": label})


def test_subset_writes_only_those_points(tmp_path):
    cloud, world = synthetic_cloud(300)
    src = tmp_path / "src.laz"
    io.write(src, cloud)
    las_cloud = io.read(src)
    mask = np.arange(300) % 3 == 0
    seg = np.arange(300, dtype=np.int32)
    io.write(tmp_path / "sub.laz", las_cloud, subset=mask, extra_dims={"segment_id": seg})
    io.write(tmp_path / "sub_idx.laz", las_cloud, subset=np.flatnonzero(mask), extra_dims={"segment_id": seg})
    for name in ("sub.laz", "sub_idx.laz"):
        back = laspy.read(tmp_path / name)
        assert np.array_equal(back.points.array[list(las_cloud.las.points.array.dtype.names)],
                              las_cloud.las.points.array[mask])
        assert np.array_equal(np.asarray(back.segment_id), seg[mask])


@pytest.mark.parametrize("subset, message", [([-1], r"\[0, 300\)"), ([300], r"\[0, 300\)"),
                                             (np.ones(299, bool), "one value per point"),
                                             (np.array([0.0, 1.0]), "point indices")])
def test_subset_outside_the_cloud_is_refused(tmp_path, subset, message):
    """numpy would read index -1 as the last point and a float array as whatever it converts to."""
    cloud, _ = synthetic_cloud(300)
    with pytest.raises(ValueError, match=message):
        io.write(tmp_path / "sub.laz", cloud, subset=subset)
    assert not (tmp_path / "sub.laz").exists()
    for writer in ("sub.ply", "sub.csv"):       # the other formats' writers take the same rule
        with pytest.raises(ValueError, match=message):
            io.write(tmp_path / writer, cloud, subset=subset)


def test_all_zero_colour_is_no_colour(tmp_path):
    world = np.random.default_rng(2).uniform(0, 10, (50, 3))
    src = tmp_path / "zero.las"
    make_las(src, world, rgb=np.zeros((50, 3), np.uint16))
    cloud = io.read(src)
    assert cloud.rgb is None and cloud.color_depth == 0
    assert io.info(src)["color"] == "all-zero"
    make_las(tmp_path / "eight.las", world, rgb=np.full((50, 3), 200))
    assert io.read(tmp_path / "eight.las").color_depth == 8
    assert io.info(tmp_path / "eight.las")["color"] == "8-bit"


def test_las_record_keeps_1e7_coordinates_exact(tmp_path):
    rng = np.random.default_rng(4)
    world = np.round((rng.uniform(0, 300, (1000, 3)) + [9_999_000.0, 9_998_500.0, 50.0]) * 100) / 100
    src = tmp_path / "far.las"
    make_las(src, world, point_format=6)
    cloud = io.read(src)
    # float32 local coordinates keep centimetre detail
    assert np.abs(cloud.xyz.astype(np.float64) + cloud.origin - world).max() < 1e-4
    io.write(tmp_path / "far_out.las", cloud, classification=rng.choice(CLASSES, 1000))
    back = laspy.read(tmp_path / "far_out.las")
    ref = laspy.read(src)
    for k in "XYZ":
        assert np.array_equal(back.points.array[k], ref.points.array[k])


@pytest.mark.parametrize("depth", [8, 16])
@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_synthetic_cloud_to_las(tmp_path, depth, ext):
    cloud, world = synthetic_cloud(depth=depth)
    cloud.attributes["confidence"] = np.linspace(0, 1, cloud.n).astype(np.float32)
    out = tmp_path / f"synth{ext}"
    io.write(out, cloud, extra_dims={"segment_id": np.arange(cloud.n, dtype=np.int32)})
    las = laspy.read(out)
    assert las.header.point_format.id == 7 and str(las.header.version) == "1.4"
    assert np.allclose(las.header.scales, 0.001) and np.array_equal(las.header.offsets, cloud.origin)
    back = io.read(out)
    got = back.world_xyz()
    assert np.abs(got - world).max() <= 0.0005 + 1e-6              # within the 1 mm scale
    assert np.array_equal(np.round(got * 100), np.round(world * 100))   # centimetres survive
    expected_rgb = cloud.rgb * 257 if depth == 8 else cloud.rgb      # LAS colour is 16-bit
    assert np.array_equal(back.rgb, expected_rgb) and back.color_depth == 16
    assert np.array_equal(back.rgb8(), cloud.rgb8())
    assert np.array_equal(back.intensity, cloud.intensity)
    assert np.array_equal(back.classification, cloud.classification)
    assert np.array_equal(np.asarray(las.confidence), cloud.attributes["confidence"])
    assert np.array_equal(np.asarray(las.segment_id), np.arange(cloud.n))


def test_las_reading_does_not_import_open3d(tmp_path):
    src = tmp_path / "a.laz"
    make_las(src, np.random.default_rng(0).uniform(0, 5, (10, 3)), point_format=6)
    code = (f"import sys, roadx_ti.io as io; io.read({str(src)!r}); io.info({str(src)!r}); "
            "print('open3d' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ----------------------------------------------------------------------------- other formats

@pytest.mark.parametrize("ext", [".ply", ".pcd", ".npz", ".xyz", ".txt", ".csv"])
@pytest.mark.parametrize("depth", [8, 16])
def test_other_format_round_trip(tmp_path, ext, depth):
    cloud, world = synthetic_cloud(depth=depth)
    label = (np.arange(cloud.n) % 4).astype(np.uint8)
    seg = (np.arange(cloud.n) - 7).astype(np.int32)
    out = tmp_path / f"cloud{ext}"
    io.write(out, cloud, extra_dims={"roadx_label": label, "segment_id": seg})
    back = io.read(out)
    tol = {".xyz": 1e-6, ".txt": 1e-6, ".csv": 1e-6}.get(ext, 0.0)
    assert np.abs(back.world_xyz() - (cloud.xyz.astype(np.float64) + cloud.origin)).max() <= tol
    if ext in (".npz", ".ply"):   # both store the origin: local coordinates come back bit for bit
        assert np.array_equal(back.xyz, cloud.xyz) and np.array_equal(back.origin, cloud.origin)
    if ext == ".pcd" and depth == 16:    # PCD colour is 8-bit
        assert back.color_depth == 8 and np.array_equal(back.rgb, np.round(cloud.rgb / 257.0))
    else:
        assert back.color_depth == depth and np.array_equal(back.rgb, cloud.rgb)
    assert np.array_equal(back.intensity, cloud.intensity)
    assert np.array_equal(back.classification, cloud.classification)
    assert np.array_equal(back.attributes["roadx_label"], label)
    assert np.array_equal(back.attributes["segment_id"], seg)
    info = io.info(out)
    assert info["point_count"] == cloud.n and info["color_depth"] == back.color_depth


def test_pcd_gives_back_8bit_colour_stored_x256_exactly(tmp_path):
    """PCD holds 8-bit colour: 16-bit colour holding 8-bit values x 256 (a shift) is written as
    those values (divided by 257 alone, every value over 128 came back one level low)."""
    cloud, _ = synthetic_cloud(depth=16)
    eight = (cloud.rgb // 257).astype(np.uint16)
    shifted = replace(cloud, rgb=eight * np.uint16(256))
    io.write(tmp_path / "c.pcd", shifted)
    back = io.read(tmp_path / "c.pcd")
    assert back.color_depth == 8 and np.array_equal(back.rgb, eight)


def test_las_to_ply_keeps_extra_dims(shared_data, tmp_path):
    src = shared_data / "road" / "ahn3_2386_9702_roads.laz"
    if not src.exists():
        pytest.skip(f"{src} is absent")
    cloud = io.read(src)
    io.write(tmp_path / "road.ply", cloud)
    back = io.read(tmp_path / "road.ply")
    # PLY holds the exact doubles; the reader's float32 local coordinates are those of the LAS read
    assert np.array_equal(back.xyz.astype(np.float64) + back.origin, cloud.xyz.astype(np.float64) + cloud.origin)
    assert np.array_equal(back.attributes["bgt_road"], np.asarray(cloud.las.bgt_road))
    assert np.array_equal(back.classification, cloud.classification)
    # LiDAR returns travel as return_number / number_of_returns columns and come back as returns
    assert np.array_equal(back.returns, cloud.returns)


def test_ply_and_pcd_written_by_open3d(tmp_path):
    o3d = pytest.importorskip("open3d")
    rng = np.random.default_rng(5)
    pts, col = rng.uniform(0, 100, (200, 3)) + [3e5, 5e6, 0], rng.uniform(0, 1, (200, 3))
    legacy = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    legacy.colors = o3d.utility.Vector3dVector(col)
    for name, ascii_ in (("a.ply", True), ("b.ply", False), ("c.pcd", False), ("d.pcd", True)):
        o3d.io.write_point_cloud(str(tmp_path / name), legacy, write_ascii=ascii_)
        ref = o3d.t.io.read_point_cloud(str(tmp_path / name))
        cloud = io.read(tmp_path / name)
        world = ref.point.positions.numpy().astype(np.float64)
        assert np.array_equal(cloud.xyz, (world - cloud.origin).astype(np.float32))
        assert cloud.color_depth == 8
        assert np.array_equal(cloud.rgb, ref.point.colors.numpy().astype(np.uint16))


def test_ply_float_colour_scales_to_8_bit(tmp_path):
    n = 20
    rng = np.random.default_rng(6)
    dtype = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "<f4"), ("green", "<f4"),
                      ("blue", "<f4"), ("scalar_Intensity", "<f4"), ("label", "i2")])
    table = np.zeros(n, dtype)
    for k in "xyz":
        table[k] = rng.uniform(0, 10, n)
    for k in ("red", "green", "blue"):
        table[k] = rng.uniform(0, 1, n)
    table["scalar_Intensity"] = rng.integers(0, 4000, n)
    table["label"] = -rng.integers(0, 300, n)
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 20\n"
            + "".join(f"property {t} {k}\n" for k, t in zip(dtype.names, ["double"] * 3 + ["float"] * 4 + ["short"]))
            + "end_header\n")
    path = tmp_path / "cc.ply"
    path.write_bytes(head.encode() + table.tobytes())
    cloud = io.read(path)
    assert cloud.color_depth == 8
    assert np.array_equal(cloud.rgb[:, 0], np.round(table["red"] * 255))
    assert np.array_equal(cloud.intensity, table["scalar_Intensity"].astype(np.uint16))
    assert np.array_equal(cloud.attributes["label"], table["label"])


def test_text_layouts(tmp_path):
    rng = np.random.default_rng(7)
    xyz = np.round(rng.uniform(0, 100, (30, 3)), 3) + [1e6, 2e6, 0]
    rgb = rng.integers(0, 256, (30, 3))
    inten = rng.integers(0, 1000, 30)
    rows = [" ".join(f"{v:.3f}" for v in p) for p in xyz]
    (tmp_path / "plain.xyz").write_text("\n".join(rows) + "\n")
    (tmp_path / "rgbi.txt").write_text("# scanner export\n" + "\n".join(
        f"{r} {c[0]} {c[1]} {c[2]} {i}" for r, c, i in zip(rows, rgb, inten)) + "\n")
    (tmp_path / "pdal.csv").write_text('"X","Y","Z","Intensity","Classification"\n' + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{i},2" for p, i in zip(xyz, inten)) + "\n")
    (tmp_path / "cc.txt").write_text("//X,Y,Z,R,G,B\n" + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{c[0]},{c[1]},{c[2]}" for p, c in zip(xyz, rgb)) + "\n")
    (tmp_path / "semicolon.csv").write_text("x;y;z;red;green;blue\n" + "\n".join(
        f"{p[0]:.3f};{p[1]:.3f};{p[2]:.3f};{c[0]};{c[1]};{c[2]}" for p, c in zip(xyz, rgb)) + "\n")
    # a delimiter at the end of every line (some spreadsheet and script exports), values in quotes
    (tmp_path / "trailing.csv").write_text("x,y,z,red,green,blue,\n" + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{c[0]},{c[1]},{c[2]}," for p, c in zip(xyz, rgb)) + "\n")
    (tmp_path / "trailing_data.csv").write_text("x,y,z,red,green,blue\n" + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{c[0]},{c[1]},{c[2]}," for p, c in zip(xyz, rgb)) + "\n")
    (tmp_path / "quoted.csv").write_text('"X","Y","Z"\n' + "\n".join(
        f'"{p[0]:.3f}","{p[1]:.3f}","{p[2]:.3f}"' for p in xyz) + "\n")
    # Excel's "CSV UTF-8" (a byte-order mark before the header), and a decimal comma between semicolons
    (tmp_path / "bom.csv").write_text("X,Y,Z,Classification\n" + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},2" for p in xyz) + "\n", encoding="utf-8-sig")
    (tmp_path / "bom_no_header.xyz").write_text("\n".join(rows) + "\n", encoding="utf-8-sig")
    (tmp_path / "decimal_comma.csv").write_text("x;y;z;red;green;blue\n" + "\n".join(
        f"{p[0]:.3f};{p[1]:.3f};{p[2]:.3f};{c[0]};{c[1]};{c[2]}".replace(".", ",") for p, c in zip(xyz, rgb)) + "\n")
    (tmp_path / "decimal_comma_no_header.csv").write_text("\n".join(
        f"{p[0]:.3f};{p[1]:.3f};{p[2]:.3f}".replace(".", ",") for p in xyz) + "\n")
    for name in ("plain.xyz", "rgbi.txt", "pdal.csv", "cc.txt", "semicolon.csv", "trailing.csv", "trailing_data.csv",
                 "quoted.csv", "bom.csv", "bom_no_header.xyz", "decimal_comma.csv", "decimal_comma_no_header.csv"):
        cloud = io.read(tmp_path / name)
        assert np.abs(cloud.world_xyz() - xyz).max() < 1e-4, name   # float32 local coordinates
    assert io.read(tmp_path / "plain.xyz").rgb is None
    rgbi = io.read(tmp_path / "rgbi.txt")
    assert rgbi.color_depth == 8 and np.array_equal(rgbi.rgb, rgb) and np.array_equal(rgbi.intensity, inten)
    pdal = io.read(tmp_path / "pdal.csv")
    assert np.array_equal(pdal.intensity, inten) and np.all(pdal.classification == 2)
    assert np.array_equal(io.read(tmp_path / "cc.txt").rgb, rgb)
    assert np.array_equal(io.read(tmp_path / "semicolon.csv").rgb, rgb)
    assert np.array_equal(io.read(tmp_path / "trailing.csv").rgb, rgb)
    assert np.array_equal(io.read(tmp_path / "trailing_data.csv").rgb, rgb)
    assert np.all(io.read(tmp_path / "bom.csv").classification == 2)
    assert np.array_equal(io.read(tmp_path / "decimal_comma.csv").rgb, rgb)


def test_an_empty_ascii_ply_is_an_empty_cloud(tmp_path):
    path = tmp_path / "empty.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n")
    assert io.read(path).n == 0       # it was an IndexError


def test_zero_points_give_an_empty_cloud(tmp_path):
    make_las(tmp_path / "none.laz", np.zeros((0, 3)), point_format=6)
    assert io.read(tmp_path / "none.laz").n == 0
    (tmp_path / "none.xyz").write_text("# x y z\n")
    assert io.read(tmp_path / "none.xyz").n == 0
    empty = Cloud(xyz=np.zeros((0, 3), np.float32), origin=np.zeros(3))
    for ext in (".laz", ".ply", ".npz", ".xyz"):
        io.write(tmp_path / f"empty{ext}", empty)
        assert io.read(tmp_path / f"empty{ext}").n == 0


# ------------------------------------------------------------------------ atomic and safety

def test_atomic_write_leaves_nothing_when_the_writer_fails(tmp_path, monkeypatch):
    cloud, _ = synthetic_cloud(100)
    out = tmp_path / "out.laz"
    out.write_bytes(b"previous result")

    def broken_write(self, destination, *args, **kw):
        destination.write(b"LASF partial bytes")
        raise RuntimeError("disk full")

    monkeypatch.setattr(laspy.LasData, "write", broken_write)
    with pytest.raises(RuntimeError, match="disk full"):
        io.write(out, cloud)
    assert out.read_bytes() == b"previous result" and leftovers(tmp_path) == []
    new = tmp_path / "new.laz"
    with pytest.raises(RuntimeError):
        io.write(new, cloud)
    assert not new.exists() and leftovers(tmp_path) == []
    monkeypatch.undo()
    io.write(new, cloud)
    assert io.read(new).n == cloud.n and leftovers(tmp_path) == []


def test_atomic_output_context(tmp_path):
    target = tmp_path / "summary.json"
    with atomic_output(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".json"
        tmp.write_text("{}")
        assert not target.exists()
    assert target.read_text() == "{}" and leftovers(tmp_path) == []
    plain = tmp_path / "plain.json"
    plain.write_text("{}")
    assert target.stat().st_mode & 0o777 == plain.stat().st_mode & 0o777   # not mkstemp's 0600
    with pytest.raises(KeyError):
        with atomic_output(target) as tmp:
            tmp.write_text("half")
            raise KeyError("boom")
    assert target.read_text() == "{}" and leftovers(tmp_path) == []


def test_writing_over_the_input_is_refused(tmp_path):
    src = tmp_path / "in.laz"
    make_las(src, np.random.default_rng(0).uniform(0, 5, (10, 3)), point_format=6)
    digest = sha256(src)
    cloud = io.read(src)
    one_line_error(src, io.write, src, cloud)
    link = tmp_path / "link.laz"
    link.symlink_to(src)
    msg = one_line_error(link, io.check_output_path, link, [src])
    assert "input" in msg
    one_line_error(tmp_path / "sub" / ".." / "in.laz", io.check_output_path, tmp_path / "sub" / ".." / "in.laz", [src])
    missing = tmp_path / "nowhere" / "out.laz"
    assert "does not exist" in one_line_error(missing, io.write, missing, cloud)
    assert sha256(src) == digest
    assert io.check_output_path(tmp_path / "ok.laz", [src]) == tmp_path / "ok.laz"


# ------------------------------------------------------------------------------------ errors

def test_error_messages_name_the_file_and_the_problem(tmp_path):
    missing = tmp_path / "missing.laz"
    assert "no such file" in one_line_error(missing, io.read, missing)
    empty = tmp_path / "empty.las"
    empty.touch()
    assert "empty file" in one_line_error(empty, io.read, empty)
    doc = tmp_path / "notes.docx"
    doc.write_text("hello")
    assert "unknown extension" in one_line_error(doc, io.read, doc)
    fake = tmp_path / "fake.las"
    fake.write_text("this is not a LAS file but it is long enough " * 20)
    assert "not a LAS/LAZ" in one_line_error(fake, io.read, fake)
    fake_ply = tmp_path / "fake.ply"
    fake_ply.write_text("hello\n")
    assert "not a PLY" in one_line_error(fake_ply, io.read, fake_ply)
    for name, problem in (("fake.pcd", "not a PCD"), ("fake.npz", "not an NPZ")):
        (tmp_path / name).write_text("hello\n")
        assert problem in one_line_error(tmp_path / name, io.read, tmp_path / name)
    nan = tmp_path / "nan.xyz"
    nan.write_text("1 2 3\nnan 2 3\n4 inf 6\n7 8 9\n")
    assert "2 of 4 points" in one_line_error(nan, io.read, nan)
    bad_npz = tmp_path / "inf.npz"
    np.savez(bad_npz, xyz=np.array([[0, 0, np.inf], [1, 1, 1]]))
    assert "1 of 2 points" in one_line_error(bad_npz, io.read, bad_npz)
    ragged = tmp_path / "ragged.txt"
    ragged.write_text("1 2 3\n4 5\n")
    one_line_error(ragged, io.read, ragged)


@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_truncated_las_is_reported(tmp_path, ext):
    rng = np.random.default_rng(8)
    src = tmp_path / f"whole{ext}"
    make_las(src, rng.uniform(0, 50, (5000, 3)), point_format=7, rgb=rng.integers(0, 65536, (5000, 3)))
    data = src.read_bytes()
    for cut in (len(data) // 2, len(data) - 5):
        cut_file = tmp_path / f"cut{ext}"
        cut_file.write_bytes(data[:cut])
        for fn in (io.read, io.info, lambda p: io.read(p, bounds=(-1, -1, 100, 100))):
            msg = one_line_error(cut_file, fn, cut_file)
            assert "truncated or corrupt" in msg or "truncated" in msg, msg


def test_too_many_points_points_to_tiling(tmp_path):
    src = tmp_path / "huge.las"
    make_las(src, np.zeros((3, 3)), point_format=1, version="1.2")
    raw = bytearray(src.read_bytes())
    raw[107:111] = np.uint32(3_000_000_000).tobytes()    # legacy point count in the LAS 1.2 header
    src.write_bytes(bytes(raw))
    assert "tiles" in one_line_error(src, io.read, src)


def test_text_with_a_ragged_row_names_the_row_not_numpy_advice(tmp_path):
    """A text table whose column count changes says where, without numpy's advice to programmers."""
    path = tmp_path / "ragged.txt"
    path.write_text("1 2 3\n4 5 6\n7 8\n")
    with pytest.raises(InputError) as err:
        io.read(path)
    message = str(err.value)
    assert "not a point table" in message and "row 3" in message
    assert "usecols" not in message and "\n" not in message


@pytest.mark.parametrize("arrays, message", [
    ({"color_depth": np.array([8, 8])}, "'color_depth' must be one number"),
    ({"color_depth": np.array("eight")}, "'color_depth' must be one number"),
    ({"origin": np.array([1.0, 2.0])}, "'origin' must be 3 numbers"),
    ({"origin": np.array(["a", "b", "c"])}, "'origin' must be 3 numbers"),
    ({"rgb": np.zeros(10, np.uint8)}, "'rgb' must be numbers of shape (10, 3)"),
    ({"xyz": np.array([["a", "b", "c"]] * 10)}, "no numeric 'xyz' array"),
])
def test_malformed_npz_is_one_input_error(tmp_path, arrays, message):
    """NPZ arrays of the wrong shape or type (they were TypeError / ValueError / AxisError tracebacks
    reported as 'unexpected error')."""
    content = {"xyz": np.zeros((10, 3), np.float32), "rgb": np.zeros((10, 3), np.uint8),
               "color_depth": np.array(8)} | arrays
    np.savez(tmp_path / "bad.npz", **content)
    with pytest.raises(io.InputError, match=re.escape(message)):
        io.read(tmp_path / "bad.npz")


def test_ply_origin_comment_far_from_the_points_is_ignored(tmp_path):
    """A PLY's 'comment origin' (our writer's local origin) 5,000 km from its points (a hand-edited or
    foreign file): ignored with a warning, so the points keep their precision (float32 offsets from it
    had put them on a 0.5 m grid). A Latin-1 byte in a header comment of an ASCII PLY is no error."""
    rng = np.random.default_rng(2)
    xyz = np.round(rng.uniform(0, 30, (50, 3)), 3)
    rows = "\n".join(" ".join(f"{v:.3f}" for v in p) for p in xyz)
    head = "ply\nformat ascii 1.0\ncomment origin 5000000 5000000 0\nelement vertex 50\n" \
           "property double x\nproperty double y\nproperty double z\nend_header\n"
    (tmp_path / "far.ply").write_text(head + rows + "\n")
    assert np.abs(io.read(tmp_path / "far.ply").world_xyz() - xyz).max() < 1e-5
    (tmp_path / "latin.ply").write_bytes(head.replace("comment origin 5000000 5000000 0", "comment caf\xe9")
                                         .encode("latin-1") + rows.encode() + b"\n")
    assert np.abs(io.read(tmp_path / "latin.ply").world_xyz() - xyz).max() < 1e-5


def test_ply_coordinates_named_in_capitals(tmp_path):
    """PLY vertices with properties X Y Z (some exporters write capitals; the text reader took them,
    the PLY reader refused them)."""
    xyz = np.round(np.random.default_rng(5).uniform(0, 30, (20, 3)), 3)
    head = "ply\nformat ascii 1.0\nelement vertex 20\nproperty double X\nproperty double Y\nproperty double Z\nend_header\n"
    (tmp_path / "caps.ply").write_text(head + "\n".join(" ".join(f"{v:.3f}" for v in p) for p in xyz) + "\n")
    assert np.abs(io.read(tmp_path / "caps.ply").world_xyz() - xyz).max() < 1e-5


def test_ply_origin_of_a_high_survey_is_kept(tmp_path, caplog):
    """Our tiled runs write PLY with the catalog's origin (z 0) beside points 1,500 m up: that origin is
    theirs (within float32's reach) and is kept, local coordinates bit for bit; only an origin farther
    than ORIGIN_REACH from the points is ignored, with a warning."""
    from roadx_ti.io.other import ORIGIN_REACH

    xyz = np.round(np.random.default_rng(6).uniform(0, 30, (20, 3)), 3) + [0, 0, 1500.0]
    rows = "\n".join(" ".join(f"{v:.3f}" for v in p) for p in xyz)
    for name, origin, kept in (("high.ply", "0 0 0", True), ("far.ply", f"{2 * ORIGIN_REACH:.0f} 0 0", False)):
        (tmp_path / name).write_text(f"ply\nformat ascii 1.0\ncomment origin {origin}\nelement vertex 20\n"
                                     "property double x\nproperty double y\nproperty double z\nend_header\n" + rows + "\n")
        caplog.clear()
        cloud = io.read(tmp_path / name)
        assert (cloud.origin.tolist() == [float(v) for v in origin.split()]) == kept
        assert ("lies far from its points" in caplog.text) == (not kept)
        assert np.abs(cloud.world_xyz() - xyz).max() < 1e-4


def test_decimal_comma_when_a_later_line_has_none(tmp_path):
    """'1,5;2,5;3,5' then '4;5;6' (whole numbers need no comma): both are data, not a header line."""
    (tmp_path / "dc.csv").write_text("1,5;2,5;3,5\n4;5;6\n7,25;8;9\n")
    assert np.allclose(io.read(tmp_path / "dc.csv").world_xyz(), [[1.5, 2.5, 3.5], [4, 5, 6], [7.25, 8, 9]])
    (tmp_path / "latin.xyz").write_bytes("# H\xf6he in m\n1 2 3\n4 5 6\n".encode("latin-1"))
    assert io.read(tmp_path / "latin.xyz").n == 2       # a Latin-1 comment was 'not a point table'


def test_values_a_format_cannot_hold_are_one_error(tmp_path):
    """An ASCII PLY uchar of 300 (it wrapped to 44 silently), and a string column written to a text table
    (it failed in numpy after the run): InputError naming the property or column; check_writable says
    the latter before any work."""
    (tmp_path / "over.ply").write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                       "property float z\nproperty uchar red\nend_header\n0 0 0 300\n1 1 1 5\n")
    with pytest.raises(io.InputError, match="'red' .* holds values its type cannot, e.g. 300"):
        io.read(tmp_path / "over.ply")
    cloud = Cloud.from_world(np.zeros((3, 3)), attributes={"label": np.array(["a", "b", "c"])})
    with pytest.raises(io.InputError, match="'label' of type <U1 cannot be written to a numeric text table"):
        io.check_writable(tmp_path / "out.xyz", cloud, {"roadx_label": "uint8"})
    with pytest.raises(io.InputError, match="'label' of type <U1"):
        io.write(tmp_path / "out.xyz", cloud)
    assert not (tmp_path / "out.xyz").exists()


def test_a_classification_column_outside_0_255_is_named_with_a_value(tmp_path):
    """A CSV 'classification' column of 300 is kept as an attribute (LAS classes are 0..255); writing
    it to LAS says which values do not fit (it said 'would hide the cloud's own classification')."""
    xyz = np.random.default_rng(8).uniform(0, 10, (5, 3))
    (tmp_path / "c.csv").write_text("x,y,z,classification\n" + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{c}" for p, c in zip(xyz, (2, 2, 300, 6, 2))) + "\n")
    cloud = io.read(tmp_path / "c.csv")
    assert cloud.classification is None and cloud.attributes["classification"].max() == 300
    with pytest.raises(io.InputError, match=r"'classification' holds values the LAS classification field cannot \(e.g. 300\)"):
        io.check_writable(tmp_path / "out.laz", cloud, {"roadx_label": "uint8"})


def test_streamed_records_equal_the_held_ones_for_a_subset_and_refuse_a_changed_input(tmp_path):
    """io.read(keep_records=False) then io.write streams the records from the input: the same file
    as from records held in memory (a subset too, in file order); an input that changed between
    reading and writing is one InputError and no output."""
    rng = np.random.default_rng(4)
    n = 250_000                                     # several of the writer's chunks
    world = np.round(rng.uniform(0, 300, (n, 3)) * 100) / 100 + np.array([512_000.0, 6_400_000.0, 40.0])
    src = tmp_path / "in.laz"
    make_las(src, world, rgb=rng.integers(0, 65536, (n, 3)).astype(np.uint16), gps_time=rng.uniform(0, 1e5, n))
    held, streamed = io.read(src), io.read(src, keep_records=False)
    for name in ("xyz", "origin", "rgb", "intensity", "classification", "returns"):
        assert np.array_equal(getattr(held, name), getattr(streamed, name)), name
    classes = rng.choice(CLASSES, n)
    extra = {"segment_id": rng.integers(-1, 99, n).astype(np.int32)}
    subset = rng.random(n) < 0.6
    for sub in (None, subset):
        io.write(tmp_path / "a.laz", held, classification=classes, extra_dims=extra, subset=sub)
        io.write(tmp_path / "b.laz", streamed, classification=classes, extra_dims=extra, subset=sub)
        a, b = laspy.read(tmp_path / "a.laz"), laspy.read(tmp_path / "b.laz")
        assert a.points.array.tobytes() == b.points.array.tobytes()
        assert len(b.points) == (n if sub is None else int(subset.sum()))
    make_las(src, world[: n - 10])                  # the input changes during the run
    with pytest.raises(InputError, match="changed during the run"):
        io.write(tmp_path / "c.laz", streamed, classification=classes, extra_dims=extra)
    assert not (tmp_path / "c.laz").exists()
    src.unlink()                                    # ... or is removed
    with pytest.raises(InputError, match="the input is gone"):
        io.write(tmp_path / "c.laz", streamed, classification=classes, extra_dims=extra)
    assert not (tmp_path / "c.laz").exists()


def test_a_header_counting_fewer_points_than_the_file_holds_is_said(tmp_path, caplog):
    """Only the counted records are read (as laspy and PDAL do), with a warning: points are not
    dropped unseen."""
    import logging
    import struct

    las = laspy.create(point_format=3, file_version="1.2")
    las.header.scales = [0.01, 0.01, 0.01]
    las.x, las.y, las.z = np.arange(3000.0) * 0.1, np.zeros(3000), np.zeros(3000)
    path = tmp_path / "short_count.las"
    las.write(path)
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, 107, 1000)          # the legacy point count
    path.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING, logger="roadx_ti"):
        cloud = io.read(path)
    assert cloud.n == 1000
    assert any("header counts 1000 points" in r.getMessage() and "2000 more" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("suffix", [".ply", ".csv", ".pcd", ".npz"])
def test_las_to_other_formats_keeps_every_las_field(tmp_path, suffix):
    """GPS time, scan angle, user data, point source, the flag bits and NIR travel as columns of the
    same names (PDAL's writers carry every dimension; they were left out silently)."""
    rng = np.random.default_rng(5)
    n = 300
    header = laspy.LasHeader(point_format=8, version="1.4")
    header.scales, header.offsets = np.full(3, 0.01), np.array([500000.0, 4500000.0, 0.0])
    las = laspy.LasData(header)
    las.x, las.y, las.z = 500000 + rng.uniform(0, 20, n), 4500000 + rng.uniform(0, 20, n), rng.uniform(0, 5, n)
    # GPS times of adjusted standard time (4e8 s and microseconds): 9 digits in text lost up to 0.5 s
    fields = {"gps_time": 4e8 + rng.uniform(0, 1e6, n), "scan_angle": rng.integers(-3000, 3000, n),
              "user_data": rng.integers(0, 256, n), "point_source_id": rng.integers(0, 65535, n),
              "synthetic": rng.integers(0, 2, n), "withheld": rng.integers(0, 2, n),
              "scanner_channel": rng.integers(0, 4, n), "edge_of_flight_line": rng.integers(0, 2, n),
              "nir": rng.integers(0, 65535, n)}
    for name, values in fields.items():
        las[name] = values
    las.red, las.green, las.blue = (rng.integers(0, 65535, n) for _ in range(3))
    las.write(tmp_path / "in.las")
    io.write(tmp_path / f"out{suffix}", io.read(tmp_path / "in.las"))
    back = io.read(tmp_path / f"out{suffix}")
    for name, values in fields.items():
        got = back.nir if name == "nir" else back.attributes[name]
        np.testing.assert_array_equal(np.asarray(got, np.float64), np.asarray(las[name], np.float64), err_msg=name)


def _ply_with_faces_first(path, binary: bool, xyz):
    """A PLY whose face element (list property) comes before its vertex element (valid PLY; Open3D
    and plyfile read it)."""
    import struct
    fmt = "binary_little_endian" if binary else "ascii"
    head = (f"ply\nformat {fmt} 1.0\nelement face 2\nproperty list uchar int vertex_indices\n"
            f"element vertex {len(xyz)}\nproperty float x\nproperty float y\nproperty float z\nend_header\n")
    with open(path, "wb") as f:
        f.write(head.encode())
        if binary:
            f.write(struct.pack("<B3i", 3, 0, 1, 2) + struct.pack("<B4i", 4, 0, 1, 2, 3))
            f.write(np.asarray(xyz, "<f4").tobytes())
        else:
            f.write(b"3 0 1 2\n4 0 1 2 3\n" + "".join(f"{x} {y} {z}\n" for x, y, z in xyz).encode())


@pytest.mark.parametrize("binary", [False, True])
def test_a_ply_with_its_faces_before_its_vertices(tmp_path, binary):
    """Was refused as 'vertex data with list properties' though the vertices hold none."""
    xyz = np.random.default_rng(1).uniform(0, 10, (50, 3)).astype(np.float32)
    _ply_with_faces_first(tmp_path / "f.ply", binary, xyz)
    cloud = io.read(tmp_path / "f.ply")
    np.testing.assert_array_equal((cloud.xyz.astype(np.float64) + cloud.origin).astype(np.float32), xyz)


def test_an_ascii_ply_holding_more_rows_than_declared_says_so(tmp_path, caplog):
    xyz = np.random.default_rng(2).uniform(0, 10, (50, 3))
    head = "ply\nformat ascii 1.0\nelement vertex 40\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    (tmp_path / "m.ply").write_text(head + "".join(f"{x} {y} {z}\n" for x, y, z in xyz))
    with caplog.at_level("WARNING", logger="roadx_ti"):
        assert io.read(tmp_path / "m.ply").n == 40
    assert "holds 50 data lines, its header declares 40" in caplog.text


# ------------------------------------------------------------------ waveform records, odd names

def _with_waveform_record(path, version: str, point_format: int, payload: bytes = bytes(range(256)) * 4) -> bytes:
    """A LAS file with internal waveform data (global encoding bit 1): LAS 1.4 in an EVLR, LAS
    1.3 appended after the points, the header's pointer (byte 227) at its 60-byte header. Returns
    the record (header and payload) as written."""
    import struct

    world = np.column_stack([np.arange(40.0), np.arange(40.0) % 7, np.zeros(40)]) + [500.0, 800.0, 10.0]
    header = laspy.LasHeader(point_format=point_format, version=version)
    header.scales, header.offsets = np.full(3, 0.01), np.zeros(3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = world[:, 0], world[:, 1], world[:, 2]
    las.wavepacket_index = np.ones(40, np.uint8)
    las.wavepacket_offset = np.arange(40, dtype=np.uint64) * 16
    las.wavepacket_size = np.full(40, 16, np.uint32)
    record = struct.pack("<H16sHQ32s", 0, b"LASF_Spec", 65535, len(payload), b"waveform data") + payload
    if version == "1.4":
        las.evlrs = laspy.vlrs.vlrlist.VLRList([laspy.VLR("LASF_Spec", 65535, "waveform data", payload)])
    las.write(path)
    data = bytearray(Path(path).read_bytes())
    if version == "1.4":
        start = struct.unpack_from("<Q", data, 235)[0]
    else:
        start = len(data)
        data += record
    data[6:8] = struct.pack("<H", struct.unpack_from("<H", data, 6)[0] | 2)
    data[227:235] = struct.pack("<Q", start)
    Path(path).write_bytes(bytes(data))
    return record


def _waveform_record_of(path) -> bytes | None:
    import struct

    data = Path(path).read_bytes()
    if not struct.unpack_from("<H", data, 6)[0] & 2:
        return None
    start = struct.unpack_from("<Q", data, 227)[0]
    return data[start:start + 60 + struct.unpack_from("<Q", data, start + 20)[0]]


@pytest.mark.parametrize("version,point_format", [("1.4", 9), ("1.3", 4)])
@pytest.mark.parametrize("suffix", [".las", ".laz"])
@pytest.mark.parametrize("keep_records", [True, False])
def test_waveform_record_kept_and_pointed_at(tmp_path, version, point_format, suffix, keep_records):
    """The header's pointer to the waveform data packet record points at the output's own record:
    it was copied from the input and pointed into the widened point records (1.4), and LAS 1.3's
    record after the points was left behind while the header still claimed it."""
    src = tmp_path / "in.las"
    record = _with_waveform_record(src, version, point_format)
    before = sha256(src)
    cloud = io.read(src, keep_records=keep_records)
    out = tmp_path / f"out{suffix}"
    io.write(out, cloud, classification=np.full(40, 2, np.uint8), extra_dims={"roadx_label": np.ones(40, np.uint8)})
    assert _waveform_record_of(out) == record
    got = laspy.read(out)
    np.testing.assert_array_equal(np.asarray(got.wavepacket_offset), np.arange(40) * 16)
    assert sha256(src) == before


def test_waveform_records_of_several_files_merged_are_said_dropped(tmp_path, caplog):
    """Two files with waveform records of their own merged into one: the output claims none (each
    file's wave packet offsets point into its own record), with a warning."""
    from roadx_ti.io.las_write import write_las_stream

    files = [tmp_path / "a.las", tmp_path / "b.las"]
    for f in files:
        _with_waveform_record(f, "1.4", 9)
    out = tmp_path / "merged.las"
    labels = lambda i, chunk: (None, {}, None)       # noqa: E731
    with caplog.at_level("WARNING"):
        write_las_stream(out, files, labels, empty=(None, {}, None))
    assert _waveform_record_of(out) is None and len(laspy.read(out).points) == 80
    assert "2 of its inputs each point into a waveform record of their own" in caplog.text
    assert not any(v.record_id == 65535 for v in laspy.read(out).header.evlrs or [])


@pytest.mark.parametrize("name,point_format,standard", [("x", 3, "X"), ("Intensity", 7, "intensity"),
                                                         ("classification", 1, "classification"),
                                                         ("bit_fields", 1, "bit_fields")])
def test_extra_dimension_named_as_a_standard_one_refused(tmp_path, name, point_format, standard):
    """An extra dimension whose name is a standard one in another case ('x' is laspy's scaled X)
    or a legacy bit field's: one line at the read (an 'x' ran the whole pipeline and failed at the
    write with 'unexpected error: IndexError'; 'intensity' read as 'truncated or corrupt')."""
    src = tmp_path / "odd.las"
    header = laspy.LasHeader(point_format=point_format, version="1.4")
    header.add_extra_dims([laspy.ExtraBytesParams(name="zzzzzzzz", type=np.float64)])
    las = laspy.LasData(header)
    las.x = las.y = las.z = np.arange(10.0)
    las.write(src)
    data = bytearray(src.read_bytes())
    at = data.find(b"zzzzzzzz")
    data[at:at + 32] = name.encode().ljust(32, b"\0")
    src.write_bytes(bytes(data))
    msg = one_line_error(src, io.read, src)
    assert f"extra dimension {name!r} has the name of the standard dimension {standard!r}" in msg


def test_input_dimension_of_a_result_name_replaced_with_a_warning(tmp_path, caplog):
    """An input that already holds a 'segment_id' (another tool's uint16, or an earlier run's) has
    it replaced by the run's: said in a warning naming its type (it went silently)."""
    src = tmp_path / "seg.las"
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.add_extra_dims([laspy.ExtraBytesParams(name="segment_id", type=np.uint16)])
    las = laspy.LasData(header)
    las.x = las.y = las.z = np.arange(10.0)
    las.segment_id = np.arange(10, dtype=np.uint16)
    las.write(src)
    with caplog.at_level("WARNING"):
        io.write(tmp_path / "out.las", io.read(src), extra_dims={"segment_id": np.full(10, -1, np.int32)})
    assert "extra dimension 'segment_id' (uint16) is replaced by this run's (int32)" in caplog.text
    assert np.asarray(laspy.read(tmp_path / "out.las").segment_id).tolist() == [-1] * 10


# ------------------------------------------------------------------ PCD, PLY, text, NPZ oddities

PCD_HEAD = "# .PCD v0.7\nVERSION 0.7\nFIELDS {fields}\nSIZE {size}\nTYPE {type}\nCOUNT {count}\nWIDTH {n}\n" \
           "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA ascii\n"


def _pcd(path, fields, rows, n=None, size=None, type_=None, count=None):
    k = len(fields)
    path.write_text(PCD_HEAD.format(fields=" ".join(fields), size=size or " ".join(["4"] * k),
                                    type=type_ or " ".join(["F"] * k), count=count or " ".join(["1"] * k),
                                    n=len(rows) if n is None else n) + "".join(r + "\n" for r in rows))
    return path


@pytest.mark.parametrize("fields,rows,kw,said", [
    (["x", "y", "z", "a", "a"], ["1 2 3 7 8", "4 5 6 1 2"], {}, "PCD field 'a' is named twice"),      # aborted (134)
    (["x", "y", "z", "x"], ["1 2 3 4", "4 5 6 7"], {}, "PCD field 'x' is named twice"),             # x from column 4
    (["x", "y", "z"], [], {"n": 2}, "2 points declared, 0 data rows"),                              # garbage points
    (["x", "y", "z"], ["1 2 3", "4 5 6"], {"n": 5}, "5 points declared, 2 data rows"),
    (["x", "y", "z", "a"], ["1 2 3 abc", "4 5 6 1"], {}, "'abc' in the data is not a number"),      # read as 0
    (["x", "y", "z", "a"], ["1 2 3 4 5 6", "4 5 6 1 2 3"], {"count": "1 1 1 3"}, "has COUNT 3"),   # 2 values lost
    (["x", "y", "z", "h"], ["1 2 3 1", "4 5 6 1"], {"size": "4 4 4 2"}, "has TYPE F SIZE 2"),      # Open3D's raw text
    (["x", "y", "z", "a"], ["1 2 3", "4 5 6 1"], {}, "data row 1 holds 3 values, FIELDS names 4"),
])
def test_pcd_headers_and_data_checked(tmp_path, fields, rows, kw, said):
    """PCD checks Open3D's reader lacks: one line each (a repeated field aborted the process; data
    rows missing were read from uninitialised memory, exit 0)."""
    kw = dict(kw)
    if "type" in kw:
        kw["type_"] = kw.pop("type")
    src = _pcd(tmp_path / "odd.pcd", fields, rows, **kw)
    assert said in one_line_error(src, io.read, src)


@pytest.mark.parametrize("name,text,said", [
    ("dup.csv", "x,y,z,a,a\n1,2,3,4,5\n4,5,6,7,8\n", "text column 'a' is given twice"),       # the first a lost
    ("caps.csv", "x,X,y,z\n1,2,3,4\n5,6,7,8\n", "text column 'X' is given twice (as 'x' too)"),  # x from X
    ("dup.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                "property float a\nproperty float a\nend_header\n1 2 3 4 5\n6 7 8 9 10\n", "PLY property 'a' is given twice"),
    ("wide.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                 "end_header\n1 2 3 4\n5 6 7 8\n", "its vertex rows hold 4 values, the header declares 3"),
])
def test_repeated_column_names_refused(tmp_path, name, text, said):
    src = tmp_path / name
    src.write_text(text)
    assert said in one_line_error(src, io.read, src)


def test_pcd_written_columns_checked_and_half_floats_widened(tmp_path):
    """A column PCD cannot hold is one line before the write ('unexpected error: RuntimeError:
    [Open3D Error] ... unsupported python array format'); float16 goes as float32."""
    world = np.column_stack([np.arange(20.0), np.zeros(20), np.zeros(20)])
    cloud = Cloud.from_world(world, attributes={"h": np.ones(20, np.float16)})
    io.write(tmp_path / "h.pcd", cloud)
    back = io.read(tmp_path / "h.pcd")
    assert back.attributes["h"].dtype == np.float32 and (back.attributes["h"] == 1).all()
    odd = Cloud.from_world(world, attributes={"c": np.ones(20, np.complex64)})
    assert "column 'c' of type complex64 cannot be a PCD field" in one_line_error(tmp_path / "c.pcd", io.write,
                                                                                   tmp_path / "c.pcd", odd)


def test_npz_rows_per_point_kept_and_members_not_arrays_refused(tmp_path):
    """(n, m) arrays come back as m columns (normals were dropped silently); a member that is not
    .npy is one line ('unexpected error: AttributeError: bytes ...'), never unpickled."""
    import zipfile
    xyz = np.random.default_rng(0).random((30, 3)).astype(np.float32)
    np.savez(tmp_path / "n.npz", xyz=xyz, normals=np.tile(np.float32([0, 0, 1]), (30, 1)))
    cloud = io.read(tmp_path / "n.npz")
    assert [cloud.attributes[f"normals_{k}"][0] for k in range(3)] == [0, 0, 1]
    with zipfile.ZipFile(tmp_path / "p.npz", "w") as z:
        z.writestr("xyz", b"\x80\x04not an npy member")
    assert "NPZ member 'xyz' is not a numpy array" in one_line_error(tmp_path / "p.npz", io.read, tmp_path / "p.npz")


def test_odd_values_of_other_formats_said(tmp_path, caplog):
    """Values that were changed silently are said: return counts that are none (300, -1: clipped to
    255 / 0, then used as the vegetation cue), NaN colour (read as black), and a binary PLY holding
    more vertex rows than it declares (the ASCII path said so, the binary one did not)."""
    xyz = np.random.default_rng(0).random((20, 3)).astype(np.float32)
    np.savez(tmp_path / "r.npz", xyz=xyz, return_number=np.full(20, 300), number_of_returns=np.ones(20, int))
    colour = np.full((20, 3), 0.5)
    colour[3] = np.nan
    rows = np.column_stack([xyz, colour]).astype(np.float32)
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 15\n" + "".join(
        f"property float {n}\n" for n in ("x", "y", "z", "red", "green", "blue")) + "end_header\n").encode()
    (tmp_path / "c.ply").write_bytes(header + rows.tobytes())
    with caplog.at_level("WARNING"):
        assert io.read(tmp_path / "r.npz").returns is None
        cloud = io.read(tmp_path / "c.ply")
    assert cloud.n == 15 and cloud.rgb[3].tolist() == [0, 0, 0]
    assert "hold values that are no return counts (whole numbers 0-255, e.g. 300)" in caplog.text
    assert "1 points have no colour value (NaN); they are taken as black" in caplog.text
    assert "holds 5 more vertex rows than its header declares (15)" in caplog.text


def test_merge_of_one_file_with_a_waveform_record_keeps_it(tmp_path):
    """Of two merged files only one has a waveform record: the output keeps it, pointed at (the
    warning said both had records of their own and the header denied the record it still held)."""
    from roadx_ti.io.las_write import write_las_stream

    with_record = tmp_path / "a.las"
    record = _with_waveform_record(with_record, "1.4", 9)
    plain = tmp_path / "b.las"
    las = laspy.read(with_record)
    las.header.global_encoding.value = 0
    las.header.evlrs = laspy.vlrs.vlrlist.VLRList()
    las.write(plain)
    out = tmp_path / "merged.las"
    write_las_stream(out, [with_record, plain], lambda i, chunk: (None, {}, None), empty=(None, {}, None))
    assert _waveform_record_of(out) == record


def test_valid_names_and_layouts_still_read(tmp_path, caplog):
    """What the checks above must not refuse: extra dimensions of distinct non-ASCII names ('α',
    'β' were two '��'), a PCL padding field '_' of several bytes, dark genuine 16-bit colour
    (no mixed-depth warning: 16 % of its points under 256)."""
    header = laspy.LasHeader(point_format=7, version="1.4")
    header.add_extra_dims([laspy.ExtraBytesParams(name=n, type=np.float32) for n in ("α", "β")])
    las = laspy.LasData(header)
    las.x = las.y = las.z = np.arange(50.0)
    rng = np.random.default_rng(0)
    dark = np.clip(rng.integers(0, 250, (50, 3)) * 3 + rng.normal(0, 20, (50, 3)), 0, 745).astype(np.uint16)
    las.red, las.green, las.blue = dark.T
    las.write(tmp_path / "greek.las")
    with caplog.at_level("WARNING"):
        cloud = io.read(tmp_path / "greek.las")
    assert cloud.n == 50 and "beside 16-bit" not in caplog.text
    body = b"".join(np.float32([i, 2 * i, 3 * i]).tobytes() + b"\0" * 4 + np.float32([7 + i]).tobytes() for i in range(3))
    head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z _ intensity\nSIZE 4 4 4 1 4\nTYPE F F F U F\nCOUNT 1 1 1 4 1\n"
            "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA binary\n").encode()
    (tmp_path / "pad.pcd").write_bytes(head + body)
    assert io.read(tmp_path / "pad.pcd").intensity.tolist() == [7, 8, 9]



def test_info_of_other_formats_sees_their_nir_and_names_the_newer_classes(tmp_path):
    """A PLY with a nir column: info says NIR present (it said absent, though io.read reads it as
    NIR); classes 19-22 carry LAS 1.4 R15's names (they were 'reserved')."""
    world = np.column_stack([np.arange(30.0), np.zeros(30), np.zeros(30)])
    cloud = Cloud.from_world(world, nir=np.arange(30, dtype=np.uint16) * 100,
                             classification=np.array([19, 20] * 15, np.uint8))
    io.write(tmp_path / "n.ply", cloud)
    described = io.info(tmp_path / "n.ply")
    assert described["fields"]["nir"]["present"] is True
    names = {row["class"]: row["name"] for row in described["classes"]}
    assert names == {19: "overhead structure", 20: "ignored ground"}


def test_returns_of_a_pdal_text_export_and_nir_into_las_and_text_column_names(tmp_path):
    """Probe 19: PDAL's writers.text names the returns ReturnNumber / NumberOfReturns (they were
    plain columns: the roof pipeline's returns cue was off); NIR read from a PLY goes to LAS as point
    format 8 (it was dropped); a column name with a space cannot be a text header's name (the header
    split it, and the read-back ignored the whole header: colour and classes lost)."""
    xyz = np.column_stack([np.arange(20.0), np.zeros(20), np.ones(20)]) + [500000.0, 4500000.0, 0]
    (tmp_path / "pdal.csv").write_text('"X","Y","Z","ReturnNumber","NumberOfReturns","Classification"\n' + "\n".join(
        f"{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{1 + k % 2},2,5" for k, p in enumerate(xyz)) + "\n")
    pdal = io.read(tmp_path / "pdal.csv")
    assert pdal.returns is not None and np.array_equal(pdal.returns[:, 0], 1 + np.arange(20) % 2)
    io.write(tmp_path / "pdal.txt", pdal)
    header = (tmp_path / "pdal.txt").read_text().splitlines()[0]
    assert "return_number" not in header and "ReturnNumber" in header        # written back once, as it came
    io.write(tmp_path / "pdal.las", pdal)                                   # to LAS: the returns fields
    las = laspy.read(tmp_path / "pdal.las")
    assert np.array_equal(np.asarray(las.return_number), 1 + np.arange(20) % 2)
    assert np.all(np.asarray(las.number_of_returns) == 2)
    assert not set(las.point_format.extra_dimension_names) & {"ReturnNumber", "NumberOfReturns"}

    rgb = np.full((20, 3), 200, np.uint16)
    nir = np.arange(20, dtype=np.uint16) * 1000
    io.write(tmp_path / "n.ply", Cloud.from_world(xyz, rgb=rgb, color_depth=8, nir=nir))
    io.write(tmp_path / "n.laz", io.read(tmp_path / "n.ply"))
    las = laspy.read(tmp_path / "n.laz")
    assert las.header.point_format.id == 8 and np.array_equal(np.asarray(las.nir), nir)
    io.write(tmp_path / "grey.ply", Cloud.from_world(xyz, nir=nir))      # NIR without colour: an extra dimension
    io.write(tmp_path / "grey.laz", io.read(tmp_path / "grey.ply"))
    assert np.array_equal(np.asarray(laspy.read(tmp_path / "grey.laz")["nir"]), nir)

    spaced = Cloud.from_world(xyz, attributes={"Echo Width": np.ones(20, np.float32)})
    for ext in (".txt", ".csv"):
        assert "cannot be a text column name" in one_line_error(tmp_path, io.write, tmp_path / f"s{ext}", spaced)
        assert not (tmp_path / f"s{ext}").exists()


def test_a_las_inputs_crs_and_records_that_another_format_cannot_hold_are_named(tmp_path, caplog):
    """Probe 19: LAS to PLY / PCD / NPZ / text dropped the CRS and the VLRs without a word (a later
    run on the output said it had no CRS); now one warning names them. LAS to LAS keeps them."""
    from rasterio.crs import CRS

    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales, header.offsets = np.full(3, 0.01), np.array([500000.0, 4500000.0, 0.0])
    header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(CRS.from_epsg(25832).to_wkt()))
    header.global_encoding.wkt = True
    header.vlrs.append(laspy.VLR(user_id="surveyor", record_id=7, description="note", record_data=b"flown 2021"))
    las = laspy.LasData(header)
    las.x, las.y, las.z = 500000.0 + np.arange(10.0), np.full(10, 4500000.0), np.zeros(10)
    las.write(tmp_path / "a.las")
    cloud = io.read(tmp_path / "a.las")
    for ext in (".ply", ".pcd", ".npz", ".txt"):
        caplog.clear()
        io.write(tmp_path / f"b{ext}", cloud)
        assert "coordinate system (an OGC WKT record) and 1 other VLR/EVLR record(s) (surveyor)" in caplog.text, ext
    caplog.clear()
    io.write(tmp_path / "b.laz", cloud)
    assert "holds no coordinate system" not in caplog.text
    assert [v.user_id for v in laspy.read(tmp_path / "b.laz").header.vlrs if v.user_id == "surveyor"] == ["surveyor"]
