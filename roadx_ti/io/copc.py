"""COPC output (a name ending in ``.copc.laz``) through copclib (the ``copc`` extra).

copclib writes the format: the LAS 1.4 header, the COPC info, LAZ, extra-bytes and WKT records,
each octree node as its own LAZ chunk and the hierarchy. Here the points are only dealt to the
nodes, as COPC writers do (PDAL's writers.copc, untwine): a node holds at most one point per cell
of a NODE_GRID^3 grid over its cube and passes the others to its eight children; a node with at
most LEAF_POINTS points keeps them all. Readers stream the coarse levels first and a bounds query
decompresses only the nodes that meet it.

COPC holds point formats 6-8 only: other formats are converted to the nearest of them with every
value carried over (the scan angle rank in the 0.006 degree steps of the 1.4 scan angle, the wave
packet fields of formats 4, 5, 9 and 10 as extra dimensions of the same names). The CRS is
written as WKT (COPC allows no GeoTIFF keys): the input's WKT record, or the WKT of its GeoTIFF
keys' EPSG codes. Other VLRs of the input are not carried (copclib writes no others); a warning
names them.
"""
from __future__ import annotations

import copy
import logging
import tempfile
from pathlib import Path

import laspy
import numpy as np

from .atomic import WriteFailure, atomic_output, fail

log = logging.getLogger("roadx_ti")

SUFFIX = ".copc.laz"
# VLR user ids whose content a COPC output carries: the CRS (as WKT), the extra-bytes
# descriptions, the COPC records themselves (made anew)
CARRIED_VLR_USERS = ("LASF_Projection", "LASF_Spec", "copc")
COPC_FORMAT = {0: 6, 1: 6, 2: 7, 3: 7, 4: 6, 5: 7, 6: 6, 7: 7, 8: 8, 9: 6, 10: 8}
NODE_GRID = 128            # cells per axis of a node's grid: one point per cell stays in the node
LEAF_POINTS = 100_000      # a node with at most this many points keeps them all
MAX_DEPTH = 10             # deepest level (a node there keeps all its points)
SCAN_ANGLE_STEP = 0.006    # degrees per unit of the LAS 1.4 scan angle
MISSING = ("COPC output needs copclib, which is not installed here (pip install 'roadx_ti[copc]'; "
           "copclib has no wheel for Python 3.14 yet): write .laz and convert it, e.g. "
           "pdal translate result.laz result.copc.laz")


def is_copc_path(path) -> bool:
    return str(path).lower().endswith(SUFFIX)


def missing() -> str | None:
    """Why COPC cannot be written here (one line), or None when it can."""
    try:
        import copclib  # noqa: F401
    except ImportError:
        return MISSING
    return None


def to_copc_format(las: laspy.LasData) -> tuple[laspy.LasData, int | None]:
    """``las`` in a COPC point format (6-8): (converted data, the former format id or None)."""
    old = las.point_format.id
    new = COPC_FORMAT[old]
    if new == old:
        return las, None
    target = laspy.PointFormat(new)
    carried = [laspy.ExtraBytesParams(name=d.name, type=d.dtype) for d in las.point_format.standard_dimensions
               if d.name not in target.dimension_names and d.name != "scan_angle_rank"]
    target.dimensions.extend(las.point_format.extra_dimensions)   # as laspy.convert does
    header = copy.deepcopy(las.header)
    header.set_version_and_point_format(laspy.header.Version(1, 4), target)
    if carried:
        header.add_extra_dims(carried)
    points = laspy.PackedPointRecord.from_point_record(las.points, header.point_format)
    if "scan_angle_rank" in las.point_format.dimension_names:
        points["scan_angle"] = np.round(np.asarray(las.scan_angle_rank, np.float64) / SCAN_ANGLE_STEP
                                        ).astype(np.int16)
    return laspy.LasData(header, points), old


def octree(xyz: np.ndarray, center: np.ndarray, halfsize: float) -> np.ndarray:
    """The node of every point as (depth, x, y, z) rows (int64 (n, 4)) of the cube ``center`` +-
    ``halfsize``."""
    n = len(xyz)
    u = np.clip((xyz - (center - halfsize)) / (2 * halfsize), 0.0, np.nextafter(1.0, 0.0))
    nodes = np.zeros((n, 4), np.int64)
    remaining = np.arange(n)
    for depth in range(MAX_DEPTH + 1):
        if len(remaining) == 0:
            break
        side = 1 << depth
        key = np.floor(u[remaining] * side).astype(np.int64)
        node_id = (key[:, 0] * side + key[:, 1]) * side + key[:, 2]
        if side ** 3 <= 2**24:      # a dense count, else a sort
            per_point = np.bincount(node_id, minlength=side ** 3)[node_id]
        else:
            _, inverse, counts = np.unique(node_id, return_inverse=True, return_counts=True)
            per_point = counts[inverse.reshape(-1)]
        stays = (per_point <= LEAF_POINTS) | (depth == MAX_DEPTH)
        busy = np.flatnonzero(~stays)
        if len(busy):   # one point per grid cell of a full node stays in it: the first in file order
            side_cells = side * NODE_GRID
            cell = np.floor(u[remaining[busy]] * side_cells).astype(np.int64)
            cell_id = (cell[:, 0] * side_cells + cell[:, 1]) * side_cells + cell[:, 2]
            _, first = np.unique(cell_id, return_index=True)
            stays[busy[first]] = True
        here = remaining[stays]
        nodes[here, 0] = depth
        nodes[here, 1:] = key[stays]
        remaining = remaining[~stays]
    return nodes


def _extra_bytes_vlr(copclib, header: laspy.LasHeader):
    """copclib's extra-bytes record with the names and types of ``header``'s extra dimensions
    (copclib builds it from a file only: a one-point LAZ of the same header, read back)."""
    if not list(header.point_format.extra_dimension_names):
        return copclib.EbVlr(0)
    with tempfile.TemporaryDirectory(prefix="roadx_ti_copc_") as folder:
        probe = copy.deepcopy(header)
        probe.global_encoding.wkt = True   # copclib reads LAS 1.4 with a WKT CRS only
        probe.vlrs = laspy.vlrs.vlrlist.VLRList([v for v in probe.vlrs if v.user_id == "LASF_Spec"])
        tiny = laspy.LasData(probe)
        tiny.points = laspy.ScaleAwarePointRecord.zeros(1, header=probe)
        tiny.write(str(Path(folder) / "probe.laz"))
        return copclib.LazReader(str(Path(folder) / "probe.laz")).laz_config.extra_bytes_vlr


def _crs_wkt(header) -> str:
    from .crs import of_header
    from .las import crs_records

    wkt, _ = crs_records(header)
    if wkt:
        return wkt
    crs = of_header(header)
    return crs.to_wkt() if crs is not None else ""


def _close_failed(writer, tmp) -> None:
    """After a failed write: the temporary file emptied and closed again. copclib's destructor
    closes a writer that is not closed, and when that throws the process aborts (std::terminate):
    a writer whose close fails again is never destroyed (one reference more than Python holds)."""
    import ctypes
    import os

    try:
        os.truncate(tmp, 0)
        writer.Close()
    except (OSError, RuntimeError):
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(writer))


def write(path, las: laspy.LasData) -> None:
    """Write ``las`` (its points, in any order) as COPC to ``path``, atomically."""
    why = missing()
    if why:
        raise fail(path, why)
    import copclib

    n = len(las.points)
    if n == 0:
        raise fail(path, "COPC output needs at least one point")
    las, former = to_copc_format(las)
    if former is not None:
        log.warning("%s: COPC holds point formats 6-8: point format %d written as %d, every value "
                    "carried over", path, former, las.point_format.id)
    h = las.header
    others = [f"{v.user_id}/{v.record_id}" for v in list(h.vlrs) + list(h.evlrs or [])
              if v.user_id not in CARRIED_VLR_USERS]
    if others:
        log.warning("%s: COPC output carries the CRS and the extra dimensions' records only; left out: "
                    "%s (write .las or .laz to keep every record)", path, ", ".join(others))
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    center = (lo + hi) / 2
    halfsize = float((hi - lo).max() / 2 + np.max(h.scales))
    nodes = octree(xyz, center, halfsize)
    node_id = ((nodes[:, 0] << 30) | (nodes[:, 1] << 20) | (nodes[:, 2] << 10) | nodes[:, 3])
    order = np.argsort(node_id, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(node_id[order]) != 0])
    records = las.points.array[order]
    cfg = copclib.CopcConfigWriter(h.point_format.id, copclib.Vector3(*h.scales), copclib.Vector3(*h.offsets),
                                   _crs_wkt(h), _extra_bytes_vlr(copclib, h))
    out = cfg.las_header
    out.min, out.max = copclib.Vector3(*lo), copclib.Vector3(*hi)
    out.file_source_id = int(h.file_source_id)
    out.system_identifier = str(h.system_identifier)[:32]
    out.generating_software = "roadx_ti (copclib)"
    returns = np.clip(np.asarray(las.return_number, np.int64), 0, 15)
    out.points_by_return = np.bincount(returns, minlength=16)[1:16].tolist()
    info = cfg.copc_info
    info.center_x, info.center_y, info.center_z = (float(c) for c in center)
    info.halfsize = halfsize
    info.spacing = 2 * halfsize / NODE_GRID
    with atomic_output(path) as tmp:
        writer = copclib.FileWriter(str(tmp), cfg)
        try:
            for s, e in zip(starts, np.r_[starts[1:], n]):
                d, x, y, z = (int(v) for v in nodes[order[s]])
                data = np.frombuffer(records[s:e].tobytes(), np.int8)
                writer.AddNode(copclib.VoxelKey(d, x, y, z), copclib.VectorChar(data))
            writer.Close()
        except RuntimeError as exc:
            # a full disk shows as a chunk or the header (written last) failing
            _close_failed(writer, tmp)
            raise WriteFailure("copclib: " + " ".join(str(exc).split())) from None
    log.info("%s: COPC, %d points in %d octree nodes (depth %d)", path, n, len(starts), int(nodes[:, 0].max()))
