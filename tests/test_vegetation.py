"""COM vegetation index against hand-computed values, a float64 numpy reference and real colours."""
import numpy as np
import pytest

from roadx_ti.kernels import vegetation

# Hand-computed rows (chromatic r, g, b; then ExG, ExGR, CIVE, VEG; COM):
# grey (100, 100, 100): r = g = b = 1/3
#   ExG = 0; ExGR = 0 - (1.4/3 - 1/3) = -0.133333; CIVE = 0.015/3 + 18.78745 = 18.79245;
#   VEG = (1/3) / (1/3)^(0.667 + 0.333) = 1
#   COM = 0.30 * -0.133333 + 0.33 * 18.79245 + 0.12 * 1 = -0.04 + 6.2015085 + 0.12 = 6.2815085
# black (0, 0, 0): taken as neutral grey -> 6.2815085
# pure green (0, 200, 0): r = b = 0 (floored at 0.01 in VEG), g = 1
#   ExG = 2; ExGR = 2 - (0 - 1) = 3; CIVE = -0.811 + 18.78745 = 17.97645; VEG = 1 / 0.01 = 100
#   COM = 0.5 + 0.9 + 5.9322285 + 12 = 19.3322285
# pure red (255, 0, 0): r = 1, g = b = 0
#   ExG = -1; ExGR = -1 - 1.4 = -2.4; CIVE = 0.441 + 18.78745 = 19.22845; VEG = 0 / ... = 0
#   COM = -0.25 - 0.72 + 6.3453885 + 0 = 5.3753885
# red tile roof (150, 100, 100): sum 350, r = 3/7, g = b = 2/7
#   ExG = 4/7 - 3/7 - 2/7 = -1/7 = -0.1428571; ExGR = -1/7 - (4.2/7 - 2/7) = -3.2/7 = -0.4571429
#   CIVE = (1.323 - 1.622 + 0.770) / 7 + 18.78745 = 0.471/7 + 18.78745 = 18.8547357
#   VEG = (2/7) / ((3/7)^0.667 * (2/7)^0.333) = 0.2857143 / (0.5682762 * 0.6589089) = 0.7630397
#   COM = -0.0357143 - 0.1371429 + 6.2220628 + 0.0915648 = 6.1407704
HAND_TABLE = [
    ((100, 100, 100), 6.2815085),
    ((0, 0, 0), 6.2815085),
    ((0, 200, 0), 19.3322285),
    ((255, 0, 0), 5.3753885),
    ((150, 100, 100), 6.1407704),
]


def reference_com(rgb):
    rgb = np.asarray(rgb, np.float64)
    total = rgb.sum(axis=1)
    chroma = np.where(total[:, None] > 0, rgb / np.where(total > 0, total, 1)[:, None], 1 / 3)
    r, g, b = chroma.T
    exg = 2 * g - r - b
    exgr = exg - (1.4 * r - g)
    cive = 0.441 * r - 0.811 * g + 0.385 * b + 18.78745
    veg = g / (np.maximum(r, 0.01) ** 0.667 * np.maximum(b, 0.01) ** 0.333)
    return 0.25 * exg + 0.30 * exgr + 0.33 * cive + 0.12 * veg


def test_hand_table(ti_arch):
    rgb = np.array([row for row, _ in HAND_TABLE], np.float32)
    expected = np.array([value for _, value in HAND_TABLE])
    com = vegetation.com_index(rgb)
    assert com.dtype == np.float32
    np.testing.assert_allclose(com, expected, rtol=0, atol=2e-5)
    np.testing.assert_allclose(reference_com(rgb), expected, rtol=0, atol=2e-7)


def test_random_colours_match_float64_reference_and_scale_free(ti_arch):
    rng = np.random.default_rng(3)
    rgb8 = rng.integers(0, 256, (2000, 3)).astype(np.float32)
    com8 = vegetation.com_index(rgb8)
    np.testing.assert_allclose(com8, reference_com(rgb8), rtol=0, atol=1e-4)
    com16 = vegetation.com_index((rgb8 * 257).astype(np.uint16))
    np.testing.assert_allclose(com16, com8, rtol=0, atol=1e-4)


def test_vegetation_mask_threshold(ti_arch):
    rgb = np.array([[100, 100, 100], [40, 90, 30], [150, 100, 100], [0, 200, 0]], np.float32)
    mask = vegetation.vegetation_mask(rgb, vegetation.DEFAULT_COM_THRESHOLD)
    assert mask.dtype == np.uint8
    np.testing.assert_array_equal(mask, [0, 1, 0, 1])
    com = vegetation.com_index(rgb)
    np.testing.assert_array_equal(vegetation.vegetation_mask(rgb, 6.2), (com > 6.2).astype(np.uint8))


def test_real_vegetation_scores_higher_than_roofs(ti_arch, shared_data):
    """The direction stated in the module docstring, on the IGN tile: class 1 (mostly vegetation)
    has a higher median COM than class 6 (building), and the default threshold separates them."""
    laspy = pytest.importorskip("laspy")
    las = laspy.read(shared_data / "roof" / "ign_870000_6618000.las")
    rgb = np.column_stack([las.red, las.green, las.blue])
    cls = np.asarray(las.classification)
    com = vegetation.com_index(rgb)
    np.testing.assert_allclose(com[:5000], reference_com(rgb[:5000]), rtol=0, atol=1e-4)
    median_other, median_roof = np.median(com[cls == 1]), np.median(com[cls == 6])
    assert median_other > median_roof + 0.05
    mask = vegetation.vegetation_mask(rgb).astype(bool)
    assert mask[cls == 1].mean() > 0.5 and mask[cls == 6].mean() < 0.15
