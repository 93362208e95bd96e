"""Cloth simulation filter (CSF, Zhang et al. 2016) as Taichi particle kernels.

Follows the `cloth-simulation-filter` package (jianboqi/CSF) step by step, in its inverted frame
(height h = -z, the cloth falls towards smaller h):
- cloth: particles every `resolution` from (min x - 2 res, min y - 2 res), floor(extent / res) + 4
  per axis, starting 0.05 above the highest inverted point;
- collision height of a particle: inverted height of the point nearest to it in xy among the points
  that round to it; particles without points take the package's scan-line fill (first point-holding
  particle to the right in the row, then left, then towards row 0, then up the column) and, where
  row and column are empty, the nearest filled particle in the 5x5 constraint neighbourhood,
  repeated outwards;
- per iteration: Verlet step (damping 0.01, gravity 0.2 * time_step^4, as the package does it) of movable particles, then
  every particle's constraint pass over its 16 neighbours (distance 1 and 2 in x, y and diagonal)
  with the package's rigidness coefficients, max displacement of movable particles, collision
  (a particle below its collision height is put on it and becomes immovable); stop after
  `iterations` or when 0 < max displacement < 0.005;
- optional slope smoothing (bSloopSmooth): in movable components of more than 50 particles,
  particles connected to an immovable one through collision-height steps below 0.3 are snapped to
  their collision height;
- a point is ground when |z - bilinear cloth height| < class_threshold.

The package runs the constraint passes as one sequential (Gauss-Seidel) sweep in particle order.
Here the same per-particle passes are swept in particle order within bands of BAND_ROWS rows;
every other band runs in parallel (they touch disjoint rows), then the rest, so the result is
deterministic and differs from the package only in the order at band borders.

Everything runs on the device; the host reads one stop flag every few iterations.
"""

from dataclasses import dataclass
import math

import numpy as np
import taichi as ti

from .common import as_ndarray, f32_order_key, f32_from_order_key, is_ndarray, length, ndarray, to_numpy

DAMPING = 0.01
GRAVITY = 0.2
CLOTH_START_ABOVE = 0.05   # the cloth starts this far above the highest inverted point
BUFFER_PARTICLES = 2       # particles added before the bounding box on each axis
STOP_DISPLACEMENT = 0.005  # early stop when the largest movable displacement is below this
SLOPE_HEIGHT_STEP = 0.3    # the package's height_diff_threshold (slope smoothing)
SLOPE_MIN_COMPONENT = 50   # slope smoothing only for movable components larger than this
ITERATIONS_PER_CHECK = 8   # iterations launched between two host reads of the stop flag

# the package's constraint coefficients per rigidness (index = rigidness, 0..14; 0.5 / 1 beyond)
_SINGLE_MOVE = (0, 0.3, 0.51, 0.657, 0.7599, 0.83193, 0.88235, 0.91765, 0.94235, 0.95965,
                0.97175, 0.98023, 0.98616, 0.99031, 0.99322)
_DOUBLE_MOVE = (0, 0.3, 0.42, 0.468, 0.4872, 0.4949, 0.498, 0.4992, 0.4997, 0.4999, 0.4999,
                0.5, 0.5, 0.5, 0.5)

# neighbour offsets (di, dj) in the order of the package's per-particle neighbour list
_NEIGHBOUR_DI = (-1, -1, -1, 0, 1, 1, 0, 1, -2, -2, -2, 0, 2, 2, 0, 2)
_NEIGHBOUR_DJ = (-1, 0, 1, -1, -1, 0, 1, 1, -2, 0, 2, -2, -2, 0, 2, 2)
BAND_ROWS = 32             # rows swept in particle order by one thread (>= 4 for disjoint bands)

_NO_POINT = -1
_FILLED_BY_SEARCH = 2
_KEY_MAX = 2**31 - 1


@ti.func
def _neighbour_offset(k: ti.i32) -> ti.math.ivec2:
    # offsets of _NEIGHBOUR_DI/_NEIGHBOUR_DJ, computed instead of tabled (no local arrays)
    ring = 1 + k // 8
    m = k % 8
    di = 0
    dj = 0
    if m == 0:
        di, dj = -1, -1
    elif m == 1:
        di, dj = -1, 0
    elif m == 2:
        di, dj = -1, 1
    elif m == 3:
        di, dj = 0, -1
    elif m == 4:
        di, dj = 1, -1
    elif m == 5:
        di, dj = 1, 0
    elif m == 6:
        di, dj = 0, 1
    else:
        di, dj = 1, 1
    return ti.math.ivec2(di * ring, dj * ring)


# ---------------------------------------------------------------- bounding box and rasterisation

@ti.kernel
def _bbox(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), keys: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    # keys: min x, min y, min z, -max x, -max y, -max z as order keys (atomic_min only)
    for p in range(xyz.shape[0]):
        for a in ti.static(range(3)):
            ti.atomic_min(keys[a], f32_order_key(xyz[p, a]))
            ti.atomic_min(keys[3 + a], f32_order_key(-xyz[p, a]))


@ti.kernel
def _raster_distance(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), x0: ti.f32, y0: ti.f32,
                     res: ti.f32, width: ti.i32, cell_key: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for p in range(xyz.shape[0]):
        dx = xyz[p, 0] - x0
        dy = xyz[p, 1] - y0
        col = ti.cast(dx / res + 0.5, ti.i32)
        row = ti.cast(dy / res + 0.5, ti.i32)
        ex = dx - col * res
        ey = dy - row * res
        ti.atomic_min(cell_key[row * width + col], f32_order_key(ex * ex + ey * ey))


@ti.kernel
def _raster_nearest(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2), x0: ti.f32, y0: ti.f32,
                    res: ti.f32, width: ti.i32, cell_key: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    cell_point: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    # among the points at the smallest distance, the first in input order (as the package)
    for p in range(xyz.shape[0]):
        dx = xyz[p, 0] - x0
        dy = xyz[p, 1] - y0
        col = ti.cast(dx / res + 0.5, ti.i32)
        row = ti.cast(dy / res + 0.5, ti.i32)
        ex = dx - col * res
        ey = dy - row * res
        c = row * width + col
        if f32_order_key(ex * ex + ey * ey) == cell_key[c]:
            ti.atomic_min(cell_point[c], p)


@ti.kernel
def _point_heights(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                   cell_point: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                   filled: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for c in cell_point:
        p = cell_point[c]
        if p != _KEY_MAX:
            height[c] = -xyz[p, 2]
            filled[c] = 1
        else:
            cell_point[c] = _NO_POINT
            filled[c] = 0


@ti.kernel
def _scanline_rows(cell_point: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                   filled: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32, rows: ti.i32):
    # empty particle: first point-holding particle to the right, else to the left (same row)
    for j in range(rows):
        base = j * width
        last = _NO_POINT               # nearest point-holding column to the right
        for k in range(width):
            i = width - 1 - k
            if cell_point[base + i] != _NO_POINT:
                last = i
            elif last != _NO_POINT:
                height[base + i] = height[base + last]
                filled[base + i] = 1
        last = _NO_POINT
        for i in range(width):
            if cell_point[base + i] != _NO_POINT:
                last = i
            elif filled[base + i] == 0 and last != _NO_POINT:
                height[base + i] = height[base + last]
                filled[base + i] = 1


@ti.kernel
def _scanline_columns(cell_point: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                      filled: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32, rows: ti.i32):
    # still empty (its whole row is empty): towards row 0 first, then up the column
    for i in range(width):
        last = _NO_POINT
        for j in range(rows):
            c = j * width + i
            if cell_point[c] != _NO_POINT:
                last = j
            elif filled[c] == 0 and last != _NO_POINT:
                height[c] = height[last * width + i]
                filled[c] = 1
        last = _NO_POINT
        for k in range(rows):
            j = rows - 1 - k
            c = j * width + i
            if cell_point[c] != _NO_POINT:
                last = j
            elif filled[c] == 0 and last != _NO_POINT:
                height[c] = height[last * width + i]
                filled[c] = 1


@ti.kernel
def _fill_from_neighbours(cell_point: ti.types.ndarray(dtype=ti.i32, ndim=1),
                          height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                          filled: ti.types.ndarray(dtype=ti.i32, ndim=1),
                          next_height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                          next_filled: ti.types.ndarray(dtype=ti.i32, ndim=1),
                          width: ti.i32, rows: ti.i32) -> ti.i32:
    # particles whose row and column are empty (corners of the buffer): the first filled
    # neighbour in the package's list order, one ring per launch, double buffered so the result
    # does not depend on thread order. The package searches breadth-first for a particle holding
    # a point instead; only these few buffer particles, which no point interpolates, can differ.
    remaining = 0
    for c in height:
        next_height[c] = height[c]
        next_filled[c] = filled[c]
        if filled[c] == 0:
            i = c % width
            j = c // width
            found = 0
            for k in range(16):
                if found == 0:
                    o = _neighbour_offset(k)
                    ni = i + o[0]
                    nj = j + o[1]
                    if 0 <= ni < width and 0 <= nj < rows:
                        q = nj * width + ni
                        if filled[q] != 0:
                            next_height[c] = height[q]
                            next_filled[c] = _FILLED_BY_SEARCH
                            found = 1
            if found == 0:
                remaining += 1
    return remaining


# ---------------------------------------------------------------- simulation

@ti.kernel
def _init_cloth(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                old_pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                state: ti.types.ndarray(dtype=ti.i32, ndim=1), start: ti.f32):
    for c in pos:
        pos[c] = start
        old_pos[c] = start
        movable[c] = 1
    for _ in range(1):
        state[0] = 0   # 1 once stopped
        state[1] = 0   # iterations run
        state[2] = 0   # order key of this iteration's largest displacement


@ti.kernel
def _verlet_step(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                 old_pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                 movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 state: ti.types.ndarray(dtype=ti.i32, ndim=1), acceleration: ti.f32):
    for c in pos:
        if state[0] == 0 and movable[c] == 1:
            here = pos[c]
            pos[c] = here + (here - old_pos[c]) * (1.0 - DAMPING) + acceleration
            old_pos[c] = here


@ti.kernel
def _mark_active(movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 active: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32, rows: ti.i32):
    # a constraint pass does something only where the particle or a neighbour is movable;
    # movability only ever ends, so a flag computed now stays a safe superset later
    for c in movable:
        i = c % width
        j = c // width
        any_movable = movable[c]
        for k in range(16):
            o = _neighbour_offset(k)
            ni = i + o[0]
            nj = j + o[1]
            if 0 <= ni < width and 0 <= nj < rows:
                any_movable |= movable[nj * width + ni]
        active[c] = any_movable


@ti.kernel
def _constraint_bands(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                      movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      active: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      state: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      width: ti.i32, rows: ti.i32, band_rows: ti.i32, phase: ti.i32,
                      single_move: ti.f32, double_move: ti.f32):
    # the package's satisfyConstraintSelf, swept in particle order within bands of rows; bands of
    # one phase (every other band) touch disjoint rows, so they run in parallel without races
    bands = (rows + band_rows - 1) // band_rows
    for t in range((bands - phase + 1) // 2):
        if state[0] == 0:
            b = phase + 2 * t
            for j in range(b * band_rows, ti.min(rows, (b + 1) * band_rows)):
                for i in range(width):
                    c = j * width + i
                    if active[c] == 1:
                        for k in range(16):
                            o = _neighbour_offset(k)
                            ni = i + o[0]
                            nj = j + o[1]
                            if 0 <= ni < width and 0 <= nj < rows:
                                q = nj * width + ni
                                mp = movable[c]
                                mq = movable[q]
                                if mp == 1 or mq == 1:
                                    d = pos[q] - pos[c]
                                    if mp == 1 and mq == 1:
                                        pos[c] += d * double_move
                                        pos[q] -= d * double_move
                                    elif mp == 1:
                                        pos[c] += d * single_move
                                    else:
                                        pos[q] -= d * single_move


@ti.kernel
def _displacement_and_collision(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                                old_pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                                movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                                height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                                state: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for _ in range(1):
        state[2] = f32_order_key(0.0)
    for c in pos:
        if state[0] == 0 and movable[c] == 1:
            ti.atomic_max(state[2], f32_order_key(ti.abs(old_pos[c] - pos[c])))
            if pos[c] < height[c]:
                pos[c] = height[c]
                movable[c] = 0


@ti.kernel
def _stop_test(state: ti.types.ndarray(dtype=ti.i32, ndim=1), iterations: ti.i32):
    for _ in range(1):
        if state[0] == 0:
            state[1] += 1
            largest = f32_from_order_key(state[2])
            if (largest != 0.0 and largest < STOP_DISPLACEMENT) or state[1] >= iterations:
                state[0] = 1


# ---------------------------------------------------------------- slope smoothing

@ti.kernel
def _component_init(movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    label: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for c in movable:
        label[c] = c if movable[c] == 1 else -1


@ti.kernel
def _component_propagate(label: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32,
                         rows: ti.i32) -> ti.i32:
    # min-label propagation over 4-connected movable particles, with pointer jumping; labels only
    # decrease and every write is a min, so the fixed point does not depend on thread order
    changed = 0
    for c in label:
        if label[c] >= 0:
            i = c % width
            j = c // width
            best = label[label[c]]
            if i > 0 and label[c - 1] >= 0:
                best = ti.min(best, label[c - 1])
            if i < width - 1 and label[c + 1] >= 0:
                best = ti.min(best, label[c + 1])
            if j > 0 and label[c - width] >= 0:
                best = ti.min(best, label[c - width])
            if j < rows - 1 and label[c + width] >= 0:
                best = ti.min(best, label[c + width])
            if best < label[c]:
                ti.atomic_min(label[c], best)
                ti.atomic_min(label[label[c]], best)
                changed += 1
    return changed


@ti.kernel
def _component_sizes(label: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     size: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for c in label:
        size[c] = 0
    for c in label:
        if label[c] >= 0:
            ti.atomic_add(size[label[c]], 1)


@ti.kernel
def _slope_snap(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                label: ti.types.ndarray(dtype=ti.i32, ndim=1),
                size: ti.types.ndarray(dtype=ti.i32, ndim=1),
                height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                snapped: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32, rows: ti.i32,
                step: ti.f32, min_component: ti.i32) -> ti.i32:
    # one ring of growth: a movable particle of a large component next to an immovable or
    # snapped particle whose collision height is within `step` of its own is snapped
    changed = 0
    for c in pos:
        big = 0
        if movable[c] == 1 and snapped[c] == 0:
            big = size[label[c]] > min_component
        if big:
            i = c % width
            j = c // width
            hit = 0
            for k in ti.static(range(4)):
                ni = i + (-1, 1, 0, 0)[k]
                nj = j + (0, 0, -1, 1)[k]
                if 0 <= ni < width and 0 <= nj < rows:
                    q = nj * width + ni
                    if (movable[q] == 0 or snapped[q] == 1) and ti.abs(height[c] - height[q]) < step:
                        hit = 1
            if hit == 1:
                snapped[c] = 2   # becomes 1 after the pass: growth by exactly one ring per launch
                changed += 1
    for c in pos:
        if snapped[c] == 2:
            snapped[c] = 1
            pos[c] = height[c]
    return changed


# ---------------------------------------------------------------- classification

@ti.kernel
def _height_above(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                  pos: ti.types.ndarray(dtype=ti.f32, ndim=1), x0: ti.f32, y0: ti.f32,
                  res: ti.f32, width: ti.i32, rows: ti.i32,
                  out: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for p in range(xyz.shape[0]):
        dx = xyz[p, 0] - x0
        dy = xyz[p, 1] - y0
        col = ti.min(ti.max(ti.cast(ti.floor(dx / res), ti.i32), 0), width - 2)
        row = ti.min(ti.max(ti.cast(ti.floor(dy / res), ti.i32), 0), rows - 2)
        sx = (dx - col * res) / res
        sy = (dy - row * res) / res
        c = row * width + col
        inverted = (pos[c] * (1.0 - sx) * (1.0 - sy) + pos[c + width] * (1.0 - sx) * sy
                    + pos[c + width + 1] * sx * sy + pos[c + 1] * sx * (1.0 - sy))
        out[p] = xyz[p, 2] + inverted      # z minus the cloth height (-inverted)


@ti.kernel
def _ground_mask(height_above: ti.types.ndarray(dtype=ti.f32, ndim=1), threshold: ti.f32,
                 ground: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for p in height_above:
        ground[p] = ti.u8(1) if ti.abs(height_above[p]) < threshold else ti.u8(0)


# ---------------------------------------------------------------- public API

@dataclass
class ClothResult:
    ground: np.ndarray          # bool (n,)
    cloth_z: np.ndarray         # float32 (rows, cols): cloth heights in the cloud's z
    x0: float                   # local x of particle (0, 0)
    y0: float                   # local y of particle (0, 0)
    resolution: float
    iterations: int = 0         # simulation iterations run

    @property
    def shape(self) -> tuple:
        return tuple(self.cloth_z.shape)

    def height_above(self, xyz) -> np.ndarray:
        """z minus the bilinear cloth height under each point (float32 (n,))."""
        rows, cols = self.cloth_z.shape
        pos = as_ndarray(-self.cloth_z.reshape(-1), np.float32)
        points = as_ndarray(xyz, np.float32)
        out = ndarray(np.float32, (length(points),))
        if length(points):
            _height_above(points, pos, self.x0, self.y0, self.resolution, cols, rows, out)
        return out.to_numpy()


def _grid(keys: np.ndarray, resolution: float):
    lo = np.asarray([f32_from_key(k) for k in keys[:3]], np.float64)
    hi = -np.asarray([f32_from_key(k) for k in keys[3:]], np.float64)
    cols = int(math.floor((hi[0] - lo[0]) / resolution)) + 2 * BUFFER_PARTICLES
    rows = int(math.floor((hi[1] - lo[1]) / resolution)) + 2 * BUFFER_PARTICLES
    x0 = float(np.float32(lo[0] - BUFFER_PARTICLES * resolution))
    y0 = float(np.float32(lo[1] - BUFFER_PARTICLES * resolution))
    return lo, hi, cols, rows, x0, y0


def f32_from_key(key) -> float:
    bits = int(key)
    if bits < 0:
        bits ^= 0x7FFFFFFF
    return float(np.array([bits], np.int32).view(np.float32)[0])


def _fill_i32(shape, value):
    a = ndarray(np.int32, shape)
    a.fill(value)
    return a


def csf(xyz, *, cloth_resolution: float = 0.5, rigidness: int = 3, time_step: float = 0.65,
        iterations: int = 500, class_threshold: float = 0.5,
        slope_smooth: bool = False) -> ClothResult:
    """Cloth simulation filter of the (n, 3) float32 local points ``xyz`` (numpy or ndarray).

    Parameters mirror the `cloth-simulation-filter` package (``interations`` -> ``iterations``,
    ``bSloopSmooth`` -> ``slope_smooth``). Returns a ClothResult; ``ground`` is numpy either way.
    """
    if not cloth_resolution > 0:
        raise ValueError("cloth_resolution must be > 0")
    if not 1 <= int(rigidness):
        raise ValueError("rigidness must be >= 1")
    if not time_step > 0:
        raise ValueError("time_step must be > 0")
    if int(iterations) < 1:
        raise ValueError("iterations must be >= 1")
    points = as_ndarray(xyz, np.float32)
    n = length(points)
    if n == 0:
        return ClothResult(np.zeros(0, bool), np.zeros((0, 0), np.float32), 0.0, 0.0,
                           float(cloth_resolution))
    res = float(cloth_resolution)

    keys = _fill_i32((6,), _KEY_MAX)
    _bbox(points, keys)
    lo, hi, cols, rows, x0, y0 = _grid(keys.to_numpy(), res)
    cells = cols * rows
    if cells >= 2**31 - 1:
        raise ValueError("cloth grid too large for 32-bit indexing; use a coarser resolution")

    # collision heights (inverted frame)
    cell_key = _fill_i32((cells,), _KEY_MAX)
    cell_point = _fill_i32((cells,), _KEY_MAX)
    height = ndarray(np.float32, (cells,))
    filled = ndarray(np.int32, (cells,))
    _raster_distance(points, x0, y0, res, cols, cell_key)
    _raster_nearest(points, x0, y0, res, cols, cell_key, cell_point)
    _point_heights(points, cell_point, height, filled)
    _scanline_rows(cell_point, height, filled, cols, rows)
    _scanline_columns(cell_point, height, filled, cols, rows)
    spare_height = ndarray(np.float32, (cells,))
    spare_filled = ndarray(np.int32, (cells,))
    remaining = -1
    while True:   # a few rings at most: only particles whose row and column are both empty
        left = _fill_from_neighbours(cell_point, height, filled, spare_height, spare_filled, cols, rows)
        height, spare_height = spare_height, height
        filled, spare_filled = spare_filled, filled
        if left == 0 or left == remaining:
            break
        remaining = left

    # simulation
    pos = ndarray(np.float32, (cells,))
    old_pos = ndarray(np.float32, (cells,))
    movable = ndarray(np.int32, (cells,))
    state = ndarray(np.int32, (3,))
    _init_cloth(pos, old_pos, movable, state, float(-lo[2] + CLOTH_START_ABOVE))
    # the package pre-multiplies gravity by time_step^2 and multiplies by it again in the
    # Verlet step: the displacement per step is gravity * time_step^4
    acceleration = -GRAVITY * time_step ** 4
    k = int(rigidness)
    single = _SINGLE_MOVE[k] if k <= 14 else 1.0
    double = _DOUBLE_MOVE[k] if k <= 14 else 0.5
    active = ndarray(np.int32, (cells,))
    done = 0
    while done < iterations:
        batch = min(ITERATIONS_PER_CHECK, iterations - done)
        _mark_active(movable, active, cols, rows)
        for _ in range(batch):
            _verlet_step(pos, old_pos, movable, state, acceleration)
            for phase in range(2):
                _constraint_bands(pos, movable, active, state, cols, rows, BAND_ROWS, phase,
                                  single, double)
            _displacement_and_collision(pos, old_pos, movable, height, state)
            _stop_test(state, int(iterations))
        done += batch
        if state.to_numpy()[0] == 1:
            break
    iterations_run = int(state.to_numpy()[1])

    if slope_smooth:
        label = ndarray(np.int32, (cells,))
        _component_init(movable, label)
        while _component_propagate(label, cols, rows) > 0:
            pass
        size = ndarray(np.int32, (cells,))
        _component_sizes(label, size)
        snapped = _fill_i32((cells,), 0)
        while _slope_snap(pos, movable, label, size, height, snapped, cols, rows,
                          SLOPE_HEIGHT_STEP, SLOPE_MIN_COMPONENT) > 0:
            pass

    above = ndarray(np.float32, (n,))
    _height_above(points, pos, x0, y0, res, cols, rows, above)
    ground = ndarray(np.uint8, (n,))
    _ground_mask(above, float(class_threshold), ground)
    cloth_z = -pos.to_numpy().reshape(rows, cols)
    return ClothResult(ground.to_numpy().astype(bool), cloth_z.astype(np.float32), x0, y0, res,
                       iterations_run)
