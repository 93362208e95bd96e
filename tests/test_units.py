"""Surveys whose CRS counts in feet (roadx_ti.units): the stages run in metres, the outputs keep
the file's units. The CLI on a suburb in metres and on the same suburb in US survey feet gives the
same roofs; without the conversion every length of the config (1 m cloth cells, 10 m2 roofs, 2 m
heights) was read in feet (a real IGN tile in feet: kappa 0.9387 -> 0.7645; converted 0.9390)."""
from __future__ import annotations

import laspy
import numpy as np
import pytest
from rasterio.crs import CRS

from roadx_ti import synthetic, units
from roadx_ti.stages.base import GroundSurface
from tests.cli_helpers import CONFIGS, run_cli, write_las

FOOT_US = 1200.0 / 3937.0


@pytest.mark.parametrize("code, horizontal, vertical", [
    ("EPSG:2263", FOOT_US, FOOT_US),               # NY Long Island (ftUS), heights in the same unit
    ("EPSG:2263+6360", FOOT_US, FOOT_US),          # + NAVD88 height (ftUS)
    ("EPSG:26918+6360", 1.0, FOOT_US),             # UTM 18N in metres, NAVD88 heights in feet
    ("EPSG:2154+5720", 1.0, 1.0),                  # Lambert-93 + NGF-IGN69 (the IGN tiles)
    ("EPSG:4326", 1.0, 1.0),                       # geographic: no factor (geographic_problem decides)
])
def test_metre_factors_read_the_crs(code, horizontal, vertical):
    f = units.metre_factors(CRS.from_user_input(code))
    assert f.horizontal == pytest.approx(horizontal, rel=1e-9)
    assert f.vertical == pytest.approx(vertical, rel=1e-9)
    assert units.metre_factors(None) == units.METRES


def test_in_metres_and_the_surface_back():
    from roadx_ti.kernels.cloth import ClothResult

    cloud = synthetic.generate("als-roof", 2_000, seed=0)
    f = units.Factors(FOOT_US, FOOT_US, "US survey foot")
    metric = units.in_metres(cloud, f)
    np.testing.assert_allclose(metric.xyz, cloud.xyz * FOOT_US, rtol=1e-6)
    np.testing.assert_allclose(metric.origin, cloud.origin * FOOT_US)
    assert units.in_metres(cloud, units.METRES) is cloud
    grid = ClothResult(np.zeros(0, bool), np.full((3, 4), 2.0, np.float32), 1.0, 2.0, 0.5)
    back = units.surface_in_units(GroundSurface(grid, metric.origin, [grid]), f)
    assert back.largest.resolution == pytest.approx(0.5 / FOOT_US)
    assert back.largest.x0 == pytest.approx(1.0 / FOOT_US)
    np.testing.assert_allclose(back.largest.cloth_z, 2.0 / FOOT_US, rtol=1e-6)
    np.testing.assert_allclose(back.origin, cloud.origin, rtol=1e-12)


@pytest.mark.slow
def test_a_survey_in_feet_gets_the_roofs_it_has_in_metres(tmp_path):
    cloud = synthetic.generate("als-roof", 120_000, seed=1)
    world = cloud.xyz.astype(np.float64) + cloud.origin
    metric = write_las(tmp_path / "m.las", world, classification=cloud.classification, scale=0.001,
                       crs_wkt=CRS.from_user_input("EPSG:2154+5720").to_wkt())
    feet = write_las(tmp_path / "f.las", world / FOOT_US, classification=cloud.classification, scale=0.001,
                     crs_wkt=CRS.from_user_input("EPSG:2263+6360").to_wkt())
    outs = {}
    for name, src in (("m", metric), ("f", feet)):
        out = tmp_path / f"{name}_out.laz"
        proc = run_cli("run", CONFIGS / "roof_als.yaml", "--input", src, "--output", out, "--backend", "cpu",
                       "--set", "output.report_png=false", "--set", f"output.dtm={tmp_path / (name + '_dtm.tif')}")
        assert proc.returncode == 0, proc.stderr
        outs[name] = laspy.read(out)
    assert "counts in US survey foot" in proc.stderr
    agree = np.mean(np.asarray(outs["m"].classification) == np.asarray(outs["f"].classification))
    assert agree >= 0.995, agree
    # the file's own coordinates, and the DTM in its units
    np.testing.assert_array_equal(np.asarray(outs["f"].X), np.asarray(laspy.read(feet).X))
    import rasterio
    with rasterio.open(tmp_path / "m_dtm.tif") as m, rasterio.open(tmp_path / "f_dtm.tif") as f:
        assert f.transform.a == pytest.approx(m.transform.a / FOOT_US)
        assert f.transform.c == pytest.approx(m.transform.c / FOOT_US, abs=1e-3)
        zm, zf = m.read(1, masked=True), f.read(1, masked=True)
        assert np.ma.median(zf) * FOOT_US == pytest.approx(np.ma.median(zm), abs=0.01)
