"""Executors of the tile jobs: one after the other in this process, or on a dask.distributed
cluster (cluster.py opens and checks it)."""
from __future__ import annotations

import contextlib
import math
import os
import uuid

from roadx_ti.tiling.catalogs import CatalogFile
from roadx_ti.tiling.errors import ClusterError, TileError
from roadx_ti.tiling.plan import Tile, TilePlan
from roadx_ti.tiling.tile import TileJob, run_tile

RETRIES = 2                      # dask retries of a failed tile before the run fails


def backend_ready() -> bool:
    from roadx_ti import backend
    return backend.is_initialized()


def make_jobs(plan: TilePlan, files: list[CatalogFile], stage_specs, *, backend: str,
              threads: int | None, seed: int, survey_estimates: dict | None = None, split=None,
              dtm: bool = False) -> list[TileJob]:
    survey_z_min = min((f.z_range[0] for f in files if f.count), default=math.inf)
    return [TileJob(tile=t, paths={k: os.path.abspath(files[k].path) for k in t.files}, grid=plan.grid,
                    neighbour_cells={u: (plan.tiles[u].col, plan.tiles[u].row) for u in t.neighbours},
                    windows={u: plan.tiles[u].window for u in t.neighbours}, read_origin=plan.read_origin,
                    stage_specs=list(stage_specs), backend=backend, threads=threads, seed=seed,
                    survey_z_min=survey_z_min, survey_points=sum(f.count for f in files),
                    survey_estimates=survey_estimates,
                    parts=split.for_tile(t.index, t.files) if split is not None else {}, dtm=dtm)
            for t in plan.tiles]


def _failure(tile: Tile, exc: BaseException, attempts: int) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if len(text) > 400:          # e.g. Taichi compile errors quote whole functions
        text = text[:400] + " ..."
    core = ", ".join(f"{v:.2f}" for v in tile.core)
    return (f"tile ({tile.col}, {tile.row}) with core bounds ({core}) failed after {attempts} "
            f"attempt(s): {type(exc).__name__}: {text}; no output was written")


def run_in_process(jobs: list[TileJob], on_done) -> None:
    """Tiles one after the other in this process (no cluster)."""
    for job in jobs:
        try:
            result = run_tile(job)
        except Exception as exc:
            raise TileError(_failure(job.tile, exc, 1)) from exc
        on_done(result)


def run_on_dask(client, jobs: list[TileJob], on_done, *, in_flight: int) -> None:
    """Tiles on a dask.distributed cluster, at most ``in_flight`` submitted at once; each tile is
    retried RETRIES times (a tile on a worker that dies is rescheduled by Dask on another)."""
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    pending = iter(jobs)
    running = {}
    done = as_completed()

    def submit():
        job = next(pending, None)
        if job is not None:
            fut = client.submit(run_tile, job, retries=RETRIES, pure=False,
                                key=f"roadx-tile-{job.tile.col}-{job.tile.row}-{token}")
            running[fut] = job
            done.add(fut)

    for _ in range(max(1, in_flight)):
        submit()
    from concurrent.futures import CancelledError

    try:
        for fut in done:
            job = running.pop(fut)
            if fut.status != "finished":
                exc = fut.exception()
                raise TileError(_failure(job.tile, exc, RETRIES + 1))
            result = fut.result()
            fut.release()
            on_done(result)
            submit()
    except (OSError, TimeoutError, CancelledError) as exc:
        raise ClusterError(f"lost the Dask cluster during the run ({type(exc).__name__}: "
                           f"{' '.join(str(exc).split())[:200]}); no output was written") from None
    finally:
        if running:
            with contextlib.suppress(Exception):
                client.cancel(list(running))
