"""roadx_ti.columns: per-column reductions equal numpy's axis-0 ones."""
import warnings

import numpy as np

from roadx_ti.columns import column_abs_nanmax, column_max, column_min


def test_column_reductions_equal_numpys_axis_0():
    rng = np.random.default_rng(0)
    floats = rng.normal(0, 1e6, (1000, 3))
    floats[5, 1] = np.nan            # min / max propagate it, nanmax of abs skips it
    floats[:, 2] = np.nan            # ... unless the column is all NaN
    ints = rng.integers(-2**31, 2**31 - 1, (1000, 2), dtype=np.int64)
    for a in (floats, floats.astype(np.float32), ints, floats[::3, :2]):
        np.testing.assert_array_equal(column_min(a), a.min(axis=0))
        np.testing.assert_array_equal(column_max(a), a.max(axis=0))
        assert column_min(a).dtype == a.dtype
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)      # numpy warns of the all-NaN column
        np.testing.assert_array_equal(column_abs_nanmax(floats), np.nanmax(np.abs(floats), axis=0))
