import numpy as np
import pytest

from roadx_ti.kernels import scan


@pytest.mark.parametrize("n", [0, 1, 7, 1000, 123457])
def test_exclusive_scan_matches_numpy(ti_arch, n):
    rng = np.random.default_rng(n)
    values = rng.integers(0, 50, n).astype(np.int32)
    prefix, total = scan.exclusive_scan(values)
    expected = np.concatenate([[0], np.cumsum(values)[:-1]]) if n else np.zeros(0)
    assert total == int(values.sum())
    np.testing.assert_array_equal(prefix, expected)
