"""Shared fixtures: the Taichi backends the kernels are tested on, and the real data folder."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from roadx_ti import backend

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("ROADX_TI_SHARED_DATA", REPO.parent / "shared" / "data"))

# CI proves the GPU-style code path through Mesa's lavapipe (a CPU Vulkan driver): there a
# missing Vulkan backend is a failure, not a skip.
KERNEL_BACKENDS = [b for b in os.environ.get("ROADX_TI_TEST_BACKENDS", "cpu,vulkan").split(",") if b]


@pytest.fixture(scope="session", params=KERNEL_BACKENDS)
def ti_arch(request):
    """Run the test on each kernel backend in turn; the runtime is shared by the whole session
    per backend, so kernels compile once per backend."""
    name = request.param
    if backend.is_initialized() and backend.current_arch() != name:
        backend.reset()
    try:
        arch = backend.init(name)
    except backend.BackendError as exc:
        if os.environ.get("CI") or os.environ.get("ROADX_TI_REQUIRE_BACKENDS"):
            pytest.fail(f"backend {name} must be available here: {exc}")
        pytest.skip(f"backend {name} not available: {exc}")
    yield arch


def switch_backend(name: str) -> None:
    """Make ``name`` the runtime of this test process (tests only: pipelines never re-initialise)."""
    if backend.is_initialized() and backend.current_arch() != name:
        backend.reset()
    backend.init(name)


@pytest.fixture(autouse=True)
def _runtime_per_test(request):
    """A test on ti_arch runs on that backend; any other test runs on the CPU (pipelines, tiles
    and stages run in this process: lavapipe left behind by a Vulkan test would make them many
    times slower, and their backend would depend on the test order)."""
    switch_backend(request.getfixturevalue("ti_arch") if "ti_arch" in request.fixturenames else "cpu")
    yield


# Seconds of the longest test files in the suite here (fresh clone, cold kernel cache, 2 xdist
# processes, 2efa713). `./dev test` hands files to its two processes whole, in collection order
# (--no-loadscope-reorder): the longest first, so that the short ones fill in at the end (by test
# count, xdist's default, a 3-minute file could start when the other process had nothing left).
LONGEST_FILES = {"test_dask.py": 228, "test_invariance.py": 213, "test_bad_inputs.py": 169,
                 "test_tiling.py": 166, "test_cli.py": 127, "test_fuzz.py": 125, "test_determinism.py": 73,
                 "test_roof_growing.py": 69, "test_dtm.py": 46, "test_neighbors.py": 41}


def pytest_collection_modifyitems(config, items):
    """Tests that run kernels on ti_arch are the 'kernel' tests (also run under taichi-forge).
    Files run longest first (LONGEST_FILES); each file's tests keep their order."""
    for item in items:
        if "ti_arch" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.kernel)
    items.sort(key=lambda item: -LONGEST_FILES.get(item.path.name, 0))     # stable


@pytest.fixture(scope="session")
def shared_data():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent")
    return SHARED_DATA


def laz_delivery(cloud, path, scale: float):
    """``cloud`` written as LAS 1.4 / point format 7 at coordinate ``scale`` (offsets: the floor of
    its lowest corner), with the colour, intensity, returns and classes it carries, and read back:
    the same survey as a file delivers it (invariance tests)."""
    import laspy
    import numpy as np

    from roadx_ti import io

    header = laspy.LasHeader(point_format=7, version="1.4")
    world = cloud.world_xyz()
    header.offsets = np.floor(world.min(axis=0))
    header.scales = np.full(3, scale)
    las = laspy.LasData(header)
    las.x, las.y, las.z = world[:, 0], world[:, 1], world[:, 2]
    if cloud.rgb is not None:
        las.red, las.green, las.blue = (cloud.rgb[:, c] for c in range(3))
    if cloud.intensity is not None:
        las.intensity = cloud.intensity
    if cloud.returns is not None:
        las.return_number, las.number_of_returns = cloud.returns[:, 0], cloud.returns[:, 1]
    las.classification = cloud.classification
    las.write(str(path))
    return io.read(path)


def deliver(cloud, variant: str, tmp_path):
    """(the survey as ``variant`` delivers it, keep): 'laz_1mm' / 'laz_1cm' (laz_delivery),
    'colour_8bit' (the colour divided by 257, depth 8), 'colour_x256' (those 8-bit values shifted up
    by 8 bits, depth 16: many writers store 8-bit colour so), 'shuffled' (a seeded permutation) or
    'thinned' (every point of the first half of a seeded permutation, in index order); variant
    point i is survey point keep[i]."""
    import numpy as np

    from roadx_ti.cloud import Cloud

    keep = np.arange(cloud.n)
    if variant in ("laz_1mm", "laz_1cm"):
        return laz_delivery(cloud, tmp_path / "s.laz", 0.001 if variant == "laz_1mm" else 0.01), keep
    if variant in ("colour_8bit", "colour_x256"):
        eight = (cloud.rgb // 257).astype(np.uint16)
        rgb, depth = (eight, 8) if variant == "colour_8bit" else (eight * np.uint16(256), 16)
        return Cloud(xyz=cloud.xyz, origin=cloud.origin, rgb=rgb, color_depth=depth,
                     intensity=cloud.intensity, returns=cloud.returns, classification=cloud.classification), keep
    rng = np.random.default_rng(1)
    keep = rng.permutation(cloud.n) if variant == "shuffled" else np.sort(rng.permutation(cloud.n)[: cloud.n // 2])
    return cloud.subset(keep), keep

