"""Connected components over a neighbour graph, region statistics and region merging.

Components are found by a data-parallel union-find: every edge unites its two end points by
hooking the larger root onto the smaller one with an integer ``atomic_min`` on the parent array
(retrying when a concurrent hook got there first), ``find`` halves paths as it walks, and a
compression pass then points every node straight at its root. Parents only ever decrease and
only ever point at a node of the same component, so whatever the thread timing, the root of a
component is its smallest point index: the labels are deterministic. A round is one hooking pass
over all edges plus one compression pass; rounds repeat until a hooking pass changes nothing
(an integer flag). Hooking retries until its union is done, so a pass joins whole chains and
the round count does not grow with the graph diameter (a 100 000-node chain takes 2-3 rounds,
like a random graph).

Region merging (PCL RegionGrowingRGB's second step) computes the region adjacency graph and mean
colours on the host with numpy (``np.unique`` and ``np.bincount``: deterministic, float64 sums),
then unites regions on the device with the same union-find over an edge list.
"""

import numpy as np
from .taichi_compat import ti

from .common import as_ndarray, index_array, is_ndarray, kernel_array, like_input, ndarray, output_array, to_numpy

# Verification rounds never exceed a handful; this bound only guards against a logic error.
_MAX_ROUNDS = 64
# Bound on one edge's hooking retries within a pass; an edge left unjoined makes another round.
_MAX_HOOK_TRIES = 1 << 20


@ti.func
def _find(parent: ti.template(), x: ti.i32) -> ti.i32:
    """Root of ``x``, halving the path on the way (each visited node's parent is set to its
    grandparent, an ancestor, so trees never split). The halving store is a plain store on
    purpose: Mesa lavapipe loses later stores of a thread after an atomic inside this loop."""
    node = x
    while parent[node] != node:
        gp = parent[parent[node]]
        parent[node] = gp
        node = gp
    return node


@ti.func
def _unite(parent: ti.template(), a: ti.i32, b: ti.i32) -> ti.i32:
    """Join the trees of ``a`` and ``b`` by hooking the larger root onto the smaller with
    atomic_min, retrying when another thread hooked that root first; returns 1 when a parent
    was written."""
    wrote = 0
    x = a
    y = b
    for _ in range(_MAX_HOOK_TRIES):
        rx = _find(parent, x)
        ry = _find(parent, y)
        if rx == ry:
            break
        lo = ti.min(rx, ry)
        hi = ti.max(rx, ry)
        old = ti.atomic_min(parent[hi], lo)
        wrote = 1
        if old == hi:
            break
        # ``hi`` had been hooked onto ``old`` meanwhile: ``old`` and ``lo`` must now be joined
        # (this also restores the link hi-old that the atomic_min may have replaced).
        x = old
        y = lo
    return wrote


@ti.kernel
def _init_parent(active: ti.types.ndarray(dtype=ti.u8, ndim=1), use_active: ti.i32,
                 parent: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in parent:
        parent[i] = i
        if use_active != 0 and active[i] == 0:
            parent[i] = -1


@ti.kernel
def _hook_neighbors(neighbors: ti.types.ndarray(dtype=ti.i32, ndim=2),
                    edge_ok: ti.types.ndarray(dtype=ti.u8, ndim=2), use_edge_ok: ti.i32,
                    parent: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    changed: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    n = parent.shape[0]
    for i, k in ti.ndrange(neighbors.shape[0], neighbors.shape[1]):
        j = neighbors[i, k]
        # Nested ifs: Taichi's ``and`` does not short-circuit, and parent[-1] must not be read.
        if j >= 0 and j < n:
            if parent[i] >= 0 and parent[j] >= 0:
                ok = 1
                if use_edge_ok != 0:
                    ok = ti.i32(edge_ok[i, k])
                if ok != 0:
                    if _unite(parent, i, j) != 0:
                        changed[0] = 1


@ti.kernel
def _hook_edge_list(src: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    dst: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    parent: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    changed: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for e in src:
        a = src[e]
        b = dst[e]
        if parent[a] >= 0 and parent[b] >= 0:
            if _unite(parent, a, b) != 0:
                changed[0] = 1


@ti.kernel
def _compress(parent: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    # Concurrent writers only ever store a node's root, so read-only walks stay valid.
    for i in parent:
        if parent[i] >= 0:
            r = i
            while parent[r] != r:
                r = parent[r]
            parent[i] = r


@ti.kernel
def _color_edges(neighbors: ti.types.ndarray(dtype=ti.i32, ndim=2),
                 rgb: ti.types.ndarray(dtype=ti.f32, ndim=2), threshold_sq: ti.f32,
                 edge_ok: ti.types.ndarray(dtype=ti.u8, ndim=2)):
    for i, k in ti.ndrange(neighbors.shape[0], neighbors.shape[1]):
        j = neighbors[i, k]
        ok = ti.u8(0)
        if j >= 0:
            d0 = rgb[i, 0] - rgb[j, 0]
            d1 = rgb[i, 1] - rgb[j, 1]
            d2 = rgb[i, 2] - rgb[j, 2]
            if d0 * d0 + d1 * d1 + d2 * d2 < threshold_sq:
                ok = ti.u8(1)
        edge_ok[i, k] = ok


def _union_rounds(parent, hook) -> int:
    """Run hooking + compression rounds until a hooking pass writes nothing; returns rounds."""
    changed = ndarray(ti.i32, (1,))
    for rounds in range(1, _MAX_ROUNDS + 1):
        changed.fill(0)
        hook(changed)
        _compress(parent)
        if int(changed[0]) == 0:
            return rounds
    raise RuntimeError("union-find did not converge; this is a bug")


def _components(neighbors, edge_ok=None, active=None):
    """connected_components returning (labels, rounds), for tests and callers that want to
    see convergence. Labels come back as numpy for numpy ``neighbors`` on the CPU backend and
    for an input with no edge slots (Taichi has no empty ndarrays), else as an ndarray."""
    n, k = int(neighbors.shape[0]), int(neighbors.shape[1])
    if n == 0 or k == 0:
        out = np.arange(n, dtype=np.int32)
        if active is not None:
            out[to_numpy(active) == 0] = -1
        return out, 0
    nbr = index_array(neighbors)
    parent = output_array(ti.i32, (n,), neighbors)
    act = kernel_array(active, "uint8") if active is not None else ndarray(ti.u8, (1,))
    _init_parent(act, int(active is not None), parent)
    ok = kernel_array(edge_ok, "uint8") if edge_ok is not None else ndarray(ti.u8, (1, 1))
    use_ok = int(edge_ok is not None)
    rounds = _union_rounds(parent, lambda changed: _hook_neighbors(nbr, ok, use_ok, parent, changed))
    return parent, rounds


def connected_components(neighbors, edge_ok=None, active=None):
    """Label the connected components of the undirected graph given by ``neighbors``.

    neighbors: int32 (n, k) neighbour indices, -1 = padding. edge_ok: uint8 (n, k), an entry
    with 0 drops that edge (None: all edges). active: uint8 (n,), 0 drops the point and every
    edge touching it (None: all active). Returns int32 (n,): the smallest point index of each
    active point's component, -1 for inactive points (numpy or ndarray, as ``neighbors``).
    """
    parent, _ = _components(neighbors, edge_ok, active)
    return like_input(parent, neighbors)


def union_edge_list(n, src, dst):
    """Components of ``n`` nodes joined by the undirected edges (src[e], dst[e]) (int32 numpy).
    Returns int32 numpy (n,): each node's smallest connected node index."""
    if n == 0:
        return np.zeros(0, np.int32)
    parent = output_array(ti.i32, (n,), src)
    _init_parent(ndarray(ti.u8, (1,)), 0, parent)
    if len(src):
        s = kernel_array(src, "int32")
        d = kernel_array(dst, "int32")
        _union_rounds(parent, lambda changed: _hook_edge_list(s, d, parent, changed))
    return to_numpy(parent)


def color_edges(neighbors, rgb, threshold):
    """uint8 (n, k): 1 where the neighbour exists and the Euclidean RGB distance between the
    two points is below ``threshold`` (PCL RegionGrowingRGB's point colour threshold)."""
    if int(neighbors.shape[0]) == 0 or int(neighbors.shape[1]) == 0:
        return np.zeros(tuple(neighbors.shape), np.uint8)
    nbr = index_array(neighbors)
    out = output_array(ti.u8, tuple(nbr.shape), neighbors)
    t = np.float32(threshold)
    _color_edges(nbr, kernel_array(rgb, "float32"), float(t * t), out)
    return like_input(out, neighbors)


def relabel_compact(labels):
    """Map labels to 0..R-1 in order of first appearance (by point index); -1 stays -1.
    Returns (compact int32 (n,), R), numpy or ndarray as ``labels`` (computed on the host)."""
    lab = to_numpy(labels).astype(np.int64, copy=False)
    out = np.full(lab.shape, -1, np.int32)
    valid = lab >= 0
    ids, first, inverse = np.unique(lab[valid], return_index=True, return_inverse=True)
    rank = np.empty(len(ids), np.int32)
    rank[np.argsort(first, kind="stable")] = np.arange(len(ids), dtype=np.int32)
    out[valid] = rank[inverse]
    if is_ndarray(labels):
        return as_ndarray(out), len(ids)
    return out, len(ids)


def region_stats(labels, values=None):
    """Per-region statistics on the host: (ids, counts, means).

    ids: int64 sorted distinct labels >= 0; counts: int64 points per region; means: float64
    (R, c) mean of ``values`` (n, c) per region, or None without values. Deterministic sums.
    """
    lab = to_numpy(labels).astype(np.int64, copy=False)
    valid = lab >= 0
    ids, region = np.unique(lab[valid], return_inverse=True)
    counts = np.bincount(region, minlength=len(ids)).astype(np.int64)
    if values is None:
        return ids, counts, None
    vals = np.asarray(to_numpy(values), dtype=np.float64)
    vals = vals.reshape(len(lab), -1)[valid]
    means = np.empty((len(ids), vals.shape[1]), np.float64)
    for c in range(vals.shape[1]):
        means[:, c] = np.bincount(region, weights=vals[:, c], minlength=len(ids))
    means /= np.maximum(counts, 1)[:, None]
    return ids, counts, means


def boundary_edges(labels: np.ndarray, neighbors: np.ndarray):
    """The graph edges (i, neighbors[i, k]) whose two end points carry different labels, both
    >= 0, read from the (n, k) table in row-major order without expanding it into edge lists:
    (label of i, neighbour index) as two 1-D arrays (host numpy)."""
    real = neighbors >= 0
    own = labels[:, None]
    other = np.where(real, labels[np.where(real, neighbors, 0)], -1)
    cut = real & (own >= 0) & (other >= 0) & (other != own)
    return np.broadcast_to(own, neighbors.shape)[cut], neighbors[cut]


def merge_regions(labels, neighbors, rgb, threshold, min_size=0):
    """Merge adjacent regions with similar mean colour, then drop small regions.

    Two regions are adjacent when an edge of ``neighbors`` joins a point of each; adjacent
    regions whose mean RGB (computed before any merging, so the result is order independent)
    differ by less than ``threshold`` (Euclidean) are merged, transitively. A merged region is
    labelled with the smallest of its input labels (its smallest point index when the labels
    come from connected_components). Regions with fewer than ``min_size`` points afterwards
    get -1. Returns int32 (n,), numpy or ndarray as ``labels``.
    """
    lab = to_numpy(labels).astype(np.int64, copy=False)
    nbr = to_numpy(neighbors).astype(np.int32, copy=False)
    n = len(lab)
    ids, counts, means = region_stats(lab, rgb)
    valid = lab >= 0
    region = np.full(n, -1, np.int32)
    region[valid] = np.searchsorted(ids, lab[valid])
    r_count = len(ids)

    if nbr.size and r_count:
        ra, other = boundary_edges(region, nbr)
        ra = ra.astype(np.int64)
        rb = region[other].astype(np.int64)
        lo = np.minimum(ra, rb)
        hi = np.maximum(ra, rb)
        pairs = np.unique(lo * r_count + hi)
        a = pairs // r_count
        b = pairs % r_count
        close = np.sum((means[a] - means[b]) ** 2, axis=1) < float(threshold) ** 2
        root = union_edge_list(r_count, a[close].astype(np.int32), b[close].astype(np.int32))
    else:
        root = np.arange(r_count, dtype=np.int32)

    merged_size = np.bincount(root, weights=counts, minlength=r_count)
    region_label = np.where(merged_size[root] >= min_size, ids[root], -1)
    out = np.full(n, -1, np.int32)
    out[valid] = region_label[region[valid]]
    return as_ndarray(out) if is_ndarray(labels) else out
