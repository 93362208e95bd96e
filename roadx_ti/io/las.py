"""LAS/LAZ through laspy (lazrs decodes LAZ).

Reading keeps the laspy ``LasData`` in ``cloud.las``; the kernels get ``xyz`` as float32
coordinates relative to a float64 local origin: the floor of the header's minimum corner (the same
origin for a whole file and for any ``bounds`` window of it, so tiles of one file line up exactly),
or the floor of the points' minimum corner when the header box does not contain the points.

Writing is roadx_ti.io.las_write.
"""
from __future__ import annotations

import contextlib
import copy
import logging
import os
import re

import laspy
import numpy as np

from ..chunks import over_chunks
from ..cloud import MIXED_DEPTH_SHARE, Cloud, byte_sized_share, detect_color_depth
from ..columns import column_abs_nanmax, column_max, column_min
from .atomic import InputError, fail

try:
    from lazrs import LazrsError
except ImportError:  # LAZ then fails in laspy with its own message, mapped below
    class LazrsError(Exception):
        pass

log = logging.getLogger(__name__)

MAX_POINTS = 2**31 - 1      # arrays and kernel indices are 32-bit
CHUNK_POINTS = 1_000_000    # points per chunk for windowed reads and info
SPLIT_CHUNK_POINTS = 4_000_000   # per chunk of split_las: lazrs decodes a chunk's parts in parallel
# a LAZ file whose header claims more record bytes than this many times its size is read in
# chunks, so that memory follows the points it really holds (LAZ compresses point records 3-11x)
PLAUSIBLE_LAZ_RATIO = 64
NEW_FILE_SCALE = 0.001      # metres: scale of LAS files written from non-LAS clouds
# LAS 1.0-1.3 formats keep the class in 5 bits (0-31); the 1.4 format with the same fields holds 0-255
WIDE_CLASS_FORMAT = {0: 6, 1: 6, 2: 7, 3: 7, 4: 9, 5: 10}
EXTRA_DIM_TYPES = {np.dtype(t) for t in ("u1", "i1", "u2", "i2", "u4", "i4", "u8", "i8", "f4", "f8")}
# what laspy and lazrs raise on a malformed file: every exception but ours (a corrupt header or
# chunk reaches struct, numpy and Rust code paths laspy does not wrap)
LAS_ERRORS = (Exception,)

# sizes of the LAS point formats 0-10 without extra bytes, and of the header per minor version
POINT_SIZES = {0: 20, 1: 28, 2: 26, 3: 34, 4: 57, 5: 63, 6: 30, 7: 36, 8: 38, 9: 59, 10: 67}
HEADER_SIZES = {0: 227, 1: 227, 2: 227, 3: 235, 4: 375}
VLR_HEADER, EVLR_HEADER = 54, 60
EXTRA_BYTES_STRUCT = 192    # bytes per dimension of the Extra Bytes VLR


_WARNED: set = set()      # (kind, file) of the warnings said already in this process


def forget_warnings() -> None:
    """warn_once says its warnings again (a new CLI run in the same process)."""
    _WARNED.clear()


def warn_once(key, message: str, *args) -> None:
    """A warning about a file said once per ``key``: the header is checked at every read of a file,
    and a streamed write builds its header for every chunk."""
    if key not in _WARNED:
        _WARNED.add(key)
        log.warning(message, *args)


def check_structure(path) -> None:
    """Check a LAS/LAZ file's header against the file itself before laspy reads it, so that a
    lying field fails in one line instead of an allocation or a loop sized by it (a VLR count of
    2^31 made laspy read VLRs until memory ran out): signature, version, header size, offset to
    the points, every VLR within the space before the points, point format and record length,
    the points of an uncompressed file within the file, the EVLRs within the file."""
    import os
    import struct

    size = os.path.getsize(path)
    with open(path, "rb") as f:
        head = f.read(375)
        if len(head) < 227:
            if head[:4] != b"LASF":
                raise fail(path, "not a LAS/LAZ file (no LASF signature)")
            raise fail(path, f"truncated LAS/LAZ file: {len(head)} bytes, a LAS header needs 227")
        if head[:4] != b"LASF":
            raise fail(path, "not a LAS/LAZ file (no LASF signature)")
        major, minor = head[24], head[25]
        if major != 1 or minor not in HEADER_SIZES:
            raise fail(path, f"LAS version {major}.{minor} is not supported (1.0 to 1.4)")
        header_size, offset, vlrs = struct.unpack_from("<HII", head, 94)
        fmt_byte, record = struct.unpack_from("<BH", head, 104)
        count = struct.unpack_from("<I", head, 107)[0]
        need = HEADER_SIZES[minor]
        if len(head) < need:
            raise fail(path, f"truncated LAS/LAZ file: {len(head)} bytes, a LAS {major}.{minor} header needs {need}")
        if minor >= 4:
            evlr_start, evlr_count, count = struct.unpack_from("<QIQ", head, 235)
            if count == 0 and struct.unpack_from("<I", head, 107)[0] > 0:
                legacy = struct.unpack_from("<I", head, 107)[0]
                raise fail(path, f"invalid header: its LAS 1.4 point count is 0 but its legacy point count says "
                                 f"{legacy} (a writer that filled only the older field); readers take the LAS 1.4 "
                                 "count, so rewrite the header (e.g. pdal translate, las2las)")
        if not need <= header_size <= offset <= size:
            raise fail(path, f"invalid header: header size {header_size}, offset to the points {offset}, "
                             f"file size {size} (LAS {major}.{minor} needs {need} <= header size <= offset <= file size)")
        if vlrs * VLR_HEADER > offset - header_size:
            raise fail(path, f"invalid header: {vlrs} VLRs cannot fit in the {offset - header_size} bytes "
                             "before the points")
        f.seek(header_size)
        block = f.read(offset - header_size)
        pos = 0
        extra_names = []
        for i in range(vlrs):
            length = struct.unpack_from("<H", block, pos + 20)[0]
            if block[pos + 2:pos + 18].rstrip(b"\0") == b"LASF_Spec" and struct.unpack_from("<H", block, pos + 18)[0] == 4:
                body = block[pos + VLR_HEADER:pos + VLR_HEADER + length]
                extra_names += [body[j + 4:j + 36].split(b"\0")[0] for j in range(0, len(body) - EXTRA_BYTES_STRUCT + 1,
                                                                                   EXTRA_BYTES_STRUCT)]
            pos += VLR_HEADER + length
            if pos > len(block):
                raise fail(path, f"invalid VLR {i + 1} of {vlrs}: its {length} bytes run past the start of "
                                 "the points")
        if head[104] & 0xC0:
            # LAZ: the points start with the chunk table's offset (-1: given at the file's end);
            # a wrong one made lazrs allocate gigabytes before failing (10 s of zeroed pages for a
            # 19 kB file whose offset to the points was one byte off)
            f.seek(offset)
            raw = f.read(8)
            table = struct.unpack("<q", raw)[0] if len(raw) == 8 else None
            if table is None or (table != -1 and not offset + 8 <= table <= size - 8):
                raise fail(path, "truncated or corrupt LAS/LAZ file (its chunk table offset "
                                 f"{'is missing' if table is None else table} lies outside the {size}-byte file)")
    point_format = fmt_byte & 0x3F
    compressed = bool(fmt_byte & 0xC0)
    if point_format not in POINT_SIZES:
        raise fail(path, f"invalid header: point format {point_format} is not a LAS point format (0 to 10)")
    _check_extra_names(path, point_format, extra_names)
    if record < POINT_SIZES[point_format]:
        raise fail(path, f"invalid header: point records of {record} bytes, point format {point_format} "
                         f"needs {POINT_SIZES[point_format]}")
    if count > MAX_POINTS:
        raise _too_many(path, count)
    if not compressed:
        # where the point records end: at the EVLRs (LAS 1.4) or waveform packets (LAS 1.3) when
        # those lie inside the file (the truncation message counted the EVLRs' bytes as points)
        end = evlr_start if minor >= 4 and evlr_count and offset <= evlr_start <= size else size
        if minor == 3 and len(head) >= 235:
            waveform = struct.unpack_from("<Q", head, 227)[0]
            end = waveform if offset < waveform <= end else end
        if offset + count * record > size or (end < size and offset + count * record > end):
            raise fail(path, f"truncated LAS/LAZ file: the header says {count} points, the file holds "
                             f"{(end - offset) // record}")
        # more whole records than the header counts (a writer that did not update the count): only
        # the counted ones are read, as every reader does; say so rather than drop points unseen
        # only whole records to the end: bytes that are not (a wrong record length, trailing data)
        # are for the reader's own checks to name
        trailing = end - offset - count * record
        extra = trailing // record if trailing > 0 and trailing % record == 0 else 0
        if extra > 0 and count == 0:
            raise fail(path, f"invalid header: it counts no points but the file holds {extra} whole point records; "
                             "rewrite the file's header (e.g. pdal translate) if they are points")
        if extra > 0:
            warn_once(
                ("uncounted", str(path)), "%s: the header counts %d points but the file holds %d more whole point records after them; "
                "only the %d counted are read (rewrite the file's header, e.g. with pdal translate, if they are points)",
                path, count, extra, count)
    if minor >= 4 and evlr_count and not (offset <= evlr_start and evlr_start + evlr_count * EVLR_HEADER <= size):
        raise fail(path, f"invalid header: {evlr_count} EVLRs from byte {evlr_start} do not fit in the file "
                         f"of {size} bytes")


def _check_extra_names(path, point_format: int, names: list) -> None:
    """Extra Bytes names that a reader cannot tell from a standard dimension (any case: 'x' is
    laspy's scaled X, 'classification' a legacy format's bit field) or from another extra
    dimension: one line naming it (an 'x' ran the whole pipeline and failed at the write)."""
    fmt = laspy.PointFormat(point_format)
    standard = {n.lower(): n for n in ("x", "y", "z", *fmt.dimension_names, *fmt.dtype().names)}
    seen = set()
    for raw in names:
        name = raw.decode("utf-8", "backslashreplace")      # distinct bytes, distinct names ('α', 'β')
        if not name:
            continue        # laspy names an unnamed one itself
        if name.lower() in standard:
            raise fail(path, f"its extra dimension {name!r} has the name of the standard dimension "
                             f"{standard[name.lower()]!r} (names compare without case): readers cannot tell them "
                             "apart; rename it (e.g. in laspy, or pdal translate with filters.ferry)")
        if raw in seen:
            raise fail(path, f"two of its extra dimensions are named {name!r}; rename one (e.g. in laspy)")
        seen.add(raw)


def _las_error(path, exc: Exception) -> InputError:
    if isinstance(exc, InputError):     # already names the file and says what is wrong
        return exc
    text = " ".join(str(exc).split()) or type(exc).__name__
    if "too small" in text or "to small" in text or "signature" in text.lower():
        return fail(path, f"not a LAS/LAZ file ({text})")
    return fail(path, f"truncated or corrupt LAS/LAZ file ({text})")


@contextlib.contextmanager
def las_errors(path):
    """Inside, a laspy / lazrs failure reading ``path`` (truncated, corrupt) is the InputError
    that names the file, as the readers here raise it."""
    try:
        yield
    except InputError:
        raise
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc


def _too_many(path, n: int) -> InputError:
    return fail(path, f"{n} points is more than one cloud can hold (2**31-1); split it into tiles "
                      "(read it in windows with read(path, bounds=...), or pdal tile / lastile)")


# m: the largest coordinate step (scale) and coordinate magnitude a survey's header can mean (a
# scale of 1e6 put points 1e15 m off, one of 10 m 64 m apart over 250 km; no CRS on Earth,
# projected or geocentric, nears 1e9 m)
MAX_SCALE = 1.0
MAX_COORDINATE = 1e9


def _numbers(values) -> str:
    return "[" + ", ".join(f"{float(v):g}" for v in values) + "]"


def _check_header(path, header) -> None:
    scales, offsets = np.asarray(header.scales, np.float64), np.asarray(header.offsets, np.float64)
    if not (np.all(np.isfinite(scales)) and np.all(np.isfinite(offsets))):
        raise fail(path, f"invalid header: scales {_numbers(scales)} offsets {_numbers(offsets)} are not finite "
                         "numbers; fix the header (e.g. pdal translate with writers.las.scale_x / offset_x)")
    if np.any(scales == 0):
        raise fail(path, f"invalid header: scales {_numbers(scales)}: a scale of 0 puts every point on the "
                         "offset; fix the header (e.g. pdal translate with writers.las.scale_x)")
    if np.any(scales < 0):
        # valid arithmetic, but the file's header box and most readers take min(X) for the smallest
        # coordinate: the output's header had min x > max x
        raise fail(path, f"invalid header: scales {_numbers(scales)}: a negative scale mirrors the records; "
                         "rewrite the file with positive scales (e.g. pdal translate with writers.las.scale_x)")
    if np.any(np.abs(scales) > MAX_SCALE) or np.any(np.abs(offsets) > MAX_COORDINATE):
        raise fail(path, f"invalid header: scales {_numbers(scales)} offsets {_numbers(offsets)}: steps over "
                         f"{MAX_SCALE:g} m or offsets over {MAX_COORDINATE:g} m are no survey's; the header's scales "
                         "or offsets are wrong")


def _check_magnitude(path, world: np.ndarray, scales) -> None:
    """Coordinates so large that float64 cannot hold them at the file's scale (an offset near
    1e308: every point collapses onto one value) are a broken header, not a survey."""
    if not len(world):
        return
    reach = column_abs_nanmax(world)
    limit = np.minimum(np.maximum(np.abs(np.asarray(scales, np.float64)), 1e-3) * 2.0**52, MAX_COORDINATE)
    bad = np.flatnonzero(np.isfinite(reach) & (reach > limit))
    if len(bad):
        a = int(bad[0])
        raise fail(path, f"{'xyz'[a]} coordinates reach {reach[a]:.3g} m, beyond what float64 holds at the "
                         f"file's {float(scales[a]):g} m scale or any survey's {MAX_COORDINATE:g} m; the header's "
                         "scales or offsets are wrong")


def _world_xyz(points) -> np.ndarray:
    """float64 world coordinates of a laspy point record: X * scale + offset per axis (laspy's
    own arithmetic), written in place a chunk at a time (roadx_ti.chunks)."""
    raw = [np.asarray(points.array[d]) for d in ("X", "Y", "Z")]
    scales, offsets = np.asarray(points.scales, np.float64), np.asarray(points.offsets, np.float64)
    out = np.empty((len(raw[0]), 3), np.float64)

    def part(start, stop):
        for a in range(3):
            out[start:stop, a] = raw[a][start:stop] * scales[a] + offsets[a]
    over_chunks(part, len(out))
    return out


def _local_origin(header_mins, header_maxs, scales, world: np.ndarray, whole: bool = True) -> np.ndarray:
    """The floor of the header's minimum corner; of the points' when the header box does not hold
    them; for a whole file (not a window, whose origin must not depend on the window), of the
    points' without the isolated ones when there are (roadx_ti.isolation.local_origin)."""
    hmin, hmax = np.asarray(header_mins, np.float64), np.asarray(header_maxs, np.float64)
    if len(world) == 0:
        return np.floor(hmin) if np.all(np.isfinite(hmin)) else np.zeros(3)
    lo, hi = column_min(world), column_max(world)
    if whole and np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
        from roadx_ti.isolation import SMALL_PART, isolated

        far = isolated(world, SMALL_PART)
        if far is not None:
            return np.floor(column_min(world[~far]))
    tol = np.abs(np.asarray(scales, np.float64))
    if np.all(np.isfinite(hmin)) and np.all(lo >= hmin - tol) and np.all(hi <= hmax + tol):
        return np.floor(hmin)
    return np.floor(lo)  # header box is stale or wrong: fall back to the data


def is_copc(header) -> bool:
    """A Cloud Optimized Point Cloud: its first VLR is the 'copc' info record."""
    return any(v.user_id == "copc" and v.record_id == 1 for v in header.vlrs)


def _read_copc_window(path, header, bounds) -> np.ndarray:
    """COPC: decompress only the octree nodes that meet the window (laspy's bounds query, in file
    order: the nodes are read by offset), then keep the half-open window exactly."""
    xmin, ymin, xmax, ymax = bounds
    pad = np.asarray(header.scales[:2], np.float64)   # the query rounds to the integer grid
    query = laspy.copc.Bounds(mins=np.array([xmin, ymin]) - pad, maxs=np.array([xmax, ymax]) + pad)
    with laspy.CopcReader.open(str(path)) as copc:
        points = copc.query(bounds=query)
    x, y = np.asarray(points.x), np.asarray(points.y)
    return points.array[(x >= xmin) & (x < xmax) & (y >= ymin) & (y < ymax)]


def _read_window(path, reader, bounds) -> laspy.ScaleAwarePointRecord:
    """Points with xmin <= x < xmax and ymin <= y < ymax, in file order: from a COPC file's
    octree nodes that meet the window, otherwise read chunk by chunk."""
    header = reader.header
    xmin, ymin, xmax, ymax = (float(b) for b in bounds)
    kept = []
    hmin, hmax = header.mins, header.maxs
    disjoint = hmax[0] < xmin or hmin[0] >= xmax or hmax[1] < ymin or hmin[1] >= ymax
    if not disjoint and is_copc(header):
        kept.append(_read_copc_window(path, header, (xmin, ymin, xmax, ymax)))
    elif not disjoint:
        _split_chunks(path, reader, [(0, (xmin, ymin, xmax, ymax))], lambda _, records: kept.append(records),
                      CHUNK_POINTS)
    array = np.concatenate(kept) if kept else np.zeros(0, dtype=header.point_format.dtype())
    if len(array) > MAX_POINTS:
        raise _too_many(path, len(array))
    return laspy.ScaleAwarePointRecord(array, header.point_format, header.scales, header.offsets)


def _read_all(path, reader) -> laspy.LasData:
    """Every point of an open file. LAZ is decompressed chunk by chunk, so memory follows the
    points the file really holds, not the count its header claims."""
    header = reader.header
    claimed = header.point_count * header.point_format.size
    if not header.are_points_compressed or claimed <= PLAUSIBLE_LAZ_RATIO * os.path.getsize(path):
        # whole: lazrs decompresses the chunks in parallel (measured 1.1 s against 1.7-2.0 s in
        # chunks of CHUNK_POINTS for 4 M points); the header's count is plausible for the file size
        las = reader.read()
        got = len(las.points)
    else:
        chunks, got = [], 0
        for chunk in reader.chunk_iterator(CHUNK_POINTS):
            chunks.append(chunk.array)
            got += len(chunk)
        array = np.concatenate(chunks) if chunks else np.zeros(0, dtype=header.point_format.dtype())
        las = laspy.LasData(copy.deepcopy(header), laspy.ScaleAwarePointRecord(
            array, header.point_format, header.scales, header.offsets))
        las.header.point_count = got
    if got != header.point_count:
        raise fail(path, f"truncated LAS/LAZ file: {got} of {header.point_count} points could be read")
    return las


def read_las(path, bounds=None, origin=None, keep_records: bool = True) -> Cloud:
    """Read a LAS/LAZ file (optionally only the points inside ``bounds`` = (xmin, ymin, xmax, ymax),
    half-open) into a Cloud that keeps the LasData in ``cloud.las``; with keep_records False (a
    whole file only) the records are let go after reading and ``cloud.records_file`` names the
    file, from which the writer streams them again (36 B per point of format 7 not held through
    a run)."""
    try:
        check_structure(path)
        with laspy.open(path) as reader:
            header = reader.header
            _check_header(path, header)
            hmins, hmaxs = np.array(header.mins, np.float64), np.array(header.maxs, np.float64)
            if bounds is None:
                if header.point_count > MAX_POINTS:
                    raise _too_many(path, header.point_count)
                las = _read_all(path, reader)
                withheld = int(np.count_nonzero(np.asarray(las.withheld))) if len(las.points) else 0
                if withheld:
                    # LAS marks them "to be treated as deleted"; PDAL keeps them too: said, not dropped
                    warn_once(("withheld", str(path)), "%s: %d of %d points are flagged withheld (LAS: to be "
                              "treated as deleted); they are processed like the others (drop them first if they "
                              "should not be, e.g. pdal translate with filters.range --filters.range.limits="
                              "'Withheld[0:0]')", path, withheld, len(las.points))
            else:
                points = _read_window(path, reader, bounds)
                las = laspy.LasData(copy.deepcopy(header), points)
    except InputError:
        raise
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc
    return _cloud_of(path, las, hmins, hmaxs, origin, whole=bounds is None,
                     keep_records=keep_records or bounds is not None)


def split_las(path, windows, write) -> None:
    """Decode a LAS/LAZ file once and hand each window its points: ``windows`` is a list of
    (key, (xmin, ymin, xmax, ymax)) half-open boxes, ``write(key, records)`` receives, chunk by
    chunk in file order, the raw point records (the file's point-format dtype) inside that box.
    Concatenated, a key's records are exactly the ones ``read_las(path, bounds)`` keeps, so that
    ``read_las_part`` of them gives the same Cloud; a window that meets no chunk gets no call."""
    try:
        check_structure(path)
        with laspy.open(path) as reader:
            _check_header(path, reader.header)
            h = reader.header
            # a tile plan is laid over the header boxes: points beyond the box went to no tile or
            # to a tile that did not expect them (the merge then found tiles disagreeing)
            tol = np.maximum(0.5 * np.asarray(h.scales[:2], np.float64), 0.01)   # bounds rounded by a writer
            box = (h.mins[0] - tol[0], h.mins[1] - tol[1], h.maxs[0] + tol[0], h.maxs[1] + tol[1])
            _split_chunks(path, reader, windows, write, SPLIT_CHUNK_POINTS, header_box=box)
    except InputError:
        raise
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc


def _split_chunks(path, reader, windows, write, chunk_points: int, header_box=None) -> None:
    """The chunk loop of windowed reads and split_las: each window's records, chunk by chunk in
    file order, to ``write(key, records)``; a truncated file is an InputError, and so are points
    beyond ``header_box`` (xmin, ymin, xmax, ymax) when given."""
    seen = 0
    for chunk in reader.chunk_iterator(chunk_points):
        seen += len(chunk)
        x, y = np.asarray(chunk.x), np.asarray(chunk.y)
        if not len(x):
            continue
        lo_x, hi_x, lo_y, hi_y = x.min(), x.max(), y.min(), y.max()
        if header_box is not None and (lo_x < header_box[0] or lo_y < header_box[1] or hi_x > header_box[2]
                                       or hi_y > header_box[3]):
            out = int(np.count_nonzero((x < header_box[0]) | (y < header_box[1]) | (x > header_box[2])
                                       | (y > header_box[3])))
            raise fail(path, f"{out} points (in its first {seen} read) lie outside the header bounds, which the "
                             "tiles are planned on; fix the header (e.g. pdal translate)")
        for key, (xmin, ymin, xmax, ymax) in windows:
            if hi_x < xmin or lo_x >= xmax or hi_y < ymin or lo_y >= ymax:
                continue
            inside = np.flatnonzero((x >= xmin) & (x < xmax) & (y >= ymin) & (y < ymax))
            if len(inside):
                write(key, chunk.array[inside])
    if seen != reader.header.point_count:
        raise fail(path, f"truncated LAS/LAZ file: {seen} of {reader.header.point_count} points could be read")


def record_dtype(path) -> np.dtype:
    """The numpy dtype of a LAS/LAZ file's point records (what split_las hands out)."""
    try:
        with laspy.open(path) as reader:
            return reader.header.point_format.dtype()
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc


def read_las_part(path, records: np.ndarray, origin) -> Cloud:
    """The Cloud of a window's point records as split_las handed them out (``origin``: the shared
    local origin of the windows): the same Cloud read_las(path, bounds, origin) gives."""
    try:
        with laspy.open(path) as reader:
            header = reader.header
            hmins, hmaxs = np.array(header.mins, np.float64), np.array(header.maxs, np.float64)
            if len(records) > MAX_POINTS:
                raise _too_many(path, len(records))
            points = laspy.ScaleAwarePointRecord(records, header.point_format, header.scales, header.offsets)
            las = laspy.LasData(copy.deepcopy(header), points)
    except InputError:
        raise
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc
    return _cloud_of(path, las, hmins, hmaxs, origin, whole=False)


def _cloud_of(path, las, hmins, hmaxs, origin, whole: bool, keep_records: bool = True) -> Cloud:
    world = _world_xyz(las.points)
    _check_magnitude(path, world, las.header.scales)
    if origin is None:
        origin = _local_origin(hmins, hmaxs, las.header.scales, world, whole=whole)
    origin = np.asarray(origin, dtype=np.float64).reshape(3)
    xyz = (world - origin).astype(np.float32)
    del world
    rgb, depth = _las_rgb(las, path)
    # copies, not views of the records, when the records are let go
    column = np.array if not keep_records else np.asarray
    return Cloud(xyz=xyz, origin=origin, rgb=rgb, color_depth=depth,
                 intensity=column(las.intensity, dtype=np.uint16),
                 classification=column(las.classification, dtype=np.uint8),
                 returns=np.column_stack([np.asarray(las.return_number), np.asarray(las.number_of_returns)]
                                         ).astype(np.uint8),
                 nir=column(las.nir, dtype=np.uint16) if "nir" in las.point_format.dimension_names else None,
                 las=las if keep_records else None, records_file="" if keep_records else str(path),
                 source=str(path))


def _las_rgb(las, path="") -> tuple[np.ndarray | None, int]:
    """RGB when the format has colour and it is not all zero (IGN tiles carry zero colour fields)."""
    if "red" not in las.point_format.dimension_names:
        return None, 0
    rgb = np.column_stack([np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)]).astype(np.uint16)
    if not rgb.any():
        return None, 0
    warn_mixed_depth(path, rgb)
    return rgb, detect_color_depth(rgb)


def warn_mixed_depth(path, rgb: np.ndarray) -> None:
    """A warning when ``path``'s colour mixes 8- and 16-bit values (cloud.byte_sized_share)."""
    share = byte_sized_share(rgb)
    if share > MIXED_DEPTH_SHARE:
        warn_once(("mixed depth", str(path)), "%s: %.0f %% of its coloured points have 8-bit colour values beside "
                  "16-bit ones; colour written at two depths (merged deliveries?) misleads the colour cues: "
                  "scale the 8-bit values by 257 (or all to 8 bits) first", path, 100 * share)


# ---------------------------------------------------------------------------------------- writing

def read_header_las(path):
    """(point count, (xmin, ymin, xmax, ymax), (zmin, zmax)) from the header alone."""
    try:
        check_structure(path)
        with laspy.open(path) as reader:
            h = reader.header
            return (int(h.point_count), (float(h.mins[0]), float(h.mins[1]), float(h.maxs[0]), float(h.maxs[1])),
                    (float(h.mins[2]), float(h.maxs[2])))
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc


def iter_xy_las(path):
    """World x, y (float64) chunk by chunk; a truncated file is an InputError."""
    try:
        check_structure(path)
        with laspy.open(path) as reader:
            _check_header(path, reader.header)
            seen = 0
            for chunk in reader.chunk_iterator(CHUNK_POINTS):
                seen += len(chunk)
                yield np.asarray(chunk.x, np.float64), np.asarray(chunk.y, np.float64)
            if seen != reader.header.point_count:
                raise fail(path, f"truncated LAS/LAZ file: {seen} of {reader.header.point_count} points could be read")
    except InputError:
        raise
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc


def crs_records(header) -> tuple[str | None, list[int]]:
    """The CRS records of a header: (the OGC WKT text, or None; the EPSG codes of its GeoTIFF keys:
    projected or geographic first, then vertical, when present)."""
    for vlr in list(header.vlrs) + list(header.evlrs or []):
        wkt = getattr(vlr, "string", None)
        if isinstance(wkt, bytes):
            wkt = wkt.decode("ascii", "replace")
        if isinstance(wkt, str) and wkt.strip(" \0\n"):
            return wkt.strip(" \0\n"), []
    for vlr in header.vlrs:
        keys = {k.id: k for k in getattr(vlr, "geo_keys", [])}
        codes = []
        for key_id in (3072, 2048, 4096):  # ProjectedCSType, GeographicType, VerticalCSType GeoKeys
            key = keys.get(key_id)
            if key is not None and key.tiff_tag_location == 0 and 0 < key.value_offset < 32767:
                if key_id != 2048 or not codes:
                    codes.append(int(key.value_offset))
        if codes:
            return None, codes
    return None, []


def crs_text(header) -> str | None:
    """The CRS as 'NAME (EPSG:n)', 'NAME' or 'EPSG:n' from the WKT or GeoTIFF-keys VLRs (no pyproj)."""
    wkt, codes = crs_records(header)
    if wkt:
        name = re.match(r'\s*\w+\[\s*"([^"]*)"', wkt)
        codes = re.findall(r'(?:AUTHORITY|ID)\[\s*"EPSG"\s*,\s*"?(\d+)"?\s*\]', wkt)
        parts = [name.group(1)] if name else []
        if codes:
            parts.append(f"(EPSG:{codes[-1]})" if parts else f"EPSG:{codes[-1]}")
        return " ".join(parts) or None
    return "+".join(f"EPSG:{c}" for c in codes) or None


def info_las(path) -> dict:
    """Header facts plus, from a chunked pass, the class histogram, exact bounds, point density,
    and the ranges of colour, intensity, NIR and return numbers (io/describe.py)."""
    from .describe import Survey, classes

    try:
        check_structure(path)
        with laspy.open(path) as reader:
            h = reader.header
            problems = []
            try:
                _check_header(path, h)
            except InputError as exc:
                # described all the same (info is where one looks at a broken header), but said
                problems.append(str(exc))
                logging.getLogger("roadx_ti").warning("%s (a run refuses this file)", exc)
            fmt = h.point_format
            dims = set(fmt.dimension_names)
            has_rgb = "red" in dims
            survey = Survey({"intensity", "return_number", "number_of_returns"}
                            | ({"rgb"} if has_rgb else set()) | ({"nir"} if "nir" in dims else set()))
            hist = np.zeros(256, dtype=np.int64)
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            seen = 0
            for chunk in reader.chunk_iterator(CHUNK_POINTS):
                seen += len(chunk)
                hist += np.bincount(np.asarray(chunk.classification, dtype=np.uint8), minlength=256)
                xyz = _world_xyz(chunk)
                lo, hi = np.minimum(lo, column_min(xyz)), np.maximum(hi, column_max(xyz))
                survey.add(xyz[:, :2], {
                    "rgb": np.column_stack([chunk.red, chunk.green, chunk.blue]) if has_rgb else None,
                    "intensity": np.asarray(chunk.intensity), "nir": np.asarray(chunk.nir) if "nir" in dims else None,
                    "return_number": np.asarray(chunk.return_number),
                    "number_of_returns": np.asarray(chunk.number_of_returns)})
            if seen != h.point_count:
                raise fail(path, f"truncated LAS/LAZ file: {seen} of {h.point_count} points could be read")
    except InputError:
        raise
    except LAS_ERRORS as exc:
        raise _las_error(path, exc) from exc
    facts = survey.facts(seen)
    color_max = facts["fields"]["rgb"]["max"] or 0
    if not has_rgb:
        color, depth = "none", None
    elif color_max == 0:
        color, depth = "all-zero", None
    else:
        depth = 16 if color_max > 255 else 8
        color = f"{depth}-bit"
    histogram = {int(c): int(k) for c, k in enumerate(hist) if k}
    return {
        "path": str(path),
        "format": "copc" if is_copc(h) else ("laz" if str(path).lower().endswith(".laz") else "las"),
        "point_count": int(h.point_count),
        "crs": crs_text(h),
        "bounds": {"min": lo.tolist(), "max": hi.tolist()} if seen else None,
        **facts,
        "point_format": int(fmt.id),
        "version": str(h.version),
        "dimensions": list(fmt.dimension_names),
        "extra_dimensions": list(fmt.extra_dimension_names),
        "color": color,
        "color_depth": depth,
        "classes": classes(histogram),
        "class_histogram": histogram,
        "scales": [float(s) for s in h.scales],
        "offsets": [float(o) for o in h.offsets],
        "problems": problems,
    }
