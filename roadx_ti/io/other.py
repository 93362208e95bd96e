"""PLY, PCD, NPZ and XYZ text: readers return a Cloud, writers take the Cloud and the same
classification / extra_dims / subset as the LAS writer (written as columns or properties).

- PLY: numpy reader/writer for ascii and binary vertex data with every PLY scalar type (Open3D's PLY
  reader skips char/short/uint properties, so it would drop attributes silently). x y z are written
  as double world coordinates; colour as uchar (8-bit) or ushort (16-bit); float colour 0..1 is
  read as 8-bit 0..255.
- PCD: Open3D, imported inside the functions so LAS users do not pay its import; PCD colour is 8-bit.
- NPZ: ``xyz`` (float32, local) + ``origin`` (float64) + rgb, color_depth, intensity, classification and
  one array per attribute, so a Cloud round-trips bit for bit; an ``xyz`` without ``origin`` is taken
  as world coordinates.
- Text (.xyz .txt .csv): whitespace, comma or semicolon separated X Y Z [R G B [I]] (X Y Z I with 4 columns),
  '#' or '//' comments; a header naming the columns (a last comment line or a first non-numeric
  line, as our writer, CloudCompare and PDAL write them) maps named columns.
"""
from __future__ import annotations

import contextlib
import logging
import os
import re
from pathlib import Path

import numpy as np

from ..cloud import Cloud, detect_color_depth, stored_8bit_scale
from .atomic import InputError, atomic_output, fail
from .las_write import per_point, point_index, return_field

log = logging.getLogger(__name__)

INTENSITY_NAMES = ("intensity", "scalar_intensity", "i")
CLASS_NAMES = ("classification", "scalar_classification", "class")
NIR_NAMES = ("nir", "near_infrared", "scalar_nir")
ORIGIN_REACH = 2.0**16    # m: a PLY's stored origin farther than this from a point is not its points'
                          # (float32 offsets from it would step by 4 mm and more)
TEXT_ENCODING = "utf-8-sig"     # UTF-8, with or without the byte-order mark spreadsheets write
RGB_NAMES = (("red", "green", "blue"), ("r", "g", "b"), ("diffuse_red", "diffuse_green", "diffuse_blue"))


# ------------------------------------------------------------------------------ shared helpers

def world_cloud(path, world: np.ndarray, origin, columns: dict) -> Cloud:
    """A Cloud from float64 world xyz and named per-point columns: colour, intensity,
    classification and NIR are recognised by name (case-insensitive), the rest become attributes."""
    world = np.asarray(world, dtype=np.float64)
    bad = int(np.count_nonzero(~np.isfinite(world).all(axis=1))) if len(world) else 0
    if bad:
        raise fail(path, f"{bad} of {len(world)} points have NaN or infinite coordinates")
    lower = {k.lower(): k for k in columns}
    taken = set()
    rgb = depth = None
    for names in RGB_NAMES:
        if all(n in lower for n in names):
            keys = [lower[n] for n in names]
            rgb, depth = _colour(path, np.column_stack([columns[k] for k in keys]))
            taken.update(keys)
            break
    intensity = _take_integral(columns, lower, INTENSITY_NAMES, np.uint16, taken)
    classification = _take_integral(columns, lower, CLASS_NAMES, np.uint8, taken)
    nir = _take_integral(columns, lower, NIR_NAMES, np.uint16, taken)
    attributes = {k: np.asarray(v) for k, v in columns.items() if k not in taken}
    kw = dict(rgb=rgb, color_depth=depth or 0, intensity=intensity, classification=classification, nir=nir,
              returns=_returns(path, attributes), attributes=attributes, source=str(path))
    return Cloud.from_world(world, origin=origin, **kw)


def _colour(path, rgb: np.ndarray) -> tuple[np.ndarray, int]:
    values = np.asarray(rgb, np.float64)
    if values.size and (np.nanmin(values) < 0 or np.nanmax(values) > 65535):
        # colour outside what 16 bits hold is not colour (a column of other values under a colour
        # name); clamping it would pass off made-up colours as the file's
        raise fail(path, f"colour values must be 0-65535 (8- or 16-bit) or 0-1, got {np.nanmin(values):g} to "
                         f"{np.nanmax(values):g}")
    if rgb.dtype.kind == "f":
        missing = int(np.count_nonzero(np.isnan(rgb).any(axis=-1))) if rgb.size else 0
        if missing:     # read as black (0), which a warning says
            log.warning("%s: %d points have no colour value (NaN); they are taken as black", path, missing)
        scale = 255.0 if rgb.size and float(np.nanmax(rgb)) <= 1.0 else 1.0
        rgb = np.clip(np.round(np.nan_to_num(rgb) * scale), 0, 65535)
    rgb = rgb.astype(np.uint16)
    from .las import warn_mixed_depth
    warn_mixed_depth(path, rgb)
    return rgb, detect_color_depth(rgb)


def _take_integral(columns, lower, names, dtype, taken):
    """The first column named as one of ``names`` when it holds integers that fit ``dtype``."""
    for name in names:
        key = lower.get(name)
        if key is None:
            continue
        a = np.asarray(columns[key])
        info = np.iinfo(dtype)
        if a.dtype.kind in "iub" or (a.dtype.kind == "f" and np.all(np.isfinite(a)) and np.all(a == np.round(a))):
            if a.size == 0 or (a.min() >= info.min and a.max() <= info.max):
                taken.add(key)
                return a.astype(dtype)
        return None  # present but not integral: left as an attribute
    return None


# LAS fields written above as the cloud's own columns (or coordinates)
LAS_COLUMNS_HELD = {"X", "Y", "Z", "red", "green", "blue", "intensity", "classification", "return_number",
                    "number_of_returns", "nir"}


def writable_columns(cloud: Cloud, classification, extra_dims, subset):
    """World xyz and ordered per-point columns to write (after ``subset``)."""
    n = cloud.n
    index = point_index(subset, n)
    pick = (lambda a: a) if index is None else (lambda a: a[index])
    world = pick(cloud.world_xyz())
    cols: dict[str, np.ndarray] = {}
    if cloud.rgb is not None:
        rgb = pick(cloud.rgb)
        for k, name in enumerate(("red", "green", "blue")):
            cols[name] = rgb[:, k].astype(np.uint8 if cloud.color_depth == 8 else np.uint16)
    if cloud.intensity is not None:
        cols["intensity"] = pick(np.asarray(cloud.intensity, dtype=np.uint16))
    classes = classification if classification is not None else cloud.classification
    if classes is not None:
        classes = per_point("classification", classes, n, index)
        if classes.size and (classes.min() < 0 or classes.max() > 255):
            raise ValueError("classification values must be 0-255")
        cols["classification"] = classes.astype(np.uint8)
    own_columns = {k.lower() for k in cloud.attributes}
    if cloud.returns is not None and not any(return_field(k) for k in cloud.attributes):   # (ReturnNumber: _returns)
        returns = pick(cloud.returns)
        cols["return_number"], cols["number_of_returns"] = returns[:, 0].copy(), returns[:, 1].copy()
    if cloud.nir is not None and "nir" not in own_columns:
        cols["nir"] = pick(np.asarray(cloud.nir, np.uint16))
    extras = dict(cloud.attributes)
    if cloud.las is not None:
        # the LAS fields the columns above do not hold (GPS time, scan angle, flags, user data,
        # point source, wave packets), as PDAL's writers carry every dimension
        for name in cloud.las.point_format.standard_dimension_names:
            if name not in LAS_COLUMNS_HELD and name not in cols:
                a = np.asarray(cloud.las[name])
                cols[name] = pick(a.astype(np.uint8) if a.dtype == bool else a)
        for name in cloud.las.point_format.extra_dimension_names:
            a = np.asarray(cloud.las[name])
            if a.ndim == 2:
                extras.update({f"{name}_{k}": a[:, k] for k in range(a.shape[1])})
            else:
                extras[name] = a
    extras.update(extra_dims or {})
    for name, values in extras.items():
        if name.lower() in {"x", "y", "z"} | {c.lower() for c in cols}:
            raise ValueError(f"extra column {name!r} would hide the cloud's own {name}; rename it")
        a = per_point(name, values, n, index)
        cols[name] = a.astype(np.uint8) if a.dtype == bool else a
    return world, cols


def _returns(path, attributes: dict) -> np.ndarray | None:
    """(n, 2) uint8 return number / number of returns from columns of those names, with or without
    underscores in any case (PDAL's writers.text names them ReturnNumber, NumberOfReturns; they
    stay attributes too, written back as they came), else None."""
    field = {return_field(k): k for k in attributes}
    if "return_number" not in field or "number_of_returns" not in field:
        return None
    pair = np.column_stack([np.asarray(attributes[field["return_number"]]),
                            np.asarray(attributes[field["number_of_returns"]])])
    if pair.size and (np.nanmin(pair) < 0 or np.nanmax(pair) > 255 or not np.array_equal(pair, np.round(pair))):
        # 300 or -1 were clipped to 255 / 0 silently; the columns stay attributes as they came
        log.warning("%s: return_number / number_of_returns hold values that are no return counts (whole numbers "
                    "0-255, e.g. %g); the returns are not used as a cue", path, pair[(pair < 0) | (pair > 255)
                    | (pair != np.round(pair))].flat[0] if pair.size else 0)
        return None
    return pair.astype(np.uint8)


def _coord_decimals(cloud: Cloud) -> int:
    """Decimals that keep the LAS scale exact, else micrometres."""
    if cloud.las is not None:
        return int(max(0, min(9, np.ceil(-np.log10(float(np.min(cloud.las.header.scales))) - 1e-9))))
    return 6


# ------------------------------------------------------------------------------------------ PLY

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
             "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
             "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
PLY_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint",
             "f4": "float", "f8": "double"}


def _unique_names(path, what: str, names) -> None:
    """InputError for a name given twice, or for two of x y z in different cases (the second
    column of a name hid the first, or a coordinate was taken from the other column)."""
    seen = {}
    for name in names:
        key = name.lower() if name.lower() in ("x", "y", "z") else name
        if key in seen:
            raise fail(path, f"{what} {name!r} is given twice" + (f" (as {seen[key]!r} too)" if seen[key] != name else "")
                       + "; rename one")
        seen[key] = name


def _ply_header(path, f):
    """(format, [(element, count, [(prop, type) or (prop, 'list')])], header bytes, origin or None)."""
    if f.readline().strip() != b"ply":
        raise fail(path, "not a PLY file (no 'ply' magic line)")
    fmt, elements, origin = None, [], None
    while True:
        line = f.readline()
        if not line:
            raise fail(path, "truncated PLY header (no end_header)")
        words = line.decode("ascii", "replace").split()
        if words[:2] == ["comment", "origin"] and len(words) == 5:   # written by write_ply
            with contextlib.suppress(ValueError):
                origin = np.array([float(w) for w in words[2:]])
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            break
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property" and words[1] == "list":
                # the count's and the items' types: a binary reader steps over the lists by them
                elements[-1][2].append((words[-1], "list", PLY_TYPES[words[2]], PLY_TYPES[words[3]]))
            elif words[0] == "property":
                elements[-1][2].append((words[2], PLY_TYPES[words[1]]))
        except (IndexError, KeyError, ValueError):
            raise fail(path, f"corrupt PLY header line: {line.decode('ascii', 'replace').strip()!r}") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise fail(path, f"unsupported PLY format {fmt!r}")
    return fmt, elements, f.tell(), origin


def read_ply(path, origin=None) -> Cloud:
    with open(path, "rb") as f:
        fmt, elements, start, stored_origin = _ply_header(path, f)
    if origin is None and stored_origin is not None and np.all(np.isfinite(stored_origin)):
        origin = stored_origin   # the writer's local origin: local coordinates come back bit for bit
    names = [e[0] for e in elements]
    if "vertex" not in names:
        raise fail(path, "PLY file has no vertex element")
    before = elements[:names.index("vertex")]
    _, count, props = elements[names.index("vertex")]
    if any(p[1] == "list" for p in props):
        raise fail(path, "PLY vertex data with list properties is not supported")
    _unique_names(path, "PLY property", [p for p, _ in props])
    # X Y Z in capitals (some exporters): the coordinates all the same
    axes = {p.lower(): p for p, _ in props if p.lower() in ("x", "y", "z")}
    if len(axes) != 3:
        raise fail(path, "PLY vertices have no x y z properties")
    if fmt == "ascii" and count == 0:
        data = {p: np.zeros(0, t) for p, t in props}
    elif fmt == "ascii":
        skip = sum(e[1] for e in before)
        try:
            table = np.loadtxt(path, dtype=np.float64, ndmin=2, max_rows=count,
                               **_ascii_after(path, start, skip))
        except ValueError as exc:
            raise fail(path, f"corrupt ASCII PLY data ({' '.join(str(exc).split())})") from None
        if count and len(table) and table.shape[1] != len(props):
            raise fail(path, f"corrupt PLY file: its vertex rows hold {table.shape[1]} values, the header declares "
                             f"{len(props)} properties")
        if len(table) != count:
            raise fail(path, f"truncated or corrupt PLY file: {count} vertices declared, {len(table)} read")
        _warn_undeclared_rows(path, start, sum(e[1] for e in elements))
        data = {p: table[:, k].astype(t) for k, (p, t) in enumerate(props)}
        for k, (p, t) in enumerate(props):      # 300 in a uchar property wrapped to 44
            if np.dtype(t).kind in "iu" and not np.array_equal(data[p], table[:, k]):
                raise fail(path, f"PLY property {p!r} ({t}) holds values its type cannot, e.g. "
                                 f"{table[:, k][data[p] != table[:, k]][0]:g}")
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        skip = _binary_bytes(path, start, before, order)
        dtype = np.dtype([(p, order + t) for p, t in props])
        raw = np.fromfile(path, dtype=np.uint8, offset=start + skip, count=count * dtype.itemsize)
        if len(raw) != count * dtype.itemsize:
            raise fail(path, f"truncated PLY file: {count} vertices declared, "
                             f"{len(raw) // max(dtype.itemsize, 1)} present")
        table = raw.view(dtype)
        data = {p: table[p].astype(np.dtype(t).newbyteorder("=")) for p, t in props}
        if names[-1] == "vertex":
            # more vertex rows than declared after the last element: not read, as the ASCII path says
            extra = (os.path.getsize(path) - start - skip - count * dtype.itemsize) // max(dtype.itemsize, 1)
            if extra > 0:
                log.warning("%s: holds %d more vertex rows than its header declares (%d); they are not read",
                            path, extra, count)
    world = np.column_stack([data.pop(axes[a]) for a in ("x", "y", "z")]).astype(np.float64)
    if origin is not None and origin is stored_origin and len(world) and np.all(np.isfinite(world)):
        if float(np.abs(world - origin).max()) > ORIGIN_REACH:
            # not our writer's origin of these points: float32 offsets from it would round them
            log.warning("%s: its 'comment origin' %s lies far from its points; ignored", path,
                        " ".join(f"{v:.10g}" for v in origin))
            origin = None
    return world_cloud(path, world, origin, data)


def _binary_bytes(path, start: int, elements, order: str) -> int:
    """Bytes of the binary rows of ``elements`` (read from ``start``): fixed rows counted, rows
    with lists (faces before the vertices) stepped over one by one."""
    if not any(p[1] == "list" for e in elements for p in e[2]):
        return sum(e[1] * sum(np.dtype(t).itemsize for _, t in e[2]) for e in elements)
    import struct

    with open(path, "rb") as f:
        f.seek(start)
        for _, count, props in elements:
            for _ in range(count):
                for p in props:
                    if p[1] != "list":
                        f.seek(np.dtype(p[1]).itemsize, 1)
                        continue
                    size = np.dtype(p[2]).itemsize
                    raw = f.read(size)
                    if len(raw) != size:
                        raise fail(path, "truncated PLY file (in an element before the vertices)")
                    items = struct.unpack(order + np.dtype(p[2]).char, raw)[0]
                    f.seek(int(items) * np.dtype(p[3]).itemsize, 1)
        return f.tell() - start


def _warn_undeclared_rows(path, start: int, declared: int) -> None:
    """An ASCII PLY holding more data lines than its elements declare: the rest is not read (as
    other readers do), which a warning says."""
    with open(path, "rb") as f:
        f.seek(start)
        # newlines counted in blocks (fast); blank lines counted out only when there may be more
        lines = sum(block.count(b"\n") for block in iter(lambda: f.read(1 << 24), b""))
        f.seek(start)
        if lines + 1 <= declared:       # + 1: a last line without its newline
            return
        rows = sum(1 for line in f if line.strip())
    if rows > declared:
        log.warning("%s: holds %d data lines, its header declares %d; the rest is not read", path, rows, declared)


def _ascii_after(path, start: int, skip_lines: int) -> dict:
    """loadtxt arguments that start reading after the header and ``skip_lines`` data lines."""
    with open(path, "rb") as f:
        header_lines = f.read(start).count(b"\n")
    # latin-1 decodes every byte: a header comment in another encoding is skipped, not an error
    return {"skiprows": header_lines + skip_lines, "comments": None, "encoding": "latin-1"}


def write_ply(path, cloud: Cloud, classification=None, extra_dims=None, subset=None) -> None:
    world, cols = writable_columns(cloud, classification, extra_dims, subset)
    fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    values = {"x": world[:, 0], "y": world[:, 1], "z": world[:, 2]}
    for name, a in ply_properties(path, cols).items():
        fields.append((name, a.dtype.newbyteorder("<").str))
        values[name] = a
    table = np.empty(len(world), dtype=np.dtype(fields))
    for name, a in values.items():
        table[name] = a
    header = ["ply", "format binary_little_endian 1.0", "comment written by roadx_ti",
              "comment origin " + " ".join(repr(float(v)) for v in cloud.origin),
              f"element vertex {len(table)}"]
    header += [f"property {PLY_NAMES[np.dtype(t).str[1:]]} {n}" for n, t in fields] + ["end_header", ""]
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            f.write("\n".join(header).encode("ascii"))
            table.tofile(f)


def ply_properties(path, cols: dict) -> dict:
    """The columns as PLY vertex properties (InputError for a name or type PLY cannot hold)."""
    out = {}
    for name, a in cols.items():
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-.]*", name):
            raise fail(path, f"column name {name!r} cannot be a PLY property name")
        out[name] = _ply_storable(path, name, a)
    return out


def _ply_storable(path, name: str, a: np.ndarray) -> np.ndarray:
    """PLY has no 64-bit integers: store them as int32 or double when that is exact."""
    a = np.asarray(a)
    if a.dtype.str[1:] in PLY_NAMES:
        return a
    if a.dtype.kind in "iu":
        if a.size == 0 or (a.min() >= -2**31 and a.max() < 2**31):
            return a.astype(np.int32)
        if np.abs(a).max() <= 2**53:
            return a.astype(np.float64)
    raise fail(path, f"column {name!r} of type {a.dtype} has no exact PLY type")


# ------------------------------------------------------------------------------------------ PCD

PCD_DATA = ("ascii", "binary", "binary_compressed")
PCD_NORMALS = ("normal_x", "normal_y", "normal_z")


PCD_TYPES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}     # what Open3D reads (TYPE: SIZEs)
PCD_STORABLE = "iuf"            # numpy kinds a PCD field holds (bool as uint8, float16 as float32)


def _pcd_count(path) -> int:
    """The point count of a PCD header, after the checks Open3D's reader lacks: a repeated field
    aborted the process (glibc's heap check), a partial normal field set crashes Open3D 0.19,
    sizes and types it cannot read, multi-value fields it cuts to their first value, and ASCII
    data of fewer rows than POINTS, whose missing rows it filled from uninitialised memory."""
    header, fields, sizes, types, counts, count, data = 0, None, None, None, None, None, None
    with open(path, "rb") as f:
        for _ in range(64):
            line = f.readline()
            header += len(line)
            words = line.decode("ascii", "replace").split()
            if not words or words[0].startswith("#"):
                continue
            key = words[0].upper()
            if key == "POINTS":
                count = int(words[1])
            elif key == "FIELDS":
                fields = words[1:]
            elif key == "SIZE":
                sizes = [int(w) for w in words[1:]]
            elif key == "TYPE":
                types = [w.upper() for w in words[1:]]
            elif key == "COUNT":
                counts = [int(w) for w in words[1:]]
            elif key == "DATA":
                data = words[1].lower() if len(words) > 1 else ""
                break
    if count is None:
        raise fail(path, "not a PCD file (no POINTS line in the header)")
    if count < 0:
        raise fail(path, f"corrupt PCD header (POINTS {count})")
    if fields is not None and not {"x", "y", "z"} <= set(fields):
        raise fail(path, f"PCD file without x y z fields (FIELDS {' '.join(fields)})")
    fields = fields or []
    repeated = sorted({name for name in fields if fields.count(name) > 1})
    if repeated:
        raise fail(path, f"PCD field {repeated[0]!r} is named twice (FIELDS {' '.join(fields)[:200]}); rename one")
    for key, values in (("SIZE", sizes), ("TYPE", types), ("COUNT", counts)):
        if values is not None and len(values) != len(fields):
            raise fail(path, f"corrupt PCD header: {len(values)} {key} values for {len(fields)} FIELDS")
    for i, name in enumerate(fields):
        size, kind = (sizes[i] if sizes else 4), (types[i] if types else "F")
        if size not in PCD_TYPES.get(kind, ()):
            raise fail(path, f"PCD field {name!r} has TYPE {kind} SIZE {size}, which is not read (floats of 4 or 8 "
                             "bytes, integers of 1, 2, 4 or 8); convert it (e.g. pcl_convert_pcd_ascii_binary, Open3D)")
        if counts is not None and counts[i] != 1 and name != "_":     # '_': PCL's padding bytes, skipped
            raise fail(path, f"PCD field {name!r} has COUNT {counts[i]}: only fields of one value are read (histograms, "
                             "descriptors: drop or split them)")
    normals = [name for name in PCD_NORMALS if name in fields]
    if normals and len(normals) < 3:
        raise fail(path, f"PCD file with {' '.join(normals)} but not all of {' '.join(PCD_NORMALS)}: "
                         "Open3D reads normals as a set of three; rename the field or add the others")
    if data is not None and data not in PCD_DATA:
        raise fail(path, f"PCD DATA {data!r} is none of {', '.join(PCD_DATA)}")
    if data == "ascii":
        _check_pcd_ascii(path, header, count, len(fields))
    elif data == "binary" and sizes is not None:
        need = header + count * sum(sizes)
        if os.path.getsize(path) < need:
            have = (os.path.getsize(path) - header) // max(sum(sizes), 1)
            raise fail(path, f"truncated PCD file: {count} points declared, the file holds {max(have, 0)}")
    return count


PCD_CHECK_CHUNK = 1 << 24      # bytes of ASCII PCD data checked at a time
PCD_NOT_NUMERIC = re.compile(rb"[^0-9eE+\-.naNiIfFtTyY\s]")   # bytes no number (nor nan / inf) holds


def _check_pcd_ascii(path, start: int, count: int, width: int) -> None:
    """ASCII PCD data: ``count`` rows of ``width`` numbers each (Open3D read missing rows as
    uninitialised memory and words as 0), checked a chunk of lines at a time."""
    rows, tail = 0, b""
    with open(path, "rb") as f:
        f.seek(start)
        while True:
            block = f.read(PCD_CHECK_CHUNK)
            text = tail + block
            if block:
                cut = text.rfind(b"\n") + 1
                text, tail = text[:cut], text[cut:]
            bad = PCD_NOT_NUMERIC.search(text)
            if bad:
                at = bad.start()
                first = max(text.rfind(b" ", 0, at), text.rfind(b"\t", 0, at), text.rfind(b"\n", 0, at)) + 1
                word = text[first:].split()[0]
                raise fail(path, f"corrupt PCD file: {word[:40].decode('ascii', 'replace')!r} in the data is not a number")
            for line in text.split(b"\n"):
                words = len(line.split())
                if not words:
                    continue
                rows += 1
                if words != width:
                    raise fail(path, f"corrupt PCD file: data row {rows} holds {words} values, FIELDS names {width}")
            if not block:
                break
    if rows != count:
        raise fail(path, f"truncated or corrupt PCD file: {count} points declared, {rows} data rows")


def _open3d_message(exc: Exception) -> str:
    """Open3D's error text without its terminal colours and C++ function and source location."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", " ".join(str(exc).split()))
    text = re.sub(r"\[Open3D (Error|WARNING)\]\s*(\(.*?\)\s*)?(\S+:\d+:\s*)?", "", text)
    return text.strip()[:200]


def pcd_fields(path, cols: dict) -> dict:
    """The columns as PCD fields (InputError for a type PCD cannot hold); float16 as float32, bool as uint8."""
    out = {}
    for name, a in cols.items():
        a = np.asarray(a)
        if a.dtype.kind == "b":
            a = a.astype(np.uint8)
        elif a.dtype == np.float16:
            a = a.astype(np.float32)
        if a.dtype.kind not in PCD_STORABLE or a.dtype.fields is not None:
            raise fail(path, f"column {name!r} of type {a.dtype} cannot be a PCD field (numbers only)")
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise fail(path, f"column name {name!r} cannot be a PCD field name")
        out[name] = a
    return out


@contextlib.contextmanager
def _quiet_open3d():
    import open3d as o3d
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        yield o3d


def read_pcd(path, origin=None) -> Cloud:
    try:
        count = _pcd_count(path)
    except InputError:
        raise
    except (ValueError, IndexError):
        raise fail(path, "corrupt PCD header") from None
    with _quiet_open3d() as o3d:
        try:
            pc = o3d.t.io.read_point_cloud(str(path))
        except RuntimeError as exc:
            raise fail(path, f"corrupt PCD file ({_open3d_message(exc)})") from None
    arrays = {k: pc.point[k].numpy() for k in pc.point}
    world = arrays.pop("positions", np.zeros((0, 3)))
    if len(world) != count:
        raise fail(path, f"truncated or corrupt PCD file: {count} points declared, {len(world)} read")
    columns = {}
    if "colors" in arrays:
        c = arrays.pop("colors")
        columns.update(red=c[:, 0], green=c[:, 1], blue=c[:, 2])
    if "normals" in arrays:
        nrm = arrays.pop("normals")
        columns.update(normal_x=nrm[:, 0], normal_y=nrm[:, 1], normal_z=nrm[:, 2])
    for name, a in arrays.items():
        if a.ndim == 2 and a.shape[1] == 1:
            columns[name] = a[:, 0]
        else:
            columns.update({f"{name}_{k}": a[:, k] for k in range(a.shape[1])})
    return world_cloud(path, world, origin, columns)


def write_pcd(path, cloud: Cloud, classification=None, extra_dims=None, subset=None) -> None:
    world, cols = writable_columns(cloud, classification, extra_dims, subset)
    cols = pcd_fields(path, cols)
    with _quiet_open3d() as o3d:
        pc = o3d.t.geometry.PointCloud()
        pc.point.positions = o3d.core.Tensor(np.ascontiguousarray(world))
        if "red" in cols:
            rgb = np.column_stack([cols.pop("red"), cols.pop("green"), cols.pop("blue")])
            if rgb.dtype != np.uint8:   # PCD packs colour in 3 bytes
                # 8-bit values stored x 256 or x 257 come back exactly (cloud.stored_8bit_scale)
                scale = stored_8bit_scale(rgb)
                log.warning("%s: PCD colour is 8-bit; 16-bit colour written divided by %d", path, scale)
                rgb = np.round(rgb / float(scale)).astype(np.uint8)
            pc.point.colors = o3d.core.Tensor(np.ascontiguousarray(rgb))
        for name, a in cols.items():
            pc.point[name] = o3d.core.Tensor(np.ascontiguousarray(a.reshape(-1, 1)))
        with atomic_output(path) as tmp:
            if not o3d.t.io.write_point_cloud(str(tmp), pc):
                raise OSError(f"{path}: Open3D could not write the PCD file")


# ------------------------------------------------------------------------------------------ NPZ

NPZ_KEYS = ("xyz", "origin", "rgb", "color_depth", "intensity", "classification")


def read_npz(path, origin=None) -> Cloud:
    import zipfile
    if not zipfile.is_zipfile(path):
        raise fail(path, "not an NPZ file (expected a numpy .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise fail(path, f"not a readable NPZ file ({' '.join(str(exc).split())})") from None
    for key, a in arrays.items():
        if not isinstance(a, np.ndarray):       # a member that is not .npy (numpy hands its raw bytes)
            raise fail(path, f"NPZ member {key!r} is not a numpy array (.npy); it is not read")
    xyz = arrays.pop("xyz", None)
    if xyz is None or xyz.ndim != 2 or xyz.shape[1] != 3 or xyz.dtype.kind not in "iuf":
        raise fail(path, "NPZ file has no numeric 'xyz' array of shape (n, 3)")
    n = len(xyz)
    stored_origin = arrays.pop("origin", None)
    if stored_origin is not None and (stored_origin.shape != (3,) or stored_origin.dtype.kind not in "iuf"):
        raise fail(path, f"NPZ array 'origin' must be 3 numbers (x y z), got {stored_origin.dtype} {stored_origin.shape}")
    world = xyz.astype(np.float64) + (0.0 if stored_origin is None else np.asarray(stored_origin, np.float64))
    shapes = {"rgb": (n, 3), "intensity": (n,), "classification": (n,)}
    for key, shape in shapes.items():
        if key in arrays and (arrays[key].shape != shape or arrays[key].dtype.kind not in "iuf"):
            raise fail(path, f"NPZ array {key!r} must be numbers of shape {shape}, got {arrays[key].dtype} "
                             f"{arrays[key].shape}")
    depth = arrays.pop("color_depth", np.array(0))
    if depth.shape != () or depth.dtype.kind not in "iu" or int(depth) not in (0, 8, 16):
        raise fail(path, f"NPZ 'color_depth' must be one number, 8 or 16 (0: no colour), got {depth!r}")
    rgb, depth = arrays.pop("rgb", None), int(depth)
    intensity, classes = arrays.pop("intensity", None), arrays.pop("classification", None)
    nir = arrays.pop("nir", None) if "nir" in arrays and arrays["nir"].shape == (n,) else None
    for key, a, top in (("rgb", rgb, 255 if depth == 8 else 65535), ("intensity", intensity, 65535),
                        ("classification", classes, 255), ("nir", nir, 65535)):
        # the fields are integers: 2.7 as a class or 300 as 8-bit colour would be cut silently
        bad = _not_whole(a, top) if a is not None else None
        if bad is not None and bad.any():
            raise fail(path, f"NPZ array {key!r} must hold whole numbers 0-{top} (e.g. "
                             f"{np.asarray(a).reshape(-1)[np.flatnonzero(bad)[0]]:g})")
    attributes = {}
    for key, a in arrays.items():
        if a.ndim == 1 and len(a) == n:
            attributes[key] = a
        elif a.ndim == 2 and len(a) == n:      # (n, m): m columns, as the PCD reader splits them
            attributes.update({f"{key}_{k}": a[:, k] for k in range(a.shape[1])})
        else:
            log.warning("%s: NPZ array %r of shape %s is not one value or row per point; it is not read", path,
                        key, a.shape)
    bad = int(np.count_nonzero(~np.isfinite(world).all(axis=1))) if n else 0
    if bad:
        raise fail(path, f"{bad} of {n} points have NaN or infinite coordinates")
    if stored_origin is not None and origin is None:  # exact round trip of a Cloud
        local = xyz.astype(np.float32)
        o = np.asarray(stored_origin, np.float64)
    else:
        o = np.floor(world.min(axis=0)) if origin is None and n else (np.zeros(3) if origin is None else origin)
        local = (world - np.asarray(o, np.float64)).astype(np.float32)
    return Cloud(xyz=local, origin=o, rgb=None if rgb is None else rgb.astype(np.uint16),
                 color_depth=depth if rgb is not None else 0,
                 intensity=None if intensity is None else intensity.astype(np.uint16),
                 classification=None if classes is None else classes.astype(np.uint8),
                 nir=None if nir is None else nir.astype(np.uint16),
                 returns=_returns(path, attributes), attributes=attributes, source=str(path))


def _not_whole(a: np.ndarray, top: int) -> np.ndarray:
    """bool per value of ``a`` (flattened): not a whole number 0-``top``."""
    flat = np.asarray(a).reshape(-1)
    return ~np.isfinite(flat) | (flat != np.round(flat)) | (flat < 0) | (flat > top)


def write_npz(path, cloud: Cloud, classification=None, extra_dims=None, subset=None) -> None:
    index = point_index(subset, cloud.n)
    pick = (lambda a: a) if index is None else (lambda a: a[index])
    _, cols = writable_columns(cloud, classification, extra_dims, subset)
    arrays = {"xyz": pick(cloud.xyz), "origin": cloud.origin}
    if cloud.rgb is not None:
        arrays["rgb"] = pick(cloud.rgb)
        arrays["color_depth"] = np.int32(cloud.color_depth)
        for name in ("red", "green", "blue"):
            cols.pop(name)
    arrays.update(cols)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)


# ----------------------------------------------------------------------------------------- text

def _text_layout(path):
    """(delimiter, column names or None, rows to skip, columns to read or None) from the first
    lines of a text file. Columns: None for all; a range when data lines end in empty fields (a
    delimiter at the end of every line, as some spreadsheet and script exports write)."""
    names, skip, lines = None, 0, []
    with open(path, "r", encoding=TEXT_ENCODING, errors="replace") as f:
        for line in f:
            stripped = line.strip()
            if lines:               # the line after a header without comment marker
                if stripped and not stripped.startswith(("#", "//")):
                    lines.append(stripped)
                    break
                continue
            if not stripped:
                skip += 1
                continue
            if stripped.startswith(("#", "//")):
                words = [w for w in re.split(r"[\s,;]+", stripped.lstrip("#/").strip()) if w]
                if words and words[0].lower() in ("x", "//x"):
                    names = words
                skip += 1
                continue
            lines.append(stripped)
    if not lines:
        return None, names, skip, None, False
    # semicolons (spreadsheets in locales with a decimal comma write them: commas are then in the
    # values), commas, else whitespace
    # (from the last line read: a data line, when the first was a header)
    delimiter = next((d for d in (";", ",") if d in lines[-1]), None)
    decimal_comma = delimiter == ";" and any("," in line for line in lines)

    def fields(line):
        tokens = [t.strip().strip('"').strip("'") for t in (line.split(delimiter) if delimiter else line.split())]
        width = len(tokens)
        while width and not tokens[width - 1]:
            width -= 1
        return tokens[:width], width < len(tokens)
    tokens, trailing = fields(lines[0])
    try:
        [_number(t, decimal_comma) for t in tokens]
    except ValueError:   # a header line without comment marker (PDAL writes "X","Y","Z",...)
        names, skip = tokens, skip + 1
        tokens, trailing = fields(lines[1]) if len(lines) > 1 else (tokens, trailing)
    columns = range(len(tokens)) if trailing else None
    return delimiter, names, skip, columns, decimal_comma


def _number(text: str, decimal_comma: bool = False) -> float:
    return float(text.replace(",", ".") if decimal_comma else text)


def _quoting(path, skip: int) -> dict:
    """loadtxt's comment and quote options: values in double quotes (spreadsheet exports) are read
    when the first data line holds one (numpy then takes one comment marker only, '#')."""
    with open(path, "r", encoding=TEXT_ENCODING, errors="replace") as f:
        for number, line in enumerate(f):
            if number >= skip and line.strip() and not line.lstrip().startswith(("#", "//")):
                return {"comments": "#", "quotechar": '"'} if '"' in line else {"comments": ("#", "//")}
    return {"comments": ("#", "//")}


def read_text(path, origin=None) -> Cloud:
    delimiter, names, skip, columns, decimal_comma = _text_layout(path)
    # '1,5;2,5;3,5': semicolons between values, commas in them (locales with a decimal comma)
    convert = {"converters": lambda t: _number(t, True)} if decimal_comma else {}
    def load(encoding):
        return np.loadtxt(path, dtype=np.float64, delimiter=delimiter, skiprows=skip, encoding=encoding,
                          ndmin=2, usecols=columns, **convert, **_quoting(path, skip))
    try:
        try:
            table = load(TEXT_ENCODING)
        except UnicodeDecodeError:    # a comment or header in Latin-1 ('# Höhe'): the numbers are ASCII
            table = load("latin-1")
    except ValueError as exc:
        # numpy's reason without its advice to the programmer ("use `usecols` ...")
        reason = " ".join(str(exc).split()).split("; use `usecols`")[0]
        raise fail(path, f"not a point table ({reason})") from None
    if table.size == 0:
        table = np.zeros((0, len(names) if names else 3))
    width = table.shape[1]
    if names is not None and len(names) != width:
        log.warning("%s: its header names %d columns but the rows hold %d; the header is ignored", path,
                    len(names), width)
    if names is not None and len(names) == width:
        _unique_names(path, "text column", names)
        names = [n.lower() if n.lower() in ("x", "y", "z") else n for n in names]
        if not {"x", "y", "z"} <= set(names):
            raise fail(path, f"text header names no x y z columns: {' '.join(names)}")
    else:
        known = {3: ["x", "y", "z"], 4: ["x", "y", "z", "intensity"], 6: ["x", "y", "z", "red", "green", "blue"],
                 7: ["x", "y", "z", "red", "green", "blue", "intensity"]}
        if width < 3:
            raise fail(path, f"{width} column(s) per line; expected X Y Z [R G B [I]]")
        names = known.get(width) or ["x", "y", "z"] + [f"column_{k}" for k in range(3, width)]
    data = {name: table[:, k] for k, name in enumerate(names)}
    world = np.column_stack([data.pop("x"), data.pop("y"), data.pop("z")])
    return world_cloud(path, world, origin, data)


def write_text(path, cloud: Cloud, classification=None, extra_dims=None, subset=None) -> None:
    world, cols = writable_columns(cloud, classification, extra_dims, subset)
    decimals = _coord_decimals(cloud)
    delimiter = "," if str(path).lower().endswith(".csv") else " "
    # float32 columns in 9 significant digits and float64 ones (GPS time, double extra dimensions)
    # in 17: each reads back to the same value (9 digits put GPS times off by up to 0.5 s)
    formats = [f"%.{decimals}f"] * 3 + ["%d" if a.dtype.kind in "iub" else "%.17g" if a.dtype.itemsize > 4 else "%.9g"
                                         for a in cols.values()]
    text_columns(path, cols)
    table = np.empty((len(world), 3 + len(cols)), dtype=np.float64)
    table[:, :3] = world
    for k, a in enumerate(cols.values()):
        table[:, 3 + k] = a
    with atomic_output(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write("# " + delimiter.join(["x", "y", "z"] + list(cols)) + "\n")
            np.savetxt(f, table, fmt=formats, delimiter=delimiter)


def text_columns(path, cols: dict) -> None:
    """InputError for a column a numeric text table cannot hold exactly (strings, huge integers) or
    a name its header line cannot hold (the reader splits it at white space, commas and semicolons:
    a LAS extra dimension 'Echo Width' became two names, and the whole header was ignored)."""
    for name, a in cols.items():
        if not name or re.search(r"[\s,;]", name) or name.startswith(("#", "//")):
            raise fail(path, f"column name {name!r} cannot be a text column name (white space, commas and "
                             "semicolons separate the header's names); rename it, or write .las / .laz / .npz")
        if a.dtype.kind not in "biuf":
            raise fail(path, f"column {name!r} of type {a.dtype} cannot be written to a numeric text table")
        if a.dtype.kind in "iu" and a.size and np.abs(a.astype(np.float64)).max() > 2**53:
            raise fail(path, "64-bit integer column too large to write exactly as text")


READERS = {"ply": read_ply, "pcd": read_pcd, "npz": read_npz, "text": read_text}
WRITERS = {"ply": write_ply, "pcd": write_pcd, "npz": write_npz, "text": write_text}
# each writer's own test of its columns (InputError), beyond writable_columns: io.check_writable runs it
COLUMN_CHECKS = {"ply": ply_properties, "pcd": pcd_fields, "text": text_columns}
