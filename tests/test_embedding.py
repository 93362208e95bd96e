"""A host program that owns the Taichi runtime and its ndarrays calls roadx_ti's kernels."""
import subprocess
import sys
import textwrap

import pytest

from roadx_ti.kernels.taichi_compat import DISTRIBUTION
from tests.conftest import KERNEL_BACKENDS

HOST_PROGRAM = textwrap.dedent("""
    import importlib
    import sys
    import numpy as np
    ti = importlib.import_module(sys.argv[2])     # the host's own Taichi (taichi or taichi_forge)

    ti.init(arch=getattr(ti, sys.argv[1]), offline_cache=False)          # the host owns the runtime

    from roadx_ti import backend
    from roadx_ti.kernels.grid import build_grid, voxel_downsample
    from roadx_ti.kernels.neighbors import knn, knn_mean_distance
    from roadx_ti.kernels.outliers import sor_keep

    rng = np.random.default_rng(0)
    host = rng.random((3000, 3)).astype(np.float32) * np.float32([20, 20, 1])
    xyz = ti.ndarray(ti.f32, (3000, 3))                   # an ndarray the host allocated
    xyz.from_numpy(host)

    assert backend.init("cpu") == backend.current_arch()   # roadx_ti does not re-initialise
    grid = build_grid(xyz, 0.5)
    idx, dist = knn(xyz, 8, grid=grid)
    keep = sor_keep(xyz, 10, 2.0)
    mean = knn_mean_distance(xyz, 10, grid=build_grid(xyz))
    vox = voxel_downsample(xyz, 1.0)
    for result in (grid.order, idx, dist, keep, mean, vox):
        assert isinstance(result, ti.Ndarray), type(result)
    assert idx.shape == (3000, 8) and keep.shape == (3000,)

    from scipy.spatial import cKDTree
    ref = cKDTree(host).query(host, 9)[1][:, 1:]
    assert (np.sort(idx.to_numpy(), 1) == np.sort(ref, 1)).mean() > 0.999
    print("EMBEDDED-OK", int(keep.to_numpy().sum()))
""")


@pytest.mark.kernel
@pytest.mark.parametrize("arch", KERNEL_BACKENDS)
def test_host_program_owns_runtime_and_ndarrays(arch):
    # a fresh interpreter: this test session already owns a Taichi runtime
    proc = subprocess.run([sys.executable, "-c", HOST_PROGRAM, arch, DISTRIBUTION], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "EMBEDDED-OK" in proc.stdout
