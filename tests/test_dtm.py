"""The cloth as a DTM raster: GeoTIFF with the input's CRS, .asc (+ .prj), .npy + .json transform;
cropped to the occupied space."""
import json

import numpy as np
import pytest
import rasterio
from rasterio.crs import CRS

from roadx_ti import config, dtm
from roadx_ti.kernels.cloth import csf
from tests.cli_helpers import message_lines, run_cli, write_las, write_tiny_config

LAMBERT93 = CRS.from_epsg(2154)


@pytest.fixture(scope="module")
def flat_cloth(ti_arch):
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 20, (20000, 2))
    z = 0.5 + rng.normal(0, 0.01, len(xy))                  # flat ground 0.5 m above the origin
    xyz = np.column_stack([xy, z]).astype(np.float32)
    return xyz, csf(xyz, cloth_resolution=1.0)


@pytest.fixture(scope="module")
def sloped_with_stray(ti_arch):
    """A 30 x 20 m slope (z = 0.5 + 0.1 x) and one stray point 400 m east of it."""
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, [30, 20], (30000, 2))
    xy[0] = [430.0, 10.0]
    z = 0.5 + 0.1 * xy[:, 0] + rng.normal(0, 0.01, len(xy))
    z[0] = 43.5
    xyz = np.column_stack([xy, z]).astype(np.float32)
    return xyz, csf(xyz, cloth_resolution=1.0)


def test_npy_and_asc_hold_the_cloth_in_world_coordinates(flat_cloth, tmp_path):
    xyz, result = flat_cloth
    origin = np.array([500000.0, 4500000.0, 100.0])
    dtm.write(tmp_path / "d.npy", result, origin)
    dtm.write(tmp_path / "d.asc", result, origin, crs=LAMBERT93)
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
    # the .prj beside the grid holds the CRS (ESRI WKT), and GDAL reads both as one raster
    assert "Lambert_93" in (tmp_path / "d.prj").read_text()
    with rasterio.open(tmp_path / "d.asc") as src:
        assert src.crs.to_epsg() == 2154 and src.shape == result.cloth_z.shape


def test_geotiff_round_trip_holds_the_cloth_the_crs_and_only_the_occupied_space(sloped_with_stray, tmp_path):
    xyz, result = sloped_with_stray
    origin = np.array([770000.0, 6277000.0, 20.0])
    assert result.cloth_z.shape[1] > 400              # the cloth spans the stray point
    t = dtm.write(tmp_path / "d.tif", result, origin, xy=xyz[:, :2], crs=LAMBERT93)
    with rasterio.open(tmp_path / "d.tif") as src:
        assert src.crs == LAMBERT93
        assert src.res == (1.0, 1.0) and src.nodata == dtm.NODATA and src.dtypes == ("float32",)
        band = src.read(1, masked=True)
        # sized by the occupied 30 x 20 m, not the 430 m box of the stray point (+ a cell of reach)
        assert 30 <= src.width <= 34 and 20 <= src.height <= 24, src.shape
        # every valid cell is the cloth's height in world z at that cell's centre
        rows, cols = np.nonzero(~band.mask)
        xs, ys = rasterio.transform.xy(src.transform, rows, cols)
    col = np.rint((np.asarray(xs) - origin[0] - result.x0) / result.resolution).astype(int)
    row = np.rint((np.asarray(ys) - origin[1] - result.y0) / result.resolution).astype(int)
    np.testing.assert_allclose(band.data[rows, cols], result.cloth_z[row, col] + origin[2], atol=1e-4)
    # ... and lies on the slope under the points, in world coordinates
    inside = (np.asarray(xs) > origin[0] + 2) & (np.asarray(xs) < origin[0] + 28)
    slope = 20.5 + 0.1 * (np.asarray(xs)[inside] - origin[0])
    np.testing.assert_allclose(band.data[rows, cols][inside], slope, atol=0.15)
    assert t["valid_cells"] == len(rows) >= 0.9 * 30 * 20


def test_geotiff_without_a_crs_has_none(flat_cloth, tmp_path):
    xyz, result = flat_cloth
    dtm.write(tmp_path / "d.tif", result, np.zeros(3), xy=xyz[:, :2], crs=None)
    with rasterio.open(tmp_path / "d.tif") as src:
        assert src.crs is None and src.read(1).max() == pytest.approx(0.5, abs=0.05)


def test_ground_run_writes_a_geotiff_with_the_las_crs_or_says_there_is_none(tmp_path):
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 40, (6000, 2))
    ground = np.column_stack([xy[:, 0] + 770000, xy[:, 1] + 6277000, 30 + 0.05 * xy[:, 0]])
    box = (np.abs(xy - 20) < 5).all(axis=1)
    ground[box, 2] += 6.0                                   # a 10 x 10 m building
    write_las(tmp_path / "crs.las", ground, crs_wkt=LAMBERT93.to_wkt())
    write_las(tmp_path / "plain.las", ground)
    cfg = write_tiny_config(tmp_path, "pipeline: ground\noutput: {report_png: false}\nstages:\n"
                                      "  - cloth_ground: {cloth_resolution: 1.0, iterations: 200}\n")
    for name in ("crs", "plain"):
        proc = run_cli("run", cfg, "--backend", "cpu", "--input", tmp_path / f"{name}.las",
                       "--output", tmp_path / "out" / f"{name}.laz")
        assert proc.returncode == 0, proc.stderr
        warnings = [line for line in message_lines(proc.stderr) if "CRS" in line]
        with rasterio.open(tmp_path / "out" / f"{name}.dtm.tif") as src:
            if name == "crs":
                assert src.crs == LAMBERT93 and not warnings
            else:
                assert src.crs is None and len(warnings) == 1 and "has no CRS" in warnings[0]
            # the building is not in the terrain: the cloth spans it at the ground's height
            centre = src.read(1)[src.index(770020.0, 6277020.0)]
            assert centre == pytest.approx(31.0, abs=0.3)
        summary = json.loads((tmp_path / "out" / f"{name}.summary.json").read_text())
        assert summary["dtm"]["crs"] == ("EPSG:2154" if name == "crs" else None)


def test_other_formats_are_config_errors():
    with pytest.raises(config.ConfigError, match="output.dtm"):
        config.from_mapping({"pipeline": "ground", "output": {"dtm": "x.png"}})
    cfg = config.from_mapping({"pipeline": "ground", "output": {"path": "o/r.copc.laz"}})
    assert str(cfg.dtm_path()) == "o/r.dtm.tif"
    assert config.from_mapping({"pipeline": "road"}).dtm_path() is None
    assert config.from_mapping({"pipeline": "road", "output": {"dtm": True}}).dtm_path().name == "result.dtm.tif"
