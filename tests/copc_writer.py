"""Test fixture: write a LAS/LAZ file's points as a COPC file (copclib), so that reading COPC
(laspy's CopcReader, in roadx_ti.io) is tested on files from an independent writer.

The octree has two levels: every 8th point in the root node, the rest in the eight depth-1
octants, so a window query decompresses the root plus the octants it meets, not the whole file.
"""
from __future__ import annotations

import laspy
import numpy as np
import pytest


def write_copc(src_path, dst_path) -> None:
    copc = pytest.importorskip("copclib", reason="copclib writes the COPC fixtures")
    src = laspy.read(src_path)
    h = src.header
    if h.point_format.id not in (6, 7, 8):
        raise ValueError(f"COPC holds point formats 6-8, {src_path} has {h.point_format.id}")
    cfg = copc.CopcConfigWriter(h.point_format.id, copc.Vector3(*h.scales), copc.Vector3(*h.offsets))
    cfg.las_header.min = copc.Vector3(*h.mins)
    cfg.las_header.max = copc.Vector3(*h.maxs)
    center = (np.asarray(h.mins) + np.asarray(h.maxs)) / 2
    info = cfg.copc_info
    info.center_x, info.center_y, info.center_z = (float(c) for c in center)
    info.halfsize = float((np.asarray(h.maxs) - np.asarray(h.mins)).max() / 2) + 1.0
    info.spacing = info.halfsize / 32
    writer = copc.FileWriter(str(dst_path), cfg)
    x, y, z = np.asarray(src.x), np.asarray(src.y), np.asarray(src.z)
    records = src.points.array
    in_root = np.arange(len(records)) % 8 == 0
    octant = (x >= center[0]).astype(int) + 2 * (y >= center[1]) + 4 * (z >= center[2])

    def add(key, mask):
        if mask.any():
            writer.AddNode(key, copc.VectorChar(np.frombuffer(records[mask].tobytes(), np.int8)))

    add(copc.VoxelKey(0, 0, 0, 0), in_root)
    for o in range(8):
        add(copc.VoxelKey(1, o & 1, (o >> 1) & 1, (o >> 2) & 1), ~in_root & (octant == o))
    writer.Close()
