"""The cloth as a DTM raster: .asc (ESRI ASCII grid) and .npy + .json transform."""
import json

import numpy as np
import pytest

from roadx_ti import config, dtm
from roadx_ti.kernels.cloth import csf


@pytest.fixture(scope="module")
def flat_cloth(ti_arch):
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 20, (20000, 2))
    z = 0.5 + rng.normal(0, 0.01, len(xy))                  # flat ground 0.5 m above the origin
    xyz = np.column_stack([xy, z]).astype(np.float32)
    return xyz, csf(xyz, cloth_resolution=1.0)


def test_npy_and_asc_hold_the_cloth_in_world_coordinates(flat_cloth, tmp_path):
    xyz, result = flat_cloth
    origin = np.array([500000.0, 4500000.0, 100.0])
    dtm.write(tmp_path / "d.npy", result, origin)
    dtm.write(tmp_path / "d.asc", result, origin)
    heights = np.load(tmp_path / "d.npy")
    t = json.loads((tmp_path / "d.json").read_text())
    np.testing.assert_allclose(heights, result.cloth_z + 100.0, atol=1e-4)
    assert t["cell_size"] == 1.0 and (t["rows"], t["cols"]) == result.cloth_z.shape
    assert t["x_lower_left"] == pytest.approx(500000.0 + result.x0 - 0.5)
    # the cloth lies on the ground: world height 100.5 under the points
    row, col = t["rows"] // 2, t["cols"] // 2
    assert heights[row, col] == pytest.approx(100.5, abs=0.05)
    lines = (tmp_path / "d.asc").read_text().splitlines()
    assert lines[0] == f"ncols {t['cols']}" and lines[1] == f"nrows {t['rows']}"
    north_row = np.array(lines[6].split(), float)
    np.testing.assert_allclose(north_row, heights[-1], atol=1e-3)


def test_other_formats_are_config_errors():
    with pytest.raises(config.ConfigError, match="output.dtm"):
        config.from_mapping({"pipeline": "ground", "output": {"dtm": "x.tif"}})
