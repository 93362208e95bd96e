"""The default tile buffer: how far each stage's decision about a point depends on other points."""
from __future__ import annotations

import math

MIN_BUFFER = 5.0                 # m: even point-local stages need their neighbours
CLOTH_SPAN = 30.0                # m: least cloth buffer (half the widest building it hangs over)

STAGE_REACH_DOC = """Spatial reach of each stage (m), the default buffer is the largest:
cloth_ground / cloth_smooth: the larger of 30 m and 15 x cloth_resolution (the cloth hangs over a
building from the terrain around it: a building cut by the window's edge loses that support, so the
buffer covers buildings up to 60 m across; the stiffness carries the cloth's shape 15 particles);
grid_slope: 4 x step; ransac_planes: ground_cell; color_growing: 20 x max_edge_distance;
roof_seeds: 4 x r_max (1.5 m for 'auto'); roof_filter: 2 x sqrt(min_roof_area) (a roof must be whole to be measured);
others: MIN_BUFFER."""


def stage_reach(name: str, options) -> float:
    """How far (m) a stage's decision about a point depends on other points (see STAGE_REACH_DOC)."""
    def get(key, default):
        value = getattr(options, key, default) or default
        return default if isinstance(value, str) else float(value)   # 'auto': follows the estimates
    reach = {
        "cloth_ground": lambda: max(CLOTH_SPAN, 15.0 * get("cloth_resolution", 1.0)),
        "cloth_smooth": lambda: max(CLOTH_SPAN, 15.0 * get("cloth_resolution", 2.0)),
        "grid_slope": lambda: 4.0 * get("step", 0.5),
        "ransac_planes": lambda: get("ground_cell", 30.0),
        "color_growing": lambda: 20.0 * get("max_edge_distance", 0.5),
        "roof_seeds": lambda: 4.0 * get("r_max", 1.5),
        "roof_filter": lambda: 2.0 * math.sqrt(get("min_roof_area", 10.0)),
    }.get(name)
    return max(MIN_BUFFER, reach() if reach else MIN_BUFFER)


def default_buffer(stage_specs) -> tuple[float, dict]:
    """(buffer in m, {stage: reach}) from the stages' spatial reach, rounded up to a metre."""
    reaches = {name: round(stage_reach(name, opts), 3) for name, opts in stage_specs}
    return float(math.ceil(max(reaches.values(), default=MIN_BUFFER))), reaches
