"""The cloth of the cloth simulation filter as a DTM raster.

Formats: ``.asc`` (ESRI ASCII grid: GDAL, QGIS and ArcGIS read it as is) and ``.npy`` (float32
heights, row 0 = south, with a ``.json`` sidecar holding the world transform). Particles are cell
centres: cell (row, col) covers world x in [x_ll + col*res, x_ll + (col+1)*res).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from roadx_ti import jsonio
from roadx_ti.io.atomic import atomic_output

FORMATS = (".asc", ".npy")


def transform(result, origin) -> dict:
    """World placement of the cloth grid (float64 math on the cloud's origin)."""
    res = float(result.resolution)
    rows, cols = result.cloth_z.shape
    return {"x_lower_left": float(origin[0]) + float(result.x0) - res / 2,
            "y_lower_left": float(origin[1]) + float(result.y0) - res / 2,
            "cell_size": res, "rows": int(rows), "cols": int(cols), "row_order": "south_to_north",
            "z_offset": float(origin[2])}


def write(path, result, origin) -> None:
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"{path}: DTM formats are {', '.join(FORMATS)}")
    t = transform(result, origin)
    heights = result.cloth_z.astype(np.float64) + t["z_offset"]
    if path.suffix.lower() == ".npy":
        with atomic_output(path) as tmp:
            np.save(tmp, heights.astype(np.float32))
        sidecar = path.with_suffix(".json")
        with atomic_output(sidecar) as tmp:
            Path(tmp).write_text(jsonio.dumps(t, indent=2) + "\n")
        return
    header = (f"ncols {t['cols']}\nnrows {t['rows']}\nxllcorner {t['x_lower_left']:.6f}\n"
              f"yllcorner {t['y_lower_left']:.6f}\ncellsize {t['cell_size']:.6f}\nNODATA_value -9999\n")
    with atomic_output(path) as tmp:
        with open(tmp, "w") as f:
            f.write(header)
            np.savetxt(f, heights[::-1], fmt="%.3f")   # ASCII grids list the north row first
