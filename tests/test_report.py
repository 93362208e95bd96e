"""Top-view pictures (roadx_ti.report): rasterised at about the point spacing, clipped to where the
points are, the scene in its colours or shaded, the result over it with counts."""
import time

import matplotlib.image
import numpy as np
import pytest

from roadx_ti import accuracy, report
from roadx_ti.cloud import Cloud
from roadx_ti.metrics import confusion


def street(n, seed=0, side=141.0, colour=True):
    """A flat street scene of ``side`` metres: a road strip (grey) through grass (green), a 6 m
    high block, and one stray point 5 km away."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, side, (n, 2))
    road = np.abs(xy[:, 1] - 0.7 * side) < 4
    block = (np.abs(xy[:, 0] - side / 2) < 15) & (np.abs(xy[:, 1] - 0.3 * side) < 10)
    z = 0.2 * np.sin(xy[:, 0] / 7) + np.where(block, 6.0, 0.0)
    xyz = np.column_stack([xy, z])
    xyz[0] = [5000.0, 5000.0, 0.0]
    road[0] = False
    kw = {}
    if colour:
        kw = {"rgb": np.where(road[:, None], [200, 30, 30], [40, 160, 40]).astype(np.uint16), "color_depth": 8}
    else:
        kw = {"intensity": np.where(road, 900, 300).astype(np.uint16)}
    return Cloud(xyz=xyz.astype(np.float32), origin=np.array([770000.0, 6277000.0, 30.0]), **kw), road


def test_a_4m_point_scene_renders_and_a_stray_point_does_not_shrink_it(tmp_path):
    import matplotlib.pyplot  # noqa: F401  (the one-time library import is not the render)
    import scipy.ndimage  # noqa: F401
    import scipy.sparse.csgraph  # noqa: F401

    cloud, road = street(4_000_000)
    predicted = road ^ (np.random.default_rng(1).random(cloud.n) < 0.02)
    t0 = time.perf_counter()
    facts = report.top_view_png(tmp_path / "big.png", cloud, predicted, truth=road, title="4 M points")
    seconds = time.perf_counter() - t0
    # a guard against rasterising the stray point's 5 km extent (minutes), not a speed claim: the
    # render takes 1-2 s alone, and the suite's other process shares the two cores
    assert seconds < 30.0, f"4 M points took {seconds:.1f} s"
    assert facts["stray_points"] == 1
    # the view is the 141 m scene (not 5 km with the scene as a dot): PANEL_PX pixels across it
    assert report.PANEL_PX - 2 <= max(facts["size_px"]) <= report.PANEL_PX + 1
    assert facts["pixel"] == pytest.approx(141.0 / report.PANEL_PX, rel=0.01)
    cm = confusion(road, predicted)
    assert [facts[k] for k in "abcd"] == [cm[k] for k in "abcd"]
    image = matplotlib.image.imread(tmp_path / "big.png")
    assert image.shape[1] > 1200 and image.shape[0] > 1200        # two columns, two rows of panels


def test_pixels_are_about_the_point_spacing_and_show_the_scene_colours(tmp_path):
    cloud, road = street(40_000, side=60.0)
    view = report.TopView(cloud.xyz[:, :2])
    spacing = np.sqrt(60.0 * 60.0 / cloud.n)
    assert view.scene.spacing == pytest.approx(spacing, rel=0.05)
    assert view.pixel == pytest.approx(report.PIXEL_SPACINGS * spacing, rel=0.05)
    image, what = report.scene_image(view, cloud)
    assert "RGB" in what
    road_pixels = np.bincount(view.index, weights=road[view.scene.keep], minlength=view.rows * view.cols)
    is_road = (road_pixels / np.maximum(view.count, 1) > 0.99).reshape(view.rows, view.cols)
    is_grass = (road_pixels == 0).reshape(view.rows, view.cols) & view.filled.reshape(view.rows, view.cols)
    assert image[is_road].mean(axis=0)[0] > 0.8 and image[is_road].mean(axis=0)[1] < 0.2     # red road
    assert image[is_grass].mean(axis=0)[1] > image[is_grass].mean(axis=0)[0] + 0.3          # green grass
    facts = report.top_view_png(tmp_path / "one.png", cloud, road, target="road")
    assert facts["predicted"] == int(road.sum()) and "a" not in facts
    assert matplotlib.image.imread(tmp_path / "one.png").shape[2] in (3, 4)


def test_without_colour_the_scene_is_shaded_intensity_or_height():
    cloud, _ = street(40_000, side=60.0, colour=False)
    view = report.TopView(cloud.xyz[:, :2])
    image, what = report.scene_image(view, cloud)
    assert what == "intensity, shaded by height"
    flat = Cloud(xyz=cloud.xyz, origin=cloud.origin, intensity=np.zeros(cloud.n, np.uint16))
    image, what = report.scene_image(view, flat)
    assert what == "height, shaded"
    # the 6 m block's edges are shaded differently from the flat ground around them
    assert image[..., 0][view.covered].std() > 0.02


def test_accuracy_dataset_png_on_a_real_tile(shared_data, tmp_path):
    from roadx_ti import io

    cloud = io.read(shared_data / "roof" / "ign_874000_6617000_reviewed.laz")
    truth = cloud.classification == 19
    predicted = truth.copy()
    predicted[: cloud.n // 10] = ~predicted[: cloud.n // 10]       # some errors of both kinds
    path = accuracy.dataset_png(tmp_path, "roof", "IGN reviewed (test)", cloud, truth, predicted)
    assert path.name == "roof_IGN_reviewed__test.png"
    image = matplotlib.image.imread(path)
    assert image.shape[1] > 1200 and image.shape[0] > 600


@pytest.mark.parametrize("shape", ["wall", "corridor"])
def test_a_narrow_north_south_scene_gives_a_picture_of_ordinary_size(tmp_path, shape):
    """A wall (every x equal) or a 10 m x 1 km corridor: the panels are at most MAX_PANEL_ASPECT
    widths high (the figure had grown with the scene's aspect: 410,346 px high for a 50 m wall, 22 GB)."""
    rng = np.random.default_rng(1)
    n = 20_000
    x = np.full(n, 100.0) if shape == "wall" else rng.uniform(0, 10, n)
    y = rng.uniform(0, 50 if shape == "wall" else 1000, n)
    cloud = Cloud.from_world(np.column_stack([x, y, rng.uniform(0, 10, n)]))
    facts = report.top_view_png(tmp_path / "narrow.png", cloud, np.zeros(n, bool), truth=y < 20)
    image = matplotlib.image.imread(tmp_path / "narrow.png")
    limit = 2 * (report.MAX_PANEL_ASPECT * report.PANEL_PX + 200)     # two rows of panels, legends
    assert image.shape[0] < limit and image.shape[1] < 2 * report.PANEL_PX + 200
    assert facts["size_px"][1] <= report.PANEL_PX + 1
