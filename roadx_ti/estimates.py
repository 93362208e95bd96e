"""Survey-wide estimates that ``auto`` stage parameters are derived from (METHODS.md, Adaptivity).

Measured once on the whole input (a tiled run streams the whole catalog once: the occupied area of
all its points and a spatially uniform sample for the rest, and hands the same values to every
tile), logged, and written to the summary JSON:

- ``plan_area_m2`` / ``density_per_m2``: occupied plan area (cells of ``AREA_CELL`` m holding a
  point) and points per m2 of it, never the bounding box (stray points far away do not count);
- ``point_spacing_m``: median distance to the nearest neighbour in plan, on a sample;
- ``pulse_spacing_m`` (where the input has return numbers): the same over first returns only, the
  spacing at which a surface seen from above (a roof) is sampled: vegetation's later returns make
  ``point_spacing_m`` smaller than a roof's spacing on wooded ALS tiles;
- ``height_noise_m``: robust spread of slope-corrected height differences between neighbours
  whose neighbourhoods are among the flatter half (1.4826 x median absolute difference /
  sqrt 2): the noise of one point on a smooth surface;
- ``colour_noise``: the same for grey levels (8-bit units) where the input has colour;
- ``distinct_points`` / ``distinct_density_per_m2`` (only where records repeat another's x, y
  and z: merged deliveries, a file written twice into one): the points at distinct positions; the
  neighbour statistics above are measured over those (a duplicate's nearest neighbour is its twin
  at 0 m, which made spacing, noise and colour noise 0); from a sample, the copies per position
  are estimated from the twins drawn together (``copies_per_position``);
- near copies (a delivery holding an overlap twice, 1 cm or 1 mm apart: each point's nearest
  neighbour its own copy): where more than NEAR_COPY_SHARE of the sample's points have neighbours
  closer than NEAR_COPY_RATIO times the next one (about 4 % of points scattered at random do), the
  spacings are measured to the nearest neighbour past those copies (the copies' 1 cm spacing made
  every radius and cell derived from it 1 cm, and the roof pipeline found no roof). A sample of a
  larger cloud rarely draws a copy with its twin: there the copies are counted among every point
  of a few windows of the cloud (copies_in_windows), and the sample's spacing past copies is
  scaled by the share of positions it holds;
- ``returns`` (where the input records return numbers): ``usable``, or why they cannot tell pulses
  apart (Cloud.returns_problem), judged once for the survey and used by every subset and tile;
- ``terrain_grade``: median grade of the terrain (rise over run), from the lowest sample point of
  each TERRAIN_CELL plan cell (bar the lowest 1 %: low noise) lowered to its 5 x 5 cells' lowest
  (buildings and crowns that fill cells do not raise it): the plan gradient between cells and
  their east and north neighbours.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from roadx_ti.cloud import RETURNS_USABLE, Cloud
from roadx_ti.sorted_keys import find

log = logging.getLogger("roadx_ti")

RETURNS_VERDICT = "returns"   # estimates key: Cloud.returns_verdict of the survey, where it has returns
AREA_CELL = 1.0          # m: plan cells counted as occupied area
TERRAIN_CELL = 10.0      # m: plan cells whose lowest points stand for the terrain (terrain_grade)
SAMPLE_POINTS = 200_000  # points the neighbour statistics are measured on
MAD_TO_SIGMA = 1.4826
NEAR_COPY_RATIO = 0.2    # a neighbour this much closer than the next is a copy of the point
NEAR_COPY_SHARE = 0.25   # share of points with such copies beyond which a survey is said to hold copies
NEAR_COPY_NEIGHBOURS = 4 # plan neighbours looked at: up to 3 copies of a position are seen past
NEAR_COPY_WINDOWS = 4    # windows of a large cloud whose every point near copies are looked for among
NEAR_COPY_WINDOW_POINTS = 5_000   # points of one such window, on average


def occupied_area(xy: np.ndarray, cell: float = AREA_CELL) -> float:
    """m2 of the plan cells of edge ``cell`` that hold at least one point."""
    if len(xy) == 0:
        return 0.0
    return float(len(np.unique(_cell_keys(xy, cell)))) * cell * cell


def uniform_sample(n: int, size: int, seed: int = 0) -> np.ndarray:
    """Sorted indices of ``size`` of ``n`` points drawn without replacement (all when n <= size)."""
    if n <= size:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, size, replace=False))


def measure(cloud: Cloud, sample_points: int = SAMPLE_POINTS, seed: int = 0, *, survey_points: int | None = None,
            area: float | None = None, drawn_by_position: bool = False, distinct: bool = False) -> dict:
    """The estimates of the module docstring for ``cloud``: a whole survey, or (with
    ``survey_points`` and ``area``) a uniform sample of one of that many points over that area:
    of its records each drawn alone, or with ``drawn_by_position`` of its positions (measure_catalog
    draws by a hash of the coordinates: a position comes with all of its copies). ``distinct``: the
    caller left repeated positions out already (the pipeline), so they are not looked for."""
    from roadx_ti.kernels.neighbors import knn

    if survey_points is None and cloud.n:
        # a whole cloud: its isolated points (strays far off, roadx_ti.isolation) left out, whose
        # occupied cells lowered the density and whose draws moved every estimate
        from roadx_ti.isolation import SMALL_PART, isolated

        far = isolated(cloud.xyz, SMALL_PART)
        if far is not None:
            cloud = cloud.subset(np.flatnonzero(~far))
    n = cloud.n
    total = n if survey_points is None else int(survey_points)
    area = occupied_area(cloud.xyz[:, :2]) if area is None else float(area)
    out = {"points": total, "plan_area_m2": round(area, 1),
           "density_per_m2": round(total / area, 3) if area else 0.0}
    if cloud.returns is not None and n and cloud.returns[:, 1].any():
        # once for the survey (a tile or a stage's points judged alone could cross the line); none
        # recorded (all 0): no verdict, nothing to read in any subset either
        out[RETURNS_VERDICT] = cloud.returns_problem() or RETURNS_USABLE
    if n < 8:
        return out
    if drawn_by_position:
        # every copy of a drawn position is in the sample: the copies per position are counted
        first = distinct_rows(cloud.xyz)
        if len(first) < n:
            total = _without_copies(out, total, n / len(first), len(first), area)
            cloud, n = cloud.subset(first), len(first)
            if n < 8:
                return out
    pick = uniform_sample(n, sample_points, seed)
    xyz = np.ascontiguousarray(cloud.xyz[pick])
    first = np.arange(len(xyz)) if distinct else distinct_rows(xyz)
    if len(first) < len(xyz):
        # records drawn alone: the copies per position from the twins drawn together
        copies = copies_per_position(len(xyz), len(first), len(xyz) / total)
        total = _without_copies(out, total, copies, len(first), area)
        pick, xyz = pick[first], np.ascontiguousarray(xyz[first])
        if len(xyz) < 8:
            return out
    k = min(8, len(xyz) - 1)
    idx, dist = knn(xyz, k)
    # plan spacing of the full cloud: a sample of fraction f is 1/sqrt(f) sparser
    flat = plan_points(xyz)
    # plan spacing of the full cloud: a sample of fraction f is 1/sqrt(f) sparser; where the cloud
    # holds m near copies per position, its positions past copies are 1 / sqrt(1 - (1 - f)^m)
    # sparser (a position is in the sample with any of its copies)
    copies = copies_in_windows(cloud, total / area if area else 0.0, seed) \
        if survey_points is None and len(xyz) < n else 1.0
    f = len(xyz) / total
    scale = np.sqrt(f) if copies <= 1.0 else np.sqrt(1.0 - (1.0 - f) ** copies)
    nn_plan = nearest_past_copies(knn(flat, NEAR_COPY_NEIGHBOURS)[1], always=copies > 1.0)
    out["point_spacing_m"] = round(float(np.median(nn_plan) * scale), 4)
    if cloud.returns is not None and (cloud.returns[pick, 1] > 1).any() and cloud.returns_problem() is None:
        first = np.flatnonzero(cloud.returns[pick, 0] <= 1)
        if len(first) >= 8:
            nn_first = nearest_past_copies(knn(np.ascontiguousarray(flat[first]), NEAR_COPY_NEIGHBOURS)[1],
                                           always=copies > 1.0)
            out["pulse_spacing_m"] = round(float(np.median(nn_first) * scale), 4)
    dz = _neighbour_steps(xyz, idx)
    out["height_noise_m"] = round(float(MAD_TO_SIGMA * np.median(np.abs(dz)) / np.sqrt(2.0)), 4)
    grade = terrain_grade(xyz)
    if grade is not None:
        out["terrain_grade"] = round(grade, 4)
    a = np.repeat(np.arange(len(xyz)), k)[idx.reshape(-1) >= 0]
    b = idx.reshape(-1)[idx.reshape(-1) >= 0]
    rgb = cloud.rgb8()
    if rgb is not None and np.ptp(rgb) > 0:
        varying = np.flatnonzero(rgb.max(axis=0) != rgb.min(axis=0))
        # one channel alone varying is a grey written into it (road_regions reads it so)
        grey = rgb[pick, varying[0]] if len(varying) == 1 else rgb[pick].mean(axis=1)
        out["colour_noise"] = round(float(MAD_TO_SIGMA * np.median(np.abs(grey[b] - grey[a])) / np.sqrt(2.0)), 3)
    log.info("survey estimates: %s", out)
    return out


def plan_points(xyz: np.ndarray) -> np.ndarray:
    """The points' x, y with z = 0 (float32 (n, 3), contiguous): kNN in plan."""
    xyz = np.asarray(xyz)
    return np.ascontiguousarray(np.column_stack([xyz[:, :2], np.zeros(len(xyz), np.float32)]), np.float32)


def copies_in_windows(cloud: Cloud, density: float, seed: int) -> float:
    """Records per position where the cloud holds near copies (module docstring), counted among
    every point of NEAR_COPY_WINDOWS square plan windows (about NEAR_COPY_WINDOW_POINTS points
    each, centred on points drawn at random): a uniform sample of a larger cloud holds a copy with
    its twin rarely. 1.0 where the windows hold none."""
    from roadx_ti.kernels.neighbors import knn

    if density <= 0:
        return 1.0
    half = 0.5 * np.sqrt(NEAR_COPY_WINDOW_POINTS / density)
    centres = cloud.xyz[np.random.default_rng(seed + 1).choice(cloud.n, NEAR_COPY_WINDOWS, replace=False)]
    inside = np.zeros(cloud.n, bool)
    for cx, cy, _ in centres:
        inside |= (np.abs(cloud.xyz[:, 0] - cx) <= half) & (np.abs(cloud.xyz[:, 1] - cy) <= half)
    index = np.flatnonzero(inside)
    if len(index) <= 2 * NEAR_COPY_NEIGHBOURS:
        return 1.0
    flat = plan_points(cloud.xyz[index])
    copies = _copies_per_point(np.asarray(knn(flat, NEAR_COPY_NEIGHBOURS)[1]))
    return float(np.mean(1 + copies)) if np.mean(copies > 0) > NEAR_COPY_SHARE else 1.0


def nearest_past_copies(distances: np.ndarray, always: bool = False) -> np.ndarray:
    """Per point, the distance to its nearest neighbour, from its kNN distances (n, k) sorted
    ascending; where the survey holds near copies (module docstring; ``always``: known to), to its
    nearest neighbour that is not one: past the last neighbour closer than NEAR_COPY_RATIO times
    the next."""
    d = np.asarray(distances)
    copies = _copies_per_point(d)
    if len(d) == 0 or (not always and np.mean(copies > 0) <= NEAR_COPY_SHARE):
        return d[:, 0]
    return d[np.arange(len(d)), copies]


def _copies_per_point(d: np.ndarray) -> np.ndarray:
    """Per row of sorted kNN distances, how many neighbours come before its last gap of more
    than 1 / NEAR_COPY_RATIO (0: none)."""
    copies = np.zeros(len(d), np.int64)
    for c in range(d.shape[1] - 1):
        copies[d[:, c] < NEAR_COPY_RATIO * d[:, c + 1]] = c + 1
    return copies


def _without_copies(out: dict, total: int, copies: float, seen: int, area: float) -> int:
    """The survey's distinct points (at least the ``seen`` ones) at ``copies`` records per
    position, written into the estimates ``out`` with their density; returned."""
    total = max(int(round(total / copies)), seen)
    out.update({"distinct_points": total, "copies_per_position": round(copies, 3),
                "distinct_density_per_m2": round(total / area, 3) if area else 0.0})
    return total


def distinct_rows(xyz: np.ndarray) -> np.ndarray:
    """Ascending indices of the first of the rows of ``xyz`` with each (x, y, z)."""
    rows = np.ascontiguousarray(xyz)
    keys = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    return np.sort(np.unique(keys, return_index=True)[1])


def copies_per_position(drawn: int, distinct: int, fraction: float) -> float:
    """Records per distinct position m of a cloud from a uniform draw of ``fraction`` of its records
    (each kept with that probability) holding ``drawn`` records at ``distinct`` positions: a position
    with m copies is drawn at least once with probability 1 - (1 - f)^m, so distinct / drawn =
    (1 - (1 - f)^m) / (m f), solved for m (m = drawn / distinct when the draw is the whole cloud)."""
    if distinct >= drawn or drawn == 0:
        return 1.0
    f = min(max(fraction, 1e-12), 1.0)
    if f >= 1.0:
        return drawn / distinct
    ratio = distinct / drawn

    def seen(m):
        return (1.0 - (1.0 - f) ** m) / (m * f)
    lo, hi = 1.0, 2.0
    while seen(hi) > ratio and hi < 1e6:
        hi *= 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if seen(mid) > ratio else (lo, mid)
    return 0.5 * (lo + hi)


def _neighbour_steps(xyz: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Slope-corrected height differences of the pairs of the kNN rows ``idx`` of ``xyz`` whose
    both ends are among the flatter half of the points (crowns, walls and edges have the curved
    neighbourhoods; all pairs when fewer than 100 are)."""
    from roadx_ti.kernels.features import curvature as neighbourhood_curvature
    from roadx_ti.kernels.regions import coarse_gradient

    k = idx.shape[1]
    gradient = coarse_gradient(xyz, 2.5)
    a = np.repeat(np.arange(len(xyz)), k)
    b = idx.reshape(-1)
    ok = b >= 0
    a, b = a[ok], b[ok]
    g = 0.5 * (gradient[a] + gradient[b])
    dz = (xyz[b, 2] - xyz[a, 2]) - (g * (xyz[b, :2] - xyz[a, :2])).sum(axis=1)
    curvature = np.asarray(neighbourhood_curvature(xyz, idx))
    flat = curvature <= np.median(curvature)
    smooth = flat[a] & flat[b]
    return dz[smooth] if smooth.sum() >= 100 else dz


def height_noise(xyz: np.ndarray, sample_points: int = SAMPLE_POINTS, seed: int = 0) -> float | None:
    """The height noise of ``xyz`` (m) as ``measure`` takes it (height_noise_m), on a uniform
    sample; None for fewer than 9 points. On a ground stage's ground points it is the sensor's
    noise on hard surfaces (IGN and AHN3 files 0.7-1.9 cm), which foliage does not inflate (the
    whole survey reads 4-8 cm on wooded IGN tiles)."""
    from roadx_ti.kernels.neighbors import knn

    if len(xyz) < 9:
        return None
    pick = uniform_sample(len(xyz), sample_points, seed)
    sample = np.ascontiguousarray(np.asarray(xyz)[pick], np.float32)
    idx, _ = knn(sample, 8)
    dz = _neighbour_steps(sample, np.asarray(idx))
    return float(MAD_TO_SIGMA * np.median(np.abs(dz)) / np.sqrt(2.0))


MIN_TERRAIN_PAIRS = 8     # cells with both neighbours occupied that a terrain grade needs
TERRAIN_REACH = 2         # cells: a cell's terrain is the lowest of the (2 r + 1)^2 cells around it


def terrain_grade(xyz: np.ndarray, cell: float = TERRAIN_CELL) -> float | None:
    """Median plan grade (rise over run) of the terrain: the lowest point of each ``cell`` m plan
    cell (bar its lowest LOW_OUTLIER_SHARE: low noise spread over 5 x 5 cells flattened a 40 %
    ridge to 0.11), lowered to the lowest of the 5 x 5 cells around it (TERRAIN_REACH: a building
    or a crown up to four cells across fills cells and raises their minima, not their
    neighbourhood's), and the grade between a cell and the cells east and north of it where both
    are occupied; None when fewer than MIN_TERRAIN_PAIRS cells have both. Occupied cells only,
    found by their sorted keys (no grid over the bounding box)."""
    from roadx_ti.terrain_trend import cell_lows

    if len(xyz) == 0:
        return None
    ix, iy, low = cell_lows(xyz, cell)
    ix, iy = ix - ix.min() + 1, iy - iy.min() + 1
    width = int(iy.max()) + 2
    cells = ix * width + iy          # ascending: cell_lows' cells are sorted by (ix, iy)

    ground = low.copy()
    for dx in range(-TERRAIN_REACH, TERRAIN_REACH + 1):
        for dy in range(-TERRAIN_REACH, TERRAIN_REACH + 1):
            index, present = find(cells, cells + dx * width + dy)
            ground = np.where(present, np.minimum(ground, low[index]), ground)
    east, has_east = find(cells, cells + width)
    north, has_north = find(cells, cells + 1)
    both = has_east & has_north
    if both.sum() < MIN_TERRAIN_PAIRS:
        return None
    gx = (ground[east[both]] - ground[both]) / cell
    gy = (ground[north[both]] - ground[both]) / cell
    return float(np.median(np.hypot(gx, gy)))


@dataclass(frozen=True)
class CellCounts:
    """Points per occupied plan cell of ``cell`` m, in world coordinates: cell (ix[i], iy[i]) is
    [ix * cell, (ix + 1) * cell) x [iy * cell, (iy + 1) * cell) and holds counts[i] points (ascending
    keys, every cell once)."""
    cell: float
    ix: np.ndarray         # int64
    iy: np.ndarray         # int64
    counts: np.ndarray     # int64

    @classmethod
    def from_keys(cls, keys: np.ndarray, counts: np.ndarray, cell: float) -> "CellCounts":
        keys = np.asarray(keys, np.int64)
        iy = (keys & 0xFFFFFFFF).astype(np.uint32).view(np.int32).astype(np.int64)
        return cls(float(cell), keys >> 32, iy, np.asarray(counts, np.int64))

    def coarsened(self, factor: int) -> "CellCounts":
        """The same points counted on cells ``factor`` times larger (cells aligned to the world grid)."""
        if factor <= 1:
            return self
        ix, iy = self.ix // factor, self.iy // factor
        keys, inverse = np.unique(ix * (1 << 32) + (iy & 0xFFFFFFFF), return_inverse=True)
        counts = np.bincount(inverse.ravel(), weights=self.counts, minlength=len(keys)).astype(np.int64)
        return CellCounts.from_keys(keys, counts, self.cell * factor)


def _merge_counts(parts: list) -> tuple[np.ndarray, np.ndarray]:
    """(keys, counts) summed over (keys, counts) pieces, each key once, ascending (none: empty)."""
    if not parts:               # a catalog's first files hold no point
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    keys = np.concatenate([k for k, _ in parts])
    counts = np.concatenate([c for _, c in parts])
    unique, inverse = np.unique(keys, return_inverse=True)
    return unique, np.bincount(inverse.ravel(), weights=counts, minlength=len(unique)).astype(np.int64)


def measure_catalog(files, read_origin, sample_points: int = 2 * SAMPLE_POINTS, chunk_points: int = 1_000_000,
                    with_cells: bool = False):
    """Survey-wide estimates of a catalog of files (roadx_ti.tiling.catalog) before tiling, equal
    in kind to ``measure`` on the whole survey in memory: every file is streamed once in chunks;
    the plan area is the occupied AREA_CELL cells of all its points, and the other estimates come
    from a spatially uniform sample of about ``sample_points`` points (a point is drawn by a hash
    of its coordinates: the same sample whatever the files' point order or chunking; runs of
    consecutive points are no such sample: exports written object by object or line by line
    gave a third of the true area). ``with_cells``: return (estimates, CellCounts of AREA_CELL),
    the points per occupied cell, from the same pass (the tile planner places tiles by them)."""
    import laspy

    from roadx_ti import io
    from roadx_ti.io.las import las_errors
    from roadx_ti.kernels.downsample import hashed_sample
    from roadx_ti.ordering import canonical_order
    from roadx_ti.stages.downsample import coordinate_cells

    total = sum(f.count for f in files)
    if total == 0:
        empty = {"points": 0, "plan_area_m2": 0.0, "density_per_m2": 0.0}
        none = np.zeros(0, np.int64)
        return (empty, CellCounts(AREA_CELL, none, none, none)) if with_cells else empty
    read_origin = np.asarray(read_origin, np.float64)
    ratio = min(1.0, sample_points / total)
    cells, xyz_parts, rgb_parts, return_parts = [], [], [], []

    def take(world, rgb, returns):
        cells.append(np.unique(_cell_keys(world[:, :2], AREA_CELL), return_counts=True))
        # the hash of the exact world coordinates (not float32 local ones: exact at any distance)
        pick = hashed_sample(coordinate_cells(world, np.zeros(3), 0.01), ratio).astype(bool)
        xyz_parts.append((world[pick] - read_origin).astype(np.float32))   # local: only the sample
        rgb_parts.append(None if rgb is None else rgb[pick])
        return_parts.append(None if returns is None else returns[pick])
    for f in files:
        if f.path.lower().endswith((".las", ".laz")):     # COPC too: its chunks read in file order
            # only the layers read here are decompressed (point formats 6-10 store them apart:
            # 17 % less decoding on the uav-road survey); other formats decode whole
            wanted = laspy.DecompressionSelection.base() | laspy.DecompressionSelection.Z | laspy.DecompressionSelection.RGB
            with las_errors(f.path), laspy.open(f.path, decompression_selection=wanted) as reader:
                colour = "red" in reader.header.point_format.dimension_names
                for record in reader.chunk_iterator(chunk_points):
                    world = np.column_stack([np.asarray(record.x), np.asarray(record.y),
                                             np.asarray(record.z)]).astype(np.float64)
                    rgb = np.column_stack([np.asarray(record[c]) for c in ("red", "green", "blue")]).astype(
                        np.uint16) if colour else None
                    returns = np.column_stack([np.asarray(record.return_number),
                                               np.asarray(record.number_of_returns)]).astype(np.uint8)
                    take(world, rgb, returns)
            cells[:] = [_merge_counts(cells)]   # occupied cells so far, once each
        else:     # the other formats: read whole
            cloud = io.read(f.path, origin=read_origin)
            take(cloud.world_xyz(), cloud.rgb, cloud.returns)
    occupied, per_cell = _merge_counts(cells)
    area = float(len(occupied)) * AREA_CELL * AREA_CELL
    rgb = None
    if all(r is not None for r in rgb_parts):
        rgb = np.concatenate(rgb_parts)
        rgb = rgb if rgb.any() else None
    returns = np.concatenate(return_parts) if all(r is not None for r in return_parts) else None
    sample = Cloud(xyz=np.concatenate(xyz_parts), origin=read_origin, rgb=rgb, returns=returns)
    # in canonical order, so that measure's own subsample does not follow the files' point order
    order = canonical_order(sample)
    sample = sample if order is None else sample.subset(order)
    out = measure(sample, survey_points=total, area=area, drawn_by_position=True)
    out["sample_points"] = int(sample.n)
    out["area_cell_m"] = AREA_CELL
    return (out, CellCounts.from_keys(occupied, per_cell, AREA_CELL)) if with_cells else out


def _cell_keys(xy: np.ndarray, cell: float) -> np.ndarray:
    """int64 key of each point's plan cell in world coordinates (any two files agree)."""
    key = np.floor(np.asarray(xy, np.float64) / cell).astype(np.int64)
    return key[:, 0] * (1 << 32) + (key[:, 1] & 0xFFFFFFFF)
