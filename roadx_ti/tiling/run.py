"""The entry point of a tiled run: catalog, plan, survey estimates, tiles on an executor, merge,
summary."""
from __future__ import annotations

import logging
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from roadx_ti.quiet_logs import FirstOfEachWarning
from roadx_ti.result_dims import DECIDED_BY
from roadx_ti.tiling.catalogs import LAS_SUFFIXES, catalog, check_compatible
from roadx_ti.tiling.cluster import _DaskSession
from roadx_ti.tiling.executors import backend_ready, make_jobs, run_in_process, run_on_dask
from roadx_ti.tiling.merge import reconcile_segments, write_outputs
from roadx_ti.tiling.plan import (MAX_WINDOW_POINTS, Tile, align_tiles, budget_tile_size, catalog_origin, default_tile_size,
                                  plan_tiles, scan_cells, TooManyTiles)
from roadx_ti.tiling.reach import default_buffer
from roadx_ti.tiling.split import Split, split_catalog
from roadx_ti.tiling.tile import TileResult

log_default = logging.getLogger("roadx_ti")


MODES = ("merged", "per-file")
MIN_POINTS_PER_TILE = 1000      # a tile size giving (many) fewer points per tile is refused


class _Progress:
    """A tqdm bar on a terminal, log lines otherwise (nothing when disabled)."""

    def __init__(self, total: int, enabled: bool, log):
        self.total, self.enabled, self.log, self.count = total, enabled, log, 0
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm
            self.bar = tqdm(total=total, unit="tile", file=sys.stderr, leave=False)

    def step(self, tile: Tile, result: TileResult):
        self.count += 1
        if self.bar is not None:
            self.bar.update(1)
        elif self.enabled:
            self.log.info("tile %d/%d (%d, %d): %d points read, %d core, %.2f s on %s", self.count,
                          self.total, tile.col, tile.row, result.points_read, result.points_core,
                          result.seconds, result.worker)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _stages_over_tiles(results: dict) -> list:
    """Each stage's points in / out and seconds summed over the tiles (the untiled summary's
    'stages'; a tile's counts include its buffer points, so the sums count those twice)."""
    out = []
    for result in results.values():
        for i, row in enumerate(result.stages):
            if i == len(out):
                out.append({"stage": row["stage"], "index": i + 1, "points_in": 0, "points_out": 0, "seconds": 0.0,
                            "note": "summed over the tiles, buffer points included"})
            for key in ("points_in", "points_out", "seconds"):
                out[i][key] += row[key]
    for row in out:
        row["seconds"] = round(row["seconds"], 4)
    return out


def _backend_name(cfg, executor: str) -> str:
    """The arch the tiles ran on: this process's for in-process tiles; workers start their own
    (CPU unless the config names a backend)."""
    if executor == "in-process":
        from roadx_ti.backend import current_arch
        return current_arch() or cfg.backend
    return "cpu" if cfg.backend == "auto" else cfg.backend


def memory_tile_size(cfg, files, survey: dict, buffer: float, workers, scheduler) -> float:
    """The default core tile edge (m): the largest whose window fits the memory each tile may use
    (the run's budget, roadx_ti.memory with its TILE_OVERHEAD, shared by the local workers; at most
    MAX_WINDOW_POINTS) where the survey is densest: the larger of its density over its occupied
    area and the densest file's over its header box (a box stretched by strays only underrates
    it; a survey of dense and sparse files must not size tiles by the mean). An existing cluster's
    workers have memory this process cannot see: cores of about TARGET_TILE_POINTS there."""
    if scheduler:
        return default_tile_size(files)
    density, window = memory_window(cfg, files, survey, workers)
    if not density > 0:
        return default_tile_size(files)
    return budget_tile_size(density, buffer, window)


def memory_window(cfg, files, survey: dict, workers) -> tuple[float, int]:
    """(density per m2 where the survey is densest, points a tile's window may hold within the
    memory each tile may use): memory_tile_size's two figures."""
    from roadx_ti import memory

    boxes = [f.count / ((f.bounds[2] - f.bounds[0]) * (f.bounds[3] - f.bounds[1])) for f in files
             if f.count and f.bounds[2] > f.bounds[0] and f.bounds[3] > f.bounds[1]]
    density = max([survey.get("density_per_m2") or 0.0] + boxes)
    if not density > 0:
        return 0.0, MAX_WINDOW_POINTS
    # the densest tiles hold the most points per window and keep the smallest share of them:
    # their estimate (points x bytes at that share) is the largest of the survey's
    kept = memory.kept_share(cfg, 0, density)
    budget = memory.run_budget() / max(1, int(workers or 1))
    return density, min(MAX_WINDOW_POINTS,
                        int(memory.points_that_fit(cfg.pipeline, int(budget), kept) / memory.TILE_OVERHEAD))


# points a tile's window must hold at least for a tiled run to be worth starting
MIN_WINDOW_POINTS = 10_000


def _check_memory_limit(cfg, workers) -> None:
    """A memory limit (--memory-limit) too small for one tile's process: one line before any work
    (each tile failed in its cloth stage with 'more than the 1 particles allowed')."""
    from roadx_ti import memory

    if not os.environ.get(memory.LIMIT_VARIABLE):
        return
    budget = memory.run_budget() / max(1, int(workers or 1))
    if memory.points_that_fit(cfg.pipeline, int(budget)) / memory.TILE_OVERHEAD < MIN_WINDOW_POINTS:
        least = memory.estimate(cfg.pipeline, int(MIN_WINDOW_POINTS * memory.TILE_OVERHEAD)) * memory.SAFETY
        per = f" per worker ({workers})" if workers else ""
        raise ValueError(f"--memory-limit {memory.format_size(memory.run_budget())}: a tile's process needs at "
                         f"least about {memory.format_size(least * max(1, int(workers or 1)))} (its fixed cost and "
                         f"{MIN_WINDOW_POINTS:,} points{per}); give more")


def _per_file_name(path, log) -> str:
    """The per-file output's name: the input's, but a COPC input's is X.laz (its output is a plain
    LAZ in tile order; named X.copc.laz, PDAL and QGIS would take it for COPC)."""
    name = Path(path).name
    if name.lower().endswith(".copc.laz"):
        plain = name[:-len(".copc.laz")] + ".laz"
        log.warning("%s: its per-file output is %s, a plain LAZ (tiled runs write no COPC yet; convert it, "
                    "e.g. pdal translate %s %s)", path, plain, plain, name)
        return plain
    return name


def run_catalog(cfg, input_paths, output_path, *, workers: int | None = None, scheduler: str | None = None,
                tile_size: float | None = None, buffer: float | None = None, output_mode: str = "merged",
                progress: bool = True, log=None, summary_path=None, split_dir=None) -> dict:
    """Run ``cfg``'s pipeline over a catalog of files in tiles with buffers and write the result.

    input_paths: files and/or folders (catalog order = input order). output_path: the merged
    LAS/LAZ (output_mode 'merged'), or a folder receiving one file per input under the input's
    name ('per-file'). workers: start a local Dask cluster of that many processes; scheduler:
    'tcp://HOST:PORT' of an existing one; neither: tiles run one by one in this process.
    tile_size (m): core tile edge (None: as large as memory allows, memory_tile_size; inf: untiled);
    buffer (m): None derives it from the stages' reach (stage_reach). The summary (returned and
    written to summary_path, default '<output stem>.summary.json' or '<folder>/summary.json')
    holds the plan, per-tile timings and counts. split_dir: where the inputs' per-tile records go
    for the run (split.py; default beside the output). Raises TileError (nothing written) when a tile
    fails after its retries."""
    from roadx_ti import __version__, io, jsonio
    from roadx_ti.config import PIPELINE_TARGET

    log = log or log_default
    t_start = time.perf_counter()
    if output_mode not in MODES:
        raise ValueError(f"output mode must be one of {', '.join(MODES)}, got {output_mode!r}")
    if workers is not None and scheduler:
        raise ValueError("give workers (a local cluster) or scheduler (an existing one), not both")
    if workers is not None and int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    _check_memory_limit(cfg, workers)
    files = catalog(input_paths)
    check_compatible(files, merged_las=output_mode == "merged" and Path(output_path).suffix.lower() in (".las", ".laz"),
                     log=log)
    total_points = sum(f.count for f in files)
    if total_points == 0:
        raise io.InputError(f"the inputs hold no points: {', '.join(f.path for f in files)}")
    stage_specs = cfg.pipeline_stages()
    auto_buffer, reaches = default_buffer(stage_specs)
    if buffer is not None and float(buffer) < auto_buffer and (tile_size is None or math.isfinite(float(tile_size))):
        widest = max(reaches, key=reaches.get)
        log.warning("buffer %g m is less than the stages' reach (%g m, %s): labels near the tiles' borders may "
                    "differ from an untiled run's", float(buffer), auto_buffer, widest)
    buffer = auto_buffer if buffer is None else float(buffer)
    plan = None
    if tile_size is not None:      # checked before the estimates' pass over the files
        tile_size = float(tile_size)
        try:
            plan = plan_tiles(files, tile_size, buffer, scan=scan_cells,
                              max_tiles=max(64, total_points // MIN_POINTS_PER_TILE))
        except TooManyTiles as exc:
            tiles = f"{exc.tiles:,}" if exc.tiles < 10**9 else f"about 10^{len(str(int(exc.tiles))) - 1}"
            raise ValueError(f"--tile-size {tile_size:g} gives {tiles} tiles for {total_points:,} points, "
                             f"fewer than {MIN_POINTS_PER_TILE} per tile (each tile reads its files): use a larger "
                             f"tile size, e.g. {default_tile_size(files):g} m") from None

    inputs = [f.path for f in files]
    if output_mode == "merged":
        out = Path(output_path)
        out.parent.mkdir(parents=True, exist_ok=True)
        io.check_output_path(out, inputs)
        outputs = [(out, list(range(len(files))))]
        scratch = out.parent
        summary_path = Path(summary_path or out.with_suffix("").as_posix() + ".summary.json")
    else:
        folder = Path(output_path)
        folder.mkdir(parents=True, exist_ok=True)
        names = [_per_file_name(f.path, log) for f in files]
        if len(set(names)) != len(names):
            raise io.InputError("per-file output needs distinct input file names; "
                                f"{len(names) - len(set(names))} repeat")
        outputs = [(folder / name, [k]) for k, name in enumerate(names)]
        for o, _ in outputs:
            io.check_output_path(o, inputs)
        scratch = folder
        summary_path = Path(summary_path or folder / "summary.json")

    from roadx_ti.estimates import measure_catalog

    dtm_path = dtm_output(cfg, output_path, output_mode)
    if dtm_path is not None and not all(getattr(options, "align_to_world", True) for _, options in stage_specs):
        log.warning("output.dtm: a ground stage has align_to_world false, so the tiles' cloths lie on "
                    "lattices of their own and make no mosaic; no DTM written (run untiled for one)")
        dtm_path = None
    t_est = time.perf_counter()
    if not backend_ready():
        from roadx_ti import backend
        backend.init(cfg.backend, threads=cfg.threads)
    survey, cells = measure_catalog(files, catalog_origin(files), with_cells=True)
    estimate_s = time.perf_counter() - t_est
    log.info("survey estimates (%d sampled points) in %.2f s: %s", survey.get("sample_points", 0), estimate_s,
             {k: v for k, v in survey.items() if k not in ("sample_points",)})
    if plan is None:
        tile_size = memory_tile_size(cfg, files, survey, buffer, workers, scheduler)
        anchor = (0.0, 0.0)
        if not scheduler:
            # sized and placed by where the points are, within the same memory per window
            tile_size, anchor = align_tiles(cells, tile_size, buffer, memory_window(cfg, files, survey, workers)[1])
        plan = plan_tiles(files, tile_size, buffer, scan=scan_cells, anchor=anchor)
    del cells
    log.info("%d file(s), %d points; %d tile(s) of %s m with a %.1f m buffer", len(files), total_points,
             len(plan.tiles), "all" if not np.isfinite(plan.tile_size) else f"{plan.tile_size:g}", plan.buffer)
    results: dict[int, TileResult] = {}
    bar = _Progress(len(plan.tiles), progress, log)

    def on_done(result: TileResult):
        results[result.index] = result
        bar.step(plan.tiles[result.index], result)
    # each file several tiles read is decoded once, here; not for an existing cluster, whose
    # workers may not see this machine's disk
    split = split_catalog(plan, files, split_dir or scratch, log=log) if not scheduler else Split(folder=None)
    t_tiles = time.perf_counter()
    session = None
    try:
        if workers is None and not scheduler:
            executor, n_workers = "in-process", 1
            jobs = make_jobs(plan, files, stage_specs, backend=cfg.backend, threads=cfg.threads, seed=cfg.seed,
                             survey_estimates=survey, split=split, dtm=dtm_path is not None)
            once = FirstOfEachWarning()
            stage_log = logging.getLogger("roadx_ti")     # the stages' log (StageContext)
            stage_log.addFilter(once)
            try:
                run_in_process(jobs, on_done)
            finally:
                stage_log.removeFilter(once)
        else:
            session = _DaskSession(workers, scheduler, log, inputs=[os.path.abspath(f.path) for f in files],
                                   connect_timeout=cfg.executor.connect_timeout,
                                   worker_timeout=cfg.executor.worker_timeout)
            executor, n_workers = session.kind, session.workers
            # one Taichi runtime per worker process; CPU unless the config names a backend
            threads = cfg.threads or (max(1, (os.cpu_count() or 1) // int(workers)) if workers else None)
            jobs = make_jobs(plan, files, stage_specs, backend="cpu" if cfg.backend == "auto" else cfg.backend,
                             threads=threads, seed=cfg.seed, survey_estimates=survey, split=split,
                             dtm=dtm_path is not None)
            run_on_dask(session.client, jobs, on_done, in_flight=2 * n_workers)
    finally:
        split.remove()          # first: the scratch records must not outlive the run
        bar.close()
        if session is not None:
            session.close()
    tiles_s = time.perf_counter() - t_tiles

    t_merge = time.perf_counter()
    segments = reconcile_segments(plan, results)
    target = PIPELINE_TARGET[cfg.pipeline]
    from roadx_ti.stages import stage_class
    extra_names = [key for name, _ in cfg.pipeline_stages() for key in stage_class(name).writes]
    written, merge = write_outputs(plan, results, files, outputs, processed_only=cfg.output.points == "processed",
                                   truth_classes=cfg.truth_classes, target=target, extra_names=extra_names)
    dtm_summary = _write_dtm(dtm_path, results, files, cfg, log) if dtm_path is not None else None
    merge_s = time.perf_counter() - t_merge

    summary = {
        "roadx_ti": __version__, "pipeline": cfg.pipeline, "executor": executor, "workers": n_workers,
        "scheduler": scheduler, "output_mode": output_mode,
        "inputs": [{"path": f.path, "points": f.count, "bounds": list(f.bounds)} for f in files],
        "outputs": [str(o) for o, _ in outputs], "points": total_points, "points_written": written,
        "tiling": plan.describe() | {"buffer_from_stages": reaches},
        "backend": _backend_name(cfg, executor),
        DECIDED_BY: {"0": "reached the last stage"} | {str(i): f"removed by {name}"
                                                       for i, (name, _) in enumerate(cfg.pipeline_stages(), 1)},
        "estimates": survey,
        "stages": _stages_over_tiles(results),
        "split": split.describe(),
        "segments": segments,
        "target_class": target, "target_points": int(merge.class_counts[target]),
        "class_counts": {str(c): int(v) for c, v in enumerate(merge.class_counts) if v},
        "seconds": {"estimates": round(estimate_s, 4), "split": round(split.seconds, 4), "tiles": round(tiles_s, 4), "merge": round(merge_s, 4),
                    "total": round(time.perf_counter() - t_start, 4),
                    "tile_sum": round(sum(r.seconds for r in results.values()), 4)},
        "tiles": [{"tile": [t.col, t.row], "core": list(t.core), "window": list(t.window),
                   "files": [Path(files[k].path).name for k in t.files],
                   "points_read": results[t.index].points_read, "points_core": results[t.index].points_core,
                   "read_seconds": round(results[t.index].read_seconds, 4),
                   "pipeline_seconds": round(results[t.index].pipeline_seconds, 4),
                   "seconds": round(results[t.index].seconds, 4), "worker": results[t.index].worker}
                  for t in plan.tiles],
    }
    truth = np.concatenate(merge.truth) if merge.truth else None
    if truth is not None and truth.any():
        from roadx_ti.metrics import scores
        summary["truth_classes"] = cfg.truth_classes
        summary["accuracy"] = scores(truth, np.concatenate(merge.pred))
    elif truth is not None:
        from roadx_ti.metrics import no_truth_line
        log.info(no_truth_line(cfg.truth_classes))
    if dtm_summary is not None:
        summary["dtm"] = dtm_summary
    summary["summary_path"] = str(summary_path)
    jsonio.write(summary_path, summary)
    log.info("wrote %s (%d points, %d tiles, %s) in %.2f s", ", ".join(summary["outputs"][:3])
             + (" ..." if len(outputs) > 3 else ""), written, len(plan.tiles), executor,
             time.perf_counter() - t_start)
    return summary


def dtm_output(cfg, output_path, output_mode: str) -> Path | None:
    """Where a tiled run's DTM goes: output.dtm's path when it names one, else (output.dtm true, or
    unset in the ground pipeline) STEM.dtm.tif beside a merged output or dtm.tif in a per-file
    output's folder; None when no DTM is asked for."""
    path = cfg.dtm_path()
    if path is None or isinstance(cfg.output.dtm, str):
        return path
    if output_mode == "per-file":
        return Path(output_path) / "dtm.tif"
    from roadx_ti.config import output_stem
    return Path(f"{output_stem(output_path)}.dtm.tif")


def _write_dtm(path: Path, results: dict, files, cfg, log) -> dict | None:
    """The ground surface of a tiled run as one DTM raster: the mosaic of the tiles' core cells
    (their cloths share one world lattice), over the occupied space, with the first LAS/LAZ
    input's CRS. None (and a warning) when no tile ran a ground stage."""
    from roadx_ti import dtm
    from roadx_ti.io.crs import of_path

    pieces = [r.dtm for _, r in sorted(results.items()) if r.dtm is not None]
    if not pieces:
        if cfg.output.dtm is not None:
            log.warning("output.dtm: no ground stage ran, so there is no DTM to write")
        return None
    las = (f.path for f in files if Path(f.path).suffix.lower() in LAS_SUFFIXES)
    crs = next((c for c in map(of_path, las) if c is not None), None)
    heights, t, left_out = dtm.mosaic(pieces)
    if left_out:
        log.warning("output.dtm: %d tile(s) hold points more than 100 m from the largest part of the survey; "
                    "the DTM covers the largest part (a raster over all would be sized by the gaps)", left_out)
    t = dtm.write_grid(path, heights, t, crs)
    log.info("wrote DTM %s: %d x %d cells of %g m over the occupied area (%d with data), the mosaic of %d "
             "tiles' cloths", path, t["cols"], t["rows"], t["cell_size"], t["valid_cells"], len(pieces) - left_out)
    return dtm.summary(path, t, crs) | {"tiles": len(pieces) - left_out}
