"""The catalog: the input files in order, with their header bounds and counts. (Plural, so that the
module does not hide the ``catalog`` function the package exports.)"""
from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

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
    from roadx_ti import io

    entries = sorted(q for q in folder.iterdir() if not q.name.startswith(".") and q.is_file())
    families = {}
    for q in entries:
        suffix = q.suffix.lower()
        if suffix in io.EXTENSIONS:
            families.setdefault("las" if suffix in LAS_SUFFIXES else suffix, []).append(q)
    if not families:
        raise io.InputError(f"{folder}: folder holds no point-cloud files ({' '.join(io.EXTENSIONS)})")
    order = ["las"] + [s for s in io.EXTENSIONS if s not in LAS_SUFFIXES]
    chosen = "las" if "las" in families else max(families, key=lambda f: (len(families[f]), -order.index(f)))
    found = families[chosen]
    skipped = [q.name for q in entries if q not in found]
    if skipped and warn:
        kind = "LAS/LAZ" if chosen == "las" else chosen
        shown = ", ".join(skipped[:5]) + (f" and {len(skipped) - 5} more" if len(skipped) > 5 else "")
        log_default.warning("%s: the catalog is its %d %s file(s); skipped %d other file(s): %s",
                            folder, len(found), kind, len(skipped), shown)
    return found


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
    if len(set(os.path.realpath(p) for p in paths)) != len(paths):
        raise io.InputError(f"the same input file is named twice in {paths}")
    return [CatalogFile(path, tuple(float(b) for b in bounds), int(count), tuple(float(z) for z in z_range))
            for path, bounds, count, z_range in io.read_headers(paths)]
