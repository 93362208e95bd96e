"""R6, region-level: colour region growing that does not leak, and road selection by kerbs.

The paper's R6 grows regions point to point (``color_growing``: PCL RegionGrowingRGB, a point
joins when its colour is within Q_t of its neighbour's). On real and simulated streets that
sits at a knife edge: colour gradients chain road into sidewalk, or noise shatters the road.
This stage keeps R6's two steps with region-level criteria and reads every threshold from the
cloud itself:

1. **Region growing** (kernels ``regions``): colours are denoised by a neighbourhood median;
   regions then merge by their *mean* colours, most similar pairs first, over a schedule of
   thresholds that are multiples of the measured colour noise; a pair whose shared boundary
   steps (kerb evidence, from an edge-preserving height filter whose width follows the measured
   height noise) never merges, nor do pairs of different chroma (grass and asphalt).
2. **Road selection** (``roadx_ti.road_graph``): the road is the lower side of kerbs, whatever
   its colour: an exact minimum cut over the region graph with kerb terms (a kerb's upper side
   is not road), contrast-sensitive smoothness, and a colour term learnt from the two sides of
   the scene's own clear kerbs.
   With ``kerb_lines`` (off by default), where the measured height noise blurs a common kerb in
   the filtered heights (2.5 noise sigmas above 10 cm), kerbs are also looked for along lines
   (``roadx_ti.kerb_lines``): a step filter 0.2 m across and 2 m along a line reads a 9 cm kerb
   under 4.6 cm of noise at its height (per point it is 2 sigmas). Graph edges between paved
   points that cross a line take its step (the larger of the two probabilities), and the regions
   on the two sides of each confident line (sampled past the slivers that lie along it) become a
   kerb pair of the cut.
3. **Surface test**: road points that stand out above the road's local surface (the median
   slope-corrected height of their nearest road points in plan) by more than a few measured
   height-noise sigmas are not road surface: the lowest parts of parked cars (within the
   cloth's class threshold of the road), kerb faces, debris.

Colour source: RGB (8-bit units), else LiDAR intensity as a grey (scaled to 8-bit units by its
99th percentile), else geometry only (kerbs and smoothness decide).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from pydantic import Field, field_validator

from roadx_ti.chunks import over_chunks
from roadx_ti.cloud import Cloud
from roadx_ti.estimates import MAD_TO_SIGMA, plan_points
from roadx_ti.kernels.regions import MAX_ROW
from roadx_ti.road_graph import Weights, kerbless_road, label_road
from roadx_ti.stages.base import CLASS_OTHER, CLASS_ROAD, MIN_BUFFER, MIN_CELL, Stage, StageContext, StageOptions, StageResult

# m: a common kerb height (kerbs are commonly 8-16 cm): measured height noise that blurs steps of
# this height gets a warning
TYPICAL_KERB = 0.10
# above this many working points the kNN rows are not held through the region merge but queried
# again after it (memory for time: 48 B/pt of rows against about 0.5 s per million points)
REQUERY_ROWS_ABOVE = 2_000_000
# m: kerb lines are looked for in the surface less its shape at this scale (roadx_ti.kerb_lines)
LINE_COARSE = 2.0
# line cells less likely than this to be a kerb make no region pair (weaker ones, summed along
# lines, took the road of held-out streets apart, and a lane's verge edges made it a kerbed road)
LINE_PAIR_MIN_PROBABILITY = 0.5


class RoadRegionsOptions(StageOptions):
    k: int = Field(12, ge=4, le=MAX_ROW - 1, description="neighbours per point of the filters (median "
                   "colour, edge-preserving heights; at most the region kernels' row: a point and 32)")
    graph_k: int | None = Field(None, ge=3, le=MAX_ROW - 1, description="the nearest this many of them are "
                                "the region graph's edges (None: all k)")
    edge_factor: float = Field(2.0, gt=0, description="longest graph edge, as a multiple of the median "
                               "distance to the k-th neighbour (the measured point spacing)")
    slope_cell: float = Field(2.5, ge=MIN_CELL, description="cell edge of the coarse planes whose slope is "
                              "taken out before heights are compared (m)")
    filter_width: float = Field(2.5, gt=0, description="edge-preserving height filter window, as a "
                                "multiple of the measured height noise")
    kerb_min: float = Field(0.05, gt=0, description="smallest height step that counts as a kerb (m)")
    kerb_max: float = Field(0.30, gt=0, description="largest (m); higher steps are walls, not kerbs")
    kerb_prior: float = Field(0.02, gt=0, lt=1, description="prior share of graph edges that cross kerbs")
    colour_levels: tuple[float, ...] = Field((1.2, 1.8, 2.4), description="region merging thresholds, "
                                             "multiples of the measured colour noise")
    max_chroma_step: float = Field(10.0, gt=0, description="regions whose chroma (colour minus grey) "
                                   "differ by more never merge (8-bit colour units)")
    step_veto: float = Field(0.1, ge=0, le=1, description="regions never merge when more than this share "
                             "of their boundary edges step")
    min_region_points: int = Field(8, ge=1, description="smaller regions join their best neighbour")
    boundary_passes: int = Field(2, ge=0, le=5, description="passes of the boundary height vote "
                                 "(kernels.regions.boundary_vote) after the road is chosen")
    surface_tol: float = Field(4.0, ge=0, description="a road point standing more than this many measured "
                               "height-noise sigmas (at least kerb_min) above the median slope-corrected "
                               "height of its surface_k nearest road points in plan is not road surface: the "
                               "skirts of cars, kerb faces, debris (0: off)")
    surface_k: int = Field(32, ge=4, le=MAX_ROW - 1, description="road points in plan that the surface "
                           "test takes the road's local height from")
    settle: float = Field(0.005, gt=0, lt=1, description="a merging level ends when a round joins fewer "
                          "than this share of the regions left (the rest is a thin tail)")
    ensemble: tuple[float, ...] = Field((1.0,), min_length=1, description="scales of the colour levels after "
                                        "the first (unitless): one segmentation and road choice per scale, each "
                                        "from the regions the first level leaves; a point is road when most of "
                                        "the choices say so. One segmentation's choice flips small pieces of road "
                                        "or sidewalk with any small change of the input (a delivery at 1 mm, "
                                        "another sample); the majority of [0.7, 0.85, 1.0, 1.15, 1.3] varies "
                                        "less, at about 1.8 x this stage's time (ACCURACY.md's notes)")
    noise_block: float | None = Field(None, gt=0, description="measure the height noise and the filtered "
                                      "steps' spread per plan block of this edge (m) rather than once over the "
                                      "run: the filter's window and the kerb evidence follow noise that varies "
                                      "across a survey (ACCURACY.md's notes: a noisy scene beside a quiet one "
                                      "lost streets); None: once")
    kerb_lines: bool = Field(False, description="where the height noise blurs common kerbs in the filtered "
                             "heights (filter_width x the noise above TYPICAL_KERB, 10 cm), find kerbs along lines "
                             "too (roadx_ti.kerb_lines): edges that cross a line take its step, and the regions "
                             "on its two sides become a kerb pair; fully from 10 % above that, not at all 10 % "
                             "below. Off by default: sidewalks of the road's grey stay off the road behind 8-10 "
                             "cm kerbs under 4-5 cm of noise, but streets bounded by crossings were lost "
                             "elsewhere (ACCURACY.md's notes)")
    line_across: float = Field(0.2, gt=0, description="kerb lines: the step filter's Gaussian across the "
                               "line (m)")
    line_along: float = Field(2.0, gt=0, description="kerb lines: its Gaussian along the line (m); shorter "
                              "steps read lower: at 1 m the 3 m sides of lowered crossings read as kerbs")
    height_noise: float | None = Field(None, gt=0, description="height noise (m); None: measured")
    colour_noise: float | None = Field(None, gt=0, description="colour noise of the median-filtered "
                                       "colours (8-bit units); None: measured")
    weights: dict = Field(default_factory=dict, description="road selection energies, see "
                          "roadx_ti.road_graph.Weights (documented defaults)")

    @field_validator("weights")
    @classmethod
    def _known_weights(cls, value: dict) -> dict:
        # checked with the config, before the input is read: a misspelt key or a word for a number
        # stopped the run at road_regions with a Python error
        known = {f.name: f for f in dataclasses.fields(Weights)}
        out = {}
        for key, number in value.items():
            if key not in known:
                raise ValueError(f"unknown weight {key!r} (known: {', '.join(sorted(known))})")
            if isinstance(number, bool) or not isinstance(number, (int, float)) or not math.isfinite(number):
                raise ValueError(f"weight {key!r} must be a finite number, not {number!r}")
            out[key] = float(number)
        return out

    @field_validator("colour_levels")
    @classmethod
    def _ascending_levels(cls, value: tuple) -> tuple:
        if not value or any(v <= 0 for v in value) or any(b <= a for a, b in zip(value, value[1:])):
            raise ValueError(f"colour_levels must be positive and ascending, not {list(value)}")
        return value

    @field_validator("ensemble")
    @classmethod
    def _positive_scales(cls, value: tuple) -> tuple:
        if any(v <= 0 for v in value):
            raise ValueError(f"ensemble scales must be positive, not {list(value)}")
        return value


def colour_channels(cloud: Cloud):
    """(source, float32 (n, 3) in 8-bit units). Colour of which one channel alone varies (a grey
    or single-band image written into red, the others zero) is that channel's grey in all three:
    as RGB every point read as saturated red and no region was road."""
    if cloud.has_color:
        rgb = cloud.rgb8()
        if rgb is not None and np.ptp(rgb) > 0:
            varying = np.flatnonzero(rgb.max(axis=0) != rgb.min(axis=0))
            if len(varying) == 1:
                band = int(varying[0])
                return f"{('red', 'green', 'blue')[band]} as grey", np.repeat(rgb[:, band:band + 1], 3, axis=1)
            return "rgb", rgb.astype(np.float32)
    if cloud.intensity is not None and cloud.intensity.any():
        value = cloud.intensity.astype(np.float32)
        scale = 255.0 / max(float(np.percentile(value, 99)), 1.0)
        return "intensity", np.repeat((value * np.float32(scale))[:, None], 3, axis=1)
    return "geometry", np.zeros((cloud.n, 3), np.float32)


def kerb_evidence(steps, sigma, kerb_min, kerb_max, prior):
    """Per edge: posterior probabilities that it steps up from a to b, or from b to a, by a
    kerb (height uniform in [kerb_min, kerb_max]) rather than lying on one surface (Gaussian of
    the measured spread, with a wider tail for outliers). Elementwise, in chunks (roadx_ti.chunks)."""
    from scipy.special import ndtr     # here: a run that stops at its config check does not import scipy

    r = np.asarray(steps, np.float64)
    sigma = np.maximum(np.asarray(sigma, np.float64), 1e-4)      # one value, or one per edge
    span = kerb_max - kerb_min
    up, down = np.empty(len(r)), np.empty(len(r))

    def part(start, stop):
        s = sigma if sigma.ndim == 0 else sigma[start:stop]
        lo, hi = kerb_min / s, kerb_max / s
        z = r[start:stop] / s
        # Gaussian densities and cdfs as plain ufuncs (scipy.special: no distribution overhead)
        flat = (0.9 * np.exp(-0.5 * z * z) + 0.1 / 3.0 * np.exp(-0.5 * z * z / 9.0)) / (s * np.sqrt(2.0 * np.pi))
        a = (1.0 - prior) * flat
        b = 0.5 * prior * ((ndtr(z - lo) - ndtr(z - hi)) / span)
        c = 0.5 * prior * ((ndtr(-z - lo) - ndtr(-z - hi)) / span)
        total = a + b + c + 1e-300
        up[start:stop] = b / total
        down[start:stop] = c / total
    over_chunks(part, len(r))
    return up, down


# a block needs this many graph edges for a noise of its own; fewer take the run's value
MIN_BLOCK_EDGES = 2000


def block_spread(values, block, overall: float, scale: float) -> np.ndarray:
    """float64 per item: ``scale`` x the median |value| of the items of its block (int64 keys),
    ``overall`` where a block has fewer than MIN_BLOCK_EDGES items."""
    keys, inverse, counts = np.unique(block, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    order = np.lexsort((np.abs(values), inverse))
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    ranked = np.abs(np.asarray(values, np.float64))[order]
    lo = ranked[starts + (counts - 1) // 2]
    hi = ranked[starts + counts // 2]
    spread = np.where(counts >= MIN_BLOCK_EDGES, scale * 0.5 * (lo + hi), overall)
    return spread[inverse]


def above_road_surface(xyz, gradient, is_road, k: int, tolerance: float):
    """(road, count): ``is_road`` without the road points that stand more than ``tolerance`` above
    the road's local surface, the median slope-corrected height of themselves and their ``k``
    nearest road points in plan, those within three times the median distance to the k-th
    (kernels regions.mode_heights with no mode steps). Cars stand on
    the road and their lowest parts, within the cloth's class threshold of it, joined its regions;
    a median over a plan neighbourhood wider than a car's skirt is the road's own height."""
    from roadx_ti.kernels import regions
    from roadx_ti.kernels.neighbors import knn

    road = np.flatnonzero(is_road)
    k = min(k, len(road) - 1)
    if k < 3:
        return is_road, 0
    part = np.ascontiguousarray(xyz[road])
    flat = plan_points(part)
    neighbours, distance = knn(flat, k)
    # no neighbours from far off (a small road piece, or another level of a bridge): at most
    # three times the typical reach of the k nearest
    neighbours = np.where(distance <= 3.0 * np.median(distance[:, -1]), neighbours, -1).astype(np.int32)
    local = regions.mode_heights(part, neighbours, np.ascontiguousarray(gradient[road]), 0.0, steps=0)
    above = part[:, 2] - np.asarray(local) > np.float32(tolerance)
    out = is_road.copy()
    out[road[above]] = False
    return out, int(above.sum())


@dataclasses.dataclass
class KerbLines:
    field: "kerb_lines.StepField"
    edge_steps: np.ndarray      # float64 per graph edge: the step up from a to b of a line it crosses
    paved: np.ndarray           # bool per point: neither chromatic nor green
    edges_per_metre: float      # graph edges that cross a metre of line (2 / pi x edge length per m2,
                                # for edges of any direction)


def _kerb_lines(xyz, colour_f, ea, eb, spacing: float, density: float, o: RoadRegionsOptions, weights: Weights,
                ctx):
    """KerbLines of the stage's points on a raster of half the point spacing (None where that raster
    would not fit: the filtered heights' kerbs alone then). Lines are looked for between paved
    points (neither chromatic nor green, road_graph's rules): grass and foliage have relief of
    their own, and colour already parts them from the road."""
    from roadx_ti import kerb_lines
    from roadx_ti.memory import dense_limit
    from roadx_ti.road_graph import plain_ground

    cell = 0.5 * spacing
    if kerb_lines.raster_cells(xyz[:, :2], cell, o.line_along) > dense_limit(len(xyz), kerb_lines.FIELD_BYTES_PER_CELL):
        ctx.log.warning("road_regions: the kerb-line raster would not fit in memory; kerbs from the filtered "
                        "heights only")
        return None
    paved = plain_ground(colour_f, weights)
    field = kerb_lines.step_field(xyz[:, :2], xyz[:, 2], cell, o.line_across, o.line_along, LINE_COARSE,
                                  measure=paved)
    # steps of half a kerb's smallest height make no kerb evidence (kerb_evidence about 0 there)
    steps = kerb_lines.edge_line_steps(xyz, ea, eb, field, floor=0.5 * o.kerb_min)
    edge_length = float(np.linalg.norm(xyz[eb, :2] - xyz[ea, :2], axis=1).sum())
    per_metre = 2.0 / np.pi * edge_length * max(density, 1e-9) / max(len(xyz), 1)
    return KerbLines(field, np.where(paved[ea] & paved[eb], steps, 0.0), paved, per_metre)


def _add_line_pairs(graph, lines: KerbLines, xyz, spacing: float, weight: float, o: RoadRegionsOptions) -> None:
    """Append to ``graph`` the region pairs across kerb lines (kerb_lines.line_pairs, sampled
    line_across plus half a spacing from each line) as kerbs in full: their length times the
    graph edges that cross a metre of line, times ``weight``."""
    from roadx_ti import kerb_lines

    def probability(steps, spread):
        return kerb_evidence(steps, spread, o.kerb_min, o.kerb_max, o.kerb_prior)[0]
    lower, upper, length = kerb_lines.line_pairs(lines.field, xyz, graph.label, o.line_across + 0.5 * spacing,
                                                 probability, min_probability=LINE_PAIR_MIN_PROBABILITY,
                                                 eligible=lines.paved)
    if not len(lower):
        return
    strength = weight * length * lines.edges_per_metre
    # pairs a < b; up: steps up from a to b
    flip = lower > upper
    graph.pa = np.concatenate([graph.pa, np.where(flip, upper, lower).astype(graph.pa.dtype)])
    graph.pb = np.concatenate([graph.pb, np.where(flip, lower, upper).astype(graph.pb.dtype)])
    graph.edges = np.concatenate([graph.edges, strength.astype(graph.edges.dtype)])
    graph.up = np.concatenate([graph.up, np.where(flip, 0.0, strength).astype(graph.up.dtype)])
    graph.down = np.concatenate([graph.down, np.where(flip, strength, 0.0).astype(graph.down.dtype)])


def plan_density(xy: np.ndarray, cell: float = 0.5) -> float:
    """Points per m2 of occupied plan area (cells of ``cell`` metres)."""
    if len(xy) == 0:
        return 0.0
    key = np.floor(xy / cell).astype(np.int64)
    key -= key.min(axis=0)
    occupied = len(np.unique(key[:, 0] * (int(key[:, 1].max()) + 1) + key[:, 1]))
    return len(xy) / (occupied * cell * cell)


class RoadRegions(Stage):
    name = "road_regions"
    labels = CLASS_ROAD
    Options = RoadRegionsOptions

    @classmethod
    def reach(cls, options, estimates=None) -> float:
        # MIN_BUFFER, as before stages declared their reach (it had no entry in the tiling's table).
        # Not its true reach: the road selection is a minimum cut over the whole region graph, so no
        # finite buffer makes tiled labels equal the whole run's; kept so that tile plans do not change.
        return MIN_BUFFER

    @staticmethod
    def _choose(graph, xyz, origin, density, spacing, weights):
        """(bool per region: road, facts) of one segmentation."""
        centroid = None
        if weights.colour_block > 0:
            # in world coordinates: the blocks are the same whatever local origin a delivery or a
            # tile's read took
            count = np.maximum(graph.count, 1.0)
            centroid = np.column_stack([np.bincount(graph.label, weights=xyz[:, c], minlength=graph.n_regions)
                                        / count + float(origin[c]) for c in (0, 1)])
        road_region, facts = label_road(graph, density, weights, centroid=centroid)
        if not road_region.any() or facts["road_kerb_share"] < weights.kerbless_below:
            # no kerb to stand on: a street without kerbs, taken by its shape in plan (where the cut
            # kept some road that no kerb bounds, only when the shape finds one)
            ribbon = kerbless_road(graph, xyz[:, :2], spacing, weights)
            if ribbon.any() or not road_region.any():
                road_region = ribbon
                facts["kerbless_road_points"] = int(graph.count[road_region].sum())
        return road_region, facts

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:
        from roadx_ti.kernels import regions
        from roadx_ti.kernels.neighbors import knn

        o = self.options
        n = cloud.n
        k = min(o.k, n - 1)
        if k < 3:
            return StageResult(labels=np.full(n, CLASS_OTHER, np.uint8), info={"skipped": "too few points"})
        xyz = cloud.xyz
        source, colour = colour_channels(cloud)
        # colour fields holding one value for every point (a writer's placeholder) are no colour
        # (all-zero LAS colour is read as none)
        one_colour = cloud.rgb is not None and len(cloud.rgb) > 0 and not cloud.has_color
        if source == "geometry":
            ctx.log.warning("road_regions: the points carry %s and no intensity: the road is chosen by "
                            "kerbs and shape alone, which finds much less of it",
                            "one colour for every point" if one_colour else "no colour")
        elif one_colour:
            ctx.log.warning("road_regions: the points carry one colour for every point: the road is chosen by "
                            "their intensity instead")
        elif source.endswith(" as grey"):
            ctx.log.warning("road_regions: only the %s channel of the colour varies; it is read as grey",
                            source.split()[0])
        indices, distances = knn(xyz, k)
        spacing = float(np.median(distances[:, -1]))
        gk = min(o.graph_k or k, k)
        ea, eb = regions.graph_edges(np.ascontiguousarray(indices[:, :gk]), np.ascontiguousarray(distances[:, :gk]),
                                     o.edge_factor * spacing)

        def rows(indices, distances):
            """The filters' neighbour rows: the k nearest within the graph's longest edge."""
            return np.where(distances <= o.edge_factor * spacing, indices, -1).astype(np.int32)
        neighbours = rows(indices, distances)
        del indices, distances          # the rows live on in `neighbours`, the pairs in ea / eb
        gradient = regions.coarse_gradient(xyz, o.slope_cell)
        raw = regions.edge_steps(xyz, xyz[:, 2].copy(), gradient, ea, eb)
        height_noise = o.height_noise or MAD_TO_SIGMA * float(np.median(np.abs(raw))) / np.sqrt(2.0)
        width = o.filter_width * height_noise
        edge_block = None
        if o.noise_block and o.height_noise is None:
            cell = np.floor((xyz[:, :2].astype(np.float64) + cloud.origin[:2]) / o.noise_block).astype(np.int64)
            point_block = cell[:, 0] * (1 << 32) + (cell[:, 1] & 0xFFFFFFFF)
            edge_block = point_block[ea]
            edge_noise = block_spread(raw, edge_block, height_noise, MAD_TO_SIGMA / np.sqrt(2.0))
            point_noise = np.full(n, height_noise, np.float64)
            point_noise[eb] = edge_noise        # a point takes its block's value (edges from its block)
            point_noise[ea] = edge_noise
            width = (o.filter_width * point_noise).astype(np.float32)
            del point_block, edge_noise, point_noise
        del raw
        filtered = regions.mode_heights(xyz, neighbours, gradient, width)
        steps = regions.edge_steps(xyz, filtered, gradient, ea, eb)
        del filtered, width
        step_sigma = MAD_TO_SIGMA * float(np.median(np.abs(steps)))
        edge_sigma = step_sigma if edge_block is None else \
            block_spread(steps, edge_block, step_sigma, MAD_TO_SIGMA).astype(np.float32)
        del edge_block
        colour_f = regions.neighbourhood_median(colour, neighbours)
        del colour
        weights = Weights(**o.weights)
        density = plan_density(xyz[:, :2])
        # kerbs along lines where the filter blurs them (ACCURACY.md's notes: unseen scenes with
        # kerbs under 2.5 noise sigmas lost streets or took sidewalks)
        line_weight = float(np.clip((o.filter_width * height_noise / TYPICAL_KERB - 0.9) / 0.2, 0.0, 1.0)) \
            if o.kerb_lines else 0.0
        lines = _kerb_lines(xyz, colour_f, ea, eb, spacing, density, o, weights, ctx) if line_weight > 0 else None
        line_spread = lines.field.spread if lines is not None else 0.0
        line_weight = line_weight if lines is not None else 0.0

        # the kerb probabilities per edge, evaluated where the merge needs them (elementwise, so
        # the same values): two full float64 arrays held through its rounds were 400 MB at 16 M
        def evidence(index):
            sigma = edge_sigma if np.ndim(edge_sigma) == 0 else edge_sigma[index]
            up, down = kerb_evidence(steps[index], sigma, o.kerb_min, o.kerb_max, o.kerb_prior)
            if lines is not None:
                line_steps = lines.edge_steps[index]
                on = np.flatnonzero(line_steps)         # the edges that cross a line
                if len(on):
                    line_up, line_down = kerb_evidence(line_steps[on], lines.field.spread, o.kerb_min, o.kerb_max,
                                                       o.kerb_prior)
                    up[on] = np.maximum(up[on], line_weight * line_up)
                    down[on] = np.maximum(down[on], line_weight * line_down)
            return up, down
        if n > REQUERY_ROWS_ABOVE:
            # the rows go before the merge and are queried again after it (the same rows: the
            # query is exact and deterministic): held through its rounds they were 184 MB of the
            # 16 M-point road run's peak; the second query costs about 2 s there
            neighbours = None
        grey = colour_f.mean(axis=1)
        colour_noise = o.colour_noise or max(MAD_TO_SIGMA * float(np.median(np.abs(grey[eb] - grey[ea]))) / np.sqrt(2.0), 0.5)
        del grey        # what the merge does not read goes before it (its rounds are the stage's peak)

        # one segmentation per scale of the later colour levels (the first level, most of the
        # merge's work, is shared): a point is road when most of their road choices say so
        levels = [colour_noise * f for f in o.colour_levels]
        scales = sorted(o.ensemble)
        graphs = regions.merge_regions_by_colour(n, ea, eb, evidence, None, colour_f, levels[:1], o.max_chroma_step,
                                                 o.step_veto, o.min_region_points, settle=o.settle,
                                                 branches=[[v * scale for v in levels[1:]] for scale in scales])
        if len(scales) == 1:
            graphs = [next(graphs)]
            del evidence, steps        # what the cut does not read goes before it
        votes = np.zeros(n, np.int32)
        middle = len(scales) // 2
        for number, graph in enumerate(graphs):
            if lines is not None:
                _add_line_pairs(graph, lines, xyz, spacing, line_weight, o)
            road_region, facts_here = self._choose(graph, xyz, cloud.origin, density, spacing, weights)
            votes += road_region[graph.label]
            if number == middle:
                segment_label, facts = graph.label, facts_here
        del graphs, graph
        evidence = steps = lines = None        # (the branches held them)
        is_road = 2 * votes > len(scales)
        if len(scales) > 1:
            facts["ensemble_split_points"] = int(((votes > 0) & (votes < len(scales))).sum())
        if o.boundary_passes and neighbours is None:
            neighbours = rows(*knn(xyz, k))
        for _ in range(o.boundary_passes):
            # the road's edge on the kerb itself: boundary points go to the side of their height
            is_road = regions.boundary_vote(xyz, neighbours, gradient, is_road.astype(np.uint8),
                                            max(0.5 * o.kerb_min, 2.0 * step_sigma)).astype(bool)
        off_surface = 0
        if o.surface_tol > 0:
            is_road, off_surface = above_road_surface(xyz, gradient, is_road, o.surface_k,
                                                      max(o.kerb_min, o.surface_tol * height_noise))
        labels = np.where(is_road, CLASS_ROAD, CLASS_OTHER).astype(np.uint8)
        # plain floats: the log line and the summary JSON show numbers, not numpy reprs
        estimates = {"point_spacing_m": round(float(spacing), 4), "density_per_m2": round(float(density), 2),
                     "height_noise_m": round(float(height_noise), 4), "filtered_step_sigma_m": round(float(step_sigma), 4),
                     "colour_noise": round(float(colour_noise), 3), "colour_levels": [round(float(v), 3) for v in levels]}
        ctx.log.info("road_regions: %s colour, estimates %s", source, estimates)
        # the edge-preserving filter keeps a step apart only when it exceeds the filter's window:
        # lower kerbs blur over the neighbourhood (ACCURACY.md's notes: unseen scenes with kerbs
        # under 2.5 noise sigmas lost streets or took sidewalks)
        resolved = o.filter_width * height_noise
        estimates["kerbs_resolved_above_m"] = round(float(resolved), 4)
        estimates["kerb_lines_weight"] = round(line_weight, 3)
        if line_weight > 0:
            estimates["kerb_line_spread_m"] = round(line_spread, 4)
        if resolved > TYPICAL_KERB:
            ctx.log.warning("road_regions: height noise %.1f cm: kerbs lower than %.0f cm blur in the filtered "
                            "heights, so sidewalks may join the road or streets be missed (kerbs are commonly "
                            "8-16 cm)", 100 * height_noise, 100 * resolved)
        return StageResult(labels=labels, segment_id=segment_label.astype(np.int32),
                           info={"color_source": source, "estimates": estimates, **facts,
                                 "off_surface_points": int(off_surface), "target_points": int(is_road.sum())})
