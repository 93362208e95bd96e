"""Sparse voxel hashing: cell coordinates, bucket counting sort, voxel downsampling.

A point's cell is ``floor((p - origin) / cell_size)`` per axis (int32). Cells are hashed into a
power-of-two table of about twice the point count, so memory grows with the point count, never
with the bounding-box volume. Point indices are counting-sorted by bucket (integer-atomic
histogram, ``scan.exclusive_scan_into``, atomic scatter); each bucket is then sorted by
(cell, point index), which makes the order independent of thread timing and puts each cell's
points in one contiguous run. A lookup hashes the cell, takes the bucket's range and skips points
of other cells that share the bucket (hash collisions). Blocks of 4x4x4 cells map to consecutive
buckets, so the sorted order is spatially coherent. Taichi has no atomic compare-and-swap, so
an open-addressing table is not an option; the bucket sort needs none.
"""

import math
from dataclasses import dataclass

import numpy as np
from .taichi_compat import runtime_program, ti

from .common import INT32_MAX, cpu_block_dim, f32_order_key, is_ndarray, length, ndarray, points_array
from .scan import exclusive_scan_into

# Large primes of the classic spatial hash (Teschner et al. 2003).
_P1, _P2, _P3 = 73856093, 19349663, 83492791
_MAX_CELL_COORD = 2**30
_BOUNDS_CHUNK = 16384
# an automatic cell size is refined when its cells hold on average more than this many times the
# points per cell asked for: the bounding box is then mostly empty (far stray points), and its
# density says nothing about the points' spacing
OVERFULL = 16.0


@dataclass
class Grid:
    """A sparse cell index over one point set (all arrays are Taichi ndarrays)."""
    n: int
    cell_size: float
    inv_cell: float            # float32(1 / cell_size): every kernel uses this exact value
    origin: tuple              # float32 x, y, z of the grid corner (the bounding-box minimum)
    table_mask: int            # table size - 1 (table size is a power of two)
    order: object              # (n,) i32: point indices sorted by (bucket, cell, index)
    bucket_start: object       # (table+1,) i32: bucket b holds order[bucket_start[b]:bucket_start[b+1]]
    sorted_xyz: object         # (n, 3) f32: xyz[order]
    sorted_cell: object        # (n, 3) i32: cell coordinates of xyz[order]
    extent: tuple              # float32 bounding-box size x, y, z
    _cell_start: object = None

    @property
    def cell_start(self):
        """(cells+1,) i32: sorted position where each occupied cell's run starts, then n
        (computed on first use)."""
        if self._cell_start is None:
            self._cell_start = _cell_runs(self.sorted_cell, self.n)
        return self._cell_start

    @property
    def n_cells(self) -> int:
        return int(self.cell_start.shape[0]) - 1

    @property
    def table_size(self) -> int:
        return self.table_mask + 1


@ti.func
def cell_of(x: ti.f32, y: ti.f32, z: ti.f32, ox: ti.f32, oy: ti.f32, oz: ti.f32,
            inv_cell: ti.f32) -> ti.math.ivec3:
    """Cell of a point; the single definition every kernel uses, so all agree bit for bit."""
    return ti.math.ivec3(ti.cast(ti.floor((x - ox) * inv_cell), ti.i32),
                         ti.cast(ti.floor((y - oy) * inv_cell), ti.i32),
                         ti.cast(ti.floor((z - oz) * inv_cell), ti.i32))


@ti.func
def cell_hash(c: ti.math.ivec3, mask: ti.i32) -> ti.i32:
    # Blocks of 4x4x4 cells hash to 64 consecutive buckets (cell position inside the block in
    # the low bits): neighbouring cells then sit close together in the sorted arrays, and
    # queries processed in sorted order walk space block by block (cache locality).
    b = c >> 2
    h = (ti.cast(b[0], ti.u32) * ti.u32(_P1)) ^ (ti.cast(b[1], ti.u32) * ti.u32(_P2)) \
        ^ (ti.cast(b[2], ti.u32) * ti.u32(_P3))
    local = ti.cast((c[0] & 3) | ((c[1] & 3) << 2) | ((c[2] & 3) << 4), ti.u32)
    return ti.cast(((h << ti.u32(6)) | local) & ti.cast(mask, ti.u32), ti.i32)


@ti.func
def cell_less(a: ti.math.ivec3, ia: ti.i32, b: ti.math.ivec3, ib: ti.i32) -> ti.i32:
    """Lexicographic (cell, index) order."""
    less = 0
    if a[0] != b[0]:
        less = ti.cast(a[0] < b[0], ti.i32)
    elif a[1] != b[1]:
        less = ti.cast(a[1] < b[1], ti.i32)
    elif a[2] != b[2]:
        less = ti.cast(a[2] < b[2], ti.i32)
    else:
        less = ti.cast(ia < ib, ti.i32)
    return less


@ti.kernel
def _bounds(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), lo_key: ti.types.ndarray(dtype=ti.i32, ndim=1),
            hi_key: ti.types.ndarray(dtype=ti.i32, ndim=1), chunk: ti.i32):
    # one chunk of points per iteration, reduced in registers: a handful of atomics per chunk
    # instead of six contended ones per point
    n = xyz.shape[0]
    for t in range((n + chunk - 1) // chunk):
        lo = ti.math.ivec3(INT32_MAX)
        hi = ti.math.ivec3(-INT32_MAX - 1)
        for i in range(t * chunk, ti.min(t * chunk + chunk, n)):
            for a in ti.static(range(3)):
                key = f32_order_key(xyz[i, a])
                lo[a] = ti.min(lo[a], key)
                hi[a] = ti.max(hi[a], key)
        for a in ti.static(range(3)):
            ti.atomic_min(lo_key[a], lo[a])
            ti.atomic_max(hi_key[a], hi[a])


@ti.kernel
def _count_buckets(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), count: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   ox: ti.f32, oy: ti.f32, oz: ti.f32, inv_cell: ti.f32, mask: ti.i32):
    for i in range(xyz.shape[0]):
        c = cell_of(xyz[i, 0], xyz[i, 1], xyz[i, 2], ox, oy, oz, inv_cell)
        ti.atomic_add(count[cell_hash(c, mask)], 1)


@ti.kernel
def _copy_i32(src: ti.types.ndarray(dtype=ti.i32, ndim=1), dst: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(src.shape[0]):
        dst[i] = src[i]


@ti.kernel
def _scatter(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
             cursor: ti.types.ndarray(dtype=ti.i32, ndim=1), ox: ti.f32, oy: ti.f32, oz: ti.f32,
             inv_cell: ti.f32, mask: ti.i32, order: ti.types.ndarray(dtype=ti.i32, ndim=1),
             sorted_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    # the point goes straight to its bucket slot with its coordinates (sequential reads,
    # scattered writes); the order inside a bucket depends on thread timing until _sort_buckets
    for i in range(xyz.shape[0]):
        c = cell_of(xyz[i, 0], xyz[i, 1], xyz[i, 2], ox, oy, oz, inv_cell)
        pos = ti.atomic_add(cursor[cell_hash(c, mask)], 1)   # cursor starts at the bucket's start
        order[pos] = i
        for a in ti.static(range(3)):
            sorted_xyz[pos, a] = xyz[i, a]


@ti.kernel
def _sorted_cells(sorted_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), sorted_cell: ti.types.ndarray(dtype=ti.i32, ndim=2),
                  ox: ti.f32, oy: ti.f32, oz: ti.f32, inv_cell: ti.f32):
    for s in range(sorted_xyz.shape[0]):
        c = cell_of(sorted_xyz[s, 0], sorted_xyz[s, 1], sorted_xyz[s, 2], ox, oy, oz, inv_cell)
        for a in ti.static(range(3)):
            sorted_cell[s, a] = c[a]


@ti.kernel
def _sort_buckets(start: ti.types.ndarray(dtype=ti.i32, ndim=1), order: ti.types.ndarray(dtype=ti.i32, ndim=1),
                  sorted_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), sorted_cell: ti.types.ndarray(dtype=ti.i32, ndim=2),
                  n_buckets: ti.i32):
    # Shell sort of each bucket by (cell, index), moving the coordinates along: in place,
    # O(m^1.3), fine for the occasional bucket of thousands (duplicated points, coarse voxels).
    ti.loop_config(block_dim=ti.static(cpu_block_dim(4096)))
    for b in range(n_buckets):
        lo = start[b]
        m = start[b + 1] - lo
        if m > 1:
            gap = 1
            while gap * 3 + 1 < m:
                gap = gap * 3 + 1
            while gap >= 1:
                for i in range(lo + gap, lo + m):
                    v = order[i]
                    cv = ti.math.ivec3(sorted_cell[i, 0], sorted_cell[i, 1], sorted_cell[i, 2])
                    pv = ti.math.vec3(sorted_xyz[i, 0], sorted_xyz[i, 1], sorted_xyz[i, 2])
                    j = i
                    while j >= lo + gap:
                        u = order[j - gap]
                        cu = ti.math.ivec3(sorted_cell[j - gap, 0], sorted_cell[j - gap, 1], sorted_cell[j - gap, 2])
                        if cell_less(cv, v, cu, u):
                            order[j] = u
                            for a in ti.static(range(3)):
                                sorted_cell[j, a] = cu[a]
                                sorted_xyz[j, a] = sorted_xyz[j - gap, a]
                            j -= gap
                        else:
                            break
                    order[j] = v
                    for a in ti.static(range(3)):
                        sorted_cell[j, a] = cv[a]
                        sorted_xyz[j, a] = pv[a]
                gap = gap // 3


def bounding_box(xyz):
    """(min, max) float32 corners of an (n, 3) float32 ndarray, reduced on the device."""
    lo = ndarray(ti.i32, (3,))
    hi = ndarray(ti.i32, (3,))
    lo.from_numpy(np.full(3, INT32_MAX, np.int32))
    hi.from_numpy(np.full(3, -INT32_MAX - 1, np.int32))
    _bounds(xyz, lo, hi, _BOUNDS_CHUNK)

    def decode(keys):
        bits = keys.to_numpy()
        bits = np.where(bits < 0, bits ^ 0x7FFFFFFF, bits).astype(np.int32)
        return bits.view(np.float32)
    return decode(lo), decode(hi)


def auto_cell_size(extent, n: int, points_per_cell: float) -> float:
    """Cell edge such that a cell holds about ``points_per_cell`` points on a surface-like cloud
    (density taken over the two largest bounding-box extents)."""
    e = np.sort(np.asarray(extent, np.float64))[::-1]
    if n <= 0 or e[0] <= 0:
        return 1.0
    area = e[0] * max(e[1], e[0] * 1e-6)
    size = math.sqrt(points_per_cell * area / n)
    # never so small that the cell coordinates of the extent overflow
    return max(size, float(e[0]) / 2**28, 1e-6)


def _occupied_cells(xyz: np.ndarray, lo: np.ndarray, cell_size: float) -> int:
    """Number of occupied cells of edge ``cell_size`` (host; hashed cell keys, collisions in 64
    bits are negligible for a size choice)."""
    c = np.floor((xyz.astype(np.float64) - lo) / cell_size).astype(np.int64)
    key = (c[:, 0] * np.int64(_P1)) ^ (c[:, 1] * np.int64(_P2)) ^ (c[:, 2] * np.int64(_P3))
    return int(len(np.unique(key)))


def refined_cell_size(xyz, lo, extent, cell_size: float, cells: int, points_per_cell: float) -> float:
    """A cell size for points whose automatic cells (``cell_size``, ``cells`` occupied) are
    overfull: shrunk until the occupied cells hold about ``points_per_cell`` points each (the
    density of the occupied space, not of the bounding box), or until shrinking stops splitting
    the points (duplicates). Returns ``cell_size`` when it is not overfull."""
    n = length(xyz)
    if n <= OVERFULL * points_per_cell * cells:
        return cell_size
    host = xyz.to_numpy() if is_ndarray(xyz) else np.asarray(xyz)
    lo = np.asarray(lo, np.float64)
    smallest = max(float(np.max(extent)) / 2**28, 1e-6)
    size = cell_size
    for _ in range(12):
        candidate = max(size * math.sqrt(max(points_per_cell * cells / n, 1e-4)), smallest)
        if candidate >= size:
            break
        found = _occupied_cells(host, lo, candidate)
        if found < 1.5 * cells:           # no longer splits the points: duplicates, not space
            break
        size, cells = candidate, found
        if n <= OVERFULL * points_per_cell * cells:
            break
    return size


_SCRATCH = {}
_SCRATCH_OWNER = [None]    # the Taichi runtime the cached buffers belong to


def scratch(name: str, dtype, shape):
    """A work ndarray reused between calls (the latest shape per name): no allocation and no
    page faults on repeated calls of the same size. Never hand one to a caller: the next call
    with the same name overwrites it. Contents are undefined (``fill`` what must start at 0).
    A new Taichi runtime (ti.reset / ti.init) drops the cache."""
    prog = runtime_program()
    if _SCRATCH_OWNER[0] is not prog:
        _SCRATCH.clear()
        _SCRATCH_OWNER[0] = prog
    shape = tuple(int(v) for v in shape)
    arr = _SCRATCH.get(name)
    if arr is None or tuple(arr.shape) != shape or arr.dtype != dtype:
        arr = ndarray(dtype, shape)
        _SCRATCH[name] = arr
    return arr


def build_grid(xyz, cell_size=None, *, points_per_cell: float = 8.0) -> Grid:
    """Sparse hashed grid over ``xyz`` (n, 3) float32 (numpy or Taichi ndarray).

    ``cell_size`` None picks one from the point density (``auto_cell_size``)."""
    return build_grid_into(xyz, cell_size, points_per_cell, private=False)


def build_grid_into(xyz, cell_size, points_per_cell: float, *, private: bool) -> Grid:
    """``build_grid``; ``private`` = the grid never leaves the calling wrapper, so its arrays may
    be scratch buffers (valid until the next private grid is built)."""
    pts = points_array(xyz)
    n = length(pts)
    lo, hi = bounding_box(pts) if n else (np.zeros(3, np.float32), np.zeros(3, np.float32))
    extent = (hi - lo).astype(np.float32)
    if not np.all(np.isfinite(extent)):
        raise ValueError("xyz holds non-finite coordinates")
    automatic = cell_size is None
    if automatic:
        cell_size = auto_cell_size(extent, n, points_per_cell)
    cell_size = float(cell_size)
    if not cell_size > 0:
        raise ValueError(f"cell_size must be > 0, got {cell_size}")
    inv_cell = np.float32(1.0 / cell_size)
    if float(extent.max(initial=0.0)) * float(inv_cell) >= _MAX_CELL_COORD:
        raise ValueError(f"cell_size {cell_size} is too small for an extent of {extent.max()} "
                         f"(cell coordinates would overflow int32)")
    table = 1 << max(6, int(math.ceil(math.log2(max(2 * n, 1)))))
    mask = table - 1
    ox, oy, oz = (float(v) for v in lo)
    def alloc(name, dtype, shape):
        return scratch("grid." + name, dtype, shape) if private else ndarray(dtype, shape)
    count = scratch("grid.count", ti.i32, (table + 1,))   # the extra slot makes start[table] = n
    count.fill(0)
    start = alloc("start", ti.i32, (table + 1,))
    order = alloc("order", ti.i32, (max(n, 1),))
    sorted_xyz = alloc("sorted_xyz", ti.f32, (max(n, 1), 3))
    sorted_cell = alloc("sorted_cell", ti.i32, (max(n, 1), 3))
    if n:
        geometry = (ox, oy, oz, float(inv_cell), mask)
        _count_buckets(pts, count, *geometry)
        exclusive_scan_into(count, start)
        _copy_i32(start, count)                 # count becomes the scatter cursor
        _scatter(pts, count, *geometry, order, sorted_xyz)
        _sorted_cells(sorted_xyz, sorted_cell, ox, oy, oz, float(inv_cell))
        _sort_buckets(start, order, sorted_xyz, sorted_cell, table)
    grid = Grid(n=n, cell_size=cell_size, inv_cell=float(inv_cell), origin=(ox, oy, oz),
                table_mask=mask, order=order, bucket_start=start, sorted_xyz=sorted_xyz,
                sorted_cell=sorted_cell, extent=tuple(float(v) for v in extent))
    if automatic and n:
        # a bounding box inflated by far stray points: its density gives cells holding most of the
        # points, and every query would scan them all; size the cells from the occupied space
        refined = refined_cell_size(pts, lo, extent, cell_size, grid.n_cells, points_per_cell)
        if refined != cell_size:
            return build_grid_into(xyz, refined, points_per_cell, private=private)
    return grid


def _cell_runs(sorted_cell, n: int):
    """Start of every cell's run in the sorted order, plus n at the end."""
    first = scratch("runs.first", ti.i32, (max(n, 1),))
    if n:
        _mark_runs(sorted_cell, first)
    runs = mask_to_indices(first) if n else ndarray(ti.i32, (0,))
    m = length(runs)
    out = ndarray(ti.i32, (m + 1,))
    if m:
        _copy_append(runs, n, out)
    else:
        out.from_numpy(np.full(1, n, np.int32))
    return out


@ti.kernel
def _copy_append(src: ti.types.ndarray(dtype=ti.i32, ndim=1), last: ti.i32, out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(out.shape[0]):
        v = last
        if i < src.shape[0]:
            v = src[i]
        out[i] = v


# ---------------------------------------------------------------- voxel downsampling

@ti.kernel
def _voxel_offsets(sorted_xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), sorted_cell: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   ox: ti.f32, oy: ti.f32, oz: ti.f32, cell_size: ti.f32,
                   offset: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    # Offsets from the voxel corner: a point and the corner are within a factor of two, so the
    # difference is exact. They go through memory (a separate kernel) so that fast-math cannot
    # reassociate the later centroid arithmetic back onto the large absolute coordinates.
    for s in range(sorted_xyz.shape[0]):
        corner = ti.math.vec3(ox, oy, oz) + ti.cast(
            ti.math.ivec3(sorted_cell[s, 0], sorted_cell[s, 1], sorted_cell[s, 2]), ti.f32) * cell_size
        for a in ti.static(range(3)):
            offset[s, a] = sorted_xyz[s, a] - corner[a]


@ti.kernel
def _voxel_pick(offset: ti.types.ndarray(dtype=ti.f32, ndim=2), sorted_cell: ti.types.ndarray(dtype=ti.i32, ndim=2),
                order: ti.types.ndarray(dtype=ti.i32, ndim=1), keep: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    # The first point of each cell run (runs are contiguous: buckets are sorted by cell) walks
    # its run twice in a fixed order: centroid, then the member nearest to it.
    n = offset.shape[0]
    for s in range(n):
        c = ti.math.ivec3(sorted_cell[s, 0], sorted_cell[s, 1], sorted_cell[s, 2])
        first = 1
        if s > 0:
            if sorted_cell[s - 1, 0] == c[0] and sorted_cell[s - 1, 1] == c[1] and sorted_cell[s - 1, 2] == c[2]:
                first = 0
        if first:
            total = ti.math.vec3(0.0)
            e = s
            while e < n:
                if sorted_cell[e, 0] != c[0] or sorted_cell[e, 1] != c[1] or sorted_cell[e, 2] != c[2]:
                    break
                total += ti.math.vec3(offset[e, 0], offset[e, 1], offset[e, 2])
                e += 1
            centre = total / ti.cast(e - s, ti.f32)
            best = s
            best_d2 = ti.math.inf
            for t in range(s, e):
                d = ti.math.vec3(offset[t, 0], offset[t, 1], offset[t, 2]) - centre
                d2 = d.dot(d)
                # members are sorted by index within the run, so a strict < keeps the lower
                # index; the relative margin lets exact ties (e.g. two-point voxels) survive
                # float32 rounding of the centroid
                if d2 < best_d2 * (1.0 - 4e-6):
                    best_d2 = d2
                    best = t
            keep[order[best]] = 1


@ti.kernel
def _mark_runs(sorted_cell: ti.types.ndarray(dtype=ti.i32, ndim=2), first: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for s in range(sorted_cell.shape[0]):
        f = 1
        if s > 0:
            if sorted_cell[s - 1, 0] == sorted_cell[s, 0] and sorted_cell[s - 1, 1] == sorted_cell[s, 1] \
                    and sorted_cell[s - 1, 2] == sorted_cell[s, 2]:
                f = 0
        first[s] = f


@ti.kernel
def _compact(mask: ti.types.ndarray(dtype=ti.i32, ndim=1), prefix: ti.types.ndarray(dtype=ti.i32, ndim=1),
             out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in range(mask.shape[0]):
        if mask[i] != 0:
            out[prefix[i]] = i


def compact_mask(mask):
    """(ascending indices of the non-zero entries of an int32 ndarray mask, their count); the
    indices are None when there are none (Taichi has no empty ndarrays)."""
    n = length(mask)
    prefix = scratch("compact.prefix", ti.i32, (max(n, 1),))
    total = exclusive_scan_into(mask, prefix) if n else 0
    if not total:
        return None, 0
    out = ndarray(ti.i32, (total,))
    _compact(mask, prefix, out)
    return out, total


def mask_to_indices(mask):
    """Ascending indices of the non-zero entries of an int32 ndarray mask (stays on the device)."""
    out, total = compact_mask(mask)
    return out if total else ndarray(ti.i32, (0,))


def voxel_downsample(xyz, voxel_size: float):
    """Indices (ascending, int32) of one real point per occupied voxel of edge ``voxel_size``:
    the point nearest the voxel's centroid, ties to the lower index. Voxels are
    ``floor((p - bbox_min) / voxel_size)``. Returns numpy for numpy input, an ndarray otherwise (numpy when no point is given)."""
    grid = build_grid_into(xyz, voxel_size, 8.0, private=True)
    keep = scratch("voxel.keep", ti.i32, (max(grid.n, 1),))
    keep.fill(0)
    if grid.n:
        offset = scratch("voxel.offset", ti.f32, (grid.n, 3))
        ox, oy, oz = grid.origin
        _voxel_offsets(grid.sorted_xyz, grid.sorted_cell, ox, oy, oz, grid.cell_size, offset)
        _voxel_pick(offset, grid.sorted_cell, grid.order, keep)
    if not grid.n:
        return np.zeros(0, np.int32)     # numpy either way: Taichi has no empty ndarray
    idx = mask_to_indices(keep)
    return idx if is_ndarray(xyz) else idx.to_numpy()
