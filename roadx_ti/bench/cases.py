"""The cases of `python -m roadx_ti bench`: where they live, their order, the jobs of one case at
one size, the helpers the case modules call, and the synthetic scenes they run on.

A case module (``benchmarks/<stage>.py``) declares STAGE, SCENE, VARIANTS, TARGETS and IMPLS (see
roadx_ti/bench/__init__.py); STAGES below lists them in the order of a run and of the tables.
"""
from __future__ import annotations

import importlib.util
import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
BENCH_DIR = REPO_ROOT / "benchmarks"        # the cases, RESULTS.md and throughput.png
DEFAULT_OUT = BENCH_DIR / "out"
CASES_ENV = "ROADX_BENCH_CASES"              # another folder of cases (tests of the harness)
# Order of the table and of a run: kernel stages in pipeline order, then the pipelines.
STAGES = ("voxel_hash", "knn", "uniform_downsample", "voxel_downsample", "sor", "normals", "ransac",
          "grid_min", "csf", "height_above_ground", "label_propagation", "road_pipeline", "roof_pipeline")
FULL_SIZES = (1_000_000, 4_000_000, 16_000_000)
QUICK_SIZES = (50_000, 200_000)


def load_case(stage: str):
    """The case module benchmarks/<stage>.py, loaded by path (benchmarks/ is not a package)."""
    path = Path(os.environ.get(CASES_ENV) or BENCH_DIR) / f"{stage}.py"
    spec = importlib.util.spec_from_file_location(f"roadx_bench_case_{stage}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _jobs(stage: str, points: int, impls_filter, *, anchors: bool, quick: bool = False) -> list[dict]:
    """(stage, variant, impl) jobs of one case at one size: the roadx_ti impl, or the anchors.
    A variant marked ``"quick": False`` (seconds even on tiny scenes) is left out of --quick, and so
    are the pipelines above the smallest quick size."""
    case = load_case(stage)
    jobs = []
    for variant in getattr(case, "VARIANTS", [{"name": "", "params": {}}]):
        if quick and not variant.get("quick", True):
            continue
        if quick and stage.endswith("_pipeline") and points > QUICK_SIZES[0]:
            continue   # --quick: the pipelines at the smallest size only
        names = variant.get("impls") or list(case.IMPLS)
        for impl in names:
            if (impl == "roadx_ti") == anchors:
                continue
            if impls_filter and impl not in impls_filter:
                continue
            jobs.append({"stage": stage, "variant": variant["name"], "impl": impl, "points": points,
                         "params": variant.get("params", {}), "scene": getattr(case, "SCENE", "uav-road"),
                         "max_points": variant.get("max_points")})
    return jobs



# ------------------------------------------------------------------- helpers of the case modules
def open3d_cloud(xyz):
    """An Open3D PointCloud of (n, 3) points (built outside the timing of the Open3D anchors)."""
    import numpy as np
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(xyz, np.float64)))


def pipeline_call(scene, config: str, pipeline: str):
    """The timed call of a pipeline case: the stages of ``config`` (relative to the repository),
    or the pipeline's default stages while that file does not exist."""
    from roadx_ti import config as cfg_mod
    from roadx_ti import pipelines

    path = REPO_ROOT / config
    specs = cfg_mod.load(path).stage_list() if path.is_file() else pipelines.default_stage_specs(pipeline)
    stages = pipelines.build_stages(specs)
    return lambda: pipelines.run(scene, stages)



# ------------------------------------------------------------------------------ the scenes
def make_scene(kind: str, points: int, seed: int):
    """The synthetic scene of the pipelines (roadx_ti.synthetic), or a stand-in while it is absent."""
    try:
        from roadx_ti import synthetic
    except ImportError:
        return _standin_scene(kind, points, seed)
    return synthetic.generate(kind, points, seed)


def _standin_scene(kind: str, n: int, seed: int):
    """Terrain + road strip + boxes + trees + a few outliers at a constant density (so that time
    should grow linearly with n): only for developing the harness before roadx_ti.synthetic."""
    import numpy as np

    from roadx_ti.cloud import Cloud

    rng = np.random.default_rng(seed)
    density = 100.0 if kind == "uav-road" else 20.0   # points per m^2
    side = float(np.sqrt(n / density))
    n_box, n_tree, n_out = int(0.15 * n), int(0.10 * n), max(1, int(0.002 * n))
    n_ground = n - n_box - n_tree - n_out
    xy = rng.uniform(0, side, (n, 2))
    z = 0.02 * xy[:, 0] + 0.5 * np.sin(xy[:, 1] / 37.0) + rng.normal(0, 0.02, n)
    cls = np.full(n, 2, np.uint8)
    rgb = np.empty((n, 3), np.float64)
    rgb[:] = (80, 130, 60)
    road = np.abs(xy[:, 1] - side / 2) < min(5.0, side / 8)
    road[n_ground:] = False
    cls[road] = 11
    rgb[road] = (120, 120, 125)
    # boxes: 20 m squares on a lattice, flat or gabled roofs 4..12 m up
    b = slice(n_ground, n_ground + n_box)
    cell = np.floor(xy[b] / 40.0)
    h = 4.0 + 8.0 * ((cell[:, 0] * 7 + cell[:, 1] * 3) % 5) / 4.0
    xy[b] = cell * 40.0 + 10.0 + rng.uniform(0, 20.0, (n_box, 2))
    z[b] = z[b] + h + 0.2 * np.abs(xy[b, 0] % 40.0 - 20.0) * (cell[:, 1] % 2)
    cls[b] = 6
    rgb[b] = (150, 60, 50)
    t = slice(n_ground + n_box, n_ground + n_box + n_tree)
    centre = rng.uniform(0, side, (max(1, n_tree // 400), 2))
    which = rng.integers(0, len(centre), n_tree)
    xy[t] = centre[which] + rng.normal(0, 1.5, (n_tree, 2))
    z[t] = z[t] + 3.0 + np.abs(rng.normal(0, 2.0, n_tree))
    cls[t] = 5
    rgb[t] = (40, 110, 40)
    o = slice(n - n_out, n)
    z[o] = z[o] + rng.uniform(-20, 40, n_out)
    cls[o] = 7
    rgb += rng.normal(0, 6, (n, 3))
    xyz = np.column_stack([xy, z - z.min()]).astype(np.float32)
    rgb16 = (np.clip(rgb, 0, 255) * 257).astype(np.uint16)
    return Cloud(xyz=xyz, origin=np.zeros(3), rgb=rgb16, color_depth=16, classification=cls,
                 source=f"stand-in {kind} scene ({n} points, seed {seed})")

