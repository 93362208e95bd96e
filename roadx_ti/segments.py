"""Per-segment statistics over point labels (host numpy, deterministic): shared by the road
pipeline's plane removal (R3, parts of an XY plane) and the roof post-filter (P4)."""
from __future__ import annotations

import numpy as np


def segment_medians(segment: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """Median of ``values`` per segment id 0..count-1 (segment -1 ignored), float64."""
    inside = segment >= 0
    seg, val = segment[inside], values[inside].astype(np.float64)
    order = np.lexsort((val, seg))
    seg, val = seg[order], val[order]
    starts = np.searchsorted(seg, np.arange(count))
    stops = np.searchsorted(seg, np.arange(count), side="right")
    lo = val[starts + (stops - starts - 1) // 2]
    hi = val[starts + (stops - starts) // 2]
    return (lo + hi) / 2
