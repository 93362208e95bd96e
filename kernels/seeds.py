"""Roof seeds (METHODS.md P2) and the classified growth from them (P3), over a kNN graph.

P2: three constraints per point from its neighbourhood features, each one switchable:
- planar:   curvature(p) < curvature_max, and at least ceil(plane_coef * k) of its k neighbours
            have curvature < curvature_max too;
- compact:  max_distance(p) < r_max (farthest of the k neighbours);
- gradient: G_z <= alpha * max(G_x, G_y), G = per-axis extent of the neighbourhood.
seed = AND of the enabled constraints.

P3 semantics (order independent, so a data-parallel run equals a sequential one):
- growth edge {i, j} for j in kNN(i) (undirected; both points active):
      |n_i . n_j| >= cos(angle_max)                      (normals as lines)
  AND (colour rule off, OR neither point vegetation-coloured, OR |rgb_i - rgb_j| < color_max)
  i.e. a vegetation-coloured point is only joined by a neighbour of similar colour (a uniformly
  green roof grows, mottled foliage does not), and always needs the normal test as well;
- expandable points: active and (seed or curvature < expand_curvature_max); only they pass growth
  on (like the PCL rule "only smooth points become new seeds");
- core components: connected components of growth edges between expandable points; a core
  component holding at least one seed is a roof segment, labelled with its smallest point index;
- a non-expandable active point joined by a growth edge (either direction) to a roof core point
  is a leaf of that roof: it takes the smallest such segment label (integer atomic min);
- every other point is -1.

Edge completion (after P4's keep decision, grow_roof_edges): points on a roof's rim (eaves, gable
ends, courtyard rims) have neighbourhoods that take in wall, gutter, foliage or ground points and
fail the seed and normal tests. Planes first: a kept roof point with curvature < planar_max
carries its own plane (position, normal); the roof's other points take the plane of their nearest
planar kNN neighbour of the same roof (rounds of the previous round's planes). Then rounds of:
an unlabelled eligible point q joins the roof of a kNN neighbour p that carries a plane (origin
o, normal m) when |q - p| <= reach, |m . (q - o)| <= tol + tilt |q - o| and at least min_support
of q's k neighbours lie on that plane by the same rule; of several, the plane closest to q wins
(ties: lower roof id, then lower point index); q takes p's roof and plane, so chains stay on one
interior plane. Each round reads only the previous round's arrays.

Footprint completion (after P4, attach_to_footprints): a roof segment's plan-view footprint also
holds points the plane growth cannot reach: walls below the roof edge, chimneys and roof units
standing on it, roof points under overhanging foliage (their orthophoto colour is the tree's).
On a 2D grid of the kept roof points (per cell: lowest roof point index, roof z range), a
non-roof point q joins a roof when
- q is *inside* a footprint: along each of +x, -x, +y, -y a roof cell lies within inside_reach
  (q's own cell counts); it takes the segment of the nearest such cell and joins when it lies on
  that cell's roof surface (z within [z_min - surface_tol, z_max + surface_tol], any colour), or
  below the roof in a cell holding roof points (a wall return under its own roof edge, any colour:
  walls of flat roofs carry the orthophoto colour of the lawn beside them), or when it may join
  off the surface (off_surface_ok 1: the caller passes "not vegetation"), or, with off_surface_ok
  NEAR_SURFACE_ONLY, when it lies within near_tol of that z range (a chimney, vent or railing whose
  pulses split, which the returns cue alone takes for foliage);
- else q is *under a roof edge*: a roof cell within wall_reach (square window) has its lowest roof
  point above z(q) + surface_tol, and off_surface_ok(q) is 1 (INSIDE_ONLY: inside a footprint only,
  as 1 there); it takes the segment of the nearest such cell (ties: lower cell id).
Every decision reads only the grid built from the roof points before any point joins, so the
result does not depend on order (one pass, no chains).
A point's decision reads roof cells within max(inside_reach, wall_reach) only: when the grid over
the roof points' bounding box would hold more than FOOTPRINT_CELLS_PER_POINT cells per point
(roofs far apart, a stray roof point), it is laid over blocks of FOOTPRINT_BLOCK cells that hold
or border roof cells, each with the roof cells within reach around it, on the same cell lattice:
the same result with memory bounded by the points.
"""

import math

import numpy as np
from .taichi_compat import ti

from .common import (INT32_MAX, as_ndarray, f32_from_order_key, f32_order_key, index_array, is_ndarray, kernel_array,
                     length, like_input, ndarray, output_array, points_array, to_numpy, zeros)

FOOTPRINT_CELLS_PER_POINT = 4
FOOTPRINT_MIN_CELLS = 1 << 20
NEAR_SURFACE_ONLY = 2            # off_surface_ok: may join inside a footprint near its surface only
INSIDE_ONLY = 3                  # off_surface_ok: as 1 inside a footprint, not under a roof edge outside it
FOOTPRINT_BLOCK = 256            # cells per block edge of the blocked footprint grid


def required_planar_neighbours(plane_coef: float, k: int) -> int:
    """ceil(plane_coef * k), robust to float noise (0.7 * 10 = 7.000000000000001 -> 7)."""
    return int(math.ceil(round(plane_coef * k, 9)))


@ti.kernel
def _seed_constraints(knn: ti.types.ndarray(dtype=ti.i32, ndim=2),
                      curvature: ti.types.ndarray(dtype=ti.f32, ndim=1),
                      max_distance: ti.types.ndarray(dtype=ti.f32, ndim=1),
                      extent: ti.types.ndarray(dtype=ti.f32, ndim=2),
                      use_planar: ti.i32, curvature_max: ti.f32, planar_needed: ti.i32,
                      use_compact: ti.i32, r_max: ti.f32,
                      use_gradient: ti.i32, alpha: ti.f32,
                      planar: ti.types.ndarray(dtype=ti.u8, ndim=1),
                      compact: ti.types.ndarray(dtype=ti.u8, ndim=1),
                      gradient: ti.types.ndarray(dtype=ti.u8, ndim=1),
                      seed: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in curvature:
        ok_planar = 1
        if use_planar:
            ok_planar = 0
            if curvature[i] < curvature_max:
                count = 0
                for j in range(knn.shape[1]):
                    nb = knn[i, j]
                    if nb >= 0:
                        if curvature[nb] < curvature_max:
                            count += 1
                if count >= planar_needed:
                    ok_planar = 1
        ok_compact = 1
        if use_compact:
            ok_compact = 1 if max_distance[i] < r_max else 0
        ok_gradient = 1
        if use_gradient:
            ok_gradient = 1 if extent[i, 2] <= alpha * ti.max(extent[i, 0], extent[i, 1]) else 0
        planar[i] = ti.u8(ok_planar)
        compact[i] = ti.u8(ok_compact)
        gradient[i] = ti.u8(ok_gradient)
        seed[i] = ti.u8(ok_planar & ok_compact & ok_gradient)


def seed_constraints(knn_indices, curvature, max_distance, extent, *, curvature_max=None,
                     plane_coef=0.8, r_max=None, alpha=None) -> dict:
    """P2 constraints as uint8 masks (1 = passes): 'planar', 'compact', 'gradient', 'seed'.

    knn_indices (n, k) int32 (entries < 0 are missing neighbours and never count), curvature (n,),
    max_distance (n,) in m, extent (n, 3) in m. A threshold of None switches its constraint off
    (its mask is all ones): curvature_max (with plane_coef in [0, 1]), r_max (m), alpha.
    """
    knn = index_array(knn_indices)
    curv = kernel_array(curvature, "float32")
    n = length(curv)
    k = int(knn.shape[1]) if len(knn.shape) == 2 else 0
    out = {name: output_array(ti.u8, (n,), curvature) for name in ("planar", "compact", "gradient", "seed")}
    if n:
        _seed_constraints(knn, curv, kernel_array(max_distance, "float32"), kernel_array(extent, "float32"),
                          int(curvature_max is not None),
                          float(curvature_max if curvature_max is not None else 0.0),
                          required_planar_neighbours(plane_coef, k),
                          int(r_max is not None), float(r_max if r_max is not None else 0.0),
                          int(alpha is not None), float(alpha if alpha is not None else 0.0),
                          out["planar"], out["compact"], out["gradient"], out["seed"])
    return {name: like_input(mask, curvature) for name, mask in out.items()}


@ti.kernel
def _growth_edges(knn: ti.types.ndarray(dtype=ti.i32, ndim=2),
                  normal: ti.types.ndarray(dtype=ti.f32, ndim=2),
                  active: ti.types.ndarray(dtype=ti.u8, ndim=1),
                  rgb: ti.types.ndarray(dtype=ti.f32, ndim=2),
                  vegetation: ti.types.ndarray(dtype=ti.u8, ndim=1),
                  cos_angle_max: ti.f32, use_color: ti.i32, color_max_sq: ti.f32,
                  edge_ok: ti.types.ndarray(dtype=ti.u8, ndim=2)):
    for i, j in knn:
        nb = knn[i, j]
        ok = 0
        if nb >= 0 and active[i] != 0 and active[nb] != 0:
            dot = normal[i, 0] * normal[nb, 0] + normal[i, 1] * normal[nb, 1] + normal[i, 2] * normal[nb, 2]
            if ti.abs(dot) >= cos_angle_max:
                ok = 1
                if use_color and (vegetation[i] != 0 or vegetation[nb] != 0):
                    dr = rgb[i, 0] - rgb[nb, 0]
                    dg = rgb[i, 1] - rgb[nb, 1]
                    db = rgb[i, 2] - rgb[nb, 2]
                    if dr * dr + dg * dg + db * db >= color_max_sq:
                        ok = 0
        edge_ok[i, j] = ti.u8(ok)


def roof_growth_edges(knn_indices, normal, *, angle_max_deg: float, active=None, rgb=None,
                      vegetation=None, color_max=None):
    """uint8 (n, k): 1 where {i, knn[i, j]} is a growth edge (module docstring).

    normal (n, 3) unit vectors; rgb (n, 3) in the units of color_max (8-bit for the stages);
    vegetation (n,) uint8. The colour rule is on only when rgb, vegetation and color_max are all
    given. active (n,) uint8, default all.
    """
    knn = index_array(knn_indices)
    n, k = int(knn.shape[0]), int(knn.shape[1])
    use_color = rgb is not None and vegetation is not None and color_max is not None
    act = kernel_array(np.ones(n, np.uint8) if active is None else active, "uint8")
    rgb_nd = kernel_array(rgb, "float32") if use_color else as_ndarray(np.zeros((1, 3), np.float32))
    veg_nd = kernel_array(vegetation, "uint8") if use_color else as_ndarray(np.zeros(1, np.uint8))
    edge_ok = output_array(ti.u8, (n, k), knn_indices)
    if n and k:
        cos_max = float(np.float32(math.cos(math.radians(angle_max_deg))))
        _growth_edges(knn, kernel_array(normal, "float32"), act, rgb_nd, veg_nd, cos_max,
                      int(use_color), float(color_max) ** 2 if use_color else 0.0, edge_ok)
    return like_input(edge_ok, knn_indices)


@ti.kernel
def _expandable(curvature: ti.types.ndarray(dtype=ti.f32, ndim=1),
                seed: ti.types.ndarray(dtype=ti.u8, ndim=1),
                active: ti.types.ndarray(dtype=ti.u8, ndim=1),
                use_curvature: ti.i32, curvature_max: ti.types.ndarray(dtype=ti.f32, ndim=1),
                out: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in out:
        ok = 0
        if active[i] != 0:
            if seed[i] != 0 or use_curvature == 0:
                ok = 1
            elif curvature[i] < curvature_max[i]:
                ok = 1
        out[i] = ti.u8(ok)


@ti.kernel
def _mark_seeded(component: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 seed: ti.types.ndarray(dtype=ti.u8, ndim=1),
                 seeded: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in component:
        c = component[i]
        if c >= 0 and seed[i] != 0:
            seeded[c] = ti.u8(1)  # every writer writes the same value: no race in the result


@ti.kernel
def _roof_cores(component: ti.types.ndarray(dtype=ti.i32, ndim=1),
                seeded: ti.types.ndarray(dtype=ti.u8, ndim=1),
                expandable: ti.types.ndarray(dtype=ti.u8, ndim=1),
                active: ti.types.ndarray(dtype=ti.u8, ndim=1),
                core: ti.types.ndarray(dtype=ti.i32, ndim=1),
                label: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in component:
        c = component[i]
        is_core = -1
        if c >= 0 and expandable[i] != 0:
            if seeded[c] != 0:
                is_core = c
        core[i] = is_core
        lab = -1
        if expandable[i] != 0:
            lab = is_core
        elif active[i] != 0:
            lab = INT32_MAX  # leaf candidate, lowered by _attach_leaves
        label[i] = lab


@ti.kernel
def _attach_leaves(knn: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   edge_ok: ti.types.ndarray(dtype=ti.u8, ndim=2),
                   core: ti.types.ndarray(dtype=ti.i32, ndim=1),
                   expandable: ti.types.ndarray(dtype=ti.u8, ndim=1),
                   active: ti.types.ndarray(dtype=ti.u8, ndim=1),
                   label: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i, j in knn:
        nb = knn[i, j]
        if nb >= 0 and edge_ok[i, j] != 0:
            if core[i] >= 0 and expandable[nb] == 0 and active[nb] != 0:
                ti.atomic_min(label[nb], core[i])
            if core[nb] >= 0 and expandable[i] == 0 and active[i] != 0:
                ti.atomic_min(label[i], core[nb])


@ti.kernel
def _unattached_to_none(label: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in label:
        if label[i] == INT32_MAX:
            label[i] = -1


def grow_roof_segments(knn_indices, edge_ok, seed, *, curvature=None, expand_curvature_max=None,
                       active=None):
    """Roof segment label per point (int32 (n,)): the smallest point index of its roof core, -1
    for non-roof (semantics in the module docstring). Compact the ids with labels.relabel_compact.

    edge_ok from roof_growth_edges; seed (n,) uint8; curvature (n,) with expand_curvature_max
    (a scalar, or one value per point): points at or above it (and not seeds) cannot pass growth
    on (None: every point can).
    """
    from .labels import connected_components

    if int(knn_indices.shape[0]) == 0:
        return np.zeros(0, np.int32)
    knn = index_array(knn_indices)
    n = int(knn.shape[0])
    seed_nd = kernel_array(seed, "uint8")
    act = kernel_array(np.ones(n, np.uint8) if active is None else active, "uint8")
    use_curv = curvature is not None and expand_curvature_max is not None
    curv = kernel_array(curvature, "float32") if use_curv else as_ndarray(np.zeros(max(n, 1), np.float32))
    edges = kernel_array(edge_ok, "uint8")
    label = output_array(ti.i32, (n,), knn_indices)
    expandable = ndarray(ti.u8, (n,))
    limit = expand_curvature_max if use_curv else 0.0
    scalar = isinstance(limit, (int, float, np.number))
    limit = kernel_array(np.full(max(n, 1), limit, np.float32) if scalar else limit, "float32")
    _expandable(curv, seed_nd, act, int(use_curv), limit, expandable)
    component = kernel_array(connected_components(knn, edge_ok=edges, active=expandable), "int32")
    seeded = zeros(ti.u8, (n,))
    _mark_seeded(component, seed_nd, seeded)
    core = ndarray(ti.i32, (n,))
    _roof_cores(component, seeded, expandable, act, core, label)
    _attach_leaves(knn, edges, core, expandable, act, label)
    _unattached_to_none(label)
    return like_input(label, knn_indices)



@ti.kernel
def _plane_round(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                 knn: ti.types.ndarray(dtype=ti.i32, ndim=2),
                 label: ti.types.ndarray(dtype=ti.i32, ndim=1),
                 has_in: ti.types.ndarray(dtype=ti.u8, ndim=1),
                 plane_in: ti.types.ndarray(dtype=ti.f32, ndim=2),
                 has_out: ti.types.ndarray(dtype=ti.u8, ndim=1),
                 plane_out: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    # a segment point without a plane takes the plane of its nearest kNN neighbour of the same
    # segment that has one (previous round's planes only)
    for i in label:
        has = has_in[i]
        for c in ti.static(range(6)):
            plane_out[i, c] = plane_in[i, c]
        if label[i] >= 0 and has == 0:
            best_d = ti.f32(3.0e38)
            best = -1
            for j in range(knn.shape[1]):
                nb = knn[i, j]
                if nb >= 0:
                    if label[nb] == label[i] and has_in[nb] != 0:
                        dx = xyz[i, 0] - xyz[nb, 0]
                        dy = xyz[i, 1] - xyz[nb, 1]
                        dz = xyz[i, 2] - xyz[nb, 2]
                        d_sq = dx * dx + dy * dy + dz * dz
                        if d_sq < best_d or (d_sq == best_d and nb < best):
                            best_d = d_sq
                            best = nb
            if best >= 0:
                has = ti.u8(1)
                for c in ti.static(range(6)):
                    plane_out[i, c] = plane_in[best, c]
        has_out[i] = has


@ti.kernel
def _edge_round(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                knn: ti.types.ndarray(dtype=ti.i32, ndim=2),
                eligible: ti.types.ndarray(dtype=ti.u8, ndim=1),
                label_in: ti.types.ndarray(dtype=ti.i32, ndim=1),
                has_in: ti.types.ndarray(dtype=ti.u8, ndim=1),
                plane_in: ti.types.ndarray(dtype=ti.f32, ndim=2),
                reach_sq: ti.f32, tol: ti.f32, tilt: ti.f32, min_support: ti.i32,
                label_out: ti.types.ndarray(dtype=ti.i32, ndim=1),
                has_out: ti.types.ndarray(dtype=ti.u8, ndim=1),
                plane_out: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    for i in label_in:
        lab = label_in[i]
        has = has_in[i]
        for c in ti.static(range(6)):
            plane_out[i, c] = plane_in[i, c]
        if lab < 0 and eligible[i] != 0:
            best_d = ti.f32(3.0e38)
            best = -1
            for j in range(knn.shape[1]):
                nb = knn[i, j]
                if nb >= 0:
                    if label_in[nb] >= 0 and has_in[nb] != 0:
                        dx = xyz[i, 0] - xyz[nb, 0]
                        dy = xyz[i, 1] - xyz[nb, 1]
                        dz = xyz[i, 2] - xyz[nb, 2]
                        if dx * dx + dy * dy + dz * dz <= reach_sq:
                            # distance to the anchor's plane (origin o, normal m), allowing for the
                            # normal's uncertainty over the distance from the plane's origin
                            ox = xyz[i, 0] - plane_in[nb, 0]
                            oy = xyz[i, 1] - plane_in[nb, 1]
                            oz = xyz[i, 2] - plane_in[nb, 2]
                            off = ti.abs(ox * plane_in[nb, 3] + oy * plane_in[nb, 4] + oz * plane_in[nb, 5])
                            if off <= tol + tilt * ti.sqrt(ox * ox + oy * oy + oz * oz):
                                s = label_in[nb]
                                if off < best_d or (off == best_d and (s < lab or (s == lab and nb < best))):
                                    best_d = off
                                    best = nb
                                    lab = s
            if best >= 0:
                # support: how many of the point's k neighbours lie on that plane too (an eave
                # point has its roof side there, a crown point beside the roof few)
                support = 0
                for j in range(knn.shape[1]):
                    nb = knn[i, j]
                    if nb >= 0:
                        ox = xyz[nb, 0] - plane_in[best, 0]
                        oy = xyz[nb, 1] - plane_in[best, 1]
                        oz = xyz[nb, 2] - plane_in[best, 2]
                        off = ti.abs(ox * plane_in[best, 3] + oy * plane_in[best, 4] + oz * plane_in[best, 5])
                        if off <= tol + tilt * ti.sqrt(ox * ox + oy * oy + oz * oz):
                            support += 1
                if support < min_support:
                    best = -1
                    lab = label_in[i]
            if best >= 0:
                has = ti.u8(1)
                for c in ti.static(range(6)):
                    plane_out[i, c] = plane_in[best, c]
        label_out[i] = lab
        has_out[i] = has


def grow_roof_edges(xyz, knn_indices, segment, normal, curvature, eligible, *, reach: float,
                    tol: float, tilt: float, planar_max: float, rounds: int, min_support: int = 0):
    """Roof segments completed out to their boundary (int32 (n,), same ids as ``segment``).

    Planes: a segment point with curvature < planar_max carries its own plane (its position and
    its normal); the segment's other points take the plane of their nearest planar kNN neighbour
    of the same segment (``rounds`` data-parallel rounds). Then in each of ``rounds`` rounds an
    unlabelled ``eligible`` point q joins the segment of a kNN neighbour p carrying a plane
    (origin o, normal m) when |q - p| <= reach (m) and |m . (q - o)| <= tol + tilt * |q - o| (m);
    q takes p's segment and plane, so a chain of joins stays on one interior plane (it cannot
    creep down a wall), and only when at least ``min_support`` of its k neighbours lie on that
    plane by the same rule. Of several such p, the plane closest to q wins (ties: lower segment id,
    then lower point index). Each round reads only the previous one's arrays: order independent
    up to exact ties.
    """
    knn = index_array(knn_indices)
    n = int(knn.shape[0])
    label = np.ascontiguousarray(to_numpy(segment), np.int32).copy()
    if n == 0 or int(knn.shape[1]) == 0 or rounds <= 0 or not (label >= 0).any():
        return label
    host_xyz = to_numpy(points_array(xyz))      # float32, checked
    if len(host_xyz) != n:
        raise ValueError(f"xyz has {len(host_xyz)} points for {n} kNN rows")
    host_curv = np.asarray(to_numpy(curvature), np.float32)
    own = (label >= 0) & (host_curv < planar_max)
    plane = np.zeros((n, 6), np.float32)
    plane[own, :3] = host_xyz[own]
    plane[own, 3:] = np.asarray(to_numpy(normal), np.float32)[own]
    pts = as_ndarray(np.ascontiguousarray(host_xyz))
    planes = [as_ndarray(plane), ndarray(ti.f32, (n, 6))]
    has = [as_ndarray(own.astype(np.uint8)), ndarray(ti.u8, (n,))]
    labels = [as_ndarray(label), ndarray(ti.i32, (n,))]
    for _ in range(int(rounds)):
        _plane_round(pts, knn, labels[0], has[0], planes[0], has[1], planes[1])
        planes.reverse()
        has.reverse()
    elig = as_ndarray(np.ascontiguousarray(to_numpy(eligible), np.uint8))
    before = int(np.count_nonzero(label >= 0))
    for _ in range(int(rounds)):
        _edge_round(pts, knn, elig, labels[0], has[0], planes[0], float(reach) ** 2, float(tol), float(tilt),
                    int(min_support), labels[1], has[1], planes[1])
        labels.reverse()
        planes.reverse()
        has.reverse()
        now = int(np.count_nonzero(labels[0].to_numpy() >= 0))
        if now == before:
            break
        before = now
    return labels[0].to_numpy()


@ti.func
def _cell_index(x: ti.f32, y: ti.f32, x0: ti.f32, y0: ti.f32, cell: ti.f32, col0: ti.i32,
                row0: ti.i32) -> ti.math.ivec2:
    # the lattice is fixed by x0, y0 (whole grid); col0, row0: first column and row of this grid
    col = ti.cast(ti.floor((x - x0) / cell), ti.i32) - col0
    row = ti.cast(ti.floor((y - y0) / cell), ti.i32) - row0
    return ti.math.ivec2(col, row)


@ti.kernel
def _footprint_cells(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                     segment: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     x0: ti.f32, y0: ti.f32, cell: ti.f32, col0: ti.i32, row0: ti.i32, n_cols: ti.i32,
                     first: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     z_low: ti.types.ndarray(dtype=ti.i32, ndim=1),
                     z_high: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in segment:
        if segment[i] >= 0:
            c = _cell_index(xyz[i, 0], xyz[i, 1], x0, y0, cell, col0, row0)
            k = c[1] * n_cols + c[0]
            ti.atomic_min(first[k], i)
            key = f32_order_key(xyz[i, 2])
            ti.atomic_min(z_low[k], key)
            ti.atomic_max(z_high[k], key)


@ti.kernel
def _attach_footprint(xyz: ti.types.ndarray(dtype=ti.f32, ndim=2),
                      segment: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      off_surface_ok: ti.types.ndarray(dtype=ti.u8, ndim=1),
                      eligible: ti.types.ndarray(dtype=ti.u8, ndim=1),
                      x0: ti.f32, y0: ti.f32, cell: ti.f32, col0: ti.i32, row0: ti.i32,
                      n_cols: ti.i32, n_rows: ti.i32,
                      first: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      z_low: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      z_high: ti.types.ndarray(dtype=ti.i32, ndim=1),
                      inside_cells: ti.i32, wall_cells: ti.i32, surface_tol: ti.f32, near_tol: ti.f32,
                      out: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for i in segment:
        label = segment[i]
        if label < 0 and eligible[i] != 0:
            c = _cell_index(xyz[i, 0], xyz[i, 1], x0, y0, cell, col0, row0)
            z = xyz[i, 2]
            if c[0] >= 0 and c[0] < n_cols and c[1] >= 0 and c[1] < n_rows:
                # inside test: the first roof cell along each axis direction
                hits = 0
                best_d = INT32_MAX
                best_k = -1
                for d in range(4):
                    dx = 1 if d == 0 else (-1 if d == 1 else 0)
                    dy = 1 if d == 2 else (-1 if d == 3 else 0)
                    found = 0
                    for s in range(inside_cells + 1):
                        if found == 0:
                            cc = c[0] + dx * s
                            rr = c[1] + dy * s
                            if cc >= 0 and cc < n_cols and rr >= 0 and rr < n_rows:
                                k = rr * n_cols + cc
                                if first[k] != INT32_MAX:
                                    found = 1
                                    if s < best_d or (s == best_d and k < best_k):
                                        best_d = s
                                        best_k = k
                    hits += found
                if hits == 4:
                    lo = f32_from_order_key(z_low[best_k])
                    hi = f32_from_order_key(z_high[best_k])
                    on_surface = z >= lo - surface_tol and z <= hi + surface_tol
                    near_surface = z >= lo - near_tol and z <= hi + near_tol
                    # below the roof in a roof cell: a wall or eave return under the roof edge
                    under_own = best_d == 0 and z < lo - surface_tol
                    ok = off_surface_ok[i]
                    if on_surface or under_own or ok == 1 or ok == INSIDE_ONLY or \
                            (ok == NEAR_SURFACE_ONLY and near_surface):
                        label = segment[first[best_k]]
                elif off_surface_ok[i] == 1:
                    # under a roof edge: a roof cell nearby whose lowest roof point is above z
                    best_d = INT32_MAX
                    best_k = -1
                    for oy in range(-wall_cells, wall_cells + 1):
                        for ox in range(-wall_cells, wall_cells + 1):
                            cc = c[0] + ox
                            rr = c[1] + oy
                            if cc >= 0 and cc < n_cols and rr >= 0 and rr < n_rows:
                                k = rr * n_cols + cc
                                if first[k] != INT32_MAX:
                                    if f32_from_order_key(z_low[k]) > z + surface_tol:
                                        dist = ox * ox + oy * oy
                                        if dist < best_d or (dist == best_d and k < best_k):
                                            best_d = dist
                                            best_k = k
                    if best_k >= 0:
                        label = segment[first[best_k]]
        out[i] = label


def attach_to_footprints(xyz, segment, off_surface_ok=None, eligible=None, *, cell: float = 1.0,
                         inside_reach: float = 3.0, wall_reach: float = 1.0,
                         surface_tol: float = 0.5, near_tol: float = 0.0):
    """Segment label per point (int32 (n,)) after footprint completion (module docstring).

    xyz (n, 3) in m; segment (n,) int32 roof segment ids, -1 = none; off_surface_ok (n,) uint8
    (default all 1): 1 = may join off a roof surface (inside a footprint above or below it, or
    under a roof edge), INSIDE_ONLY (3) = as 1 inside a footprint but not under a roof edge outside
    it, NEAR_SURFACE_ONLY (2) = may join inside a footprint within ``near_tol`` of
    its roof cell's z range only (roof superstructures whose pulses split), 0 = on the surface
    only; eligible (n,) uint8 (default all 1): points that may join at all
    (the stage passes "high enough above ground"). cell, inside_reach, wall_reach, surface_tol in m.
    """
    if cell <= 0:
        raise ValueError(f"cell must be > 0, got {cell}")
    pts = points_array(xyz)
    seg = kernel_array(segment, "int32")
    n = length(seg)
    out = ndarray(ti.i32, (n,))
    seg_np = seg.to_numpy() if hasattr(seg, "to_numpy") else np.asarray(seg)
    roof = seg_np >= 0
    if n == 0 or not roof.any():
        if n:
            out.from_numpy(seg_np.astype(np.int32))
        return like_input(out, segment)
    host = to_numpy(pts)
    xy = host[roof, :2]
    margin = max(inside_reach, wall_reach) + cell
    x0, y0 = float(xy[:, 0].min() - margin), float(xy[:, 1].min() - margin)
    n_cols = int(np.floor((xy[:, 0].max() + margin - x0) / cell)) + 1
    n_rows = int(np.floor((xy[:, 1].max() + margin - y0) / cell)) + 1
    reach = (int(math.ceil(round(inside_reach / cell, 9))), int(math.ceil(round(wall_reach / cell, 9))))
    ok = np.ones(n, np.uint8) if off_surface_ok is None else to_numpy(off_surface_ok).astype(np.uint8)
    elig = np.ones(n, np.uint8) if eligible is None else to_numpy(eligible).astype(np.uint8)
    tols = (float(surface_tol), float(max(near_tol, surface_tol)))
    if n_cols * n_rows <= FOOTPRINT_CELLS_PER_POINT * n + FOOTPRINT_MIN_CELLS:
        _attach_on_grid(pts, seg, ok, elig, (x0, y0, cell), (0, 0, n_cols, n_rows), reach,
                        tols, out)
        return like_input(out, segment)
    result = seg_np.astype(np.int32).copy()
    _attach_by_blocks(host, seg_np, ok, elig, (x0, y0, cell), reach, tols, result)
    out.from_numpy(result)
    return like_input(out, segment)


def _attach_on_grid(pts, seg, ok, elig, lattice, window, reach, tols, out):
    """The footprint kernels on the grid of ``window`` = (col0, row0, n_cols, n_rows) cells of
    the lattice (x0, y0, cell); every roof point of ``seg`` must lie inside the window."""
    x0, y0, cell = lattice
    col0, row0, n_cols, n_rows = window
    first = ndarray(ti.i32, (n_cols * n_rows,))
    z_low = ndarray(ti.i32, (n_cols * n_rows,))
    z_high = ndarray(ti.i32, (n_cols * n_rows,))
    first.fill(INT32_MAX)
    z_low.fill(INT32_MAX)
    z_high.fill(-INT32_MAX - 1)
    ok, elig = as_ndarray(ok, "uint8"), as_ndarray(elig, "uint8")
    _footprint_cells(pts, seg, x0, y0, float(cell), col0, row0, n_cols, first, z_low, z_high)
    _attach_footprint(pts, seg, ok, elig, x0, y0, float(cell), col0, row0, n_cols, n_rows, first,
                      z_low, z_high, reach[0], reach[1], tols[0], tols[1], out)


def _attach_by_blocks(xyz, seg, ok, elig, lattice, reach, tols, result):
    """attach_to_footprints over blocks of FOOTPRINT_BLOCK cells holding or bordering roof cells
    (module docstring); writes the labels of the points of those blocks into ``result``."""
    x0, y0, cell = lattice
    # the kernels' own float32 arithmetic for the cells
    cells = [np.clip(np.floor((xyz[:, a] - np.float32(o)) / np.float32(cell)), -2**30, 2**30).astype(np.int64)
             for a, o in ((0, x0), (1, y0))]
    col, row = cells
    halo = max(reach) + 1
    shift = np.int64(1 << 32)
    # block coordinates + 2: the roof points' blocks and their neighbours are >= 0
    block_key = (col // FOOTPRINT_BLOCK + 2) * shift + (row // FOOTPRINT_BLOCK + 2)
    roof = seg >= 0
    ring = np.array([dc * shift + dr for dc in (-1, 0, 1) for dr in (-1, 0, 1)], np.int64)
    around = np.unique(np.unique(block_key[roof])[:, None] + ring[None, :])
    order = np.argsort(block_key, kind="stable")
    sorted_key = block_key[order]

    def points_of(keys):
        lo, hi = np.searchsorted(sorted_key, keys, "left"), np.searchsorted(sorted_key, keys, "right")
        return np.concatenate([order[a:b] for a, b in zip(lo, hi)])

    for b in around:
        core = points_of([b])
        if not len(core) or not ((~roof[core]) & (elig[core] != 0)).any():
            continue
        bc, br = divmod(int(b), int(shift))
        col0, row0 = (bc - 2) * FOOTPRINT_BLOCK - halo, (br - 2) * FOOTPRINT_BLOCK - halo
        size = FOOTPRINT_BLOCK + 2 * halo
        near = points_of(b + ring)
        near = near[roof[near] & (col[near] >= col0) & (col[near] < col0 + size)
                    & (row[near] >= row0) & (row[near] < row0 + size)]
        members = np.union1d(core, near)       # ascending: ties by point index as on one grid
        part = np.empty(len(members), np.int32)
        _attach_on_grid(np.ascontiguousarray(xyz[members]), np.ascontiguousarray(seg[members], np.int32),
                        ok[members], elig[members], lattice, (col0, row0, size, size), reach,
                        tols, part)
        inside = np.isin(members, core, assume_unique=True)
        result[members[inside]] = part[inside]


__all__ = ["seed_constraints", "required_planar_neighbours", "roof_growth_edges",
           "grow_roof_segments", "grow_roof_edges", "attach_to_footprints"]
