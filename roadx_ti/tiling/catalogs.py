"""The catalog: the input files in order, with their header bounds and counts. (Plural, so that the
module does not hide the ``catalog`` function the package exports.)"""
from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

from roadx_ti.result_dims import DECIDED_BY

log_default = logging.getLogger("roadx_ti")


@dataclass(frozen=True)
class CatalogFile:
    path: str
    bounds: tuple          # header (xmin, ymin, xmax, ymax), max inclusive
    count: int
    z_range: tuple = (math.inf, -math.inf)   # header (zmin, zmax)


LAS_SUFFIXES = (".las", ".laz")      # .copc.laz included


def folder_files(folder: Path, warn: bool = True) -> list[Path]:
    """The point-cloud files of a catalog folder, sorted by name: its LAS/LAZ/COPC files when it
    holds any, else the files of the point-cloud format it holds most of (ties: io.EXTENSIONS
    order). Other files (a readme.txt, a .prj, a format in the minority) are skipped with one
    warning line; hidden files (a killed run's .partial file, .DS_Store) and sub-folders silently."""
    entries = sorted(q for q in folder.iterdir() if not q.name.startswith(".") and q.is_file())
    return point_cloud_files(entries, f"{folder}: folder", str(folder), warn)


def pattern_files(pattern: str, matches, warn: bool = True) -> list[Path]:
    """The point-cloud files among a wildcard pattern's matches (sorted), by folder_files' rules:
    'tiles/*' skips a run's sidecars (summary JSON, config YAML, picture) and 'tiles/*.laz' a
    run's own output written beside its tiles (its points would be read twice)."""
    return point_cloud_files(sorted(Path(m) for m in matches), f"{pattern}: the pattern", pattern, warn)


def point_cloud_files(entries: list[Path], holder: str, where: str, warn: bool = True) -> list[Path]:
    """folder_files' choice among ``entries`` (sorted files); ``holder`` names them in the error
    when none is a point-cloud file, ``where`` in the warnings."""
    from roadx_ti import io

    families = {}
    for q in entries:
        suffix = q.suffix.lower()
        if suffix in io.EXTENSIONS:
            families.setdefault("las" if suffix in LAS_SUFFIXES else suffix, []).append(q)
    if not families:
        raise io.InputError(f"{holder} holds no point-cloud files ({' '.join(io.EXTENSIONS)})")
    order = ["las"] + [s for s in io.EXTENSIONS if s not in LAS_SUFFIXES]
    chosen = "las" if "las" in families else max(families, key=lambda f: (len(families[f]), -order.index(f)))
    found = families[chosen]
    if chosen == "las":
        # a run's own output written into its input folder (--output tiles/merged.laz) would join the
        # next run of that folder as a tile: every point twice. Files carrying the result dimension
        # are left out while the folder holds others (name one to process it)
        ours = [q for q in found if _written_by_us(q)]
        if ours and len(ours) < len(found):
            found = [q for q in found if q not in ours]
            if warn:
                shown = ", ".join(q.name for q in ours[:5]) + (f" and {len(ours) - 5} more" if len(ours) > 5 else "")
                log_default.warning("%s: skipped %d file(s) that roadx_ti wrote (they carry %s): %s; name a "
                                    "file to process it", where, len(ours), DECIDED_BY, shown)
            entries = [q for q in entries if q not in ours]
    skipped = [q.name for q in entries if q not in found]
    if skipped and warn:
        kind = "LAS/LAZ" if chosen == "las" else chosen
        shown = ", ".join(skipped[:5]) + (f" and {len(skipped) - 5} more" if len(skipped) > 5 else "")
        log_default.warning("%s: the catalog is its %d %s file(s); skipped %d other file(s): %s",
                            where, len(found), kind, len(skipped), shown)
    return found


def _written_by_us(path: Path) -> bool:
    """The LAS/LAZ file carries DECIDED_BY (a header read; unreadable files say so later)."""
    import laspy

    try:
        with laspy.open(path) as reader:
            return DECIDED_BY in reader.header.point_format.extra_dimension_names
    except Exception:
        return False


def catalog(inputs, warn: bool = True) -> list[CatalogFile]:
    """The input files in order: each given file, or a folder's point-cloud files sorted by name
    (``folder_files``). Bounds and counts come from the headers (io.read_headers)."""
    from roadx_ti import io

    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    paths = []
    for given in inputs:
        p = Path(given)
        if p.is_dir():
            paths.extend(str(q) for q in folder_files(p, warn))
        else:
            paths.append(str(p))
    if not paths:
        raise io.InputError("no input files given")
    if len(set(_identity(p) for p in paths)) != len(paths):
        raise io.InputError(f"the same input file is named twice in {paths}")
    return [CatalogFile(path, tuple(float(b) for b in bounds), int(count), tuple(float(z) for z in z_range))
            for path, bounds, count, z_range in io.read_headers(paths)]


def _identity(path: str):
    """What makes two names one file: its device and inode (a hard link, a symbolic link, another
    spelling), or its real path where it cannot be looked at (a missing file says so later)."""
    try:
        st = os.stat(path)
    except OSError:
        return os.path.realpath(path)
    return st.st_dev, st.st_ino


def check_compatible(files: list[CatalogFile], merged_las: bool, log=None) -> None:
    """Files that one run may take together (LAS/LAZ headers; other formats carry neither CRS nor
    scales): a ValueError when one counts in other units than metres (roadx_ti.units); an InputError
    when two name different coordinate systems (their coordinates do not
    share one frame: tiles, buffers and the merged output would mix them); a warning when some
    name one and others none (assumed the same) or only their vertical CRSs differ, and, for a
    merged LAS/LAZ output (written from the records: other formats take world coordinates), when their scales or
    offsets put their coordinates off the first file's grid (the merged file takes the first file's
    scales and offsets: the others' points are rounded to it)."""
    from roadx_ti import io
    from roadx_ti.io.crs import of_header
    from roadx_ti.io.las_write import fits_records

    import laspy

    from roadx_ti import units

    log = log or log_default
    las = [f for f in files if Path(f.path).suffix.lower() in LAS_SUFFIXES]
    crs, grids, formats = {}, {}, {}
    for f in las:
        with laspy.open(f.path) as reader:
            formats[f.path] = reader.header.point_format
            crs[f.path] = of_header(reader.header)
            grids[f.path] = (tuple(float(v) for v in reader.header.scales),
                             tuple(float(v) for v in reader.header.offsets))
        problem = units.geographic_problem(crs[f.path], max(abs(f.bounds[0]), abs(f.bounds[2])),
                                           max(abs(f.bounds[1]), abs(f.bounds[3]))) if f.count else None
        if problem:
            # the untiled run's rule on the header box (degrees and wrong geographic records ran
            # silently in tiles, their DTM georeferenced as degrees)
            raise io.InputError(f"{f.path}: {problem}")
        factors = units.metre_factors(crs[f.path])
        if not factors.metric:
            # windows and buffers are planned in the files' units (a whole-file run converts)
            raise ValueError(f"{f.path}: counts in {factors.name}; tiled runs work in the files' units and "
                             "need metres: run the file whole (without --tile-size / tiling.auto) or "
                             "reproject the catalog to a metric CRS")
    if len(las) < 2:
        return
    named = {p: c for p, c in crs.items() if c is not None}
    if named:
        first_path, first = next(iter(named.items()))
        for path, other in named.items():
            if other != first and _horizontal(other) == _horizontal(first):
                # e.g. EPSG:25832+5783 beside EPSG:25832 (a tool dropped the vertical CRS): x, y agree
                log.warning("%s is in %s, %s in %s: the same horizontal CRS, taken as one survey",
                            first_path, _crs_name(first), path, _crs_name(other))
            elif other != first:
                raise io.InputError(f"the inputs are in different coordinate systems: {first_path} is in "
                                    f"{_crs_name(first)}, {path} in {_crs_name(other)}; reproject them to one "
                                    "(e.g. pdal translate with filters.reprojection) or run them apart")
        unnamed = [p for p, c in crs.items() if c is None]
        if unnamed:
            log.warning("%d input file(s) name no coordinate system (e.g. %s); taken to be in %s like %s",
                        len(unnamed), unnamed[0], _crs_name(first), first_path)
    if merged_las:
        # the merged file takes the header of io.las_write.template_source's file (the first with
        # points and a CRS record, else the first with points): the checks below test against it
        # (they tested the first file with points, and a catalog whose CRS came from a later file
        # failed at the merge, after every tile, or was warned of with the wrong file's grid)
        from roadx_ti.io.las_write import template_source

        first_path = template_source([f.path for f in las])
        # one merged file holds one point format: say it before the tiles run, not at the merge
        for f in las:
            # laspy's own test when it writes (ids, and extra dimensions with their descriptions)
            if formats[f.path] != formats[first_path]:
                a, b = formats[first_path].id, formats[f.path].id
                what = f"point format {a} against {b}" if a != b else "other extra dimensions"
                raise io.InputError(f"{f.path}: cannot be merged with {first_path} ({what}: a merged LAS/LAZ "
                                    "output holds one point format); use output.mode per-file, or convert them "
                                    "to one format first (e.g. pdal translate --writers.las.dataformat_id)")
        scales, offsets = grids[first_path]
        for f in las:
            lows, highs = (f.bounds[0], f.bounds[1], f.z_range[0]), (f.bounds[2], f.bounds[3], f.z_range[1])
            for axis, (low, high) in enumerate(zip(lows, highs)):
                if f.count and not fits_records(low, high, scales[axis], offsets[axis]):
                    raise io.InputError(
                        f"{f.path}: its {'xyz'[axis]} coordinates ({low:.3f} .. {high:.3f}) lie beyond what the "
                        f"merged output, with {Path(first_path).name}'s scale {scales[axis]:g} and offset "
                        f"{offsets[axis]:g}, can hold (32-bit integers); use output.mode per-file, or give the "
                        "files one offset near their points (e.g. pdal translate)")
        differ = [f.path for f in las if f.count and not _on_grid(grids[f.path], grids[first_path])]
        if differ:
            log.warning("%d input file(s) have other scales or offsets than %s (e.g. %s: scales %s, offsets %s); "
                        "the merged output takes %s's (scales %s, offsets %s), and those of their points that lie "
                        "off it are rounded to it (output.mode per-file keeps each file's)", len(differ), first_path, differ[0],
                        _numbers(grids[differ[0]][0]), _numbers(grids[differ[0]][1]), Path(first_path).name,
                        _numbers(scales), _numbers(offsets))


def _on_grid(grid, first) -> bool:
    """Every coordinate representable on ``grid`` (scales, offsets) is exactly one of ``first``'s:
    its scales whole multiples of the first's and its offsets whole steps of them away."""
    for scale, offset, first_scale, first_offset in zip(*grid, *first):
        steps, shift = scale / first_scale, (offset - first_offset) / first_scale
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1 or abs(shift - round(shift)) > 1e-6:
            return False
    return True


def _horizontal(crs):
    """The horizontal part of a compound CRS (WKT1 COMPD_CS: its first child), else the CRS."""
    from rasterio.crs import CRS
    from rasterio.errors import CRSError

    wkt = crs.to_wkt()
    if not wkt.startswith("COMPD_CS["):
        return crs
    start = min((i for i in (wkt.find("PROJCS["), wkt.find("GEOGCS[")) if i >= 0), default=-1)
    if start < 0:
        return crs
    depth = 0
    for end in range(start, len(wkt)):
        depth += {"[": 1, "]": -1}.get(wkt[end], 0)
        if depth == 0 and wkt[end] == "]":
            try:
                return CRS.from_wkt(wkt[start:end + 1])
            except CRSError:
                return crs
    return crs


def _crs_name(crs) -> str:
    code = crs.to_epsg()
    return f"EPSG:{code}" if code else " ".join(crs.to_wkt().split())[:80]


def _numbers(values) -> str:
    return " ".join(f"{v:.10g}" for v in values)
