"""R1 uniform downsampling kernel against the formula of METHODS.md R1."""
import numpy as np
import pytest

from roadx_ti.kernels.common import as_ndarray
from roadx_ti.kernels.downsample import uniform_sample


@pytest.mark.parametrize("n, m", [(10, 3), (1000, 999), (1000, 1000), (12345, 100), (7, 0)])
def test_stride_matches_formula(ti_arch, n, m):
    xyz = np.random.default_rng(n).random((n, 3), dtype=np.float32)
    index, kept = uniform_sample(xyz, m)
    expected = (np.arange(m, dtype=np.int64) * n // max(m, 1)).astype(np.int32)
    np.testing.assert_array_equal(index, expected)
    np.testing.assert_array_equal(kept, xyz[expected])


def test_index_product_beyond_32_bits(ti_arch):
    # j * n exceeds 2^31 for n = 100 000 and j near m: the index must stay exact
    n, m = 100_000, 60_000
    xyz = np.zeros((n, 3), np.float32)
    xyz[:, 0] = np.arange(n)
    index, kept = uniform_sample(as_ndarray(xyz), m)
    expected = np.arange(m, dtype=np.int64) * n // m
    np.testing.assert_array_equal(index.to_numpy(), expected)
    np.testing.assert_array_equal(kept.to_numpy()[:, 0], expected.astype(np.float32))
