"""Memory: what is free for a run, what a run will need, and how large a dense structure may be.

``available_bytes``: the machine's available memory (psutil), lowered by a cgroup limit
(containers, batch schedulers), an address-space rlimit (``ulimit -v``) and ROADX_TI_MEMORY_LIMIT
(``--memory-limit`` / ``memory_limit`` in a config), whichever is smallest.

``estimate``: peak memory of a pipeline run over n points, from bytes per point measured on the
CPU backend (peak RSS of ``python -m roadx_ti run`` at 300 k and 1 M points, the difference divided
by the points: see BYTES_PER_POINT) plus the process's base (Python, Taichi runtime, numpy,
laspy: BASE_BYTES).

``dense_limit``: how many cells a dense grid or lattice may have: a multiple of the points it is
laid over (work and memory bounded by the points, not by their extent) and what fits in memory.
"""
from __future__ import annotations

import math
import os
import re

LIMIT_VARIABLE = "ROADX_TI_MEMORY_LIMIT"

# peak RSS growth per input point (bytes), CPU backend, measured on synthetic scenes (uav-road for
# the road pipeline, als-roof for roof and ground) at 300 k and 1 M points: (RSS(1 M) - RSS(300 k)) / 700 k
BYTES_PER_POINT = {"road": 700, "roof": 950, "ground": 330}
BASE_BYTES = 450 * 2**20          # Python + Taichi + numpy + laspy + scipy, before any points
READ_BYTES_PER_POINT = 80         # the LAS record and float64 world coordinates while reading
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
    for unit, scale in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 2**10:.0f} KB"


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


def available_bytes() -> int:
    """Memory this run may still use (bytes): the smallest of the machine's available memory, the
    cgroup's and the rlimit's headroom, and ROADX_TI_MEMORY_LIMIT minus what this process holds."""
    import psutil

    candidates = [psutil.virtual_memory().available, _cgroup_free(), _rlimit_free()]
    limit = os.environ.get(LIMIT_VARIABLE)
    if limit:
        held = psutil.Process().memory_info().rss
        candidates.append(max(parse_size(limit) - held, 0))
    return int(min(c for c in candidates if c is not None))


def estimate(pipeline: str, points: int) -> int:
    """Expected peak memory (bytes) of a run of ``pipeline`` over ``points`` points."""
    per_point = BYTES_PER_POINT.get(pipeline, max(BYTES_PER_POINT.values())) + READ_BYTES_PER_POINT
    return int(BASE_BYTES + per_point * points)


def points_that_fit(pipeline: str, free: int) -> int:
    """How many points a run of ``pipeline`` can take in ``free`` bytes (with the safety factor)."""
    per_point = BYTES_PER_POINT.get(pipeline, max(BYTES_PER_POINT.values())) + READ_BYTES_PER_POINT
    return max(int((free / SAFETY - BASE_BYTES) / per_point), 0)


def fits(pipeline: str, points: int, free: int | None = None) -> tuple[bool, int, int]:
    """(fits, estimated bytes, free bytes) for a run of ``pipeline`` over ``points`` points."""
    need = estimate(pipeline, points)
    free = available_bytes() if free is None else free
    return need * SAFETY <= free, need, free


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
