"""knn: exact k nearest neighbours of every point (the point itself excluded), build + query.

Anchor scipy: cKDTree build + query of k+1 (scipy counts the point itself) with workers=-1.
"""
STAGE = "knn"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"k": 16}}]
TARGETS = {"scipy": 5.0}


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


IMPLS = {"roadx_ti": roadx_ti, "scipy": scipy_ckdtree}
