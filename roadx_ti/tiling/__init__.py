"""Scale-out: multi-file catalogs, a fixed grid of core tiles with buffers, executors (in-process or
dask.distributed) and the merge back into one output.

The parts: ``catalogs`` (the input files), ``reach`` (the default buffer, from each Stage.reach), ``plan`` (the core grid and
its tiles), ``tile`` (one tile on a worker), ``executors`` (in-process, Dask) with ``cluster`` (the
Dask session and its checks), ``split`` (each file decoded once into the tiles' windows), ``merge``
(segment reconciliation, writing the outputs), ``run``
(``run_catalog``: the whole run), ``compare`` (tiled against untiled), ``errors``.

    summary = run_catalog(cfg, ["tiles/"], "out/all.laz", workers=4)          # local Dask cluster
    summary = run_catalog(cfg, paths, "out/", output_mode="per-file", scheduler="tcp://host:8786")

How a run goes:
1. ``catalog``: the input files (a folder gives its point-cloud files sorted by name) with their
   header bounds; input order = catalog order, each file's points in file order.
2. ``plan_tiles``: core tiles on a grid anchored at multiples of a given ``--tile-size``; by
   default as large as the memory allows and placed where the points are (``align_tiles``: the
   size and grid offset that read the fewest window points, from the survey estimates' points per
   occupied cell); a tile exists where some file's header box meets its core. Each tile reads core + ``buffer`` on every side,
   only from the files whose box meets that window (io.read(path, bounds=window, origin=shared)).
   A LAS/LAZ file that several tiles read is decoded once beforehand (``split_catalog``), its
   records kept per tile in a scratch folder beside the output; a tile reads them back
   (io.read_part: the same Cloud as the windowed read). Not with an existing cluster's workers.
3. ``run_tile`` (on any executor) runs the whole pipeline on the window and keeps the labels of its
   core points only. Cores are half-open [x0, x1) x [y0, y1), so every point has exactly one core.
   A point's core is found by ``CoreGrid.cells`` everywhere (workers and merge), so all parts of
   the run agree on it bit for bit. Only occupied cores are tiles: a file whose header box spans
   many cores is scanned for the cores its points occupy, and nothing is allocated per grid cell.
4. Segments cut by a core border are reconciled: a tile returns, per neighbour, the segment ids of
   its buffer points that are the neighbour's core points, and the ids of its core points inside
   the neighbour's window; both lists hold the same points in the same (catalog, file) order, so
   pairing them links (tile, segment) nodes, and a union-find gives one global id per component.
5. The merge streams every input file again in chunks and takes each point's labels from its core
   tile in order (the k-th point of file f in core t is the k-th core point of f that t returned).
   Nothing is written until every tile has succeeded; outputs are written atomically.
"""
from __future__ import annotations

from roadx_ti.tiling.catalogs import LAS_SUFFIXES, CatalogFile, catalog, folder_files
from roadx_ti.tiling.cluster import CONNECT_TIMEOUT, ENVIRONMENT_PACKAGES, WORKER_TIMEOUT, environment, unreadable
from roadx_ti.tiling.compare import DISTANCE_BINS, compare_outputs, segment_agreement
from roadx_ti.tiling.errors import ClusterError, TileError
from roadx_ti.tiling.executors import RETRIES, backend_ready, make_jobs, run_in_process, run_on_dask
from roadx_ti.tiling.merge import MERGE_CHUNK_POINTS, reconcile_segments, write_outputs
from roadx_ti.tiling.plan import (MAX_HEADER_CELLS, MAX_LISTED_EDGES, MAX_WINDOW_POINTS, SCAN_CELLS, TARGET_TILE_POINTS,
                                  TILE_SIZE_STEP, align_tiles, budget_tile_size, catalog_origin,
                                  CoreGrid, Tile, TilePlan, default_tile_size, plan_tiles, scan_cells, tile_lookup)
from roadx_ti.tiling.reach import CLOTH_SPAN, MIN_BUFFER, default_buffer, stage_reach
from roadx_ti.tiling.run import MIN_POINTS_PER_TILE, MODES, run_catalog
from roadx_ti.tiling.split import Split, split_catalog
from roadx_ti.tiling.tile import MMAP_THRESHOLD, FilePart, TileJob, TileResult, concat_clouds, run_tile

__all__ = ["CLOTH_SPAN", "CONNECT_TIMEOUT", "DISTANCE_BINS", "ENVIRONMENT_PACKAGES", "LAS_SUFFIXES", "MAX_HEADER_CELLS",
           "MAX_LISTED_EDGES", "MAX_WINDOW_POINTS", "MERGE_CHUNK_POINTS", "MIN_BUFFER", "MIN_POINTS_PER_TILE", "MMAP_THRESHOLD", "MODES",
           "RETRIES", "SCAN_CELLS", "Split", "TARGET_TILE_POINTS", "TILE_SIZE_STEP", "WORKER_TIMEOUT",
           "CatalogFile", "ClusterError", "CoreGrid", "FilePart", "Tile", "TileError", "TileJob", "TilePlan",
           "TileResult", "align_tiles", "backend_ready", "budget_tile_size", "catalog", "catalog_origin", "compare_outputs", "concat_clouds", "default_buffer",
           "default_tile_size", "environment", "folder_files", "make_jobs", "plan_tiles", "reconcile_segments",
           "run_catalog", "run_in_process", "run_on_dask", "run_tile", "scan_cells", "segment_agreement",
           "split_catalog", "stage_reach", "tile_lookup", "unreadable", "write_outputs"]
