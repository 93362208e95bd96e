"""The extra dimensions every point-cloud output of a run carries beside its classification."""
from __future__ import annotations

DECIDED_BY = "roadx_label"     # uint8: 0 = reached the last stage, i = stage i removed the point
SEGMENT = "segment_id"         # int32: the point's segment (roof) or region, -1 for none
RESULT_DIMS = {DECIDED_BY: "uint8", SEGMENT: "int32"}


def result_dims(decided_by, segment_id, extra: dict) -> dict:
    """The output's extra dimensions: the two result dimensions, then each stage's own data."""
    return {DECIDED_BY: decided_by, SEGMENT: segment_id, **extra}
