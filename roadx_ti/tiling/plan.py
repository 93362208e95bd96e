"""The tile plan: a grid of half-open core tiles anchored at multiples of the tile size, each read
with a buffer, where the catalog's files (or, for a stray-stretched header box, their points) are."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from roadx_ti.sorted_keys import find
from roadx_ti.tiling.catalogs import CatalogFile

TARGET_TILE_POINTS = 2_000_000   # smallest default core tile: about this many points
MAX_WINDOW_POINTS = 16_000_000   # default tiles: a window (core and buffer) of at most about this many
TILE_SIZE_STEP = 10.0            # default tile sizes are rounded to a multiple of this (m)


def _core_edge(points: float, density: float) -> float:
    """Edge (m) of a square holding about ``points`` at ``density``, rounded up to TILE_SIZE_STEP."""
    return TILE_SIZE_STEP * math.ceil(math.sqrt(points / max(density, 1e-6)) / TILE_SIZE_STEP)


def default_tile_size(files: list[CatalogFile], target_points: int = TARGET_TILE_POINTS) -> float:
    """Edge (m) of a square core holding about ``target_points`` at the catalog's mean density."""
    area = sum(max(f.bounds[2] - f.bounds[0], 1.0) * max(f.bounds[3] - f.bounds[1], 1.0) for f in with_points(files))
    return _core_edge(target_points, sum(f.count for f in files) / area)


def budget_tile_size(density: float, buffer: float, window_points: int) -> float:
    """Edge (m) of the largest core whose window (the core and ``buffer`` on every side) holds
    about ``window_points`` at ``density`` (points per m2 of occupied area), rounded down to
    TILE_SIZE_STEP, and never below a core of TARGET_TILE_POINTS: large tiles read fewer buffer
    points per core point (the window/core ratio falls from 2.4 at 110 m cores with 30 m buffers
    to 1.5 at 300 m)."""
    density = max(float(density), 1e-6)
    edge = math.sqrt(max(window_points, 1) / density) - 2.0 * buffer
    edge = TILE_SIZE_STEP * math.floor(edge / TILE_SIZE_STEP)
    return float(max(edge, _core_edge(TARGET_TILE_POINTS, density)))


# the planner's cost of a tile beyond its window's points (reading, the pipeline's fixed costs,
# the reconciliation), in points: a 0.17 M-point window of the uav-road survey took 1.3 s in all
# against about 2.2 us per point of larger windows (2026-12-06)
TILE_COST_POINTS = 400_000
PLAN_CELL = 5.0                   # m: the raster the planner counts window points on
ALIGN_STEPS = 8                   # grid offsets tried per axis (multiples of PLAN_CELL, spread over a tile)
SIZE_RANGE = (0.6, 1.5)           # tile sizes tried, as multiples of the density's size (TILE_SIZE_STEP apart)


def _window_points(ix, iy, counts, cell: float, size: float, ox: float, oy: float, buffer: float):
    """(sum of the windows' points, tiles, largest window) of the grid of cores ``size`` m anchored
    at (ox, oy) with ``buffer`` around each, from points per plan cell (ix, iy, counts; cell m,
    world). A tile exists where a core holds a point; a cell counts in every window it lies in
    (a window edge inside a cell counts the whole cell: an upper bound)."""
    lo_x, lo_y = ix * cell, iy * cell
    col = np.floor((lo_x + 0.5 * cell - ox) / size).astype(np.int64)
    row = np.floor((lo_y + 0.5 * cell - oy) / size).astype(np.int64)
    row_span = int(row.max() - row.min()) + 3
    key = (col - col.min() + 1) * row_span + (row - row.min() + 1)
    tiles, inverse = np.unique(key, return_inverse=True)
    window = np.zeros(len(tiles), np.int64)
    reach = int(math.ceil(buffer / size))
    for dc in range(-reach, reach + 1):
        c = col + dc
        in_x = (ox + c * size - buffer < lo_x + cell) & (lo_x < ox + (c + 1) * size + buffer)
        for dr in range(-reach, reach + 1):
            if dc == 0 and dr == 0:
                window += np.bincount(inverse.ravel(), weights=counts, minlength=len(tiles)).astype(np.int64)
                continue
            r = row + dr
            inside = in_x & (oy + r * size - buffer < lo_y + cell) & (lo_y < oy + (r + 1) * size + buffer)
            if not inside.any():
                continue
            k = key[inside] + dc * row_span + dr
            j = np.minimum(np.searchsorted(tiles, k), len(tiles) - 1)
            hit = tiles[j] == k
            window += np.bincount(j[hit], weights=counts[inside][hit], minlength=len(tiles)).astype(np.int64)
    return int(window.sum()), len(tiles), int(window.max())


def align_tiles(cells, tile_size: float, buffer: float, window_cap: int) -> tuple[float, tuple[float, float]]:
    """(core size, grid anchor) of the default tiles, placed by where the points are: among sizes
    around ``tile_size`` (TILE_SIZE_STEP apart, SIZE_RANGE of it) and grid offsets (ALIGN_STEPS per
    axis, on PLAN_CELL), the one that reads the fewest points (windows summed, plus TILE_COST_POINTS
    per tile) with no window over ``window_cap`` points. A grid anchored at multiples of the tile
    size cuts a survey where it happens to: on the uav-road survey six of twelve 200 m tiles held a
    sliver of core (0-286 points) and read 1.2-1.6 M points of buffer each. ``cells``: the survey's
    estimates.CellCounts. Ties go to the larger size, then the smaller offsets (deterministic)."""
    if not len(cells.counts) or not math.isfinite(tile_size):
        return tile_size, (0.0, 0.0)
    plan = cells.coarsened(max(1, int(round(PLAN_CELL / cells.cell))))     # the planner's raster
    ix, iy, counts, cell = plan.ix, plan.iy, plan.counts, plan.cell
    lo = max(TILE_SIZE_STEP, TILE_SIZE_STEP * math.floor(SIZE_RANGE[0] * tile_size / TILE_SIZE_STEP))
    hi = TILE_SIZE_STEP * math.floor(SIZE_RANGE[1] * tile_size / TILE_SIZE_STEP)
    best = None
    for size in np.arange(hi, lo - 0.5 * TILE_SIZE_STEP, -TILE_SIZE_STEP):
        size = float(size)
        step = cell * max(1, round(size / ALIGN_STEPS / cell))
        offsets = sorted({float(step * k) % size for k in range(ALIGN_STEPS)})
        for ox in offsets:
            for oy in offsets:
                total, tiles, largest = _window_points(ix, iy, counts, cell, size, ox, oy, buffer)
                if largest > window_cap:
                    continue
                cost = total + TILE_COST_POINTS * tiles
                if best is None or cost < best[0]:
                    best = (cost, size, (ox, oy))
    if best is None:
        return tile_size, (0.0, 0.0)
    return best[1], best[2]


def with_points(files: list[CatalogFile]) -> list[CatalogFile]:
    """The files that hold points (all of them when none does): an empty file's header box is
    (0, 0, 0) - (0, 0, 0) by laspy's default, and taken into the catalog's extent it put the
    shared origin millions of metres from the points, whose float32 coordinates lost their
    centimetres (spacing estimates 0, 11 % of a roof run's labels changed)."""
    return [f for f in files if f.count] or list(files)


def catalog_origin(files: list[CatalogFile]) -> np.ndarray:
    """The local origin every read of a run shares: the floor of the minimum corner of the
    catalog's files that hold points."""
    files = with_points(files)
    xmin = min(f.bounds[0] for f in files)
    ymin = min(f.bounds[1] for f in files)
    if not all(math.isfinite(v) for v in (xmin, ymin)):
        raise ValueError("the catalog's header bounds are not finite; fix the headers (e.g. pdal translate)")
    return np.array([math.floor(xmin), math.floor(ymin), 0.0])


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
        j, hit = find(keys, key)
        out[inside] = np.where(hit, ids[j], -1)
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


class TooManyTiles(ValueError):
    """The tile size gives more occupied tiles than ``plan_tiles``' ``max_tiles``: raised before
    the tiles' windows and neighbour lists are made (their cost grows with the tiles squared when
    the buffer spans many tiles: a 0.1 m tile size on a 25 m scene ran for minutes)."""

    def __init__(self, tiles: int, tile_size: float):
        self.tiles, self.tile_size = tiles, tile_size
        super().__init__(f"tile size {tile_size:g} m gives {tiles:,} tiles")


def plan_tiles(files: list[CatalogFile], tile_size: float, buffer: float, scan=None,
               max_tiles: int | None = None, anchor: tuple[float, float] = (0.0, 0.0)) -> TilePlan:
    """Core tiles of ``tile_size`` on a grid whose lines run through ``anchor`` (world x, y; by
    default at multiples of the tile size), each read with
    ``buffer`` on every side. ``tile_size`` = inf (or <= 0) gives one core over the whole catalog
    and no buffer: the untiled run, through the same code path.
    A tile exists where a file's header box meets its core; a file whose box meets more than
    SCAN_CELLS cores is scanned instead when ``scan`` is given (``scan(file, grid)`` -> keys of the
    cells its points occupy): stray points far off stretch a header box over thousands of empty
    tiles. Nothing is allocated per grid cell. ``max_tiles``: raise TooManyTiles when there are more
    occupied tiles."""
    held = with_points(files)
    xmin, ymin = min(f.bounds[0] for f in held), min(f.bounds[1] for f in held)
    xmax, ymax = max(f.bounds[2] for f in held), max(f.bounds[3] for f in held)
    if not all(math.isfinite(v) for v in (xmin, ymin, xmax, ymax)):
        raise ValueError("the catalog's header bounds are not finite; fix the headers (e.g. pdal translate)")
    read_origin = catalog_origin(files)
    if tile_size is None or not np.isfinite(tile_size) or tile_size <= 0:
        tile_size, buffer = math.inf, 0.0
        # header max is inclusive; +1 m keeps the last points inside the half-open core
        gx, gy = float(math.floor(xmin)), float(math.floor(ymin))
        grid = CoreGrid(gx, gy, float(math.floor(xmax) + 1.0) - gx, float(math.floor(ymax) + 1.0) - gy, 1, 1)
    else:
        tile_size = float(tile_size)
        ax, ay = (float(v) for v in anchor)
        x0 = ax + math.floor((xmin - ax) / tile_size) * tile_size
        y0 = ay + math.floor((ymin - ay) / tile_size) * tile_size
        cols = int(math.floor((xmax - x0) / tile_size)) + 1
        rows = int(math.floor((ymax - y0) / tile_size)) + 1
        if cols * rows >= 2**62:
            # cell keys (row * cols + col) beyond int64: a tile size of 1e-300
            raise TooManyTiles(cols * rows, tile_size)
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
    if max_tiles is not None and len(keys) > max_tiles:
        raise TooManyTiles(len(keys), tile_size)
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


def _border_distance(grid: CoreGrid, x, y) -> np.ndarray:
    col, row = grid.cells(x, y)
    col, row = np.clip(col, 0, grid.cols - 1), np.clip(row, 0, grid.rows - 1)
    return np.minimum.reduce([x - grid.x_edge(col), grid.x_edge(col + 1) - x,
                              y - grid.y_edge(row), grid.y_edge(row + 1) - y])
