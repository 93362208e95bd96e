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


def test_a_tiled_run_writes_the_mosaic_of_its_tiles_cloths(tmp_path):
    """A tiled ground run (two files, tiles of 15 m, in process and on two Dask workers) writes one
    DTM, the mosaic of its tiles' core cells (their cloths share one world lattice): the untiled
    run's raster, same grid and cells with data, with the files' CRS; heights within 2 cm on 98 %
    of the cells (measured 98.6 %: where the last, 3 m wide column of tiles ends at the data's edge
    its cloth's edge sags otherwise, by up to 17 cm), the same in process and on workers."""
    rng = np.random.default_rng(4)
    xy = rng.uniform(0, 48, (12000, 2))
    ground = np.column_stack([xy[:, 0] + 770000, xy[:, 1] + 6277000,
                              30 + 0.05 * xy[:, 0] + 0.3 * np.sin(xy[:, 1] / 7.0)])
    box = (np.abs(xy - 24) < 5).all(axis=1)
    ground[box, 2] += 6.0                                   # a 10 x 10 m building
    west = xy[:, 0] < 24
    write_las(tmp_path / "west.las", ground[west], crs_wkt=LAMBERT93.to_wkt())
    write_las(tmp_path / "east.las", ground[~west], crs_wkt=LAMBERT93.to_wkt())
    cfg = write_tiny_config(tmp_path, "pipeline: ground\noutput: {report_png: false}\nstages:\n"
                                      "  - cloth_ground: {cloth_resolution: 1.0, iterations: 200}\n")
    runs = {"untiled": [], "one_tile": ["--tile-size", "inf"], "tiled": ["--tile-size", "15"],
            "workers": ["--tile-size", "15", "--workers", "2"]}
    rasters = {}
    for name, extra in runs.items():
        proc = run_cli("run", cfg, "--backend", "cpu", "--input", tmp_path / "west.las", tmp_path / "east.las",
                       "--output", tmp_path / name / "ground.laz", *extra)
        assert proc.returncode == 0, proc.stderr
        lines = [line for line in message_lines(proc.stderr) if "DTM" in line]
        assert len(lines) == 1 and "wrote DTM" in lines[0], lines     # no warning about it
        with rasterio.open(tmp_path / name / "ground.dtm.tif") as src:
            rasters[name] = (src.read(1, masked=True), src.transform, src.crs)
        summary = json.loads((tmp_path / name / "ground.summary.json").read_text())
        assert summary["dtm"]["crs"] == "EPSG:2154"
    base, base_transform, _ = rasters["untiled"]
    for name in ("one_tile", "tiled", "workers"):
        heights, transform, crs = rasters[name]
        assert crs == LAMBERT93
        assert heights.shape == base.shape
        assert transform.almost_equals(base_transform, precision=1e-6)
        np.testing.assert_array_equal(heights.mask, base.mask)
        diff = np.abs(heights - base).compressed()
        assert np.mean(diff < 0.02) > 0.98 and diff.max() < 0.25, (name, np.mean(diff < 0.02), diff.max())
    np.testing.assert_array_equal(rasters["tiled"][0], rasters["workers"][0])


def test_mosaic_lays_pieces_on_their_lattice_and_leaves_far_parts_out():
    """Pieces on one 0.5 m lattice (corners carrying float32-sized rounding) are pasted at their
    lattice cells; a piece more than 100 m from the others (a stray point's tile) is left out, so
    the raster is not sized by the gap."""
    def piece(col, row, heights, noise=0.0):
        t = {"x_lower_left": (col - 0.5) * 0.5 + noise, "y_lower_left": (row - 0.5) * 0.5 - noise,
             "cell_size": 0.5, "rows": heights.shape[0], "cols": heights.shape[1], "row_order": "south_to_north",
             "z_offset": 0.0}
        return np.asarray(heights, np.float32), np.ones(np.shape(heights), bool), t      # all core
    west = piece(1000, 2000, np.full((3, 4), 1.0), 3e-5)
    east = piece(1004, 2001, np.array([[2.0, np.nan], [2.0, 2.0]]), -2e-5)
    far = piece(1004 + 20000, 2000, np.full((2, 2), 9.0))
    heights, t, left_out = dtm.mosaic([west, east, far])
    assert left_out == 1 and heights.shape == (3, 6)
    assert t["x_lower_left"] == pytest.approx(999.5 * 0.5) and t["y_lower_left"] == pytest.approx(1999.5 * 0.5)
    np.testing.assert_array_equal(heights[:, :4], 1.0)
    np.testing.assert_array_equal(heights[1:, 4:], [[2.0, np.nan], [2.0, 2.0]])
    assert np.isnan(heights[0, 4:]).all()
    # overlapping pieces: a cell comes from the piece whose core holds it, else from the first
    a = (np.full((1, 3), 1.0, np.float32), np.array([[True, False, False]]), piece(0, 0, np.zeros((1, 3)))[2])
    b = (np.full((1, 3), 2.0, np.float32), np.array([[False, False, True]]), piece(1, 0, np.zeros((1, 3)))[2])
    np.testing.assert_array_equal(dtm.mosaic([a, b])[0], [[1.0, 1.0, 1.0, 2.0]])
    np.testing.assert_array_equal(dtm.mosaic([b, a])[0], [[1.0, 2.0, 2.0, 2.0]])
    b[1][0, 1] = True           # cell 2 now in b's core: b's whatever the order
    np.testing.assert_array_equal(dtm.mosaic([a, b])[0], [[1.0, 1.0, 2.0, 2.0]])


def test_other_formats_are_config_errors():
    with pytest.raises(config.ConfigError, match="output.dtm"):
        config.from_mapping({"pipeline": "ground", "output": {"dtm": "x.png"}})
    cfg = config.from_mapping({"pipeline": "ground", "output": {"path": "o/r.copc.laz"}})
    assert str(cfg.dtm_path()) == "o/r.dtm.tif"
    assert config.from_mapping({"pipeline": "road"}).dtm_path() is None
    assert config.from_mapping({"pipeline": "road", "output": {"dtm": True}}).dtm_path().name == "result.dtm.tif"
