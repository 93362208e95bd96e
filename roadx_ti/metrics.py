"""Accuracy measures of METHODS.md: type I / type II / total error and Cohen's kappa.

a = truth positive & predicted positive, b = truth positive & predicted negative,
c = truth negative & predicted positive, d = both negative; e = a + b, f = c + d, g = a + c,
h = b + d, n = a + b + c + d. Type I = b / e (R's E1), type II = c / f (R's E2),
total = (b + c) / n, kappa = (p_o - p_e) / (1 - p_e), p_o = (a + d) / n, p_e = (e g + f h) / n^2.
"""
from __future__ import annotations

import numpy as np


def confusion(truth: np.ndarray, pred: np.ndarray) -> dict:
    truth = np.asarray(truth, bool)
    pred = np.asarray(pred, bool)
    if truth.shape != pred.shape:
        raise ValueError(f"truth has {truth.size} points, prediction {pred.size}: they must match one to one")
    a = int(np.count_nonzero(truth & pred))
    b = int(np.count_nonzero(truth & ~pred))
    c = int(np.count_nonzero(~truth & pred))
    d = int(truth.size - a - b - c)
    return {"a": a, "b": b, "c": c, "d": d}


def scores(truth: np.ndarray, pred: np.ndarray) -> dict:
    """All measures for boolean truth / prediction arrays matched by order."""
    cm = confusion(truth, pred)
    a, b, c, d = cm["a"], cm["b"], cm["c"], cm["d"]
    e, f, g, h = a + b, c + d, a + c, b + d
    n = a + b + c + d
    p_o = (a + d) / n if n else float("nan")
    p_e = (e * g + f * h) / (n * n) if n else float("nan")
    kappa = (p_o - p_e) / (1 - p_e) if n and p_e != 1 else float("nan")
    return {
        "type1": b / e if e else float("nan"),
        "type2": c / f if f else float("nan"),
        "total": (b + c) / n if n else float("nan"),
        "kappa": kappa,
        "points": n,
        "truth_positive": e,
        "predicted_positive": g,
        "confusion": cm,
    }


def no_truth_line(classes) -> str:
    """The log line of a run that gives no accuracy because no input point carries ``classes``."""
    return f"no accuracy: no input point carries class {', '.join(str(c) for c in classes)} (evaluate.truth_classes)"


def class_mask(classification: np.ndarray, classes) -> np.ndarray:
    return np.isin(np.asarray(classification), np.asarray(list(classes)))
