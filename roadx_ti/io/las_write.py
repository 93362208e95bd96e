"""Writing LAS/LAZ (laspy; lazrs encodes LAZ).

A cloud read from LAS is written from its point records: every standard attribute and extra
dimension is copied byte for byte in the input order, the header (version, point format, scales,
offsets, VLRs with the CRS) is kept, and only the classification and the named extra dimensions
change. A cloud from elsewhere becomes LAS 1.4 point format 7 (with colour) or 6, scale 1 mm,
offset = its origin. Outputs are written atomically (roadx_ti.io.atomic).
"""
from __future__ import annotations

import contextlib
import copy
from dataclasses import replace
import logging
from pathlib import Path

import laspy
import numpy as np

from ..cloud import Cloud
from .atomic import InputError, atomic_output, fail
from .las import CHUNK_POINTS, EVLR_HEADER, EXTRA_DIM_TYPES, HEADER_SIZES, MAX_POINTS, NEW_FILE_SCALE, WIDE_CLASS_FORMAT, _too_many, is_copc, \
    warn_once

log = logging.getLogger(__name__)


def point_index(subset, n: int):
    """``subset`` (bool mask or indices) checked against n points; None keeps all."""
    if subset is None:
        return None
    index = np.asarray(subset)
    if index.dtype == bool:
        if index.shape != (n,):
            raise ValueError(f"subset: a mask must hold one value per point ({n}), not shape {index.shape}")
        return index
    if index.ndim != 1 or (index.size and not np.issubdtype(index.dtype, np.integer)):
        raise ValueError(f"subset: give a bool mask or a 1-D array of point indices, not {index.dtype} of shape "
                         f"{index.shape}")
    # numpy's own rule would read -1 as the last point
    if index.size and (index.min() < 0 or index.max() >= n):
        raise ValueError(f"subset: point indices must lie in [0, {n}), not {int(index.min())}..{int(index.max())}")
    return index.astype(np.int64, copy=False)


def per_point(name: str, values, n: int, index) -> np.ndarray:
    a = np.asarray(values)
    if a.ndim != 1 or len(a) != n:
        raise ValueError(f"{name} has shape {a.shape}, expected ({n},)")
    return a if index is None else a[index]


def _classes(path, values: np.ndarray) -> np.ndarray:
    if values.size and not np.issubdtype(values.dtype, np.integer):
        raise fail(path, f"classification must be integers 0-255, got {values.dtype}")
    if values.size and (int(values.min()) < 0 or int(values.max()) > 255):
        raise fail(path, f"classification values {int(values.min())}..{int(values.max())} "
                         "are outside the LAS range 0-255")
    return values.astype(np.uint8)


def _extra_dim_values(path, name: str, values: np.ndarray) -> np.ndarray:
    if values.dtype == bool:
        values = values.astype(np.uint8)
    if values.dtype.newbyteorder("=") not in EXTRA_DIM_TYPES:
        raise fail(path, f"extra dimension {name!r} has type {values.dtype}; LAS extra bytes hold "
                         "8-64 bit integers and 32/64 bit floats")
    if not name or len(name.encode()) > 32:
        raise fail(path, f"extra dimension name {name!r} must be 1-32 bytes long")
    return values.astype(values.dtype.newbyteorder("="), copy=False)


def _set_extra_dims(path, header, array: np.ndarray, extra: dict) -> laspy.ScaleAwarePointRecord:
    """A record with ``header``'s format plus ``extra`` dims (same-named extra dims replaced in
    place when the type matches, else re-declared); existing fields are copied as raw bytes."""
    fmt = header.point_format
    existing = {d.name: d for d in fmt.extra_dimensions}
    standard = set(fmt.standard_dimension_names) | {"x", "y", "z"}
    replace, add = [], []
    for name, values in extra.items():
        if name in standard:
            raise fail(path, f"extra dimension {name!r} clashes with the standard LAS dimension of "
                             "that name; pass the classification through classification=")
        old = existing.get(name)
        if old is not None:
            # an earlier run's labels, or another tool's dimension of that name: said, not silent
            was = f"{array.dtype[name].base}{list(array.dtype[name].shape) or ''}" + (
                " scaled" if old.scales is not None or old.offsets is not None else "")
            warn_once(("replaced", str(path), name), "writing %s: the input's extra dimension %r (%s) is replaced by this "
                      "run's (%s)", path, name, was, values.dtype)
        if old is not None and (array.dtype[name].base != values.dtype or array.dtype[name].shape
                                or old.scales is not None or old.offsets is not None):
            replace.append(name)
        if old is None or name in replace:
            add.append(laspy.ExtraBytesParams(name=name, type=values.dtype))
    declared = _declared_no_data(header)
    if replace:
        header.remove_extra_dims(replace)
    if add:
        header.add_extra_dims(add)
    if declared and add:
        # laspy (2.7) reads an extra dimension's no-data value but forgets it when it rebuilds the
        # Extra Bytes record for the added dimensions: a sentinel (-9999) became a plain value
        fmt = header.point_format
        fmt.dimensions[:] = [d._replace(no_data=declared[d.name]) if not d.is_standard and d.name in declared
                             and d.name not in replace else d for d in fmt.dimensions]
        header._sync_extra_bytes_vlr()
    record = laspy.ScaleAwarePointRecord.zeros(len(array), header=header)
    fields, new_fields = array.dtype.fields, record.array.dtype.fields
    if not replace and array.flags.c_contiguous and all(new_fields[f][1] == fields[f][1] for f in fields):
        # the added dims follow the old ones: the old records as one block of bytes (a copy field
        # by field is ~0.2 s per 4 M points)
        rows = record.array.view(np.uint8).reshape(len(array), record.array.dtype.itemsize)
        rows[:, :array.dtype.itemsize] = array.view(np.uint8).reshape(len(array), array.dtype.itemsize)
    else:
        for name in array.dtype.names:
            if name not in replace:
                record.array[name] = array[name]
    for name, values in extra.items():
        record.array[name] = values
    return record


def _declared_no_data(header) -> dict:
    """name: no-data value of each extra dimension whose Extra Bytes record declares one."""
    found = header.vlrs.get("ExtraBytesVlr")
    if not found:
        return {}
    return {s.format_name(): s.no_data for s in found[0].extra_bytes_structs if s.no_data is not None}


def _plain_header(header) -> laspy.LasHeader:
    """A copy of a read header to write with: without a COPC file's octree records (an output is a
    plain LAS/LAZ in a new point order; laspy does not write COPC)."""
    header = copy.deepcopy(header)
    if is_copc(header):
        header.vlrs = laspy.vlrs.vlrlist.VLRList([v for v in header.vlrs if v.user_id != "copc"])
        if header.evlrs is not None:
            header.evlrs = laspy.vlrs.vlrlist.VLRList([v for v in header.evlrs if v.user_id != "copc"])
    return header


def _las_from_record(path, src, n: int, classification, extra_dims, index) -> laspy.LasData:
    if len(src.points) != n:
        raise ValueError(f"cloud has {n} points but its LAS record has {len(src.points)}")
    header = _plain_header(src.header)
    array = src.points.array if index is None else src.points.array[index]
    classes = None if classification is None else _classes(path, per_point("classification", classification, n, index))
    fmt_id = header.point_format.id
    if classes is not None and fmt_id in WIDE_CLASS_FORMAT and classes.size and int(classes.max()) > 31:
        wide = WIDE_CLASS_FORMAT[fmt_id]
        warn_once(("class", str(path)), "%s: class %d does not fit LAS point format %d (classes 0-31); "
                   "writing LAS 1.4 point format %d instead", path, int(classes.max()), fmt_id, wide)
        upgraded = laspy.convert(laspy.LasData(header, laspy.ScaleAwarePointRecord(
            array.copy(), header.point_format, header.scales, header.offsets)),
            point_format_id=wide, file_version="1.4")
        header, array = upgraded.header, upgraded.points.array
    version = f"{header.version.major}.{header.version.minor}"
    fmt_id = header.point_format.id
    if fmt_id not in laspy.point.dims.VERSION_TO_POINT_FMT.get(version, ()):
        # laspy reads LAS 1.0 and odd version / format pairs but writes neither
        target = laspy.point.dims.preferred_file_version_for_point_format(fmt_id)
        warn_once(("version", str(path)), "%s: LAS %s with point format %d cannot be written; writing LAS %s "
                   "(the point records are the same)", path, version, fmt_id, target)
        upgraded = laspy.convert(laspy.LasData(header, laspy.ScaleAwarePointRecord(
            array.copy(), header.point_format, header.scales, header.offsets)),
            point_format_id=fmt_id, file_version=target)
        header, array = upgraded.header, upgraded.points.array
    extra = {name: _extra_dim_values(path, name, per_point(name, v, n, index))
             for name, v in (extra_dims or {}).items()}
    if extra:
        record = _set_extra_dims(path, header, array, extra)
    else:
        record = laspy.ScaleAwarePointRecord(array.copy(), header.point_format, header.scales, header.offsets)
    if classes is not None:
        record["classification"] = classes   # legacy formats: only the 5 class bits change
    return laspy.LasData(header, record)


def _example(a: np.ndarray) -> str:
    """A value of a column for a message (its largest, or the first if not numeric)."""
    a = np.asarray(a)
    if not a.size:
        return "none"
    return f"{np.nanmax(a):g}" if a.dtype.kind in "iuf" else repr(str(a[0]))


def fits_new_file(local: np.ndarray) -> bool:
    """Whether local coordinates (m from the origin) fit a new LAS file's int32 at NEW_FILE_SCALE."""
    return not local.size or float(np.abs(local).max()) / NEW_FILE_SCALE <= 2**31 - 1.5


# column names (lower case, without underscores) that are the LAS returns fields (io.other reads
# PDAL writers.text's ReturnNumber / NumberOfReturns as the returns)
RETURN_FIELDS = {"returnnumber": "return_number", "numberofreturns": "number_of_returns"}


def return_field(name: str) -> str | None:
    """The LAS returns field a column name stands for ('ReturnNumber', 'return_number', ...), or None."""
    return RETURN_FIELDS.get(name.lower().replace("_", ""))


def las_from_arrays(path, cloud: Cloud, classification, extra_dims, index) -> laspy.LasData:
    n = cloud.n
    has_rgb = cloud.rgb is not None
    # NIR (a PLY / PCD / NPZ / text column read as such) goes to point format 8 beside colour, or
    # to an extra dimension 'nir' without it (format 8 holds RGB too): it was dropped silently
    nir_field = cloud.nir is not None and has_rgb
    header = laspy.LasHeader(point_format=8 if nir_field else 7 if has_rgb else 6, version="1.4")
    header.scales = np.full(3, NEW_FILE_SCALE)
    header.offsets = cloud.origin.copy()
    standard = set(header.point_format.standard_dimension_names)
    columns = dict(cloud.attributes)
    if cloud.nir is not None and not nir_field and "nir" not in columns:
        columns["nir"] = np.asarray(cloud.nir, np.uint16)
    columns.update(extra_dims or {})
    standard_cols, extra = {}, {}
    taken = {"X", "Y", "Z", "x", "y", "z"} | ({"red", "green", "blue"} if has_rgb else set())
    taken |= {"intensity"} if cloud.intensity is not None else set()
    taken |= {"nir"} if nir_field else set()
    taken |= {"classification"} if classification is not None or cloud.classification is not None else set()
    for name, values in columns.items():
        a = per_point(name, values, n, index)
        if name in taken:
            # a column read under a standard name whose values that field cannot hold (classes of 300)
            raise fail(path, f"column {name!r} holds values the LAS {name} field cannot (e.g. {_example(a)}); "
                             "it would also hide the result's own; fix its values or rename it")
        alias = return_field(name)
        if name in standard:
            standard_cols[name] = a
        elif alias in standard and alias not in columns:
            standard_cols[alias] = a      # PDAL's ReturnNumber / NumberOfReturns: the LAS fields
        else:
            extra[name] = _extra_dim_values(path, name, a)
    local = cloud.xyz.astype(np.float64) if index is None else cloud.xyz[index].astype(np.float64)
    ints = np.round(local / NEW_FILE_SCALE)
    if not fits_new_file(local):
        raise fail(path, "coordinates span more than +-2147 km from the origin at 1 mm scale; "
                         "split the cloud or move its origin")
    record = _set_extra_dims(path, header, np.zeros(len(local), dtype=header.point_format.dtype()), extra)
    record.array["X"], record.array["Y"], record.array["Z"] = (ints[:, k].astype(np.int32) for k in range(3))
    if has_rgb:
        rgb = cloud.rgb if index is None else cloud.rgb[index]
        rgb = rgb.astype(np.uint16) * np.uint16(257) if cloud.color_depth == 8 else rgb.astype(np.uint16)
        record["red"], record["green"], record["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    if cloud.intensity is not None:
        record["intensity"] = per_point("intensity", cloud.intensity, n, index).astype(np.uint16)
    if nir_field:
        record["nir"] = per_point("nir", cloud.nir, n, index).astype(np.uint16)
    classes = classification if classification is not None else cloud.classification
    if classes is not None:
        record["classification"] = _classes(path, per_point("classification", classes, n, index))
    for name, a in standard_cols.items():
        target = record[name]
        cast = a.astype(np.asarray(target).dtype)
        if not np.array_equal(cast, a):
            raise fail(path, f"attribute {name!r} does not fit the LAS {name} field ({np.asarray(target).dtype})")
        record[name] = cast
    return laspy.LasData(header, record)


WAVE_PACKET_FIELDS = ("wavepacket_offset", "wavepacket_size", "return_point_wave_location", "x_t", "y_t", "z_t")


def check_laz_wave_packets(path, las: laspy.LasData, state: dict) -> None:
    """InputError when a LAZ ``path`` would get point format 9 / 10 records with wave packet fields
    from more than one scanner channel: lazrs 0.8 decodes them wrong (a write and read of such a
    file alone changes 99.9 % of their offsets and x_t / y_t / z_t). ``state`` carries the channels
    and whether packets were seen over the chunks of one output."""
    if not str(path).lower().endswith(".laz") or las.header.point_format.id not in (9, 10) or not len(las.points):
        return
    state.setdefault("channels", set()).update(np.unique(np.asarray(las.scanner_channel)).tolist())
    state["packets"] = state.get("packets", False) or any(np.any(np.asarray(las[f])) for f in WAVE_PACKET_FIELDS)
    if state["packets"] and len(state["channels"]) > 1:
        raise InputError(f"{path}: LAZ cannot keep these points' wave packet fields (point format "
                         f"{las.header.point_format.id}, {len(state['channels'])} scanner channels: lazrs compresses "
                         "them wrongly); write .las instead")


def check_writable_records_of(path, source, state: dict | None = None) -> None:
    """Before a run (untiled, and tiled for each input): InputError when the LAS/LAZ ``source``'s
    records cannot be written back to the LAS/LAZ ``path`` (more than 3 undocumented extra bytes
    per point: laspy declares them as one undocumented field it cannot read back, and the write
    failed after the whole pipeline), then check_laz_wave_packets_of (``state``: see there)."""
    if not str(path).lower().endswith((".las", ".laz")) or not str(source).lower().endswith((".las", ".laz")):
        return
    with laspy.open(source) as reader:
        undocumented = [d for d in reader.header.point_format.extra_dimensions if d.name == "ExtraBytes"]
    if undocumented and undocumented[0].num_elements > 3:
        raise InputError(f"{source}: its point records carry {undocumented[0].num_elements} undocumented extra bytes "
                         "(no Extra Bytes record describes them), which a LAS/LAZ output cannot carry back "
                         "readably; describe them (an Extra Bytes VLR) or drop them first (e.g. pdal translate), "
                         "or write .ply / .npz")
    check_laz_wave_packets_of(path, source, state)


def check_laz_wave_packets_of(path, source, state: dict | None = None) -> None:
    """check_laz_wave_packets over the records of the LAS/LAZ file ``source`` (decoded only when it
    holds point format 9 or 10 and ``path`` is LAZ): before a run, not after its pipeline.
    ``state``: shared over the files that go into one output (a catalog merged)."""
    if not str(path).lower().endswith(".laz") or not str(source).lower().endswith((".las", ".laz")):
        return
    with laspy.open(source) as reader:
        if reader.header.point_format.id not in (9, 10):
            return
        state = {} if state is None else state
        for chunk in reader.chunk_iterator(CHUNK_POINTS):
            check_laz_wave_packets(path, laspy.LasData(reader.header, chunk), state)


def write_las(path, cloud: Cloud, *, classification=None, extra_dims=None, subset=None) -> None:
    """Write ``cloud`` to LAS, LAZ when ``path`` ends with .laz, COPC when it ends with
    .copc.laz (io/copc.py), atomically."""
    index = point_index(subset, cloud.n)
    from . import copc
    if cloud.las is None and cloud.records_file:
        if not copc.is_copc_path(path):
            _write_from_records_file(path, cloud, classification, extra_dims, index)
            return
        cloud = replace(cloud, las=_records_of(cloud))     # COPC orders its points itself: all in memory
    if cloud.las is not None:
        las = _las_from_record(path, cloud.las, cloud.n, classification, extra_dims, index)
    else:
        las = las_from_arrays(path, cloud, classification, extra_dims, index)
    if len(las.points) > MAX_POINTS:
        raise _too_many(path, len(las.points))
    if copc.is_copc_path(path):
        copc.write(path, las)
        return
    check_laz_wave_packets(path, las, {})
    compress = str(path).lower().endswith(".laz")
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            las.write(f, do_compress=compress)
        if cloud.las is not None and cloud.source:
            keep_waveform_record(path, tmp, waveform_sources([cloud.source]))
        check_written(path, tmp, cloud.source)


def _records_of(cloud: Cloud) -> laspy.LasData:
    """The point records of ``cloud.records_file``, read whole, checked against the cloud."""
    from .las import read_las
    las = read_las(cloud.records_file).las
    if len(las.points) != cloud.n:
        raise InputError(f"{cloud.records_file}: holds {len(las.points)} points, {cloud.n} when it was read; "
                         "it changed during the run")
    return las


def _write_from_records_file(path, cloud: Cloud, classification, extra_dims, index) -> None:
    """``write_las`` of a cloud whose records stay in ``cloud.records_file``: its records streamed
    from there chunk by chunk, bit for bit but the classification and ``extra_dims`` (the points
    of a subset in file order)."""
    n = cloud.n
    if not Path(cloud.records_file).is_file():
        raise InputError(f"{cloud.records_file}: the input is gone (moved or removed during the run); the output's "
                         "point records are written from it, so nothing was written")
    mask = None
    if index is not None:
        mask = index if index.dtype == bool else np.zeros(n, bool)
        if index.dtype != bool:
            mask[index] = True
    extra = {name: np.asarray(values) for name, values in (extra_dims or {}).items()}
    classes = None if classification is None else np.asarray(classification)
    position = [0]

    def labels(_, chunk):
        start, end = position[0], position[0] + len(chunk)
        position[0] = end
        if end > n:
            raise InputError(f"{cloud.records_file}: holds more than the {n} points read from it; it changed "
                             "during the run")
        return (None if classes is None else classes[start:end], {k: v[start:end] for k, v in extra.items()},
                None if mask is None else np.flatnonzero(mask[start:end]))

    def read_whole(_, seen):
        if seen != n:
            raise InputError(f"{cloud.records_file}: holds {seen} points, {n} when it was read; it changed "
                             "during the run")

    empty = (None if classes is None else classes[:0], {k: v[:0] for k, v in extra.items()}, None)
    write_las_stream(path, [cloud.records_file], labels, empty=empty, on_file=read_whole)


WAVEFORM_INTERNAL = 0x2     # global encoding bit 1: the waveform data packets are inside the file
WAVEFORM_POINTER = 227      # header byte of the start of the waveform data packet record (LAS 1.3+)


def keep_waveform_record(path, tmp, holders: list) -> None:
    """The written ``tmp``'s pointer to its waveform data packet record, which the header copied
    from the input pointed into the input's layout (inside the output's point records once the
    result dimensions widened them): LAS 1.4 points to the output's own waveform EVLR; LAS 1.3
    (laspy leaves the record behind) gets the input's record copied after its points. Several
    inputs with packets of their own cannot share one record: the bit and pointer are cleared,
    with a warning (the points' wave packet fields are kept as read). ``holders``: the inputs'
    waveform_sources."""
    import struct

    with open(tmp, "rb") as f:
        head = f.read(HEADER_SIZES[4])
    if len(head) < HEADER_SIZES[3] or head[25] < 3:
        return
    encoding = struct.unpack_from("<H", head, 6)[0]
    pointer = struct.unpack_from("<Q", head, WAVEFORM_POINTER)[0]
    if not encoding & WAVEFORM_INTERNAL and pointer == 0:
        return
    where = 0
    if not encoding & WAVEFORM_INTERNAL:
        pass                         # external or no packets: a stale pointer is cleared below
    elif len(holders) > 1:
        warn_once(("waveform", str(path)), "writing %s: %d of its inputs each point into a waveform record of their "
                  "own, which one file cannot hold; the output has none (the wave packet fields are kept as read)",
                  path, len(holders))
    elif head[25] >= 4:
        where = _waveform_evlr(tmp, head)
    elif holders:
        where = _append_waveform_record(tmp, holders[0])
    if not where and encoding & WAVEFORM_INTERNAL and len(holders) <= 1:
        warn_once(("waveform", str(path)), "writing %s: the input's waveform data packet record could not be found; "
                  "the output says it has none (the wave packet fields are kept as read)", path)
    with open(tmp, "r+b") as f:
        f.seek(6)
        f.write(struct.pack("<H", encoding if where else encoding & ~WAVEFORM_INTERNAL))
        f.seek(WAVEFORM_POINTER)
        f.write(struct.pack("<Q", where))


def waveform_sources(sources) -> list:
    """The distinct LAS sources whose header says their waveform data packets are inside them."""
    import struct

    out = []
    for source in dict.fromkeys(str(s) for s in sources):
        with contextlib.suppress(OSError), open(source, "rb") as f:
            head = f.read(8)
            if len(head) == 8 and head[:4] == b"LASF" and struct.unpack_from("<H", head, 6)[0] & WAVEFORM_INTERNAL:
                out.append(source)
    return out


def _waveform_evlr(tmp, head: bytes) -> int:
    """Byte offset of the waveform data packet EVLR (LASF_Spec, 65535) of a written LAS 1.4 file, or 0."""
    import os
    import struct

    start, count = struct.unpack_from("<QI", head, HEADER_SIZES[3])   # the EVLRs' start and count follow the 1.3 header
    size = os.path.getsize(tmp)
    with open(tmp, "rb") as f:
        at = start
        for _ in range(count):
            f.seek(at)
            raw = f.read(EVLR_HEADER)
            if len(raw) < EVLR_HEADER:
                return 0
            user, record, length = raw[2:18].rstrip(b"\0"), *struct.unpack_from("<HQ", raw, 18)
            if user == b"LASF_Spec" and record == 65535:
                return at
            at += EVLR_HEADER + length
            if at > size:
                return 0
    return 0


def _append_waveform_record(tmp, source) -> int:
    """The LAS 1.3 ``source``'s waveform data packet record appended to ``tmp``: where it starts, or 0."""
    import os
    import struct

    try:
        size = os.path.getsize(source)
        with open(source, "rb") as f:
            head = f.read(HEADER_SIZES[3])
            if len(head) < HEADER_SIZES[3] or not struct.unpack_from("<H", head, 6)[0] & WAVEFORM_INTERNAL:
                return 0
            start = struct.unpack_from("<Q", head, WAVEFORM_POINTER)[0]
            if not 0 < start <= size - EVLR_HEADER:
                return 0
            f.seek(start)
            record = f.read(EVLR_HEADER)
            length = struct.unpack_from("<Q", record, 20)[0]
            if start + EVLR_HEADER + length > size:
                return 0
            record += f.read(length)
    except OSError:
        return 0
    with open(tmp, "ab") as out:
        where = out.tell()
        out.write(record)
    return where


def check_written(path, tmp, source="") -> None:
    """The written temporary file parses as LAS/LAZ (header, VLRs, point format), or the write
    fails in one line and the output is not replaced: laspy writes some headers it cannot read
    back (an undeclared extra-bytes field of more than 3 elements, from an input whose extra-bytes
    VLR does not describe its records)."""
    try:
        with laspy.open(tmp) as reader:
            reader.header.point_format.dtype()
    except Exception as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise fail(path, f"the point records{f' of {source}' if source else ''} cannot be written back as a "
                         f"readable LAS/LAZ file ({text}); check its header (point format, record length, "
                         "extra-bytes VLR), e.g. with pdal info --metadata") from None


# ------------------------------------------------------------------------------- header look-ups

def template_source(sources):
    """The source whose header a merged LAS/LAZ output takes: the first that holds points (an empty
    tile's default header, scales 0.001 and offsets 0, put every other file's coordinates beyond
    int32) and a CRS record, when one does (a catalog takes the CRS of its files that state one for
    those that do not: a first file without one left the merged output without any), else the
    first that holds points, else the first."""
    from .las import crs_records

    with_points = []
    for source in sources:
        with laspy.open(source) as reader:
            if reader.header.point_count:
                if any(crs_records(reader.header)):
                    return source
                with_points.append(source)
    return with_points[0] if with_points else sources[0]


def fits_records(low: float, high: float, scale: float, offset: float) -> bool:
    """Whether coordinates from ``low`` to ``high`` are 32-bit integer records at ``scale`` and
    ``offset`` (laspy's rescaling clips the others: every point of a file 300 km off sat on one x)."""
    steps = ((low - offset) / scale, (high - offset) / scale)
    return min(steps) >= -2**31 and max(steps) <= 2**31 - 1


def _check_fits(source, template, las, header) -> None:
    """InputError when the chunk's coordinates fall beyond the records of the output's scales and
    offsets (fits_records); a chunk on the output's own grid is copied as it is and always fits."""
    if not len(las.points) or (np.array_equal(las.header.scales, header.scales)
                               and np.array_equal(las.header.offsets, header.offsets)):
        return
    for axis, name in enumerate("xyz"):
        values = np.asarray(las[name], np.float64)
        if not fits_records(values.min(), values.max(), header.scales[axis], header.offsets[axis]):
            raise InputError(f"{source}: its {name} coordinates ({values.min():.3f} .. {values.max():.3f}) lie beyond "
                             f"what a LAS file with {Path(template).name}'s scale {header.scales[axis]:g} and offset "
                             f"{header.offsets[axis]:g} can hold (32-bit integers); use output.mode per-file, or "
                             "give the files one offset near their points (e.g. pdal translate)")


def write_las_stream(path, sources, labels, *, empty, chunk_points: int = CHUNK_POINTS, on_file=None,
                     mismatch_hint: str = "") -> int:
    """Stream the point records of the LAS/LAZ files ``sources`` (in order, ``chunk_points`` at a
    time) into one LAS/LAZ ``path`` (LAZ when it ends with .laz), written atomically: every record
    bit for bit as read but its classification and the extra dimensions ``labels`` gives; the
    header is the first source's with points (template_source) with those dimensions. Returns the number of points written.

    ``labels(i, chunk)`` -> (classification, extra_dims, subset) of a chunk (laspy point record) of
    ``sources[i]``, called in file order; subset None keeps every point of the chunk. ``empty`` is
    that triple for no points (the dtypes of its arrays shape the header). ``on_file(i, seen)`` is
    called when ``sources[i]`` has been read, with its number of points. A source whose point format
    cannot join the first's raises InputError (ending with ``mismatch_hint``)."""
    written = 0
    packets = {}
    template = template_source(sources)
    holders = waveform_sources(sources)       # the inputs with waveform records of their own
    with atomic_output(path) as tmp:
        writer = None
        try:
            with laspy.open(template) as reader:    # the template's header, with the result dimensions
                header = copy.deepcopy(reader.header)
            none = laspy.ScaleAwarePointRecord.zeros(0, header=header)
            first = _las_from_record(path, laspy.LasData(header, none), 0, *empty)
            writer = laspy.open(tmp, mode="w", header=first.header, do_compress=Path(path).suffix.lower() == ".laz")
            for i, source in enumerate(sources):
                seen = 0
                with laspy.open(source) as reader:
                    header = copy.deepcopy(reader.header)
                    for chunk in reader.chunk_iterator(chunk_points):
                        seen += len(chunk)
                        las = _las_from_record(path, laspy.LasData(header, chunk), len(chunk), *labels(i, chunk))
                        _check_fits(source, template, las, writer.header)
                        check_laz_wave_packets(path, las, packets)
                        try:
                            writer.write_points(las.points)
                        except laspy.errors.LaspyException as exc:
                            raise InputError(f"{source}: cannot be merged with {template} ({exc}: point "
                                             f"formats differ){mismatch_hint}") from None
                        written += len(las.points)
                if on_file is not None:
                    on_file(i, seen)
            evlrs = first.header.evlrs
            if evlrs and len(holders) > 1:
                # several files' waveform records: none is the merged points' (keep_waveform_record says so)
                evlrs = laspy.vlrs.vlrlist.VLRList([v for v in evlrs if not (v.user_id == "LASF_Spec"
                                                                             and v.record_id == 65535)])
            if evlrs and writer.header.version.minor >= 4:
                # the first file's extended VLRs (a WKT CRS, PDAL's metadata, waveform descriptions)
                # after the points, as LasData.write puts them; laspy's writer leaves them out
                writer.write_evlrs(evlrs)
        finally:
            if writer is not None:
                writer.close()
        keep_waveform_record(path, tmp, holders)
        check_written(path, tmp)
    return written
