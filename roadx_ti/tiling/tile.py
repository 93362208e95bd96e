"""One tile, in any process: read its window, run the pipeline, keep the labels of its core points
and the segment ids its neighbours need for the reconciliation."""
from __future__ import annotations

import ctypes
import math
import os
import socket
import time
from dataclasses import dataclass, field

import numpy as np

from roadx_ti.cloud import Cloud, stored_8bit_scale
from roadx_ti.stages.base import ESTIMATES, GROUND_SURFACE, SURVEY_POINTS, SURVEY_Z_MIN
from roadx_ti.tiling.plan import CoreGrid, Tile
from roadx_ti.tiling.split import read_part


@dataclass
class TileJob:
    """Everything a worker needs (picklable; files are read by the worker from their paths)."""
    tile: Tile
    paths: dict            # catalog index -> path, for the tile's files
    grid: CoreGrid         # the plan's core cells
    neighbour_cells: dict  # neighbour tile index -> (col, row) of its core
    windows: dict          # neighbour tile index -> its window
    read_origin: np.ndarray
    stage_specs: list
    backend: str
    threads: int | None
    seed: int
    survey_z_min: float = math.inf   # world: the lowest header z of the catalog (cloth start)
    survey_points: int = 0           # points of the catalog (a tile of a stray point sees it isolated)
    survey_estimates: dict | None = None   # roadx_ti.estimates of the whole catalog, for 'auto' options
    parts: dict = field(default_factory=dict)  # catalog index -> split.Part (None: no points here) of split files
    dtm: bool = False                # keep the ground surface's cells in the core (output.dtm)


@dataclass
class FilePart:
    """Labels of one file's core points in one tile, in file order."""
    classification: np.ndarray
    decided_by: np.ndarray
    segment_id: np.ndarray    # local to the tile
    processed: np.ndarray
    extra: dict = field(default_factory=dict)   # the stages' point outputs (Stage.writes): name -> float32


@dataclass
class TileResult:
    index: int
    parts: dict               # catalog index -> FilePart
    segments: int             # local segment ids are 0..segments-1
    buffer_in: dict = field(default_factory=dict)   # neighbour -> seg ids of my buffer points in its core
    core_in: dict = field(default_factory=dict)     # neighbour -> seg ids of my core points in its window
    points_read: int = 0
    points_core: int = 0
    read_seconds: float = 0.0
    pipeline_seconds: float = 0.0
    seconds: float = 0.0
    worker: str = ""
    dtm: tuple | None = None  # (float32 heights, transform) of the ground surface's core cells (roadx_ti.dtm)
    stages: list = field(default_factory=list)


def _world_xy(cloud: Cloud) -> tuple[np.ndarray, np.ndarray]:
    """float64 x, y exactly as io.read's bounds test saw them."""
    if cloud.las is not None:
        return np.asarray(cloud.las.x, np.float64), np.asarray(cloud.las.y, np.float64)
    return (cloud.xyz[:, 0].astype(np.float64) + cloud.origin[0],
            cloud.xyz[:, 1].astype(np.float64) + cloud.origin[1])


def concat_clouds(clouds: list[Cloud], origin: np.ndarray) -> Cloud:
    """One processing cloud from several files' windows (same origin); colour only when all have it."""
    if len(clouds) == 1:
        return clouds[0]
    rgb = None
    if all(c.rgb is not None for c in clouds):
        deep = max(c.color_depth for c in clouds)
        # 8-bit files beside 16-bit ones take the 16-bit files' own scale (cloud.stored_8bit_scale:
        # x 256 or x 257), so that the window reads each file's colour as it alone would
        wide = [c.rgb for c in clouds if c.color_depth == 16]
        scale = stored_8bit_scale(np.concatenate(wide)) if wide and deep == 16 else 1
        rgb = np.concatenate([c.rgb.astype(np.uint16) * np.uint16(scale if c.color_depth == 8 else 1)
                              for c in clouds])
    pick = lambda name: (np.concatenate([getattr(c, name) for c in clouds])  # noqa: E731
                         if all(getattr(c, name) is not None for c in clouds) else None)
    return Cloud(xyz=np.concatenate([c.xyz for c in clouds]), origin=origin, rgb=rgb,
                 color_depth=max(c.color_depth for c in clouds) if rgb is not None else 0,
                 intensity=pick("intensity"), classification=pick("classification"),
                 returns=pick("returns"), nir=pick("nir"), source="+".join(c.source for c in clouds))


def _inside(x, y, box) -> np.ndarray:
    return (x >= box[0]) & (x < box[2]) & (y >= box[1]) & (y < box[3])


_M_MMAP_THRESHOLD = -3           # glibc mallopt parameter
MMAP_THRESHOLD = 64 * 1024       # bytes: larger blocks are mmapped, and unmapped when freed


def _large_buffers_back_to_os() -> None:
    """Serve blocks above MMAP_THRESHOLD from mmap, so that a tile's large arrays go back to the OS
    when the tile ends. glibc's adaptive threshold otherwise grows past the sizes freed, keeps
    later ones in the heap, and the next tiles fragment it: on the 16 M benchmark (2 M-point
    tiles) the peak RSS went from 675 to about 520 MB, the untiled run's stayed 1745 MB. glibc only;
    process-wide (also for a host program that runs tiles in-process), harmless elsewhere."""
    try:
        ctypes.CDLL(None).mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    except (OSError, AttributeError):
        pass


def run_tile(job: TileJob) -> TileResult:
    """Read the tile's window from its files, run the pipeline, keep the core points' labels.
    Runs in any process: Taichi is started once per process (backend.init is idempotent)."""
    from roadx_ti import backend, io, pipelines
    from roadx_ti.stages.base import StageContext

    _large_buffers_back_to_os()
    t_start = time.perf_counter()
    tile = job.tile
    pieces, xs, ys, owners = [], [], [], []
    for k in tile.files:
        if k in job.parts:      # decoded once for all tiles (split.py)
            if job.parts[k] is None:
                continue
            piece = read_part(job.paths[k], job.parts[k], job.read_origin)
        else:
            piece = io.read(job.paths[k], bounds=tile.window, origin=job.read_origin)
        if piece.n:
            x, y = _world_xy(piece)
            piece.las = None           # the record is not needed for processing; free it
            pieces.append(piece)
            xs.append(x)
            ys.append(y)
            owners.append(k)
    read_s = time.perf_counter() - t_start
    result = TileResult(index=tile.index, parts={}, segments=0, read_seconds=read_s,
                        worker=f"{socket.gethostname()}:{os.getpid()}")
    if not pieces:
        result.seconds = time.perf_counter() - t_start
        return result
    counts = [p.n for p in pieces]
    cloud = concat_clouds(pieces, job.read_origin)
    x, y = np.concatenate(xs), np.concatenate(ys)
    del pieces, xs, ys
    if not backend.is_initialized():
        backend.init(job.backend, threads=job.threads)
    t0 = time.perf_counter()
    ctx = StageContext(seed=job.seed)
    if math.isfinite(job.survey_z_min):
        # the cloth of every tile starts where the whole survey's would (stages/cloth.py)
        ctx.facts[SURVEY_Z_MIN] = job.survey_z_min - float(job.read_origin[2])
    ctx.facts[SURVEY_POINTS] = job.survey_points
    if job.survey_estimates is not None:
        ctx.facts[ESTIMATES] = dict(job.survey_estimates)   # every tile the survey's values
    with backend.collect_in_this_thread():     # a Dask worker's task thread on a GPU
        labels = pipelines.run(cloud, pipelines.build_stages(job.stage_specs), ctx=ctx)
    surface = ctx.facts.get(GROUND_SURFACE) if job.dtm else None
    if surface is not None:
        # the cloth's cells whose centres lie in this tile's core (the tiles' cloths share one
        # world lattice): the survey's DTM is their mosaic (tiling/run.py)
        from roadx_ti import dtm
        xy = np.column_stack([x - float(job.read_origin[0]), y - float(job.read_origin[1])])
        result.dtm = dtm.core_piece(surface.largest, surface.origin, xy, tile.core)
        del xy
    result.pipeline_seconds = time.perf_counter() - t0
    result.stages = [{k: r[k] for k in ("stage", "points_in", "points_out", "seconds")} for r in labels.stages]
    n = cloud.n
    del cloud
    col, row = job.grid.cells(x, y)
    core = (col == tile.col) & (row == tile.row)
    sizes = np.cumsum([0] + counts)
    for k, lo, hi in zip(owners, sizes[:-1], sizes[1:]):
        keep = np.flatnonzero(core[lo:hi]) + lo
        result.parts[k] = FilePart(labels.classification[keep], labels.decided_by[keep],
                                   labels.segment_id[keep], labels.processed[keep],
                                   {name: values[keep] for name, values in labels.extra_dims.items()})
    result.points_read = int(n)
    result.points_core = int(core.sum())
    seg = labels.segment_id
    result.segments = int(seg.max()) + 1 if n else 0
    if result.segments:
        # points of the buffer that are a neighbour's core points, and my core points in its
        # window: the neighbour holds the same two sets, in the same order, from its side
        for u in tile.neighbours:
            u_col, u_row = job.neighbour_cells[u]
            result.buffer_in[u] = seg[(col == u_col) & (row == u_row)]
            result.core_in[u] = seg[core & _inside(x, y, job.windows[u])]
    result.seconds = time.perf_counter() - t_start
    return result
