"""A tiled run against an untiled (reference) run of the same points: where they disagree, relative
to the core borders, and whether segments stay whole."""
from __future__ import annotations

import math

import numpy as np

from roadx_ti.result_dims import SEGMENT
from roadx_ti.tiling.plan import CoreGrid, _border_distance
from roadx_ti.tiling.tile import _world_xy

DISTANCE_BINS = (0.0, 1.0, 2.0, 5.0, 10.0, 20.0, math.inf)


def segment_agreement(a: np.ndarray, b: np.ndarray) -> float:
    """Share of the points segmented in ``a`` whose ``b`` id is the one most of their ``a``
    segment has (1.0: every ``a`` segment is whole in ``b``); ids are arbitrary labels."""
    sel = a >= 0
    if not sel.any():
        return 1.0
    pairs, counts = np.unique(np.column_stack([a[sel], b[sel]]), axis=0, return_counts=True)
    best = np.zeros(int(a.max()) + 1, np.int64)
    np.maximum.at(best, pairs[:, 0], counts)
    return float(best.sum() / sel.sum())


def compare_outputs(tiled_summary: dict, tiled_output, reference_output, *, summary_path=None) -> dict:
    """Tiled vs reference (untiled) labels of the same points (merged outputs, same order):
    disagreements counted and located by their distance to the nearest core border, and the
    segment partitions compared. Added to the summary JSON as 'comparison' when summary_path is given."""
    from roadx_ti import io, jsonio

    a, b = io.read(tiled_output), io.read(reference_output)
    if a.n != b.n:
        raise ValueError(f"{tiled_output} has {a.n} points, {reference_output} {b.n}")
    xa, ya = _world_xy(a)
    xb, yb = _world_xy(b)
    if not (np.array_equal(xa, xb) and np.array_equal(ya, yb)):
        raise ValueError("the outputs do not hold the same points in the same order")
    differ = a.classification != b.classification
    tiling = tiled_summary["tiling"]
    grid = CoreGrid(**tiling["grid"])
    dist = _border_distance(grid, xa[differ], ya[differ])
    hist, _ = np.histogram(dist, bins=DISTANCE_BINS)
    seg_a = np.asarray(a.las[SEGMENT], np.int64)
    seg_b = np.asarray(b.las[SEGMENT], np.int64)
    crossing, whole = 0, 0
    if (seg_b >= 0).any():
        # reference segments spread over several cores: are they one segment in the tiled run?
        cell = np.column_stack(grid.cells(xb, yb))
        for s in np.unique(seg_b[seg_b >= 0]):
            sel = seg_b == s
            if len(np.unique(cell[sel], axis=0)) > 1:
                crossing += 1
                ids, counts = np.unique(seg_a[sel], return_counts=True)
                whole += int(counts.max() >= 0.99 * sel.sum() and ids[counts.argmax()] >= 0)
    comparison = {
        "points": int(a.n), "disagreements": int(differ.sum()),
        "agreement": float(1.0 - differ.mean()) if a.n else 1.0,
        "disagreements_by_border_distance_m": {
            f"{lo:g}-{hi:g}": int(h) for lo, hi, h in zip(DISTANCE_BINS[:-1], DISTANCE_BINS[1:], hist)},
        "disagreement_max_border_distance_m": float(dist.max()) if len(dist) else None,
        "segment_agreement": min(segment_agreement(seg_b, seg_a), segment_agreement(seg_a, seg_b)),
        "reference_segments_crossing_borders": crossing, "crossing_segments_kept_whole": whole,
        "reference": str(reference_output),
    }
    if summary_path is not None:
        summary = dict(tiled_summary) | {"comparison": comparison}
        jsonio.write(summary_path, summary)
    return comparison
