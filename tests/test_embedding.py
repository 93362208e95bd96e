"""A host program that owns the Taichi runtime and its ndarrays calls roadx_ti's kernels."""
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from roadx_ti.kernels.taichi_compat import DISTRIBUTION
from tests.conftest import KERNEL_BACKENDS

HOST_PROGRAM = textwrap.dedent("""
    import importlib
    import sys
    import numpy as np
    ti = importlib.import_module(sys.argv[2])     # the host's own Taichi (taichi or taichi_forge)

    ti.init(arch=getattr(ti, sys.argv[1]), offline_cache=False, fast_math=False)   # the host owns the runtime

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


def test_host_runtime_settings_and_misuse_are_clear_errors():
    """A host's runtime with default_fp f64 (it aborted the process in LLVM) or none at all
    ('NoneType' object has no attribute 'config'), neighbour indices past the cloud (a
    segmentation fault), empty inputs of radius_search / voxel_downsample (Taichi's '(0,) is not
    a valid shape'), and API misuse: each a clear Python exception, the process alive."""
    program = textwrap.dedent("""
        import sys
        import numpy as np
        from roadx_ti.kernels.taichi_compat import RuntimeSettingsError, ti
        from roadx_ti.kernels.outliers import sor_keep
        xyz = np.random.default_rng(0).random((500, 3)).astype(np.float32) * 10
        try:
            sor_keep(xyz, 8, 2.0)
            raise SystemExit("no error without a runtime")
        except RuntimeSettingsError as exc:
            assert "not initialised" in str(exc), exc
        ti.init(arch=ti.cpu, default_fp=ti.f64, offline_cache=False)
        try:
            sor_keep(xyz, 8, 2.0)
            raise SystemExit("no error under default_fp f64")
        except RuntimeSettingsError as exc:
            assert "default_fp=f64" in str(exc), exc
        ti.reset()
        ti.init(arch=ti.cpu, offline_cache=False)
        from roadx_ti.kernels.features import covariance_features
        from roadx_ti.kernels.grid import voxel_downsample
        from roadx_ti.kernels.neighbors import knn, radius_search
        for bad, said in ((np.full((500, 8), 10**8, np.int32), "outside the cloud of 500 points"),
                          (np.zeros((10, 8), np.int32), "10 rows for 500 points")):
            try:
                covariance_features(xyz, bad)
                raise SystemExit("bad indices taken")
            except ValueError as exc:
                assert said in str(exc), exc
        offsets, idx = radius_search(np.float32([[0, 0, 0], [10, 0, 0]]), 1.0)
        assert list(offsets) == [0, 0, 0] and len(idx) == 0
        offsets, idx = radius_search(np.zeros((0, 3), np.float32), 1.0)
        assert list(offsets) == [0] and len(idx) == 0
        assert len(voxel_downsample(np.zeros((0, 3), np.float32), 0.5)) == 0
        assert knn(xyz[:20].tolist(), 4)[0].shape == (20, 4)          # a list of points
        from roadx_ti import config, io, pipelines
        from roadx_ti.cloud import Cloud
        for call, said in ((lambda: pipelines.run(Cloud.from_world(xyz.astype(float)), None), "list of stage objects"),
                           (lambda: pipelines.run(None, []), "roadx_ti.cloud.Cloud"),
                           (lambda: io.write("w.ply", None), "roadx_ti.cloud.Cloud"),
                           (lambda: io.write("w.ply", Cloud.from_world(xyz.astype(float)),
                                             classification=np.full(500, 2.5)), "whole class numbers"),
                           (lambda: config.load(sys.argv[1], "seed=1"), "list of 'KEY=VALUE' strings")):
            try:
                call()
                raise SystemExit(f"accepted: {said}")
            except (TypeError, ValueError) as exc:
                assert said in str(exc), exc
        print("ok")
    """)
    from tests.conftest import REPO
    proc = subprocess.run([sys.executable, "-c", program, str(REPO / "configs" / "ground.yaml")], capture_output=True,
                          text=True, timeout=300, cwd="/tmp")
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stderr[-2000:]
    assert proc.stderr.count("runs with fast_math on (ti.init's default)") == 1, proc.stderr[-2000:]
    assert "about 0.1 % of the labels" in proc.stderr


EMPTY_INPUTS = textwrap.dedent('''
    import sys
    import numpy as np
    from roadx_ti.kernels.taichi_compat import ti
    ti.init(arch=getattr(ti, sys.argv[1]), offline_cache=False, fast_math=False)
    from roadx_ti.kernels import cloth, grid, neighbors
    empty = np.zeros((0, 3), np.float32)
    assert len(grid.voxel_downsample(empty, 0.5)) == 0
    offsets, idx = neighbors.radius_search(empty, 0.5)
    assert list(offsets) == [0] and len(idx) == 0
    assert grid.build_grid(empty).n == 0
    assert len(cloth.csf(empty).ground) == 0
    from roadx_ti.kernels.smoothing import neighbor_mean
    assert neighbor_mean(np.zeros(0, np.float32), np.zeros((0, 3), np.int32)).shape == (0,)
    print("ok")
''')


@pytest.mark.parametrize("arch", KERNEL_BACKENDS)
def test_empty_inputs_give_empty_results_on_every_arch(arch):
    """No point in, no point out, on a GPU arch too (Vulkan copied the empty numpy input to the
    device: '(0, 3) is not a valid shape for ndarray')."""
    proc = subprocess.run([sys.executable, "-c", EMPTY_INPUTS, arch], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok"), proc.stderr[-2000:]


def test_main_run_twice_in_one_process_keeps_no_setting_of_the_first(tmp_path):
    """cli.main called again in the same process (a host, the test driver): a --memory-limit of one
    call is not the next call's (it stayed in the environment, and refused every later run)."""
    from cli_helpers import bumpy_ground, run_in_one_process, write_las, write_tiny_config

    source = write_las(tmp_path / "in.laz", bumpy_ground(3000))
    config = write_tiny_config(tmp_path)
    run = ["run", str(config), "--backend", "cpu", "--quiet", "--input", str(source)]
    calls = [{"id": 0, "argv": [*run, "--output", str(tmp_path / "a.laz"), "--memory-limit", "1MB"]},
             {"id": 1, "argv": [*run, "--output", str(tmp_path / "b.laz")]}]
    results = run_in_one_process(calls, call_seconds=120, total_seconds=300)
    assert results[0]["code"] == 1 and "more than the 1.0 MB" in results[0]["stderr"], results[0]
    assert results[1]["code"] == 0, results[1]["stderr"]
    assert (tmp_path / "b.laz").is_file()


def test_main_run_twice_on_one_file_warns_about_it_each_time(tmp_path):
    """A file's warnings (points flagged withheld) are said by every main() that reads it, not
    only by the first in the process; a usage mistake is main()'s exit 2 there too."""
    import laspy

    from cli_helpers import bumpy_ground, run_in_one_process, write_las, write_tiny_config

    source = write_las(tmp_path / "in.las", bumpy_ground(3000))
    las = laspy.read(source)
    las.withheld = (np.arange(3000) % 2).astype(np.uint8)
    las.write(source)
    run = ["run", str(write_tiny_config(tmp_path)), "--backend", "cpu", "--quiet", "--input", str(source)]
    calls = [{"id": k, "argv": [*run, "--output", str(tmp_path / f"{k}.laz")]} for k in range(2)]
    calls.append({"id": 2, "argv": [*run, "--no-such-option"]})
    results = run_in_one_process(calls, call_seconds=120, total_seconds=300)
    for k in range(2):
        assert results[k]["code"] == 0 and "1500 of 3000 points are flagged withheld" in results[k]["stderr"], results[k]
    assert results[2]["code"] == 2 and results[2]["raised"] is None, results[2]
