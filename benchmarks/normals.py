"""normals: covariance features (normal, curvature, ...) from the k nearest neighbours, the kNN
search included (as in Open3D's estimate_normals).

Anchor Open3D estimate_normals(KDTreeSearchParamKNN(k)) (its k counts the point itself); the
normals are cleared before each call so that it never orients against a previous result.
"""
STAGE = "normals"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"k": 20}}]
TARGETS = {"open3d": 5.0}


def roadx_ti(scene, k):
    from roadx_ti.kernels.features import covariance_features
    from roadx_ti.kernels.neighbors import knn

    xyz = scene.xyz

    def run():
        idx, _ = knn(xyz, k)
        return covariance_features(xyz, idx)
    return run


def open3d_normals(scene, k):
    import open3d as o3d

    from roadx_ti.bench import open3d_cloud

    cloud = open3d_cloud(scene.xyz)
    param = o3d.geometry.KDTreeSearchParamKNN(knn=k)

    def run():
        cloud.normals = o3d.utility.Vector3dVector()
        cloud.estimate_normals(param)
        return cloud.normals
    return run


IMPLS = {"roadx_ti": roadx_ti, "open3d": open3d_normals}
