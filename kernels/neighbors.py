"""Exact k nearest neighbours and radius search over a hashed grid (``grid.build_grid``).

Every query scans the cube of cells within Chebyshev ring L of its own cell. All points closer
than the cube's *safe radius* s(L) = (L + distance from the query to its cell's faces) * cell_size
lie inside the cube, so once the k-th candidate is closer than s(L) the answer is exact;
otherwise the cube grows by one ring. Far from everything (outliers), once the cube would hold
more cells than a brute scan costs, the query scans all points instead.

Neighbours are ordered by (float32 distance, point index): ties break by index, so results are
deterministic whatever the scan order. (For k <= SMALL_K the selection itself runs on
(squared distance, index); rows are then re-ordered by (distance, index).)

Kernels for k <= SMALL_K:
* ``_knn_cells`` (CPU): one occupied cell per iteration. The runs of its 27 neighbouring cells
  are looked up once per cell, then its points are queried one after the other, each starting
  from a bound on its k-th distance taken from the previous query (rejects most candidates
  up front). Candidates within the bound go, branch-free, into an unordered buffer of 2k slots,
  cut to its k best by a quickselect whenever it fills (the cut's k-th tightens the bound):
  cheaper than keeping an ordered list, whose insertions branch on every comparison (k 16:
  -5 %, k 32: -13 % against the list, same rows). A query not settled by the 3x3x3 cube adds the second ring's cells
  within reach; the few still unsettled (outliers, sparse regions) go to ``_knn_blocks``. Rows are
  ordered by each pair's rank, counted branch-free.
* ``_knn_blocks``: one query per thread, keeping an ascending list of the k best, shell by shell over blocks of 4x4x4 cells (64
  consecutive buckets: cheap to skip empty space) or, on GPUs, for every query over single
  cells; blocks beyond the current k-th are skipped, a brute scan ends hopeless searches
  (``_block_search``, which ``nearest`` also runs for the points of another set: k = 1).
* larger k (``_knn_select``; SOR uses k = 500): selection by counting, with no per-thread array
  of k slots. The pass that fixes the ring also histograms the float bits of the distances just
  below the safe radius (32 bins in registers); further passes re-histogram inside the bin that
  holds the k-th (5 bits a pass) until at most SMALL_K candidates remain, and the wanted one is
  found among those by counting. Exact ties at the k-th distance are split by a radix selection
  over point indices. ``knn_mean_distance`` sums distances per bin on the way (no extra pass);
  ``knn`` makes one more pass to emit the k rows, then heap-sorts each row in place. Every pass
  skips cells whose box lies beyond the current bound on the k-th distance.
"""

import numpy as np
from .taichi_compat import ti

from .common import cpu_block_dim, host_memory_backend, length, like_input, ndarray, output_array, points_array
from .grid import Grid, build_grid, build_grid_into, cell_hash, cell_of, compact_mask, scratch
from .scan import exclusive_scan_into

SMALL_K = 32
PPC_DIV = 8.0
MAX_K = 512
_BINS = 32
_BIN_BITS = 5
_INF_KEY = 0x7F800000          # float bits of +inf: larger than any finite distance
_FIRST_SHIFT = 19              # first bins: 1/16 octave (2^23 float bits per octave), 2 octaves
_BRUTE_SHIFT = 26              # brute force: 32 bins cover every finite float
_BLOCK_BITS = 2                # blocks of 4x4x4 cells: 64 consecutive buckets (grid.cell_hash)
_BUF = 2 * SMALL_K              # candidate buffer of the cell kernel (i64 slots)
_CAP_PER_K = 2                 # the buffer is cut to its k best when it holds this many per k
_CPU_GRAIN = 64                # iterations a CPU thread takes at a time (dynamic load balance)


@ti.func
def _pair_less(ka: ti.i32, ia: ti.i32, kb: ti.i32, ib: ti.i32) -> ti.i32:
    return ti.cast((ka < kb) or (ka == kb and ia < ib), ti.i32)


@ti.func
def _safe_radius(u: ti.math.vec3, c: ti.math.ivec3, ring: ti.i32, cell_size: ti.f32) -> ti.f32:
    """Radius within which every point lies inside the cube of ``ring`` rings.

    ``u`` is the query in cell units; the margin covers float32 rounding of the cell assignment
    (relative to the coordinate magnitude)."""
    frac = u - ti.cast(c, ti.f32)
    b = ti.min(ti.min(frac, 1.0 - frac).min(), 1.0)
    margin = (ti.abs(u).max() + 2.0) * 1e-6
    return ti.max((ti.cast(ring, ti.f32) + b - margin) * cell_size, 0.0)


@ti.func
def _next_offset(d: ti.math.ivec3, ring: ti.i32) -> ti.math.ivec3:
    """Odometer step through the cube [-ring, ring]^3 (cyclic: n_cells steps from any start
    visit every cell once), without the integer divisions of decoding a flat index."""
    e = d
    e[0] += 1
    if e[0] > ring:
        e[0] = -ring
        e[1] += 1
        if e[1] > ring:
            e[1] = -ring
            e[2] += 1
            if e[2] > ring:
                e[2] = -ring
    return e


@ti.func
def _box_margin(u: ti.math.vec3) -> ti.f32:
    """Slack for float32 rounding of the cell assignment (relative to the coordinate magnitude)."""
    return (ti.abs(u).max() + 2.0) * 1e-6


@ti.func
def _box_gap_sq(frac: ti.math.vec3, d: ti.math.ivec3, margin: ti.f32) -> ti.f32:
    """Squared lower bound, in cell units, of the distance from a query at ``frac`` in its cell
    to any point of the cell at offset d."""
    gap = ti.math.vec3(0.0)
    for a in ti.static(range(3)):
        if d[a] > 0:
            gap[a] = ti.cast(d[a], ti.f32) - frac[a]
        elif d[a] < 0:
            gap[a] = frac[a] - 1.0 - ti.cast(d[a], ti.f32)
    g = ti.max(gap - margin, 0.0)
    return g.dot(g)


@ti.func
def _box_distance(u: ti.math.vec3, c: ti.math.ivec3, d: ti.math.ivec3, cell_size: ti.f32) -> ti.f32:
    """Lower bound of the distance from the query to any point of cell c + d."""
    return ti.sqrt(_box_gap_sq(u - ti.cast(c, ti.f32), d, _box_margin(u))) * cell_size


@ti.func
def _cell_range(target: ti.math.ivec3, brute: ti.i32, n: ti.i32, bstart: ti.template(),
                mask: ti.i32) -> ti.math.ivec2:
    """Range of sorted positions to scan for a cell (its hash bucket), or all points when brute."""
    rg = ti.math.ivec2(0, n)
    if brute == 0:
        h = cell_hash(target, mask)
        rg = ti.math.ivec2(bstart[h], bstart[h + 1])
    return rg


@ti.func
def _is_member(j: ti.i32, target: ti.math.ivec3, brute: ti.i32, qi: ti.i32, order: ti.template(),
               scell: ti.template()) -> ti.i32:
    """Point j is a candidate: not the query, and in the looked-up cell (buckets hold colliding cells)."""
    same = ti.cast(scell[j, 0] == target[0], ti.i32) & ti.cast(scell[j, 1] == target[1], ti.i32) \
        & ti.cast(scell[j, 2] == target[2], ti.i32)
    return ti.cast(order[j] != qi, ti.i32) & (same | brute)


@ti.func
def _distance(j: ti.i32, q: ti.math.vec3, sxyz: ti.template()) -> ti.f32:
    p = ti.math.vec3(sxyz[j, 0], sxyz[j, 1], sxyz[j, 2]) - q
    return ti.sqrt(p.dot(p))


@ti.func
def _pack(key: ti.i32, idx: ti.i32) -> ti.i64:
    """(key, index) as one word ordered as the pair (both are >= 0): one comparison and one
    move per step of the list's insertion sort instead of two."""
    return (ti.cast(key, ti.i64) << 32) | ti.cast(idx, ti.i64)


@ti.func
def _key_of(packed: ti.i64) -> ti.i32:
    return ti.cast(packed >> 32, ti.i32)


@ti.func
def _idx_of(packed: ti.i64) -> ti.i32:
    return ti.cast(packed & ti.i64(0xFFFFFFFF), ti.i32)


@ti.func
def _insert_at(best: ti.template(), pos: ti.i32, packed: ti.i64):
    """Put a packed pair at slot ``pos`` or before it, shifting larger pairs of slots < pos one
    up (slot ``pos`` itself is free or dropped): one insertion-sort step."""
    while pos > 0:
        if packed < best[pos - 1]:
            best[pos] = best[pos - 1]
            pos -= 1
        else:
            break
    best[pos] = packed


@ti.func
def _offer_best(best: ti.template(), size: ti.i32, k: ti.i32, packed: ti.i64) -> ti.i32:
    """Offer a packed (key, idx) pair to the ascending list of the k smallest pairs so far
    (insertion from the end; the k-th is always at size - 1); returns the new size."""
    pos = -1
    if size < k:
        pos = size
        size += 1
    elif packed < best[k - 1]:
        pos = k - 1
    if pos >= 0:
        _insert_at(best, pos, packed)
    return size


@ti.func
def _kth_distance(best: ti.template(), k: ti.i32) -> ti.f32:
    """Distance of the k-th of a full list (keys are squared-distance float bits)."""
    return ti.sqrt(ti.bit_cast(_key_of(best[k - 1]), ti.f32))


@ti.func
def _emit_best(best: ti.template(), size: ti.i32, k: ti.i32, qi: ti.i32,
               self_slots: ti.i32, out_idx: ti.template(), out_dist: ti.template(),
               out_mean: ti.template(), emit_rows: ti.i32, ranked: ti.template()):
    """Write the row (ascending (distance, index)) or its mean (summed in that canonical order,
    so every scan order gives the same bits)."""
    # the k hold (squared distance, index); distances are their float32 square roots, which may
    # tie where the squares differ: the row is put in (distance, index) order again
    for r in range(k):
        dist = ti.sqrt(ti.bit_cast(_key_of(best[r]), ti.f32))
        best[r] = _pack(ti.bit_cast(dist, ti.i32), _idx_of(best[r]))
    if ti.static(ranked):
        # in any order (the cell kernel's buffer): each pair's place is its rank, counted
        # branch-free (the pairs are distinct: one per point), where an insertion sort's exits
        # mispredicted once per pair
        row = ti.Vector([0] * SMALL_K, ti.i64)
        for r in range(k):
            v = best[r]
            rank = 0
            for t in range(k):
                rank += ti.cast(best[t] < v, ti.i32)
            row[rank] = v
        for r in range(k):
            best[r] = row[r]
    else:
        # an ascending list (the block search's): an insertion pass for the few such ties
        for r in range(1, k):
            _insert_at(best, r, best[r])
    dist_sum = 0.0
    for r in range(k):
        dist = ti.bit_cast(_key_of(best[r]), ti.f32)
        if emit_rows != 0:
            out_idx[qi, r] = _idx_of(best[r])
            out_dist[qi, r] = dist
        else:
            dist_sum += dist
    if emit_rows == 0:
        out_mean[qi] = dist_sum / ti.cast(k + self_slots, ti.f32)


@ti.func
def _offer_run(lo: ti.i32, hi: ti.i32, s: ti.i32, q: ti.math.vec3, best: ti.template(),
               size: ti.i32, k: ti.i32, order: ti.template(),
               sxyz: ti.template(), bound: ti.f32) -> ti.i32:
    """Offer the points at sorted positions [lo, hi) (except s, the query) that lie within
    ``bound`` (an upper bound on the k-th distance, +inf when none is known) to the list of
    the k smallest (squared distance, index) pairs."""
    # keys are the float bits of squared distances (ordered as the floats, no sqrt per candidate)
    top = ti.bit_cast(bound * bound * 1.00001, ti.i32)
    if size == k:
        top = ti.min(top, _key_of(best[k - 1]))
    for j in range(lo, hi):
        p = ti.math.vec3(sxyz[j, 0], sxyz[j, 1], sxyz[j, 2]) - q
        key = ti.bit_cast(p.dot(p), ti.i32)
        if key <= top and j != s:
            size = _offer_best(best, size, k, _pack(key, order[j]))
            if size == k:
                top = ti.min(top, _key_of(best[k - 1]))
    return size


@ti.func
def _cell_run(target: ti.math.ivec3, bstart: ti.template(), scell: ti.template(), mask: ti.i32) -> ti.math.ivec2:
    """Sorted positions [lo, hi) of a cell's points (empty when unoccupied): its hash bucket,
    less the points of other cells sharing the bucket (a bucket is sorted by cell)."""
    h = cell_hash(target, mask)
    lo = 0
    hi = 0
    for j in range(bstart[h], bstart[h + 1]):
        if scell[j, 0] == target[0] and scell[j, 1] == target[1] and scell[j, 2] == target[2]:
            if hi == 0:
                lo = j
            hi = j + 1
    return ti.math.ivec2(lo, hi)


@ti.func
def _select_k(buf: ti.template(), m: ti.i32, k: ti.i32) -> ti.i64:
    """Quickselect on the m distinct packed pairs of ``buf``: afterwards buf[0:k] holds the k
    smallest (in no order); returns the k-th (their largest). Partitions are branch-free (a
    conditional swap per element), so unpredictable comparisons cost no mispredictions."""
    lo = 0
    hi = m - 1
    target = k - 1
    while lo < hi:
        mid = (lo + hi) >> 1
        # median of three moved to hi as the pivot
        a = buf[lo]
        b = buf[mid]
        c = buf[hi]
        med_pos = hi
        if (a < b) != (a < c):
            med_pos = lo
        elif (b < a) != (b < c):
            med_pos = mid
        pivot = buf[med_pos]
        buf[med_pos] = c
        buf[hi] = pivot
        store = lo
        for i in range(lo, hi):
            v = buf[i]
            t = buf[store]
            less = v < pivot
            buf[store] = ti.select(less, v, t)
            buf[i] = ti.select(less, t, v)
            store += ti.cast(less, ti.i32)
        buf[hi] = buf[store]
        buf[store] = pivot
        if store == target:
            lo = hi
        elif store < target:
            lo = store + 1
        else:
            hi = store - 1
    return buf[target]


@ti.func
def _append_run(lo: ti.i32, hi: ti.i32, s: ti.i32, q: ti.math.vec3, buf: ti.template(), m: ti.i32,
                k: ti.i32, cap: ti.i32, top: ti.i32, order: ti.template(), sxyz: ti.template()) -> ti.math.ivec2:
    """Append the points at sorted positions [lo, hi) (except s, the query) whose squared-distance
    key is at most ``top`` to the unordered buffer of m candidates; a full buffer (``cap``) is cut
    to its k smallest, whose k-th becomes the new ``top``. Returns (m, top). The append is
    branch-free: a candidate is always written at slot m, and m advances only when it passes."""
    for j in range(lo, hi):
        p = ti.math.vec3(sxyz[j, 0], sxyz[j, 1], sxyz[j, 2]) - q
        key = ti.bit_cast(p.dot(p), ti.i32)
        buf[m] = _pack(key, order[j])
        m += ti.cast(key <= top, ti.i32) & ti.cast(j != s, ti.i32)
        if m == cap:
            top = _key_of(_select_k(buf, m, k))
            m = k
    return ti.math.ivec2(m, top)


@ti.func
def _settle_buffer(buf: ti.template(), m: ti.i32, k: ti.i32, top: ti.i32) -> ti.math.ivec2:
    """Cut the buffer to its k smallest when it holds more (their k-th becomes ``top``); with
    exactly k, ``top`` becomes their largest. Returns (size, top)."""
    if m > k:
        top = _key_of(_select_k(buf, m, k))
        m = k
    elif m == k:
        kth = buf[0]
        for r in range(1, k):
            kth = ti.max(kth, buf[r])
        top = _key_of(kth)
    return ti.math.ivec2(m, top)


@ti.kernel
def _knn_cells(order: ti.types.ndarray(dtype=ti.i32, ndim=1), sxyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
               scell: ti.types.ndarray(dtype=ti.i32, ndim=2), bstart: ti.types.ndarray(dtype=ti.i32, ndim=1),
               cell_start: ti.types.ndarray(dtype=ti.i32, ndim=1),
               mask: ti.i32, ox: ti.f32, oy: ti.f32, oz: ti.f32, cell_size: ti.f32, inv_cell: ti.f32,
               k: ti.i32, self_slots: ti.i32, pending: ti.types.ndarray(dtype=ti.i32, ndim=1),
               out_idx: ti.types.ndarray(dtype=ti.i32, ndim=2), out_dist: ti.types.ndarray(dtype=ti.f32, ndim=2),
               out_mean: ti.types.ndarray(dtype=ti.f32, ndim=1), emit_rows: ti.i32):
    """k <= SMALL_K, one occupied cell per iteration: the runs of its 27 neighbouring cells are
    looked up once, then each of its points keeps an ascending register list of the nearest
    candidates from them. A point whose k-th is not inside the cube's safe radius adds the cells of the second
    ring that its k-th can reach; if that does not settle it either, it is marked in ``pending``
    (indexed by sorted position) for the ring-growing kernel."""
    ti.loop_config(block_dim=ti.static(cpu_block_dim(_CPU_GRAIN)))
    for ci in range(cell_start.shape[0] - 1):
        a = cell_start[ci]
        b = cell_start[ci + 1]
        c = ti.math.ivec3(scell[a, 0], scell[a, 1], scell[a, 2])
        run_lo = ti.Vector([0] * 27, ti.i32)
        run_hi = ti.Vector([0] * 27, ti.i32)
        run_dx = ti.Vector([0] * 27, ti.i32)          # the run's cell offset + 1 per axis
        run_dy = ti.Vector([0] * 27, ti.i32)
        run_dz = ti.Vector([0] * 27, ti.i32)
        n_runs = 0
        # own cell, then the 6 face, 12 edge and 8 corner neighbours: near candidates first,
        # so the list's k-th tightens early and most later candidates fail one comparison
        for rank in range(4):
            for t in range(27):
                d = ti.math.ivec3(t % 3 - 1, (t // 3) % 3 - 1, t // 9 - 1)
                if ti.abs(d).sum() == rank:
                    rg = ti.math.ivec2(a, b)
                    if rank > 0:
                        rg = _cell_run(c + d, bstart, scell, mask)
                    if rg[1] > rg[0]:
                        run_lo[n_runs] = rg[0]
                        run_hi[n_runs] = rg[1]
                        run_dx[n_runs] = d[0] + 1
                        run_dy[n_runs] = d[1] + 1
                        run_dz[n_runs] = d[2] + 1
                        n_runs += 1
        prev_q = ti.math.vec3(0.0)
        prev_kth = ti.math.inf
        cap = ti.min(_BUF, ti.max(_CAP_PER_K * k, 16))
        # one buffer for all the cell's queries: slots at or beyond a query's count are never read
        buf = ti.Vector([0] * _BUF, ti.i64)
        for s in range(a, b):
            q = ti.math.vec3(sxyz[s, 0], sxyz[s, 1], sxyz[s, 2])
            u = (q - ti.math.vec3(ox, oy, oz)) * inv_cell
            # the previous query's k nearest plus that query itself are k points other than q
            # within prev_kth + |q - prev_q|: a bound that rejects most candidates up front
            bound = (prev_kth + (q - prev_q).norm()) * 1.00001 + 1e-30
            # keys are the float bits of squared distances (ordered as the floats, no sqrt per
            # candidate); ``top`` is the largest key that may still be among the k nearest
            top = ti.bit_cast(bound * bound * 1.00001, ti.i32)
            m = 0
            # cells are tested in squared cell units: no square root per cell and candidate
            frac = u - ti.cast(c, ti.f32)
            margin = _box_margin(u)
            inv_cell_sq = inv_cell * inv_cell
            # squared gaps to the cells before, at and after the query's along each axis
            # (_box_gap_sq's terms): a run's gap is three look-ups and two additions
            below = ti.max(frac - margin, 0.0)
            above = ti.max(1.0 - frac - margin, 0.0)
            gap_x = ti.Vector([below[0] * below[0], 0.0, above[0] * above[0]])
            gap_y = ti.Vector([below[1] * below[1], 0.0, above[1] * above[1]])
            gap_z = ti.Vector([below[2] * below[2], 0.0, above[2] * above[2]])
            for r in range(n_runs):
                gap_sq = gap_x[run_dx[r]] + gap_y[run_dy[r]] + gap_z[run_dz[r]]
                if gap_sq <= ti.bit_cast(top, ti.f32) * inv_cell_sq:
                    mt = _append_run(run_lo[r], run_hi[r], s, q, buf, m, k, cap, top, order, sxyz)
                    m = mt[0]
                    top = mt[1]
            mt = _settle_buffer(buf, m, k, top)
            m = mt[0]
            top = mt[1]
            settled = 0
            if m == k and ti.sqrt(ti.bit_cast(top, ti.f32)) < _safe_radius(u, c, 1, cell_size):
                settled = 1
            else:
                for t in range(125):
                    d = ti.math.ivec3(t % 5 - 2, (t // 5) % 5 - 2, t // 25 - 2)
                    if ti.abs(d).max() == 2:
                        if _box_gap_sq(frac, d, margin) <= ti.bit_cast(top, ti.f32) * inv_cell_sq:
                            rg = _cell_run(c + d, bstart, scell, mask)
                            mt = _append_run(rg[0], rg[1], s, q, buf, m, k, cap, top, order, sxyz)
                            m = mt[0]
                            top = mt[1]
                mt = _settle_buffer(buf, m, k, top)
                m = mt[0]
                top = mt[1]
                if m == k and ti.sqrt(ti.bit_cast(top, ti.f32)) < _safe_radius(u, c, 2, cell_size):
                    settled = 1
            if m == k:
                prev_q = q
                prev_kth = ti.sqrt(ti.bit_cast(top, ti.f32))
            if settled:
                # _emit_best orders the k by (distance, index) itself
                _emit_best(buf, m, k, order[s], self_slots, out_idx, out_dist, out_mean, emit_rows, True)
            pending[s] = 1 - settled


@ti.func
def _block_search(q: ti.math.vec3, s: ti.i32, best: ti.template(), k: ti.i32, order: ti.template(),
                  sxyz: ti.template(), scell: ti.template(), bstart: ti.template(), mask: ti.i32,
                  ox: ti.f32, oy: ti.f32, oz: ti.f32, cell_size: ti.f32, inv_cell: ti.f32,
                  brute_blocks: ti.i32, block_bits: ti.i32) -> ti.i32:
    """Fill ``best`` with the k nearest grid points of q (sorted position s excluded; -1: none)
    and return how many it holds. Searches blocks of cells shell by shell around q's block,
    skipping blocks farther than the current k-th; past ``brute_blocks`` it scans all points."""
    n = sxyz.shape[0]
    block = 1 << block_bits
    span = 1 << (3 * block_bits)
    block_size = cell_size * ti.cast(block, ti.f32)
    # q's cell as the grid assigns it (cell_of: the same arithmetic as the build)
    cb = cell_of(q[0], q[1], q[2], ox, oy, oz, inv_cell) >> block_bits
    u = (q - ti.math.vec3(ox, oy, oz)) * (inv_cell / ti.cast(block, ti.f32))
    size = 0
    ring = 0
    done = 0
    while done == 0:
        if (2 * ring + 1) * (2 * ring + 1) * (2 * ring + 1) > brute_blocks:
            # far from everything: every point outside the rings already scanned
            for j in range(n):
                if j != s:
                    bj = ti.math.ivec3(scell[j, 0], scell[j, 1], scell[j, 2]) >> block_bits
                    if ti.abs(bj - cb).max() >= ring:
                        size = _offer_run(j, j + 1, s, q, best, size, k, order, sxyz, ti.math.inf)
            done = 1
        else:
            # the shell of blocks at Chebyshev distance ring: whole faces at dz or dy = +-ring,
            # otherwise only dx = +-ring
            for dz in range(-ring, ring + 1):
                for dy in range(-ring, ring + 1):
                    step = 1
                    if ti.abs(dz) != ring and ti.abs(dy) != ring:
                        step = ti.max(2 * ring, 1)
                    dx = -ring
                    while dx <= ring:
                        d = ti.math.ivec3(dx, dy, dz)
                        visit = 1
                        if size == k:
                            if _box_distance(u, cb, d, block_size) > _kth_distance(best, k):
                                visit = 0
                        if visit:
                            target = cb + d
                            base = cell_hash(target << block_bits, mask)   # its span of buckets
                            for j in range(bstart[base], bstart[base + span]):
                                if scell[j, 0] >> block_bits == target[0] and scell[j, 1] >> block_bits == target[1] \
                                        and scell[j, 2] >> block_bits == target[2]:
                                    size = _offer_run(j, j + 1, s, q, best, size, k, order, sxyz, ti.math.inf)
                        dx += step
            if size == k and _kth_distance(best, k) < _safe_radius(u, cb, ring, block_size):
                done = 1
            else:
                ring += 1
    return size


@ti.kernel
def _knn_blocks(order: ti.types.ndarray(dtype=ti.i32, ndim=1), sxyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                scell: ti.types.ndarray(dtype=ti.i32, ndim=2), bstart: ti.types.ndarray(dtype=ti.i32, ndim=1),
                queries: ti.types.ndarray(dtype=ti.i32, ndim=1),
                mask: ti.i32, ox: ti.f32, oy: ti.f32, oz: ti.f32, cell_size: ti.f32, inv_cell: ti.f32,
                k: ti.i32, brute_blocks: ti.i32, self_slots: ti.i32, block_bits: ti.i32,
                out_idx: ti.types.ndarray(dtype=ti.i32, ndim=2), out_dist: ti.types.ndarray(dtype=ti.f32, ndim=2),
                out_mean: ti.types.ndarray(dtype=ti.f32, ndim=1), emit_rows: ti.i32):
    """k <= SMALL_K, one query per thread for the points at sorted positions ``queries``
    (``_block_search``). ``block_bits`` 2: blocks of 4x4x4 cells (one contiguous range of 64
    buckets, ``grid.cell_hash``): the sparse regions and outliers the cell kernel leaves on CPUs,
    every query on GPUs. (With single cells, an isolated outlier walked so many empty shells that
    it reached the scan of every point, whose long invocation lavapipe cut short: wrong rows. Mesa's
    llvmpipe ends all loops of an invocation after 65,535 iterations in all, silently: an isolated
    point's search can still run that long there, tests/test_determinism.py.)"""
    for qs in range(queries.shape[0]):
        s = queries[qs]
        q = ti.math.vec3(sxyz[s, 0], sxyz[s, 1], sxyz[s, 2])
        best = ti.Vector([0] * SMALL_K, ti.i64)
        size = _block_search(q, s, best, k, order, sxyz, scell, bstart, mask, ox, oy, oz, cell_size,
                             inv_cell, brute_blocks, block_bits)
        _emit_best(best, size, k, order[s], self_slots, out_idx, out_dist, out_mean, emit_rows, False)


@ti.kernel
def _nearest_of(query_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), order: ti.types.ndarray(dtype=ti.i32, ndim=1),
                sxyz: ti.types.ndarray(dtype=ti.f32, ndim=2), scell: ti.types.ndarray(dtype=ti.i32, ndim=2),
                bstart: ti.types.ndarray(dtype=ti.i32, ndim=1),
                mask: ti.i32, ox: ti.f32, oy: ti.f32, oz: ti.f32, cell_size: ti.f32, inv_cell: ti.f32,
                brute_blocks: ti.i32, block_bits: ti.i32,
                out_idx: ti.types.ndarray(dtype=ti.i32, ndim=1), out_dist: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    """The nearest grid point of every query point (another point set): (squared distance,
    index) minimum, so ties go to the lower index."""
    for qi in range(query_xyz.shape[0]):
        q = ti.math.vec3(query_xyz[qi, 0], query_xyz[qi, 1], query_xyz[qi, 2])
        best = ti.Vector([0] * 1, ti.i64)
        _block_search(q, -1, best, 1, order, sxyz, scell, bstart, mask, ox, oy, oz, cell_size,
                      inv_cell, brute_blocks, block_bits)
        out_idx[qi] = _idx_of(best[0])
        out_dist[qi] = ti.sqrt(ti.bit_cast(_key_of(best[0]), ti.f32))


@ti.func
def _bins_top(lo: ti.i32, width_bits: ti.i32) -> ti.f32:
    """Distance at the top of the bit range [lo, lo + 2^width_bits), +inf where that overflows."""
    top = ti.math.inf
    if width_bits < 30:
        width = 1 << width_bits
        if lo < _INF_KEY - width:
            top = ti.bit_cast(lo + width, ti.f32)
    return top


@ti.kernel
def _knn_select(order: ti.types.ndarray(dtype=ti.i32, ndim=1), sxyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                scell: ti.types.ndarray(dtype=ti.i32, ndim=2), bstart: ti.types.ndarray(dtype=ti.i32, ndim=1),
                mask: ti.i32, ox: ti.f32, oy: ti.f32, oz: ti.f32, cell_size: ti.f32, inv_cell: ti.f32,
                k: ti.i32, brute_cells: ti.i32, self_slots: ti.i32,
                out_idx: ti.types.ndarray(dtype=ti.i32, ndim=2), out_dist: ti.types.ndarray(dtype=ti.f32, ndim=2),
                out_mean: ti.types.ndarray(dtype=ti.f32, ndim=1), emit_rows: ti.i32):
    """k > SMALL_K: selection of the k-th (distance, index) by counting, then one emit pass."""
    n = sxyz.shape[0]
    for s in range(n):
        qi = order[s]
        q = ti.math.vec3(sxyz[s, 0], sxyz[s, 1], sxyz[s, 2])
        c = ti.math.ivec3(scell[s, 0], scell[s, 1], scell[s, 2])
        u = (q - ti.math.vec3(ox, oy, oz)) * inv_cell

        # 1. the ring whose safe radius holds at least k candidates (or all points). The same
        #    pass histograms the distance bits of the top two octaves below the safe radius
        #    (32 bins of 1/16 octave), so a first narrowing comes for free.
        ring = 1
        brute = 0
        searching = 1
        sr = 0.0
        bound = 0.0
        lo = 0
        shift = 0
        below = 0                  # candidates known to rank before the current bins
        dist_sum = 0.0             # their distance sum (mean only)
        hist = ti.Vector([0] * _BINS, ti.i32)
        hsum = ti.Vector([0.0] * _BINS, ti.f32)
        while searching:
            sr = _safe_radius(u, c, ring, cell_size)
            if brute:
                sr = ti.math.inf
            span = 2 * ring + 1
            n_cells = span * span * span
            if brute:
                n_cells = 1
                shift = _BRUTE_SHIFT
                lo = 0
            else:
                shift = _FIRST_SHIFT
                lo = ti.max(ti.bit_cast(sr, ti.i32) - (_BINS << _FIRST_SHIFT), 0)
            for bz in range(_BINS):
                hist[bz] = 0
                hsum[bz] = 0.0
            bound = sr
            count = 0
            below = 0
            dist_sum = 0.0
            d = ti.math.ivec3(0, 0, 0)
            for t in range(n_cells):
                if t > 0:
                    d = _next_offset(d, ring)
                target = c + d
                rg = ti.math.ivec2(0, 0)
                if brute or _box_distance(u, c, d, cell_size) <= bound:
                    rg = _cell_range(target, brute, n, bstart, mask)
                for j in range(rg[0], rg[1]):
                    if _is_member(j, target, brute, qi, order, scell):
                        dist = _distance(j, q, sxyz)
                        if dist < sr or brute:
                            count += 1
                            v = ti.bit_cast(dist, ti.i32)
                            if v < lo:
                                below += 1
                                dist_sum += dist
                            else:
                                hb = (v - lo) >> shift
                                if hb < _BINS:
                                    hist[hb] += 1
                                    hsum[hb] += dist
            if count >= k or brute:
                searching = 0
            elif (2 * ring + 3) * (2 * ring + 3) * (2 * ring + 3) > brute_cells:
                brute = 1
            else:
                ring += 1
        span = 2 * ring + 1
        n_cells = span * span * span
        if brute:
            n_cells = 1

        # 2. radix narrowing: choose the bin holding the k-th, re-histogram inside it (5 bits a
        #    pass) until it holds at most SMALL_K candidates. Phase 1 splits candidates at
        #    exactly the k-th distance by point index.
        phase = 0
        rank = k
        t_key = 0
        fresh = 1                  # hist already holds the pass over the current bins
        if below >= rank:
            fresh = 0              # the k-th is closer than the first bins: restart from 0
            lo = 0
            below = 0
            dist_sum = 0.0
            shift = 0
            while (ti.bit_cast(sr, ti.i32) >> shift) >= _BINS:
                shift += 1
        narrowing = 1
        while narrowing:
            if fresh == 0:
                for bz in range(_BINS):
                    hist[bz] = 0
                    hsum[bz] = 0.0
                bound = sr
                if phase == 0:
                    bound = _bins_top(lo, shift + _BIN_BITS)
                else:
                    bound = ti.bit_cast(t_key, ti.f32)
                d = ti.math.ivec3(0, 0, 0)
                for t in range(n_cells):
                    if t > 0:
                        d = _next_offset(d, ring)
                    target = c + d
                    rg = ti.math.ivec2(0, 0)
                    if brute or _box_distance(u, c, d, cell_size) <= bound:
                        rg = _cell_range(target, brute, n, bstart, mask)
                    for j in range(rg[0], rg[1]):
                        if _is_member(j, target, brute, qi, order, scell):
                            dist = _distance(j, q, sxyz)
                            v = ti.bit_cast(dist, ti.i32)
                            if phase == 1:
                                v = -1
                                if ti.bit_cast(dist, ti.i32) == t_key:
                                    v = order[j]
                            if v >= lo:
                                hb = (v - lo) >> shift
                                if hb < _BINS:
                                    hist[hb] += 1
                                    hsum[hb] += dist
            fresh = 0
            cum = below
            chosen = _BINS - 1
            found = 0
            for hb in range(_BINS):
                if found == 0:
                    if cum + hist[hb] >= rank:
                        chosen = hb
                        found = 1
                    else:
                        cum += hist[hb]
                        if phase == 0:
                            dist_sum += hsum[hb]
            below = cum
            lo += chosen << shift
            in_bin = hist[chosen]
            if in_bin <= SMALL_K:
                narrowing = 0
            elif shift == 0:
                # in_bin candidates share the k-th distance: select among them by index
                t_key = lo
                phase = 1
                rank -= below
                below = 0
                dist_sum += ti.cast(rank, ti.f32) * ti.bit_cast(t_key, ti.f32)
                lo = 0
                while (n >> shift) >= _BINS:
                    shift += 1
            else:
                shift = ti.max(shift - _BIN_BITS, 0)

        # 3. the few candidates of the chosen bin; the wanted one by counting
        buf_key = ti.Vector([0] * SMALL_K, ti.i32)
        buf_idx = ti.Vector([0] * SMALL_K, ti.i32)
        size = 0
        bound = ti.bit_cast(t_key, ti.f32)
        if phase == 0:
            bound = _bins_top(lo, shift)
        d = ti.math.ivec3(0, 0, 0)
        for t in range(n_cells):
            if t > 0:
                d = _next_offset(d, ring)
            target = c + d
            rg = ti.math.ivec2(0, 0)
            if brute or _box_distance(u, c, d, cell_size) <= bound:
                rg = _cell_range(target, brute, n, bstart, mask)
            for j in range(rg[0], rg[1]):
                if _is_member(j, target, brute, qi, order, scell):
                    key = ti.bit_cast(_distance(j, q, sxyz), ti.i32)
                    v = key
                    if phase == 1:
                        v = -1
                        if key == t_key:
                            v = order[j]
                    if v >= lo:
                        if (v - lo) >> shift == 0:
                            if size < SMALL_K:
                                buf_key[size] = key
                                buf_idx[size] = order[j]
                                size += 1
        wanted = rank - below - 1
        t_idx = 0
        for cand in range(size):
            smaller = 0
            for other in range(size):
                smaller += _pair_less(buf_key[other], buf_idx[other], buf_key[cand], buf_idx[cand])
            if smaller <= wanted and phase == 0:
                dist_sum += ti.bit_cast(buf_key[cand], ti.f32)
            if smaller == wanted:
                t_key = buf_key[cand]
                t_idx = buf_idx[cand]

        # 4. rows only: emit every candidate up to (t_key, t_idx)
        if emit_rows != 0:
            emitted = 0
            bound = ti.bit_cast(t_key, ti.f32)
            d = ti.math.ivec3(0, 0, 0)
            for t in range(n_cells):
                if t > 0:
                    d = _next_offset(d, ring)
                target = c + d
                rg = ti.math.ivec2(0, 0)
                if brute or _box_distance(u, c, d, cell_size) <= bound:
                    rg = _cell_range(target, brute, n, bstart, mask)
                for j in range(rg[0], rg[1]):
                    if _is_member(j, target, brute, qi, order, scell):
                        dist = _distance(j, q, sxyz)
                        key = ti.bit_cast(dist, ti.i32)
                        idx = order[j]
                        if _pair_less(key, idx, t_key, t_idx) | (ti.cast(key == t_key, ti.i32) & ti.cast(idx == t_idx, ti.i32)):
                            if emitted < k:
                                out_idx[qi, emitted] = idx
                                out_dist[qi, emitted] = dist
                            emitted += 1
        if emit_rows != 0:
            # heap sort of the row in place (global memory): ascending (distance, index)
            m = k
            start = m // 2 - 1
            end = m - 1
            while end > 0:
                pos = 0
                if start >= 0:
                    pos = start
                    start -= 1
                else:
                    tk = out_dist[qi, 0]
                    tx = out_idx[qi, 0]
                    out_dist[qi, 0] = out_dist[qi, end]
                    out_idx[qi, 0] = out_idx[qi, end]
                    out_dist[qi, end] = tk
                    out_idx[qi, end] = tx
                    end -= 1
                while True:
                    child = 2 * pos + 1
                    if child > end:
                        break
                    sibling = ti.min(child + 1, end)
                    if child + 1 <= end:
                        if _pair_less(ti.bit_cast(out_dist[qi, child], ti.i32), out_idx[qi, child],
                                      ti.bit_cast(out_dist[qi, sibling], ti.i32), out_idx[qi, sibling]):
                            child = sibling
                    if _pair_less(ti.bit_cast(out_dist[qi, pos], ti.i32), out_idx[qi, pos],
                                  ti.bit_cast(out_dist[qi, child], ti.i32), out_idx[qi, child]):
                        tk = out_dist[qi, pos]
                        tx = out_idx[qi, pos]
                        out_dist[qi, pos] = out_dist[qi, child]
                        out_idx[qi, pos] = out_idx[qi, child]
                        out_dist[qi, child] = tk
                        out_idx[qi, child] = tx
                        pos = child
                    else:
                        break
        else:
            out_mean[qi] = dist_sum / ti.cast(k + self_slots, ti.f32)


def _prepare(xyz, k, grid, cell_size, points_per_cell):
    if grid is None:
        grid = build_grid_into(xyz, cell_size, points_per_cell, private=True)
    elif grid.n != length(xyz):
        raise ValueError(f"grid was built over {grid.n} points, xyz has {length(xyz)}")
    return grid


def _check_k(k, n):
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
        raise TypeError(f"k must be a whole number of neighbours, got {k!r}")
    k = int(k)
    if not 1 <= k <= MAX_K:
        raise ValueError(f"k must be in 1..{MAX_K}, got {k}")
    if k >= n:
        raise ValueError(f"k={k} neighbours need at least k+1 points (the point itself is excluded); "
                         f"the cloud has {n}")
    return k


def _brute_cells(n: int) -> int:
    # a cube of more cells than this costs more lookups than scanning every point
    return max(125, n // 8)


def _run_scan(grid: Grid, k: int, out_idx, out_dist, out_mean, emit_rows: bool, self_slots: int):
    # rows or means: a runtime flag, not a template, so that each scan kernel compiles once per
    # process (each template value is another kernel to transform and JIT: ~0.2 s each)
    emit_rows = int(emit_rows)
    ox, oy, oz = grid.origin
    geometry = (grid.table_mask, ox, oy, oz, grid.cell_size, grid.inv_cell, k)
    if k > SMALL_K:
        _knn_select(grid.order, grid.sorted_xyz, grid.sorted_cell, grid.bucket_start, *geometry,
                    _brute_cells(grid.n), self_slots, out_idx, out_dist, out_mean, emit_rows)
        return
    if not host_memory_backend():
        # GPUs: one query per thread (the cell kernel runs one cell's queries serially in one
        # thread, which suits CPUs; lavapipe ends loops after 65,535 iterations per invocation)
        queries = scratch("knn.all_queries", ti.i32, (grid.n,))
        _iota(queries)
        _knn_blocks(grid.order, grid.sorted_xyz, grid.sorted_cell, grid.bucket_start, queries,
                    *geometry, _brute_cells(grid.n), self_slots, _BLOCK_BITS, out_idx, out_dist, out_mean,
                    emit_rows)
        return
    pending = scratch("knn.pending", ti.i32, (grid.n,))
    _knn_cells(grid.order, grid.sorted_xyz, grid.sorted_cell, grid.bucket_start, grid.cell_start,
               *geometry, self_slots, pending, out_idx, out_dist, out_mean, emit_rows)
    queries, n_pending = compact_mask(pending)
    if n_pending:
        _knn_blocks(grid.order, grid.sorted_xyz, grid.sorted_cell, grid.bucket_start, queries,
                    *geometry, _brute_cells(grid.n), self_slots, _BLOCK_BITS, out_idx, out_dist, out_mean,
                    emit_rows)


@ti.kernel
def _iota(out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(out.shape[0]):
        out[i] = i


def default_points_per_cell(k: int) -> float:
    """Cells of about 1.25 k points on a surface for small k (the 3x3 cells around a query then hold
    its k nearest nearly always, and few queries need the second ring or the block search);
    finer cells for large k, where the passes skip cells whose box lies beyond the current
    bound, so fewer wasted candidates are scanned."""
    return max(8.0, 1.25 * k) if k <= SMALL_K else max(16.0, k / PPC_DIV)


def knn(xyz, k: int, *, grid: Grid = None, cell_size: float = None):
    """Exact k nearest neighbours of every point, the point itself excluded.

    Returns (indices int32 (n, k), distances float32 (n, k)), each row sorted by (distance,
    index). numpy in -> numpy out; Taichi ndarray in -> ndarrays out. ``grid`` reuses a grid
    built over the same ``xyz``; ``cell_size`` overrides the automatic cell size."""
    n = length(xyz)
    k = _check_k(k, n)
    pts = points_array(xyz)
    grid = _prepare(pts, k, grid, cell_size, default_points_per_cell(k))
    out_idx = output_array(ti.i32, (n, k), xyz)
    out_dist = output_array(ti.f32, (n, k), xyz)
    # the unused output of the kind the used ones are (numpy or ndarray): the scan kernels then
    # have one argument signature for knn and knn_mean_distance and compile once per process
    dummy = output_array(ti.f32, (1,), xyz)
    _run_scan(grid, k, out_idx, out_dist, dummy, True, 0)
    return like_input(out_idx, xyz), like_input(out_dist, xyz)


def knn_mean_distance(xyz, k: int, *, include_self: bool = False, grid: Grid = None,
                      cell_size: float = None):
    """Mean Euclidean distance from every point to its k nearest neighbours (float32 (n,)),
    without materialising an (n, k) array. ``include_self`` counts the point itself as one of
    the k at distance 0 (Open3D's convention): the mean is then over its k-1 nearest others
    plus a zero."""
    pts = points_array(xyz)
    n = length(pts)
    k = _check_k(k, n + 1 if include_self else n)      # with the point itself: k <= n
    others = k - 1 if include_self else k
    if others == 0:
        out = ndarray(ti.f32, (n,))   # only the point itself: distance 0
        return like_input(out, xyz)
    others = _check_k(others, n)
    grid = _prepare(pts, others, grid, cell_size, default_points_per_cell(others))
    out_mean = output_array(ti.f32, (n,), xyz)
    dummy_i = output_array(ti.i32, (1, 1), xyz)      # of out_mean's kind (see knn)
    dummy_f = output_array(ti.f32, (1, 1), xyz)
    _run_scan(grid, others, dummy_i, dummy_f, out_mean, False, 1 if include_self else 0)
    return like_input(out_mean, xyz)


NEAREST_POINTS_PER_CELL = 16.0  # k = 1 mostly settles in its own cell or the next ring


def nearest(reference, queries, *, grid: Grid = None, cell_size: float = None):
    """Nearest ``reference`` point of every ``queries`` point (two point sets, (n, 3) and (m, 3)
    float32, in the same local frame), exact, ties to the lower reference index.

    Returns (indices int32 (m,), distances float32 (m,)). numpy in -> numpy out; a Taichi
    ndarray of queries -> ndarrays out (numpy when m = 0: Taichi has no empty ndarrays).
    ``grid`` reuses a grid built over ``reference``; ``cell_size`` overrides the automatic one."""
    ref = points_array(reference, "reference")
    pts = points_array(queries, "queries")
    n, m = length(ref), length(pts)
    if n == 0:
        raise ValueError("nearest: the reference point set is empty")
    if m == 0:
        return np.zeros(0, np.int32), np.zeros(0, np.float32)
    grid = _prepare(ref, 1, grid, cell_size, NEAREST_POINTS_PER_CELL)
    out_idx = output_array(ti.i32, (m,), queries)
    out_dist = output_array(ti.f32, (m,), queries)
    ox, oy, oz = grid.origin
    _nearest_of(pts, grid.order, grid.sorted_xyz, grid.sorted_cell, grid.bucket_start, grid.table_mask,
                ox, oy, oz, grid.cell_size, grid.inv_cell, _brute_cells(grid.n), 0, out_idx, out_dist)
    return like_input(out_idx, queries), like_input(out_dist, queries)


# ---------------------------------------------------------------- radius search

@ti.kernel
def _radius_scan(order: ti.types.ndarray(dtype=ti.i32, ndim=1), sxyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                 scell: ti.types.ndarray(dtype=ti.i32, ndim=2), bstart: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 mask: ti.i32, rings: ti.i32, r2: ti.f32, count: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 offsets: ti.types.ndarray(dtype=ti.i32, ndim=1), out_idx: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 out_dist: ti.types.ndarray(dtype=ti.f32, ndim=1), fill: ti.template()):
    for s in range(sxyz.shape[0]):
        qi = order[s]
        q = ti.math.vec3(sxyz[s, 0], sxyz[s, 1], sxyz[s, 2])
        c = ti.math.ivec3(scell[s, 0], scell[s, 1], scell[s, 2])
        span = 2 * rings + 1
        m = 0
        base = 0
        if ti.static(fill):
            base = offsets[qi]
        d = ti.math.ivec3(0, 0, 0)
        for t in range(span * span * span):
            if t > 0:
                d = _next_offset(d, rings)
            target = c + d
            h = cell_hash(target, mask)
            for j in range(bstart[h], bstart[h + 1]):
                if scell[j, 0] == target[0] and scell[j, 1] == target[1] and scell[j, 2] == target[2] \
                        and order[j] != qi:
                    p = ti.math.vec3(sxyz[j, 0], sxyz[j, 1], sxyz[j, 2]) - q
                    d2 = p.dot(p)
                    if d2 <= r2:
                        if ti.static(fill):
                            # never past the row the count pass sized: a backend may round the
                            # two compilations differently at the sphere's boundary
                            if m < count[qi]:
                                out_idx[base + m] = order[j]
                                out_dist[base + m] = ti.sqrt(d2)
                        m += 1
        if ti.static(fill):
            # heap sort of the row in place by (distance, index)
            m = ti.min(m, count[qi])
            heap_start = m // 2 - 1
            end = m - 1
            while end > 0:
                pos = 0
                if heap_start >= 0:
                    pos = heap_start
                    heap_start -= 1
                else:
                    tk = out_dist[base]
                    tx = out_idx[base]
                    out_dist[base] = out_dist[base + end]
                    out_idx[base] = out_idx[base + end]
                    out_dist[base + end] = tk
                    out_idx[base + end] = tx
                    end -= 1
                while True:
                    child = 2 * pos + 1
                    if child > end:
                        break
                    sibling = ti.min(child + 1, end)
                    if child + 1 <= end:
                        if _pair_less(ti.bit_cast(out_dist[base + child], ti.i32), out_idx[base + child],
                                      ti.bit_cast(out_dist[base + sibling], ti.i32), out_idx[base + sibling]):
                            child = sibling
                    if _pair_less(ti.bit_cast(out_dist[base + pos], ti.i32), out_idx[base + pos],
                                  ti.bit_cast(out_dist[base + child], ti.i32), out_idx[base + child]):
                        tk = out_dist[base + pos]
                        tx = out_idx[base + pos]
                        out_dist[base + pos] = out_dist[base + child]
                        out_idx[base + pos] = out_idx[base + child]
                        out_dist[base + child] = tk
                        out_idx[base + child] = tx
                        pos = child
                    else:
                        break
        else:
            count[qi] = m


@ti.kernel
def _clip_counts(offsets: ti.types.ndarray(dtype=ti.i32, ndim=1), limit: ti.i32,
                 count: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(count.shape[0] - 1):
        count[i] = ti.min(offsets[i + 1] - offsets[i], limit)


@ti.kernel
def _copy_rows(offsets: ti.types.ndarray(dtype=ti.i32, ndim=1), idx: ti.types.ndarray(dtype=ti.i32, ndim=1),
               new_offsets: ti.types.ndarray(dtype=ti.i32, ndim=1), new_idx: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(new_offsets.shape[0] - 1):
        for r in range(new_offsets[i + 1] - new_offsets[i]):
            new_idx[new_offsets[i] + r] = idx[offsets[i] + r]


def _csr_offsets(count):
    n = length(count) - 1
    offsets = ndarray(ti.i32, (n + 1,))
    total = exclusive_scan_into(count, offsets)
    return offsets, total


def radius_search(xyz, radius: float, *, max_neighbors: int = None, grid: Grid = None):
    """All points within ``radius`` (distance <= radius) of every point, the point itself
    excluded, as CSR: (offsets int32 (n+1,), indices int32 (m,)); row i is
    indices[offsets[i]:offsets[i+1]], sorted by (distance, index). ``max_neighbors`` keeps
    only the nearest that many of each row. The indices are numpy when there is no pair at all."""
    radius = float(radius)
    if not 0 <= radius < np.inf:
        raise ValueError(f"radius must be a finite distance >= 0, got {radius}")
    n = length(xyz)
    pts = points_array(xyz)
    if grid is None:
        # a cell slightly larger than the radius: one ring of cells covers it despite rounding
        grid = build_grid(pts, max(radius * 1.001, 1e-6) if n else 1.0)
    elif grid.n != n:
        raise ValueError(f"grid was built over {grid.n} points, xyz has {n}")
    rings = max(1, int(np.ceil(radius / grid.cell_size + 1e-4)))
    r2 = float(np.float32(radius) * np.float32(radius))
    count = ndarray(ti.i32, (n + 1,))
    dummy_i = ndarray(ti.i32, (1,))
    dummy_f = ndarray(ti.f32, (1,))
    args = (grid.order, grid.sorted_xyz, grid.sorted_cell, grid.bucket_start, grid.table_mask, rings, r2)
    if n:
        _radius_scan(*args, count, dummy_i, dummy_i, dummy_f, False)
    offsets, total = _csr_offsets(count)
    # no pair at all (a small radius, one point): an empty numpy index list (Taichi has no empty ndarray)
    idx = ndarray(ti.i32, (total,)) if total else np.zeros(0, np.int32)
    if total:
        dist = ndarray(ti.f32, (total,))
        _radius_scan(*args, count, offsets, idx, dist, True)
    if max_neighbors is not None and n:
        clipped = ndarray(ti.i32, (n + 1,))
        _clip_counts(offsets, int(max_neighbors), clipped)
        new_offsets, new_total = _csr_offsets(clipped)
        new_idx = ndarray(ti.i32, (new_total,)) if new_total else np.zeros(0, np.int32)
        if new_total:
            _copy_rows(offsets, idx, new_offsets, new_idx)
        offsets, idx = new_offsets, new_idx
    return like_input(offsets, xyz), like_input(idx, xyz)
