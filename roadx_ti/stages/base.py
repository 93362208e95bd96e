"""What a stage is: declared options (defaults, units, validation) and a run over a Cloud.

A stage gets the current working cloud (the points every earlier stage kept) and a context, and
returns a StageResult: a keep-mask that narrows the working set, labels for the working points,
or both. Stages never call ``ti.init`` and never read or write files.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from roadx_ti.cloud import Cloud

# ASPRS classes written by the pipelines
CLASS_OTHER = 1
CLASS_GROUND = 2
CLASS_BUILDING = 6
CLASS_ROAD = 11


class StageOptions(BaseModel):
    """Base of every stage's options: unknown keys are errors, values are validated on build."""
    model_config = ConfigDict(extra="forbid", validate_assignment=True)


@dataclass
class StageResult:
    # bool per working point: True = stays in the working set. None = the stage removes nothing.
    keep: np.ndarray | None = None
    # 'filter': removed points are decided now (they get `removed_class`);
    # 'subsample': removed points are only skipped for speed and later take the label of their
    # nearest processed point (METHODS.md R1 "label transfer").
    mode: str = "filter"
    removed_class: int = CLASS_OTHER
    # int per working point: final ASPRS class, for the labelling stage that ends a pipeline
    labels: np.ndarray | None = None
    segment_id: np.ndarray | None = None     # int32 per working point, -1 for none
    # per working point arrays later stages may use (e.g. 'height_above_ground', 'normal')
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)  # counts and facts for the summary JSON


# ctx.facts key: local z of the lowest point of the whole survey a cloud was cut from (tiled runs)
SURVEY_Z_MIN = "survey_z_min"
# ctx.facts key: survey-wide estimates (roadx_ti.estimates.measure) that 'auto' options follow
ESTIMATES = "estimates"


def estimate(ctx: "StageContext", key: str, default=None):
    """A survey-wide estimate (see roadx_ti.estimates), or ``default`` when not measured."""
    value = ctx.facts.get(ESTIMATES, {}).get(key)
    return default if value is None else value
# ctx.facts key: number of points of the whole survey a cloud was cut from (tiled runs)
SURVEY_POINTS = "survey_points"


@dataclass
class StageContext:
    seed: int = 0
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("roadx_ti"))
    progress: Any = None          # roadx_ti.progress.Progress or None
    # per working point arrays produced by earlier stages; the pipeline narrows them with the
    # working set, so a stage always sees them aligned with its cloud
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    # cloud-level facts produced by earlier stages (e.g. point density)
    facts: dict[str, Any] = field(default_factory=dict)


class Stage:
    """Subclass with ``name``, ``Options`` and ``run``."""
    name: ClassVar[str] = ""
    Options: ClassVar[type[StageOptions]] = StageOptions

    def __init__(self, options: StageOptions | dict | None = None):
        if options is None:
            options = self.Options()
        elif isinstance(options, dict):
            options = self.Options(**options)
        self.options = options

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:  # pragma: no cover
        raise NotImplementedError
