"""Run reports: the summary JSON and top-view PNGs (classes; truth / prediction / error)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from roadx_ti.io.atomic import atomic_output

CLASS_COLOURS = {1: "#b0b0b0", 2: "#a0522d", 3: "#9acd32", 4: "#3cb371", 5: "#006400",
                 6: "#d62728", 7: "#ff00ff", 11: "#1f1f1f", 18: "#ff00ff"}
MAX_PLOT_POINTS = 400_000


def write_json(path: str | Path, data: dict) -> None:
    with atomic_output(path) as tmp:
        Path(tmp).write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _plot_sample(n: int) -> np.ndarray:
    step = max(1, -(-n // MAX_PLOT_POINTS))
    return np.arange(0, n, step)


def top_view_png(path, xy: np.ndarray, classification: np.ndarray, *, truth: np.ndarray | None = None,
                 predicted: np.ndarray | None = None, title: str = "") -> None:
    """A top view coloured by class; with ``truth`` and ``predicted`` (bool per point) three
    panels: truth, prediction, errors (type I red, type II blue)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    pick = _plot_sample(len(xy))
    x, y = xy[pick, 0], xy[pick, 1]
    span = max(np.ptp(x) if len(x) else 1.0, 1e-6), max(np.ptp(y) if len(y) else 1.0, 1e-6)
    aspect = span[1] / span[0]
    size = max(0.05, min(2.0, 40000 / max(len(pick), 1)))
    panels = 3 if truth is not None and predicted is not None else 1
    fig, axes = plt.subplots(1, panels, figsize=(6 * panels, max(3.0, 6 * aspect)), squeeze=False)
    axes = axes[0]
    if panels == 1:
        cls = classification[pick]
        colours = np.array([CLASS_COLOURS.get(int(c), "#17becf") for c in cls])
        axes[0].scatter(x, y, c=colours, s=size, linewidths=0)
        axes[0].set_title(title or "classification")
    else:
        t, p = truth[pick], predicted[pick]
        binary = ListedColormap(["#d9d9d9", "#1f1f1f"])
        axes[0].scatter(x, y, c=t.astype(int), cmap=binary, vmin=0, vmax=1, s=size, linewidths=0)
        axes[0].set_title("truth")
        axes[1].scatter(x, y, c=p.astype(int), cmap=binary, vmin=0, vmax=1, s=size, linewidths=0)
        axes[1].set_title("prediction")
        err = np.zeros(len(pick), int)
        err[t & p] = 1
        err[t & ~p] = 2          # type I: target missed
        err[~t & p] = 3          # type II: false target
        cmap = ListedColormap(["#eeeeee", "#7f7f7f", "#d62728", "#1f77b4"])
        axes[2].scatter(x, y, c=err, cmap=cmap, vmin=0, vmax=3, s=size, linewidths=0)
        axes[2].set_title("errors: red type I (missed), blue type II (false)")
        if title:
            fig.suptitle(title)
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
