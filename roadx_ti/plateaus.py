"""Raised plateaus of a cloth: flat roofs the cloth sank into, put back under the terrain.

The cloth simulation filter hangs a cloth of limited stiffness over the inverted cloud: over a
building wider than the cloth can span (about 200 m at 1 m resolution, rigidness 3: a 250 x 150 m
warehouse, where 150 x 100 m holds) it sinks onto the roof, and the whole roof becomes ground.
What gives such a roof away is its outline: ground on it is cut off from the ground around it by a
wall, a step of at least a storey down on nearly every side. Terrain is not: slopes, terraces and
embankments join the ground around them on some side, and a cut (a railway, a sunken road) leaves
its sides level with the ground beyond it.

The test runs on the cloth's own lattice. A cell is *supported* when a ground point lies on it;
neighbouring supported cells whose cloth heights differ by at most half the step belong to one
component. A component is a raised plateau when, of its outline cells with other ground within
``reach`` (the cloth's span), at least ``OUTLINE_SHARE`` have it lower by ``step`` or more, and
such outline cells are at least ``OUTLINE_SHARE`` of all its outline (the rest: the data's edge
or ground hidden under vegetation). The largest component, and any holding half the supported
cells or more, is terrain by definition. A plateau's cloth is then lowered to the plane fitted
to the lower ground around it, over its cells and the cells closer to it than to other ground.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

OUTLINE_SHARE = 0.75   # least share of a plateau's outline that must step down to the ground around it
MIN_CELLS = 25         # smaller components are not judged (noise, a ground point on a bin)
EDGE_CELLS = 2         # an outline cell with no point within this many cells outside is the data's edge


@dataclass
class Plateau:
    cells: int          # supported cloth cells of the plateau
    step: float         # median drop (m) from its outline to the nearest lower ground
    outline_share: float


def _components(z: np.ndarray, supported: np.ndarray, jump: float) -> np.ndarray:
    """Labels (rows, cols) int64 of supported cells joined through 8-neighbours within ``jump``
    of each other's height; -1 off the support."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows, cols = z.shape
    index = np.full(z.shape, -1, np.int64)
    index[supported] = np.arange(int(supported.sum()))
    a_all, b_all = [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r0, r1 = 0, rows - dr
        c0, c1 = max(0, -dc), cols - max(0, dc)
        here = (slice(r0, r1), slice(c0, c1))
        there = (slice(r0 + dr, r1 + dr), slice(c0 + dc, c1 + dc))
        join = supported[here] & supported[there] & (np.abs(z[here] - z[there]) <= jump)
        a_all.append(index[here][join])
        b_all.append(index[there][join])
    a, b = np.concatenate(a_all), np.concatenate(b_all)
    n = int(supported.sum())
    graph = coo_matrix((np.ones(len(a), np.int8), (a, b)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    out = np.full(z.shape, -1, np.int64)
    out[supported] = label
    return out


def find(cloth_z: np.ndarray, supported: np.ndarray, resolution: float, step: float,
         reach: float, occupied: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """(patched cloth heights or None, [Plateau]): ``cloth_z`` (rows, cols) with each raised
    plateau lowered to the terrain around it; ``supported`` (rows, cols) bool, the cells holding
    a ground point; ``step`` (m) the least wall height of a plateau, ``reach`` (m) how far from
    its outline the ground around it is looked for; ``occupied`` (rows, cols) bool, the cells
    holding any point (None: the supported ones): an outline cell with no occupied cell beside it
    outside the plateau (within EDGE_CELLS) is the data's edge, no evidence either way."""
    from scipy import ndimage

    if not supported.any():
        return None, []
    z = cloth_z.astype(np.float64)
    label = _components(z, supported, step / 2.0)
    sizes = np.bincount(label[supported])
    total = int(supported.sum())
    largest = int(np.argmax(sizes))
    reach_cells = max(1, int(np.ceil(reach / resolution)))
    patched = None
    found = []
    square = np.ones((3, 3), bool)
    boxes = ndimage.find_objects(label + 1)   # label -1 (off the support) is 0: no object
    for comp in np.flatnonzero(sizes >= MIN_CELLS):
        if comp == largest or 2 * sizes[comp] >= total:
            continue
        rows, cols = boxes[comp]
        r0, r1 = max(0, rows.start - reach_cells), min(z.shape[0], rows.stop + reach_cells)
        c0, c1 = max(0, cols.start - reach_cells), min(z.shape[1], cols.stop + reach_cells)
        window = (slice(r0, r1), slice(c0, c1))
        mine = label[window] == comp
        other = supported[window] & ~mine
        # its outer outline: gaps in sparse data and courtyards inside it are not where it steps
        filled = ndimage.binary_fill_holes(mine)
        outline = filled & ~ndimage.binary_erosion(filled, square, border_value=0)
        if not other.any():
            continue
        # the nearest other ground cell of every cell (the outline's view of the ground around)
        dist, (nr, nc) = ndimage.distance_transform_edt(~other, return_indices=True)
        # beside the outline, outside the plateau: points (a wall, the cloth's ring, the ground
        # beyond), or nothing (the survey ends there: a terrace at the edge is no plateau)
        beside = ndimage.maximum_filter((supported if occupied is None else occupied)[window] & ~filled,
                                        size=2 * EDGE_CELLS + 1, mode="constant", cval=False)
        near = outline & beside & (dist * resolution <= reach)
        if near.sum() < OUTLINE_SHARE * outline.sum():
            continue
        zw = z[window]
        drop = zw[near] - zw[nr[near], nc[near]]
        share = float(np.mean(drop >= step))
        if share < OUTLINE_SHARE:
            continue
        # the plane of the lower ground around: the nearest other cells the outline steps down to
        lower = np.zeros_like(other)
        lower[nr[near][drop >= step], nc[near][drop >= step]] = True
        lr, lc = np.nonzero(lower)
        height = zw[lower]
        design = np.column_stack([np.ones(len(lr)), lr - lr.mean(), lc - lc.mean()])
        if len(lr) >= 3 and np.linalg.matrix_rank(design) == 3:
            coef = np.linalg.lstsq(design, height, rcond=None)[0]
        else:
            coef = np.array([float(np.median(height)), 0.0, 0.0])
        # the plateau's cells and every cell closer to it than to other ground, within reach
        to_mine = ndimage.distance_transform_edt(~filled)
        cover = (to_mine <= dist) & (to_mine * resolution <= reach)
        gr, gc = np.nonzero(cover)
        plane = coef[0] + coef[1] * (gr - lr.mean()) + coef[2] * (gc - lc.mean())
        if patched is None:
            patched = cloth_z.copy()
        sub = patched[window]
        sub[gr, gc] = np.minimum(sub[gr, gc], plane.astype(np.float32))
        found.append(Plateau(int(sizes[comp]), float(np.median(drop)), share))
    return patched, found


def supported_cells(result, xyz: np.ndarray, ground: np.ndarray) -> np.ndarray:
    """(rows, cols) bool: the cloth particles of ``result`` (a ClothResult) nearest to a ground
    point of ``xyz`` (its local (n, 3) points)."""
    rows, cols = result.cloth_z.shape
    pts = np.asarray(xyz)[ground, :2].astype(np.float64)
    c = np.clip(np.rint((pts[:, 0] - result.x0) / result.resolution).astype(np.int64), 0, cols - 1)
    r = np.clip(np.rint((pts[:, 1] - result.y0) / result.resolution).astype(np.int64), 0, rows - 1)
    out = np.zeros((rows, cols), bool)
    out[r, c] = True
    return out
