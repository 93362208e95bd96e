"""The cloth of the cloth simulation filter as a DTM raster.

Formats: ``.tif`` / ``.tiff`` (GeoTIFF through rasterio, float32, deflate, with the input's CRS),
``.asc`` (ESRI ASCII grid, with a ``.prj`` holding the CRS: GDAL, QGIS and ArcGIS read both) and
``.npy`` (float32 heights, row 0 = south, NaN where there is no data, with a ``.json`` sidecar
holding the world transform and the CRS as WKT). Particles are cell centres: cell (row, col)
covers world x in [x_ll + col*res, x_ll + (col+1)*res).

Given the points (``xy``), the raster covers the occupied space only: the cells within
``footprint.scene``'s cell size of a point of the scene (stray groups of points left out); the
grid is cropped to them and every other cell is nodata. The cloth itself spans the bounding box
of the points it was run on, buffer included.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from roadx_ti import jsonio
from roadx_ti.io.atomic import atomic_output

FORMATS = (".tif", ".tiff", ".asc", ".npy")
NODATA = -9999.0
log = logging.getLogger("roadx_ti")


def transform(result, origin, window=None) -> dict:
    """World placement of the cloth grid, or of ``window`` = (row0, col0, rows, cols) of it
    (float64 math on the cloud's origin)."""
    res = float(result.resolution)
    row0, col0, rows, cols = window or (0, 0, *result.cloth_z.shape)
    return {"x_lower_left": float(origin[0]) + float(result.x0) + (col0 - 0.5) * res,
            "y_lower_left": float(origin[1]) + float(result.y0) + (row0 - 0.5) * res,
            "cell_size": res, "rows": int(rows), "cols": int(cols), "row_order": "south_to_north",
            "z_offset": float(origin[2])}


def occupied_window(result, xy: np.ndarray):
    """(window (row0, col0, rows, cols), valid bool (rows, cols)): the cloth cells within the
    scene's cell size of one of its points, and the smallest window of the grid holding them."""
    from scipy.ndimage import binary_dilation

    from roadx_ti import footprint

    rows, cols = result.cloth_z.shape
    res = float(result.resolution)
    scene = footprint.scene(xy)
    for pts in (np.asarray(xy)[scene.keep, :2], np.asarray(xy)[:, :2]):
        # the scene's points, or, where none lie under this cloth (a cloud of scattered single
        # points: the cloth is over its largest part, the scene another), all of them
        pts = pts.astype(np.float64)
        c = np.rint((pts[:, 0] - result.x0) / res).astype(np.int64)
        r = np.rint((pts[:, 1] - result.y0) / res).astype(np.int64)
        inside = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        c, r = c[inside], r[inside]
        if len(c):
            break
    if len(c) == 0:
        return (0, 0, 0, 0), np.zeros((0, 0), bool)
    reach = max(1, math.ceil(scene.cell / res))
    row0, col0 = max(0, int(r.min()) - reach), max(0, int(c.min()) - reach)
    row1, col1 = min(rows, int(r.max()) + reach + 1), min(cols, int(c.max()) + reach + 1)
    occupied = np.zeros((row1 - row0, col1 - col0), bool)
    occupied[r - row0, c - col0] = True
    valid = binary_dilation(occupied, structure=np.ones((3, 3), bool), iterations=reach)
    return (row0, col0, row1 - row0, col1 - col0), valid


def grid(result, origin, xy: np.ndarray | None = None):
    """(heights, transform): the cloth of ``result`` (a ClothResult on a cloud with local
    ``origin``) as world heights (float64 (rows, cols), row 0 south, NaN off the occupied space),
    cropped to the cells within the scene's cell size of a point of ``xy`` (the cloud's local xy;
    None: the whole cloth)."""
    if xy is None:
        window = (0, 0, *result.cloth_z.shape)
        valid = np.ones(result.cloth_z.shape, bool)
    else:
        window, valid = occupied_window(result, xy)
    row0, col0, rows, cols = window
    t = transform(result, origin, window)
    heights = result.cloth_z[row0:row0 + rows, col0:col0 + cols].astype(np.float64) + t["z_offset"]
    heights[~valid] = np.nan
    return heights, t


def core_piece(result, origin, xy: np.ndarray, core):
    """``grid(result, origin, xy)`` (a tile's cloth over its window's points), cropped to its cells
    with data, with a mask of the cells whose centres lie in the world rectangle ``core`` = (x0, y0,
    x1, y1), half-open (the tile's core: the cores of a survey's tiles share no cell):
    (float32 heights, bool in_core, transform), or None without any cell with data. ``mosaic``
    takes each cell from the tile whose core holds it, and a cell no core holds (beyond the core
    grid's edge, or in a core cell without a tile: the rim of the occupied space) from the first
    tile that has it."""
    heights, t = grid(result, origin, xy)
    finite = np.isfinite(heights)
    rows, cols = np.flatnonzero(finite.any(axis=1)), np.flatnonzero(finite.any(axis=0))
    if not len(rows):
        return None
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    res = t["cell_size"]
    t = dict(t, x_lower_left=t["x_lower_left"] + c0 * res, y_lower_left=t["y_lower_left"] + r0 * res,
             rows=int(r1 - r0), cols=int(c1 - c0))
    cx = t["x_lower_left"] + (np.arange(t["cols"]) + 0.5) * res
    cy = t["y_lower_left"] + (np.arange(t["rows"]) + 0.5) * res
    in_core = ((cy >= core[1]) & (cy < core[3]))[:, None] & ((cx >= core[0]) & (cx < core[2]))[None, :]
    return heights[r0:r1, c0:c1].astype(np.float32), in_core, t


def mosaic(pieces, gap: float = 100.0):
    """(float32 heights, transform, pieces left out): one grid of ``pieces`` [(heights, in_core,
    transform)] cut from cloths on one world lattice (the cloth stages' align_to_world: cell centres
    at world multiples of the cell size), a tiled run's core_pieces in tile order: each cell from
    the piece whose core holds it, else from the first piece with data there; NaN where none has
    any. Pieces within ``gap`` (m) of each other form one part, and only the part with the most
    cells with data is laid (an untiled run's DTM covers its largest part too): a raster over
    parts kilometres apart, or over a stray point's tile, would be sized by the gap."""
    res = pieces[0][-1]["cell_size"]
    # the lattice index of each piece's first cell centre (float32 rounding of the cloth's own
    # corner moves it by far less than a cell)
    at = [(int(round(t["x_lower_left"] / res + 0.5)), int(round(t["y_lower_left"] / res + 0.5))) for *_, t in pieces]
    part = _parts([(c, r, c + t["cols"], r + t["rows"]) for (c, r), (*_, t) in zip(at, pieces)], gap / res)
    cells = np.bincount(part, weights=[np.isfinite(h).sum() for h, *_ in pieces])
    keep = part == int(np.argmax(cells))
    left_out = int((~keep).sum())
    at = [a for a, k in zip(at, keep) if k]
    pieces = [p for p, k in zip(pieces, keep) if k]
    c_min = min(c for c, _ in at)
    r_min = min(r for _, r in at)
    cols = max(c + t["cols"] for (c, _), (*_, t) in zip(at, pieces)) - c_min
    rows = max(r + t["rows"] for (_, r), (*_, t) in zip(at, pieces)) - r_min
    out = np.full((rows, cols), np.nan, np.float32)     # the GeoTIFF's type: half the memory
    for core_pass in (False, True):
        # first the cells outside each piece's core (the first piece with data wins), then the
        # core cells, which no two pieces share
        for (c, r), (h, in_core, t) in zip(at, pieces):
            window = out[r - r_min:r - r_min + t["rows"], c - c_min:c - c_min + t["cols"]]
            take = np.isfinite(h) & (in_core if core_pass else ~in_core & np.isnan(window))
            np.copyto(window, h, where=take)
    t = dict(pieces[0][-1], x_lower_left=(c_min - 0.5) * res, y_lower_left=(r_min - 0.5) * res,
             rows=int(rows), cols=int(cols))
    return out, t, left_out


def _parts(boxes, gap: float) -> np.ndarray:
    """Part index per box (c0, r0, c1, r1), half-open, in cells: boxes less than ``gap`` cells apart
    (the larger of the two axes' gaps) are one part. Candidate pairs from a kd-tree of the boxes'
    centres (a run has one box per tile: thousands of tiles make no all-pairs matrix)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    centre = 0.5 * (b[:, :2] + b[:, 2:])
    half = 0.5 * (b[:, 2:] - b[:, :2])
    # boxes closer than the gap have centres within the gap plus two half-extents (Chebyshev)
    pairs = cKDTree(centre).query_pairs(gap + 2.0 * float(half.max(initial=0.0)), p=np.inf, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    gx = np.maximum(b[i, 0] - b[j, 2], b[j, 0] - b[i, 2])
    gy = np.maximum(b[i, 1] - b[j, 3], b[j, 1] - b[i, 3])
    near = np.maximum(gx, gy) < gap
    i, j = i[near], j[near]
    _, part = connected_components(coo_matrix((np.ones(len(i)), (i, j)), shape=(len(b), len(b))), directed=False)
    return part


def write(path, result, origin, *, xy: np.ndarray | None = None, crs=None) -> dict | None:
    """Write the cloth of ``result`` (a ClothResult on a cloud with local ``origin``) to ``path``.
    ``xy``: the cloud's local xy, to crop the raster to the occupied space (None: the whole cloth).
    ``crs``: a rasterio CRS, or None (the GeoTIFF and .asc then carry none). Returns the transform,
    or None (nothing written) when no cell under the points has data."""
    heights, t = grid(result, origin, xy)
    if not np.isfinite(heights).any():
        return None
    return write_grid(path, heights, t, crs)


def write_grid(path, heights: np.ndarray, t: dict, crs=None) -> dict:
    """Write world ``heights`` (row 0 south, NaN = no data) placed by the transform ``t`` to
    ``path`` (one of FORMATS); returns ``t`` with its cells with data counted. Without a CRS a
    GeoTIFF or ASCII grid carries none, which one warning line says."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{path}: DTM formats are {', '.join(FORMATS)}")
    if crs is None and suffix != ".npy":
        log.warning("%s: the input has no CRS, so the DTM carries none", path)
    heights = np.asarray(heights)
    # the heights are world heights: the cloth's local z offset is in them already (the .npy's
    # sidecar carried it, 20 m untiled and 0 tiled for the same heights)
    t = {k: v for k, v in t.items() if k != "z_offset"} | {"valid_cells": int(np.isfinite(heights).sum())}
    if suffix == ".npy":
        with atomic_output(path) as tmp:
            np.save(tmp, heights.astype(np.float32))
        with atomic_output(path.with_suffix(".json")) as tmp:
            Path(tmp).write_text(jsonio.dumps(t | {"nodata": "NaN", "crs": crs.to_wkt() if crs else None},
                                            indent=2) + "\n")
        return t
    north_first = np.where(np.isnan(heights), NODATA, heights)[::-1]
    if suffix == ".asc":
        _write_asc(path, north_first, t, crs)
    else:
        _write_geotiff(path, north_first, t, crs)
    return t


def summary(path, t: dict, crs) -> dict:
    """The run summary's 'dtm' entry of a raster written to ``path`` (write / write_grid's ``t``)."""
    keys = ("cell_size", "rows", "cols", "x_lower_left", "y_lower_left", "valid_cells")
    return {"path": str(path), "crs": crs.to_string() if crs else None} | {k: t[k] for k in keys}


def _write_asc(path: Path, north_first: np.ndarray, t: dict, crs) -> None:
    header = (f"ncols {t['cols']}\nnrows {t['rows']}\nxllcorner {t['x_lower_left']:.6f}\n"
              f"yllcorner {t['y_lower_left']:.6f}\ncellsize {t['cell_size']:.6f}\nNODATA_value {NODATA:g}\n")
    with atomic_output(path) as tmp:
        with open(tmp, "w") as f:
            f.write(header)
            np.savetxt(f, north_first, fmt="%.3f")   # ASCII grids list the north row first
    if crs is not None:
        from rasterio.enums import WktVersion

        with atomic_output(path.with_suffix(".prj")) as tmp:
            Path(tmp).write_text(crs.to_wkt(version=WktVersion.WKT1_ESRI) + "\n")


def _write_geotiff(path: Path, north_first: np.ndarray, t: dict, crs) -> None:
    import rasterio
    from rasterio.transform import Affine

    res = t["cell_size"]
    profile = {"driver": "GTiff", "width": t["cols"], "height": t["rows"], "count": 1, "dtype": "float32",
               "nodata": NODATA, "crs": crs,
               "transform": Affine(res, 0.0, t["x_lower_left"], 0.0, -res, t["y_lower_left"] + t["rows"] * res),
               "compress": "deflate", "predictor": 3, "tiled": True, "blockxsize": 256, "blockysize": 256}
    with atomic_output(path) as tmp:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(north_first.astype(np.float32), 1)
            dst.update_tags(AREA_OR_POINT="Area", TIFFTAG_SOFTWARE="roadx_ti (cloth simulation filter)")
            dst.set_band_description(1, "cloth height (DTM)")
