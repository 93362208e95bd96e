"""Scale-out: multi-file catalogs, a fixed grid of core tiles with buffers, executors (in-process or
dask.distributed) and the merge back into one output.

    summary = run_catalog(cfg, ["tiles/"], "out/all.laz", workers=4)          # local Dask cluster
    summary = run_catalog(cfg, paths, "out/", output_mode="per-file", scheduler="tcp://host:8786")

How a run goes:
1. ``catalog``: the input files (a folder gives its point-cloud files sorted by name) with their
   header bounds; input order = catalog order, each file's points in file order.
2. ``plan_tiles``: core tiles on a grid anchored at multiples of the tile size; a tile exists
   where some file's header box meets its core. Each tile reads core + ``buffer`` on every side,
   only from the files whose box meets that window (io.read(path, bounds=window, origin=shared)).
3. ``run_tile`` (on any executor) runs the whole pipeline on the window and keeps the labels of its
   core points only. Cores are half-open [x0, x1) x [y0, y1), so every point has exactly one core.
   A point's core is found by ``CoreGrid.cells`` everywhere (workers and merge), so all parts of
   the run agree on it bit for bit. Only occupied cores are tiles: a file whose header box spans
   many cores is scanned for the cores its points occupy, and nothing is allocated per grid cell.
4. Segments cut by a core border are reconciled: a tile returns, per neighbour, the segment ids of
   its buffer points that are the neighbour's core points, and the ids of its core points inside
   the neighbour's window; both lists hold the same points in the same (catalog, file) order, so
   pairing them links (tile, segment) nodes, and a union-find gives one global id per component.
5. The merge streams every input file again in chunks and takes each point's labels from its core
   tile in order (the k-th point of file f in core t is the k-th core point of f that t returned).
   Nothing is written until every tile has succeeded; outputs are written atomically.
"""
from __future__ import annotations

import contextlib
import copy
import ctypes
import logging
import math
import os
import socket
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roadx_ti.cloud import Cloud
from roadx_ti.errors import DataError
from roadx_ti.stages.base import ESTIMATES, SURVEY_POINTS, SURVEY_Z_MIN

log_default = logging.getLogger("roadx_ti")

TARGET_TILE_POINTS = 2_000_000   # default core tile: about this many points
TILE_SIZE_STEP = 10.0            # default tile sizes are rounded up to a multiple of this (m)
MIN_BUFFER = 5.0                 # m: even point-local stages need their neighbours
CLOTH_SPAN = 30.0                # m: least cloth buffer (half the widest building it hangs over)
MERGE_CHUNK_POINTS = 1_000_000
RETRIES = 2                      # dask retries of a failed tile before the run fails
MODES = ("merged", "per-file")


class TileError(RuntimeError):
    """A tile failed (after its retries); the message names it by its bounds. Nothing was written."""


class ClusterError(DataError):
    """The Dask cluster cannot run the tiles (unreachable scheduler, no workers, workers with
    another environment or without the inputs); one line, raised before any tile runs."""


CONNECT_TIMEOUT = 5.0            # s: reaching the scheduler
WORKER_TIMEOUT = 30.0            # s: waiting for the first worker
# what must match between the client and every worker (README, Scale-out)
ENVIRONMENT_PACKAGES = ("numpy", "laspy", "lazrs", "scipy", "dask", "distributed")


# ------------------------------------------------------------------------------------- catalog

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


# -------------------------------------------------------------------------------------- plan

STAGE_REACH_DOC = """Spatial reach of each stage (m), the default buffer is the largest:
cloth_ground / cloth_smooth: the larger of 30 m and 15 x cloth_resolution (the cloth hangs over a
building from the terrain around it: a building cut by the window's edge loses that support, so the
buffer covers buildings up to 60 m across; the stiffness carries the cloth's shape 15 particles);
grid_slope: 4 x step; ransac_planes: ground_cell; color_growing: 20 x max_edge_distance;
roof_seeds: 4 x r_max (1.5 m for 'auto'); roof_filter: 2 x sqrt(min_roof_area) (a roof must be whole to be measured);
others: MIN_BUFFER."""


def stage_reach(name: str, options) -> float:
    """How far (m) a stage's decision about a point depends on other points (see STAGE_REACH_DOC)."""
    def get(key, default):
        value = getattr(options, key, default) or default
        return default if isinstance(value, str) else float(value)   # 'auto': follows the estimates
    reach = {
        "cloth_ground": lambda: max(CLOTH_SPAN, 15.0 * get("cloth_resolution", 1.0)),
        "cloth_smooth": lambda: max(CLOTH_SPAN, 15.0 * get("cloth_resolution", 2.0)),
        "grid_slope": lambda: 4.0 * get("step", 0.5),
        "ransac_planes": lambda: get("ground_cell", 30.0),
        "color_growing": lambda: 20.0 * get("max_edge_distance", 0.5),
        "roof_seeds": lambda: 4.0 * get("r_max", 1.5),
        "roof_filter": lambda: 2.0 * math.sqrt(get("min_roof_area", 10.0)),
    }.get(name)
    return max(MIN_BUFFER, reach() if reach else MIN_BUFFER)


def default_buffer(stage_specs) -> tuple[float, dict]:
    """(buffer in m, {stage: reach}) from the stages' spatial reach, rounded up to a metre."""
    reaches = {name: round(stage_reach(name, opts), 3) for name, opts in stage_specs}
    return float(math.ceil(max(reaches.values(), default=MIN_BUFFER))), reaches


def default_tile_size(files: list[CatalogFile], target_points: int = TARGET_TILE_POINTS) -> float:
    """Edge (m) of a square core holding about ``target_points`` at the catalog's mean density."""
    area = sum(max(f.bounds[2] - f.bounds[0], 1.0) * max(f.bounds[3] - f.bounds[1], 1.0) for f in files)
    density = max(sum(f.count for f in files) / area, 1e-6)
    return TILE_SIZE_STEP * math.ceil(math.sqrt(target_points / density) / TILE_SIZE_STEP)


@dataclass(frozen=True)
class CoreGrid:
    """The core tile grid: column c is [x0 + sx * c, x0 + sx * (c + 1)), rows alike, cols x rows
    cells. Grid lines are computed as ``x0 + sx * k`` in float64 (as np.arange-based edges were),
    and a point's cell is the one whose half-open interval holds it exactly; nothing is
    allocated per cell, so a grid over a huge extent costs nothing."""
    x0: float
    y0: float
    sx: float
    sy: float
    cols: int
    rows: int

    def x_edge(self, k):
        return self.x0 + self.sx * np.asarray(k, np.float64)

    def y_edge(self, k):
        return self.y0 + self.sy * np.asarray(k, np.float64)

    @staticmethod
    def _index(v, origin, step, count, edge):
        v = np.asarray(v, np.float64)
        with np.errstate(invalid="ignore", over="ignore"):
            g = np.clip(np.floor((v - origin) / step), -1, count)
        g = np.where(np.isnan(g), -1, g).astype(np.int64)
        for _ in range(2):   # float rounding of the guess: at most a cell off either way
            g = np.where((g >= 0) & (edge(np.maximum(g, 0)) > v), g - 1, g)
            g = np.where((g < count) & (edge(np.minimum(g + 1, count)) <= v), g + 1, g)
        return g

    def cells(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(col, row) of the cells holding world points x, y: x_edge(col) <= x < x_edge(col+1);
        -1 below the grid, cols (rows) at or beyond its far edge. The one test of core
        membership, used everywhere."""
        return (self._index(x, self.x0, self.sx, self.cols, self.x_edge),
                self._index(y, self.y0, self.sy, self.rows, self.y_edge))

    def key(self, col, row):
        return np.asarray(row, np.int64) * np.int64(self.cols) + np.asarray(col, np.int64)

    def describe(self) -> dict:
        return {"x0": self.x0, "y0": self.y0, "sx": self.sx, "sy": self.sy, "cols": self.cols, "rows": self.rows}


MAX_LISTED_EDGES = 10_000          # summaries list the grid lines of grids up to this many columns
SCAN_CELLS = 16                    # a file whose header box meets more core cells is scanned for the
                                   # cells its points occupy (a stray point stretches a header box)
MAX_HEADER_CELLS = 1 << 20         # unscanned header boxes may mark at most this many cells


@dataclass(frozen=True)
class Tile:
    index: int
    col: int
    row: int
    core: tuple            # (x0, y0, x1, y1), half-open
    window: tuple          # core + buffer, half-open
    files: tuple           # catalog indices of the files whose header box meets the window
    neighbours: tuple      # tile indices whose cores meet this window


@dataclass
class TilePlan:
    grid: CoreGrid         # the core cells (x_edges / y_edges: their grid lines)
    tile_size: float       # inf for an untiled run (one core over everything)
    buffer: float
    read_origin: np.ndarray  # (3,) float64 local origin shared by every read
    tiles: list[Tile]
    tile_keys: np.ndarray  # sorted int64 grid.key(col, row) of the cells that have a tile
    tile_ids: np.ndarray   # int64 tile index of each of tile_keys

    @property
    def x_edges(self) -> np.ndarray:
        return self.grid.x_edge(np.arange(self.grid.cols + 1))

    @property
    def y_edges(self) -> np.ndarray:
        return self.grid.y_edge(np.arange(self.grid.rows + 1))

    def cells(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.grid.cells(x, y)

    def tile_index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Index of the tile whose core holds each point, -1 where none does."""
        col, row = self.cells(x, y)
        return tile_lookup(self.grid, self.tile_keys, self.tile_ids, col, row)

    def border_distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance (m) of each point to the nearest border of its core tile (inf untiled)."""
        return _border_distance(self.grid, x, y)

    def describe(self) -> dict:
        listed = self.grid.cols <= MAX_LISTED_EDGES and self.grid.rows <= MAX_LISTED_EDGES
        return {"tile_size": self.tile_size if np.isfinite(self.tile_size) else None,
                "buffer": self.buffer, "grid_origin": [float(self.grid.x0), float(self.grid.y0)],
                "columns": self.grid.cols, "rows": self.grid.rows, "tiles": len(self.tiles),
                "grid": self.grid.describe(),
                "x_edges": self.x_edges.tolist() if listed else None,
                "y_edges": self.y_edges.tolist() if listed else None,
                "read_origin": self.read_origin.tolist()}


def tile_lookup(grid: CoreGrid, keys: np.ndarray, ids: np.ndarray, col, row) -> np.ndarray:
    """Tile index of each (col, row) among the sorted cell ``keys`` (-1 outside the grid or
    where the cell has no tile)."""
    col, row = np.asarray(col, np.int64), np.asarray(row, np.int64)
    out = np.full(col.shape, -1, np.int64)
    inside = (col >= 0) & (col < grid.cols) & (row >= 0) & (row < grid.rows)
    if len(keys) and inside.any():
        key = grid.key(col[inside], row[inside])
        j = np.minimum(np.searchsorted(keys, key), len(keys) - 1)
        out[inside] = np.where(keys[j] == key, ids[j], -1)
    return out


def _header_cells(grid: CoreGrid, f: CatalogFile) -> np.ndarray:
    """Keys of the cells a file's header box meets (clamped to the grid)."""
    c0, c1 = (int(np.clip(v, 0, grid.cols - 1)) for v in grid.cells([f.bounds[0], f.bounds[2]], [0, 0])[0])
    r0, r1 = (int(np.clip(v, 0, grid.rows - 1)) for v in grid.cells([0, 0], [f.bounds[1], f.bounds[3]])[1])
    count = (c1 - c0 + 1) * (r1 - r0 + 1)
    if count > MAX_HEADER_CELLS:
        raise ValueError(f"{f.path}: its header box {f.bounds[0]:.0f}, {f.bounds[1]:.0f} .. {f.bounds[2]:.0f}, "
                         f"{f.bounds[3]:.0f} spans {count:,} tiles of {grid.sx:g} m; use a larger --tile-size")
    cc, rr = np.meshgrid(np.arange(c0, c1 + 1), np.arange(r0, r1 + 1))
    return grid.key(cc.ravel(), rr.ravel())


def plan_tiles(files: list[CatalogFile], tile_size: float, buffer: float, scan=None) -> TilePlan:
    """Core tiles of ``tile_size`` on a grid anchored at multiples of the tile size, each read with
    ``buffer`` on every side. ``tile_size`` = inf (or <= 0) gives one core over the whole catalog
    and no buffer: the untiled run, through the same code path.
    A tile exists where a file's header box meets its core; a file whose box meets more than
    SCAN_CELLS cores is scanned instead when ``scan`` is given (``scan(file, grid)`` -> keys of the
    cells its points occupy): stray points far off stretch a header box over thousands of empty
    tiles. Nothing is allocated per grid cell."""
    xmin = min(f.bounds[0] for f in files)
    ymin = min(f.bounds[1] for f in files)
    xmax = max(f.bounds[2] for f in files)
    ymax = max(f.bounds[3] for f in files)
    if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax)):
        raise ValueError("the catalog's header bounds are not finite; fix the headers (e.g. pdal translate)")
    read_origin = np.array([math.floor(xmin), math.floor(ymin), 0.0])
    if tile_size is None or not np.isfinite(tile_size) or tile_size <= 0:
        tile_size, buffer = math.inf, 0.0
        # header max is inclusive; +1 m keeps the last points inside the half-open core
        gx, gy = float(math.floor(xmin)), float(math.floor(ymin))
        grid = CoreGrid(gx, gy, float(math.floor(xmax) + 1.0) - gx, float(math.floor(ymax) + 1.0) - gy, 1, 1)
    else:
        tile_size = float(tile_size)
        x0 = math.floor(xmin / tile_size) * tile_size
        y0 = math.floor(ymin / tile_size) * tile_size
        cols = int(math.floor((xmax - x0) / tile_size)) + 1
        rows = int(math.floor((ymax - y0) / tile_size)) + 1
        grid = CoreGrid(float(x0), float(y0), tile_size, tile_size, cols, rows)
    if buffer < 0:
        raise ValueError(f"tiling buffer must be >= 0 m, got {buffer}")
    used = []
    for f in files:
        if not f.count:
            continue
        if scan is not None and np.isfinite(tile_size) and _box_cells(grid, f) > SCAN_CELLS:
            used.append(np.asarray(scan(f, grid), np.int64))
        else:
            used.append(_header_cells(grid, f))
    keys = np.unique(np.concatenate(used)) if used else np.zeros(0, np.int64)
    ids = np.arange(len(keys), dtype=np.int64)
    tiles = []
    for i, key in enumerate(keys.tolist()):
        r, c = divmod(key, grid.cols)
        core = (float(grid.x_edge(c)), float(grid.y_edge(r)), float(grid.x_edge(c + 1)), float(grid.y_edge(r + 1)))
        window = (core[0] - buffer, core[1] - buffer, core[2] + buffer, core[3] + buffer)
        meets = [k for k, f in enumerate(files) if f.count and f.bounds[2] >= window[0]
                 and f.bounds[0] < window[2] and f.bounds[3] >= window[1] and f.bounds[1] < window[3]]
        lo_c, lo_r = grid.cells([window[0]], [window[1]])
        hi_c, hi_r = grid.cells([np.nextafter(window[2], -np.inf)], [np.nextafter(window[3], -np.inf)])
        found = _tiles_in(grid, keys, ids, (max(int(lo_c[0]), 0), min(int(hi_c[0]), grid.cols - 1)),
                          (max(int(lo_r[0]), 0), min(int(hi_r[0]), grid.rows - 1)))
        near = tuple(int(t) for t in found if t != i)
        tiles.append(Tile(i, c, r, core, window, tuple(meets), near))
    return TilePlan(grid, float(tile_size), float(buffer), read_origin, tiles, keys, ids)


def _tiles_in(grid: CoreGrid, keys: np.ndarray, ids: np.ndarray, cols: tuple, rows: tuple) -> np.ndarray:
    """Ascending tile indices whose cells lie in the column and row ranges (inclusive): by looking
    up the range's cells when they are few, else by filtering the tiles (a buffer far larger than
    the tiles must not enumerate the cells it spans)."""
    if cols[0] > cols[1] or rows[0] > rows[1]:
        return np.zeros(0, np.int64)
    if (cols[1] - cols[0] + 1) * (rows[1] - rows[0] + 1) <= len(keys):
        cc, rr = np.meshgrid(np.arange(cols[0], cols[1] + 1), np.arange(rows[0], rows[1] + 1))
        found = tile_lookup(grid, keys, ids, cc.ravel(), rr.ravel())
        return np.sort(found[found >= 0])
    r, c = np.divmod(keys, grid.cols)
    return np.sort(ids[(c >= cols[0]) & (c <= cols[1]) & (r >= rows[0]) & (r <= rows[1])])


MIN_POINTS_PER_TILE = 1000      # a tile size giving (many) fewer points per tile is refused


def _box_cells(grid: CoreGrid, f: CatalogFile) -> int:
    cols, rows = grid.cells([f.bounds[0], f.bounds[2]], [f.bounds[1], f.bounds[3]])
    cols, rows = np.clip(cols, 0, grid.cols - 1), np.clip(rows, 0, grid.rows - 1)
    return int((cols[1] - cols[0] + 1) * (rows[1] - rows[0] + 1))


def scan_cells(f: CatalogFile, grid: CoreGrid) -> np.ndarray:
    """Keys of the core cells the points of a file occupy (one streaming pass over the file)."""
    from roadx_ti import io

    found = []
    for x, y in io.iter_xy(f.path):
        col, row = grid.cells(x, y)
        col, row = np.clip(col, 0, grid.cols - 1), np.clip(row, 0, grid.rows - 1)
        found.append(np.unique(grid.key(col, row)))
    return np.unique(np.concatenate(found)) if found else np.zeros(0, np.int64)


# --------------------------------------------------------------------------------- one tile

@dataclass
class TileJob:
    """Everything a worker needs (picklable; files are read by the worker from their paths)."""
    tile: Tile
    paths: dict            # catalog index -> path, for the tile's files
    grid: CoreGrid         # the plan's core cells
    neighbour_cells: dict  # neighbour tile index -> (col, row) of its core
    windows: dict          # neighbour tile index -> its window
    read_origin: np.ndarray
    stage_specs: list
    backend: str
    threads: int | None
    seed: int
    survey_z_min: float = math.inf   # world: the lowest header z of the catalog (cloth start)
    survey_points: int = 0           # points of the catalog (a tile of a stray point sees it isolated)
    survey_estimates: dict | None = None   # roadx_ti.estimates of the whole catalog, for 'auto' options


@dataclass
class FilePart:
    """Labels of one file's core points in one tile, in file order."""
    classification: np.ndarray
    decided_by: np.ndarray
    segment_id: np.ndarray    # local to the tile
    processed: np.ndarray


@dataclass
class TileResult:
    index: int
    parts: dict               # catalog index -> FilePart
    segments: int             # local segment ids are 0..segments-1
    buffer_in: dict = field(default_factory=dict)   # neighbour -> seg ids of my buffer points in its core
    core_in: dict = field(default_factory=dict)     # neighbour -> seg ids of my core points in its window
    points_read: int = 0
    points_core: int = 0
    read_seconds: float = 0.0
    pipeline_seconds: float = 0.0
    seconds: float = 0.0
    worker: str = ""
    stages: list = field(default_factory=list)


def _world_xy(cloud: Cloud) -> tuple[np.ndarray, np.ndarray]:
    """float64 x, y exactly as io.read's bounds test saw them."""
    if cloud.las is not None:
        return np.asarray(cloud.las.x, np.float64), np.asarray(cloud.las.y, np.float64)
    return (cloud.xyz[:, 0].astype(np.float64) + cloud.origin[0],
            cloud.xyz[:, 1].astype(np.float64) + cloud.origin[1])


def concat_clouds(clouds: list[Cloud], origin: np.ndarray) -> Cloud:
    """One processing cloud from several files' windows (same origin); colour only when all have it."""
    if len(clouds) == 1:
        return clouds[0]
    rgb = None
    if all(c.rgb is not None for c in clouds):
        deep = max(c.color_depth for c in clouds)
        rgb = np.concatenate([c.rgb.astype(np.uint16) * np.uint16(257 if deep == 16 and c.color_depth == 8 else 1)
                              for c in clouds])
    pick = lambda name: (np.concatenate([getattr(c, name) for c in clouds])  # noqa: E731
                         if all(getattr(c, name) is not None for c in clouds) else None)
    return Cloud(xyz=np.concatenate([c.xyz for c in clouds]), origin=origin, rgb=rgb,
                 color_depth=max(c.color_depth for c in clouds) if rgb is not None else 0,
                 intensity=pick("intensity"), classification=pick("classification"),
                 returns=pick("returns"), nir=pick("nir"), source="+".join(c.source for c in clouds))


def _inside(x, y, box) -> np.ndarray:
    return (x >= box[0]) & (x < box[2]) & (y >= box[1]) & (y < box[3])


_M_MMAP_THRESHOLD = -3           # glibc mallopt parameter
MMAP_THRESHOLD = 64 * 1024       # bytes: larger blocks are mmapped, and unmapped when freed


def _large_buffers_back_to_os() -> None:
    """Serve blocks above MMAP_THRESHOLD from mmap, so that a tile's large arrays go back to the OS
    when the tile ends. glibc's adaptive threshold otherwise grows past the sizes freed, keeps
    later ones in the heap, and the next tiles fragment it: on the 16 M benchmark (2 M-point
    tiles) the peak RSS went from 675 to about 520 MB, the untiled run's stayed 1745 MB. glibc only;
    process-wide (also for a host program that runs tiles in-process), harmless elsewhere."""
    try:
        ctypes.CDLL(None).mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    except (OSError, AttributeError):
        pass


def run_tile(job: TileJob) -> TileResult:
    """Read the tile's window from its files, run the pipeline, keep the core points' labels.
    Runs in any process: Taichi is started once per process (backend.init is idempotent)."""
    from roadx_ti import backend, io, pipelines
    from roadx_ti.stages.base import StageContext

    _large_buffers_back_to_os()
    t_start = time.perf_counter()
    tile = job.tile
    pieces, xs, ys, owners = [], [], [], []
    for k in tile.files:
        piece = io.read(job.paths[k], bounds=tile.window, origin=job.read_origin)
        if piece.n:
            x, y = _world_xy(piece)
            piece.las = None           # the record is not needed for processing; free it
            pieces.append(piece)
            xs.append(x)
            ys.append(y)
            owners.append(k)
    read_s = time.perf_counter() - t_start
    result = TileResult(index=tile.index, parts={}, segments=0, read_seconds=read_s,
                        worker=f"{socket.gethostname()}:{os.getpid()}")
    if not pieces:
        result.seconds = time.perf_counter() - t_start
        return result
    counts = [p.n for p in pieces]
    cloud = concat_clouds(pieces, job.read_origin)
    x, y = np.concatenate(xs), np.concatenate(ys)
    del pieces, xs, ys
    if not backend.is_initialized():
        backend.init(job.backend, threads=job.threads)
    t0 = time.perf_counter()
    ctx = StageContext(seed=job.seed)
    if math.isfinite(job.survey_z_min):
        # the cloth of every tile starts where the whole survey's would (stages/cloth.py)
        ctx.facts[SURVEY_Z_MIN] = job.survey_z_min - float(job.read_origin[2])
    ctx.facts[SURVEY_POINTS] = job.survey_points
    if job.survey_estimates is not None:
        ctx.facts[ESTIMATES] = dict(job.survey_estimates)   # every tile the survey's values
    labels = pipelines.run(cloud, pipelines.build_stages(job.stage_specs), ctx=ctx)
    result.pipeline_seconds = time.perf_counter() - t0
    result.stages = [{k: r[k] for k in ("stage", "points_in", "points_out", "seconds")} for r in labels.stages]
    n = cloud.n
    del cloud
    col, row = job.grid.cells(x, y)
    core = (col == tile.col) & (row == tile.row)
    sizes = np.cumsum([0] + counts)
    for k, lo, hi in zip(owners, sizes[:-1], sizes[1:]):
        keep = np.flatnonzero(core[lo:hi]) + lo
        result.parts[k] = FilePart(labels.classification[keep], labels.decided_by[keep],
                                   labels.segment_id[keep], labels.processed[keep])
    result.points_read = int(n)
    result.points_core = int(core.sum())
    seg = labels.segment_id
    result.segments = int(seg.max()) + 1 if n else 0
    if result.segments:
        # points of the buffer that are a neighbour's core points, and my core points in its
        # window: the neighbour holds the same two sets, in the same order, from its side
        for u in tile.neighbours:
            u_col, u_row = job.neighbour_cells[u]
            result.buffer_in[u] = seg[(col == u_col) & (row == u_row)]
            result.core_in[u] = seg[core & _inside(x, y, job.windows[u])]
    result.seconds = time.perf_counter() - t_start
    return result


# -------------------------------------------------------------------------------- executors

def backend_ready() -> bool:
    from roadx_ti import backend
    return backend.is_initialized()


def make_jobs(plan: TilePlan, files: list[CatalogFile], stage_specs, *, backend: str,
              threads: int | None, seed: int, survey_estimates: dict | None = None) -> list[TileJob]:
    survey_z_min = min((f.z_range[0] for f in files if f.count), default=math.inf)
    return [TileJob(tile=t, paths={k: os.path.abspath(files[k].path) for k in t.files}, grid=plan.grid,
                    neighbour_cells={u: (plan.tiles[u].col, plan.tiles[u].row) for u in t.neighbours},
                    windows={u: plan.tiles[u].window for u in t.neighbours}, read_origin=plan.read_origin,
                    stage_specs=list(stage_specs), backend=backend, threads=threads, seed=seed,
                    survey_z_min=survey_z_min, survey_points=sum(f.count for f in files),
                    survey_estimates=survey_estimates)
            for t in plan.tiles]


def _failure(tile: Tile, exc: BaseException, attempts: int) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if len(text) > 400:          # e.g. Taichi compile errors quote whole functions
        text = text[:400] + " ..."
    core = ", ".join(f"{v:.2f}" for v in tile.core)
    return (f"tile ({tile.col}, {tile.row}) with core bounds ({core}) failed after {attempts} "
            f"attempt(s): {type(exc).__name__}: {text}; no output was written")


def run_in_process(jobs: list[TileJob], on_done) -> None:
    """Tiles one after the other in this process (no cluster)."""
    for job in jobs:
        try:
            result = run_tile(job)
        except Exception as exc:
            raise TileError(_failure(job.tile, exc, 1)) from exc
        on_done(result)


def run_on_dask(client, jobs: list[TileJob], on_done, *, in_flight: int) -> None:
    """Tiles on a dask.distributed cluster, at most ``in_flight`` submitted at once; each tile is
    retried RETRIES times (a tile on a worker that dies is rescheduled by Dask on another)."""
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    pending = iter(jobs)
    running = {}
    done = as_completed()

    def submit():
        job = next(pending, None)
        if job is not None:
            fut = client.submit(run_tile, job, retries=RETRIES, pure=False,
                                key=f"roadx-tile-{job.tile.col}-{job.tile.row}-{token}")
            running[fut] = job
            done.add(fut)

    for _ in range(max(1, in_flight)):
        submit()
    from concurrent.futures import CancelledError

    try:
        for fut in done:
            job = running.pop(fut)
            if fut.status != "finished":
                exc = fut.exception()
                raise TileError(_failure(job.tile, exc, RETRIES + 1))
            result = fut.result()
            fut.release()
            on_done(result)
            submit()
    except (OSError, TimeoutError, CancelledError) as exc:
        raise ClusterError(f"lost the Dask cluster during the run ({type(exc).__name__}: "
                           f"{' '.join(str(exc).split())[:200]}); no output was written") from None
    finally:
        if running:
            with contextlib.suppress(Exception):
                client.cancel(list(running))


def environment() -> dict:
    """The versions a worker must share with the client: roadx_ti, Python (major.minor), the Taichi
    distribution and version, and ENVIRONMENT_PACKAGES. Runs on every worker (Client.run)."""
    import importlib.metadata as metadata

    import roadx_ti
    from roadx_ti.kernels import taichi_compat

    env = {"roadx_ti": roadx_ti.__version__, "python": "%d.%d" % sys.version_info[:2],
           taichi_compat.DISTRIBUTION: ".".join(map(str, taichi_compat.ti.__version__))}
    for name in ENVIRONMENT_PACKAGES:
        try:
            env[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            env[name] = None
    return env


def unreadable(paths) -> list:
    """[(path, problem)] of the input files this process cannot read (runs on every worker)."""
    problems = []
    for p in paths:
        try:
            with open(p, "rb") as f:
                f.read(1)
        except OSError as exc:
            problems.append((p, exc.strerror or type(exc).__name__))
    return problems


def _reachable(address: str, timeout: float) -> None:
    """A plain TCP connection to a tcp:// scheduler address, so that a closed port or an unknown
    host fails at once instead of after the client's retries."""
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return
    parts = urlsplit(address)
    try:
        port = parts.port
    except ValueError:
        raise ClusterError(f"--scheduler {address}: not a tcp://HOST:PORT address") from None
    if not parts.hostname or port is None:
        raise ClusterError(f"--scheduler {address}: not a tcp://HOST:PORT address")
    try:
        socket.create_connection((parts.hostname, port), timeout=timeout).close()
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise ClusterError(f"cannot reach the Dask scheduler at {address} ({why}); start `dask scheduler` "
                           "there, or run without --scheduler") from None


class _DaskSession:
    """A client on an existing scheduler, or on a LocalCluster of worker processes we own.
    Before any tile: the scheduler is reached within CONNECT_TIMEOUT, a worker joins within
    WORKER_TIMEOUT, every worker runs the client's environment and can read every input."""

    def __init__(self, workers: int | None, scheduler: str | None, log, inputs=(),
                 connect_timeout: float = CONNECT_TIMEOUT, worker_timeout: float = WORKER_TIMEOUT):
        from distributed import Client, LocalCluster

        self.cluster = None
        self.client = None
        if scheduler:
            _reachable(scheduler, connect_timeout)
            try:
                self.client = Client(scheduler, timeout=f"{connect_timeout}s")
            except (OSError, TimeoutError) as exc:
                raise ClusterError(f"cannot connect to the Dask scheduler at {scheduler} within "
                                   f"{connect_timeout:g} s ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
                                   ) from None
            try:
                self.client.wait_for_workers(1, timeout=worker_timeout)
            except (OSError, TimeoutError):
                self.close()
                raise ClusterError(f"the Dask scheduler at {scheduler} has no worker after {worker_timeout:g} s; "
                                   f"start one with `dask worker {scheduler}`") from None
            self.kind = "scheduler"
        else:
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=logging.WARNING)
            self.client = Client(self.cluster)
            self.kind = "local-cluster"
        try:
            self._check_workers(inputs)
        except BaseException:
            self.close()
            raise
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        log.info("Dask %s at %s with %d worker(s)", self.kind, self.client.scheduler.address, self.workers)

    def _check_workers(self, inputs):
        mine = environment()
        theirs = self.client.run(environment, on_error="return")
        for worker, env in sorted(theirs.items()):
            if isinstance(env, BaseException):
                raise ClusterError(f"Dask worker {worker} cannot run roadx_ti ({type(env).__name__}: "
                                   f"{' '.join(str(env).split())[:200]}); install the client's roadx_ti "
                                   "environment on every worker")
            differ = [f"{k} {env.get(k)} (here {v})" for k, v in mine.items() if env.get(k) != v]
            if differ:
                raise ClusterError(f"Dask worker {worker} runs {', '.join(differ)}; every worker needs the "
                                   "client's environment (the same roadx_ti, Python and package versions)")
        if inputs:
            problems = self.client.run(unreadable, list(inputs), on_error="return")
            for worker, found in sorted(problems.items()):
                if isinstance(found, BaseException):
                    raise ClusterError(f"Dask worker {worker} cannot check the inputs ({type(found).__name__}: "
                                       f"{' '.join(str(found).split())[:200]})")
                if found:
                    path, why = found[0]
                    more = f" (and {len(found) - 1} more input(s))" if len(found) > 1 else ""
                    raise ClusterError(f"Dask worker {worker} cannot read {path} ({why}){more}; every input "
                                       "must be readable under the same absolute path on every worker")

    def close(self):
        if self.client is not None:
            with contextlib.suppress(Exception):
                self.client.close()
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()


class _Progress:
    """A tqdm bar on a terminal, log lines otherwise (nothing when disabled)."""

    def __init__(self, total: int, enabled: bool, log):
        self.total, self.enabled, self.log, self.count = total, enabled, log, 0
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm
            self.bar = tqdm(total=total, unit="tile", file=sys.stderr, leave=False)

    def step(self, tile: Tile, result: TileResult):
        self.count += 1
        if self.bar is not None:
            self.bar.update(1)
        elif self.enabled:
            self.log.info("tile %d/%d (%d, %d): %d points read, %d core, %.2f s on %s", self.count,
                          self.total, tile.col, tile.row, result.points_read, result.points_core,
                          result.seconds, result.worker)

    def close(self):
        if self.bar is not None:
            self.bar.close()


# ----------------------------------------------------------------------------- reconciliation

def reconcile_segments(plan: TilePlan, results: dict) -> dict:
    """Give segments cut by core borders one id: union-find over (tile, local segment) nodes that
    share a point (labelled in both tiles), then compact global ids in tile order. Rewrites the
    parts' segment ids in place; returns counts for the summary."""
    base, total = {}, 0
    for t in range(len(plan.tiles)):
        base[t] = total
        total += results[t].segments
    parent = np.arange(total, dtype=np.int64)

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    links = 0
    for t, res in results.items():
        for u, mine in res.buffer_in.items():
            other = results[u].core_in.get(t)
            if other is None:       # the neighbour found no segments at all
                continue
            if len(other) != len(mine):
                raise TileError(f"tiles {t} and {u} disagree on the points they share "
                                f"({len(mine)} vs {len(other)}); no output was written")
            both = (mine >= 0) & (other >= 0)
            pairs = np.unique(np.column_stack([base[t] + mine[both], base[u] + other[both]]), axis=0)
            for a, b in pairs:
                ra, rb = find(a), find(b)
                if ra != rb:
                    parent[max(ra, rb)] = min(ra, rb)
                    links += 1
    global_id = {}
    for t in range(len(plan.tiles)):
        res = results[t]
        if not res.segments:
            continue
        local_to_global = np.full(res.segments, -1, np.int32)
        used = np.unique(np.concatenate([p.segment_id for p in res.parts.values()] or [np.zeros(0, np.int32)]))
        for s in used[used >= 0]:
            root = find(base[t] + int(s))
            local_to_global[s] = global_id.setdefault(root, len(global_id))
        for part in res.parts.values():
            seg = part.segment_id
            part.segment_id = np.where(seg >= 0, local_to_global[np.maximum(seg, 0)], -1).astype(np.int32)
        res.buffer_in, res.core_in = {}, {}
    return {"local_segments": total, "merges": links, "segments": len(global_id)}


# ------------------------------------------------------------------------------------- merge

class _Merge:
    """Hands out each input point's labels from its core tile, in file order, and keeps counts."""

    def __init__(self, plan: TilePlan, results: dict, files: list[CatalogFile], truth_classes, target: int):
        self.plan, self.results, self.files = plan, results, files
        self.cursor = {}
        self.truth_classes, self.target = truth_classes, target
        self.class_counts = np.zeros(256, np.int64)
        self.truth, self.pred = [], []
        self.written = 0

    def labels(self, k: int, x: np.ndarray, y: np.ndarray, input_classes=None):
        n = len(x)
        tiles = self.plan.tile_index(x, y)
        if (tiles < 0).any():
            raise TileError(f"{self.files[k].path}: {int((tiles < 0).sum())} points lie outside the "
                            "header bounds, so no tile read them; fix the header (e.g. pdal translate)")
        out = (np.empty(n, np.uint8), np.empty(n, np.uint8), np.empty(n, np.int32), np.empty(n, bool))
        order = np.argsort(tiles, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(tiles[order]) != 0])
        ends = np.r_[starts[1:], n]
        for s, e in zip(starts, ends):
            t = int(tiles[order[s]])
            part = self.results[t].parts.get(k)
            c = self.cursor.get((t, k), 0)
            if part is None or c + (e - s) > len(part.classification):
                raise TileError(f"{self.files[k].path}: tile {t} returned fewer core points than the "
                                "file holds in its core; no output was written")
            idx = order[s:e]
            for dst, src in zip(out, (part.classification, part.decided_by, part.segment_id, part.processed)):
                dst[idx] = src[c:c + e - s]
            self.cursor[(t, k)] = c + e - s
        self.class_counts += np.bincount(out[0], minlength=256)
        if input_classes is not None and self.truth_classes:
            from roadx_ti.metrics import class_mask
            self.truth.append(class_mask(input_classes, self.truth_classes))
            self.pred.append(out[0] == self.target)
        return out

    def check_file(self, k: int, seen: int) -> None:
        """Every point of file k was handed out exactly once and every core point returned used."""
        if seen != self.files[k].count:
            raise TileError(f"{self.files[k].path}: read {seen} points, the header says {self.files[k].count}")
        for t, res in self.results.items():
            part = res.parts.get(k)
            if part is not None and self.cursor.get((t, k), 0) != len(part.classification):
                raise TileError(f"{self.files[k].path}: tile {t} returned {len(part.classification)} core "
                                f"points, the file has {self.cursor.get((t, k), 0)} there")


def _is_las(path) -> bool:
    return Path(path).suffix.lower() in (".las", ".laz")


def _write_las_stream(out: Path, file_ids, merge: _Merge, processed_only: bool) -> int:
    """Stream the files' points (their LAS records, bit-exact but classification and the result
    dimensions) into one LAS/LAZ written atomically; returns the number of points written."""
    import laspy

    from roadx_ti import io
    from roadx_ti.io import las as io_las

    def record(k, header, chunk, labels):
        cls, dec, seg, proc = labels
        return io_las._las_from_record(out, laspy.LasData(header, chunk), len(chunk), cls,
                                       {"roadx_label": dec, "segment_id": seg},
                                       proc if processed_only else None)

    written = 0
    with io.atomic_output(out) as tmp:
        writer = None
        try:
            for k in file_ids:
                seen = 0
                with laspy.open(merge.files[k].path) as reader:
                    header = copy.deepcopy(reader.header)
                    if writer is None:    # the first file's header, with the result dimensions
                        empty = laspy.ScaleAwarePointRecord.zeros(0, header=header)
                        first = record(k, header, empty, (np.zeros(0, np.uint8), np.zeros(0, np.uint8),
                                                          np.zeros(0, np.int32), np.zeros(0, bool)))
                        writer = laspy.open(tmp, mode="w", header=first.header,
                                            do_compress=out.suffix.lower() == ".laz")
                    for chunk in reader.chunk_iterator(MERGE_CHUNK_POINTS):
                        seen += len(chunk)
                        labels = merge.labels(k, np.asarray(chunk.x), np.asarray(chunk.y),
                                              np.asarray(chunk.classification))
                        las = record(k, header, chunk, labels)
                        try:
                            writer.write_points(las.points)
                        except laspy.errors.LaspyException as exc:
                            raise io.InputError(f"{merge.files[k].path}: cannot be merged with "
                                                f"{merge.files[file_ids[0]].path} ({exc}: point formats "
                                                "differ); use output.mode per-file") from None
                        written += len(las.points)
                merge.check_file(k, seen)
        finally:
            if writer is not None:
                writer.close()
        io_las.check_written(out, tmp)
    return written


def _write_generic(out: Path, file_ids, merge: _Merge, processed_only: bool) -> int:
    """Any other format: whole files in memory, written with io.write."""
    from roadx_ti import io

    clouds, labels = [], []
    for k in file_ids:
        cloud = io.read(merge.files[k].path, origin=merge.plan.read_origin)
        x, y = _world_xy(cloud)
        labels.append(merge.labels(k, x, y, cloud.classification))
        merge.check_file(k, cloud.n)
        clouds.append(cloud)
    cloud = concat_clouds(clouds, merge.plan.read_origin)
    cls, dec, seg, proc = (np.concatenate(parts) for parts in zip(*labels))
    io.write(out, cloud, classification=cls, extra_dims={"roadx_label": dec, "segment_id": seg},
             subset=proc if processed_only else None)
    return int(proc.sum()) if processed_only else cloud.n


def write_outputs(plan, results, files, outputs: list[tuple[Path, list[int]]], *, processed_only: bool,
                  truth_classes, target: int) -> tuple[int, _Merge]:
    merge = _Merge(plan, results, files, truth_classes, target)
    written = 0
    for out, file_ids in outputs:
        stream = _is_las(out) and all(_is_las(files[k].path) for k in file_ids)
        written += (_write_las_stream if stream else _write_generic)(out, file_ids, merge, processed_only)
    return written, merge


# ---------------------------------------------------------------------------------- entry point

def run_catalog(cfg, input_paths, output_path, *, workers: int | None = None, scheduler: str | None = None,
                tile_size: float | None = None, buffer: float | None = None, output_mode: str = "merged",
                progress: bool = True, log=None, summary_path=None) -> dict:
    """Run ``cfg``'s pipeline over a catalog of files in tiles with buffers and write the result.

    input_paths: files and/or folders (catalog order = input order). output_path: the merged
    LAS/LAZ (output_mode 'merged'), or a folder receiving one file per input under the input's
    name ('per-file'). workers: start a local Dask cluster of that many processes; scheduler:
    'tcp://HOST:PORT' of an existing one; neither: tiles run one by one in this process.
    tile_size (m): core tile edge (None: about TARGET_TILE_POINTS points per tile; inf: untiled);
    buffer (m): None derives it from the stages' reach (stage_reach). The summary (returned and
    written to summary_path, default '<output stem>.summary.json' or '<folder>/summary.json')
    holds the plan, per-tile timings and counts. Raises TileError (nothing written) when a tile
    fails after its retries."""
    from roadx_ti import __version__, io, jsonio, pipelines
    from roadx_ti.config import PIPELINE_TARGET

    log = log or log_default
    t_start = time.perf_counter()
    if output_mode not in MODES:
        raise ValueError(f"output mode must be one of {', '.join(MODES)}, got {output_mode!r}")
    if workers is not None and scheduler:
        raise ValueError("give workers (a local cluster) or scheduler (an existing one), not both")
    if workers is not None and int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    files = catalog(input_paths)
    total_points = sum(f.count for f in files)
    if total_points == 0:
        raise io.InputError(f"the inputs hold no points: {', '.join(f.path for f in files)}")
    stage_specs = cfg.stage_list() or pipelines.default_stage_specs(cfg.pipeline)
    auto_buffer, reaches = default_buffer(stage_specs)
    buffer = auto_buffer if buffer is None else float(buffer)
    tile_size = default_tile_size(files) if tile_size is None else float(tile_size)
    plan = plan_tiles(files, tile_size, buffer, scan=scan_cells)
    if len(plan.tiles) > max(64, total_points // MIN_POINTS_PER_TILE):
        raise ValueError(f"--tile-size {tile_size:g} gives {len(plan.tiles):,} tiles for {total_points:,} points, "
                         f"fewer than {MIN_POINTS_PER_TILE} per tile (each tile reads its files): use a larger "
                         f"tile size, e.g. {default_tile_size(files):g} m")

    inputs = [f.path for f in files]
    if output_mode == "merged":
        out = Path(output_path)
        out.parent.mkdir(parents=True, exist_ok=True)
        io.check_output_path(out, inputs)
        outputs = [(out, list(range(len(files))))]
        summary_path = Path(summary_path or out.with_suffix("").as_posix() + ".summary.json")
    else:
        folder = Path(output_path)
        folder.mkdir(parents=True, exist_ok=True)
        names = [Path(f.path).name for f in files]
        if len(set(names)) != len(names):
            raise io.InputError("per-file output needs distinct input file names; "
                                f"{len(names) - len(set(names))} repeat")
        outputs = [(folder / name, [k]) for k, name in enumerate(names)]
        for o, _ in outputs:
            io.check_output_path(o, inputs)
        summary_path = Path(summary_path or folder / "summary.json")

    log.info("%d file(s), %d points; %d tile(s) of %s m with a %.1f m buffer", len(files), total_points,
             len(plan.tiles), "all" if not np.isfinite(plan.tile_size) else f"{plan.tile_size:g}", plan.buffer)
    results: dict[int, TileResult] = {}
    bar = _Progress(len(plan.tiles), progress, log)

    def on_done(result: TileResult):
        results[result.index] = result
        bar.step(plan.tiles[result.index], result)

    from roadx_ti.estimates import measure_catalog

    t_est = time.perf_counter()
    if not backend_ready():
        from roadx_ti import backend
        backend.init(cfg.backend, threads=cfg.threads)
    survey = measure_catalog(files, plan.read_origin)
    estimate_s = time.perf_counter() - t_est
    log.info("survey estimates (%d sampled points) in %.2f s: %s", survey.get("sample_points", 0), estimate_s,
             {k: v for k, v in survey.items() if k not in ("sample_points",)})
    t_tiles = time.perf_counter()
    session = None
    try:
        if workers is None and not scheduler:
            executor, n_workers = "in-process", 1
            jobs = make_jobs(plan, files, stage_specs, backend=cfg.backend, threads=cfg.threads, seed=cfg.seed,
                             survey_estimates=survey)
            run_in_process(jobs, on_done)
        else:
            session = _DaskSession(workers, scheduler, log, inputs=[os.path.abspath(f.path) for f in files],
                                   connect_timeout=cfg.executor.connect_timeout,
                                   worker_timeout=cfg.executor.worker_timeout)
            executor, n_workers = session.kind, session.workers
            # one Taichi runtime per worker process; CPU unless the config names a backend
            threads = cfg.threads or (max(1, (os.cpu_count() or 1) // int(workers)) if workers else None)
            jobs = make_jobs(plan, files, stage_specs, backend="cpu" if cfg.backend == "auto" else cfg.backend,
                             threads=threads, seed=cfg.seed, survey_estimates=survey)
            run_on_dask(session.client, jobs, on_done, in_flight=2 * n_workers)
    finally:
        bar.close()
        if session is not None:
            session.close()
    tiles_s = time.perf_counter() - t_tiles

    t_merge = time.perf_counter()
    segments = reconcile_segments(plan, results)
    target = PIPELINE_TARGET[cfg.pipeline]
    written, merge = write_outputs(plan, results, files, outputs, processed_only=cfg.output.points == "processed",
                                   truth_classes=cfg.truth_classes, target=target)
    merge_s = time.perf_counter() - t_merge

    summary = {
        "roadx_ti": __version__, "pipeline": cfg.pipeline, "executor": executor, "workers": n_workers,
        "scheduler": scheduler, "output_mode": output_mode,
        "inputs": [{"path": f.path, "points": f.count, "bounds": list(f.bounds)} for f in files],
        "outputs": [str(o) for o, _ in outputs], "points": total_points, "points_written": written,
        "tiling": plan.describe() | {"buffer_from_stages": reaches},
        "estimates": survey,
        "segments": segments,
        "target_class": target, "target_points": int(merge.class_counts[target]),
        "class_counts": {str(c): int(v) for c, v in enumerate(merge.class_counts) if v},
        "seconds": {"estimates": round(estimate_s, 4), "tiles": round(tiles_s, 4), "merge": round(merge_s, 4),
                    "total": round(time.perf_counter() - t_start, 4),
                    "tile_sum": round(sum(r.seconds for r in results.values()), 4)},
        "tiles": [{"tile": [t.col, t.row], "core": list(t.core), "window": list(t.window),
                   "files": [Path(files[k].path).name for k in t.files],
                   "points_read": results[t.index].points_read, "points_core": results[t.index].points_core,
                   "read_seconds": round(results[t.index].read_seconds, 4),
                   "pipeline_seconds": round(results[t.index].pipeline_seconds, 4),
                   "seconds": round(results[t.index].seconds, 4), "worker": results[t.index].worker}
                  for t in plan.tiles],
    }
    truth = np.concatenate(merge.truth) if merge.truth else None
    if truth is not None and truth.any():
        from roadx_ti.metrics import scores
        summary["truth_classes"] = cfg.truth_classes
        summary["accuracy"] = scores(truth, np.concatenate(merge.pred))
    summary["summary_path"] = str(summary_path)
    jsonio.write(summary_path, summary)
    log.info("wrote %s (%d points, %d tiles, %s) in %.2f s", ", ".join(summary["outputs"][:3])
             + (" ..." if len(outputs) > 3 else ""), written, len(plan.tiles), executor,
             time.perf_counter() - t_start)
    return summary


# --------------------------------------------------------------------------- tiled vs untiled

DISTANCE_BINS = (0.0, 1.0, 2.0, 5.0, 10.0, 20.0, math.inf)


def _border_distance(grid: CoreGrid, x, y) -> np.ndarray:
    col, row = grid.cells(x, y)
    col, row = np.clip(col, 0, grid.cols - 1), np.clip(row, 0, grid.rows - 1)
    return np.minimum.reduce([x - grid.x_edge(col), grid.x_edge(col + 1) - x,
                              y - grid.y_edge(row), grid.y_edge(row + 1) - y])


def segment_agreement(a: np.ndarray, b: np.ndarray) -> float:
    """Share of the points segmented in ``a`` whose ``b`` id is the one most of their ``a``
    segment has (1.0: every ``a`` segment is whole in ``b``); ids are arbitrary labels."""
    sel = a >= 0
    if not sel.any():
        return 1.0
    pairs, counts = np.unique(np.column_stack([a[sel], b[sel]]), axis=0, return_counts=True)
    best = np.zeros(int(a.max()) + 1, np.int64)
    np.maximum.at(best, pairs[:, 0], counts)
    return float(best.sum() / sel.sum())


def compare_outputs(tiled_summary: dict, tiled_output, reference_output, *, summary_path=None) -> dict:
    """Tiled vs reference (untiled) labels of the same points (merged outputs, same order):
    disagreements counted and located by their distance to the nearest core border, and the
    segment partitions compared. Added to the summary JSON as 'comparison' when summary_path is given."""
    from roadx_ti import io, jsonio

    a, b = io.read(tiled_output), io.read(reference_output)
    if a.n != b.n:
        raise ValueError(f"{tiled_output} has {a.n} points, {reference_output} {b.n}")
    xa, ya = _world_xy(a)
    xb, yb = _world_xy(b)
    if not (np.array_equal(xa, xb) and np.array_equal(ya, yb)):
        raise ValueError("the outputs do not hold the same points in the same order")
    differ = a.classification != b.classification
    tiling = tiled_summary["tiling"]
    grid = CoreGrid(**tiling["grid"])
    dist = _border_distance(grid, xa[differ], ya[differ])
    hist, _ = np.histogram(dist, bins=DISTANCE_BINS)
    seg_a = np.asarray(a.las["segment_id"], np.int64)
    seg_b = np.asarray(b.las["segment_id"], np.int64)
    crossing, whole = 0, 0
    if (seg_b >= 0).any():
        # reference segments spread over several cores: are they one segment in the tiled run?
        cell = np.column_stack(grid.cells(xb, yb))
        for s in np.unique(seg_b[seg_b >= 0]):
            sel = seg_b == s
            if len(np.unique(cell[sel], axis=0)) > 1:
                crossing += 1
                ids, counts = np.unique(seg_a[sel], return_counts=True)
                whole += int(counts.max() >= 0.99 * sel.sum() and ids[counts.argmax()] >= 0)
    comparison = {
        "points": int(a.n), "disagreements": int(differ.sum()),
        "agreement": float(1.0 - differ.mean()) if a.n else 1.0,
        "disagreements_by_border_distance_m": {
            f"{lo:g}-{hi:g}": int(h) for lo, hi, h in zip(DISTANCE_BINS[:-1], DISTANCE_BINS[1:], hist)},
        "disagreement_max_border_distance_m": float(dist.max()) if len(dist) else None,
        "segment_agreement": min(segment_agreement(seg_b, seg_a), segment_agreement(seg_a, seg_b)),
        "reference_segments_crossing_borders": crossing, "crossing_segments_kept_whole": whole,
        "reference": str(reference_output),
    }
    if summary_path is not None:
        summary = dict(tiled_summary) | {"comparison": comparison}
        jsonio.write(summary_path, summary)
    return comparison
