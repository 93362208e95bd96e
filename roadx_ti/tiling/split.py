"""Decode each LAS/LAZ file of a catalog once, before the tiles run, and keep every tile's share of
it as raw point records in a scratch folder: a tile then reads its window back from those records
instead of decoding the whole file again (a LAZ without a spatial index must be decoded whole for
any window, so a file under n tiles was decoded n times). The records are the file's own, so a
tile's Cloud is the one a windowed read gives, bit for bit. The folder goes when the run ends."""
from __future__ import annotations

import logging
import os
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roadx_ti.io.atomic import host_tag, process_alive
from roadx_ti.tiling.catalogs import LAS_SUFFIXES, CatalogFile
from roadx_ti.tiling.plan import TilePlan

log_default = logging.getLogger("roadx_ti")

FOLDER_PREFIX = ".roadx_ti-split-"   # hidden: a catalog folder's listing skips it
DISK_MARGIN = 1.2                    # free space wanted, times the estimated record bytes


@dataclass
class Part:
    """One file's points in one tile's window: raw records of ``dtype`` in ``path``."""
    path: str
    dtype: object


@dataclass
class Split:
    folder: Path | None
    parts: dict = field(default_factory=dict)    # (tile index, file index) -> Part
    files: list = field(default_factory=list)    # catalog indices that were split
    seconds: float = 0.0
    bytes: int = 0

    def for_tile(self, tile_index: int, file_indices) -> dict:
        """The split files of one tile: file index -> Part, or None where the window holds none
        of that file's points (a split file without a part there)."""
        return {k: self.parts.get((tile_index, k)) for k in file_indices if k in self.files}

    def describe(self) -> dict:
        return {"files": len(self.files), "parts": len(self.parts), "bytes": self.bytes,
                "seconds": round(self.seconds, 4)}

    def remove(self) -> None:
        """Delete the scratch folder; a second Ctrl-C or SIGTERM arriving meanwhile (a terminal
        signals the whole process group, and impatient users press twice) is held until the folder
        is gone, then raised: the records must not outlive the run."""
        if self.folder is None:
            return
        interrupted = None
        for _ in range(5):
            try:
                shutil.rmtree(self.folder, ignore_errors=True)
                break
            except BaseException as exc:      # KeyboardInterrupt, cli.Terminated
                interrupted = interrupted or exc
        self.folder = None
        if interrupted is not None:
            raise interrupted


def remove_stale_folders(where, log=None) -> list[Path]:
    """Remove the scratch folders under ``where`` that runs on this host left when they were killed
    (SIGKILL, the OOM killer: no cleanup ran): named by their pid, which no longer runs. Returns
    the removed folders. A running run's folder and other hosts' are never touched."""
    pattern = re.compile(re.escape(FOLDER_PREFIX) + r"p(\d+)-([A-Za-z0-9_]+)-")
    removed = []
    try:
        names = os.listdir(where)
    except OSError:
        return removed
    for name in names:
        m = pattern.match(name)
        path = Path(where) / name
        if not m or m.group(2) != host_tag() or process_alive(int(m.group(1))):
            continue
        if path.is_symlink() or not path.is_dir():
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path)
    if removed:
        (log or log_default).info("removed %d scratch folder(s) of killed runs under %s", len(removed), where)
    return removed


def _overlap(a, b) -> float:
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def splittable(plan: TilePlan, files: list[CatalogFile]) -> list[int]:
    """Catalog indices of the LAS/LAZ files that two or more tiles read (a file read by one tile
    gains nothing from a split)."""
    readers = {}
    for t in plan.tiles:
        for k in t.files:
            readers[k] = readers.get(k, 0) + 1
    return [k for k, f in enumerate(files)
            if readers.get(k, 0) >= 2 and Path(f.path).suffix.lower() in LAS_SUFFIXES and f.count]


def estimated_bytes(plan: TilePlan, files: list[CatalogFile], chosen: list[int], record_sizes: dict) -> int:
    """Record bytes the split writes: each file's records times the windows' cover of its box
    (points assumed uniform over the header box)."""
    total = 0.0
    for k in chosen:
        box = files[k].bounds
        area = max(box[2] - box[0], 1e-9) * max(box[3] - box[1], 1e-9)
        cover = sum(_overlap(t.window, box) for t in plan.tiles if k in t.files) / area
        total += cover * files[k].count * record_sizes[k]
    return int(total)


def split_catalog(plan: TilePlan, files: list[CatalogFile], where, *, log=None) -> Split:
    """Split the files several tiles read into per-tile record files in a new hidden folder under
    ``where``; nothing is split (tiles read their files directly) when no file needs it or the
    disk lacks the room (a warning then)."""
    from roadx_ti import io

    log = log or log_default
    chosen = splittable(plan, files)
    if not chosen:
        return Split(folder=None)
    t0 = time.perf_counter()
    dtypes = {k: io.record_dtype(files[k].path) for k in chosen}
    need = estimated_bytes(plan, files, chosen, {k: d.itemsize for k, d in dtypes.items()})
    where = Path(where)
    free = shutil.disk_usage(where).free
    if free < DISK_MARGIN * need:
        from roadx_ti.memory import format_size
        log.warning("not splitting the inputs for the tiles: about %s of point records would not fit in the %s "
                    "free under %s; each tile decodes its files itself", format_size(need), format_size(free), where)
        return Split(folder=None)
    remove_stale_folders(where, log)
    prefix = f"{FOLDER_PREFIX}p{os.getpid()}-{host_tag()}-"
    split = Split(folder=Path(tempfile.mkdtemp(prefix=prefix, dir=where)), files=chosen)
    try:
        for k in chosen:
            windows = [(t.index, t.window) for t in plan.tiles if k in t.files]

            def write(tile_index, records, k=k):
                part = split.parts.get((tile_index, k))
                if part is None:
                    part = split.parts[(tile_index, k)] = Part(str(split.folder / f"t{tile_index}_f{k}.rec"),
                                                               dtypes[k])
                with open(part.path, "ab") as out:
                    records.tofile(out)
                split.bytes += records.nbytes

            io.split(files[k].path, windows, write)
    except BaseException:
        split.remove()
        raise
    split.seconds = time.perf_counter() - t0
    log.info("split %d file(s) into %d tile part(s) once (%.2f GB of records) in %.2f s", len(chosen),
             len(split.parts), split.bytes / 1e9, split.seconds)
    return split


def read_part(path: str, part: Part, origin):
    """The Cloud of one tile's part of a split file (as io.read(path, bounds=window, origin))."""
    from roadx_ti import io

    return io.read_part(path, np.fromfile(part.path, dtype=part.dtype), origin)
