"""uniform_downsample: METHODS.md R1 deterministic stride to a ratio of the points, with the
gather of the kept points (every implementation returns the kept coordinates).

Anchors: numpy stride slicing (copied), Open3D uniform_down_sample(every_k_points).
"""
STAGE = "uniform_downsample"
SCENE = "uav-road"
VARIANTS = [{"name": "", "params": {"every": 2}}]
TARGETS = {"numpy": 1.0, "open3d": 1.0}


def roadx_ti(scene, every):
    from roadx_ti.kernels.downsample import uniform_sample

    xyz = scene.xyz
    target = -(-len(xyz) // every)
    return lambda: uniform_sample(xyz, target)


def numpy_stride(scene, every):
    xyz = scene.xyz
    return lambda: xyz[::every].copy()


def open3d_uniform(scene, every):
    from roadx_ti.bench import open3d_cloud

    cloud = open3d_cloud(scene.xyz)
    return lambda: cloud.uniform_down_sample(every)


IMPLS = {"roadx_ti": roadx_ti, "numpy": numpy_stride, "open3d": open3d_uniform}
