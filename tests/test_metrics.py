import math

import numpy as np
import pytest

from roadx_ti.metrics import scores


def test_hand_computed_example():
    # a=40 b=10 c=5 d=45: type I 10/50, type II 5/50, total 15/100,
    # p_o = 0.85, p_e = (50*45 + 50*55) / 100^2 = 0.5, kappa = 0.7
    truth = np.array([1] * 50 + [0] * 50, bool)
    pred = np.array([1] * 40 + [0] * 10 + [1] * 5 + [0] * 45, bool)
    s = scores(truth, pred)
    assert s["confusion"] == {"a": 40, "b": 10, "c": 5, "d": 45}
    assert s["type1"] == pytest.approx(0.2)
    assert s["type2"] == pytest.approx(0.1)
    assert s["total"] == pytest.approx(0.15)
    assert s["kappa"] == pytest.approx(0.7)


def test_perfect_and_mismatch():
    truth = np.array([1, 0, 1, 0], bool)
    assert scores(truth, truth)["kappa"] == pytest.approx(1.0)
    assert math.isnan(scores(np.zeros(3, bool), np.zeros(3, bool))["type1"])
    with pytest.raises(ValueError, match="match one to one"):
        scores(truth, truth[:3])
