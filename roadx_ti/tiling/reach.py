"""The default tile buffer: the largest spatial reach the stages declare (Stage.reach)."""
from __future__ import annotations

import math

from roadx_ti.stages import stage_class
from roadx_ti.stages.base import MIN_BUFFER
from roadx_ti.stages.cloth import CLOTH_SPAN

__all__ = ["CLOTH_SPAN", "MIN_BUFFER", "default_buffer", "stage_reach"]


def stage_reach(name: str, options, estimates: dict | None = None) -> float:
    """How far (m) a stage's decision about a point depends on other points (its Stage.reach),
    at least MIN_BUFFER."""
    return max(MIN_BUFFER, stage_class(name).reach(options, estimates))


def default_buffer(stage_specs, estimates: dict | None = None) -> tuple[float, dict]:
    """(buffer in m, {stage: reach}) from the stages' spatial reach, rounded up to a metre."""
    reaches = {name: round(stage_reach(name, opts, estimates), 3) for name, opts in stage_specs}
    return float(math.ceil(max(reaches.values(), default=MIN_BUFFER))), reaches
