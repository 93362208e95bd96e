"""ransac: the dominant plane from 1000 hypotheses (METHODS.md R3 scoring, refit included).

Anchor Open3D segment_plane with 1000 iterations (probability 1.0: no early stop, so it runs all
1000 as the kernel does).
"""
STAGE = "ransac"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"distance_threshold": 0.1, "hypotheses": 1000}}]
TARGETS = {"open3d": 5.0}


def roadx_ti(scene, distance_threshold, hypotheses):
    from roadx_ti.kernels.ransac import fit_plane

    xyz = scene.xyz
    return lambda: fit_plane(xyz, distance_threshold, hypotheses=hypotheses, seed=0)


def open3d_plane(scene, distance_threshold, hypotheses):
    from roadx_ti.bench import open3d_cloud

    cloud = open3d_cloud(scene.xyz)
    return lambda: cloud.segment_plane(distance_threshold, 3, hypotheses, probability=1.0)


IMPLS = {"roadx_ti": roadx_ti, "open3d": open3d_plane}
