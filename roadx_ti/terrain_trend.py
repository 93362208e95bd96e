"""The terrain's trend: a smooth surface under a steep survey that the cloth can hang over level.

The cloth simulation filter assumes level ground: on a hillside steeper than about 40 % even the
steep-slope cloth (rigidness 1) stays off the ground, and the hillside above it passes for roof
(a town on a 50 % grade: kappa 0.60-0.75). Run on heights relative to the terrain's trend, the
same hillside is level and the cloth settles on it; the trend is added back to the cloth after.

The trend is the terrain's lowest points smoothed: the lowest point (bar the lowest
LOW_OUTLIER_SHARE, low noise) of each ``cell`` m plan cell, on a lattice of world multiples of the
cell; empty cells take their nearest occupied cell's; a grey opening over ``window`` x ``window``
cells takes out what stands on the terrain (buildings and crowns narrower than the window; a plane
passes an opening unchanged) and a Gaussian of ``sigma`` cells smooths the steps that cell minima
of a slope make (a cell's lowest point lies wherever its ground happens to be sampled lowest). The
lattice is padded by point reflection before both filters, so a plane comes out a plane to the
survey's edges.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LOW_OUTLIER_SHARE = 0.01   # a cell's lowest points left out as possible low noise (its k-th lowest stands)


@dataclass
class TerrainTrend:
    x0: float            # local x of cell (0, 0)'s lower-left corner
    y0: float
    cell: float
    grid: np.ndarray     # float64 (nx, ny): trend height at cell centres

    def at(self, xy: np.ndarray) -> np.ndarray:
        """Bilinear trend height (float64) at local plan positions ``xy`` (n, 2)."""
        from scipy import ndimage

        xy = np.asarray(xy, np.float64)
        u = (xy[:, 0] - self.x0) / self.cell - 0.5
        v = (xy[:, 1] - self.y0) / self.cell - 0.5
        return ndimage.map_coordinates(self.grid, [u, v], order=1, mode="nearest")


def cell_lows(xyz: np.ndarray, cell: float, origin=(0.0, 0.0)):
    """(ix, iy, low): occupied cells of ``cell`` m on world multiples (``origin``: the local
    coordinates' world offset) and each one's lowest height bar its lowest LOW_OUTLIER_SHARE."""
    xyz = np.asarray(xyz)
    ix = np.floor((xyz[:, 0].astype(np.float64) + float(origin[0])) / cell).astype(np.int64)
    iy = np.floor((xyz[:, 1].astype(np.float64) + float(origin[1])) / cell).astype(np.int64)
    i0, j0 = ix.min(), iy.min()
    key = (ix - i0) * (int(iy.max() - j0) + 1) + (iy - j0)
    # by cell (ascending (ix, iy)), then by height: one int64 sort over the cell and the float32
    # height's order-preserving bits (faster than a two-key lexsort)
    bits = np.ascontiguousarray(xyz[:, 2], np.float32).view(np.int32).astype(np.int64)
    bits = np.where(bits < 0, ~bits & 0x7FFFFFFF, bits | 0x80000000)
    order = np.argsort((key << 32) | bits, kind="stable")
    key = key[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    counts = np.diff(np.r_[start, len(key)])
    rank = np.minimum(np.floor(LOW_OUTLIER_SHARE * counts).astype(np.int64), counts - 1)
    first = order[start]
    low = xyz[order[start + rank], 2].astype(np.float64)
    return ix[first], iy[first], low


def _smoothed(ix, iy, low, shape, window: int, sigma: float, pad: int) -> np.ndarray:
    """The lows on their lattice (``shape``; empty cells take the nearest occupied cell's), padded by
    point reflection by ``pad`` cells, opened over window x window cells and Gaussian-smoothed."""
    from scipy import ndimage

    grid = np.full(shape, np.nan)
    grid[ix, iy] = low
    empty = np.isnan(grid)
    if empty.any():
        _, (a, b) = ndimage.distance_transform_edt(empty, return_indices=True)
        grid = grid[a, b]
    if min(grid.shape) > 1:
        padded = np.pad(grid, pad, mode="reflect", reflect_type="odd")
    else:
        padded = np.pad(grid, pad, mode="edge")
    padded = ndimage.grey_opening(padded, size=(window, window), mode="nearest")
    if sigma > 0:
        padded = ndimage.gaussian_filter(padded, sigma, mode="nearest")
    return padded


def fit(xyz: np.ndarray, cell: float, window: int, sigma: float, origin=(0.0, 0.0)) -> TerrainTrend:
    """The trend of the module docstring over the (n, 3) local points ``xyz``. Two passes: a cell's
    lowest point on a slope lies at its downhill side, or wherever its ground is sampled lowest
    (the survey's edge cuts cells, a building covers a cell's downhill half), so the first trend
    is off by up to a cell's rise there; the second smooths the lows of the heights above the
    first, which are level, and adds them."""
    ix, iy, low = cell_lows(xyz, cell, origin)
    i0, j0 = int(ix.min()), int(iy.min())
    shape = (int(ix.max()) - i0 + 1, int(iy.max()) - j0 + 1)
    pad = window + int(np.ceil(3 * sigma))
    first = _smoothed(ix - i0, iy - j0, low, shape, window, sigma, pad)
    # one padding cell kept: a point in the outer half of an edge cell interpolates on the plane
    # (clamped to the edge cell's centre, the trend would be level there)
    keep = pad - 1
    trend = TerrainTrend((i0 - 1) * cell - float(origin[0]), (j0 - 1) * cell - float(origin[1]), float(cell),
                         first[keep:-keep, keep:-keep])
    level = np.array(xyz, np.float64)
    level[:, 2] -= trend.at(level[:, :2])
    ix2, iy2, low2 = cell_lows(level, cell, origin)
    second = _smoothed(ix2 - i0, iy2 - j0, low2, shape, window, sigma, pad)
    trend.grid = trend.grid + second[keep:-keep, keep:-keep]
    return trend
