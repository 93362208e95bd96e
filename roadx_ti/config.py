"""YAML run configuration -> a typed, validated object.

Every key is declared with its default and unit (lengths in metres); unknown keys, wrong types and
out-of-range values are errors that name the key, the value and what is allowed, in one line.
``--set a.b=value`` overrides any key; a stage is addressed by its name (``stages.sor.k=30``) or its
position (``stages.1.k=30``, or both: ``stages.1.sor.k=30``).
"""
from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any, Literal, Union

import yaml
from pydantic import Field, PrivateAttr, StrictBool, ValidationError, field_validator, model_validator

from roadx_ti import backend as _backend
from roadx_ti.dtm import FORMATS as DTM_FORMATS
from roadx_ti.option_rules import CheckedOptions, shown
from roadx_ti.stages import REGISTRY, stage_class


class ConfigError(ValueError):
    """A configuration mistake; the message is one line meant for the user."""


class _Strict(CheckedOptions):
    """A section of the run config (option_rules.CheckedOptions)."""


class SyntheticInput(_Strict):
    kind: Literal["uav-road", "uav-road-v1", "als-roof", "als-roof-v1"] = "uav-road"
    points: int = Field(1_000_000, ge=1000, lt=2**31, description="number of points")
    seed: int = Field(0, ge=0)


class InputConfig(_Strict):
    paths: list[str] = Field(default_factory=list, description="LAS/LAZ/PLY/PCD/NPZ/XYZ files")
    synthetic: SyntheticInput | None = None


class OutputConfig(_Strict):
    path: str = Field("out/result.laz", description="result point cloud (.laz/.las/.ply/.npz/.xyz)")
    points: Literal["all", "processed"] = Field(
        "all", description="all: every input point in input order (label transfer for points "
        "skipped by downsampling and for records repeating another's x, y, z); processed: only the "
        "points the stages worked on (neither skipped nor a repeat)")
    report_png: bool = Field(True, description="write a top-view PNG beside the output")
    dtm: str | StrictBool | None = Field(None, description="write the cloth of the last cloth stage as a DTM "
                                   "raster: a path (.tif/.tiff GeoTIFF with the input's CRS, .asc ESRI "
                                   "ASCII grid + .prj, .npy + .json transform); true: NAME.dtm.tif beside "
                                   "the output; false: none; null (default): NAME.dtm.tif for the ground "
                                   "pipeline, none for the others")
    mode: Literal["merged", "per-file"] = Field(
        "merged", description="tiled runs over several files: one merged output in input order, or "
        "one output per input file in the output folder")


    @field_validator("dtm")
    @classmethod
    def _dtm_format(cls, value):
        if isinstance(value, str) and Path(value).suffix.lower() not in DTM_FORMATS:
            raise ValueError("a DTM is written as .tif/.tiff (GeoTIFF), .asc (ESRI ASCII grid + .prj) "
                             "or .npy (+ .json transform)")
        return value

    @field_validator("path")
    @classmethod
    def _a_file_name(cls, value):
        why = output_name_problem(value)
        if why:
            raise ValueError(why)
        return value


class TilingConfig(_Strict):
    enabled: bool = Field(False, description="run in tiles with buffers even for one input file")
    tile_size: float | None = Field(None, gt=0, allow_inf_nan=True, description="core tile edge (m); null: the largest whose "
                                    "window fits the run's memory budget (at most 16 M points); .inf: untiled")
    buffer: float | None = Field(None, ge=0, description="buffer on every side of a tile (m); null: the "
                                 "largest spatial reach of the stages")
    auto: bool = Field(False, description="run in tiles when the run's memory estimate exceeds the memory "
                       "it may use (roadx_ti/memory.py); false: stop with one line suggesting a tile size")


class ExecutorConfig(_Strict):
    workers: int | None = Field(None, ge=1, description="start a local Dask cluster of this many processes")
    scheduler: str | None = Field(None, pattern=r"^(tcp|tls|inproc|ucx)://", description="address of an "
                                  "existing Dask scheduler, e.g. tcp://10.0.0.5:8786")
    connect_timeout: float = Field(5.0, gt=0, description="seconds to reach the scheduler before the run stops")
    worker_timeout: float = Field(30.0, gt=0, description="seconds to wait for the scheduler's first worker")


class EvaluateConfig(_Strict):
    truth_classes: list[int] | None = Field(
        None, description="input classes that are the target truth (default: the pipeline's "
        "target class); accuracy is reported when the input has a classification")

    @field_validator("truth_classes", mode="before")
    @classmethod
    def _one_class(cls, value):
        # --set evaluate.truth_classes=6: one class, as the list [6]
        value = [value] if isinstance(value, int) and not isinstance(value, bool) else value
        if isinstance(value, list) and not value:
            # [] fell back to the pipeline's class silently (null is how to say "the default")
            raise ValueError("names no class; give the classes of the truth (e.g. [6]) or null for the pipeline's")
        if isinstance(value, list) and any(isinstance(v, int) and not 0 <= v <= 255 for v in value):
            raise ValueError("classes are integers 0..255 (LAS classification)")
        return value


PIPELINE_TARGET = {"road": 11, "roof": 6, "ground": 2}


class RunConfig(_Strict):
    pipeline: Literal["road", "roof", "ground"] = "road"
    input: InputConfig = Field(default_factory=InputConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)
    backend: Literal[_backend.CHOICES] = "auto"  # type: ignore[valid-type]
    threads: int | None = Field(None, ge=1, description="CPU threads for Taichi (default: all)")
    memory_limit: str | None = Field(None, description="memory the run may use in total, e.g. 8G or 512M "
                                     "(default: what this machine has available)")
    seed: int = Field(0, ge=0, description="seed of every random choice (RANSAC hypotheses)")
    evaluate: EvaluateConfig = Field(default_factory=EvaluateConfig)
    tiling: TilingConfig = Field(default_factory=TilingConfig)
    executor: ExecutorConfig = Field(default_factory=ExecutorConfig)
    stages: list[dict[str, Any]] = Field(default_factory=list)
    # (name, options object) per stage: built once, by stage_list (from_mapping calls it)
    _stage_specs: list | None = PrivateAttr(default=None)

    @field_validator("stages")
    @classmethod
    def _stage_entries(cls, stages):
        if not stages:      # only a list given in the file gets here: a left-out key is the defaults
            raise ValueError("stages: the list is empty; list the stages to run, or leave out "
                             "'stages' for the pipeline's default stages")
        for i, entry in enumerate(stages):
            if not isinstance(entry, dict) or len(entry) != 1:
                raise ValueError(f"stages[{i}] must be a mapping of one stage name to its options")
            (name,) = entry
            if name not in REGISTRY:
                raise ValueError(f"stages[{i}]: unknown stage {name!r}; known: {', '.join(REGISTRY)}")
        return stages

    def stage_list(self):
        """(name, options object) per stage, options validated by the stage's own model and the
        stage order checked (Stage.requires / provides); built once, on first call (from_mapping
        makes that call, before any work), and the same objects returned after."""
        if self._stage_specs is None:
            self._stage_specs = self._build_stage_list()
        return list(self._stage_specs)

    def pipeline_stages(self):
        """The stages a run of this config runs: stage_list(), or the pipeline's defaults
        (pipelines.DEFAULT_STAGES) when the config lists none."""
        from roadx_ti import pipelines

        return self.stage_list() or pipelines.default_stage_specs(self.pipeline)

    def _build_stage_list(self):
        from roadx_ti.stages.base import StageOrderError, check_order

        out = []
        for i, entry in enumerate(self.stages):
            (name, opts), = entry.items()
            cls = stage_class(name)
            try:
                out.append((name, cls.Options(**(opts or {}))))
            except ValidationError as exc:
                raise ConfigError(_one_line(exc, prefix=f"stages[{i}].{name}")) from None
            except TypeError:
                raise ConfigError(f"stages[{i}].{name}: options must be a mapping, got {opts!r}") from None
        try:
            check_order(stage_class(name) for name, _ in out)
        except StageOrderError as exc:
            raise ConfigError(f"config error: {exc}") from None
        target = PIPELINE_TARGET[self.pipeline]
        labelling = [(i, name, stage_class(name).labels) for i, (name, _) in enumerate(out)
                     if stage_class(name).labels is not None]
        if labelling and labelling[-1][2] != target:
            # the last labelling stage gives the output's classes: pipeline: roof over the road
            # stages wrote class 11 and scored class 6 (none)
            i, name, labels = labelling[-1]
            pipeline = next(p for p, c in PIPELINE_TARGET.items() if c == labels)
            raise ConfigError(f"config error: pipeline = {self.pipeline!r}, but stages[{i}] {name} labels class "
                              f"{labels} ({pipeline}), not {target}; set pipeline: {pipeline}")
        after = [(j, n) for j, (n, _) in enumerate(out) if labelling and j > labelling[-1][0]
                 and stage_class(n).narrows]
        if after:
            # the labels are made on the points that reach the labelling stage: a filter after it
            # removed labelled points (road_regions first, then the filters: exit 0, no road at all)
            i, name, labels = labelling[-1]
            named = ", ".join(f"stages[{j}] {n}" for j, n in after)
            raise ConfigError(f"config error: {named} after stages[{i}] {name}, which labels class {labels}, would "
                              f"remove labelled points; put the filters before {name}")
        return out

    @field_validator("memory_limit", mode="before")
    @classmethod
    def _memory_size(cls, value):
        if isinstance(value, bool):
            raise ValueError(f"not a memory size: {value!r} (use e.g. 512M, 8G)")
        if isinstance(value, (int, float)):       # a number of bytes (YAML and --set give numbers)
            value = str(value)
        if value is not None:
            from roadx_ti.memory import parse_size
            if parse_size(value) <= 0:
                raise ValueError(f"must be more than 0 bytes, got {value!r}")
        return value

    @model_validator(mode="after")
    def _executor_rules(self):
        if self.executor.workers is not None and self.executor.scheduler:
            raise ValueError("executor: give workers (a local cluster) or scheduler (an existing one), not both")
        workers = self.executor.workers
        if workers is not None and workers > max_local_workers():
            raise ValueError(f"executor.workers {workers}: a local cluster of more than {max_local_workers()} "
                             f"processes ({WORKERS_PER_CPU} per CPU here) would only wait on each other; for more "
                             "machines start a Dask scheduler and give --scheduler")
        return self

    @property
    def tiled(self) -> bool:
        """Whether the run goes through the tiling engine (several inputs, a folder, or asked)."""
        # --tile-size inf on one file is an untiled run (the tiling engine's one tile lays its cloth
        # on a world lattice, not the file's own box: other labels)
        finite_tiles = self.tiling.tile_size is not None and math.isfinite(self.tiling.tile_size)
        return (self.tiling.enabled or finite_tiles or len(self.input.paths) > 1
                or any(Path(p).is_dir() for p in self.input.paths)
                or self.executor.workers is not None or bool(self.executor.scheduler))

    def dtm_path(self) -> Path | None:
        """Where the DTM goes: output.dtm's path, NAME.dtm.tif beside the output (true, or unset
        in the ground pipeline), or None."""
        dtm = self.output.dtm
        if dtm is False or (dtm is None and self.pipeline != "ground"):
            return None
        if isinstance(dtm, str):
            return Path(dtm)
        return Path(f"{output_stem(self.output.path)}.dtm.tif")

    @property
    def truth_classes(self) -> list[int]:
        return self.evaluate.truth_classes or [PIPELINE_TARGET[self.pipeline]]


def output_name_problem(path) -> str | None:
    """Why ``path`` cannot name an output file ('' or a path ending in '.' / '..'), or None."""
    if not str(path).strip():
        return "the output path is empty"
    if Path(path).name in ("", ".", ".."):
        return f"{path!r} names a folder, not an output file (e.g. {Path(path) / 'result.laz'})"
    return None


def output_stem(path) -> Path:
    """The output's path without its format suffix (``.copc.laz`` counts as one): the sidecar
    files are STEM.summary.json, STEM.config.yaml, STEM.png, STEM.dtm.tif."""
    path = Path(path)
    if path.name.lower().endswith(".copc.laz"):
        return path.with_name(path.name[:-len(".copc.laz")])
    return path.with_suffix("")


# pydantic names the member of a union a value failed in its error location (``constrained-float``,
# ``literal['auto']``, ``float``): not a key of the config
_UNION_MEMBER_TYPES = {"float", "int", "str", "bool", "none", "list", "tuple", "dict"}


WORKERS_PER_CPU = 4    # a local cluster's processes per CPU at most (each holds tiles in memory)


def max_local_workers() -> int:
    return WORKERS_PER_CPU * (os.cpu_count() or 1)


def _error_key(loc) -> str:
    return ".".join(str(p) for p in loc
                    if isinstance(p, int) or (str(p).isidentifier() and str(p) not in _UNION_MEMBER_TYPES))


def _one_line(exc: ValidationError, prefix: str = "") -> str:
    errors = exc.errors()
    loc = _error_key(errors[0]["loc"])
    key = f"{prefix}.{loc}" if prefix and loc else (prefix or loc)
    # a value outside every member of a union: what each member wanted, on one line
    same = [e for e in errors if _error_key(e["loc"]) == loc]
    msgs = []
    for err in same:
        msg = "unknown key" if err["type"] == "extra_forbidden" else err["msg"].removeprefix("Value error, ")
        if msg not in msgs:
            msgs.append(msg)
    rest = len(errors) - len(same)
    more = f" (and {rest} more)" if rest else ""
    if not key:
        # a rule over several keys (a model validator): its input is the whole config, not worth
        # printing; its message names the keys
        return "config error: " + ", or ".join(msgs) + more
    return f"config error: {key} = {shown(errors[0].get('input'))}: {', or '.join(msgs)}{more}"


def parse_point_count(text: str) -> int:
    """Point counts as users type them: 1000000, 1M, 250k (argparse type: bad text is a usage error)."""
    import argparse

    t = text.strip().lower()
    scale = {"k": 1_000, "m": 1_000_000}.get(t[-1:], 1)
    try:
        exact = float(t[:-1] if scale != 1 else t) * scale
        value = int(exact)
    except (ValueError, OverflowError):     # OverflowError: inf, 1e400
        raise argparse.ArgumentTypeError(f"not a point count: {text!r}") from None
    if exact != value:                       # 1.5 points: a whole number is meant, say which text
        raise argparse.ArgumentTypeError(f"a point count is a whole number, got {text!r}")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"point count must be > 0, got {text!r}")
    return value


def parse_scene_size(text: str) -> int:
    """A synthetic scene's point count as users type it (parse_point_count), at least the
    generator's 1000 (argparse type: a smaller one is a usage error before any scene is built)."""
    import argparse

    from roadx_ti.synthetic import MIN_POINTS

    value = parse_point_count(text)
    if value < MIN_POINTS:
        raise argparse.ArgumentTypeError(f"a synthetic scene holds at least {MIN_POINTS} points, got {text!r}")
    return value


def parse_value(text: str):
    """A --set value: YAML scalar syntax (numbers, true/false, null, [lists])."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)
    except (yaml.YAMLError, ConfigError):
        return text


def apply_override(raw: dict, assignment: str) -> None:
    """Apply ``a.b.c=value`` to the raw config mapping, in place."""
    if "=" not in assignment:
        raise ConfigError(f"--set {assignment!r}: expected KEY=VALUE, e.g. stages.sor.k=30")
    key, _, text = assignment.partition("=")
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise ConfigError(f"--set {assignment!r}: empty key")
    node: Any = raw
    i = 0
    while i < len(parts) - 1:
        part = parts[i]
        i += 1
        if isinstance(node, list):
            name, node = _stage_options(node, part, key)
            # stages.1.sor.k: the position and the name of the same stage
            if part.isdigit() and i < len(parts) - 1:
                if parts[i] == name:
                    i += 1
                elif parts[i] in REGISTRY:
                    raise ConfigError(f"--set {key}: stage {part} of this config is {name}, not {parts[i]}")
            continue
        if part not in node or node[part] is None:
            node[part] = {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        raise ConfigError(f"--set {key}: name an option of the stage, e.g. {key}.k=30")
    if not isinstance(node, dict):
        raise ConfigError(f"--set {key}: {'.'.join(parts[:-1])} is not a mapping")
    node[last] = parse_value(text)


def _stage_options(stages: list, part: str, key: str) -> tuple[str, dict]:
    named = [i for i, entry in enumerate(stages) if isinstance(entry, dict) and part in entry]
    if not part.isdigit() and len(named) > 1:
        # two stages of one name: which one is meant is the user's to say (the first changed silently)
        rest = key.split(part, 1)[1]
        raise ConfigError(f"--set {key}: this config has {len(named)} {part} stages (stages "
                          f"{', '.join(map(str, named))}); name one by its position, e.g. stages.{named[0]}.{part}{rest}")
    for i, entry in enumerate(stages):
        if isinstance(entry, dict) and (part in entry or part == str(i)):
            (name,) = entry
            if entry[name] is None:
                entry[name] = {}
            return name, entry[name]
    raise ConfigError(f"--set {key}: no stage {part!r} in this config")


class _UniqueKeyLoader(yaml.SafeLoader):
    """yaml.SafeLoader that refuses a key given twice in one mapping (PyYAML keeps the last one
    silently: a second 'stages:' pasted below the first would replace it unseen)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == MERGE_TAG:
                continue    # '<<: *anchor' (SafeLoader merges it; the mapping's own keys win)
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, (str, int, float, bool)) and key is not None:   # '? [a, b]': a list key
                raise ConfigError(f"a {type(key).__name__} as a key is not a name (line {key_node.start_mark.line + 1})")
            if key in seen:
                raise ConfigError(f"key {key!r} given twice (line {key_node.start_mark.line + 1})")
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


MERGE_TAG = "tag:yaml.org,2002:merge"
# YAML 1.2's floats without a point (1e-3, 2E5): PyYAML (YAML 1.1) reads them as text
_UniqueKeyLoader.add_implicit_resolver("tag:yaml.org,2002:float",
                                       re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
                                       list("-+0123456789"))


def load(path: str | Path, overrides: list[str] = ()) -> RunConfig:
    """Read, override and validate a YAML config; every mistake raises ConfigError (one line)."""
    if isinstance(overrides, (str, bytes)):     # load(path, "k=v") went through it letter by letter
        raise TypeError(f"overrides must be a list of 'KEY=VALUE' strings, e.g. [{overrides!r}]")
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"config file {path} is a folder; give the YAML file (e.g. configs/road_uav.yaml)")
    if not path.is_file():
        raise ConfigError(f"config file {path} does not exist")
    try:
        raw = yaml.load(path.read_bytes().decode("utf-8"), Loader=_UniqueKeyLoader)
    except UnicodeDecodeError as exc:
        raise ConfigError(f"config file {path} is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset "
                          f"{exc.start}); save it as UTF-8") from None
    except ConfigError as exc:
        raise ConfigError(f"config file {path}: {exc}") from None
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}" if where else ""
        raise ConfigError(f"config file {path} is not valid YAML{at}") from None
    if raw is None:
        # an empty (or truncated to nothing) file is a mistake, not "every default": say so
        raise ConfigError(f"config file {path} is empty: a config names at least its pipeline "
                          "(pipeline: road | roof | ground; see the files in configs/)")
    if not isinstance(raw, dict):
        raise ConfigError(f"config file {path} must hold a mapping of keys, got {type(raw).__name__}")
    return from_mapping(raw, overrides)


def from_mapping(raw: dict, overrides: list[str] = ()) -> RunConfig:
    raw = yaml.safe_load(yaml.safe_dump(raw))  # deep copy of plain data
    if isinstance(raw.get("input"), (str, list)):  # shorthand: input: path | [paths]
        paths = raw["input"]
        raw["input"] = {"paths": [paths] if isinstance(paths, str) else paths}
    if isinstance(raw.get("output"), str):  # shorthand: output: path
        raw["output"] = {"path": raw["output"]}
    for assignment in overrides:
        apply_override(raw, assignment)
    try:
        cfg = RunConfig(**raw)
    except ValidationError as exc:
        raise ConfigError(_one_line(exc)) from None
    cfg.stage_list()  # build and validate every stage's options now, before any work starts
    return cfg


def dump(cfg: RunConfig) -> str:
    """The resolved config as YAML (what was run, written beside the output): every stage that
    ran with all its options, defaults included (a config that left 'stages' out lists the
    pipeline's default stages), so that running the file again runs the same."""
    data = cfg.model_dump(mode="json")
    data["stages"] = [{name: options.model_dump(mode="json")} for name, options in cfg.pipeline_stages()]
    if (data.get("input") or {}).get("paths"):
        # absolute: run again from another folder, a relative path read another file (the copy's
        # own folder held the earlier output of the same name, scored against itself)
        data["input"]["paths"] = [os.path.abspath(p) for p in data["input"]["paths"]]
    return yaml.safe_dump(data, sort_keys=False)
