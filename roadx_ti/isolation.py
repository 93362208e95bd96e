"""Parts of a cloud and its isolated points, found on a coarse block grid (host numpy).

Real surveys carry stray points far from everything else: a multipath return kilometres out, a
bird, a low-noise point hundreds of metres down. A grid, lattice or raster laid over a bounding box
that includes them grows with the extent instead of the points, and statistics over all points
(SOR's mean and deviation of neighbour distances) are dominated by them.

A *part* is a connected set of occupied blocks of edge ``gap`` (GAP m; blocks touching by a face,
an edge or a corner are connected). Points closer than ``gap`` always share a part; points of two
parts are at least ``gap`` apart. A stage that looks at the k nearest neighbours of a point treats
the points of a part of at most k points as *isolated*: their neighbourhood necessarily reaches
across the gap. Stages that would drop such points drop them (SOR), the others label them
non-target without letting them size a structure (cloth), and a cloud without isolated points is
processed exactly as before.

Memory and work are O(points): the block occupancy is a dense array only when the bounding box
holds few blocks (at most DENSE_BLOCKS), otherwise the occupied blocks are found by sorting their
keys (np.unique) and joined through the keys of their neighbours.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from roadx_ti.columns import column_max, column_min
from roadx_ti.sorted_keys import find

GAP = 100.0              # m: block edge; points of different parts are at least this far apart
SMALL_PART = 10          # points: a part of at most this many points is isolated for the cloth
DENSE_BLOCKS = 1 << 22   # bounding boxes of up to this many blocks use a dense occupancy array
_AXIS_BITS = 21          # sparse keys: 21 bits of block coordinate per axis (3 axes in an int64)
_AXIS_MAX = (1 << _AXIS_BITS) - 1
_CHUNK = 1 << 18         # points per chunk when computing block keys


@dataclass
class Parts:
    count: int
    label: np.ndarray | None    # int64 part of each point (parts numbered by their first point);
                                # None when there is one part (or none)
    sizes: np.ndarray           # int64 points per part

    def isolated(self, max_points: int, survey_points: int | None = None) -> np.ndarray | None:
        """bool per point: its part holds at most ``max_points`` points. None when no point is
        isolated, and also when no part is larger (a small cloud is not isolated from itself),
        unless the cloud is a tile of a survey of more than ``max_points`` points
        (``survey_points``): a tile holding only a stray point then sees it isolated, as the
        whole run does."""
        larger = bool((self.sizes > max_points).any()) or (survey_points or 0) > max_points
        small = self.sizes <= max_points
        if not larger or not small.any():
            return None
        if self.label is None:
            return np.ones(int(self.sizes.sum()), bool)
        return small[self.label]

    def members(self) -> list[np.ndarray]:
        """Ascending point indices of each part, in part order."""
        if self.label is None:
            return [np.arange(int(self.sizes.sum()))] if self.count else []
        order = np.argsort(self.label, kind="stable")
        return np.split(order, np.cumsum(self.sizes)[:-1])


def _block_keys(points: np.ndarray, lo: np.ndarray, gap: float, dims: np.ndarray, packed: bool) -> np.ndarray:
    """int64 key of every point's block (coordinates relative to the block of ``lo``, clipped to
    _AXIS_MAX: points more than 2^21 blocks away share the last block, and a structure over
    them would be refused anyway): the flat index in the dense array of ``dims`` blocks, or the
    coordinates packed in _AXIS_BITS bits each (``packed``)."""
    n, d = points.shape
    out = np.empty(n, np.int64)
    base = np.floor(lo / gap)
    weights = ([1 << (_AXIS_BITS * (d - 1 - a)) for a in range(d)] if packed
               else [int(np.prod(dims[a + 1:])) for a in range(d)])
    for s in range(0, n, _CHUNK):
        chunk = points[s:s + _CHUNK]
        key = np.zeros(len(chunk), np.int64)
        for a in range(d):
            block = np.floor(chunk[:, a] / gap) - base[a]
            np.clip(block, 0, _AXIS_MAX, out=block)
            key += block.astype(np.int64) * weights[a]
        out[s:s + _CHUNK] = key
    return out


def _number_by_first_point(block_part: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Renumber part ids (per point) so that parts are ordered by their first point."""
    first = np.full(count, len(block_part), np.int64)
    np.minimum.at(first, block_part, np.arange(len(block_part)))
    rank = np.empty(count, np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(count)
    label = rank[block_part]
    return label, np.bincount(label, minlength=count).astype(np.int64)


def _sparse_block_parts(keys: np.ndarray, d: int) -> tuple[int, np.ndarray]:
    """(count, part of each block) of sorted packed block keys: blocks joined to the neighbours
    found by key (each unordered pair once: offsets after 0 in lexicographic order)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    shifts = [_AXIS_BITS * (d - 1 - a) for a in range(d)]
    coords = np.stack([(keys >> s) & _AXIS_MAX for s in shifts], axis=1)
    rows, cols = [], []
    for offset in product((-1, 0, 1), repeat=d):
        if offset <= (0,) * d:
            continue
        moved = coords + np.asarray(offset)
        valid = ((moved >= 0) & (moved <= _AXIS_MAX)).all(axis=1)
        target = np.zeros(len(keys), np.int64)
        for a in range(d):
            target |= np.clip(moved[:, a], 0, _AXIS_MAX) << shifts[a]
        j, hit = find(keys, target)
        hit &= valid
        rows.append(np.flatnonzero(hit))
        cols.append(j[hit])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(len(keys), len(keys)))
    return connected_components(graph, directed=False)


def parts(points, gap: float = GAP) -> Parts:
    """The parts of ``points`` ((n, 2) or (n, 3), any float dtype, finite) at ``gap`` metres."""
    from scipy import ndimage

    pts = np.asarray(points)
    n, d = pts.shape
    if n == 0:
        return Parts(0, None, np.zeros(0, np.int64))
    lo = column_min(pts).astype(np.float64)
    hi = column_max(pts).astype(np.float64)
    dims = np.minimum(np.floor(hi / gap) - np.floor(lo / gap), _AXIS_MAX).astype(np.int64) + 1
    blocks = int(np.prod(dims))
    if blocks == 1:
        return Parts(1, None, np.array([n], np.int64))
    if blocks <= DENSE_BLOCKS:
        flat = _block_keys(pts, lo, gap, dims, packed=False)
        occupied = np.bincount(flat, minlength=blocks).reshape(tuple(dims)) > 0
        block_part, count = ndimage.label(occupied, structure=np.ones((3,) * d, bool))
        if count == 1:
            return Parts(1, None, np.array([n], np.int64))
        label, sizes = _number_by_first_point(block_part.ravel()[flat] - 1, count)
        return Parts(count, label, sizes)
    keys, inverse = np.unique(_block_keys(pts, lo, gap, dims, packed=True), return_inverse=True)
    count, block_part = _sparse_block_parts(keys, d)
    if count == 1:
        return Parts(1, None, np.array([n], np.int64))
    label, sizes = _number_by_first_point(block_part[inverse.reshape(-1)], count)
    return Parts(count, label, sizes)


def isolated(points, max_points: int, gap: float = GAP, survey_points: int | None = None) -> np.ndarray | None:
    """bool per point: it lies in a part of at most ``max_points`` points (None: no such point;
    ``survey_points``: see Parts.isolated)."""
    return parts(points, gap).isolated(max_points, survey_points)


def isolated_in(xyz, max_points: int, ctx) -> np.ndarray | None:
    """``isolated`` for a stage's cloud: a tile's survey size from its context (SURVEY_POINTS)."""
    from roadx_ti.stages.base import SURVEY_POINTS

    return isolated(xyz, max_points, survey_points=getattr(ctx, "facts", {}).get(SURVEY_POINTS))


def local_origin(world) -> np.ndarray:
    """Local origin of float64 world points: the floor of their minimum corner, leaving out
    isolated points (SMALL_PART), so that float32 local coordinates keep their detail near the
    points that matter (a stray point 20 km off would cost a decimal digit of every other).
    The floor of the plain minimum when no point is isolated (or some are not finite)."""
    world = np.asarray(world, np.float64)
    if len(world) == 0:
        return np.zeros(world.shape[1] if world.ndim == 2 else 3)
    lowest = column_min(world)
    if not np.all(np.isfinite(lowest)) or not np.all(np.isfinite(column_max(world))):
        return np.floor(lowest)
    far = isolated(world, SMALL_PART)
    return np.floor(lowest if far is None else column_min(world[~far]))


def corner_without_isolated(xyz, ctx=None, far=...):
    """(x_min, y_min) of the points without the isolated ones (SMALL_PART), as a grid corner;
    None when no point is isolated, or all are (the grid then takes the points' own minimum).
    ``far``: isolated_in's answer for these points when the caller has it already."""
    if far is ...:
        far = isolated_in(xyz, SMALL_PART, ctx) if len(xyz) else None
    if far is None or far.all():
        return None
    lowest = column_min(np.asarray(xyz)[~far, :2])
    return float(lowest[0]), float(lowest[1])
