"""height_above_ground: z normalised by the ground surface (stages/height.py) on a synthetic als-roof
scene, the cloth of cloth_ground (cloth_resolution 0.5 m) computed once outside the timing.

Anchor scipy: RegularGridInterpolator (linear, extrapolated at the border) over a grid of the same
cell size (the anchors run without Taichi, so not the cloth itself: the lowest z per cell).
"""
STAGE = "height_above_ground"
SCENE = "als-roof"
VARIANTS = [{"name": "", "params": {"cloth_resolution": 0.5}}]
TARGETS = {"scipy": 1.0}


def _surface(scene, cloth_resolution):
    from roadx_ti.stages.base import GROUND_SURFACE, StageContext
    from roadx_ti.stages.cloth import ClothGround

    ctx = StageContext()
    ClothGround({"cloth_resolution": cloth_resolution}).run(scene, ctx)
    return ctx.facts[GROUND_SURFACE]


def roadx_ti(scene, cloth_resolution):
    from roadx_ti.stages.base import GROUND_SURFACE, StageContext
    from roadx_ti.stages.height import HeightAboveGround

    ctx = StageContext(facts={GROUND_SURFACE: _surface(scene, cloth_resolution)})
    stage = HeightAboveGround()
    return lambda: stage.run(scene, ctx)


def scipy_grid(scene, cloth_resolution):
    """The anchors run without Taichi: the grid is the lowest z per cell of the same size (numpy,
    untimed); the timed work, a bilinear height per point, is the stage's."""
    import numpy as np
    from scipy.interpolate import RegularGridInterpolator

    xyz = np.asarray(scene.xyz, np.float64)
    lo = xyz[:, :2].min(axis=0)
    cell = np.floor((xyz[:, :2] - lo) / cloth_resolution).astype(np.int64)
    cols, rows = cell.max(axis=0) + 1
    lowest = np.full(rows * cols, np.inf)
    np.minimum.at(lowest, cell[:, 1] * cols + cell[:, 0], xyz[:, 2])
    lowest[~np.isfinite(lowest)] = np.nanmin(lowest)
    x = lo[0] + cloth_resolution * (np.arange(cols) + 0.5)
    y = lo[1] + cloth_resolution * (np.arange(rows) + 0.5)

    def run():
        f = RegularGridInterpolator((y, x), lowest.reshape(rows, cols), bounds_error=False, fill_value=None)
        return xyz[:, 2] - f(xyz[:, [1, 0]])
    return run


IMPLS = {"roadx_ti": roadx_ti, "scipy": scipy_grid}
