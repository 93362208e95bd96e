"""roadx_ti.segments: per-segment statistics shared by R3 (parts of an XY plane) and P4."""
import numpy as np

from roadx_ti.segments import segment_medians


def test_segment_medians_equal_numpy_per_segment_and_ignore_unlabelled():
    rng = np.random.default_rng(3)
    segment = rng.integers(-1, 6, 500)
    values = rng.normal(size=500).astype(np.float32)
    values[segment == 4] = 2.5                        # ties inside one segment
    got = segment_medians(segment, values, 6)
    want = [np.median(values[segment == s].astype(np.float64)) for s in range(6)]
    np.testing.assert_array_equal(got, want)
    # even and odd counts: the mean of the two middle values, as numpy
    assert segment_medians(np.array([0, 0, 1, 1, 1, -1]), np.array([4.0, 1.0, 7.0, 3.0, 5.0, 99.0]), 2).tolist() == [2.5, 5.0]
    # the result does not depend on the point order
    order = rng.permutation(500)
    np.testing.assert_array_equal(segment_medians(segment[order], values[order], 6), got)
