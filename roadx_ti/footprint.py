"""Where the points are: occupied cells of an xy grid, the point density over them, and the part
of a cloud that is the scene (groups of cells far from the rest, e.g. a stray point kilometres
away, left out), so that rasters and pictures are sized by occupied space, not by a bounding box.

Density is points per occupied cell area: cells of DENSITY_CELL (map units, metres for a projected
CRS), doubled until the occupied ones hold MIN_POINTS_PER_CELL points on average (sparse data
would otherwise count the gaps between points as empty space). Spacing is 1 / sqrt(density).
Works chunk by chunk (``Occupancy.add``) for files read in pieces.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from roadx_ti.sorted_keys import find

DENSITY_CELL = 1.0          # first cell edge of the density estimate (map units)
MAX_DENSITY_CELL = 64.0     # coarsest cell tried
MIN_POINTS_PER_CELL = 4.0   # mean points per occupied cell that makes a cell size fit the data
STRAY_SHARE = 0.01          # a group of connected cells with less than this share of points is stray
REACH_CELLS = 2             # cells up to this many apart (Chebyshev) belong to one group
_BIAS = np.int64(2**31)


def _keys(ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
    return ((ix.astype(np.int64) + _BIAS) << np.int64(32)) | (iy.astype(np.int64) + _BIAS)


def _decode(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (keys >> np.int64(32)) - _BIAS, (keys & np.int64(0xFFFFFFFF)) - _BIAS


def cells(xy: np.ndarray, cell: float):
    """(sorted unique cell keys, cell of each point as an index into them, points per cell).
    A dense count over the cells' bounding box when it is not much larger than the points (no
    sort), else a sort of the points' cell keys."""
    ix = np.floor(xy[:, 0] / cell).astype(np.int64)
    iy = np.floor(xy[:, 1] / cell).astype(np.int64)
    x0, y0 = int(ix.min()), int(iy.min())
    w, h = int(ix.max()) - x0 + 1, int(iy.max()) - y0 + 1
    if w * h <= 16 * len(ix) + 2**20:
        linear = (ix - x0) * h + (iy - y0)
        dense = np.bincount(linear, minlength=w * h)
        occupied = np.flatnonzero(dense)
        compact = np.zeros(w * h, np.int64)
        compact[occupied] = np.arange(len(occupied))
        keys = _keys(occupied // h + x0, occupied % h + y0)   # ascending, like np.unique's
        return keys, compact[linear], dense[occupied]
    keys, inverse, counts = np.unique(_keys(ix, iy), return_inverse=True, return_counts=True)
    return keys, inverse.reshape(-1), counts


def _coarsen(keys: np.ndarray, counts: np.ndarray):
    """Cells of twice the edge: (keys, points per cell, coarse cell of each fine cell)."""
    ix, iy = _decode(keys)
    coarse, inverse = np.unique(_keys(ix >> 1, iy >> 1), return_inverse=True)
    inverse = inverse.reshape(-1)
    return coarse, np.bincount(inverse, weights=counts, minlength=len(coarse)).astype(np.int64), inverse


class Occupancy:
    """Points per occupied cell of DENSITY_CELL, accumulated over chunks of a file."""

    def __init__(self):
        self.keys = np.zeros(0, np.int64)
        self.counts = np.zeros(0, np.int64)

    def add(self, xy: np.ndarray) -> None:
        if len(xy) == 0:
            return
        keys, _, counts = cells(xy, DENSITY_CELL)
        if len(self.keys):
            keys, inverse = np.unique(np.concatenate([self.keys, keys]), return_inverse=True)
            counts = np.bincount(inverse.reshape(-1), weights=np.concatenate([self.counts, counts]),
                                 minlength=len(keys)).astype(np.int64)
        self.keys, self.counts = keys, counts

    def density(self) -> dict:
        """{'cell', 'occupied_area', 'density', 'spacing'} (None values without points)."""
        return _density(self.keys, self.counts, DENSITY_CELL)


def _density_cells(xy: np.ndarray):
    """(keys, cell of each point, points per cell, cell edge, _density's facts) of the occupied
    cells at the density estimate's cell."""
    keys, inverse, counts = cells(xy, DENSITY_CELL)
    facts = _density(keys, counts, DENSITY_CELL)
    cell = DENSITY_CELL
    while cell < facts["cell"]:
        keys, counts, to_coarse = _coarsen(keys, counts)
        inverse = to_coarse[inverse]
        cell *= 2
    return keys, inverse, counts, cell, facts


def _density(keys: np.ndarray, counts: np.ndarray, cell: float) -> dict:
    n = int(counts.sum())
    if n == 0:
        return {"cell": None, "occupied_area": None, "density": None, "spacing": None}
    while n / len(keys) < MIN_POINTS_PER_CELL and cell < MAX_DENSITY_CELL:
        keys, counts, _ = _coarsen(keys, counts)
        cell *= 2
    area = len(keys) * cell * cell
    return {"cell": cell, "occupied_area": area, "density": n / area, "spacing": float(np.sqrt(area / n))}


@dataclass
class Scene:
    keep: np.ndarray        # bool per point: in the scene (not a stray group)
    cell: float             # cell edge of the density estimate and of the groups
    density: float          # points per unit area of occupied cells
    spacing: float          # 1 / sqrt(density)
    bounds: tuple           # (xmin, ymin, xmax, ymax) of the kept points

    @property
    def stray(self) -> int:
        return int((~self.keep).sum())


def scene(xy: np.ndarray, stray_share: float = STRAY_SHARE) -> Scene:
    """The scene part of the points ``xy`` ((n, >=2)): occupied cells are grouped with those up to
    REACH_CELLS cells away; groups holding less than ``stray_share`` of the points (never the
    largest) are left out."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    xy = np.asarray(xy)[:, :2]
    n = len(xy)
    if n == 0:
        return Scene(np.zeros(0, bool), DENSITY_CELL, 0.0, 0.0, (0.0, 0.0, 0.0, 0.0))
    keys, inverse, counts, cell, facts = _density_cells(xy)
    ix, iy = _decode(keys)
    rows, cols = [], []
    for dx in range(-REACH_CELLS, REACH_CELLS + 1):
        for dy in range(-REACH_CELLS, REACH_CELLS + 1):
            if (dx, dy) <= (0, 0):
                continue            # each pair once
            at, hit = find(keys, _keys(ix + dx, iy + dy))
            rows.append(np.flatnonzero(hit))
            cols.append(at[hit])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(len(keys), len(keys)))
    _, group = connected_components(graph, directed=False)
    points = np.bincount(group, weights=counts)
    kept_groups = points >= stray_share * n
    kept_groups[np.argmax(points)] = True
    keep = kept_groups[group[inverse]]
    kx, ky = xy[keep, 0], xy[keep, 1]
    bounds = (float(kx.min()), float(ky.min()), float(kx.max()), float(ky.max()))
    return Scene(keep, cell, facts["density"], facts["spacing"], bounds)


@dataclass
class DataEdge:
    """The outer edge of where a cloud has points: occupied cells (of the density estimate's
    cell) with two unoccupied cells in a row beside them in x or y. A single empty cell is a gap
    of sparse sampling, not an edge. What lies at the edge was cut by the tile or survey boundary
    (or by a void wider than two cells), so its plan extent across the edge is not observed."""
    keys: np.ndarray        # sorted cell keys of the edge cells
    cell: float

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """bool per point of ``xy``: in an edge cell."""
        xy = np.asarray(xy)
        if len(xy) == 0:
            return np.zeros(0, bool)
        return find(self.keys, _keys(np.floor(xy[:, 0] / self.cell).astype(np.int64),
                                     np.floor(xy[:, 1] / self.cell).astype(np.int64)))[1]


def data_edge(xy: np.ndarray) -> DataEdge:
    """DataEdge of the points ``xy`` ((n, >=2), local coordinates)."""
    xy = np.asarray(xy)[:, :2]
    if len(xy) == 0:
        return DataEdge(np.zeros(0, np.int64), DENSITY_CELL)
    keys, _, _, cell, _ = _density_cells(xy)
    ix, iy = _decode(keys)

    def occupied(dx, dy):
        return find(keys, _keys(ix + dx, iy + dy))[1]

    edge = np.zeros(len(keys), bool)
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        edge |= ~occupied(dx, dy) & ~occupied(2 * dx, 2 * dy)
    return DataEdge(keys[edge], cell)
