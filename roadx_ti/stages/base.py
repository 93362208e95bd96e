"""What a stage is: everything about it in one class.

A Stage subclass declares:
- ``name`` and ``Options`` (defaults, units, validation; built once, by config validation);
- ``reach(options, estimates)``: how far (m) its decision about a point depends on other points,
  for the tile buffers of tiled runs (every stage declares one: the base class raises);
- ``requires`` / ``provides``: the per-point data (``ctx.point_data`` / ``StageResult.point_data``
  keys, and GROUND_SURFACE) it reads from earlier stages and hands on, and ``right_after``: the
  stage that must run just before it; ``check_order`` checks them when the pipeline is built,
  before any input is read;
- ``writes``: the per-point data of its own that the output carries as extra dimensions;
- a ground stage provides GROUND_SURFACE: ``export_ground`` puts its surface in ctx.facts, and the
  DTM export (output.dtm) and later stages (height_above_ground) read it from there.

A stage gets the current working cloud (the points every earlier stage kept) and a context, and
returns a StageResult: a keep-mask that narrows the working set, labels for the working points,
or both. Stages never call ``ti.init`` and never read or write files.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import ConfigDict, Field

from roadx_ti.cloud import Cloud
from roadx_ti.option_rules import CheckedOptions

# ASPRS classes written by the pipelines
# an option that is a length or size (> 0) or 'auto' (estimated from the survey)
# m: the smallest cell, resolution or grid step an option takes (finer ones overflowed the 64-bit
# cell keys of a survey's coordinates, or asked for more cells than memory holds)
MIN_CELL = 0.001
# a cell size (m) or 'auto'
PositiveOrAuto = Annotated[float, Field(ge=MIN_CELL)] | Literal["auto"]

CLASS_OTHER = 1
CLASS_GROUND = 2
CLASS_BUILDING = 6
CLASS_ROAD = 11


class StageOptions(CheckedOptions):
    """Base of every stage's options (option_rules.CheckedOptions), validated on assignment too."""
    model_config = ConfigDict(validate_assignment=True)


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


# ctx.facts key: share of the survey's points that the pipeline's downsampling stages keep (their
# product; 1 or absent: every point), a survey-wide value (from the survey's estimates, not a tile's draw)
SAMPLED_SHARE = "sampled_share"


def survey_spacing(ctx: "StageContext"):
    """The survey's pulse spacing (m), or its point spacing where the input has no returns, at the
    density the stages see: over the share of the points downsampling kept (SAMPLED_SHARE) the
    spacing is 1 / sqrt(share) times the survey's. None when neither was measured."""
    spacing = estimate(ctx, "pulse_spacing_m") or estimate(ctx, "point_spacing_m")
    share = float(ctx.facts.get(SAMPLED_SHARE) or 1.0)
    return spacing / np.sqrt(share) if spacing and share < 1.0 else spacing


def spacing_cell(ctx: "StageContext", spacings: float, min_cell: float, fallback: float) -> float:
    """A plan cell (m) of ``spacings`` survey spacings (survey_spacing), at least ``min_cell``;
    ``fallback`` without a spacing estimate."""
    spacing = survey_spacing(ctx)
    return max(spacings * float(spacing), min_cell) if spacing else fallback


# ctx.facts key: number of points of the whole survey a cloud was cut from (tiled runs)
SURVEY_POINTS = "survey_points"
# ctx.facts key (and a name in requires / provides): the GroundSurface of the last ground stage
GROUND_SURFACE = "ground_surface"
# ctx.facts key: the height noise of a ground stage's ground points (m; estimates.height_noise):
# the sensor's noise on hard surfaces, which foliage does not inflate
GROUND_NOISE = "ground_noise_m"
# ctx.facts key: roadx_ti.footprint.DataEdge of the points a pipeline run got (a tile's with its
# buffer), set before the first stage when a stage declares uses_data_edge
DATA_EDGE = "data_edge"

# m: the least tile buffer, and the reach a stage declares when its decisions are point-local
# (even those need their neighbours: kNN statistics, a downsampling stride)
MIN_BUFFER = 5.0


class StageOrderError(ValueError):
    """A pipeline whose stages need data no earlier stage provides; the message is one line."""


@dataclass
class GroundSurface:
    """A ground stage's surface: grids with ``cloth_z`` (rows, cols) heights in the cloud's local
    z, ``x0`` / ``y0`` (local x, y of cell (0, 0)), ``resolution`` and ``height_above(xyz)``
    (kernels.cloth.ClothResult), one per part of the cloud; ``largest`` is the DTM's."""
    largest: Any
    origin: np.ndarray
    parts: list = field(default_factory=list)   # every part's grid (largest included)

    def height_above(self, xyz: np.ndarray) -> np.ndarray:
        """float32 (n,): z minus the surface under each point (local coordinates of the cloud the
        surface was made on); a point under no part's grid (an isolated point, which no cloth lies
        under) gets NaN, not the grid's border height."""
        out = np.full(len(xyz), np.nan, np.float32)
        left = np.ones(len(xyz), bool)
        for grid in self.parts or [self.largest]:
            rows, cols = grid.cloth_z.shape
            x = (xyz[:, 0] - grid.x0) / grid.resolution
            y = (xyz[:, 1] - grid.y0) / grid.resolution
            under = left & (x >= 0) & (x <= cols - 1) & (y >= 0) & (y <= rows - 1)
            if under.any():
                out[under] = grid.height_above(xyz[under])
                left &= ~under
        return out


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
    """Subclass with ``name``, ``Options``, ``reach``, ``run`` and, where it applies, ``requires``,
    ``provides`` and ``writes`` (see the module's docstring; the README's CONTRIBUTING recipe)."""
    name: ClassVar[str] = ""
    Options: ClassVar[type[StageOptions]] = StageOptions
    # point_data keys (or GROUND_SURFACE) that an earlier stage must provide
    requires: ClassVar[tuple[str, ...]] = ()
    # point_data keys (or GROUND_SURFACE) that every result of this stage carries
    provides: ClassVar[tuple[str, ...]] = ()
    # the stage that must run right before this one (its graph over the same working points)
    right_after: ClassVar[str | None] = None
    # the class a labelling stage gives its target (road, roof, ground): the config's pipeline must be
    # the one of the last such stage's class (config.PIPELINE_TARGET); None for the other stages
    labels: ClassVar[int | None] = None
    # False: the stage keeps every working point (it computes or segments); only such stages may
    # follow the last labelling stage (a filter after it removed labelled points)
    narrows: ClassVar[bool] = True
    # point_data keys of this stage's result written to the output as extra dimensions (untiled
    # runs; float32, NaN for a point the stage did not see)
    writes: ClassVar[tuple[str, ...]] = ()
    # True: the stage reads ctx.facts[DATA_EDGE] (the outer edge of the run's points); a stage
    # whose options decide it makes this a property
    uses_data_edge: ClassVar[bool] = False

    @classmethod
    def reach(cls, options: StageOptions, estimates: dict | None = None) -> float:
        """How far (m) this stage's decision about a point depends on other points, from its
        options and, for 'auto' options, the survey-wide estimates (None: not measured yet,
        the documented fallback holds). The tile buffer is the largest over the stages, at least
        MIN_BUFFER. Every stage declares its own: a stage without one is a mistake, not 5 m."""
        raise NotImplementedError(f"stage {cls.name!r} declares no reach (Stage.reach): how far its "
                                  "decision about a point depends on other points, in m")

    def __init__(self, options: StageOptions | dict | None = None):
        if options is None:
            options = self.Options()
        elif isinstance(options, dict):
            options = self.Options(**options)
        self.options = options

    def run(self, cloud: Cloud, ctx: StageContext) -> StageResult:  # pragma: no cover
        raise NotImplementedError

    @staticmethod
    def export_ground(ctx: StageContext, surface: GroundSurface) -> None:
        """A ground stage's surface, for the DTM export and later stages (GROUND_SURFACE)."""
        ctx.facts[GROUND_SURFACE] = surface


def check_order(stage_classes) -> None:
    """Raise StageOrderError (one line) when a stage requires data no earlier stage provides."""
    have: set[str] = set()
    previous = None
    for number, cls in enumerate(stage_classes):
        missing = [key for key in cls.requires if key not in have]
        if missing:
            raise StageOrderError(f"stages[{number}] {cls.name} needs {', '.join(map(repr, missing))} from an "
                                  f"earlier stage ({_makers(missing)}); put it after that stage")
        if cls.right_after and previous != cls.right_after:
            raise StageOrderError(f"stages[{number}] {cls.name} must follow {cls.right_after} directly (it works "
                                  f"on the neighbour graph {cls.right_after} made of the same points); put it right after it")
        previous = cls.name
        have.update(cls.provides)


def _makers(keys) -> str:
    """'KEY from STAGE or STAGE; ...' over the registered stages (the error path only)."""
    from roadx_ti.stages import REGISTRY, stage_class

    makers = {key: [name for name in REGISTRY if key in stage_class(name).provides] for key in keys}
    groups: dict[tuple, list] = {}
    for key, names in makers.items():
        groups.setdefault(tuple(names), []).append(repr(key))
    return "; ".join(f"{', '.join(group)} from {' or '.join(names) if names else 'no stage'}"
                     for names, group in groups.items())
