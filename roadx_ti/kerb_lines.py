"""Kerb lines found along lines, for surfaces too noisy for a per-point step filter.

A kerb is a line metres long along which the step is the same. Per point (road_regions' edge-
preserving height filter over 12 neighbours) a kerb of 8-10 cm under 4-5 cm of height noise
blurs; along a line of a few metres the two sides' mean heights differ by many standard errors.

``step_field``: the heights go onto a plan raster (normalised Gaussian convolution of one cell:
empty cells take their surroundings'), the surface at ``coarse`` scale is taken out, and the rest
is differentiated across lines of ``orientations`` directions by a derivative of a Gaussian of
``across`` m, elongated along the line by a Gaussian of ``along`` m (the raster rotated, a
separable filter, rotated back). A straight step of height h reads h / sqrt(2 pi) x (1 / s -
1 / coarse) there (s: across and the fill together), so the response converts to a height. Per
cell the strongest orientation is kept and thinned to the line (non-maximum suppression across
it, as in Canny's detector); ``spread`` is the filter's own noise (robust sigma of one
orientation's response over the paved cells, whose noise is the sensor's, not a lawn's relief).

The road stage uses a field two ways: graph edges that cross a line take its step
(``edge_line_steps``), and the regions on the two sides of each line, sampled past the slivers
that lie along it, become a kerb pair (``line_pairs``).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from roadx_ti.estimates import MAD_TO_SIGMA

SQRT_2PI = float(np.sqrt(2.0 * np.pi))
# bytes per raster cell at the field's peak: float64 sums, counts, heights, responses, the best
# response and its angle, and a rotated copy (up to twice the cells)
FIELD_BYTES_PER_CELL = 200
THREADS = 2      # orientations filtered at once (each holds a rotated raster, up to twice the cells)


@dataclass
class StepField:
    steps: np.ndarray       # (H, W) float64: the step height (m) of the line through the cell, 0 off lines
    direction: np.ndarray   # (H, W, 2) float64: unit vector in plan up the step
    lo: np.ndarray          # (2,) float64: the raster's corner (the points' frame)
    cell: float             # m
    spread: float           # m: the filter's own noise (robust sigma)


def _frame(xy: np.ndarray, cell: float, along: float):
    """(corner (2,), shape (H, W), cell indices (n, 2)) of the field's raster over ``xy``: the
    points' extent with 3 ``along`` of margin (the filter's reach along a line)."""
    pad = 3.0 * along
    lo = xy.min(axis=0) - pad
    ij = np.floor((xy - lo) / cell).astype(np.int64)
    return lo, tuple(int(v) + 1 + int(np.ceil(pad / cell)) for v in ij.max(axis=0)), ij


def raster_cells(xy: np.ndarray, cell: float, along: float) -> int:
    """Cells of the raster ``step_field`` makes for these points."""
    if len(xy) == 0:
        return 0
    _, shape, _ = _frame(np.asarray(xy, np.float64), cell, along)
    return shape[0] * shape[1]


def step_field(xy: np.ndarray, z: np.ndarray, cell: float, across: float, along: float, coarse: float,
               orientations: int = 12, measure: np.ndarray | None = None) -> StepField:
    """The kerb-line field of points ``xy`` (n, 2) with heights ``z`` (see the module docstring);
    ``measure``: bool per point, the points whose cells the spread is measured on (None: all)."""
    lo, shape, ij = _frame(np.asarray(xy, np.float64), cell, along)
    flat = ij[:, 0] * shape[1] + ij[:, 1]
    size = shape[0] * shape[1]
    total = np.bincount(flat, weights=np.asarray(z, np.float64), minlength=size).reshape(shape)
    count = np.bincount(flat, minlength=size).reshape(shape).astype(np.float64)
    weight = ndimage.gaussian_filter(count, 1.0, mode="constant")
    fine = ndimage.gaussian_filter(total, 1.0, mode="constant") / np.maximum(weight, 1e-9)
    s_coarse = coarse / cell
    surface = ndimage.gaussian_filter(total, s_coarse, mode="constant") / \
        np.maximum(ndimage.gaussian_filter(count, s_coarse, mode="constant"), 1e-9)
    inside = weight >= 0.2 * np.median(weight[count > 0])
    measured = inside & (count > 0)
    if measure is not None:
        chosen = np.bincount(flat, weights=np.asarray(measure, np.float64), minlength=size).reshape(shape)
        measured &= chosen > 0.5 * count
        if not measured.any():
            measured = inside & (count > 0)
    detail = np.where(inside, fine - surface, 0.0)
    del total, fine, surface
    to_height = SQRT_2PI / (1.0 / np.hypot(across, cell) - 1.0 / coarse)

    def response(k):
        """The step response of orientation k (a derivative across the line, the rotated raster's
        first axis, and a mean along it), back in the raster's frame."""
        theta = 180.0 * k / orientations
        rotated = ndimage.rotate(detail, theta, reshape=True, order=1, mode="constant")
        filtered = ndimage.gaussian_filter(rotated, (across / cell, along / cell), order=(1, 0), mode="constant") / cell
        del rotated
        back = ndimage.rotate(filtered, -theta, reshape=True, order=1, mode="constant")
        o0, o1 = (back.shape[0] - shape[0]) // 2, (back.shape[1] - shape[1]) // 2
        return back[o0:o0 + shape[0], o1:o1 + shape[1]]

    best = np.zeros(shape)
    angle = np.zeros(shape)
    spread = 0.0
    # orientations THREADS at a time on threads (scipy.ndimage releases the GIL), taken in order:
    # the same field as one after the other, with at most THREADS responses held
    with ThreadPoolExecutor(max_workers=THREADS) as pool:
        for first in range(0, orientations, THREADS):
            batch = [pool.submit(response, k) for k in range(first, min(first + THREADS, orientations))]
            for k, future in enumerate(batch, start=first):
                back = future.result()
                if k == 0:
                    spread = MAD_TO_SIGMA * float(np.median(np.abs(back[measured]))) * to_height
                better = np.abs(back) > np.abs(best)
                best = np.where(better, back, best)
                angle = np.where(better, np.deg2rad(180.0 * k / orientations), angle)
                del back, better
            del batch
    # the derivative's direction in raster axes (axis 0 turned by theta), pointing up the step
    sign = np.sign(best)
    ux, uy = sign * np.cos(angle), -sign * np.sin(angle)
    magnitude = np.abs(best)
    del best, angle, sign
    keep = inside
    ii, jj = np.indices(shape)
    for side in (1.0, -1.0):
        ni = np.clip(np.rint(ii + side * ux).astype(np.int64), 0, shape[0] - 1)
        nj = np.clip(np.rint(jj + side * uy).astype(np.int64), 0, shape[1] - 1)
        keep = keep & (magnitude >= magnitude[ni, nj])
    steps = np.where(keep, magnitude * to_height, 0.0)
    return StepField(steps, np.stack([ux, uy], axis=-1), lo, float(cell), float(spread))


def edge_line_steps(xyz: np.ndarray, ea: np.ndarray, eb: np.ndarray, field: StepField,
                    floor: float = 0.0) -> np.ndarray:
    """float64 per edge (a, b): the step up from a to b of the line nearest the edge's middle
    (within 1.5 cells; lines of steps under ``floor`` m left out) when a and b lie on its two
    sides, else 0."""
    out = np.zeros(len(ea))
    lines = field.steps > floor
    if not lines.any() or not len(ea):
        return out
    shape = field.steps.shape
    distance, (ni, nj) = ndimage.distance_transform_edt(~lines, return_indices=True)
    near_cell = distance <= 1.5
    del distance
    xy = np.asarray(xyz[:, :2], np.float64)
    ij = np.floor((0.5 * (xy[ea] + xy[eb]) - field.lo) / field.cell).astype(np.int64)
    np.clip(ij[:, 0], 0, shape[0] - 1, out=ij[:, 0])
    np.clip(ij[:, 1], 0, shape[1] - 1, out=ij[:, 1])
    near = np.flatnonzero(near_cell[ij[:, 0], ij[:, 1]])
    ij = ij[near]
    li, lj = ni[ij[:, 0], ij[:, 1]], nj[ij[:, 0], ij[:, 1]]
    del ni, nj
    u = field.direction[li, lj]
    centre = field.lo + (np.column_stack([li, lj]) + 0.5) * field.cell
    a, b = ea[near], eb[near]
    da = ((xy[a] - centre) * u).sum(axis=1)
    db = ((xy[b] - centre) * u).sum(axis=1)
    crosses = np.sign(da) * np.sign(db) < 0
    out[near] = np.where(crosses, np.sign(db - da) * field.steps[li, lj], 0.0)
    return out


def line_pairs(field: StepField, xyz: np.ndarray, label: np.ndarray, reach: float, probability,
               min_probability: float = 0.05, eligible: np.ndarray | None = None):
    """(lower region, upper region, length) int64, int64, float64 per region pair across kerb
    lines: the regions of the points nearest in plan to ``reach`` m below and above each line
    cell (both within ``reach``), and the length (m) of line between them, each cell weighted by
    ``probability(steps, spread)`` (those under ``min_probability`` left out)."""
    from roadx_ti.kernels.neighbors import nearest

    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    on = np.flatnonzero(field.steps.ravel() > 0)
    if not len(on) or len(xyz) == 0:
        return empty
    i, j = np.unravel_index(on, field.steps.shape)
    p = np.asarray(probability(field.steps[i, j], field.spread), np.float64)
    keep = p > min_probability
    i, j, p = i[keep], j[keep], p[keep]
    if not len(p):
        return empty
    u = field.direction[i, j]
    centre = field.lo + (np.column_stack([i, j]) + 0.5) * field.cell
    flat = np.ascontiguousarray(np.column_stack([xyz[:, :2], np.zeros(len(xyz))]), np.float32)
    sides = []
    for sign in (-1.0, 1.0):
        query = np.ascontiguousarray(np.column_stack([centre + sign * reach * u, np.zeros(len(u))]), np.float32)
        index, distance = nearest(flat, query)
        sides.append((np.asarray(index), np.asarray(distance) <= reach))
    ok = sides[0][1] & sides[1][1]
    if eligible is not None:
        ok &= eligible[sides[0][0]] & eligible[sides[1][0]]
    label = np.asarray(label, np.int64)
    lower, upper = label[sides[0][0][ok]], label[sides[1][0][ok]]
    weight = p[ok] * field.cell
    apart = lower != upper
    lower, upper, weight = lower[apart], upper[apart], weight[apart]
    if not len(lower):
        return empty
    span = int(label.max()) + 1
    key, inverse = np.unique(lower * span + upper, return_inverse=True)
    return key // span, key % span, np.bincount(inverse.ravel(), weights=weight)
