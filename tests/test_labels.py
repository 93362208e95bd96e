import math

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components as csgraph_components
from scipy.spatial import cKDTree

from roadx_ti.kernels import labels
from roadx_ti.kernels.common import as_ndarray, is_ndarray, to_numpy

from references import edge_mask, flood_fill


def scipy_components(neighbors, edge_ok=None, active=None):
    """Reference for large graphs: scipy's components, relabelled by smallest index."""
    n = len(neighbors)
    rows, cols = edge_mask(neighbors, edge_ok, active)
    graph = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, comp = csgraph_components(graph, directed=False)
    smallest = np.full(comp.max() + 1, n)
    np.minimum.at(smallest, comp, np.arange(n))
    out = smallest[comp].astype(np.int32)
    if active is not None:
        out[active == 0] = -1
    return out


def random_graph(rng, n, k, p_pad):
    neighbors = rng.integers(0, n, (n, k)).astype(np.int32)
    neighbors[rng.random((n, k)) < p_pad] = -1
    return neighbors


def knn_graph(xyz, k):
    _, idx = cKDTree(xyz).query(xyz, k=k + 1)
    return idx[:, 1:].astype(np.int32)


def clustered_cloud(rng, n, n_clusters=12):
    centres = rng.uniform(0, 30, (n_clusters, 3))
    which = rng.integers(0, n_clusters, n)
    return (centres[which] + rng.normal(0, 0.6, (n, 3))).astype(np.float32), which


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_graph_matches_flood_fill(ti_arch, seed):
    rng = np.random.default_rng(seed)
    n = 3000
    neighbors = random_graph(rng, n, 3, 0.6)
    edge_ok = (rng.random(neighbors.shape) < 0.8).astype(np.uint8)
    active = (rng.random(n) < 0.85).astype(np.uint8)
    for ok, act in [(None, None), (edge_ok, None), (None, active), (edge_ok, active)]:
        got = labels.connected_components(neighbors, ok, act)
        assert got.dtype == np.int32
        np.testing.assert_array_equal(got, flood_fill(neighbors, ok, act))


@pytest.mark.parametrize("kind", ["uniform", "clustered"])
def test_knn_graph_matches_flood_fill(ti_arch, kind):
    rng = np.random.default_rng(7)
    n = 4000
    if kind == "uniform":
        xyz = rng.uniform(0, 20, (n, 3)).astype(np.float32)
    else:
        xyz, _ = clustered_cloud(rng, n)
    neighbors = knn_graph(xyz, 4)
    # a distance cut makes many components out of the kNN graph
    dist = np.linalg.norm(xyz[neighbors] - xyz[:, None, :], axis=2)
    edge_ok = (dist < np.quantile(dist, 0.5)).astype(np.uint8)
    expected = flood_fill(neighbors, edge_ok)
    assert len(np.unique(expected)) > 10
    np.testing.assert_array_equal(labels.connected_components(neighbors, edge_ok), expected)
    np.testing.assert_array_equal(labels.connected_components(neighbors), flood_fill(neighbors))


@pytest.mark.parametrize("order", ["ascending", "descending", "shuffled"])
def test_long_chain_converges_in_few_rounds(ti_arch, order):
    n = 100_000
    perm = np.arange(n) if order == "ascending" else (
        np.arange(n)[::-1] if order == "descending" else np.random.default_rng(3).permutation(n))
    neighbors = np.full((n, 2), -1, np.int32)
    neighbors[perm[:-1], 0] = perm[1:]  # a path of diameter n - 1
    parent, rounds = labels._components(neighbors)
    assert rounds <= math.ceil(math.log2(n))
    np.testing.assert_array_equal(to_numpy(parent), np.zeros(n, np.int32))
    # cut it in pieces, some points inactive
    rng = np.random.default_rng(4)
    edge_ok = (rng.random(neighbors.shape) < 0.999).astype(np.uint8)
    active = (rng.random(n) < 0.999).astype(np.uint8)
    got, rounds = labels._components(neighbors, edge_ok, active)
    assert rounds <= math.ceil(math.log2(n))
    np.testing.assert_array_equal(to_numpy(got), scipy_components(neighbors, edge_ok, active))


def test_edge_cases(ti_arch):
    empty = labels.connected_components(np.zeros((0, 3), np.int32))
    assert empty.shape == (0,)
    isolated = labels.connected_components(np.full((5, 2), -1, np.int32))
    np.testing.assert_array_equal(isolated, np.arange(5))
    # an edge only one end lists, and self loops
    neighbors = np.array([[-1], [0], [2], [2]], np.int32)
    np.testing.assert_array_equal(labels.connected_components(neighbors), [0, 0, 2, 2])
    active = np.array([1, 1, 0, 1], np.uint8)
    np.testing.assert_array_equal(labels.connected_components(neighbors, active=active),
                                  [0, 0, -1, 3])


def test_ndarray_in_ndarray_out(ti_arch):
    rng = np.random.default_rng(5)
    neighbors = random_graph(rng, 500, 3, 0.5)
    rgb = rng.uniform(0, 255, (500, 3)).astype(np.float32)
    nd = as_ndarray(neighbors)
    got = labels.connected_components(nd)
    assert is_ndarray(got)
    np.testing.assert_array_equal(got.to_numpy(), flood_fill(neighbors))
    ok = labels.color_edges(nd, as_ndarray(rgb), 100.0)
    assert is_ndarray(ok)
    np.testing.assert_array_equal(ok.to_numpy(), labels.color_edges(neighbors, rgb, 100.0))


def test_color_edges_matches_numpy(ti_arch):
    rng = np.random.default_rng(6)
    n = 2000
    neighbors = random_graph(rng, n, 5, 0.2)
    rgb = rng.integers(0, 256, (n, 3)).astype(np.float32)
    for threshold in (10.0, 37.5, 120.0):
        got = labels.color_edges(neighbors, rgb, threshold)
        diff = rgb[np.maximum(neighbors, 0)] - rgb[:, None, :]
        dist = np.sqrt((diff.astype(np.float64) ** 2).sum(axis=2))
        expected = ((neighbors >= 0) & (dist < threshold)).astype(np.uint8)
        assert got.dtype == np.uint8
        np.testing.assert_array_equal(got, expected)


def test_relabel_compact(ti_arch):
    lab = np.array([5, 5, -1, 2, 9, 2, 5, -1, 9], np.int32)
    compact, count = labels.relabel_compact(lab)
    assert count == 3
    np.testing.assert_array_equal(compact, [0, 0, -1, 1, 2, 1, 0, -1, 2])
    nd, count = labels.relabel_compact(as_ndarray(lab))
    assert is_ndarray(nd) and count == 3


def merge_reference(lab, neighbors, rgb, threshold, min_size):
    """Pure numpy/Python region merging: means before merging, sequential union-find."""
    ids = sorted(set(lab[lab >= 0].tolist()))
    means = {r: rgb[lab == r].astype(np.float64).mean(axis=0) for r in ids}
    parent = {r: r for r in ids}

    def find(r):
        while parent[r] != r:
            r = parent[r]
        return r

    for i in range(len(lab)):
        for j in neighbors[i]:
            if j < 0 or lab[i] < 0 or lab[j] < 0 or lab[i] == lab[j]:
                continue
            if np.linalg.norm(means[lab[i]] - means[lab[j]]) < threshold:
                a, b = find(lab[i]), find(lab[j])
                parent[max(a, b)] = min(a, b)
    out = np.array([find(r) if r >= 0 else -1 for r in lab], np.int32)
    ids_out, counts = np.unique(out[out >= 0], return_counts=True)
    small = set(ids_out[counts < min_size].tolist())
    out[np.isin(out, list(small))] = -1
    return out


@pytest.mark.parametrize("min_size", [0, 30])
def test_merge_regions_matches_reference(ti_arch, min_size):
    rng = np.random.default_rng(8)
    n = 3000
    xyz, cluster = clustered_cloud(rng, n, n_clusters=8)
    base = rng.uniform(0, 255, (8, 3))
    rgb = np.clip(base[cluster] + rng.normal(0, 12, (n, 3)), 0, 255).astype(np.float32)
    neighbors = knn_graph(xyz, 6)
    grown = labels.connected_components(neighbors, labels.color_edges(neighbors, rgb, 18.0))
    assert len(np.unique(grown)) > 20  # growing alone over-segments
    for threshold in (15.0, 60.0):
        expected = merge_reference(grown, neighbors, rgb, threshold, min_size)
        got = labels.merge_regions(grown, neighbors, rgb, threshold, min_size)
        assert got.dtype == np.int32
        np.testing.assert_array_equal(got, expected)
    nd = labels.merge_regions(as_ndarray(grown), as_ndarray(neighbors), rgb, 60.0, min_size)
    assert is_ndarray(nd)
    np.testing.assert_array_equal(nd.to_numpy(), merge_reference(grown, neighbors, rgb, 60.0, min_size))


def test_region_stats():
    lab = np.array([3, 3, -1, 0, 3], np.int32)
    values = np.array([[1.0], [2.0], [50.0], [4.0], [6.0]])
    ids, counts, means = labels.region_stats(lab, values)
    np.testing.assert_array_equal(ids, [0, 3])
    np.testing.assert_array_equal(counts, [1, 3])
    np.testing.assert_allclose(means[:, 0], [4.0, 3.0])


def test_boundary_edges_lists_edges_between_two_labels():
    from roadx_ti.kernels.labels import boundary_edges

    labels = np.array([0, 0, 1, -1, 2], np.int32)
    neighbors = np.array([[1, 2], [0, -1], [0, 4], [2, 0], [3, 2]], np.int32)
    own, other = boundary_edges(labels, neighbors)
    # row-major over the table: 0->2, 2->0, 2->4, 4->2; edges within a label, to or from an
    # unlabelled point (-1) and padding are left out
    np.testing.assert_array_equal(own, [0, 1, 1, 2])
    np.testing.assert_array_equal(other, [2, 0, 4, 2])
