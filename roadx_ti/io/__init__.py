"""Point-cloud files in and out.

    cloud = roadx_ti.io.read("tile.laz")                      # LAS/LAZ, PLY, PCD, NPZ, XYZ/TXT/CSV
    cloud = roadx_ti.io.read("big.laz", bounds=(x0, y0, x1, y1))   # chunked window, [min, max)
    roadx_ti.io.write("out.laz", cloud, classification=labels,
                      extra_dims={"roadx_label": lab_u8, "segment_id": seg_i32})
    roadx_ti.io.info("tile.laz")   -> dict (count, bounds, format, dimensions, colour, classes, CRS)
    roadx_ti.io.read_headers(paths) -> [(path, (xmin, ymin, xmax, ymax), point_count, (zmin, zmax)), ...]
    roadx_ti.io.split("big.laz", [(key, box), ..], write)      # decode once, records per window

The format follows the extension. Problems with the user's files raise ``InputError`` (a
ValueError) with one line 'PATH: problem'. Outputs are written atomically and never over an input
(see ``check_output_path``). Details per format: ``las.py`` (LAS/LAZ) and ``other.py``.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..cloud import Cloud
from . import las as _las
from . import las_write as _las_write
from . import other as _other
from .atomic import InputError, atomic_output, check_output_path, fail

__all__ = ["InputError", "read", "write", "info", "read_headers", "iter_xy", "check_output_path",
           "atomic_output", "split", "read_part", "record_dtype", "EXTENSIONS"]

EXTENSIONS = {".las": "las", ".laz": "las", ".ply": "ply", ".pcd": "pcd", ".npz": "npz",
              ".xyz": "text", ".txt": "text", ".csv": "text"}


def _kind(path: Path) -> str:
    kind = EXTENSIONS.get(path.suffix.lower())
    if kind is None:
        raise fail(path, f"not a point-cloud file name: unknown extension {path.suffix or '(none)'!r} "
                         f"(expected {' '.join(EXTENSIONS)}; .copc.laz writes COPC)")
    return kind


def _check_input(path: Path) -> None:
    if not path.exists():
        raise fail(path, "no such file")
    if path.is_dir():
        raise fail(path, "is a folder, expected a point-cloud file")
    if not os.access(path, os.R_OK):
        raise fail(path, "not readable (permission denied)")
    if path.stat().st_size == 0:
        raise fail(path, "empty file (0 bytes)")


def read(path, *, bounds=None, origin=None, keep_records: bool = True) -> Cloud:
    """Read a point cloud. ``bounds`` = (xmin, ymin, xmax, ymax) keeps the points with
    xmin <= x < xmax and ymin <= y < ymax (LAS/LAZ are read in chunks, so only those points are held).
    ``origin`` (float64 xyz) overrides the local origin, e.g. to share one origin across tiles.
    ``keep_records`` False (a whole LAS/LAZ file): the point records are not held (``write`` to
    LAS/LAZ streams them from the file again; ``cloud.records_file``). A file with zero points
    gives an empty Cloud."""
    path = Path(path)
    kind = _kind(path)
    _check_input(path)
    if bounds is not None:
        bounds = tuple(float(b) for b in bounds)
        if len(bounds) != 4 or not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
            raise ValueError(f"bounds must be (xmin, ymin, xmax, ymax) with min < max, got {bounds}")
    if kind == "las":
        cloud = _las.read_las(path, bounds, origin, keep_records=keep_records)
    else:
        try:
            cloud = _other.READERS[kind](path, origin)
        except (UnicodeDecodeError, MemoryError) as exc:
            raise fail(path, f"cannot be read as {kind} ({type(exc).__name__})") from None
        if bounds is not None:
            world = cloud.xyz.astype(np.float64) + cloud.origin
            inside = ((world[:, 0] >= bounds[0]) & (world[:, 0] < bounds[2])
                      & (world[:, 1] >= bounds[1]) & (world[:, 1] < bounds[3]))
            cloud = cloud.subset(inside)
    return _checked(path, cloud)


def split(path, windows, write) -> None:
    """Decode a LAS/LAZ file once and hand each of ``windows`` [(key, (xmin, ymin, xmax, ymax)), ..]
    its raw point records chunk by chunk: ``write(key, records)`` (las.split_las). With
    ``read_part`` of a key's records concatenated, a tiled run decodes each file once, not once
    per tile that touches it."""
    path = Path(path)
    _check_input(path)
    if _kind(path) != "las":
        raise ValueError(f"{path}: only LAS/LAZ files are split")
    _las.split_las(path, windows, write)


def read_part(path, records, origin) -> Cloud:
    """The Cloud of one window's records from ``split`` (same as ``read(path, bounds=window, origin=origin)``)."""
    path = Path(path)
    return _checked(path, _las.read_las_part(path, records, origin))


record_dtype = _las.record_dtype


def _checked(path: Path, cloud: Cloud) -> Cloud:
    if not np.all(np.isfinite(cloud.origin)):
        raise fail(path, f"local origin {cloud.origin.tolist()} is not finite")
    bad = int(np.count_nonzero(~np.isfinite(cloud.xyz).all(axis=1))) if cloud.n else 0
    if bad:
        raise fail(path, f"{bad} of {cloud.n} points have NaN or infinite coordinates (relative to the "
                         f"origin {cloud.origin.tolist()})")
    if cloud.n > _las.MAX_POINTS:
        raise _las._too_many(path, cloud.n)
    return cloud


def write(path, cloud: Cloud, *, classification=None, extra_dims=None, subset=None) -> None:
    """Write ``cloud`` atomically in the format of ``path``'s extension (LAS/LAZ, PLY, PCD, NPZ, text).

    classification: per-point uint8 classes replacing the cloud's (ASPRS: 1 other, 2 ground,
    6 building, 11 road). extra_dims: {name: per-point array}, LAS extra dimensions (replacing
    same-named ones) or extra columns/properties. subset: bool mask or indices of the points to write
    (classification and extra_dims are given for all points of the cloud).
    A cloud read from LAS is written from its point records: every attribute is kept bit-exact."""
    if not isinstance(cloud, Cloud):
        raise TypeError(f"cloud must be a roadx_ti.cloud.Cloud, got {type(cloud).__name__}")
    if classification is not None:
        classes = np.asarray(classification)
        if classes.dtype.kind == "f" and classes.size and not np.array_equal(classes, np.round(classes)):
            # 2.5 was written as class 2 to PLY, PCD, NPZ and text
            raise ValueError(f"classification must hold whole class numbers, e.g. not {classes[classes != np.round(classes)][0]:g}")
    if subset is not None:
        _las_write.point_index(subset, cloud.n)        # before the output path is checked or made
    path = Path(path)
    kind = _kind(path)
    inputs = [cloud.source] if cloud.source and Path(cloud.source).exists() else []
    check_output_path(path, inputs)
    if kind == "las":
        _las_write.write_las(path, cloud, classification=classification, extra_dims=extra_dims, subset=subset)
    else:
        try:
            _other.WRITERS[kind](path, cloud, classification, extra_dims, subset)
        except InputError:
            raise
        except ValueError as exc:      # a column the format cannot hold (other.writable_columns)
            raise fail(path, f"cannot be written: {' '.join(str(exc).split())}") from None
        _say_what_the_format_drops(path, cloud)     # once written (a refused write drops nothing)


WRITABLE_CHUNK = 1 << 20    # points check_writable converts at a time


def check_writable(path, cloud: Cloud, result_dims: dict) -> None:
    """Before a run: raise InputError now, not after the whole pipeline, when ``cloud``'s own
    columns cannot be written to ``path``'s format (a float 'intensity' into LAS's integer field,
    a column named like one the writer makes). ``result_dims``: {name: dtype} of the per-point
    results the run will add. A LAS cloud written to LAS keeps its records: nothing to check."""
    path = Path(path)
    kind = _kind(path)
    if kind == "las" and (cloud.las is not None or cloud.records_file):
        return
    classification = np.zeros(cloud.n, np.uint8)
    extra = {name: np.zeros(cloud.n, dtype) for name, dtype in result_dims.items()}
    # the writer's own conversion, a chunk of points at a time: its memory stays small
    for start in range(0, max(cloud.n, 1), WRITABLE_CHUNK):
        index = np.arange(start, min(start + WRITABLE_CHUNK, cloud.n))
        if kind == "las":
            _las_write.las_from_arrays(path, cloud, classification, extra, index)
            continue
        try:
            _, columns = _other.writable_columns(cloud, classification, extra, index)
        except ValueError as exc:
            raise fail(path, f"{cloud.source or 'the input'} cannot be written to {path.suffix}: {exc}") from None
        if kind in _other.COLUMN_CHECKS:
            _other.COLUMN_CHECKS[kind](path, columns)


def _say_what_the_format_drops(path: Path, cloud: Cloud) -> None:
    """A warning when a LAS input's coordinate system and records (VLRs / EVLRs) have no place in
    a PLY / PCD / NPZ / text output (they went silently; a later run on the output had no CRS)."""
    import logging

    import laspy

    if cloud.las is not None:
        header = cloud.las.header
    elif cloud.records_file:
        with laspy.open(cloud.records_file) as reader:
            header = reader.header
    else:
        return
    wkt, codes = _las.crs_records(header)
    records = list(header.vlrs) + list(header.evlrs or [])
    crs_ids = (2112, 34735, 34736, 34737)         # OGC WKT, GeoTIFF keys, doubles, ascii params
    crs_vlrs = [v for v in records if v.user_id == "LASF_Projection" and v.record_id in crs_ids]
    others = [v for v in records if v not in crs_vlrs
              and not isinstance(v, laspy.vlrs.known.ExtraBytesVlr)         # written as columns
              and v.user_id not in ("laszip encoded", "LASF_Spec")]       # the file's own layout
    named = "EPSG:" + str(codes[0]) if codes else "an OGC WKT record" if wkt else "GeoTIFF keys"
    parts = [f"coordinate system ({named})"] if wkt or codes or crs_vlrs else []
    parts += [f"{len(others)} other VLR/EVLR record(s) ({', '.join(sorted({v.user_id for v in others}))})"] if others else []
    if parts:
        logging.getLogger("roadx_ti").warning(
            "%s: %s holds no coordinate system and no LAS records: the input's %s are not in it "
            "(write .las / .laz to keep them)", path, path.suffix.lower(), " and ".join(parts))


def info(path) -> dict:
    """Summary of a file: point_count, crs (LAS, when it has one), bounds {min, max},
    point_density / point_spacing / occupied_area (over occupied cells, not the bounding box),
    fields {rgb, intensity, nir, return_number, number_of_returns: present, varies, min, max},
    format, point_format and version (LAS), dimensions, extra_dimensions, color ('16-bit',
    '8-bit', 'all-zero', 'none'), color_depth, classes [{class, name, points}], class_histogram
    {class: count}. LAS is scanned in chunks. Strict JSON: no NaN (None where unknown)."""
    path = Path(path)
    kind = _kind(path)
    _check_input(path)
    if kind == "las":
        return _las.info_las(path)
    from .describe import Survey, classes

    cloud = read(path)
    world = cloud.xyz.astype(np.float64) + cloud.origin
    dims = ["x", "y", "z"] + (["red", "green", "blue"] if cloud.rgb is not None else [])
    dims += [name for name, a in (("intensity", cloud.intensity), ("classification", cloud.classification))
             if a is not None]
    hist = {}
    if cloud.classification is not None:
        values, counts = np.unique(cloud.classification, return_counts=True)
        hist = {int(v): int(c) for v, c in zip(values, counts)}
    survey = Survey()
    returns = cloud.returns
    survey.add(world[:, :2], {"rgb": cloud.rgb, "intensity": cloud.intensity,
                              "nir": cloud.nir if cloud.nir is not None else cloud.attributes.get("nir"),
                              "return_number": None if returns is None else returns[:, 0],
                              "number_of_returns": None if returns is None else returns[:, 1]})
    return {
        "path": str(path), "format": kind if kind != "text" else path.suffix.lower().lstrip("."),
        "point_count": cloud.n, "crs": None,
        "bounds": {"min": world.min(axis=0).tolist(), "max": world.max(axis=0).tolist()} if cloud.n else None,
        **survey.facts(cloud.n),
        "point_format": None, "version": None,
        "dimensions": dims + list(cloud.attributes), "extra_dimensions": list(cloud.attributes),
        "color": f"{cloud.color_depth}-bit" if cloud.rgb is not None else "none",
        "color_depth": cloud.color_depth if cloud.rgb is not None else None,
        "classes": classes(hist), "class_histogram": hist,
    }


def iter_xy(path):
    """World x, y (float64) of a file's points, chunk by chunk (LAS/LAZ streamed; other formats
    read whole)."""
    path = Path(path)
    kind = _kind(path)
    _check_input(path)
    if kind == "las":
        yield from _las.iter_xy_las(path)
        return
    cloud = read(path)
    if cloud.n:
        world = cloud.world_xyz()
        yield world[:, 0], world[:, 1]


def read_headers(paths) -> list[tuple[str, tuple[float, float, float, float], int, tuple[float, float]]]:
    """[(path, (xmin, ymin, xmax, ymax), point_count, (zmin, zmax))] per file, from the LAS header
    alone (other formats have no header bounds and are read). Bounds are the header's, max inclusive."""
    out = []
    for p in paths:
        path = Path(p)
        kind = _kind(path)
        _check_input(path)
        if kind == "las":
            count, bounds, z_range = _las.read_header_las(path)
        else:
            cloud = read(path)
            world = cloud.xyz.astype(np.float64) + cloud.origin
            count = cloud.n
            bounds = ((float(world[:, 0].min()), float(world[:, 1].min()), float(world[:, 0].max()),
                       float(world[:, 1].max())) if count else (0.0, 0.0, 0.0, 0.0))
            z_range = (float(world[:, 2].min()), float(world[:, 2].max())) if count else (0.0, 0.0)
        out.append((str(p), bounds, count, z_range))
    return out
