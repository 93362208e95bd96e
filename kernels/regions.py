"""Region-level road segmentation kernels (METHODS.md R6, the region-graph reading).

Per point, on a kNN graph (``knn`` rows, -1 = dropped):
- ``neighbourhood_median``: per channel median of a point's value and its neighbours' (colour
  denoising that keeps edges where they are, unlike a mean);
- ``mode_heights``: an edge-preserving height filter: the slope-corrected heights of a point and
  its neighbours (``gradient``: dz/dx, dz/dy of a coarse local plane), their median, then a few
  steps to the median of those within ``width`` of the current estimate: noise drops by about
  the square root of the neighbourhood size while a kerb stays a step;
- ``edge_steps``: the slope-corrected filtered height difference along each graph edge.

Every thread reads its own row in slot order and writes only its own output: results are
bit-identical run to run and across backends with the same float rules.

``graph_edges``: each undirected kNN edge once (kernels: count, scatter, sort per row).

Host functions (numpy, deterministic): ``coarse_gradient`` (least-squares planes of coarse
cells) and ``merge_regions_by_colour``: region merging on the region adjacency graph with a region-level criterion (region mean colours), in
rounds of star merges (a region joins its most similar larger neighbour unless another region
joins it in the same round), over a schedule of colour thresholds, with a veto on pairs whose
shared boundary shows steps (kerbs): colour gradients cannot chain regions together as a
point-to-point threshold does. ``merge_regions_sequential`` is the plain reference of the same
rounds, one region at a time, for tests.
"""

import numpy as np

from .common import (host_memory_backend, index_array, is_ndarray, kernel_array, length, like_input, output_array,
                     points_array, to_numpy)
from .taichi_compat import ti

MAX_ROW = 33          # a point and at most 32 neighbours


@ti.func
def _insertion_sort(v: ti.template(), lo: ti.i32, hi: ti.i32):
    """v[lo:hi] sorted in place (a register vector or an ndarray; short runs)."""
    for a in range(lo + 1, hi):
        x = v[a]
        b = a
        while b > lo:
            if v[b - 1] > x:
                v[b] = v[b - 1]
                b -= 1
            else:
                break
        v[b] = x


@ti.func
def _median(v: ti.template(), count: ti.i32) -> ti.f32:
    """Median of v[0:count] (sorted in place); the mean of the middle two for an even count, as
    numpy's median."""
    _insertion_sort(v, 0, count)
    mid = count // 2
    out = v[mid]
    if count % 2 == 0:
        out = 0.5 * (v[mid - 1] + v[mid])
    return out


@ti.kernel
def _neighbourhood_median(nbr: ti.types.ndarray(dtype=ti.i32, ndim=2),
                          values: ti.types.ndarray(dtype=ti.f32, ndim=2),
                          out: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    for i, c in ti.ndrange(values.shape[0], values.shape[1]):
        v = ti.Vector([0.0] * MAX_ROW, ti.f32)
        v[0] = values[i, c]
        count = 1
        for s in range(nbr.shape[1]):
            j = nbr[i, s]
            if j >= 0:
                v[count] = values[j, c]
                count += 1
        out[i, c] = _median(v, count)


@ti.kernel
def _mode_heights(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), nbr: ti.types.ndarray(dtype=ti.i32, ndim=2),
                  grad: ti.types.ndarray(dtype=ti.f32, ndim=2), width: ti.types.ndarray(dtype=ti.f32, ndim=1),
                  steps: ti.i32, out: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for i in range(xyz.shape[0]):
        zc = ti.Vector([0.0] * MAX_ROW, ti.f32)
        zc[0] = xyz[i, 2]
        count = 1
        for s in range(nbr.shape[1]):
            j = nbr[i, s]
            if j >= 0:
                dx = xyz[j, 0] - xyz[i, 0]
                dy = xyz[j, 1] - xyz[i, 1]
                zc[count] = xyz[j, 2] - grad[i, 0] * dx - grad[i, 1] * dy
                count += 1
        work = zc
        z = _median(work, count)
        for _ in range(steps):
            near = ti.Vector([0.0] * MAX_ROW, ti.f32)
            m = 0
            for a in range(count):
                if ti.abs(zc[a] - z) <= width[i]:
                    near[m] = zc[a]
                    m += 1
            if m > 0:
                z = _median(near, m)
        out[i] = z


@ti.kernel
def _edge_steps(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), z: ti.types.ndarray(dtype=ti.f32, ndim=1),
                grad: ti.types.ndarray(dtype=ti.f32, ndim=2), ea: ti.types.ndarray(dtype=ti.i32, ndim=1),
                eb: ti.types.ndarray(dtype=ti.i32, ndim=1), out: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for e in range(ea.shape[0]):
        a = ea[e]
        b = eb[e]
        gx = 0.5 * (grad[a, 0] + grad[b, 0])
        gy = 0.5 * (grad[a, 1] + grad[b, 1])
        out[e] = (z[b] - z[a]) - gx * (xyz[b, 0] - xyz[a, 0]) - gy * (xyz[b, 1] - xyz[a, 1])


@ti.kernel
def _boundary_vote(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), nbr: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   grad: ti.types.ndarray(dtype=ti.f32, ndim=2), label: ti.types.ndarray(dtype=ti.u8, ndim=1),
                   step: ti.f32, out: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in range(xyz.shape[0]):
        ones = ti.Vector([0.0] * MAX_ROW, ti.f32)
        zeros = ti.Vector([0.0] * MAX_ROW, ti.f32)
        n1 = 0
        n0 = 0
        for s in range(nbr.shape[1]):
            j = nbr[i, s]
            if j >= 0:
                zc = xyz[j, 2] - grad[i, 0] * (xyz[j, 0] - xyz[i, 0]) - grad[i, 1] * (xyz[j, 1] - xyz[i, 1])
                if label[j] == 1:
                    ones[n1] = zc
                    n1 += 1
                else:
                    zeros[n0] = zc
                    n0 += 1
        out[i] = label[i]
        if n1 >= 3 and n0 >= 3:
            z1 = _median(ones, n1)
            z0 = _median(zeros, n0)
            if ti.abs(z1 - z0) >= step:
                out[i] = ti.cast(ti.abs(xyz[i, 2] - z1) < ti.abs(xyz[i, 2] - z0), ti.u8)


def _check_rows(nbr, n):
    if len(nbr.shape) != 2 or int(nbr.shape[0]) != n:
        raise ValueError(f"neighbour table must have shape (n, k) with n={n}, got {tuple(nbr.shape)}")
    if int(nbr.shape[1]) + 1 > MAX_ROW:
        raise ValueError(f"at most {MAX_ROW - 1} neighbours per point, got {int(nbr.shape[1])}")


def neighbourhood_median(values, neighbors):
    """float32 (n, c): per channel median of each point's value and its neighbours' (rows of
    ``neighbors`` int32 (n, k <= 32), -1 = none). numpy or ndarray, as ``values``."""
    vals = kernel_array(values, np.float32)
    n = length(vals)
    nbr = index_array(neighbors, n)
    _check_rows(nbr, n)
    out = output_array(ti.f32, tuple(vals.shape), values)
    if n:
        _neighbourhood_median(nbr, vals, out)
    return like_input(out, values)


def mode_heights(xyz, neighbors, gradient, width, steps: int = 3):
    """float32 (n,): edge-preserving filtered height of every point (see the module docstring).
    ``gradient`` float32 (n, 2) is the local slope used to compare heights at one place;
    ``width`` (m) the window of heights that count as the same surface (about 2.5 x the height
    noise): one value, or one per point (float32 (n,): noise that varies across a survey)."""
    pts = points_array(xyz)
    n = length(pts)
    nbr = index_array(neighbors, n)
    _check_rows(nbr, n)
    out = output_array(ti.f32, (n,), xyz)
    if n:
        widths = np.full(n, width, np.float32) if np.ndim(width) == 0 else width
        _mode_heights(pts, nbr, kernel_array(gradient, np.float32), kernel_array(widths, np.float32), int(steps), out)
    return like_input(out, xyz)


def boundary_vote(xyz, neighbors, gradient, label, step: float):
    """uint8 (n,): a point with neighbours of both labels (at least three each) whose two groups'
    median slope-corrected heights differ by at least ``step`` (a kerb between them) takes the
    label of the group whose height is closer to its own; every other point keeps its label.
    Region labels follow region boundaries; this puts the boundary on the step itself."""
    pts = points_array(xyz)
    n = length(pts)
    nbr = index_array(neighbors, n)
    _check_rows(nbr, n)
    out = output_array(ti.u8, (n,), xyz)
    if n:
        _boundary_vote(pts, nbr, kernel_array(gradient, np.float32), kernel_array(label, np.uint8), float(step), out)
    return like_input(out, xyz)


def edge_steps(xyz, heights, gradient, ea, eb):
    """float32 (E,): heights[b] - heights[a] minus the slope's share, per edge (a, b)."""
    pts = points_array(xyz)
    a = kernel_array(ea, np.int32)
    out = output_array(ti.f32, (length(a),), ea)
    if length(a):
        _edge_steps(pts, kernel_array(heights, np.float32), kernel_array(gradient, np.float32), a,
                    kernel_array(eb, np.int32), out)
    return like_input(out, ea)


# ------------------------------------------------------------------------------------------------
# host: graph, coarse slope, region merging

@ti.func
def _edge_owner(nbr: ti.template(), dist: ti.template(), max_length: ti.f32, i: ti.i32, s: ti.i32) -> ti.i32:
    """The row that lists undirected edge (i, nbr[i, s]) once: i when i < j, j when i > j and
    j's row does not hold i (a one-way neighbour), else -1 (dropped, or listed by j)."""
    j = nbr[i, s]
    owner = -1
    if j >= 0 and dist[i, s] <= max_length:
        if i < j:
            owner = i
        elif i > j:
            owner = j
            for t in range(nbr.shape[1]):
                if nbr[j, t] == i:
                    owner = -1
    return owner


@ti.kernel
def _edge_counts(nbr: ti.types.ndarray(dtype=ti.i32, ndim=2), dist: ti.types.ndarray(dtype=ti.f32, ndim=2),
                 max_length: ti.f32, count: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i, s in ti.ndrange(nbr.shape[0], nbr.shape[1]):
        owner = _edge_owner(nbr, dist, max_length, i, s)
        if owner >= 0:
            ti.atomic_add(count[owner], 1)


@ti.kernel
def _edge_scatter(nbr: ti.types.ndarray(dtype=ti.i32, ndim=2), dist: ti.types.ndarray(dtype=ti.f32, ndim=2),
                  max_length: ti.f32, offset: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  fill: ti.types.ndarray(dtype=ti.i32, ndim=1), eb: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i, s in ti.ndrange(nbr.shape[0], nbr.shape[1]):
        owner = _edge_owner(nbr, dist, max_length, i, s)
        if owner >= 0:
            eb[offset[owner] + ti.atomic_add(fill[owner], 1)] = i + nbr[i, s] - owner


@ti.kernel
def _sort_runs(offset: ti.types.ndarray(dtype=ti.i32, ndim=1), values: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """Each run values[offset[r]:offset[r + 1]] sorted in place (runs are short)."""
    for r in range(offset.shape[0] - 1):
        _insertion_sort(values, offset[r], offset[r + 1])


def graph_edges(indices, distances, max_length: float):
    """Each undirected edge of a kNN table once, as (a, b) int32 with a < b, sorted by (a, b):
    an entry i -> j no longer than ``max_length``, taken from the row of i when i < j, or from
    the row of j when j's row does not hold i (a one-way neighbour). Kernels count each row's
    edges, scatter them and sort each row's run: the same list whatever the thread order."""
    nbr = kernel_array(indices, np.int32)
    n = length(nbr)
    dist = kernel_array(distances, np.float32)
    # the largest float32 not above max_length: the float32 test equals the exact one
    limit = np.float32(min(max_length, np.finfo(np.float32).max))
    if float(limit) > max_length:
        limit = np.nextafter(limit, np.float32(-np.inf))
    limit = float(limit)
    count = output_array(ti.i32, (n,), indices)
    if n:
        _edge_counts(nbr, dist, limit, count)
    per_row = to_numpy(count)
    offset = np.zeros(n + 1, np.int64)
    np.cumsum(per_row, out=offset[1:])
    if offset[-1] >= np.iinfo(np.int32).max:
        raise ValueError(f"{offset[-1]} graph edges exceed Taichi's 32-bit indexing; tile the input")
    offset32 = kernel_array(offset.astype(np.int32), np.int32)
    eb = output_array(ti.i32, (max(int(offset[-1]), 1),), indices)
    if n:
        _edge_scatter(nbr, dist, limit, offset32, output_array(ti.i32, (n,), indices), eb)
        _sort_runs(offset32, eb)
    ea = np.repeat(np.arange(n, dtype=np.int32), per_row)
    return ea, np.asarray(to_numpy(eb))[:len(ea)]


def coarse_gradient(xyz: np.ndarray, cell: float) -> np.ndarray:
    """float32 (n, 2): slope (dz/dx, dz/dy) of the least-squares plane through each point's
    square cell of edge ``cell`` (cells of fewer than 6 points or degenerate: 0). float64 sums
    in input order (deterministic)."""
    n = len(xyz)
    if n == 0:
        return np.zeros((0, 2), np.float32)
    key = np.floor(xyz[:, :2] / cell).astype(np.int64)
    key -= key.min(axis=0)
    _, inv = np.unique(key[:, 0] * (int(key[:, 1].max()) + 1) + key[:, 1], return_inverse=True)
    inv = inv.ravel()
    x, y, z = (xyz[:, c].astype(np.float64) for c in range(3))
    cnt = np.bincount(inv).astype(np.float64)

    def total(v):
        return np.bincount(inv, weights=v)
    dx, dy, dz = x - (total(x) / cnt)[inv], y - (total(y) / cnt)[inv], z - (total(z) / cnt)[inv]
    sxx, sxy, syy, sxz, syz = total(dx * dx), total(dx * dy), total(dy * dy), total(dx * dz), total(dy * dz)
    det = sxx * syy - sxy * sxy
    ok = (cnt >= 6) & (det > 1e-12 * np.maximum(sxx * syy, 1e-30))
    safe = np.where(ok, det, 1.0)
    a = np.where(ok, (sxz * syy - syz * sxy) / safe, 0.0)
    b = np.where(ok, (syz * sxx - sxz * sxy) / safe, 0.0)
    return np.column_stack([a[inv], b[inv]]).astype(np.float32)


class RegionGraph:
    """Regions (points per region, colour sums) and their adjacency (pairs a < b with the
    number of graph edges between them and how many of those step up from a to b / from b to
    a). ``label`` maps points to regions 0..R-1."""

    def __init__(self, label, count, colour_sum, pa, pb, edges, up, down):
        self.label, self.count, self.colour_sum = label, count, colour_sum
        self.pa, self.pb, self.edges, self.up, self.down = pa, pb, edges, up, down

    @property
    def n_regions(self) -> int:
        return len(self.count)

    def mean_colour(self) -> np.ndarray:
        return self.colour_sum / np.maximum(self.count, 1)[:, None]


# fixed-point scales: integer atomics make every sum independent of thread order
COLOUR_SCALE = 64          # colour units -> int64 sums
STEP_SCALE = 4096          # step probabilities -> int64 sums
_EMPTY = np.iinfo(np.int64).max
MAX_LOAD = 0.7             # largest share of the pair table's slots in use (linear probing)
# the merge rounds re-key their pairs through tables of at most about this many slots (24 B each),
# one run of partitions of the keys (by hash) at a time: one table for all of a 16 M-point survey's first
# re-keying took 2^25 slots, 805 MB, at the peak of the road pipeline
MAX_TABLE_BITS = 22
_NO_PART = 255             # an item of the last round that joins regions that are now one
_KEPT = 254                # ... that is carried as it is
NARROW_STEPS_MAX = 2**31 - 1  # a pair list's step sums are int32 while every sum is at most this
EDGE_CHUNK = 1 << 22      # edges per chunk of the final region graph's pass over every edge
MAX_PART_BITS = 7          # at most 128 partitions (a uint8 per item names its kind)
# on the CPU, compacted pair lists are grouped by their first region's id in at most this many
# buckets (a few thousand regions each: their counts, colour sums and offers fit a core's cache),
# counted in at most MAX_TABLE_BLOCKS blocks of the table's slots
ID_BUCKETS = 256
MAX_TABLE_BLOCKS = 1024
_HASH = -7046029254386353131      # 0x9E3779B97F4A7C15 as a signed 64-bit constant


@ti.func
def _hash(key: ti.i64) -> ti.u64:
    return ti.cast(key * ti.i64(_HASH), ti.u64)


@ti.func
def _part_slot(key: ti.i64, bits: ti.i32, part_bits: ti.i32) -> ti.i32:
    """The slot of ``key`` in its partition's table: the ``bits`` hash bits after the
    ``part_bits`` that chose the partition (_partition_of; 0: one table, the top bits)."""
    return ti.cast((_hash(key) << ti.u64(part_bits)) >> ti.u64(64 - bits), ti.i32)


@ti.func
def _partition_of(key: ti.i64, part_bits: ti.i32) -> ti.i32:
    part = 0
    if part_bits > 0:
        part = ti.cast(_hash(key) >> ti.u64(64 - part_bits), ti.i32)
    return part


@ti.kernel
def _reset_regions(count: ti.types.ndarray(dtype=ti.i64, ndim=1), csum: ti.types.ndarray(dtype=ti.i64, ndim=2),
                   colour: ti.types.ndarray(dtype=ti.f32, ndim=2), label: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(label.shape[0]):
        label[i] = i
        count[i] = 1
        for c in ti.static(range(3)):
            csum[i, c] = ti.cast(ti.round(colour[i, c] * COLOUR_SCALE), ti.i64)


@ti.kernel
def _clear_table(table: ti.types.ndarray(dtype=ti.i64, ndim=2), size: ti.i32):
    for i in range(size):
        table[i, 0] = ti.i64(_EMPTY)
        table[i, 1] = 0
        table[i, 2] = 0


@ti.func
def _insert_key(table: ti.template(), key: ti.i64, bits: ti.i32, part_bits: ti.i32):
    """``key`` into column 0 of an open-addressing table: an integer atomic_min claims an empty
    slot or displaces a larger key, which is carried on (keys in a slot only ever decrease, so
    the table ends the same whatever the order: each key in one slot)."""
    mask = (1 << bits) - 1
    slot = _part_slot(key, bits, part_bits)
    for _ in range(1 << bits):
        old = ti.atomic_min(table[slot, 0], key)
        if old == key or old == ti.i64(_EMPTY):
            break
        if old > key:
            key = old          # displaced: carry the larger key on
        slot = (slot + 1) & mask


@ti.kernel
def _insert_pairs(ea: ti.types.ndarray(dtype=ti.i32, ndim=1), eb: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  start: ti.i32, items: ti.i32, label: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  table: ti.types.ndarray(dtype=ti.i64, ndim=2), bits: ti.i32, part_bits: ti.i32, n: ti.i64):
    """Items [start, start + items)'s region pairs (one run of partitions') into its open-addressing
    table (_insert_key)."""
    for e in range(start, start + items):
        la = label[ea[e]]
        lb = label[eb[e]]
        if la != lb:
            _insert_key(table, ti.min(la, lb) * n + ti.max(la, lb), bits, part_bits)


@ti.func
def _find_slot(table: ti.template(), key: ti.i64, bits: ti.i32, part_bits: ti.i32) -> ti.i32:
    mask = (1 << bits) - 1
    slot = _part_slot(key, bits, part_bits)
    while table[slot, 0] != key:
        slot = (slot + 1) & mask
    return slot


@ti.kernel
def _insert_keys(keys: ti.types.ndarray(dtype=ti.i64, ndim=1), table: ti.types.ndarray(dtype=ti.i64, ndim=2),
                 bits: ti.i32):
    for e in range(keys.shape[0]):
        _insert_key(table, keys[e], bits, 0)


@ti.kernel
def _slots_of_keys(keys: ti.types.ndarray(dtype=ti.i64, ndim=1), table: ti.types.ndarray(dtype=ti.i64, ndim=2),
                   bits: ti.i32, out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for e in range(keys.shape[0]):
        out[e] = _find_slot(table, keys[e], bits, 0)


def _group_keys(keys: np.ndarray):
    """(sorted distinct keys, index of each key among them): np.unique(keys, return_inverse=True)
    by a hash table in the kernels (one insertion and one lookup per key, a sort of the distinct
    keys only) on backends with 64-bit atomics; numpy's sort of every key elsewhere."""
    if not len(keys) or not _native_int64_atomics():
        uk, inv = np.unique(keys, return_inverse=True)
        return uk, inv.ravel()
    bits = max(4, int(np.ceil(np.log2(len(keys) / MAX_LOAD))))
    table = np.full((1 << bits, 1), _EMPTY, np.int64)      # one column: the key
    _insert_keys(keys, table, bits)
    slot = np.empty(len(keys), np.int32)
    _slots_of_keys(keys, table, bits, slot)
    used = np.flatnonzero(table[:, 0] != _EMPTY)
    distinct = table[used, 0]
    del table
    order = np.argsort(distinct, kind="stable")
    rank = np.empty(1 << bits, np.int32)
    rank[used[order]] = np.arange(len(used), dtype=np.int32)
    return distinct[order], rank[slot]


@ti.kernel
def _accumulate_pairs(ea: ti.types.ndarray(dtype=ti.i32, ndim=1), eb: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      weight: ti.types.ndarray(dtype=ti.i32, ndim=1), steps: ti.types.ndarray(ndim=1),
                      start: ti.i32, items: ti.i32, label: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      table: ti.types.ndarray(dtype=ti.i64, ndim=2), bits: ti.i32, part_bits: ti.i32, n: ti.i64):
    """Items (a, b, edges, steps) [start, start + items): graph edges in the first round, then the
    previous round's region pairs (a and b root points, mapped through ``label`` to their
    regions now), summed into their table rows."""
    for e in range(start, start + items):
        la = label[ea[e]]
        lb = label[eb[e]]
        if la != lb:
            slot = _find_slot(table, ti.min(la, lb) * n + ti.max(la, lb), bits, part_bits)
            ti.atomic_add(table[slot, 1], ti.cast(weight[e], ti.i64))
            ti.atomic_add(table[slot, 2], ti.cast(steps[e], ti.i64))


@ti.func
def _retouched(a: ti.i32, b: ti.i32, everything: ti.i32, hook: ti.template(), targeted: ti.template()) -> ti.i32:
    return everything != 0 or hook[a] >= 0 or hook[b] >= 0 or targeted[a] != 0 or targeted[b] != 0


@ti.kernel
def _carry_counts(ua: ti.types.ndarray(dtype=ti.i32, ndim=1), ub: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  items: ti.i32, everything: ti.i32, hook: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  targeted: ti.types.ndarray(dtype=ti.i32, ndim=1), label: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  n: ti.i64, part_bits: ti.i32, block: ti.i32, part: ti.types.ndarray(dtype=ti.u8, ndim=1),
                  counts: ti.types.ndarray(dtype=ti.i32, ndim=2)):
    """Per item: carried as it is (_KEPT), re-keyed in the partition of its new key's hash, or
    dropped (_NO_PART: its two regions are now one); per block, the items of each kind
    (column 0 kept, 1 + p partition p)."""
    for blk in range(counts.shape[0]):
        for e in range(blk * block, ti.min(blk * block + block, items)):
            column = 0
            kind = _KEPT
            if _retouched(ua[e], ub[e], everything, hook, targeted):
                kind = _NO_PART
                la = label[ua[e]]
                lb = label[ub[e]]
                if la != lb:
                    kind = _partition_of(ti.min(la, lb) * n + ti.max(la, lb), part_bits)
                    column = 1 + kind
            if kind != _NO_PART:
                counts[blk, column] += 1
            part[e] = ti.cast(kind, ti.u8)


@ti.kernel
def _gather_kind(ua: ti.types.ndarray(dtype=ti.i32, ndim=1), ub: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 uw: ti.types.ndarray(ndim=1), us: ti.types.ndarray(ndim=1), items: ti.i32,
                 part: ti.types.ndarray(dtype=ti.u8, ndim=1), kind: ti.i32, kind_end: ti.i32, block: ti.i32,
                 offsets: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 pa: ti.types.ndarray(dtype=ti.i32, ndim=1), pb: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 pw: ti.types.ndarray(dtype=ti.i32, ndim=1), ps: ti.types.ndarray(ndim=1), wide: ti.template()):
    """The last round's items of the kinds [kind, kind_end) (_carry_counts: _KEPT, or a run of
    partitions of the re-keyed) into a list of their own, in order, each block from its offset: a
    pair neither of whose regions took part in the last round's merges is still a distinct pair
    and is carried as it is; the others are re-keyed through their run's table (merges may have made several
    of them one pair); a re-keyed pair keeps a region that took part, so it never equals a
    carried one. ``uw`` / ``us``: the graph's per-edge uint8 / int16 in the first rounds; ``ps``
    int64 when ``wide``, else int32."""
    for blk in range(offsets.shape[0]):
        at = offsets[blk]
        for e in range(blk * block, ti.min(blk * block + block, items)):
            k = ti.cast(part[e], ti.i32)
            if k >= kind and k < kind_end:
                pa[at] = ua[e]
                pb[at] = ub[e]
                pw[at] = ti.cast(uw[e], ti.i32)
                if ti.static(wide):
                    ps[at] = ti.cast(us[e], ti.i64)
                else:
                    ps[at] = ti.cast(us[e], ti.i32)
                at += 1


@ti.kernel
def _table_counts(table: ti.types.ndarray(dtype=ti.i64, ndim=2), size: ti.i32, block: ti.i32, n: ti.i64,
                  shift: ti.i32, counts: ti.types.ndarray(dtype=ti.i32, ndim=2),
                  largest: ti.types.ndarray(dtype=ti.i64, ndim=1)):
    """Per block of slots: the pairs in use per bucket of their first region (a >> shift) and
    their largest step sum."""
    for blk in range(counts.shape[0]):
        top = ti.i64(0)
        for s in range(blk * block, ti.min(blk * block + block, size)):
            key = table[s, 0]
            if key != ti.i64(_EMPTY):
                counts[blk, ti.cast(key // n, ti.i32) >> shift] += 1
                top = ti.max(top, table[s, 2])
        largest[blk] = top


@ti.kernel
def _compact_pairs(table: ti.types.ndarray(dtype=ti.i64, ndim=2), size: ti.i32, block: ti.i32, n: ti.i64,
                   shift: ti.i32, offsets: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   pa: ti.types.ndarray(dtype=ti.i32, ndim=1), pb: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   weight: ti.types.ndarray(dtype=ti.i32, ndim=1), steps: ti.types.ndarray(ndim=1),
                   wide: ti.template()):
    """The table's pairs as a dense list grouped by bucket of their first region (a >> shift),
    each block's pairs of a bucket from its offset (_table_counts; the offsets are its cursors),
    in slot order within them: the next rounds read the regions' counts, sums and best offers of
    each pair, which then lie close in memory (hash order scattered them over every region: the
    rounds' pair passes ran 1.7-2x slower). Every slot is left empty. ``steps``: int64 when
    ``wide``, else int32 (every sum fits)."""
    for blk in range(offsets.shape[0]):
        for s in range(blk * block, ti.min(blk * block + block, size)):
            key = table[s, 0]
            if key != ti.i64(_EMPTY):
                a = ti.cast(key // n, ti.i32)
                at = offsets[blk, a >> shift]
                offsets[blk, a >> shift] = at + 1
                pa[at] = a
                pb[at] = ti.cast(key % n, ti.i32)
                weight[at] = ti.cast(table[s, 1], ti.i32)
                if ti.static(wide):
                    steps[at] = table[s, 2]
                else:
                    steps[at] = ti.cast(table[s, 2], ti.i32)
                # the slot emptied again: the table is clear for the next round
                table[s, 0] = ti.i64(_EMPTY)
                table[s, 1] = 0
                table[s, 2] = 0


def _blocks(items: int, most: int = 16384):
    """(block length, number of blocks) of a blocked pass: enough blocks for every thread (at most
    ``most``), each long enough that a thread's serial loop outweighs its launch."""
    count = max(1, min(most, -(-items // 256)))
    block = max(1, -(-items // count))
    return block, -(-items // block) if items else 1


@ti.func
def _mean_colour(csum: ti.template(), count: ti.template(), r: ti.i32):
    # float64: its division is correctly rounded on every backend with f64, so CPU and Vulkan
    # make the same merges (float32 division may differ in the last bit on GPUs)
    inv = 1.0 / (ti.cast(count[r], ti.f64) * COLOUR_SCALE)
    return ti.Vector([ti.cast(csum[r, 0], ti.f64) * inv, ti.cast(csum[r, 1], ti.f64) * inv,
                      ti.cast(csum[r, 2], ti.f64) * inv], ti.f64)


@ti.kernel
def _best_neighbours(pa: ti.types.ndarray(dtype=ti.i32, ndim=1), pb: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     weight: ti.types.ndarray(ndim=1), steps: ti.types.ndarray(ndim=1),
                     items: ti.i32, count: ti.types.ndarray(dtype=ti.i64, ndim=1),
                     csum: ti.types.ndarray(dtype=ti.i64, ndim=2), best: ti.types.ndarray(dtype=ti.i64, ndim=1),
                     level: ti.f64, size_pass: ti.i32, min_size: ti.i64, max_chroma: ti.f64, veto: ti.f64):
    """Each valid pair offers itself to both of its regions: best[r] = min over (cost bits << 32 |
    other region), an integer minimum (ties to the lower region id). Costs are squared mean
    colour distances in float64 (rounded to float32 for the order key)."""
    for e in range(items):
        a = pa[e]
        b = pb[e]
        # the mean colours from the sums per pair (an (n, 3) float64 array of them was 92 MB at 16 M
        # points, held through the rounds; the same values)
        d = _mean_colour(csum, count, a) - _mean_colour(csum, count, b)
        cost2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        grey = (d[0] + d[1] + d[2]) / 3.0
        c0, c1, c2 = d[0] - grey, d[1] - grey, d[2] - grey
        chroma2 = c0 * c0 + c1 * c1 + c2 * c2
        ok = ti.cast(steps[e], ti.f64) <= veto * STEP_SCALE * ti.cast(weight[e], ti.f64) \
            and chroma2 <= max_chroma * max_chroma
        if size_pass:
            ok = ok and (count[a] < min_size or count[b] < min_size)
        else:
            ok = ok and cost2 <= level * level
        if ok:
            bits = ti.cast(ti.bit_cast(ti.cast(cost2, ti.f32), ti.i32), ti.i64) << 32
            ti.atomic_min(best[a], bits | ti.cast(b, ti.i64))
            ti.atomic_min(best[b], bits | ti.cast(a, ti.i64))


@ti.kernel
def _choose_hooks(best: ti.types.ndarray(dtype=ti.i64, ndim=1), count: ti.types.ndarray(dtype=ti.i64, ndim=1),
                  label: ti.types.ndarray(dtype=ti.i32, ndim=1), hook: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  targeted: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """A region hooks onto its best neighbour when that one is larger (size, then id)."""
    for r in range(label.shape[0]):
        hook[r] = -1
        if label[r] == r and best[r] != ti.i64(_EMPTY):
            other = ti.cast(best[r] & ti.i64(0xFFFFFFFF), ti.i32)
            if count[other] > count[r] or (count[other] == count[r] and other > r):
                hook[r] = other
                targeted[other] = 1


@ti.kernel
def _apply_hooks(hook: ti.types.ndarray(dtype=ti.i32, ndim=1), targeted: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 count: ti.types.ndarray(dtype=ti.i64, ndim=1), csum: ti.types.ndarray(dtype=ti.i64, ndim=2),
                 merged: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """Star merges: a hooking region that nobody hooks onto joins its target (sizes and colour
    sums added with integer atomics); a region others hook onto stays put this round."""
    for r in range(hook.shape[0]):
        h = hook[r]
        if h >= 0 and targeted[r] == 0:
            ti.atomic_add(count[h], count[r])
            for c in ti.static(range(3)):
                ti.atomic_add(csum[h, c], csum[r, c])
            ti.atomic_add(merged[0], 1)
        else:
            hook[r] = -1


@ti.kernel
def _relabel(label: ti.types.ndarray(dtype=ti.i32, ndim=1), hook: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(label.shape[0]):
        h = hook[label[i]]
        if h >= 0:
            label[i] = h


@ti.kernel
def _clear_round(best: ti.types.ndarray(dtype=ti.i64, ndim=1), targeted: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for r in range(best.shape[0]):
        best[r] = ti.i64(_EMPTY)
        targeted[r] = 0


def _host_round(label, count, csum, ea, eb, weight, step_sum, n, level, size_pass, min_size, max_chroma, veto):
    """One merging round on the host (numpy), the same arithmetic as the kernels: for backends
    without 64-bit atomics (Vulkan, Metal). Updates label/count/csum in place; returns the
    number of regions that joined another and the round's region pairs (the next round's items)."""
    la, lb = label[ea], label[eb]
    cross = la != lb
    key = np.minimum(la, lb)[cross].astype(np.int64) * n + np.maximum(la, lb)[cross]
    uk, inv = np.unique(key, return_inverse=True)
    inv = inv.ravel()
    pair_edges = np.bincount(inv, weights=weight[cross], minlength=len(uk)).astype(np.int64)
    pair_steps = np.bincount(inv, weights=step_sum[cross], minlength=len(uk)).astype(np.int64)
    items = (uk // n, uk % n, pair_edges, pair_steps)
    edges = pair_edges.astype(np.float64)
    steps = pair_steps.astype(np.float64)
    pa, pb = uk // n, uk % n
    inv_a = 1.0 / (count[pa].astype(np.float64) * COLOUR_SCALE)
    inv_b = 1.0 / (count[pb].astype(np.float64) * COLOUR_SCALE)
    d = csum[pa].astype(np.float64) * inv_a[:, None] - csum[pb].astype(np.float64) * inv_b[:, None]
    cost2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    grey = (d[:, 0] + d[:, 1] + d[:, 2]) / 3.0
    c = d - grey[:, None]
    chroma2 = c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1] + c[:, 2] * c[:, 2]
    ok = (steps <= veto * STEP_SCALE * edges) & (chroma2 <= max_chroma * max_chroma)
    if size_pass:
        ok &= (count[pa] < min_size) | (count[pb] < min_size)
    else:
        ok &= cost2 <= level * level
    bits = cost2.astype(np.float32).view(np.int32).astype(np.int64) << 32
    best = np.full(n, _EMPTY, np.int64)
    np.minimum.at(best, pa[ok], bits[ok] | pb[ok])
    np.minimum.at(best, pb[ok], bits[ok] | pa[ok])
    me = np.flatnonzero((label[np.arange(n)] == np.arange(n)) & (best != _EMPTY))
    other = (best[me] & 0xFFFFFFFF).astype(np.int64)
    larger = (count[other] > count[me]) | ((count[other] == count[me]) & (other > me))
    me, other = me[larger], other[larger]
    targeted = np.zeros(n, bool)
    targeted[other] = True
    keep = ~targeted[me]
    me, other = me[keep], other[keep]
    if not len(me):
        return 0, items
    np.add.at(count, other, count[me])
    np.add.at(csum, other, csum[me])
    hook = np.arange(n, dtype=np.int64)
    hook[me] = other
    label[:] = hook[label]
    return len(me), items


def _device_round(state, chunks, n, level, size_pass, min_size, max_chroma, veto, first):
    """The same round with the kernels (64-bit integer atomics), on pair lists that stay in the
    kernels' memory: ``chunks``, the last round's pairs as a list of (a, b, edges, steps, count).
    Pairs that the last round's merges did not touch are carried over into one list; the others
    go through the hash table, one run of partitions of their keys at a time, each run's distinct
    pairs into a list of their own (grouped by their first region: _compact_pairs). Every list is made at its exact length: a round holds the
    last round's pairs and its own, never a buffer for all the items before their merging (at
    16 M points the second round's was 640 MB and the survey's peak). ``first``: None in later
    rounds; in the first, "distinct" when the graph's edges are distinct pairs (used as they
    are), else "rekey" (all through the table). Returns the regions joined and the round's pairs
    (the next round's chunks)."""
    label, count, csum, best, hook, targeted, merged, table = state
    if first != "distinct":
        chunks = _carry_and_rekey(state, chunks, n, everything=int(first == "rekey"))
    _clear_round(best, targeted)
    for pa, pb, pw, ps, pairs in chunks:
        _best_neighbours(pa, pb, pw, ps, pairs, count, csum, best, level, size_pass, int(min_size),
                         float(max_chroma), float(veto))
    _choose_hooks(best, count, label, hook, targeted)
    merged[0] = 0
    _apply_hooks(hook, targeted, count, csum, merged)
    joined = int(merged[0])
    if joined:
        _relabel(label, hook)
    return joined, chunks


def _carry_and_rekey(state, chunks, n, everything):
    """The pairs of the regions now (see _device_round) as a new list of chunks."""
    label, hook, targeted, table = state[0], state[4], state[5], state[7]
    like = chunks[0][0]
    m = sum(c[4] for c in chunks)
    # the re-keyed pairs go through tables of at most about 2^MAX_TABLE_BITS slots: when all m
    # items (an upper bound of those re-keyed) could overflow one, each item is put in one of
    # 2^MAX_PART_BITS partitions of the keys (by hash) and runs of partitions go through the
    # table together, as many as the items re-keyed this round fill (later rounds re-key few of
    # their pairs: partitions chosen for all m items took as many passes over the items as the
    # second round's)
    capacity = int(MAX_LOAD * (1 << MAX_TABLE_BITS))
    part_bits = MAX_PART_BITS if m > capacity else 0
    kinds = []                  # per chunk: each item's kind, and per block the items of each kind
    for ua, ub, _, _, items in chunks:
        block, n_blocks = _blocks(items)
        part = output_array(ti.u8, (max(items, 1),), ua)
        counts = output_array(ti.i32, (n_blocks, 1 + (1 << part_bits)), ua)
        _carry_counts(ua, ub, items, everything, hook, targeted, label, n, part_bits, block, part, counts)
        kinds.append((part, np.asarray(to_numpy(counts), np.int64), block))
    size = sum(c.sum(axis=0) for _, c, _ in kinds)        # kept, then each partition's items
    out = []
    # the gathered items keep int32 step sums unless a source list needed int64 (see below): one
    # kernel variant each for the usual lists (every variant is compiled or loaded per process)
    wide = any(_is_int64(c[3]) for c in chunks)
    if size[0]:
        out.append(_gather(chunks, kinds, (0, 1), (_KEPT, _KEPT + 1), int(size[0]), like, wide))
    groups = _partition_runs(size[1:], capacity)
    if groups:
        bits = max(4, int(np.ceil(np.log2(max(int(size[1 + lo:1 + hi].sum()) for lo, hi in groups) / MAX_LOAD))))
        # made again when too small, or more than twice too large (later rounds re-key fewer
        # pairs: a table kept from the second round was 50 MB at the third round's peak)
        if table[0] is None or int(table[0].shape[0]) not in (1 << bits, 2 << bits):
            table[0] = None
            table[0] = output_array(ti.i64, (1 << bits, 3), table[1])
            _clear_table(table[0], 1 << bits)          # then each compaction empties it again
        rows, size_t = table[0], 1 << bits
        # grouped on the CPU, whose cores' caches the grouping is for; a GPU keeps a thread per
        # 256 slots and one bucket (its blocks x buckets counts would be 16 MB a round)
        grouped = host_memory_backend()
        tblock, t_blocks = _blocks(size_t, MAX_TABLE_BLOCKS if grouped else 16384)
        shift = _bucket_shift(n) if grouped else 31
        buckets = ((n - 1) >> shift) + 1
    for lo, hi in groups:
        pa, pb, pw, ps, items = _gather(chunks, kinds, (1 + lo, 1 + hi), (lo, hi), int(size[1 + lo:1 + hi].sum()),
                                        like, wide)
        _insert_pairs(pa, pb, 0, items, label, rows, bits, part_bits, n)
        _accumulate_pairs(pa, pb, pw, ps, 0, items, label, rows, bits, part_bits, n)
        del pa, pb, pw, ps
        used = output_array(ti.i32, (t_blocks, buckets), like)
        largest = output_array(ti.i64, (t_blocks,), like)
        _table_counts(rows, size_t, tblock, n, shift, used, largest)
        u = np.asarray(to_numpy(used), np.int64)
        # block b's pairs of bucket j start after every pair of the buckets before j and block b's
        # predecessors' pairs of bucket j
        per_bucket = u.sum(axis=0)
        starts = np.cumsum(u, axis=0) - u + (np.cumsum(per_bucket) - per_bucket)[None, :]
        pairs = int(per_bucket.sum())
        # a pair's step sum is at most (STEP_SCALE + 1) x its edges: int32 up to about 500 k edges
        # between two regions; a list holding a larger sum is int64 (the kernels take either)
        wide_out = int(np.max(to_numpy(largest))) > NARROW_STEPS_MAX
        qa, qb, qw, qs = _pair_list(pairs, like, wide_out)
        # the offsets are the kernel's cursors: a fresh int32 copy (numpy, written in place on the CPU)
        _compact_pairs(rows, size_t, tblock, n, shift, kernel_array(starts.astype(np.int32), np.int32),
                       qa, qb, qw, qs, wide_out)
        out.append((qa, qb, qw, qs, pairs))
    return out


def _partition_runs(sizes, capacity: int) -> list:
    """[(first, end)] runs of consecutive partitions holding items, each with at most ``capacity``
    items in all (or one partition alone that holds more)."""
    runs, first, held = [], None, 0
    for p in np.flatnonzero(sizes):
        if first is not None and held + int(sizes[p]) > capacity:
            runs.append((first, end))
            first = None
        if first is None:
            first, held = int(p), 0
        held += int(sizes[p])
        end = int(p) + 1
    if first is not None:
        runs.append((first, end))
    return runs


def _bucket_shift(n: int) -> int:
    """log2 of the region ids per bucket of a compacted pair list: at most ID_BUCKETS buckets."""
    return max(0, int(np.ceil(np.log2(max(n, 1) / ID_BUCKETS))))


def _is_int64(a) -> bool:
    return a.dtype == ti.i64 if is_ndarray(a) else a.dtype == np.int64


def _pair_list(items, like, wide):
    """Arrays (a, b, edges, steps) for ``items`` pairs: step sums int64 when ``wide``, else int32."""
    return tuple(output_array(t, (max(items, 1),), like) for t in (ti.i32, ti.i32, ti.i32, ti.i64 if wide else ti.i32))


def _gather(chunks, kinds, columns, kind, total, like, wide):
    """The items whose kind lies in ``kind`` (first, end) from every chunk, in order, as a new
    chunk of ``total`` items (step sums int64 when ``wide``, else int32); ``columns`` (first, end):
    those kinds' columns of the per-block counts."""
    pa, pb, pw, ps = _pair_list(total, like, wide)
    at = 0
    for (ua, ub, uw, us, items), (part, counts, block) in zip(chunks, kinds):
        per_block = counts[:, columns[0]:columns[1]].sum(axis=1)
        if not per_block.any():
            continue            # no item of these kinds in the chunk: no pass over it
        offsets = np.zeros(len(per_block), np.int64)
        np.cumsum(per_block[:-1], out=offsets[1:])
        _gather_kind(ua, ub, uw, us, items, part, kind[0], kind[1], block,
                     kernel_array((offsets + at).astype(np.int32), np.int32), pa, pb, pw, ps, wide)
        at += int(per_block.sum())
    return pa, pb, pw, ps, total


def _step_evidence(steps_up, steps_down):
    """evidence(index) -> (up, down) float64 for those edges: ``steps_up`` itself when it is such a
    function (``steps_down`` None), else a view of the two arrays."""
    if callable(steps_up):
        return steps_up
    up, down = np.asarray(steps_up, np.float64), np.asarray(steps_down, np.float64)
    return lambda index: (up[index], down[index])


def _quantised_steps(evidence, n_edges: int, chunk: int = 1 << 20):
    """int16 (E,) rint(up * STEP_SCALE) + rint(down * STEP_SCALE) (at most STEP_SCALE + 1: up +
    down <= 1), a chunk of edges at a time (float temporaries of one chunk only; large enough
    that the evidence function's own threading pays)."""
    out = np.empty(n_edges, np.int16)
    for start in range(0, n_edges, chunk):
        up, down = evidence(slice(start, min(start + chunk, n_edges)))
        out[start:start + len(up)] = np.rint(up * STEP_SCALE).astype(np.int64) + np.rint(down * STEP_SCALE).astype(np.int64)
    return out


def _native_int64_atomics() -> bool:
    """Backends whose 64-bit integer atomics Taichi maps to hardware ones (CPU and CUDA); the
    SPIR-V backends (Vulkan, Metal) are given the host rounds (measured: lavapipe's i64
    atomic_min gave run-to-run different merges)."""
    from .taichi_compat import current_arch
    return current_arch() in (ti.x64, ti.arm64, ti.cuda)


def merge_regions_by_colour(n_points, ea, eb, steps_up, steps_down, colour, levels, max_chroma_step,
                            step_veto, min_size=0, max_rounds=1000, settle=0.005, host=None, branches=None):
    """Agglomerate points into regions (see the module docstring) and return a RegionGraph.

    ea, eb: int (E,) graph edges; steps_up / steps_down: float (E,) probability that the edge
    steps up from a to b (b to a) by a kerb, or steps_up a function of an edge index (a slice or
    an index array) returning both for those edges and steps_down None: the caller then holds
    neither full float64 array through the rounds (it is called once over all edges, a chunk at
    a time, and once for the edges between the final regions); colour: float (n, 3); levels: ascending colour
    thresholds (colour units) of the schedule: a pair merges at a level when its mean colours
    differ by at most the level, their chroma (colour minus grey) by at most
    ``max_chroma_step``, and the step probabilities of its boundary edges sum to at most
    ``step_veto`` of their number; min_size: a last pass lets regions smaller than this join
    their best neighbour whatever the colour (still under the step veto). Each round: every
    region finds its most similar valid neighbour; a region whose best neighbour is larger joins
    it, unless another region joins it in the same round (star merges, no chains). A level ends
    when a round joins fewer than ``settle`` of the regions left. ``host``: run the rounds with
    numpy (default: on backends without native 64-bit atomics); the result is the same.

    ``branches``: a list of level lists; the merge then runs ``levels`` once and, from the
    regions they leave, each branch's levels and the min_size pass on its own (rounds over those
    regions as nodes: cheaper than the first levels over every point), and returns an iterator
    of one RegionGraph per branch, made as it is taken. A branch [l2, l3] after levels [l1] gives
    the regions of levels [l1, l2, l3], its pairs and step sums included; a single branch runs as
    that one schedule."""
    n = int(n_points)
    col = np.ascontiguousarray(colour, np.float32)
    a32 = np.ascontiguousarray(ea, np.int32)
    b32 = np.ascontiguousarray(eb, np.int32)
    evidence = _step_evidence(steps_up, steps_down)
    up_q = _quantised_steps(evidence, len(a32))
    host = (not _native_int64_atomics()) if host is None else bool(host)
    state = None
    if host:
        label = np.arange(n, dtype=np.int64)
        count = np.ones(n, np.int64)
        csum = np.rint(col.astype(np.float32) * np.float32(COLOUR_SCALE)).astype(np.int64)
    else:
        label = output_array(ti.i32, (n,), col)
        count = output_array(ti.i64, (n,), col)
        csum = output_array(ti.i64, (n, 3), col)
        # graph_edges' edges: a < b, sorted by (a, b), each pair once (then used as they are)
        da, db = np.diff(a32), np.diff(b32)
        distinct = bool(np.all(a32 < b32) and np.all((da > 0) | ((da == 0) & (db > 0))))
        del da, db
        # the first round's pairs are the graph's edges: (a, b, edges, steps, count), a and b read in
        # place (they may be the caller's arrays), one edge each (uint8) and the edge's steps (int16)
        chunks = [tuple(kernel_array(v, v.dtype) for v in (a32, b32, np.ones(len(a32), np.uint8), up_q)) + (len(a32),)]
        # the pair table (rows key, edges, steps) is made when a round first re-keys pairs, sized
        # for that round's, and grown when a later round re-keys more
        state = (label, count, csum) + tuple(output_array(t, (n,), col) for t in (ti.i64, ti.i32, ti.i32)) \
            + (output_array(ti.i32, (1,), col), [None, col])
        if n:
            _reset_regions(count, csum, kernel_array(col, np.float32), label)
    live = (a32, b32, np.ones(len(a32), np.int64), up_q) if host else chunks
    up_q = chunks = None     # the first chunk holds it; it goes when the second round has re-keyed it
    single = branches is not None and len(branches) == 1
    if single:
        # one branch: the whole schedule in one merge (the same regions), no rounds over nodes
        levels, branches = list(levels) + list(branches[0]), None
    last_pass = [(0.0, 1)] if min_size > 1 else []
    schedule = [(float(v), 0) for v in levels] + (last_pass if branches is None else [])
    first = None if host else ("distinct" if distinct else "rekey")
    rounds, regions_left, live = _rounds(label, count, csum, state, live, n, schedule, host, first, 0, n,
                                         max_rounds, min_size, float(max_chroma_step), float(step_veto), settle)
    if branches is not None:
        # the pairs of the regions now: the last round's items keyed again (as a next round would;
        # with no round run, the graph's edges)
        if host:
            items = _host_items(label, *live, n)
        elif not sum(c[4] for c in live):
            items = (np.zeros(0, np.int64),) * 4
        elif rounds:
            items = _gathered(_carry_and_rekey(state, live, n, 0))
        else:
            items = _host_items(np.arange(n), *_gathered(live), n)
    label, count, csum = np.asarray(to_numpy(label)).astype(np.int64), to_numpy(count), to_numpy(csum)
    # the rounds' pair lists and table go before the final pair table is built
    state = live = None
    if branches is None:
        graph = _region_graph(label, count, csum, a32, b32, evidence)
        return iter([graph]) if single else graph
    roots = np.unique(label)                        # ascending point ids: the host rounds' ties
    node = np.searchsorted(roots, label)            # break as they would over the points
    pairs = _node_items(items, roots)
    del items
    # the edges between the regions now: every branch's regions are unions of them
    cross = np.flatnonzero(node[a32] != node[b32])
    ca, cb = a32[cross], b32[cross]

    def cross_evidence(index):
        return evidence(cross[index])

    def branch_graph(branch):
        tail = [(float(v), 0) for v in branch] + last_pass
        node_root, node_count, node_csum = _merge_nodes(count[roots], csum[roots], pairs, tail, host, rounds,
                                                        regions_left, max_rounds, min_size, float(max_chroma_step),
                                                        float(step_veto), settle)
        point_count = np.zeros(n, np.int64)
        point_count[roots] = node_count
        point_csum = np.zeros((n, 3), np.int64)
        point_csum[roots] = node_csum
        return _region_graph(roots[node_root[node]], point_count, point_csum, ca, cb, cross_evidence)
    # one branch's graph at a time (each holds per-point and per-pair arrays)
    return (branch_graph(branch) for branch in branches)


def _host_items(label, ea, eb, weight, step_sum, n):
    """A host round's items (pairs of the regions in ``label`` with their edge and step sums)."""
    la, lb = label[ea], label[eb]
    cross = la != lb
    key = np.minimum(la, lb)[cross].astype(np.int64) * n + np.maximum(la, lb)[cross]
    uk, inv = np.unique(key, return_inverse=True)
    inv = inv.ravel()
    return (uk // n, uk % n, np.bincount(inv, weights=weight[cross], minlength=len(uk)).astype(np.int64),
            np.bincount(inv, weights=step_sum[cross], minlength=len(uk)).astype(np.int64))


def _gathered(chunks):
    """The kernel rounds' pair lists as one host list (a, b, edges, steps), int64."""
    parts = [[np.asarray(to_numpy(c[i]))[:c[4]].astype(np.int64) for c in chunks] for i in range(4)]
    return tuple(np.concatenate(p) if p else np.zeros(0, np.int64) for p in parts)


def _node_items(items, roots):
    """Round items keyed by root point ids -> the pairs of their nodes (indices into ``roots``):
    a < b, sorted by (a, b), each pair once (the items hold each pair of regions once)."""
    a, b = np.searchsorted(roots, items[0]), np.searchsorted(roots, items[1])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.argsort(lo * len(roots) + hi, kind="stable")
    return lo[order], hi[order], items[2][order], items[3][order]


def _rounds(label, count, csum, state, live, n, schedule, host, first, rounds, regions_left, max_rounds,
            min_size, max_chroma, veto, settle):
    """The merge rounds of ``schedule`` (level, size pass) from the regions in label / count /
    csum (host arrays) or ``state`` (kernel arrays) and the round items ``live``: a level ends
    when a round joins no region or fewer than ``settle`` of those left. ``first``: the first
    round's kind for the kernels (see _device_round). Returns (rounds, regions left, the last
    round's items: its pairs, keyed by the regions before that round's merges)."""
    for level, size_pass in schedule:
        while rounds < max_rounds and n and (len(live[0]) if host else sum(c[4] for c in live)):
            rounds += 1
            if host:
                joined, live = _host_round(label, count, csum, *live, n, level, size_pass, min_size, max_chroma, veto)
            else:
                joined, live = _device_round(state, live, n, level, size_pass, min_size, max_chroma, veto, first)
                first = None
            if joined == 0:
                break
            regions_left -= joined
            if joined < settle * regions_left:
                break       # the level has settled: the rest of its merges are a thin tail
    return rounds, regions_left, live


def _merge_nodes(count, csum, pairs, schedule, host, rounds, regions_left, max_rounds, min_size, max_chroma, veto,
                 settle):
    """The merge rounds of ``schedule`` over regions as nodes (``count``, ``csum`` per node,
    ``pairs`` from _node_items: distinct and sorted), with the kernels or on the host.
    Returns (root node per node, count and colour sum per node, valid at roots) as numpy int64."""
    n = len(count)
    count = np.array(count, np.int64)
    csum = np.array(csum, np.int64)
    if not len(pairs[0]):
        return np.arange(n, dtype=np.int64), count, csum          # nothing left to join
    if host:
        label = np.arange(n, dtype=np.int64)
        _rounds(label, count, csum, None, pairs, n, schedule, True, None, rounds, regions_left, max_rounds,
                min_size, max_chroma, veto, settle)
        return label, count, csum
    # the kernel rounds' state over the nodes (the numpy arrays are written in place on the CPU)
    label = kernel_array(np.arange(n, dtype=np.int32), np.int32)
    count_k, csum_k = kernel_array(count, np.int64), kernel_array(csum, np.int64)
    state = (label, count_k, csum_k) + tuple(output_array(t, (n,), count) for t in (ti.i64, ti.i32, ti.i32)) \
        + (output_array(ti.i32, (1,), count), [None, count])
    pa, pb, edges, steps = pairs
    wide = len(steps) and int(steps.max()) > NARROW_STEPS_MAX
    live = [(kernel_array(pa, np.int32), kernel_array(pb, np.int32), kernel_array(edges, np.int32),
             kernel_array(steps, np.int64 if wide else np.int32), len(pa))]
    _rounds(label, count_k, csum_k, state, live, n, schedule, False, "distinct", rounds, regions_left, max_rounds,
            min_size, max_chroma, veto, settle)
    return (np.asarray(to_numpy(label)).astype(np.int64), np.asarray(to_numpy(count_k)).astype(np.int64),
            np.asarray(to_numpy(csum_k)).astype(np.int64))


def _region_graph(label, count, csum, ea, eb, evidence):
    """Compact region ids 0..R-1 in order of each region's first point (so that equal partitions
    get equal ids, whichever point a backend's merges left as the root) and the final pair table."""
    roots, first, compact = np.unique(label, return_index=True, return_inverse=True)
    rank = np.empty(len(roots), np.int32)          # int32 ids: the per-edge lookups below are large
    order = np.argsort(first, kind="stable")
    rank[order] = np.arange(len(roots), dtype=np.int32)
    compact = rank[compact.ravel()]
    roots = roots[order]
    # the edges between regions and their pairs' keys (min, max), a chunk of edges at a time: each
    # per-edge temporary of this table is large (it was the road pipeline's peak at 16 M points)
    n_regions = max(len(roots), 1)
    crosses, keys, flips = [np.zeros(0, np.int32)], [np.zeros(0, np.int64)], [np.zeros(0, bool)]
    for start in range(0, len(ea), EDGE_CHUNK):
        chunk = slice(start, start + EDGE_CHUNK)
        la, lb = compact[ea[chunk]], compact[eb[chunk]]
        at = np.flatnonzero(la != lb)
        la, lb = la[at], lb[at]
        crosses.append((at + start).astype(np.int32))
        flips.append(la > lb)               # the edge runs from the pair's second region to its first
        keys.append(np.minimum(la, lb).astype(np.int64) * n_regions + np.maximum(la, lb))
    cross, flip, key = np.concatenate(crosses), np.concatenate(flips), np.concatenate(keys)
    del crosses, flips, keys
    uk, inv = _group_keys(key)
    del key
    pa, pb = uk // n_regions, uk % n_regions
    del uk
    m = np.bincount(inv, minlength=len(pa)).astype(np.float64)
    # oriented step probabilities summed per pair (up: from the pair's first region to its second),
    # edge by edge in order as one bincount would (np.add.at continues each sum across chunks)
    u, d = np.zeros(len(pa)), np.zeros(len(pa))
    for start in range(0, len(cross), EDGE_CHUNK):
        chunk = slice(start, start + EDGE_CHUNK)
        up, down = evidence(cross[chunk])
        np.add.at(u, inv[chunk], np.where(flip[chunk], down, up))
        np.add.at(d, inv[chunk], np.where(flip[chunk], up, down))
    del cross, flip, inv
    return RegionGraph(compact, count[roots].astype(np.float64),
                       csum[roots].astype(np.float64) / COLOUR_SCALE, pa, pb, m, u, d)
