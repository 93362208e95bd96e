"""Run reports: the summary JSON and top-view pictures.

``top_view_png`` rasterises a cloud seen from above: a pixel is a square of about the point
spacing (coarser only when the scene is wider than PANEL_PX pixels), the view is clipped to where
the points are (``footprint.scene``: a stray point far away is left out, not drawn as a dot
that shrinks the scene), the scene is shown in its own colours, or as shaded intensity / height
(hillshade) without colour, and the result is laid over it in a strong colour, with a legend
(counts) and a scale bar. With truth: four panels, scene / truth / prediction / errors (type I,
missed: red; type II, false: blue). Rasterisation is numpy (bincount on pixel indices).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from roadx_ti.io.atomic import atomic_output

PANEL_PX = 640              # raster pixels across a panel at most (the figure's panel width)
PIXEL_SPACINGS = 1.4        # pixel edge in point spacings: about 2 points per pixel
DPI = 110
PANEL_INCHES = PANEL_PX / DPI
MAX_PANEL_ASPECT = 2.0      # a panel is at most this many widths high: a narrow north-south scene
                            # (a corridor, a wall) is drawn narrower, not as a figure 400 k px high
FILL_GAPS_PX = 2            # empty pixels this close to a filled one take its value
TARGET = np.array([1.0, 0.0, 0.85])         # strong magenta: the result / the truth
CORRECT = np.array([1.0, 0.55, 0.93])       # light magenta: target found
MISSED = np.array([0.95, 0.05, 0.0])        # red: type I, target missed
FALSE = np.array([0.0, 0.4, 1.0])           # blue: type II, taken for target
OVERLAY_ALPHA = 0.8
EMPTY = np.array([1.0, 1.0, 1.0])


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


# ------------------------------------------------------------------------------ rasterisation

class TopView:
    """The kept points of a cloud binned into square pixels (row 0 = north)."""

    def __init__(self, xy: np.ndarray, max_px: int = PANEL_PX):
        from roadx_ti import footprint

        self.scene = footprint.scene(xy)
        xmin, ymin, xmax, ymax = self.scene.bounds
        span = max(xmax - xmin, ymax - ymin, 1e-6)
        self.pixel = max(PIXEL_SPACINGS * self.scene.spacing, span / max_px)
        self.cols = int(math.floor((xmax - xmin) / self.pixel)) + 1
        self.rows = int(math.floor((ymax - ymin) / self.pixel)) + 1
        # (left, right, bottom, top): pixel (row, col) covers x from xmin + col * pixel and y down
        # from ymax - row * pixel
        self.extent = (xmin, xmin + self.cols * self.pixel, ymax - self.rows * self.pixel, ymax)
        pts = np.asarray(xy, np.float64)[self.scene.keep]
        col = np.minimum(((pts[:, 0] - xmin) / self.pixel).astype(np.int64), self.cols - 1)
        row = np.minimum(((ymax - pts[:, 1]) / self.pixel).astype(np.int64), self.rows - 1)
        self.index = row * self.cols + col
        self.count = np.bincount(self.index, minlength=self.rows * self.cols)
        self.filled = self.count > 0
        self._nearest = None

    def mean(self, values: np.ndarray) -> np.ndarray:
        """Per pixel mean of a per-point value (of the kept points), NaN where empty."""
        total = np.bincount(self.index, weights=np.asarray(values, np.float64)[self.scene.keep],
                            minlength=self.rows * self.cols)
        with np.errstate(invalid="ignore", divide="ignore"):
            return (total / self.count).reshape(self.rows, self.cols)

    def maximum(self, values: np.ndarray) -> np.ndarray:
        out = np.full(self.rows * self.cols, -np.inf)
        np.maximum.at(out, self.index, np.asarray(values, np.float64)[self.scene.keep])
        out[~self.filled] = np.nan
        return out.reshape(self.rows, self.cols)

    def fill(self, image: np.ndarray) -> np.ndarray:
        """Empty pixels within FILL_GAPS_PX of a filled one take the nearest one's value."""
        if self._nearest is None:
            from scipy.ndimage import distance_transform_edt

            dist, (r, c) = distance_transform_edt(~self.filled.reshape(self.rows, self.cols),
                                                  return_indices=True)
            self._nearest = (r, c, dist <= FILL_GAPS_PX)
        r, c, near = self._nearest
        out = image[r, c]
        out[~near] = np.nan
        return out

    @property
    def covered(self) -> np.ndarray:
        return self._nearest[2] if self._nearest is not None else self.filled.reshape(self.rows, self.cols)


def _stretch(a: np.ndarray, lo_pct=1.0, hi_pct=99.0) -> np.ndarray:
    finite = a[np.isfinite(a)]
    if finite.size == 0:
        return np.zeros_like(a)
    lo, hi = np.percentile(finite, [lo_pct, hi_pct])
    return np.clip((a - lo) / (hi - lo), 0, 1) if hi > lo else np.full_like(a, 0.5)


def _varies(values) -> bool:
    return values is not None and len(values) > 0 and int(np.max(values)) != int(np.min(values))


def scene_image(view: TopView, cloud) -> tuple[np.ndarray, str]:
    """(rows, cols, 3) float image of the scene and what it shows."""
    if cloud.rgb is not None:
        rgb = cloud.rgb8()
        image = np.stack([view.fill(view.mean(rgb[:, k])) for k in range(3)], axis=-1)
        finite = np.isfinite(image[..., 0])
        lo, hi = np.percentile(image[finite], [0.5, 99.5]) if finite.any() else (0.0, 255.0)
        image = np.clip((image - lo) / max(hi - lo, 1e-6), 0, 1)
        what = "its colours (RGB)"
    else:
        from matplotlib.colors import LightSource

        z = view.fill(view.maximum(cloud.xyz[:, 2]))
        filled = np.where(np.isfinite(z), z, np.nanmin(z) if np.isfinite(z).any() else 0.0)
        if min(filled.shape) >= 2:
            shade = LightSource(azdeg=315, altdeg=45).hillshade(filled, vert_exag=1.0, dx=view.pixel, dy=view.pixel)
        else:       # a view one pixel wide or high (a few points, a line of them) has no slope to shade
            shade = np.full(filled.shape, 0.5)
        if _varies(cloud.intensity):
            grey = _stretch(view.fill(view.mean(cloud.intensity)), 2, 98)
            grey = np.where(np.isfinite(grey), grey, 0.5) * (0.45 + 0.55 * shade)
            what = "intensity, shaded by height"
        else:
            grey = 0.15 + 0.8 * shade
            what = "height, shaded"
        image = np.repeat(grey[..., None], 3, axis=-1)
    image[~view.covered] = EMPTY
    return image, what


def _muted(image: np.ndarray) -> np.ndarray:
    """The scene in grey, darker, so that strong colours stand out on it."""
    grey = image @ np.array([0.299, 0.587, 0.114])
    return np.repeat((0.12 + 0.6 * grey)[..., None], 3, axis=-1)


def _paint(base: np.ndarray, where: np.ndarray, colour: np.ndarray, alpha: float = OVERLAY_ALPHA) -> None:
    base[where] = (1 - alpha) * base[where] + alpha * colour


# ----------------------------------------------------------------------------------- figure

def _nice_length(span: float) -> float:
    raw = span / 5
    power = 10 ** math.floor(math.log10(raw))
    return max(m * power for m in (1, 2, 5, 10) if m * power <= raw) if raw > 0 else 1.0


def _panel(ax, image, view: TopView, title: str, legend: list[tuple[np.ndarray, str]]) -> None:
    from matplotlib.patches import Patch
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    x0, x1, y0, y1 = view.extent
    ax.imshow(image, extent=(x0, x1, y0, y1), interpolation="nearest", origin="upper")
    ax.set_title(title, fontsize=13, fontweight="bold", loc="left")
    ax.set_xticks([])
    ax.set_yticks([])
    length = _nice_length(x1 - x0)
    bar = AnchoredSizeBar(ax.transData, length, f"{length:g} m", "lower left", pad=0.4, sep=4,
                          color="black", frameon=True, size_vertical=(y1 - y0) / 150, fontproperties={"size": 11})
    bar.patch.set_alpha(0.8)
    ax.add_artist(bar)
    handles = [Patch(facecolor=c, edgecolor="black", linewidth=0.5, label=text) for c, text in legend]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.01), frameon=False, fontsize=11.5,
              handlelength=1.2, borderaxespad=0.2, labelspacing=0.3)


def top_view_png(path, cloud, predicted: np.ndarray, *, truth: np.ndarray | None = None,
                 target: str = "road", title: str = "") -> dict:
    """Write the top view of ``cloud`` with the ``predicted`` points (bool per point) laid over it;
    with ``truth`` (bool per point) scene / truth / prediction / errors panels. Returns what was
    drawn: pixel size, extent, stray points left out, counts."""
    # the figure API and the Agg canvas, not pyplot: importing pyplot costs ~0.5 s per process
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    predicted = np.asarray(predicted, bool)
    view = TopView(cloud.xyz[:, :2])
    base, what = scene_image(view, cloud)
    muted = _muted(base)
    muted[~view.covered] = EMPTY
    shown = view.covered

    def share(mask):
        return view.fill(view.mean(mask.astype(np.float64)))

    facts = {"pixel": view.pixel, "spacing": view.scene.spacing, "size_px": [view.cols, view.rows],
             "stray_points": view.scene.stray, "points": cloud.n, "predicted": int(predicted.sum())}
    scene_legend = [(np.array([0.8, 0.8, 0.8]), f"{cloud.n:,} points, spacing {view.scene.spacing:.2g} m, "
                                                f"pixel {view.pixel:.2g} m")]
    if view.scene.stray:
        plural = "s" if view.scene.stray > 1 else ""
        scene_legend.append((EMPTY, f"{view.scene.stray:,} stray point{plural} outside the view"))
    panels = [("scene: " + what, base, scene_legend)]
    pred_img = muted.copy()
    _paint(pred_img, (share(predicted) >= 0.5) & shown, TARGET)
    if truth is None:
        panels.append((f"result: {target}", pred_img, [(TARGET, f"{target}: {int(predicted.sum()):,} points")]))
    else:
        from roadx_ti.metrics import scores

        truth = np.asarray(truth, bool)
        s = scores(truth, predicted)
        cm = s["confusion"]
        truth_img = muted.copy()
        _paint(truth_img, (share(truth) >= 0.5) & shown, TARGET)
        shares = np.stack([share(truth & predicted), share(truth & ~predicted), share(~truth & predicted),
                           share(~truth & ~predicted)], axis=-1)
        kind = np.argmax(np.nan_to_num(shares, nan=-1.0), axis=-1)
        err_img = muted.copy()
        for k, colour in enumerate((CORRECT, MISSED, FALSE)):
            _paint(err_img, (kind == k) & shown, colour, alpha=0.9)
        panels += [
            ("truth", truth_img, [(TARGET, f"{target} (truth): {s['truth_positive']:,} points")]),
            ("prediction", pred_img, [(TARGET, f"{target} (predicted): {s['predicted_positive']:,} points")]),
            ("errors", err_img, [(CORRECT, f"{target} found: {cm['a']:,}"),
                                 (MISSED, f"type I, {target} missed: {cm['b']:,} ({100 * s['type1']:.2f} %)"),
                                 (FALSE, f"type II, taken for {target}: {cm['c']:,} ({100 * s['type2']:.2f} %)")]),
        ]
        facts.update({k: cm[k] for k in "abcd"})
    grid_rows = (len(panels) + 1) // 2
    aspect = min(view.rows / view.cols, MAX_PANEL_ASPECT)
    legend_lines = [max(len(p[2]) for p in panels[2 * r:2 * r + 2]) for r in range(grid_rows)]
    height = sum(PANEL_INCHES * aspect + 0.4 + 0.22 * lines for lines in legend_lines) + (0.35 if title else 0)
    fig = Figure(layout="constrained", figsize=(2 * PANEL_INCHES + 0.3, height))
    FigureCanvasAgg(fig)
    axes = fig.subplots(grid_rows, 2, squeeze=False)
    fig.get_layout_engine().set(h_pad=0.1, w_pad=0.08)     # inches between title, panels and legends
    for ax, (name, image, legend) in zip(axes.flat, panels):
        _panel(ax, image, view, name, legend)
    if title:
        # a file name that is not UTF-8 arrives with surrogate escapes, which the renderer refuses
        fig.suptitle(title.encode("utf-8", "surrogateescape").decode("utf-8", "replace"), fontsize=14, fontweight="bold")
    _save_png(fig, path)
    return facts


def _save_png(fig, path) -> None:
    """The figure as a 256-colour PNG (a quarter of the bytes of full colour for photo-like
    scenes: 0.58 against 2.4 MB for the demo), atomically. Rendered straight to pixels (no PNG
    encoded and decoded on the way) and written with zlib's default effort: 1.7 -> 0.6 s for the
    4 M-point scene's picture, 3 % more bytes than with PIL's optimize."""
    import numpy as np
    from PIL import Image

    fig.set_dpi(DPI)
    fig.set_facecolor("white")
    fig.canvas.draw()
    pixels = np.asarray(fig.canvas.buffer_rgba())[..., :3]
    image = Image.fromarray(np.ascontiguousarray(pixels)).quantize(256, method=Image.Quantize.FASTOCTREE)
    with atomic_output(path) as tmp:
        image.save(tmp, format="PNG")
