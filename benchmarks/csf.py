"""csf: cloth simulation filter (METHODS.md R5), parameters named as the package names them.

Anchor: the `cloth-simulation-filter` package (module CSF) on the same points and parameters,
a new filter object per call (setPointCloud inside the timing: the package copies the points).
"""
STAGE = "csf"
SCENE = "uav-road"
_COMMON = {"rigidness": 3, "time_step": 0.65, "iterations": 500, "class_threshold": 0.5, "slope_smooth": False}
VARIANTS = [
    {"name": "res0.5", "params": {"cloth_resolution": 0.5, **_COMMON}, "targets": {"csf": 5.0},
     "quick": False},   # 500 iterations of a fine cloth: seconds even on tiny scenes
    {"name": "res2.0", "params": {"cloth_resolution": 2.0, **_COMMON}, "targets": {"csf": 1.0}},
]
TARGETS = {"csf": 1.0}


def roadx_ti(scene, **params):
    from roadx_ti.kernels.cloth import csf

    xyz = scene.xyz
    return lambda: csf(xyz, **params)


def csf_package(scene, cloth_resolution, rigidness, time_step, iterations, class_threshold, slope_smooth):
    import numpy as np

    import CSF

    xyz = np.asarray(scene.xyz, np.float64)

    def run():
        f = CSF.CSF()
        f.params.cloth_resolution = cloth_resolution
        f.params.rigidness = rigidness
        f.params.time_step = time_step
        f.params.interations = iterations     # sic: the package's spelling
        f.params.class_threshold = class_threshold
        f.params.bSloopSmooth = slope_smooth  # sic
        f.setPointCloud(xyz)
        ground, off_ground = CSF.VecInt(), CSF.VecInt()
        f.do_filtering(ground, off_ground, False)
        return ground
    return run


IMPLS = {"roadx_ti": roadx_ti, "csf": csf_package}
