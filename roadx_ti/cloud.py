"""Cloud: the point cloud as a struct of arrays with a float64 local origin.

Kernels see ``xyz`` only: float32 coordinates relative to ``origin`` (float64), so that LAS
coordinates of 10^5..10^7 m keep centimetre detail in float32 math. Writers never rebuild
coordinates from ``xyz``: a cloud read from LAS keeps its ``las`` record and is written back from
it bit for bit, with only the classification and the result dimensions changed.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

# values stored_8bit_scale tests at a time
CHUNK = 1 << 22


def stored_8bit_scale(rgb: np.ndarray) -> int:
    """The factor 16-bit colour values carry: 257 when every value is a multiple of 257 (8-bit
    scaled to full range), 256 when every value is a multiple of 256 (8-bit shifted up), else 257
    (genuine 16-bit colour, 65535 full scale). Chunked: no full-size temporary."""
    values = np.asarray(rgb).reshape(-1)
    for factor in (257, 256):
        if all(not np.any(values[start:start + CHUNK] % factor) for start in range(0, len(values), CHUNK)):
            return factor
    return 257


RETURNS_USABLE = "usable"     # Cloud.returns_verdict of returns that tell pulses apart (or none recorded)


@dataclass
class Cloud:
    xyz: np.ndarray                         # (n, 3) float32, world - origin
    origin: np.ndarray                      # (3,) float64
    rgb: np.ndarray | None = None           # (n, 3) uint16, as stored in the file
    color_depth: int = 0                    # 8 or 16 when rgb is set, 0 without colour
    intensity: np.ndarray | None = None     # (n,) uint16
    classification: np.ndarray | None = None  # (n,) uint8: input classes (truth in tests)
    # (n, 2) uint8: LiDAR return number and number of returns of the point's pulse (1-based)
    returns: np.ndarray | None = None
    nir: np.ndarray | None = None           # (n,) uint16: near infrared (LAS point formats 8 and 10)
    attributes: dict = field(default_factory=dict)  # other per-point arrays (non-LAS formats)
    las: object | None = None               # laspy.LasData this cloud came from, if any
    # a LAS/LAZ file whose point records are this cloud's points in this order, not held in memory
    # (io.read(..., keep_records=False)): the writer streams them from there
    records_file: str = ""
    source: str = ""                        # path or description, for messages
    # returns_problem's verdict on the whole survey, carried into every subset and tile (None: judge
    # this cloud's own returns): "usable" or the problem. Judged on each stage's points or tile, a
    # file with 0.8 % bad return numbers crossed the 1 % line in its vegetation or in one tile
    returns_verdict: str | None = None

    def __post_init__(self):
        self.xyz = np.ascontiguousarray(self.xyz, dtype=np.float32)
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(3)
        if self.xyz.ndim != 2 or self.xyz.shape[1] != 3:
            raise ValueError("xyz must have shape (n, 3)")
        n = len(self.xyz)
        for name in ("rgb", "intensity", "classification", "returns", "nir"):
            a = getattr(self, name)
            if a is not None and len(a) != n:
                raise ValueError(f"{name} has {len(a)} rows for {n} points")
        if self.rgb is not None and self.color_depth not in (8, 16):
            self.color_depth = detect_color_depth(self.rgb)

    @property
    def n(self) -> int:
        return int(self.xyz.shape[0])

    def __len__(self) -> int:
        return self.n

    @property
    def has_color(self) -> bool:
        """Colour that says something: an RGB field whose values vary from point to point (one
        colour for every point, a placeholder some writers fill in, is no cue: the road stage
        already read it so, the roof stage took it for colour)."""
        if self.rgb is None or not len(self.rgb):
            return False
        return bool(np.any(self.rgb.max(axis=0) != self.rgb.min(axis=0)))

    def rgb8(self) -> np.ndarray | None:
        """Colour as float32 in 0..255 whatever the stored depth (thresholds are in 8-bit units).
        16-bit colour holding 8-bit values scaled by 256 (a shift, as many writers store them) or
        by 257 (full scale) gives those 8-bit values exactly (divided by 257 alone, x 256 colour
        read 0.4 % darker and changed road labels); other 16-bit colour is divided by 257."""
        if self.rgb is None:
            return None
        rgb = self.rgb.astype(np.float32)
        if self.color_depth == 16:
            rgb /= np.float32(stored_8bit_scale(self.rgb))
        return rgb

    def ndvi(self) -> np.ndarray | None:
        """float32 (n,) NDVI = (NIR - red) / (NIR + red) in -1..1 (0 where both are 0), or None
        unless the cloud has colour and a NIR field whose values vary (IGN Lidar HD tiles carry
        all-zero NIR fields)."""
        if self.nir is None or self.rgb is None or not self.n or int(self.nir.min()) == int(self.nir.max()):
            return None
        nir = self.nir.astype(np.float32)
        red = self.rgb[:, 0].astype(np.float32)
        if self.color_depth == 8:        # NIR is 16-bit in LAS; bring red to the same scale
            red *= 257.0
        total = nir + red
        return np.where(total > 0, (nir - red) / np.maximum(total, 1.0), 0.0).astype(np.float32)

    def returns_problem(self) -> str | None:
        """Why the points' return numbers cannot tell pulses apart, or None (also without returns):
        return numbers of 0 or above their pulse's number of returns on more than 1 % of the points
        (LAS allows 1 to the number of returns; a writer that left them 0 made every point an
        earlier return of its pulse, foliage to the roof pipeline), or one number of returns above
        1 on every point (a constant carries no pulse). The survey's verdict where one is set
        (returns_verdict)."""
        if self.returns is None or not self.n:
            return None
        if self.returns_verdict is not None:
            return None if self.returns_verdict == RETURNS_USABLE else self.returns_verdict
        number, count = self.returns[:, 0], self.returns[:, 1]
        if not count.any():
            return None      # no returns recorded (photogrammetry, converted clouds): nothing to read
        bad = np.count_nonzero((number == 0) | (count == 0) | (number > count))
        if bad > 0.01 * self.n:
            return (f"{100 * bad / self.n:.0f} % of the points have a return number of 0 or above their "
                    "number of returns")
        top = int(count.max())
        if top > 1 and int(count.min()) == top:
            return f"every point has the same number of returns ({top})"
        return None

    def _split_pulses(self):
        """(return number, number of returns) per point; None without return information, when
        no pulse has more than one return (nothing to tell apart), or when returns_problem says
        they cannot be read."""
        if self.returns is None:
            return None
        number, count = self.returns[:, 0], self.returns[:, 1]
        if not (count > 1).any() or self.returns_problem() is not None:
            return None
        return number, count

    def penetrated(self) -> np.ndarray | None:
        """bool (n,): the point is an earlier return of a pulse that went on (return number below
        the number of returns): foliage, hedges and roof edges, rarely roof interiors. None as
        _split_pulses."""
        pulses = self._split_pulses()
        return None if pulses is None else pulses[0] < pulses[1]

    def later_returns(self) -> np.ndarray | None:
        """bool (n,): the point is not the first return of its pulse (something above it returned
        part of the pulse first). None as _split_pulses."""
        pulses = self._split_pulses()
        return None if pulses is None else pulses[0] >= 2

    def world_xyz(self) -> np.ndarray:
        """float64 world coordinates (exact for LAS input: taken from the scaled integers)."""
        if self.las is not None:
            return np.column_stack([np.asarray(self.las.x), np.asarray(self.las.y),
                                    np.asarray(self.las.z)]).astype(np.float64)
        return self.xyz.astype(np.float64) + self.origin

    def subset(self, index: np.ndarray) -> "Cloud":
        """A new cloud of the points selected by ``index`` (bool mask or integer indices).
        The LAS record is not carried: a subset is for processing, the full cloud is written."""
        index = np.asarray(index)
        if index.dtype == bool:
            index = np.flatnonzero(index)
        elif index.dtype != np.intp:
            index = index.astype(np.intp)

        # np.take along axis 0: the same rows as a[index], 3-4x faster for (n, 3) columns
        def pick(a):
            return None if a is None else np.take(a, index, axis=0)
        return replace(self, xyz=pick(self.xyz), rgb=pick(self.rgb), intensity=pick(self.intensity),
                       classification=pick(self.classification), returns=pick(self.returns), nir=pick(self.nir),
                       attributes={k: pick(v) for k, v in self.attributes.items()}, las=None,
                       records_file="")

    @classmethod
    def from_world(cls, xyz_world: np.ndarray, origin: np.ndarray | None = None, **kw) -> "Cloud":
        """Build a cloud from float64 world coordinates, choosing a local origin when not given
        (the floor of the minimum corner, so local coordinates are small and non-negative; far
        isolated points left out: roadx_ti.isolation.local_origin)."""
        from roadx_ti.isolation import local_origin

        xyz_world = np.asarray(xyz_world, dtype=np.float64)
        if origin is None:
            origin = local_origin(xyz_world) if len(xyz_world) else np.zeros(3)
        local = (xyz_world - origin).astype(np.float32)
        return cls(xyz=local, origin=origin, **kw)


MIXED_DEPTH_SHARE = 0.05     # of the coloured points: more that fit in a byte beside 16-bit values is a mix


def byte_sized_share(rgb: np.ndarray) -> float:
    """In colour with 16-bit values, the share of the points not black whose three channels all
    fit in a byte: 8-bit values written beside 16-bit ones (merged deliveries; every second point
    so collapsed the road to 5 % of itself). Genuine 16-bit colour scaled from 8 bits holds almost
    none, and dark genuine 16-bit colour as many in 256-511 (0 then). 0 for 8-bit colour."""
    if rgb is None or not len(rgb) or detect_color_depth(rgb) != 16:
        return 0.0
    top = rgb.max(axis=1)
    lit = top > 0
    low = int(np.count_nonzero(lit & (top <= 255)))
    # genuine dark 16-bit colour runs on past 255 (a scene of 0-745 had 16 % of its points under
    # 256); 8-bit values beside ones scaled by 256 or 257 leave 256-511 nearly empty
    if np.count_nonzero((top > 255) & (top <= 511)) > 0.1 * low:
        return 0.0
    return float(low / max(int(np.count_nonzero(lit)), 1))


def detect_color_depth(rgb: np.ndarray) -> int:
    """8 when every channel fits in a byte, else 16 (LAS stores 16-bit, many writers scale 8-bit
    values by 256 or 257, others store them raw)."""
    return 16 if rgb.size and int(rgb.max()) > 255 else 8
