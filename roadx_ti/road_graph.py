"""Road / not-road labelling of a region graph (METHODS.md R6, target road selection).

The road is taken as the lower side of kerbs: the regions of a colour segmentation (kernels
``regions.merge_regions_by_colour``) and the steps along their shared boundaries are scored as a
binary labelling problem and solved exactly by one minimum cut (scipy's max-flow):

- a pair whose boundary steps up (a kerb: at least ``kerb_from`` of its edges step, fully from
  ``kerb_full``) penalises its upper side being road while the lower is not (``upper_road``) and
  both being road (``both_road``), and rewards its lower side being road (``lower_road``);
- a pair whose boundary is continuous wants one label (``smooth`` per edge), less so when its
  chroma or brightness differ (contrast-sensitive);
- each region's own term is the log ratio of two colour densities at its mean colour: of the
  regions on the lower sides of kerbs (road samples) and of those on the upper sides (sidewalk
  samples), weighted by their kerb edges: "road-like" is learnt from the scene itself, block by
  block (``colour_block``: the kerbs of the 3 x 3 blocks of 40 m around a region, a quarter of the
  scene's model mixed in), so that a street of its own asphalt shade learns its own. Strongly
  chromatic regions lean to not road, and so do green ones by their excess green of chromatic
  coordinates, which a shadow does not change (a lawn in tree shadow has little absolute chroma).

After the cut, road components (over continuous pairs) that are small or lack kerb evidence are
dropped (a large one too when no kerb at all lies along it, unless it is the largest: a paved yard
of the asphalt's grey is a blob apart from the street network), and not-road groups mostly
enclosed by road (markings, shadow patches, manholes) join it.

Streets without kerbs (country lanes between verges, village streets, shared spaces) give the cut
nothing to stand on: the lower sides of whatever steps the scene has (ditches, building feet)
teach it no road colour. When it keeps no road at all, or road that kerbs bound along less than
``kerbless_below`` of its outline (``road_kerb_share``), ``kerbless_road`` takes the road as what
such a street is in plan: a long ribbon, of a plausible carriageway width, of ground that is
neither chromatic nor green (asphalt, concrete, setts; verges, fields and gardens are not).
All energies are integers after scaling, so the cut is deterministic.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


# bytes per cell of kerbless_road's plan raster at its peak (float64 votes and distances, int32 parts)
RIBBON_BYTES_PER_CELL = 48
STRAY_SHARE = 0.05             # % of the points at each end of x and y that may lie off that raster


@dataclass(frozen=True)
class Weights:
    kerb_from: float = 0.05       # fraction of stepping boundary edges where a pair starts to be a kerb
    kerb_full: float = 0.20       # ... and is fully one
    upper_road: float = 32.0      # per kerb edge: upper side road, lower not
    both_road: float = 6.0        # per kerb edge: both sides road
    lower_road: float = 1.0       # per kerb edge: reward of the lower side being road
    smooth: float = 1.0           # per continuous edge: the two sides differ
    colour: float = 0.24          # per point: weight of the colour log ratio (at the reference density)
    colour_bandwidth: float = 6.0   # colour units of the density kernels
    max_chroma: float = 20.0      # regions more chromatic than this lean to not road ...
    chroma_cost: float = 1.0      # ... by this per point and per max_chroma beyond it
    green_from: float = 0.10      # regions whose excess green 2g - r - b of chromatic coordinates
    green_full: float = 0.25      # ... exceeds this lean to not road, fully from this (vegetation,
    green_cost: float = 2.0       # ... also in shadow, where absolute chroma fades): per point
    colour_block: float = 40.0    # m: learn the colour term from the kerbs in the 3 x 3 blocks of this
                                  # edge around each region (0: one model for the whole scene)
    colour_global: float = 0.25   # ... mixed with this share of the scene's model
    contrast: float = 12.0        # colour scale of the contrast-sensitive smoothness (chroma)
    bright_floor: float = 0.3     # smoothness across a brightness step keeps at least this share (0.7, 1.0 measured: no better)
    reference_density: float = 60.0   # points / m2 at which colour and smoothness balance as given
    colour_density_power: float = 1.5  # ... and at another density by (reference_density / density) ** this
    keep_area: float = 300.0      # a road component stays when it covers this many m2 ...
    keep_kerb: float = 0.15       # ... or this share of its boundary edges are kerbs below which it lies
    keep_area_kerb: float = 0.01  # a large component needs this share of kerbs below which it lies too
                                  # (the largest component excepted: the street network itself)
    min_area: float = 4.0         # and it covers at least this many m2
    absorb: float = 0.6           # a not-road group with this share of its boundary on road joins it
    absorb_max: float = 0.1       # ... when not larger than this share of the road
    # streets without kerbs (country lanes, shared spaces): when the kerb cut keeps no road at all,
    # the road is the ribbon of achromatic, not green ground (kerbless_road)
    ribbon_min_width: float = 2.5     # m: narrower ribbons are paths, kerb lines or gaps
    ribbon_max_width: float = 25.0    # m: ground wider than this everywhere is a yard, square or field
    ribbon_min_length: float = 4.0    # a ribbon is at least this many times longer than wide ...
    ribbon_min_area: float = 300.0    # ... and covers at least this many m2 (keep_area's scale)
    ribbon_colour: float = 20.0       # colour units: other ribbons of the largest one's colour are road too
    kerbless_below: float = 0.05      # ... also when kerbs bound less than this share of the outline of
                                      # the road the cut keeps (kerbed streets measured 0.14-0.81)


def kerb_relations(graph, w: Weights):
    """Per pair: kerb strength (in edges), continuity strength (in edges), and which side is
    upper (True: region pb is higher)."""
    m = graph.edges
    frac = (graph.up + graph.down) / np.maximum(m, 1e-9)
    span = max(w.kerb_full - w.kerb_from, 1e-9)
    kerb = m * np.clip((frac - w.kerb_from) / span, 0.0, 1.0)
    smooth = m - kerb
    return kerb, smooth, graph.up >= graph.down


GREEN_DARK = 30.0   # R + G + B (8-bit units) below which a region's chromatic coordinates are noise


def excess_green(mean):
    """ExG = 2g - r - b of the chromatic coordinates of region mean colours (Woebbecke et al.
    1995; kernels.vegetation): scale free, so a lawn in shadow scores as in sun. Regions darker
    than GREEN_DARK (R + G + B, 8-bit units) are taken at that brightness: noise, not green."""
    mean, total = _with_brightness(mean)
    return (2.0 * mean[:, 1] - mean[:, 0] - mean[:, 2]) / total


def _with_brightness(mean):
    """(float64 region mean colours, their R + G + B floored at GREEN_DARK): the denominator of
    chromatic coordinates that dark regions' noise does not blow up."""
    mean = np.asarray(mean, np.float64)
    return mean, np.maximum(mean.sum(axis=1), GREEN_DARK)


GREEN_DOMINANCE = 0.05   # chromatic g above both r and b by this much: vegetation's colour
ABSORB_MAX_VEGETATION = 0.1   # share of a not-road group's points in vegetation that keeps it out


def green_dominant(mean):
    """bool per region mean colour: green is its largest chromatic coordinate by GREEN_DOMINANCE
    (vegetation reflects most in green). Yellow and white paint, asphalt and concrete are not,
    though excess green (2g - r - b) scores yellow as green. Regions darker than GREEN_DARK
    (R + G + B, 8-bit units) are taken at that brightness."""
    mean, total = _with_brightness(mean)
    r, g, b = (mean[:, c] / total for c in range(3))
    return g - np.maximum(r, b) > GREEN_DOMINANCE


def chroma_vectors(mean):
    """Region mean colours minus their grey (the mean of the three channels)."""
    return mean - mean.mean(axis=1, keepdims=True)


def plain_ground(colour, w: Weights) -> np.ndarray:
    """bool per colour (region means or points' colours, 8-bit units): neither chromatic (chroma
    up to w.max_chroma) nor green (excess green under w.green_from): asphalt, concrete, setts."""
    chroma = np.sqrt((chroma_vectors(colour) ** 2).sum(axis=1))
    return (chroma <= w.max_chroma) & (excess_green(colour) < w.green_from)


_FILTER_SIGMA = 2.0                             # cells
_FILTER_RADIUS = int(4.0 * _FILTER_SIGMA + 0.5)  # gaussian_filter's default truncate (4 sigma)


def _log_ratio_at(query, lo_mean, lo_w, up_mean, up_w, bandwidth):
    """log(p_lower / p_upper) at the colours ``query``: weighted histograms of the sample colours
    (cells of half the bandwidth), smoothed by a Gaussian of the bandwidth, read at each query's cell."""
    from scipy.ndimage import gaussian_filter
    cell = bandwidth / 2.0
    bins = int(np.ceil(256.0 / cell)) + 1

    def cells(m):
        return tuple(np.clip(np.floor(np.asarray(m, np.float64) / cell).astype(np.int64), 0, bins - 1).T)
    at = cells(query)

    def density(m, wt):
        if len(m) == 0 or wt.sum() <= 0:
            return np.zeros(len(query))
        # only the box of the samples' cells and the filter's radius: the rest of the grid stays
        # exactly 0 (the same values as filtering the whole grid; 3 x 3 blocks of the colour
        # model filter one box each)
        c = np.asarray(cells(m))
        lo = np.maximum(c.min(axis=1) - _FILTER_RADIUS, 0)
        hi = np.minimum(c.max(axis=1) + _FILTER_RADIUS + 1, bins)
        grid = np.zeros(tuple(hi - lo))
        np.add.at(grid, tuple(c - lo[:, None]), wt)
        grid = gaussian_filter(grid, sigma=_FILTER_SIGMA, mode="constant") / wt.sum()
        q = np.asarray(at)
        inside = np.all((q >= lo[:, None]) & (q < hi[:, None]), axis=0)
        out = np.zeros(len(query))
        out[inside] = grid[tuple(q[:, inside] - lo[:, None])]
        return out
    floor = 1e-4 * (2.0 * np.pi * 4.0) ** -1.5      # about the old kernel floor, per cell
    p_lo, p_up = density(lo_mean, lo_w), density(up_mean, up_w)
    return np.clip(np.log((p_lo + floor) / (p_up + floor)), -3.0, 3.0)


def _colour_log_ratio(mean, lower, upper, weight, bandwidth, centroid=None, block=0.0, global_share=1.0):
    """log(p_lower / p_upper) at every region's mean colour, the densities those of the sample
    regions' mean colours (lower / upper sides of clear kerbs, weighted by their kerb edges).
    With ``block`` > 0 and region centroids: each region's densities from the samples in the
    3 x 3 blocks of that edge around its own (a street of its own asphalt shade learns its own
    road colour), mixed with the scene's by ``global_share``."""
    llr = _log_ratio_at(mean, mean[lower], weight, mean[upper], weight, bandwidth)
    if block <= 0 or centroid is None or global_share >= 1.0 or len(lower) == 0:
        return llr
    cell = np.floor(np.asarray(centroid, np.float64) / block).astype(np.int64)
    blocks, inverse = np.unique(cell, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    # the regions of each block, in region order: one sort instead of a scan per block
    members = np.split(np.argsort(inverse, kind="stable"), np.cumsum(np.bincount(inverse))[:-1])
    cell_lo, cell_up = cell[lower], cell[upper]
    out = llr.copy()
    for block_cell, here in zip(blocks, members):
        lo = np.all(np.abs(cell_lo - block_cell) <= 1, axis=1)
        up = np.all(np.abs(cell_up - block_cell) <= 1, axis=1)
        if not lo.any() or not up.any():
            continue
        local = _log_ratio_at(mean[here], mean[lower[lo]], weight[lo], mean[upper[up]], weight[up], bandwidth)
        out[here] = (1.0 - global_share) * local + global_share * llr[here]
    return out


def _min_cut(unary_road, A, B, C, D, pa, pb, n):
    """Minimise sum unary_road * x + sum E_pair(x_a, x_b) over binary x (1 = road), with pair
    energies A=E(0,0), B=E(0,1), C=E(1,0), D=E(1,1), B + C >= A + D. Returns bool (n,)."""
    # scipy here, not at the top: a CLI run that stops at its config check does not pay for it
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import breadth_first_order, maximum_flow

    lin = unary_road.copy()
    np.add.at(lin, pa, C - A)
    np.add.at(lin, pb, D - C)
    pair = B + C - A - D
    source, sink = n, n + 1
    pos, neg, pe = lin > 0, lin < 0, pair > 0
    rows = np.concatenate([np.flatnonzero(pos), np.full(int(neg.sum()), source), pb[pe]])
    cols = np.concatenate([np.full(int(pos.sum()), sink), np.flatnonzero(neg), pa[pe]])
    cap = np.concatenate([lin[pos], -lin[neg], pair[pe]])
    scale = 100.0 / max(1.0, cap.max(initial=0.0) / 2.0e7)   # integer capacities below 2^31
    cap = np.maximum(np.rint(cap * scale), 0).astype(np.int64)
    graph = csr_matrix((cap.astype(np.int32), (rows, cols)), shape=(n + 2, n + 2))
    graph.sum_duplicates()
    flow = maximum_flow(graph, source, sink)
    residual = graph - flow.flow
    residual.data[residual.data < 0] = 0
    residual.eliminate_zeros()
    reached = breadth_first_order(residual, source, directed=True, return_predecessors=False)
    road = np.zeros(n + 2, bool)
    road[reached] = True
    return road[:n]


def label_road(graph, density: float, w: Weights = Weights(), centroid=None):
    """bool per region (road) and facts for the summary. centroid: (R, 2) region centroids in
    plan (m), for a colour term learnt block by block (Weights.colour_block)."""
    n = graph.n_regions
    pa, pb, count = graph.pa, graph.pb, graph.count
    if n == 0:
        return np.zeros(0, bool), {"kerb_edges": 0}
    kerb, smooth, b_upper = kerb_relations(graph, w)
    mean = graph.mean_colour()
    chroma_vec = chroma_vectors(mean)
    chroma = np.sqrt((chroma_vec ** 2).sum(axis=1))
    d_chroma = np.sqrt(((chroma_vec[pa] - chroma_vec[pb]) ** 2).sum(axis=1))
    d_bright = np.abs(mean[pa].mean(axis=1) - mean[pb].mean(axis=1))
    contrast = np.exp(-0.5 * (d_chroma / w.contrast) ** 2) * \
        (w.bright_floor + (1.0 - w.bright_floor) * np.exp(-0.5 * (d_bright / (3.0 * w.contrast)) ** 2))
    potts = w.smooth * contrast * smooth
    k_up_b = kerb * b_upper
    k_up_a = kerb * ~b_upper
    A = w.lower_road * kerb
    B = potts + w.upper_road * k_up_b
    C = potts + w.upper_road * k_up_a
    D = w.both_road * kerb
    # the scene's own road colour, from the two sides of clear kerbs (kerb samples of paved
    # surfaces only, without the lawns kerbs also edge, measured no better: 300 k median E1 1.66 -> 2.22)
    clear = kerb > 0.5 * graph.edges
    lower = np.where(b_upper, pa, pb)[clear]
    upper = np.where(b_upper, pb, pa)[clear]
    llr = _colour_log_ratio(mean, lower, upper, kerb[clear], w.colour_bandwidth, centroid,
                            w.colour_block, w.colour_global)
    # points per area vs edges per boundary length: keep the balance at any density
    balance = np.sqrt(w.reference_density / max(density, 1e-6))
    # colour per point: 0.24 x (reference / density)^1.5. At 1.0 x sqrt the colour of whole regions
    # outweighed their kerbs: a sidewalk of mildly road-like colour along a noisy kerb joined the
    # road, a street of its own asphalt shade or a repair patch left it (uav-road 300 k seed 1 E2
    # 9.67 %, 4 M seed 8 E1 6.87 %). A flat 0.3 x sqrt lost road where points are sparse and the
    # road leans on its colour (AHN3 at 13 points/m2 E1 6.75 -> 13.5 %, a held-out street at 20
    # points/m2 2.5 -> 4.1 %): below the reference the weight grows faster (ACCURACY.md's notes)
    colour_balance = (w.reference_density / max(density, 1e-6)) ** w.colour_density_power
    # vegetation in sun or shade (the absolute chroma above fades in shadow): ExG of the region's mean
    green = np.clip((excess_green(mean) - w.green_from) / max(w.green_full - w.green_from, 1e-9), 0.0, 1.0)
    unary = -count * w.colour * colour_balance * llr + count * w.chroma_cost * \
        np.maximum(chroma - w.max_chroma, 0.0) / w.max_chroma + count * w.green_cost * balance * green
    road = _min_cut(unary, A, B, C, D, pa, pb, n)
    cut_road = int(count[road].sum())
    road = _keep_components(graph, road, kerb, b_upper, density, w)
    road, absorbed = _absorb_enclosed(graph, road, kerb, w, vegetation=green_dominant(mean))
    facts = {"regions": int(n), "kerb_edges": float(round(kerb.sum(), 1)),
             "kerb_pairs": int(clear.sum()), "road_points_after_cut": cut_road,
             "absorbed_points": int(absorbed), "road_kerb_share": round(road_kerb_share(graph, road, kerb, b_upper), 4)}
    return road, facts


def road_kerb_share(graph, road, kerb, b_upper) -> float:
    """Share of the road's outline (its graph edges to not-road regions) that is kerb edges the
    road lies below: high where kerbs bound the streets, near 0 where none does."""
    out = road[graph.pa] != road[graph.pb]
    edges = graph.edges[out].sum()
    if edges <= 0:
        return 0.0
    lower = np.where(b_upper, graph.pa, graph.pb)       # as in label_road and _keep_components
    return float(kerb[out & road[lower]].sum() / edges)


def _components(n, pa, pb, link):
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    g = csr_matrix((np.ones(int(link.sum())), (pa[link], pb[link])), shape=(n, n))
    return connected_components(g, directed=False)


def _keep_components(graph, road, kerb, b_upper, density, w):
    """Road components over continuous pairs: keep the large ones (area, with at least
    keep_area_kerb of their boundary kerbs they lie below, or the largest) and those bounded by
    kerbs they lie below (keep_kerb of their own boundary): absolute rules, so that a street
    segment cut off by parked cars counts the same in a small scene and a large one."""
    n, pa, pb = graph.n_regions, graph.pa, graph.pb
    if not road.any():
        return road
    nc, comp = _components(n, pa, pb, road[pa] & road[pb] & (kerb < 0.5 * graph.edges))
    area = np.bincount(comp, weights=graph.count * road, minlength=nc) / max(density, 1e-9)
    lower = np.where(b_upper, pa, pb)
    upper = np.where(b_upper, pb, pa)
    ev = (kerb > 0) & road[lower] & ~road[upper]
    evidence = np.bincount(comp[lower[ev]], weights=kerb[ev], minlength=nc)
    out_a = road[pa] & ~road[pb]
    out_b = road[pb] & ~road[pa]
    boundary = np.bincount(np.concatenate([comp[pa[out_a]], comp[pb[out_b]]]),
                           weights=np.concatenate([graph.edges[out_a], graph.edges[out_b]]), minlength=nc)
    boundary = np.maximum(boundary, 1e-9)
    # keep_area_kerb 0: every large component (evidence >= 0)
    large = (area >= w.keep_area) & ((evidence >= w.keep_area_kerb * boundary) | (area == area.max()))
    keep = (large | (evidence >= w.keep_kerb * boundary)) & (area >= w.min_area)
    return road & keep[comp]


def _absorb_enclosed(graph, road, kerb, w, rounds=3, vegetation=None):
    """Not-road groups (over continuous pairs) whose boundary is mostly road, with no kerb
    between them and the road, and not too large, join the road: markings, shadow patches,
    manholes. A group with vegetation (``vegetation``, bool per region: at least
    ABSORB_MAX_VEGETATION of its points in such regions) is a verge, an island or a garden and
    does not (uav-road 4 M seed 3: a 70 k-point lawn with a shadowed sidewalk joined the road)."""
    n, pa, pb, m = graph.n_regions, graph.pa, graph.pb, graph.edges
    green = np.zeros(n, bool) if vegetation is None else np.asarray(vegetation, bool)
    before = graph.count[road].sum()
    road = road.copy()
    for _ in range(rounds):
        if not road.any():
            break
        ng, group = _components(n, pa, pb, ~road[pa] & ~road[pb] & (kerb < 0.5 * m))
        group = np.where(road, -1, group)
        ga, gb = group[pa], group[pb]
        leaving = ga != gb
        sides = [(ga, leaving & (ga >= 0)), (gb, leaving & (gb >= 0))]
        boundary = sum(np.bincount(g[s], weights=m[s], minlength=ng) for g, s in sides)
        onto_road = sum(np.bincount(g[s & road[o]], weights=m[s & road[o]], minlength=ng)
                        for (g, s), o in zip(sides, (pb, pa)))
        kerb_road = sum(np.bincount(g[s & road[o]], weights=kerb[s & road[o]], minlength=ng)
                        for (g, s), o in zip(sides, (pb, pa)))
        inside = group >= 0
        size = np.bincount(group[inside], weights=graph.count[inside], minlength=ng)
        verdure = np.bincount(group[inside & green], weights=graph.count[inside & green], minlength=ng)
        take = (onto_road >= w.absorb * np.maximum(boundary, 1e-9)) & (kerb_road <= 0.2 * onto_road) \
            & (size <= w.absorb_max * graph.count[road].sum()) & (verdure < ABSORB_MAX_VEGETATION * size)
        if not take.any():
            break
        road |= (group >= 0) & take[np.maximum(group, 0)]
    return road, graph.count[road].sum() - before


def kerbless_road(graph, xy, spacing: float, w: Weights = Weights()):
    """bool per region: the road of a scene without kerbs (see the module docstring). The regions
    neither chromatic nor green are rasterised in plan (cells of about two point spacings, sized
    from the occupied cells' extent, gaps of one cell closed); the parts of that ground wider
    than ``ribbon_max_width`` (an opening by a disk of half that width, by two distance
    transforms) are taken out; the connected ribbons left that are long (``ribbon_min_length``
    widths, ``ribbon_min_area``) and of a carriageway's width (twice the 90th percentile of the
    distance to their edge) and of the largest such ribbon's mean colour (``ribbon_colour``) are
    road, and so is each region with most of its points on them."""
    from scipy import ndimage

    from roadx_ti.memory import dense_limit

    n = graph.n_regions
    road = np.zeros(n, bool)
    if n == 0 or len(xy) == 0:
        return road
    mean = graph.mean_colour()
    plain = plain_ground(mean, w)
    cell = max(2.0 * float(spacing), 0.25)
    xy = np.asarray(xy, np.float64)
    # the raster spans the points less a few strays (real files carry points kilometres away)
    lo, hi = np.percentile(xy, STRAY_SHARE, axis=0) - cell, np.percentile(xy, 100.0 - STRAY_SHARE, axis=0) + cell
    inside_box = np.all((xy >= lo) & (xy <= hi), axis=1)
    ij = np.floor((np.clip(xy, lo, hi) - lo) / cell).astype(np.int64)
    shape = tuple(int(v) + 1 for v in ij.max(axis=0))
    if shape[0] * shape[1] > dense_limit(len(xy), RIBBON_BYTES_PER_CELL):
        return road
    flat = ij[:, 0] * shape[1] + ij[:, 1]
    on = plain[graph.label] & inside_box
    # a cell is plain ground when most of its points are
    votes = np.bincount(flat, weights=np.where(on, 1.0, -1.0), minlength=shape[0] * shape[1])
    ground = ndimage.binary_closing((votes > 0).reshape(shape), structure=np.ones((3, 3), bool),
                                    border_value=0) | (votes > 0).reshape(shape)
    half = 0.5 * w.ribbon_max_width
    inside = ndimage.distance_transform_edt(ground) * cell
    wide = ndimage.distance_transform_edt(~(inside > half)) * cell <= half
    ribbon = ground & ~wide
    parts, count = ndimage.label(ribbon, structure=np.ones((3, 3), bool))
    if count == 0:
        return road
    index = np.arange(1, count + 1)
    area = np.bincount(parts.ravel(), minlength=count + 1)[1:] * cell * cell
    width = 2.0 * np.array(ndimage.labeled_comprehension(inside, parts, index, lambda v: np.percentile(v, 90),
                                                         float, 0.0))
    length = area / np.maximum(width, 1e-9)
    keep = (area >= w.ribbon_min_area) & (width >= w.ribbon_min_width) & (width <= w.ribbon_max_width) \
        & (length >= w.ribbon_min_length * width)
    if not keep.any():
        return road
    # one street network, one surface: the largest ribbon is the road, and the others are too
    # when their colour is its colour (a gravel yard round a farm or a field in a tree's shadow
    # make ribbons of other colours)
    on_ribbon = on & (parts.ravel()[flat] > 0)
    which = parts.ravel()[flat[on_ribbon]] - 1
    colour = mean[graph.label[on_ribbon]]
    points = np.maximum(np.bincount(which, minlength=count), 1)
    ribbon_colour = np.column_stack([np.bincount(which, weights=colour[:, c], minlength=count) for c in range(3)]) \
        / points[:, None]
    main = int(np.argmax(np.where(keep, area, -1.0)))
    keep &= np.linalg.norm(ribbon_colour - ribbon_colour[main], axis=1) <= w.ribbon_colour
    kept = np.concatenate([[False], keep])[parts].ravel()
    share = np.bincount(graph.label, weights=kept[flat] & on, minlength=n) / np.maximum(
        np.bincount(graph.label, minlength=n), 1)
    return share >= 0.5
