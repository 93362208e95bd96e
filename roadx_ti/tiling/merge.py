"""After the tiles: segments cut by core borders get one id, then every input file is streamed again
and each point takes its labels from its core tile, in file order."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from roadx_ti.result_dims import DECIDED_BY, SEGMENT, result_dims
from roadx_ti.tiling.catalogs import CatalogFile
from roadx_ti.tiling.errors import TileError
from roadx_ti.tiling.plan import TilePlan
from roadx_ti.tiling.tile import _world_xy, concat_clouds

MERGE_CHUNK_POINTS = 1_000_000


def reconcile_segments(plan: TilePlan, results: dict) -> dict:
    """Give segments cut by core borders one id: connected components over (tile, local segment)
    nodes that share a point (labelled in both tiles), then compact global ids in order of first
    appearance, tiles in order and each tile's segments ascending. Rewrites the parts' segment ids
    in place; returns counts for the summary."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    base, total = {}, 0
    for t in range(len(plan.tiles)):
        base[t] = total
        total += results[t].segments
    ends_a, ends_b = [], []
    for t, res in results.items():
        for u, mine in res.buffer_in.items():
            other = results[u].core_in.get(t)
            if other is None:       # the neighbour found no segments at all
                continue
            if len(other) != len(mine):
                raise TileError(f"tiles {t} and {u} disagree on the points they share "
                                f"({len(mine)} vs {len(other)}); no output was written")
            both = (mine >= 0) & (other >= 0)
            pairs = np.unique(np.column_stack([base[t] + mine[both].astype(np.int64),
                                               base[u] + other[both].astype(np.int64)]), axis=0)
            ends_a.append(pairs[:, 0])
            ends_b.append(pairs[:, 1])
    a = np.concatenate(ends_a) if ends_a else np.zeros(0, np.int64)
    b = np.concatenate(ends_b) if ends_b else np.zeros(0, np.int64)
    components, component = connected_components(
        coo_matrix((np.ones(len(a), np.int8), (a, b)), shape=(total, total)), directed=False)
    # the segments in use, in tile order: a component's global id is its rank of first appearance
    used_nodes, used_of = [], {}
    for t in range(len(plan.tiles)):
        res = results[t]
        if not res.segments:
            continue
        used = np.unique(np.concatenate([p.segment_id for p in res.parts.values()] or [np.zeros(0, np.int32)]))
        used_of[t] = used[used >= 0].astype(np.int64)
        used_nodes.append(base[t] + used_of[t])
    nodes = np.concatenate(used_nodes) if used_nodes else np.zeros(0, np.int64)
    first_of, first = np.unique(component[nodes], return_index=True)
    rank = np.empty(components, np.int64)
    rank[first_of[np.argsort(first, kind="stable")]] = np.arange(len(first_of))
    for t, used in used_of.items():
        res = results[t]
        local_to_global = np.full(res.segments, -1, np.int32)
        local_to_global[used] = rank[component[base[t] + used]]
        for part in res.parts.values():
            seg = part.segment_id
            part.segment_id = np.where(seg >= 0, local_to_global[np.maximum(seg, 0)], -1).astype(np.int32)
        res.buffer_in, res.core_in = {}, {}
    for res in results.values():
        res.buffer_in, res.core_in = {}, {}
    return {"local_segments": total, "merges": int(total - components), "segments": int(len(first_of))}


class _Merge:
    """Hands out each input point's labels from its core tile, in file order, and keeps counts."""

    def __init__(self, plan: TilePlan, results: dict, files: list[CatalogFile], truth_classes, target: int,
                 extra_names=()):
        self.plan, self.results, self.files = plan, results, files
        self.extra_names = tuple(extra_names)     # the stages' point outputs (Stage.writes)
        self.cursor = {}
        self.truth_classes, self.target = truth_classes, target
        self.class_counts = np.zeros(256, np.int64)
        self.truth, self.pred = [], []
        self.written = 0

    def labels(self, k: int, x: np.ndarray, y: np.ndarray, input_classes=None):
        n = len(x)
        tiles = self.plan.tile_index(x, y)
        if (tiles < 0).any():
            raise TileError(f"{self.files[k].path}: {int((tiles < 0).sum())} points lie outside the "
                            "header bounds, so no tile read them; fix the header (e.g. pdal translate)")
        out = (np.empty(n, np.uint8), np.empty(n, np.uint8), np.empty(n, np.int32), np.empty(n, bool))
        # NaN where a tile's pipeline did not see a point (as in an untiled run's output)
        extra = {name: np.full(n, np.nan, np.float32) for name in self.extra_names}
        order = np.argsort(tiles, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(tiles[order]) != 0])
        ends = np.r_[starts[1:], n]
        for s, e in zip(starts, ends):
            t = int(tiles[order[s]])
            part = self.results[t].parts.get(k)
            c = self.cursor.get((t, k), 0)
            if part is None or c + (e - s) > len(part.classification):
                raise TileError(f"{self.files[k].path}: tile {t} returned fewer core points than the "
                                "file holds in its core; no output was written")
            idx = order[s:e]
            for dst, src in zip(out, (part.classification, part.decided_by, part.segment_id, part.processed)):
                dst[idx] = src[c:c + e - s]
            for name, dst in extra.items():
                if name in part.extra:
                    dst[idx] = part.extra[name][c:c + e - s]
            self.cursor[(t, k)] = c + e - s
        self.class_counts += np.bincount(out[0], minlength=256)
        if input_classes is not None and self.truth_classes:
            from roadx_ti.metrics import class_mask
            self.truth.append(class_mask(input_classes, self.truth_classes))
            self.pred.append(out[0] == self.target)
        return out + (extra,)

    def check_file(self, k: int, seen: int) -> None:
        """Every point of file k was handed out exactly once and every core point returned used."""
        if seen != self.files[k].count:
            raise TileError(f"{self.files[k].path}: read {seen} points, the header says {self.files[k].count}")
        for t, res in self.results.items():
            part = res.parts.get(k)
            if part is not None and self.cursor.get((t, k), 0) != len(part.classification):
                raise TileError(f"{self.files[k].path}: tile {t} returned {len(part.classification)} core "
                                f"points, the file has {self.cursor.get((t, k), 0)} there")


def _is_las(path) -> bool:
    return Path(path).suffix.lower() in (".las", ".laz")


def _write_las_stream(out: Path, file_ids, merge: _Merge, processed_only: bool) -> int:
    """Stream the files' points (their LAS records, bit-exact but classification and the result
    dimensions) into one LAS/LAZ written atomically; returns the number of points written."""
    from roadx_ti.io import las_write as io_las

    def labels(i, chunk):
        cls, dec, seg, proc, extra = merge.labels(file_ids[i], np.asarray(chunk.x), np.asarray(chunk.y),
                                                  np.asarray(chunk.classification))
        return cls, result_dims(dec, seg, extra), proc if processed_only else None

    empty = (np.zeros(0, np.uint8), {DECIDED_BY: np.zeros(0, np.uint8), SEGMENT: np.zeros(0, np.int32),
                                     **{name: np.zeros(0, np.float32) for name in merge.extra_names}},
             np.zeros(0, bool) if processed_only else None)
    return io_las.write_las_stream(out, [merge.files[k].path for k in file_ids], labels, empty=empty,
                                   chunk_points=MERGE_CHUNK_POINTS,
                                   on_file=lambda i, seen: merge.check_file(file_ids[i], seen),
                                   mismatch_hint="; use output.mode per-file")


def _write_generic(out: Path, file_ids, merge: _Merge, processed_only: bool) -> int:
    """Any other format: whole files in memory, written with io.write."""
    from roadx_ti import io

    clouds, labels = [], []
    for k in file_ids:
        cloud = io.read(merge.files[k].path, origin=merge.plan.read_origin)
        x, y = _world_xy(cloud)
        labels.append(merge.labels(k, x, y, cloud.classification))
        merge.check_file(k, cloud.n)
        clouds.append(cloud)
    cloud = concat_clouds(clouds, merge.plan.read_origin)
    records = _records_together(clouds)
    if records is not None:
        # every LAS field as a column and the exact coordinates, as an untiled run writes them
        # (the concatenation held x, y, z as float32 offsets and the common columns only)
        cloud = replace(cloud, las=records)
    cls, dec, seg, proc = (np.concatenate(parts) for parts in zip(*(label[:4] for label in labels)))
    extra = {name: np.concatenate([label[4][name] for label in labels]) for name in merge.extra_names}
    io.write(out, cloud, classification=cls, extra_dims=result_dims(dec, seg, extra),
             subset=proc if processed_only else None)
    return int(proc.sum()) if processed_only else cloud.n


def _records_together(clouds):
    """One LasData of the clouds' LAS records, in order, when every cloud has them with one point
    format, scales and offsets (what a merged LAS output needs too); else None."""
    import copy

    import laspy

    las = [c.las for c in clouds]
    if not las or any(x is None for x in las):
        return None
    first = las[0].header
    if any(x.header.point_format != first.point_format or not np.array_equal(x.header.scales, first.scales)
           or not np.array_equal(x.header.offsets, first.offsets) for x in las[1:]):
        return None
    array = np.concatenate([x.points.array for x in las]) if len(las) > 1 else las[0].points.array
    return laspy.LasData(copy.deepcopy(first), laspy.ScaleAwarePointRecord(array, first.point_format, first.scales,
                                                                           first.offsets))


def write_outputs(plan, results, files, outputs: list[tuple[Path, list[int]]], *, processed_only: bool,
                  truth_classes, target: int, extra_names=()) -> tuple[int, _Merge]:
    """extra_names: the stages' point outputs (Stage.writes) the files carry as extra dimensions."""
    merge = _Merge(plan, results, files, truth_classes, target, extra_names)
    written = 0
    for out, file_ids in outputs:
        stream = _is_las(out) and all(_is_las(files[k].path) for k in file_ids)
        written += (_write_las_stream if stream else _write_generic)(out, file_ids, merge, processed_only)
    return written, merge
