"""knn: exact k nearest neighbours of every point (the point itself excluded), build + query.

Anchors, build + query of k+1 (both count the point itself) on all cores: scipy's cKDTree
(workers=-1) and pykdtree (OpenMP; the fastest CPU kd-tree on PyPI, float32 as given).
"""
STAGE = "knn"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"k": 16}}]
TARGETS = {"scipy": 5.0, "pykdtree": 3.0}


def roadx_ti(scene, k):
    from roadx_ti.kernels.neighbors import knn

    xyz = scene.xyz
    return lambda: knn(xyz, k)


def scipy_ckdtree(scene, k):
    from scipy.spatial import cKDTree

    xyz = scene.xyz

    def run():
        return cKDTree(xyz).query(xyz, k=k + 1, workers=-1)
    return run


def pykdtree_kdtree(scene, k):
    from pykdtree.kdtree import KDTree

    xyz = scene.xyz

    def run():
        return KDTree(xyz).query(xyz, k=k + 1)
    return run


IMPLS = {"roadx_ti": roadx_ti, "scipy": scipy_ckdtree, "pykdtree": pykdtree_kdtree}
