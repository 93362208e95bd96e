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
"""

import math

import numpy as np
import taichi as ti

from .common import INT32_MAX, as_ndarray, length, like_input, ndarray


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
    knn = as_ndarray(knn_indices, "int32")
    curv = as_ndarray(curvature, "float32")
    n = length(curv)
    k = int(knn.shape[1]) if len(knn.shape) == 2 else 0
    out = {name: ndarray(ti.u8, (n,)) for name in ("planar", "compact", "gradient", "seed")}
    if n:
        _seed_constraints(knn, curv, as_ndarray(max_distance, "float32"), as_ndarray(extent, "float32"),
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
    knn = as_ndarray(knn_indices, "int32")
    n, k = int(knn.shape[0]), int(knn.shape[1])
    use_color = rgb is not None and vegetation is not None and color_max is not None
    act = as_ndarray(np.ones(n, np.uint8) if active is None else active, "uint8")
    rgb_nd = as_ndarray(rgb, "float32") if use_color else as_ndarray(np.zeros((1, 3), np.float32))
    veg_nd = as_ndarray(vegetation, "uint8") if use_color else as_ndarray(np.zeros(1, np.uint8))
    edge_ok = ndarray(ti.u8, (n, k))
    if n and k:
        cos_max = float(np.float32(math.cos(math.radians(angle_max_deg))))
        _growth_edges(knn, as_ndarray(normal, "float32"), act, rgb_nd, veg_nd, cos_max,
                      int(use_color), float(color_max) ** 2 if use_color else 0.0, edge_ok)
    return like_input(edge_ok, knn_indices)


@ti.kernel
def _expandable(curvature: ti.types.ndarray(dtype=ti.f32, ndim=1),
                seed: ti.types.ndarray(dtype=ti.u8, ndim=1),
                active: ti.types.ndarray(dtype=ti.u8, ndim=1),
                use_curvature: ti.i32, curvature_max: ti.f32,
                out: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in out:
        ok = 0
        if active[i] != 0:
            if seed[i] != 0 or use_curvature == 0:
                ok = 1
            elif curvature[i] < curvature_max:
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

    edge_ok from roof_growth_edges; seed (n,) uint8; curvature (n,) with expand_curvature_max:
    points at or above it (and not seeds) cannot pass growth on (None: every point can).
    """
    from .labels import connected_components

    knn = as_ndarray(knn_indices, "int32")
    n = int(knn.shape[0])
    seed_nd = as_ndarray(seed, "uint8")
    act = as_ndarray(np.ones(n, np.uint8) if active is None else active, "uint8")
    use_curv = curvature is not None and expand_curvature_max is not None
    curv = as_ndarray(curvature, "float32") if use_curv else as_ndarray(np.zeros(max(n, 1), np.float32))
    label = ndarray(ti.i32, (n,))
    if n == 0:
        return like_input(label, knn_indices)
    expandable = ndarray(ti.u8, (n,))
    _expandable(curv, seed_nd, act, int(use_curv), float(expand_curvature_max or 0.0), expandable)
    component = as_ndarray(connected_components(knn, edge_ok=as_ndarray(edge_ok, "uint8"),
                                                active=expandable), "int32")
    seeded = ndarray(ti.u8, (n,))
    seeded.fill(0)
    _mark_seeded(component, seed_nd, seeded)
    core = ndarray(ti.i32, (n,))
    _roof_cores(component, seeded, expandable, act, core, label)
    _attach_leaves(knn, as_ndarray(edge_ok, "uint8"), core, expandable, act, label)
    _unattached_to_none(label)
    return like_input(label, knn_indices)


__all__ = ["seed_constraints", "required_planar_neighbours", "roof_growth_edges",
           "grow_roof_segments"]
