"""sor: statistical outlier removal (METHODS.md R2), Open3D's convention and 'upper' mode.

Anchor Open3D remove_statistical_outlier(nb_neighbors=k, std_ratio). The k=500 variant (the
paper's) runs roadx_ti only, up to 4 M points (issue 3: it must complete there, time recorded),
and not in --quick runs.
"""
STAGE = "sor"
SCENE = "uav-road"
VARIANTS = [
    {"name": "k20", "params": {"k": 20, "std_ratio": 2.0}, "targets": {"open3d": 5.0}},
    {"name": "k500", "params": {"k": 500, "std_ratio": 2.0}, "impls": ["roadx_ti"], "max_points": 4_000_000,
     "quick": False},
]
TARGETS = {"open3d": 5.0}


def roadx_ti(scene, k, std_ratio):
    from roadx_ti.kernels.outliers import sor_keep

    xyz = scene.xyz
    return lambda: sor_keep(xyz, k, std_ratio, mode="upper", convention="open3d")


def open3d_sor(scene, k, std_ratio):
    from roadx_ti.bench import open3d_cloud

    cloud = open3d_cloud(scene.xyz)
    return lambda: cloud.remove_statistical_outlier(nb_neighbors=k, std_ratio=std_ratio)


IMPLS = {"roadx_ti": roadx_ti, "open3d": open3d_sor}
