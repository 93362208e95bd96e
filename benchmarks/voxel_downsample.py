"""voxel_downsample: one real point per occupied voxel (the one nearest the voxel centroid).

Anchor Open3D voxel_down_sample (it returns the centroids, not real points: less work than ours).
"""
STAGE = "voxel_downsample"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"voxel_size": 0.25}}]
TARGETS = {"open3d": 10.0}


def roadx_ti(scene, voxel_size):
    from roadx_ti.kernels.grid import voxel_downsample

    xyz = scene.xyz
    return lambda: voxel_downsample(xyz, voxel_size)


def open3d_voxel(scene, voxel_size):
    from roadx_ti.bench import open3d_cloud

    cloud = open3d_cloud(scene.xyz)
    return lambda: cloud.voxel_down_sample(voxel_size)


IMPLS = {"roadx_ti": roadx_ti, "open3d": open3d_voxel}
