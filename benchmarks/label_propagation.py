"""label_propagation: connected components of the colour-similar kNN graph (METHODS.md R6 first
step): colour edge test + data-parallel union-find.

Anchor scipy: the same edge test in numpy, a CSR matrix and scipy.sparse.csgraph.connected_components.
The kNN graph (k neighbours per point) is built outside the timing: with roadx_ti's exact kNN in
the Taichi workers, scipy's cKDTree in the anchors' (the same sets up to distance ties).
"""
STAGE = "label_propagation"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"k": 12, "threshold": 10.0}}]
TARGETS = {"scipy": 1.0}


def _graph(scene, k, use_roadx):
    import numpy as np

    xyz = scene.xyz
    if use_roadx:
        from roadx_ti.kernels.neighbors import knn

        return np.asarray(knn(xyz, k)[0], np.int32)
    from scipy.spatial import cKDTree

    tree = cKDTree(xyz)
    out = np.empty((len(xyz), k), np.int32)
    step = 1_000_000   # chunks: scipy returns float64 + int64 arrays
    for s in range(0, len(xyz), step):
        out[s:s + step] = tree.query(xyz[s:s + step], k=k + 1, workers=-1)[1][:, 1:]
    return out


def _colour(scene):
    import numpy as np

    rgb = scene.rgb8() if scene.rgb is not None else None
    return np.zeros((scene.n, 3), np.float32) if rgb is None else np.ascontiguousarray(rgb, np.float32)


def roadx_ti(scene, k, threshold):
    from roadx_ti.kernels.labels import color_edges, connected_components

    neighbors = _graph(scene, k, use_roadx=True)
    rgb = _colour(scene)

    def run():
        return connected_components(neighbors, color_edges(neighbors, rgb, threshold))
    return run


def scipy_csgraph(scene, k, threshold):
    import numpy as np
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    neighbors = _graph(scene, k, use_roadx=False)
    rgb = _colour(scene)
    n = len(neighbors)

    def run():
        diff = rgb[neighbors] - rgb[:, None, :]
        ok = np.einsum("nkc,nkc->nk", diff, diff) < np.float32(threshold) ** 2
        rows = np.repeat(np.arange(n, dtype=np.int32), k)[ok.ravel()]
        graph = csr_matrix((np.ones(len(rows), np.int8), (rows, neighbors.ravel()[ok.ravel()])), shape=(n, n))
        return connected_components(graph, directed=False)
    return run


IMPLS = {"roadx_ti": roadx_ti, "scipy": scipy_csgraph}
