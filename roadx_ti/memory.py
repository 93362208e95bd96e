"""Memory: what a run may use, what it will need, and how large a dense structure may be.

``run_budget``: bytes a run may use in total: ROADX_TI_MEMORY_LIMIT when set (``--memory-limit``,
``memory_limit`` in a config: the user's word, which also overrides what is detected), else what
this process holds plus the machine's available memory (psutil), lowered by a cgroup limit
(containers, batch schedulers) and an address-space rlimit (``ulimit -v``).

``estimate``: peak RSS of ``python -m roadx_ti run`` over n points: BASE_BYTES plus
BYTES_PER_POINT of the pipeline, measured on the CPU backend with /usr/bin/time on synthetic scenes
(uav-road with configs/road_uav.yaml, als-roof with roof_als.yaml and ground.yaml; LAZ in and out,
no PNG): the growth of the peak from 300 k to 1 M points per point (road 239, roof 226, ground 154
B/pt; at 16 M, benchmarks/RESULTS.md: road 4.06 GB, roof 3.31 GB, ground 1.74 GB, i.e. 240, 195,
98 B/pt above the base), rounded up; road re-measured 2026-12-02 (commit 0adc645, the region-level
road_regions): 4 M 1.48 GB, 16 M 5.02 GiB, 335 and 324 B/pt above the base; again 2026-12-05 (a
kernel's first call no longer keeps its arrays, the region merge re-keys through partition tables):
4 M 1.17 GB, 16 M 3.95 GiB, 246 and 240 B/pt above the base (and without the canonical copy of
the cloud through the stages: 4 M 1.08 GB, 16 M 3.53 GB, 224 and 213 B/pt; and with the input's LAS
records streamed again at the write instead of held, io.read keep_records: 4 M 0.95 GB, 16 M
3.09 GB, 184 and 180 B/pt); roof 16 M 3.29 GiB, 208 B/pt (4 M 0.96 -> 0.71 GB with the streamed
records); ``synth`` (a synthetic scene generated and written, 2026-12-05): 1 M to 4 M points
138 B/pt (uav-road) and 150 B/pt (als-roof). A run is refused (or tiled, with tiling.auto) when the
estimate times SAFETY exceeds the budget.

Road, 2026-12-05 (commit 7edbbe8): its peak follows the points R1 (uniform downsampling) keeps, not
the input's: uav-road 4 M seed 0 (194 points/m2, R1 keeps 31 % at its target of 60 /m2) 781 MB,
seed 6 (61 /m2, R1 keeps 99 %) 1,613 MB, i.e. about 50 B per input point plus 310 per kept point.
BYTES_PER_POINT road is the whole (every point kept, 360); KEPT_BYTES_PER_POINT the part that
shrinks with the share R1 keeps (``kept_share``, from the config and the density where known).

``dense_limit``: how many cells a dense grid or lattice may have: a multiple of the points it is
laid over (work and memory bounded by the points, not by their extent) and what fits in memory.
"""
from __future__ import annotations

import logging
import math
import os
import re

log = logging.getLogger("roadx_ti")

LIMIT_VARIABLE = "ROADX_TI_MEMORY_LIMIT"

BYTES_PER_POINT = {"road": 360, "roof": 230, "ground": 160, "synth": 160}
KEPT_BYTES_PER_POINT = {"road": 310}   # of BYTES_PER_POINT: bytes of a point only while R1 keeps it
# peak RSS of a run over a few points (Python, Taichi, numpy, laspy) on a cold offline cache: a
# first run compiles its kernels (10 k points, 2026-12-06: road / roof / ground 243 / 246 / 240 MB
# cold, 219 / 217 / 210 MB warm; at 200 MB the roof run over 100 k points peaked at 295 MB cold
# against an estimate of 291 MB with its margin)
BASE_BYTES = 250 * 2**20
# a tile of a tiled run peaks higher per point of its window than a whole-file run per point
# (the tile's records and world x/y, the labels of the tiles done so far); default tiles are sized
# with this factor. Measured: the 137 M-point road survey (benchmarks/paper_scale, 8 GB limit)
# peaked at 10.8 GB on windows of up to 20.2 M points at a42f852 (535 B/pt against 324 untiled);
# at 3ffd321, windows of at most 16 M points, 4.0 GB in process and 5.4 GB with --workers 2
TILE_OVERHEAD = 1.7
SAFETY = 1.25                     # the estimate is raised by this factor before it is compared

CELLS_PER_POINT = 64              # a dense structure may hold this many cells per point ...
MIN_DENSE_CELLS = 1 << 22         # ... and at least this many, whatever the points


def parse_size(text) -> int:
    """Bytes from '512M', '8G', '1.5T', '123456' (binary units: K = 1024)."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)i?b?\s*", str(text).lower())
    if not m:
        raise ValueError(f"not a memory size: {text!r} (use e.g. 512M, 8G)")
    scale = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}[m.group(2)]
    return int(float(m.group(1)) * scale)


def format_size(n: float) -> str:
    for unit, scale in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20), ("KB", 2**10)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}" if unit != "KB" else f"{n / scale:.0f} KB"
    return f"{n:.0f} bytes"     # --memory-limit 1 read '0 KB


def _read_int(path: str):
    try:
        text = open(path).read().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _cgroup_free():
    """Bytes left under this process's cgroup memory limit (v2, then v1), None without one."""
    for limit_path, usage_path in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        limit, usage = _read_int(limit_path), _read_int(usage_path)
        if limit is not None and usage is not None and limit < 2**60:
            return max(limit - usage, 0)
    return None


def _rlimit_free():
    try:
        import resource
        import psutil

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft == resource.RLIM_INFINITY:
            return None
        return max(soft - psutil.Process().memory_info().vms, 0)
    except (ImportError, OSError, ValueError):
        return None


def _held() -> int:
    import psutil

    return int(psutil.Process().memory_info().rss)


def run_budget() -> int:
    """Bytes this run may use in total (module docstring)."""
    import psutil

    limit = os.environ.get(LIMIT_VARIABLE)
    if limit:
        return parse_size(limit)
    headroom = [psutil.virtual_memory().available, _cgroup_free(), _rlimit_free()]
    return _held() + int(min(h for h in headroom if h is not None))


def available_bytes() -> int:
    """Bytes this process may still grow by: the run budget less what it holds."""
    return max(run_budget() - _held(), 0)


def _per_point(pipeline: str, kept_share: float) -> float:
    whole = BYTES_PER_POINT.get(pipeline, max(BYTES_PER_POINT.values()))
    share = min(max(float(kept_share), 0.0), 1.0)
    return whole - KEPT_BYTES_PER_POINT.get(pipeline, 0) * (1.0 - share)


def estimate(pipeline: str, points: int, kept_share: float = 1.0) -> int:
    """Expected peak memory (bytes) of a run of ``pipeline`` over ``points`` points, of which the
    pipeline's downsampling keeps ``kept_share`` (1: all, the upper bound)."""
    return int(BASE_BYTES + _per_point(pipeline, kept_share) * points)


def points_that_fit(pipeline: str, budget: int, kept_share: float = 1.0) -> int:
    """How many points a run of ``pipeline`` can take within ``budget`` bytes (with SAFETY)."""
    return max(int((budget / SAFETY - BASE_BYTES) / _per_point(pipeline, kept_share)), 0)


def kept_share(cfg, points: int, density: float | None) -> float:
    """Share of the points the config's first stage keeps when it declares one (the uniform
    downsampling's ``kept_share``: its ratio, target density or count against the data's); 1
    otherwise."""
    specs = cfg.pipeline_stages()
    share = getattr(specs[0][1], "kept_share", None) if specs else None
    return float(share(points, density)) if share else 1.0


def fits(pipeline: str, points: int, budget: int | None = None,
         kept_share: float = 1.0) -> tuple[bool, int, int]:
    """(fits, estimated bytes, budget bytes) for a run of ``pipeline`` over ``points`` points."""
    need = estimate(pipeline, points, kept_share)
    budget = run_budget() if budget is None else budget
    return need * SAFETY <= budget, need, budget


def dense_limit(points: int, bytes_per_cell: int) -> int:
    """Most cells a dense grid or lattice over ``points`` points may hold: CELLS_PER_POINT per point
    (at least MIN_DENSE_CELLS), and no more than half the available memory holds."""
    by_points = max(CELLS_PER_POINT * int(points), MIN_DENSE_CELLS)
    by_memory = available_bytes() // (2 * max(int(bytes_per_cell), 1))
    return int(max(min(by_points, by_memory), 1))


def tile_size_for(points: int, area: float, target_points: int) -> float:
    """Edge (m, rounded up to 10 m) of square tiles holding about ``target_points`` of ``points``
    spread over ``area`` m2."""
    density = max(points / max(area, 1.0), 1e-9)
    return 10.0 * math.ceil(math.sqrt(max(target_points, 1) / density) / 10.0)


# ---------------------------------------------------------------- a run's memory guard
def points_before_reading(cfg):
    """The run's point count from the LAS header or the synthetic scene's size (None otherwise)."""
    if cfg.input.synthetic is not None and not cfg.input.paths:
        return cfg.input.synthetic.points
    from pathlib import Path

    from roadx_ti import io

    path = Path(cfg.input.paths[0])
    if path.suffix.lower() not in (".las", ".laz") or not path.is_file():
        return None
    try:
        return io.read_headers([path])[0][2]
    except io.InputError:
        return None                   # the read will say what is wrong with the file


def check_run(cfg, points, cloud=None) -> None:
    """Stop with one line, or switch to tiles (tiling.auto), when the run's memory estimate
    exceeds what it may use (``fits``)."""
    from roadx_ti.errors import DataError

    if points is None:
        return
    area = _box_area(cfg, cloud)
    # a box stretched by strays underrates the density: the kept share errs upwards (safe)
    share = kept_share(cfg, points, points / area if area else None)
    ok, need, budget = fits(cfg.pipeline, points, kept_share=share)
    if ok:
        return
    fit = points_that_fit(cfg.pipeline, budget, share)
    size = tile_size_for(points, area, max(fit // 2, 1)) if area else None
    said = (f"{points:,} points through the {cfg.pipeline} pipeline need about "
            f"{format_size(need * SAFETY)}, more than the {format_size(budget)} this run may use")
    if size is None or not cfg.input.paths or fit < 1000:
        raise DataError(f"{said}: run on fewer points (e.g. a smaller synthetic scene) or with more memory")
    if cfg.tiling.auto:
        log.warning("%s: running in tiles of %g m (tiling.auto)", said, size)
        cfg.tiling.tile_size = size
        return
    raise DataError(f"{said}: run in tiles (--tile-size {size:g}, about {fit // 2:,} points per tile) "
                    "or set tiling.auto: true (--set tiling.auto=true)")


def _box_area(cfg, cloud=None):
    """Plan area (m2) of the input's box (header bounds, or the cloud's bounds once read); None
    without bounds."""
    from roadx_ti import io

    if cloud is not None and cloud.n:
        from roadx_ti.columns import column_max, column_min

        lo, hi = column_min(cloud.xyz[:, :2]), column_max(cloud.xyz[:, :2])
    elif cfg.input.paths:
        try:
            bounds = io.read_headers([cfg.input.paths[0]])[0][1]
        except io.InputError:
            return None
        lo, hi = bounds[:2], bounds[2:]
    else:
        return None
    area = max(float(hi[0] - lo[0]), 1.0) * max(float(hi[1] - lo[1]), 1.0)
    return area
