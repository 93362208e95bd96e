"""Sequential references shared by the kernel tests (the parallel kernels must equal them)."""
from collections import deque

import numpy as np


def edge_mask(neighbors, edge_ok=None, active=None):
    n, k = neighbors.shape
    rows = np.repeat(np.arange(n), k)
    cols = neighbors.reshape(-1)
    keep = cols >= 0
    if edge_ok is not None:
        keep &= edge_ok.reshape(-1) != 0
    if active is not None:
        keep &= (active[rows] != 0) & (active[np.maximum(cols, 0)] != 0)
    return rows[keep], cols[keep]


def flood_fill(neighbors, edge_ok=None, active=None):
    """Sequential breadth-first flood fill; every component is labelled by the index of the
    point it was started from, visiting points in index order (= its smallest index)."""
    n = len(neighbors)
    rows, cols = edge_mask(neighbors, edge_ok, active)
    adjacency = [[] for _ in range(n)]
    for a, b in zip(rows.tolist(), cols.tolist()):
        adjacency[a].append(b)
        adjacency[b].append(a)
    out = np.full(n, -1, np.int32)
    for seed in range(n):
        if out[seed] >= 0 or (active is not None and not active[seed]):
            continue
        out[seed] = seed
        queue = deque([seed])
        while queue:
            p = queue.popleft()
            for q in adjacency[p]:
                if out[q] < 0:
                    out[q] = seed
                    queue.append(q)
    return out
