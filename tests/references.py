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


def merge_regions_reference(n, ea, eb, up, down, colour, levels, max_chroma, veto, min_size=0, settle=0.002):
    """Plain sequential reading of kernels.regions.merge_regions_by_colour: one round at a
    time, one region at a time, the same fixed-point sums and float32 costs. Returns the point
    labels (root point index of each region)."""
    f32 = np.float32
    label = list(range(n))
    count = [1] * n
    csum = [[int(np.rint(f32(colour[i][c]) * f32(64))) for c in range(3)] for i in range(n)]
    up_q = [int(np.rint(u * 4096)) for u in up]
    down_q = [int(np.rint(d * 4096)) for d in down]

    def mean(r):
        inv = 1.0 / (float(count[r]) * 64.0)
        return [float(csum[r][c]) * inv for c in range(3)]

    schedule = [(float(v), False) for v in levels] + ([(0.0, True)] if min_size > 1 else [])
    left = n
    for level, size_pass in schedule:
        while True:
            pairs = {}
            for e in range(len(ea)):
                la, lb = label[ea[e]], label[eb[e]]
                if la != lb:
                    key = (min(la, lb), max(la, lb))
                    m, s = pairs.get(key, (0, 0))
                    pairs[key] = (m + 1, s + up_q[e] + down_q[e])
            if not pairs:
                break
            best = {}
            for (a, b), (m, s) in sorted(pairs.items()):
                ma, mb = mean(a), mean(b)
                d = [ma[c] - mb[c] for c in range(3)]
                cost2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                grey = (d[0] + d[1] + d[2]) / 3.0
                ch = [d[c] - grey for c in range(3)]
                chroma2 = ch[0] * ch[0] + ch[1] * ch[1] + ch[2] * ch[2]
                ok = float(s) <= veto * 4096 * float(m) and chroma2 <= max_chroma * max_chroma
                ok = ok and ((count[a] < min_size or count[b] < min_size) if size_pass else cost2 <= level * level)
                if ok:
                    key32 = f32(cost2)
                    for me, other in ((a, b), (b, a)):
                        if me not in best or (key32, other) < best[me]:
                            best[me] = (key32, other)
            hooks = {}
            for r in sorted(best):
                other = best[r][1]
                if count[other] > count[r] or (count[other] == count[r] and other > r):
                    hooks[r] = other
            targeted = set(hooks.values())
            joined = 0
            for r, h in sorted(hooks.items()):
                if r in targeted:
                    continue
                count[h] += count[r]
                for c in range(3):
                    csum[h][c] += csum[r][c]
                joined += 1
                label_of = h
                for i in range(n):
                    if label[i] == r:
                        label[i] = label_of
            if joined == 0:
                break
            left -= joined
            if joined < settle * left:
                break
    return np.array(label)


def graph_edges_reference(indices, distances, max_length):
    """Plain numpy of kernels.regions.graph_edges: entries i -> j no longer than max_length, from
    i's row when i < j, from j's when j's row does not hold i; (a, b) sorted."""
    n, k = indices.shape
    src = np.repeat(np.arange(n, dtype=np.int64), k)
    dst = indices.reshape(-1).astype(np.int64)
    ok = (dst >= 0) & (distances.reshape(-1) <= max_length) & (dst != src)
    src, dst = src[ok], dst[ok]
    forward = src < dst
    back = ~forward
    mutual = (indices[dst[back]] == src[back, None]).any(axis=1)
    keep_back = np.flatnonzero(back)[~mutual]
    a = np.concatenate([src[forward], dst[keep_back]])
    b = np.concatenate([dst[forward], src[keep_back]])
    order = np.lexsort((b, a))
    return a[order], b[order]
