"""Combined vegetation index COM (Guijarro et al. 2011) per point, from RGB (METHODS.md P3).

On chromatic coordinates r = R/(R+G+B), g = G/(R+G+B), b = B/(R+G+B):
    ExG  = 2g - r - b
    ExGR = ExG - (1.4r - g)
    CIVE = 0.441r - 0.811g + 0.385b + 18.78745
    VEG  = g / (r^0.667 * b^0.333)
    COM  = 0.25 ExG + 0.30 ExGR + 0.33 CIVE + 0.12 VEG

CIVE keeps the sign of the source (green gives *low* CIVE), but ExG, ExGR and VEG rise on green
and outweigh it, so **higher COM means more vegetation**. Measured on the IGN Lidar HD tiles in
shared/data/roof (16-bit RGB from orthophotos; the index is scale free, so 8- and 16-bit colour
give the same COM):
    ign_870000_6618000.las          median CIVE: class 1 (mostly vegetation) 18.763, class 6
                                    (building) 18.810; median COM: class 1 6.330, class 6 6.242
                                    COM percentiles 5/25/50/75/95:
                                      class 1 6.231 6.279 6.330 6.403 6.495
                                      class 2 6.239 6.283 6.323 6.365 6.444
                                      class 6 6.182 6.212 6.242 6.276 6.338
    ign_874000_6617000_reviewed.laz class 0 (other, mostly vegetation) 6.248 6.328 6.406 6.472 6.536
                                    class 19 (building)                 6.167 6.181 6.193 6.218 6.317
                                    class 20 (rejected: trees, hedges)  6.275 6.286 6.300 6.340 6.439
Neutral grey (R = G = B) has COM = 0.3 * (-0.4/3) + 0.33 * 18.79245 + 0.12 = 6.28151.

Zero denominators (documented choices):
- R + G + B = 0 (black): the point is taken as neutral, r = g = b = 1/3 (COM of grey).
- VEG: r and b are floored at VEG_CHROMA_FLOOR = 0.01 before the powers, so pure green gives
  VEG = 1 / 0.01 = 100 instead of a division by zero.
"""

from .taichi_compat import ti

from .common import kernel_array, length, like_input, output_array

VEG_CHROMA_FLOOR = 0.01
# default vegetation threshold on COM (points with COM > threshold are vegetation-coloured),
# chosen on the tiles above: grey and 90-95 % of roof points stay below, the median vegetation
# point is above (ign_870000: class 1 59.6 % above, class 6 9.9 %; reviewed tile: class 0 79 %,
# class 19 5.4 %); the end-to-end roof scores peaked between 6.31 and 6.33
DEFAULT_COM_THRESHOLD = 6.31


@ti.func
def _com_of(red: ti.f32, green: ti.f32, blue: ti.f32) -> ti.f32:
    total = red + green + blue
    r = ti.f32(1.0 / 3.0)
    g = ti.f32(1.0 / 3.0)
    b = ti.f32(1.0 / 3.0)
    if total > 0:
        r = red / total
        g = green / total
        b = blue / total
    exg = 2.0 * g - r - b
    exgr = exg - (1.4 * r - g)
    cive = 0.441 * r - 0.811 * g + 0.385 * b + 18.78745
    veg = g / (ti.pow(ti.max(r, VEG_CHROMA_FLOOR), 0.667) * ti.pow(ti.max(b, VEG_CHROMA_FLOOR), 0.333))
    return 0.25 * exg + 0.30 * exgr + 0.33 * cive + 0.12 * veg


@ti.kernel
def _com_index(rgb: ti.types.ndarray(dtype=ti.f32, ndim=2), com: ti.types.ndarray(dtype=ti.f32, ndim=1)):
    for i in com:
        com[i] = _com_of(rgb[i, 0], rgb[i, 1], rgb[i, 2])


@ti.kernel
def _threshold_above(values: ti.types.ndarray(dtype=ti.f32, ndim=1), threshold: ti.f32,
                     mask: ti.types.ndarray(dtype=ti.u8, ndim=1)):
    for i in values:
        mask[i] = ti.u8(1) if values[i] > threshold else ti.u8(0)


def com_index(rgb):
    """COM per point (float32, (n,)) from colour (n, 3) in any unit (8-bit, 16-bit, 0..1).
    Higher = more vegetation (see the module docstring for measured values)."""
    src = kernel_array(rgb, "float32")
    com = output_array(ti.f32, (length(src),), rgb)
    if length(src):
        _com_index(src, com)
    return like_input(com, rgb)


def vegetation_mask(rgb, threshold: float = DEFAULT_COM_THRESHOLD):
    """uint8 (n,): 1 where the point is vegetation-coloured (COM > threshold), else 0."""
    com = kernel_array(com_index(rgb), "float32")
    mask = output_array(ti.u8, (length(com),), rgb)
    if length(com):
        _threshold_above(com, float(threshold), mask)
    return like_input(mask, rgb)


__all__ = ["com_index", "vegetation_mask", "VEG_CHROMA_FLOOR", "DEFAULT_COM_THRESHOLD"]
