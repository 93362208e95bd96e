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
- per iteration: Verlet step of movable particles (damping 0.01, gravity 0.2 * time_step^4, as
  the package does it), then
  every particle's constraint pass over its 16 neighbours (distance 1 and 2 in x, y and diagonal)
  with the package's rigidness coefficients, max displacement of movable particles, collision
  (a particle below its collision height is put on it and becomes immovable); stop after
  `iterations` or when max displacement < 0.005 (the package needs > 0 too: see _stop_test);
- optional slope smoothing (bSloopSmooth): in movable components of more than 50 particles,
  particles connected to an immovable one through collision-height steps below 0.3 are snapped to
  their collision height;
- a point is ground when |z - bilinear cloth height| < class_threshold.

The package runs the constraint passes as one sequential (Gauss-Seidel) sweep in particle order.
Here the same per-particle passes are swept in particle order within bands of BAND_ROWS rows;
every other band runs in parallel (they touch disjoint rows), then the rest, so the result is
deterministic and differs from the package only in the order at band borders. With a
``lattice_origin`` (a world lattice) the bands and their parity lie on world rows, so the tiles of
one survey and the whole survey sweep every particle in the same order.

Cost: each band keeps the list of its active particles (movable, or with a movable neighbour:
the only ones whose constraint pass does anything), refreshed every ITERATIONS_PER_CHECK
iterations, and every per-iteration step runs over these lists only. On the CPU with few
threads, or for small cloths, all iterations run in one serial launch (_simulate_serial) in
exactly the banded order, so both schedules give bit-identical results; otherwise one launch per
iteration (_iterate) and a host read of the stop flag every ITERATIONS_PER_CHECK iterations.
Numpy points are passed to the kernels in place on the CPU (no copy of millions of points).
"""

from dataclasses import dataclass
import math
import os

import numpy as np
from .taichi_compat import cpu_threads, ti

from .common import (as_ndarray, cpu_block_dim, f32_from_order_key, f32_order_key, host_memory_backend, length,
                     ndarray, points_array, to_numpy)
from .grid import bounding_box

DAMPING = 0.01
GRAVITY = 0.2
CLOTH_START_ABOVE = 0.05   # the cloth starts this far above the highest inverted point
BUFFER_PARTICLES = 2       # particles added before the bounding box on each axis
STOP_DISPLACEMENT = 0.005  # early stop when the largest movable displacement is below this
SLOPE_HEIGHT_STEP = 0.3    # the package's height_diff_threshold (slope smoothing)
SLOPE_MIN_COMPONENT = 50   # slope smoothing only for movable components larger than this
SERIAL_CELLS = 2**18       # on the CPU, smaller cloths run all iterations in one serial launch
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
LATTICE_PERIOD = 2 * BAND_ROWS   # particles: a lattice_origin is a world multiple of this many
                                 # resolutions, which fixes the world rows of bands and their parity

_NO_POINT = -1
_FILLED_BY_SEARCH = 2
_KEY_MAX = 2**31 - 1


# _NEIGHBOUR_DI/_DJ + 1 of the first ring, 2 bits per neighbour: the offsets are computed in the
# kernels instead of tabled (no local arrays) or unrolled (compile time)
_RING_DI_CODE = sum((_NEIGHBOUR_DI[m] + 1) << (2 * m) for m in range(8))
_RING_DJ_CODE = sum((_NEIGHBOUR_DJ[m] + 1) << (2 * m) for m in range(8))


@ti.func
def _neighbour_offset(k: ti.i32) -> ti.math.ivec2:
    m = k & 7
    ring = 1 + (k >> 3)
    return ti.math.ivec2((((_RING_DI_CODE >> (2 * m)) & 3) - 1) * ring,
                         (((_RING_DJ_CODE >> (2 * m)) & 3) - 1) * ring)


# ---------------------------------------------------------------- rasterisation

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
        key = f32_order_key(ex * ex + ey * ey)
        c = row * width + col
        if key < cell_key[c]:     # most points are not the nearest: skip their atomic
            ti.atomic_min(cell_key[c], key)


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
# Every loop over the cloth runs over bands of BAND_ROWS rows, one thread per band (block_dim 1
# on the CPU, which would otherwise give a few bands to one thread; GPUs keep their default:
# Vulkan refuses blocks of one), and within a band over its list of active particles in particle
# order. A particle is active while it or one of its 16 neighbours is movable: only then does its
# constraint pass change anything. The lists shrink as the cloth settles, so late iterations cost
# what is still moving, not the cloth size.

@ti.func
def _band_row_range(b, rows, band_rows, band_shift) -> ti.math.ivec2:
    """Rows [lo, hi) of band b: bands are laid on world rows (multiples of band_rows from the
    lattice's period origin), so that the tiles of a survey and the whole survey cut the cloth
    into the same bands; band_shift is the lattice row of row 0 modulo band_rows."""
    return ti.math.ivec2(ti.max(b * band_rows - band_shift, 0), ti.min((b + 1) * band_rows - band_shift, rows))


@ti.func
def _even_bands(bands, band_phase):
    """How many of the bands have an even world index (band_phase: world index parity of band 0)."""
    return (bands - band_phase + 1) // 2


@ti.func
def _phase_band(t, bands, band_phase):
    """t-th band of the sweep order: the bands of even world index first, then the odd ones
    (band_phase: world index parity of band 0)."""
    first = _even_bands(bands, band_phase)
    b = 2 * t + band_phase
    if t >= first:
        b = 2 * (t - first) + 1 - band_phase
    return b


@ti.kernel
def _init_cloth(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                old_pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                band_list: ti.types.ndarray(dtype=ti.i32, ndim=1),
                band_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
                state: ti.types.ndarray(dtype=ti.i32, ndim=1), start: ti.f32, width: ti.i32,
                rows: ti.i32, band_rows: ti.i32, band_shift: ti.i32):
    for c in pos:
        pos[c] = start
        old_pos[c] = start
        movable[c] = 1
        band_list[c] = c        # band b lists its particles in its own cell range
    for b in band_count:
        span = _band_row_range(b, rows, band_rows, band_shift)
        band_count[b] = (span[1] - span[0]) * width
    for _ in range(1):
        state[0] = 0   # 1 once stopped
        state[1] = 0   # iterations run


@ti.func
def _any_neighbour_movable(movable: ti.template(), i, j, width, rows):
    interior = 2 <= i < width - 2 and 2 <= j < rows - 2
    found = 0
    for k in range(16):
        o = _neighbour_offset(k)
        if interior or (0 <= i + o[0] < width and 0 <= j + o[1] < rows):
            found |= movable[(j + o[1]) * width + i + o[0]]
    return found


@ti.func
def _refresh_band(b, movable: ti.template(), band_list: ti.template(), band_count: ti.template(),
                  width, rows, band_rows, band_shift):
    # drop the particles that became inactive, in place and in order; movability only ever
    # ends, so a particle inactive now stays inactive
    begin = _band_row_range(b, rows, band_rows, band_shift)[0] * width
    kept = begin
    for e in range(begin, begin + band_count[b]):
        c = band_list[e]
        active = movable[c]
        if active == 0:
            active = _any_neighbour_movable(movable, c % width, c // width, width, rows)
        if active == 1:
            band_list[kept] = c
            kept += 1
    band_count[b] = kept - begin


@ti.func
def _verlet_band(b, pos: ti.template(), old_pos: ti.template(), movable: ti.template(),
                 band_list: ti.template(), band_count: ti.template(), width, rows, band_rows,
                 band_shift, acceleration):
    begin = _band_row_range(b, rows, band_rows, band_shift)[0] * width
    for e in range(begin, begin + band_count[b]):
        c = band_list[e]
        if movable[c] == 1:
            here = pos[c]
            pos[c] = here + (here - old_pos[c]) * (1.0 - DAMPING) + acceleration
            old_pos[c] = here


@ti.func
def _collide_band(b, pos: ti.template(), old_pos: ti.template(), movable: ti.template(),
                  height: ti.template(), band_list: ti.template(), band_count: ti.template(),
                  band_max: ti.template(), width, rows, band_rows, band_shift):
    # largest displacement of a movable particle (before collision, as the package), then the
    # collision: a particle below its collision height is put on it and becomes immovable
    largest = 0.0
    begin = _band_row_range(b, rows, band_rows, band_shift)[0] * width
    for e in range(begin, begin + band_count[b]):
        c = band_list[e]
        if movable[c] == 1:
            largest = ti.max(largest, ti.abs(old_pos[c] - pos[c]))
            if pos[c] < height[c]:
                pos[c] = height[c]
                movable[c] = 0
    band_max[b] = f32_order_key(largest)


@ti.func
def _stop_test(band_max: ti.template(), state: ti.template(), iterations):
    largest_key = 0
    for b in range(band_max.shape[0]):
        largest_key = ti.max(largest_key, band_max[b])
    state[1] += 1
    largest = f32_from_order_key(largest_key)
    # the package also requires largest != 0; a largest displacement of exactly 0 means no particle
    # can move any more (gravity moves every movable one), so stopping then changes nothing
    if largest < STOP_DISPLACEMENT or state[1] >= iterations:
        state[0] = 1


@ti.func
def _constraint_step(pos: ti.template(), movable: ti.template(), here, q, keep, take, push):
    # one neighbour q of the package's satisfyConstraintSelf, without branches (movable and
    # immovable particles mix unpredictably): the particle moves to here * keep + pq * take and
    # q by (pq - here) * push; keep/take/push (index 0: q immovable, 1: q movable) are set per
    # particle so that an immovable side stays exactly where it is (keep 1, take 0, push 0)
    pq = pos[q]
    mq = movable[q] == 1
    pos[q] = pq - (pq - here) * ti.select(mq, push[1], push[0])
    return here * ti.select(mq, keep[1], keep[0]) + pq * ti.select(mq, take[1], take[0])


@ti.func
def _constraint_pass(pos: ti.template(), movable: ti.template(), c, width, rows, moves):
    # the package's satisfyConstraintSelf: its 16 neighbours in its list order, each correction
    # seeing the previous ones (pos[c] stays in a register: no neighbour is c itself). Interior
    # particles, nearly all of them, take the unrolled path without bounds tests.
    # moves: single move w1, double move w2, 1 - w1, 1 - w2. The particle's update
    # here + (pq - here) * w is written here * (1 - w) + pq * w with (1 - w) passed in, so the
    # compiler cannot refactor it: two dependent operations per neighbour instead of three on
    # the chain of the particle's 16 updates, the critical path of the sweep.
    i = c % width
    j = c // width
    here = pos[c]
    keep = ti.math.vec2(1.0, 1.0)
    take = ti.math.vec2(0.0, 0.0)
    push = ti.math.vec2(0.0, moves[0])
    if movable[c] == 1:
        keep = ti.math.vec2(moves[2], moves[3])
        take = ti.math.vec2(moves[0], moves[1])
        push = ti.math.vec2(0.0, moves[1])
    if 2 <= i < width - 2 and 2 <= j < rows - 2:
        for k in ti.static(range(16)):
            here = _constraint_step(pos, movable, here,
                                    c + ti.static(_NEIGHBOUR_DJ[k]) * width + ti.static(_NEIGHBOUR_DI[k]),
                                    keep, take, push)
    else:
        for k in range(16):
            o = _neighbour_offset(k)
            if 0 <= i + o[0] < width and 0 <= j + o[1] < rows:
                here = _constraint_step(pos, movable, here, c + o[1] * width + o[0], keep, take,
                                        push)
    pos[c] = here


@ti.func
def _sweep_band(b, pos: ti.template(), movable: ti.template(), band_list: ti.template(),
                band_count: ti.template(), width, rows, band_rows, band_shift, moves):
    begin = _band_row_range(b, rows, band_rows, band_shift)[0] * width
    for e in range(begin, begin + band_count[b]):
        _constraint_pass(pos, movable, band_list[e], width, rows, moves)


@ti.kernel
def _refresh_active(movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    band_list: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    band_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
                    width: ti.i32, rows: ti.i32, band_rows: ti.i32, band_shift: ti.i32):
    ti.loop_config(block_dim=ti.static(cpu_block_dim(1)))
    for b in band_count:
        _refresh_band(b, movable, band_list, band_count, width, rows, band_rows, band_shift)


@ti.kernel
def _iterate(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
             old_pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
             movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
             height: ti.types.ndarray(dtype=ti.f32, ndim=1),
             band_list: ti.types.ndarray(dtype=ti.i32, ndim=1),
             band_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
             band_max: ti.types.ndarray(dtype=ti.i32, ndim=1),
             state: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32, rows: ti.i32,
             band_rows: ti.i32, band_shift: ti.i32, band_phase: ti.i32, acceleration: ti.f32,
             moves: ti.math.vec4, iterations: ti.i32, bands: ti.i32):
    # one iteration of the package's loop, bands in parallel: Verlet step, constraint sweep
    # (the bands of even world index, they touch disjoint rows, then the odd ones), largest
    # displacement and
    # collision, stop test; nothing once stopped
    ti.loop_config(block_dim=ti.static(cpu_block_dim(1)))
    for b in range(bands):
        if state[0] == 0:
            _verlet_band(b, pos, old_pos, movable, band_list, band_count, width, rows, band_rows,
                         band_shift, acceleration)
    ti.loop_config(block_dim=ti.static(cpu_block_dim(1)))
    for t in range(_even_bands(bands, band_phase)):
        if state[0] == 0:
            _sweep_band(2 * t + band_phase, pos, movable, band_list, band_count, width, rows,
                        band_rows, band_shift, moves)
    ti.loop_config(block_dim=ti.static(cpu_block_dim(1)))
    for t in range(bands - _even_bands(bands, band_phase)):
        if state[0] == 0:
            _sweep_band(2 * t + 1 - band_phase, pos, movable, band_list, band_count, width, rows,
                        band_rows, band_shift, moves)
    ti.loop_config(block_dim=ti.static(cpu_block_dim(1)))
    for b in range(bands):
        if state[0] == 0:
            _collide_band(b, pos, old_pos, movable, height, band_list, band_count, band_max,
                          width, rows, band_rows, band_shift)
    for _ in range(1):
        if state[0] == 0:
            _stop_test(band_max, state, iterations)


@ti.kernel
def _simulate_serial(pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                     old_pos: ti.types.ndarray(dtype=ti.f32, ndim=1),
                     movable: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     height: ti.types.ndarray(dtype=ti.f32, ndim=1),
                     band_list: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     band_count: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     band_max: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     state: ti.types.ndarray(dtype=ti.i32, ndim=1), width: ti.i32, rows: ti.i32,
                     band_rows: ti.i32, band_shift: ti.i32, band_phase: ti.i32,
                     acceleration: ti.f32, moves: ti.math.vec4, iterations: ti.i32,
                     refresh_every: ti.i32, bands: ti.i32):
    # the same steps in the same order as _refresh_active + _iterate, all iterations in one
    # thread and one launch: for small cloths, where per-iteration launches and thread wake-ups
    # would cost more than the work. CPU only: the SPIR-V backends do not serialize the loop.
    ti.loop_config(serialize=True)
    for it in range(iterations):
        if state[0] == 0:
            if it > 0 and it % refresh_every == 0:
                for b in range(bands):
                    _refresh_band(b, movable, band_list, band_count, width, rows, band_rows,
                                  band_shift)
            for b in range(bands):
                _verlet_band(b, pos, old_pos, movable, band_list, band_count, width, rows,
                             band_rows, band_shift, acceleration)
            for t in range(bands):
                # in the order of the two parallel phases
                _sweep_band(_phase_band(t, bands, band_phase), pos, movable, band_list, band_count,
                            width, rows, band_rows, band_shift, moves)
            for b in range(bands):
                _collide_band(b, pos, old_pos, movable, height, band_list, band_count, band_max,
                              width, rows, band_rows, band_shift)
            _stop_test(band_max, state, iterations)


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

@ti.func
def _cloth_height_above(xyz: ti.template(), pos: ti.template(), p, x0, y0, res, width, rows):
    # z minus the bilinear cloth height (the package's c2cdist)
    u = (xyz[p, 0] - x0) / res
    v = (xyz[p, 1] - y0) / res
    # truncation, not floor: the same once clamped to >= 0, and cheaper
    col = ti.min(ti.max(ti.cast(u, ti.i32), 0), width - 2)
    row = ti.min(ti.max(ti.cast(v, ti.i32), 0), rows - 2)
    sx = u - col
    sy = v - row
    c = row * width + col
    inverted = (pos[c] * (1.0 - sx) * (1.0 - sy) + pos[c + width] * (1.0 - sx) * sy
                + pos[c + width + 1] * sx * sy + pos[c + 1] * sx * (1.0 - sy))
    return xyz[p, 2] + inverted


@ti.kernel
def _height_above(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                  pos: ti.types.ndarray(dtype=ti.f32, ndim=1), x0: ti.f32, y0: ti.f32,
                  res: ti.f32, width: ti.i32, rows: ti.i32,
                  out: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for p in range(xyz.shape[0]):
        out[p] = _cloth_height_above(xyz, pos, p, x0, y0, res, width, rows)


@ti.kernel
def _ground_mask(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                 pos: ti.types.ndarray(dtype=ti.f32, ndim=1), x0: ti.f32, y0: ti.f32,
                 res: ti.f32, width: ti.i32, rows: ti.i32, threshold: ti.f32,
                 ground: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for p in range(xyz.shape[0]):
        above = _cloth_height_above(xyz, pos, p, x0, y0, res, width, rows)
        ground[p] = ti.u8(1) if ti.abs(above) < threshold else ti.u8(0)


def _serial_simulation(cells: int) -> bool:
    """On the CPU, run all iterations in one thread and launch (_simulate_serial) for small
    cloths, and for every cloth when there are at most two threads: banded parallelism then
    saves less than its five synchronised tasks per iteration cost (measured on 2 cores)."""
    if not host_memory_backend():
        return False
    return cells <= SERIAL_CELLS or cpu_threads() <= 2


def _point_output(dtype, n):
    """Per-point output array: numpy on the CPU backend (written in place), else an ndarray."""
    return np.empty(n, dtype) if host_memory_backend() else ndarray(dtype, (n,))


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
        points = points_array(xyz)
        out = _point_output(np.float32, length(points))
        if length(points):
            _height_above(points, pos, self.x0, self.y0, self.resolution, cols, rows, out)
        return to_numpy(out)


def _grid(lo, hi, resolution: float, lattice_origin=None):
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    if lattice_origin is None:   # the package's layout: from the bounding box
        cols = int(math.floor((hi[0] - lo[0]) / resolution)) + 2 * BUFFER_PARTICLES
        rows = int(math.floor((hi[1] - lo[1]) / resolution)) + 2 * BUFFER_PARTICLES
        x0 = float(np.float32(lo[0] - BUFFER_PARTICLES * resolution))
        y0 = float(np.float32(lo[1] - BUFFER_PARTICLES * resolution))
        return lo, hi, cols, rows, x0, y0, 0
    # particles on a fixed lattice (first particle snapped down onto it), so clouds cut from one
    # survey (tiles) share their particles, and their bands, with the whole run
    corner = []
    counts = []
    steps = []
    for axis in (0, 1):
        start = lo[axis] - BUFFER_PARTICLES * resolution
        step = math.floor((start - lattice_origin[axis]) / resolution)
        start = lattice_origin[axis] + step * resolution
        corner.append(float(np.float32(start)))
        counts.append(int(math.ceil((hi[axis] - start) / resolution)) + BUFFER_PARTICLES)
        steps.append(step)
    return lo, hi, counts[0], counts[1], corner[0], corner[1], steps[1]


class LatticeTooLarge(ValueError):
    """The cloth over the points' extent would hold more particles than allowed (``csf``'s
    ``max_particles``); raised before anything is allocated."""

    def __init__(self, cols: int, rows: int, resolution: float, limit: int, why: str = ""):
        self.cols, self.rows, self.resolution, self.limit = cols, rows, resolution, limit
        self.particles = cols * rows
        super().__init__(f"a cloth of {cols} x {rows} particles ({cols * resolution:.0f} x "
                         f"{rows * resolution:.0f} m at {resolution:g} m) is more than the "
                         f"{limit} particles allowed" + (f" ({why})" if why else ""))


# bytes per particle of the simulation's arrays, slope smoothing included (at most)
PARTICLE_BYTES = 64


def _memory_particles():
    """Particles that half the machine's physical memory holds at PARTICLE_BYTES each (None where the
    system does not say; a container's own limit is the host's business: roadx_ti's cloth stages
    pass max_particles from roadx_ti.memory, which reads it)."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    return max(int(total) // (2 * PARTICLE_BYTES), 1) if total > 0 else None


def _fill_i32(shape, value):
    a = ndarray(np.int32, shape)
    a.fill(value)
    return a


def csf(xyz, *, cloth_resolution: float = 0.5, rigidness: int = 3, time_step: float = 0.65,
        iterations: int = 500, class_threshold: float = 0.5,
        slope_smooth: bool = False, lattice_origin=None, start_z: float = None,
        max_particles: int = None) -> ClothResult:
    """Cloth simulation filter of the (n, 3) float32 local points ``xyz`` (numpy or ndarray).

    Parameters mirror the `cloth-simulation-filter` package (``interations`` -> ``iterations``,
    ``bSloopSmooth`` -> ``slope_smooth``). Returns a ClothResult; ``ground`` is numpy either way.
    ``lattice_origin`` (x, y), local coordinates: lay the particles on that point plus multiples of
    the resolution instead of the package's bounding-box layout, so that tiles of one survey and
    the whole survey share one lattice (None: the package's layout); it should be a world multiple
    of LATTICE_PERIOD resolutions, so that the simulation's bands lie on the same world rows too.
    ``start_z`` (local z): the cloth starts above min(start_z, lowest point) instead of the lowest
    point (tiles of one survey pass the survey's lowest z: a cloth falling from another height
    collides at other speeds and settles differently).
    ``max_particles``: raise LatticeTooLarge, before any allocation, when the cloth over the
    points' bounding box would hold more particles (None: as many as half the machine's memory
    holds at PARTICLE_BYTES each; one stray point 10,000 km off had asked for 13 GB).
    """
    if not cloth_resolution > 0:
        raise ValueError("cloth_resolution must be > 0")
    if not 1 <= int(rigidness):
        raise ValueError("rigidness must be >= 1")
    if not time_step > 0:
        raise ValueError("time_step must be > 0")
    if int(iterations) < 1:
        raise ValueError("iterations must be >= 1")
    points = points_array(xyz)
    n = length(points)
    if n == 0:
        return ClothResult(np.zeros(0, bool), np.zeros((0, 0), np.float32), 0.0, 0.0,
                           float(cloth_resolution))
    res = float(cloth_resolution)

    # grid.bounding_box: the one bounding-box kernel (a kernel of its own here cost a compile)
    lo, hi, cols, rows, x0, y0, lattice_row = _grid(*bounding_box(points), res, lattice_origin)
    cells = cols * rows
    limit = _memory_particles() if max_particles is None else int(max_particles)
    if limit is not None and cells > limit:
        raise LatticeTooLarge(cols, rows, res, limit, "by half this machine's memory; max_particles sets another "
                              "bound" if max_particles is None else "by max_particles")
    if cells >= 2**31 - 1:
        raise LatticeTooLarge(cols, rows, res, 2**31 - 2)

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
    state = ndarray(np.int32, (2,))
    band_shift = lattice_row % BAND_ROWS
    band_phase = (lattice_row // BAND_ROWS) % 2
    bands = (rows + band_shift + BAND_ROWS - 1) // BAND_ROWS
    band_list = ndarray(np.int32, (cells,))
    band_count = ndarray(np.int32, (bands,))
    band_max = ndarray(np.int32, (bands,))
    floor_z = lo[2] if start_z is None else min(lo[2], float(start_z))
    _init_cloth(pos, old_pos, movable, band_list, band_count, state,
                float(-floor_z + CLOTH_START_ABOVE), cols, rows, BAND_ROWS, band_shift)
    # the package pre-multiplies gravity by time_step^2 and multiplies by it again in the
    # Verlet step: the displacement per step is gravity * time_step^4
    acceleration = -GRAVITY * time_step ** 4
    k = int(rigidness)
    single = _SINGLE_MOVE[k] if k <= 14 else 1.0
    double = _DOUBLE_MOVE[k] if k <= 14 else 0.5
    moves = ti.math.vec4(single, double, 1.0 - single, 1.0 - double)
    if _serial_simulation(cells):
        _simulate_serial(pos, old_pos, movable, height, band_list, band_count, band_max, state,
                         cols, rows, BAND_ROWS, band_shift, band_phase, acceleration, moves,
                         int(iterations), ITERATIONS_PER_CHECK, bands)
    done = 0
    while done < iterations and state.to_numpy()[0] == 0:
        batch = min(ITERATIONS_PER_CHECK, iterations - done)
        if done > 0:
            _refresh_active(movable, band_list, band_count, cols, rows, BAND_ROWS, band_shift)
        for _ in range(batch):
            _iterate(pos, old_pos, movable, height, band_list, band_count, band_max, state, cols,
                     rows, BAND_ROWS, band_shift, band_phase, acceleration, moves,
                     int(iterations), bands)
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

    ground = _point_output(np.uint8, n)
    _ground_mask(points, pos, x0, y0, res, cols, rows, float(class_threshold), ground)
    cloth_z = -pos.to_numpy().reshape(rows, cols)
    return ClothResult(to_numpy(ground).view(bool), cloth_z.astype(np.float32), x0, y0, res,
                       iterations_run)
