"""Synthetic labelled scenes: the demo's default input, the scale benchmarks' data and the accuracy
test bed of the road (METHODS.md R) and roof (METHODS.md P) pipelines.

Pure numpy, deterministic from ``seed``. The scene is a tiling of seeded city blocks whose extent
grows with the point count at a fixed nominal density (uav-road ~200 pts/m2, als-roof ~15 pts/m2),
never smaller than one block (so tiny clouds get a lower density). Surfaces are sampled by area,
thinned by a density field and by occlusion, then trimmed to exactly ``n_points``; a fixed fraction
of outliers is added last. Truth is the ASPRS class of every point:

    1 other (cars, lamp posts)      2 ground (sidewalks, kerbs, grass, hillside, yards)
    3/4/5 low / medium / high vegetation (flower beds, bushes and hedges, trees)
    6 building (roofs, walls, chimneys, roof superstructures, sheds and annexes: als-roof sheds can
      be smaller than a typical minimum roof area of ~10 m2 and are still class 6)
    7 low noise, 18 high noise, 11 road surface (asphalt carriageway including its markings)

Coordinates: ``xyz`` is local float32 in [0, side] x [0, side] (plus heights), ``origin`` is the
float64 projected-CRS corner (500000, 4500000, 0) for uav-road and (870000, 6618000, 0) for als-roof.
Colour is 8-bit scaled by 257 into 16 bits (``color_depth`` 16), as photogrammetry exports do.
Intensity: uav-road has no sensor intensity (photogrammetry), so it carries the colour luminance
(x 257); als-roof carries a per-material LiDAR intensity (asphalt low, vegetation medium, roofs
varied) on a 0..4000-ish scale like IGN Lidar HD.

What the scenes are built to test (and to break):
- uav-road: asphalt close in colour to the sidewalks (15-30 units darker) and separated from them
  only by a 10-15 cm kerb; flat roofs in ground-like grey above the road level (R3/R4 must remove
  them by height, colour alone cannot); crowns over the road thin the road points below; cast
  shadows darken parts of road and sidewalk (colour growing must not split there); a sloped branch
  and a steep hillside (R4's slope test and CSF); parked cars on the road edge; outliers (R2).
- als-roof: orthophoto colour (every point takes the colour of the top surface above it, so walls
  and ground under trees carry roof or foliage colour), green roofs of uniform colour against
  foliage of strong per-point colour variation (P3), hedges and vehicle roofs (P2 distance test),
  small sheds (P4 area filter), trees touching roofs, chimneys and superstructures, few walls.
"""
from __future__ import annotations

import math

import numpy as np

from roadx_ti.cloud import Cloud

KINDS = ("uav-road", "als-roof")
MIN_POINTS = 1000
ORIGINS = {"uav-road": (500000.0, 4500000.0, 0.0), "als-roof": (870000.0, 6618000.0, 0.0)}
NOMINAL_DENSITY = {"uav-road": 200.0, "als-roof": 15.0}   # points per m2 of scene footprint
OUTLIER_FRACTION = {"uav-road": 0.005, "als-roof": 0.0008}

CLASS_OTHER, CLASS_GROUND, CLASS_LOW_VEG, CLASS_MED_VEG, CLASS_HIGH_VEG = 1, 2, 3, 4, 5
CLASS_BUILDING, CLASS_LOW_NOISE, CLASS_ROAD, CLASS_HIGH_NOISE = 6, 7, 11, 18

F32 = np.float32


def generate(kind: str, n_points: int, seed: int = 0) -> Cloud:
    """A synthetic labelled scene of exactly ``n_points`` points (see the module docstring)."""
    if kind not in KINDS:
        raise ValueError(f"unknown synthetic scene kind {kind!r}; allowed: {', '.join(KINDS)}")
    if isinstance(n_points, bool) or int(n_points) != n_points or int(n_points) < MIN_POINTS:
        raise ValueError(f"n_points must be an integer >= {MIN_POINTS}, got {n_points!r}")
    n = int(n_points)
    scene_cls = _UavRoadScene if kind == "uav-road" else _AlsRoofScene
    side = max(math.sqrt(n / NOMINAL_DENSITY[kind]), scene_cls.BLOCK)
    scene = scene_cls(side, int(seed))
    xyz, rgb8, intensity, cls = scene.sample_exact(n, OUTLIER_FRACTION[kind])
    rgb16 = (np.clip(np.rint(rgb8), 0, 255).astype(np.uint16) * np.uint16(257))
    return Cloud(xyz=xyz, origin=np.array(ORIGINS[kind], dtype=np.float64), rgb=rgb16,
                 color_depth=16, intensity=intensity, classification=cls,
                 source=f"synthetic:{kind}:n={n}:seed={int(seed)}")


# ------------------------------------------------------------------------------------------------
# small vectorised helpers

def _smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


class _SmoothNoise:
    """A smooth random field ~N(0, 1) at wavelength ~``scale`` metres: a sum of plane waves."""

    def __init__(self, rng, scale, n_waves=6):
        k = rng.uniform(0.6, 1.6, n_waves) * 2 * np.pi / scale
        ang = rng.uniform(0, 2 * np.pi, n_waves)
        self.kx = (k * np.cos(ang)).astype(F32)
        self.ky = (k * np.sin(ang)).astype(F32)
        self.ph = rng.uniform(0, 2 * np.pi, n_waves).astype(F32)
        self.amp = F32(math.sqrt(2.0 / n_waves))

    def __call__(self, x, y):
        out = np.zeros(np.shape(x), dtype=F32)
        for kx, ky, ph in zip(self.kx, self.ky, self.ph):
            out += np.cos(kx * x + ky * y + ph)
        return out * self.amp


def _counts(rng, expected):
    """Integer counts with the given expectation (floor plus a Bernoulli remainder)."""
    expected = np.maximum(np.asarray(expected, dtype=np.float64), 0.0)
    base = np.floor(expected)
    return (base + (rng.random(expected.shape) < expected - base)).astype(np.int64)


def _repeat_index(counts):
    return np.repeat(np.arange(len(counts)), counts)


def _colour(base, n, rng, sigma):
    """n colours around ``base`` (3,) or (n,3) with per-point Gaussian noise (8-bit units)."""
    base = np.broadcast_to(np.asarray(base, dtype=F32), (n, 3))
    return base + rng.standard_normal((n, 3), dtype=F32) * F32(sigma)


def _ellipsoid_shell(rng, n, top_bias, thickness):
    """Unit-ellipsoid offsets: points near the surface, biased to the upper half (what a nadir
    view or the first LiDAR returns see of a crown)."""
    d = rng.standard_normal((n, 3), dtype=F32)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), F32(1e-6))
    flip = (d[:, 2] < 0) & (rng.random(n, dtype=F32) < top_bias)
    d[flip, 2] *= -1
    d *= (1.0 - thickness * rng.random(n, dtype=F32) ** 2)[:, None]
    return d


class _Raster:
    """A square grid over [0, side]^2 used for occluder heights, shadows and orthophotos."""

    def __init__(self, side, cell):
        self.cell = float(cell)
        self.n = int(math.ceil(side / cell)) + 1
        c = (np.arange(self.n, dtype=F32) + F32(0.5)) * F32(cell)
        self.xc, self.yc = np.meshgrid(c, c, indexing="xy")   # [row=y, col=x]

    def index(self, x, y):
        col = np.clip((x / self.cell).astype(np.int64), 0, self.n - 1)
        row = np.clip((y / self.cell).astype(np.int64), 0, self.n - 1)
        return row, col

    def window(self, x0, y0, x1, y1):
        c0 = max(int(x0 / self.cell), 0)
        c1 = min(int(math.ceil(x1 / self.cell)) + 1, self.n)
        r0 = max(int(y0 / self.cell), 0)
        r1 = min(int(math.ceil(y1 / self.cell)) + 1, self.n)
        if c0 >= c1 or r0 >= r1:
            return None
        return (slice(r0, r1), slice(c0, c1))


def _shadow_height(top, cell, sun_azimuth, sun_tan_elev, pool=1):
    """S[p] = max over t > 0 of top[p + t * sun_dir] - t * tan(elevation): a point at p lies in a
    cast shadow when its height is below S[p]. ``top`` is the highest surface per cell; ``pool``
    computes on a coarser grid (max-pooled) and expands the result back."""
    if pool > 1:
        n0 = top.shape[0]
        m = -(-n0 // pool) * pool
        padded = np.full((m, m), -np.inf, dtype=F32)
        padded[:n0, :n0] = top
        coarse = padded.reshape(m // pool, pool, m // pool, pool).max(axis=(1, 3))
        s = _shadow_height(coarse, cell * pool, sun_azimuth, sun_tan_elev)
        return np.repeat(np.repeat(s, pool, axis=0), pool, axis=1)[:n0, :n0]
    sx, sy = math.cos(sun_azimuth), math.sin(sun_azimuth)
    finite = top[np.isfinite(top)]
    relief = float(finite.max() - finite.min()) if finite.size else 0.0
    steps = int(min(relief / (sun_tan_elev * cell) + 2, 400))
    n = top.shape[0]
    shadow = np.full(top.shape, -np.inf, dtype=F32)
    for t in range(1, steps + 1):
        di, dj = int(round(t * sy)), int(round(t * sx))
        if abs(di) >= n or abs(dj) >= n:
            break
        drop = F32(t * cell * sun_tan_elev)
        dst = (slice(max(0, -di), n - max(0, di)), slice(max(0, -dj), n - max(0, dj)))
        src = (slice(max(0, di), n - max(0, -di)), slice(max(0, dj), n - max(0, -dj)))
        np.maximum(shadow[dst], top[src] - drop, out=shadow[dst])
    return shadow


class _Boxes:
    """Struct of arrays for rotated rectangles (centre, half sizes, angle) and their attributes."""

    def __init__(self, **cols):
        n = len(next(iter(cols.values()))) if cols else 0
        self.n = n
        for k, v in cols.items():
            setattr(self, k, np.asarray(v))

    @staticmethod
    def from_rows(rows, keys):
        if not rows:
            return _Boxes(**{k: np.zeros((0,) if not k.endswith("rgb") else (0, 3)) for k in keys})
        return _Boxes(**{k: np.array([r[k] for r in rows], dtype=np.float64) for k in keys})


def _to_local(x, y, cx, cy, ang):
    c, s = np.cos(ang).astype(F32), np.sin(ang).astype(F32)
    dx, dy = x - cx, y - cy
    return dx * c + dy * s, -dx * s + dy * c


def _to_world(lx, ly, cx, cy, ang):
    c, s = np.cos(ang).astype(F32), np.sin(ang).astype(F32)
    return cx + lx * c - ly * s, cy + lx * s + ly * c


def _roof_height(lx, ly, b):
    """Roof height over local coordinates for box rows ``b`` (arrays aligned with lx): flat (0),
    gable (1, ridge along local x) or hip (2)."""
    hx, hy = b["hx"], b["hy"]
    rise = b["ridge"] - b["eave"]
    tanp = rise / np.maximum(hy, F32(0.1))
    gable = b["eave"] + (hy - np.abs(ly)) * tanp
    hip = b["eave"] + np.minimum(hx - np.abs(lx), hy - np.abs(ly)) * tanp
    return np.where(b["roof"] == 0, b["ridge"], np.where(b["roof"] == 1, gable, hip))


# ------------------------------------------------------------------------------------------------

class _Scene:
    BLOCK = 100.0

    def __init__(self, side, seed):
        self.side = float(side)
        ss = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, self.KIND_ID])
        self.rng_layout, self.rng_sample, self.rng_pick, self.rng_noise = [
            np.random.default_rng(s) for s in ss.spawn(4)]
        self.nb = int(math.ceil(self.side / self.BLOCK))
        self._layout()

    # subclasses: _layout(), _density(x, y) -> accept probability, _emit_all(rho)

    def _keep(self, x, y):
        """Accept candidates by the density field (the field gives the relative density)."""
        return self.rng_sample.random(len(x), dtype=F32) < self._density(x, y)

    def _sample(self, rho):
        self._parts = []
        self._emit_all(rho)
        parts = self._parts
        self._parts = None
        xyz = np.concatenate([p[0] for p in parts])
        rgb = np.concatenate([p[1] for p in parts])
        inten = np.concatenate([p[2] for p in parts])
        cls = np.concatenate([p[3] for p in parts])
        return xyz, rgb, inten, cls

    def _emit(self, x, y, z, rgb, cls, intensity=None):
        inside = (x >= 0) & (x <= self.side) & (y >= 0) & (y <= self.side)
        if not inside.all():
            x, y, z = x[inside], y[inside], z[inside]
            rgb = np.asarray(rgb)[inside]
            cls = cls if np.ndim(cls) == 0 else cls[inside]
            intensity = intensity if intensity is None or np.ndim(intensity) == 0 else intensity[inside]
        n = len(x)
        if n == 0:
            return
        xyz = np.empty((n, 3), dtype=F32)
        xyz[:, 0], xyz[:, 1], xyz[:, 2] = x, y, z
        if intensity is None:
            intensity = np.zeros(n, dtype=F32)
        cls = np.broadcast_to(np.asarray(cls, dtype=np.uint8), (n,))
        self._parts.append((xyz, np.asarray(rgb, dtype=F32).reshape(n, 3),
                            np.broadcast_to(np.asarray(intensity, dtype=F32), (n,)), cls))

    def sample_exact(self, n, outlier_fraction):
        n_out = int(round(n * outlier_fraction))
        n_core = n - n_out
        rho = n_core / max(self._expected_per_rho(), 1e-9) * 1.04
        for _ in range(6):
            xyz, rgb, inten, cls = self._sample(rho)
            if len(xyz) >= n_core:
                break
            rho *= n_core / max(len(xyz), 1) * 1.05
        else:  # pragma: no cover - the density loop always converges in practice
            raise RuntimeError("synthetic sampler could not reach the requested point count")
        keys = self.rng_pick.random(len(xyz), dtype=F32)
        pick = np.sort(np.argpartition(keys, n_core - 1)[:n_core]) if n_core < len(xyz) \
            else np.arange(len(xyz))
        xyz, rgb, inten, cls = xyz[pick], rgb[pick], inten[pick], cls[pick]
        xyz, rgb, inten, cls = self._finish(xyz, rgb, inten, cls)
        if n_out:
            xyz, rgb, inten, cls = self._add_outliers(n_out, xyz, rgb, inten, cls)
        inten = self._final_intensity(rgb, inten)
        order = self._file_order(xyz)
        inten16 = np.clip(np.rint(inten[order]), 0, 65535).astype(np.uint16)
        return xyz[order], rgb[order], inten16, cls[order].astype(np.uint8)

    def _expected_per_rho(self):
        """Expected accepted points per unit of rho: sample the scene once at a tiny rho."""
        probe = 4000.0 / (self.side * self.side)
        state = self.rng_sample.bit_generator.state
        xyz, *_ = self._sample(probe)
        self.rng_sample.bit_generator.state = state
        return max(len(xyz), 1) / probe

    def _finish(self, xyz, rgb, inten, cls):
        return xyz, rgb, inten, cls

    def _final_intensity(self, rgb, inten):
        return inten

    def _add_outliers(self, n_out, xyz, rgb, inten, cls):
        rng = self.rng_noise
        base = rng.integers(0, len(xyz), n_out)
        high = rng.random(n_out) < 0.5
        oxyz = xyz[base].copy()
        oxyz[:, :2] += rng.normal(0, 0.5, (n_out, 2)).astype(F32)
        lo, hi = self.OUTLIER_RANGE
        dz = rng.uniform(lo, hi, n_out).astype(F32)
        oxyz[:, 2] += np.where(high, dz * self.HIGH_SCALE, -dz)
        oxyz[:, :2] = np.clip(oxyz[:, :2], 0, self.side)
        orgb = np.clip(rgb[base] + rng.normal(0, 20, (n_out, 3)).astype(F32), 0, 255)
        ocls = np.where(high, CLASS_HIGH_NOISE, CLASS_LOW_NOISE).astype(np.uint8)
        return (np.concatenate([xyz, oxyz]), np.concatenate([rgb, orgb]),
                np.concatenate([inten, inten[base]]), np.concatenate([cls, ocls]))

    def _covered(self, x, y, rect):
        """Ground candidates that an object hides: inside a footprint (buildings, cars, beds) they
        are removed; under a crown a part ``UNDER_CANOPY_HIDDEN`` is occluded."""
        if not hasattr(self, "_bbox_cache"):
            self._bbox_cache = [(b, self._bboxes(b, footprint=True)) for b in self._footprints] + \
                [(t, self._bboxes(t, footprint=False)) for t in self._canopies]
        x0, y0, x1, y1 = rect
        hidden = np.zeros(len(x), dtype=bool)
        under = np.zeros(len(x), dtype=bool)
        for objs, bb in self._bbox_cache:
            near = np.nonzero((bb[:, 2] >= x0) & (bb[:, 0] <= x1) & (bb[:, 3] >= y0) & (bb[:, 1] <= y1))[0]
            for i in near:
                sel = np.nonzero((x >= bb[i, 0]) & (x <= bb[i, 2]) & (y >= bb[i, 1]) & (y <= bb[i, 3]))[0]
                if not len(sel):
                    continue
                if objs in self._footprints:
                    ang = objs.ang[i] if hasattr(objs, "ang") else 0.0
                    lx, ly = _to_local(x[sel], y[sel], F32(objs.cx[i]), F32(objs.cy[i]), ang)
                    hidden[sel[(np.abs(lx) <= objs.hx[i]) & (np.abs(ly) <= objs.hy[i])]] = True
                else:
                    r2 = F32((objs.R[i] * 0.95) ** 2)
                    under[sel[(x[sel] - F32(objs.cx[i])) ** 2 + (y[sel] - F32(objs.cy[i])) ** 2 < r2]] = True
        hidden |= under & (self.rng_sample.random(len(x), dtype=F32) < F32(self.UNDER_CANOPY_HIDDEN))
        return hidden

    @staticmethod
    def _bboxes(objs, footprint):
        if objs.n == 0:
            return np.zeros((0, 4))
        rad = np.hypot(objs.hx, objs.hy) if footprint else objs.R
        return np.column_stack([objs.cx - rad, objs.cy - rad, objs.cx + rad, objs.cy + rad])

    def _emit_boxes(self, boxes, rho, wall_factor, cls, windows):
        """Roofs (flat, gable, hip) and walls of rotated boxes (buildings, chimneys, car bodies).
        Walls get ``wall_factor`` of the surface density (nadir views and ALS see few)."""
        if boxes.n == 0:
            return
        rng = self.rng_sample
        f = {k: getattr(boxes, k).astype(F32) for k in ("cx", "cy", "hx", "hy", "ang", "base", "eave",
                                                       "ridge", "roof")}
        over = np.where(f["roof"] == 0, F32(0), F32(0.4)) if not hasattr(boxes, "over") \
            else boxes.over.astype(F32)
        # roof (top face), sampled by plan area
        idx = _repeat_index(_counts(rng, 4 * (f["hx"] + over) * (f["hy"] + over) * rho))
        b = {k: v[idx] for k, v in f.items()}
        lx = (rng.random(len(idx), dtype=F32) * 2 - 1) * (b["hx"] + over[idx])
        ly = (rng.random(len(idx), dtype=F32) * 2 - 1) * (b["hy"] + over[idx])
        x, y = _to_world(lx, ly, b["cx"], b["cy"], b["ang"])
        k = self._keep(x, y)
        z = _roof_height(lx[k], ly[k], {kk: v[k] for kk, v in b.items()})
        rgb = _colour(boxes.roof_rgb[idx[k]], int(k.sum()), rng, 7.0)
        self._emit(x[k], y[k], z, rgb, cls, self._material_intensity(boxes, idx[k], 1.0))
        # walls, sampled by area along the perimeter, cut by the roof line
        per = 4 * (f["hx"] + f["hy"])
        hmax = f["ridge"] - f["base"]
        idx = _repeat_index(_counts(rng, per * hmax * rho * wall_factor))
        b = {k: v[idx] for k, v in f.items()}
        s = rng.random(len(idx), dtype=F32) * per[idx]
        hx, hy = b["hx"], b["hy"]
        lx, ly = np.empty_like(s), np.empty_like(s)
        e1, e2, e3 = 2 * hx, 2 * hx + 2 * hy, 4 * hx + 2 * hy
        m0, m1, m2 = s < e1, (s >= e1) & (s < e2), (s >= e2) & (s < e3)
        m3 = s >= e3
        lx[m0], ly[m0] = -hx[m0] + s[m0], -hy[m0]
        lx[m1], ly[m1] = hx[m1], -hy[m1] + (s[m1] - e1[m1])
        lx[m2], ly[m2] = hx[m2] - (s[m2] - e2[m2]), hy[m2]
        lx[m3], ly[m3] = -hx[m3], hy[m3] - (s[m3] - e3[m3])
        z = b["base"] + rng.random(len(idx), dtype=F32) * hmax[idx]
        x, y = _to_world(lx, ly, b["cx"], b["cy"], b["ang"])
        k = (z <= _roof_height(lx, ly, b)) & self._keep(x, y)
        idx, x, y, z, s = idx[k], x[k], y[k], z[k], s[k]
        if windows:
            base_rgb = boxes.wall_rgb[idx].astype(F32)
            win = ((s % F32(3.2)) > F32(1.1)) & ((s % F32(3.2)) < F32(2.4)) \
                & (((z - f["base"][idx]) % F32(3.0)) > F32(1.0)) & (((z - f["base"][idx]) % F32(3.0)) < F32(2.3))
            base_rgb[win] = (55, 62, 72)
        else:   # car bodies: dark window band below the roof
            base_rgb = boxes.roof_rgb[idx].astype(F32)
            rel = f["eave"][idx] - z
            base_rgb[(rel > F32(0.1)) & (rel < F32(0.55))] = (30, 34, 40)
        self._emit(x, y, z, _colour(base_rgb, len(x), rng, 7.0), cls,
                   self._material_intensity(boxes, idx, 0.6))

    def _material_intensity(self, objs, idx, scale):
        """Per-point LiDAR intensity from the objects' ``inten`` (zeros where they have none)."""
        if not hasattr(objs, "inten"):
            return None
        base = objs.inten[idx].astype(F32) * F32(scale)
        return base * (F32(1.0) + F32(0.12) * self.rng_sample.standard_normal(len(idx), dtype=F32))

    def _emit_crowns(self, t, rho, cls, colour_sigma, trunk, area_factor=1.0, top_bias=0.7,
                     thickness=0.35):
        """Crowns as ellipsoids: points near the surface, mostly on the upper half; ALS passes a
        larger ``thickness`` (returns from inside the crown) and ``area_factor`` (several returns)."""
        if t.n == 0:
            return
        rng = self.rng_sample
        idx = _repeat_index(_counts(rng, np.pi * t.R ** 2 * area_factor * rho))
        d = _ellipsoid_shell(rng, len(idx), top_bias=top_bias, thickness=thickness)
        x = t.cx[idx].astype(F32) + d[:, 0] * t.R[idx].astype(F32)
        y = t.cy[idx].astype(F32) + d[:, 1] * t.R[idx].astype(F32)
        z = t.cz[idx].astype(F32) + d[:, 2] * t.rz[idx].astype(F32)
        k = self._keep(x, y)
        n = int(k.sum())
        lum = (F32(1.0) + F32(0.18) * d[k, 2] + F32(0.12) * rng.standard_normal(n, dtype=F32))[:, None]
        rgb = t.rgb[idx[k]].astype(F32) * lum + rng.standard_normal((n, 3), dtype=F32) * F32(colour_sigma)
        self._emit(x[k], y[k], z[k], rgb, cls, self._material_intensity(t, idx[k], 1.0))
        if trunk:
            r = F32(0.18)
            h = (t.cz - t.rz * 0.6 - t.ground).astype(F32)
            idx = _repeat_index(_counts(rng, 2 * np.pi * 0.18 * h * rho * 0.3))
            a = rng.random(len(idx), dtype=F32) * F32(2 * np.pi)
            x = t.cx[idx].astype(F32) + r * np.cos(a)
            y = t.cy[idx].astype(F32) + r * np.sin(a)
            z = t.ground[idx].astype(F32) + rng.random(len(idx), dtype=F32) * h[idx]
            k = self._keep(x, y)
            self._emit(x[k], y[k], z[k], _colour((92, 72, 55), int(k.sum()), rng, 10.0), cls,
                       self._material_intensity(t, idx[k], 0.8))

    def _file_order(self, xyz):
        """Points in 10 m tiles, row by row, shuffled inside a tile (like a tiled export)."""
        tile = 10.0
        nt = int(math.ceil(self.side / tile)) + 1
        col = np.clip((xyz[:, 0] / tile).astype(np.int64), 0, nt - 1)
        row = np.clip((xyz[:, 1] / tile).astype(np.int64), 0, nt - 1)
        key = ((row * nt + col) << 32) | self.rng_pick.integers(0, 1 << 32, len(xyz), dtype=np.int64)
        return np.argsort(key)


# ------------------------------------------------------------------------------------------------
# uav-road

_CAR_COLOURS = np.array([[180, 30, 30], [30, 60, 150], [225, 225, 225], [25, 25, 28], [160, 162, 165],
                         [70, 72, 75], [200, 170, 40], [40, 110, 60], [120, 20, 30]], dtype=F32)
_WALL_COLOURS = np.array([[205, 190, 165], [222, 216, 204], [150, 85, 65], [160, 158, 152],
                          [190, 170, 130]], dtype=F32)
_PITCHED_ROOF_COLOURS = np.array([[150, 70, 50], [125, 82, 62], [72, 74, 80], [165, 95, 60]], dtype=F32)
_FLAT_ROOF_COLOURS = np.array([[130, 125, 115], [58, 58, 62], [200, 200, 196], [104, 103, 100]], dtype=F32)


class _UavRoadScene(_Scene):
    """Blocks of 70 m: a main road along x (11 m carriageway with parking lanes) at v = 10 m in
    every block row, a branch road along y (8 m) from it to the next row's main road (a T-junction
    at each end), 3 m sidewalks behind 10-15 cm kerbs, and four lots per block: buildings, gardens,
    and in some blocks (always the first) a hillside."""
    KIND_ID = 1
    BLOCK = 70.0
    ROAD_V, WM, WB, SW = 10.0, 6.0, 4.5, 3.0
    OUTLIER_RANGE = (0.3, 3.0)
    HIGH_SCALE = 3.0
    UNDER_CANOPY_HIDDEN = 0.7
    ASPHALT = (84, 84, 87)
    SIDEWALK = (106, 105, 101)     # ~20 units brighter than asphalt
    KERB_STONE = (140, 138, 132)
    GRASS = (78, 112, 52)
    SOIL = (120, 100, 76)

    # ---------------------------------------------------------------- layout
    def _layout(self):
        r = self.rng_layout
        B, nb = self.BLOCK, self.nb
        self.z0 = 100.0
        self.kerb = r.uniform(0.10, 0.15)
        slope_y = r.uniform(0.05, 0.08)              # steepest grade of the branch roads
        self.a_y = slope_y * B / np.pi
        self.a_x, self.p_x, self.ph_x = r.uniform(0.3, 1.0), r.uniform(180, 320), r.uniform(0, 6.28)
        self.xb = r.uniform(27.0, 43.0, (nb, nb))
        self.xb[0, 0] = r.uniform(30.0, 36.0)
        self.density_noise = _SmoothNoise(r, 40.0)
        self.sigma_noise = _SmoothNoise(r, 30.0)
        self.asphalt_noise = _SmoothNoise(r, 6.0)
        self.grass_noise = _SmoothNoise(r, 3.0)
        self.sun_az = r.uniform(0, 2 * np.pi)
        self.sun_tan = math.tan(math.radians(r.uniform(38, 55)))

        self.hill = np.zeros((nb, nb, 6))         # u0, u1, v0, v1, H, ramp
        buildings, trees, cars, poles, bushes, beds = [], [], [], [], [], []
        for bx in range(nb):
            for by in range(nb):
                self._layout_block(r, bx, by, buildings, trees, cars, poles, bushes, beds)
        keys_b = ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge", "roof", "roof_rgb", "wall_rgb")
        self.buildings = _Boxes.from_rows(buildings, keys_b)
        self.trees = _Boxes.from_rows(trees, ("cx", "cy", "ground", "cz", "R", "rz", "trunk", "rgb"))
        self.bushes = _Boxes.from_rows(bushes, ("cx", "cy", "ground", "cz", "R", "rz", "trunk", "rgb"))
        self.cars = _Boxes.from_rows(cars, ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge",
                                            "roof", "roof_rgb", "wall_rgb"))
        self.poles = _Boxes.from_rows(poles, ("x", "y", "ground", "h"))
        self.beds = _Boxes.from_rows(beds, ("cx", "cy", "hx", "hy", "ground", "h"))
        self._footprints = (self.buildings, self.cars, self.beds)
        self._canopies = (self.trees, self.bushes)
        self._build_shadow_raster()

    def _layout_block(self, r, bx, by, buildings, trees, cars, poles, bushes, beds):
        B, W, WB, SW = self.BLOCK, self.WM, self.WB, self.SW
        ox, oy = bx * B, by * B
        if ox >= self.side or oy >= self.side:
            return
        xb = self.xb[bx, by]
        first = bx == 0 and by == 0
        # lots: left / right of the branch, front / back
        sides = [(1.0, xb - WB - SW - 1.0), (xb + WB + SW + 1.0, B - 1.0)]
        slots_v = [(20.0, 44.5), (45.0, 69.5)]
        hill_side = 0 if first else (int(r.integers(0, 2)) if r.random() < 0.25 else -1)
        if hill_side >= 0:
            u0, u1 = sides[hill_side]
            H = r.uniform(6.0, 10.0) if first else r.uniform(5.0, 12.0)
            self.hill[bx, by] = (u0, u1, 20.0, 69.5, H, r.uniform(0.35, 0.6))
            for _ in range(int(r.integers(1, 4))):
                self._tree(r, trees, ox + r.uniform(u0 + 3, u1 - 3), oy + r.uniform(24, 66))
        for si, (u0, u1) in enumerate(sides):
            if si == hill_side:
                continue
            for vi, (v0, v1) in enumerate(slots_v):
                if first:
                    kind = "flat_grey" if vi == 0 else "gable"
                else:
                    kind = "garden" if r.random() < 0.2 else ("flat" if r.random() < 0.5 else "gable")
                if kind != "garden":
                    self._building(r, buildings, kind, ox, oy, u0, u1, v0, v1)
                n_trees = int(r.integers(2, 5)) if kind == "garden" else int(r.integers(0, 2))
                for _ in range(n_trees):
                    if kind == "garden":
                        tx, ty = r.uniform(u0 + 3, u1 - 3), r.uniform(v0 + 3, v1 - 3)
                    else:   # garden trees along the lot edge facing the branch
                        tx = u1 - 2.0 if si == 0 else u0 + 2.0
                        ty = r.uniform(v0 + 3, v1 - 3)
                    self._tree(r, trees, ox + tx, oy + ty)
                for _ in range(int(r.integers(2, 6))):
                    bu, bv = (u1 - 1.2 if si == 0 else u0 + 1.2), r.uniform(v0 + 1.5, v1 - 1.5)
                    if kind == "garden":
                        bu = r.uniform(u0 + 2, u1 - 2)
                    R, h = r.uniform(0.8, 1.6), r.uniform(1.0, 2.0)
                    g = self._ground_height(ox + bu, oy + bv)
                    bushes.append(dict(cx=ox + bu, cy=oy + bv, ground=g, cz=g + h / 2, R=R, rz=h / 2,
                                       trunk=0.0, rgb=r.uniform([40, 70, 30], [70, 100, 50])))
                if r.random() < 0.8 or first:
                    hx, hy = r.uniform(1.5, 4.0), r.uniform(0.6, 1.2)
                    cu = (u0 + 1.0 + hx) if si == 1 else (u1 - 1.0 - hx)
                    cv = v0 + 1.0 + hy
                    beds.append(dict(cx=ox + cu, cy=oy + cv, hx=hx, hy=hy,
                                     ground=self._ground_height(ox + cu, oy + cv), h=r.uniform(0.15, 0.45)))
        # street trees on the main road sidewalks (crowns overhang the carriageway)
        xb_below = self.xb[bx, by - 1] if by > 0 else None
        for sgn in (+1, -1):
            u = r.uniform(2.0, 8.0)
            while u < B - 2.0:
                mouth = xb if sgn > 0 else xb_below
                if mouth is None or abs(u - mouth) > WB + 5.0:
                    if r.random() < (0.8 if first else 0.7):
                        self._tree(r, trees, ox + u, oy + self.ROAD_V + sgn * (W + 1.0), street=True)
                u += r.uniform(9.0, 14.0)
        # trees along the branch, one side
        for v in np.arange(24.0, 66.0, 12.0):
            if r.random() < 0.5:
                self._tree(r, trees, ox + xb + (WB + 1.0) * (1 if r.random() < 0.5 else -1), oy + v, street=True)
        # parked cars in the parking lanes of the main road, one on the branch
        for sgn in (+1, -1):
            u = r.uniform(1.0, 6.0)
            mouth = xb if sgn > 0 else xb_below
            while u < B - 6.0:
                L = r.uniform(4.0, 4.8)
                if (mouth is None or abs(u + L / 2 - mouth) > WB + L) and r.random() < 0.55:
                    self._car(r, cars, ox + u + L / 2, oy + self.ROAD_V + sgn * 4.85, L / 2, 0.0)
                u += L + r.uniform(1.0, 6.0)
        if r.random() < 0.8 or first:
            self._car(r, cars, ox + xb + self.WB - 1.05, oy + r.uniform(30, 55), r.uniform(2.0, 2.4), np.pi / 2)
        # lamp posts on the sidewalks
        for u in np.arange(r.uniform(3, 12), B - 2, 25.0):
            if abs(u - xb) > WB + SW + 1:
                x, y = ox + u, oy + self.ROAD_V + W + SW - 0.6
                poles.append(dict(x=x, y=y, ground=self._ground_height(x, y), h=r.uniform(6.0, 8.0)))

    def _tree(self, r, trees, x, y, street=False):
        if not (0 <= x <= self.side + 3 and 0 <= y <= self.side + 3):
            return
        R = r.uniform(3.0, 4.5) if street else r.uniform(2.0, 4.5)
        rz = R * r.uniform(0.7, 1.0)
        trunk = r.uniform(2.8, 4.5)
        g = self._ground_height(x, y)
        trees.append(dict(cx=x, cy=y, ground=g, cz=g + trunk + rz, R=R, rz=rz, trunk=trunk,
                          rgb=r.uniform([45, 80, 30], [85, 120, 60])))

    def _car(self, r, cars, cx, cy, hl, ang):
        hw = r.uniform(0.85, 0.95)
        g = self._ground_height(cx, cy)
        h = r.uniform(1.4, 1.65)
        hx, hy = (hl, hw) if ang == 0.0 else (hl, hw)
        cars.append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=g, eave=g + h, ridge=g + h, roof=0,
                         roof_rgb=_CAR_COLOURS[r.integers(0, len(_CAR_COLOURS))],
                         wall_rgb=np.zeros(3)))

    def _building(self, r, buildings, kind, ox, oy, u0, u1, v0, v1):
        wmax, dmax = min(20.0, u1 - u0 - 3.0), min(18.0, v1 - v0 - 3.0)
        if wmax < 6.0:
            return
        w, d = r.uniform(8.0, max(wmax, 8.5)), r.uniform(8.0, dmax)
        w = min(w, wmax)
        cu = r.uniform(u0 + 1.5 + w / 2, max(u1 - 1.5 - w / 2, u0 + 1.5 + w / 2 + 1e-3))
        cv = r.uniform(v0 + 1.5 + d / 2, v1 - 1.5 - d / 2)
        cx, cy = ox + cu, oy + cv
        corners = np.array([[cx - w / 2, cy - d / 2], [cx + w / 2, cy - d / 2], [cx - w / 2, cy + d / 2],
                            [cx + w / 2, cy + d / 2]], dtype=F32)
        base = float(self._ground_height(corners[:, 0], corners[:, 1]).min()) - 0.05
        # ridge along the longer side: local x is the ridge axis
        ang = 0.0 if w >= d else np.pi / 2
        hx, hy = (w / 2, d / 2) if w >= d else (d / 2, w / 2)
        if kind.startswith("flat"):
            top = base + r.uniform(3.0, 15.0)
            roof_rgb = _FLAT_ROOF_COLOURS[3] if kind == "flat_grey" else \
                _FLAT_ROOF_COLOURS[r.integers(0, len(_FLAT_ROOF_COLOURS))]
            buildings.append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=base, eave=top, ridge=top,
                                  roof=0, roof_rgb=roof_rgb,
                                  wall_rgb=_WALL_COLOURS[r.integers(0, len(_WALL_COLOURS))]))
        else:
            eave = base + r.uniform(3.0, 8.0)
            rise = min(hy * math.tan(math.radians(r.uniform(25, 40))), base + 15.0 - eave)
            buildings.append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=base, eave=eave,
                                  ridge=eave + rise, roof=1,
                                  roof_rgb=_PITCHED_ROOF_COLOURS[r.integers(0, len(_PITCHED_ROOF_COLOURS))],
                                  wall_rgb=_WALL_COLOURS[r.integers(0, len(_WALL_COLOURS))]))

    # ---------------------------------------------------------------- ground surface
    def _block_coords(self, x, y):
        B = F32(self.BLOCK)
        bx = np.clip((x // B).astype(np.int64), 0, self.nb - 1)
        by = np.clip((y // B).astype(np.int64), 0, self.nb - 1)
        return bx, by, x - bx * B, y - by * B

    def _terrain(self, x, y):
        return (F32(self.z0) + F32(self.a_y * 0.5) * (1 - np.cos(F32(2 * np.pi / self.BLOCK) * (y - F32(self.ROAD_V))))
                + F32(self.a_x) * np.sin(F32(2 * np.pi / self.p_x) * x + F32(self.ph_x)))

    def _hill_height(self, bx, by, u, v):
        p = self.hill[bx, by].astype(F32)
        u0, u1, v0, v1, H, slope = (p[..., i] for i in range(6))
        ramp = np.maximum(H / np.maximum(slope, F32(0.1)), F32(1.0))
        ru = np.minimum(ramp, np.maximum((u1 - u0) / 2 - 1, F32(1.0)))
        rv = np.minimum(ramp, np.maximum((v1 - v0) / 2 - 1, F32(1.0)))
        s = (_smoothstep((u - u0) / ru) * _smoothstep((u1 - u) / ru)
             * _smoothstep((v - v0) / rv) * _smoothstep((v1 - v) / rv))
        return H * s

    def _roads(self, x, y):
        bx, by, u, v = self._block_coords(x, y)
        dm = np.abs(v - F32(self.ROAD_V))
        xb_own = self.xb[bx, by].astype(F32)
        xb_below = np.where(by > 0, self.xb[bx, np.maximum(by - 1, 0)], np.nan).astype(F32)
        xbr = np.where(v >= F32(self.ROAD_V), xb_own, xb_below)
        db = np.abs(u - xbr)
        db = np.where(np.isnan(db), F32(np.inf), db)
        return bx, by, u, v, dm, db, xbr

    def _ground(self, x, y, colour=True):
        """Height, class and colour of the ground-level surface (road, sidewalk, lots, hill)."""
        bx, by, u, v, dm, db, xbr = self._roads(x, y)
        W, WB, SW, kerb = F32(self.WM), F32(self.WB), F32(self.SW), F32(self.kerb)
        T = self._terrain(x, y)
        in_main, in_br = dm < W, db < WB
        road = in_main | in_br
        d_c = np.where(in_br, np.minimum(dm, db), dm)
        e_m, e_b = dm - W, db - WB
        near_main = e_m <= e_b
        e = np.minimum(e_m, e_b)
        walk = ~road & (e < SW)
        z_road = T - F32(0.02) * d_c
        z_walk = T - F32(0.02) * np.where(near_main, W, WB) + kerb + F32(0.015) * e
        hill = self._hill_height(bx, by, u, v)
        z_lot = T - F32(0.02) * W + kerb + F32(0.015) * SW + F32(0.03) + hill
        z = np.where(road, z_road, np.where(walk, z_walk, z_lot))
        if not colour:
            return z
        n = len(x)
        cls = np.where(road, CLASS_ROAD, CLASS_GROUND).astype(np.uint8)
        rng = self.rng_sample
        # asphalt with low-frequency texture (patches, wear)
        tex = self.asphalt_noise(x, y) * F32(5.0)
        rgb = np.empty((n, 3), dtype=F32)
        rgb[:] = np.asarray(self.ASPHALT, dtype=F32)
        rgb += tex[:, None]
        branch_only = in_br & ~in_main
        vrel = v - F32(self.ROAD_V + self.WM)
        yellow = in_main & (np.abs(dm - F32(0.16)) < F32(0.075))
        white = (in_main & ~in_br & (np.abs(dm - F32(3.6)) < F32(0.075)))
        white |= branch_only & (db < F32(0.075)) & ((y % F32(9.0)) < F32(3.0)) & (vrel > F32(5.2))
        white |= branch_only & (v >= F32(self.ROAD_V)) & (vrel > F32(1.0)) & (vrel < F32(4.0)) \
            & (((u - xbr + WB) % F32(1.0)) < F32(0.5))
        white |= branch_only & (v >= F32(self.ROAD_V)) & (vrel > F32(4.6)) & (vrel < F32(5.0)) & (u < xbr)
        worn = rng.random(n, dtype=F32) < F32(0.12)
        rgb[white & ~worn] = (218, 218, 212)
        rgb[yellow & ~worn] = (214, 172, 48)
        # sidewalk slabs with joints, kerb stones along the kerb
        walk_rgb = np.asarray(self.SIDEWALK, dtype=F32) + tex[:, None] * F32(0.6)
        joint = ((np.where(near_main, x, y) % F32(1.5)) < F32(0.04))
        walk_rgb[joint] -= F32(14.0)
        stone = e < F32(0.15)
        walk_rgb[stone] = self.KERB_STONE
        rgb = np.where(walk[:, None], walk_rgb, rgb)
        # grass, with bare soil on the hillside
        lot = ~road & ~walk
        gn = self.grass_noise(x, y)
        grass_rgb = np.asarray(self.GRASS, dtype=F32) + (gn * F32(10.0))[:, None] \
            + rng.standard_normal((n, 3), dtype=F32) * F32(9.0)
        soil = (hill > F32(0.5)) & (gn > F32(0.3))
        grass_rgb[soil] = np.asarray(self.SOIL, dtype=F32) + rng.standard_normal((int(soil.sum()), 3), dtype=F32) * F32(8)
        rgb = np.where(lot[:, None], grass_rgb, rgb)
        # slightly rough grass
        z = z + np.where(lot, F32(0.02) * gn + F32(0.015) * rng.standard_normal(n, dtype=F32), F32(0))
        return z, cls, rgb, road

    def _ground_height(self, x, y):
        scalar = np.ndim(x) == 0
        z = self._ground(np.atleast_1d(np.asarray(x, dtype=F32)), np.atleast_1d(np.asarray(y, dtype=F32)),
                         colour=False)
        return float(z[0]) if scalar else z

    # ---------------------------------------------------------------- shadows and density
    def _build_shadow_raster(self):
        ras = _Raster(self.side, 0.5)
        top = self._ground(ras.xc.ravel(), ras.yc.ravel(), colour=False).reshape(ras.xc.shape)
        for boxes in (self.buildings, self.cars):
            for i in range(boxes.n):
                b = {k: np.asarray(getattr(boxes, k)[i]) for k in ("cx", "cy", "hx", "hy", "ang", "eave",
                                                                   "ridge", "roof")}
                rad = math.hypot(b["hx"], b["hy"]) + 0.5
                w = ras.window(b["cx"] - rad, b["cy"] - rad, b["cx"] + rad, b["cy"] + rad)
                if w is None:
                    continue
                lx, ly = _to_local(ras.xc[w], ras.yc[w], F32(b["cx"]), F32(b["cy"]), b["ang"])
                inside = (np.abs(lx) <= b["hx"] + 0.4) & (np.abs(ly) <= b["hy"] + 0.4)
                h = _roof_height(lx, ly, {k: F32(v) for k, v in b.items()})
                top[w] = np.where(inside, np.maximum(top[w], h), top[w])
        for t in (self.trees, self.bushes):
            for i in range(t.n):
                cx, cy, R, cz, rz = t.cx[i], t.cy[i], t.R[i], t.cz[i], t.rz[i]
                w = ras.window(cx - R, cy - R, cx + R, cy + R)
                if w is None:
                    continue
                q = 1 - ((ras.xc[w] - cx) ** 2 + (ras.yc[w] - cy) ** 2) / R ** 2
                h = np.where(q > 0, cz + rz * np.sqrt(np.maximum(q, 0)), -np.inf).astype(F32)
                top[w] = np.maximum(top[w], h)
        self.shadow_raster = ras
        self.shadow = _shadow_height(top, ras.cell, self.sun_az, self.sun_tan, pool=max(1, round(0.5 / ras.cell)))

    def _density(self, x, y):
        # 100..400 pts/m2 around the mean: a factor of 4 between the sparsest and densest areas
        t = 0.5 + 0.5 * np.tanh(self.density_noise(x, y))
        return F32(0.25) + F32(0.75) * t

    # ---------------------------------------------------------------- sampling
    def _emit_all(self, rho):
        rng = self.rng_sample
        side, tile = self.side, self.BLOCK / 4
        for x0 in np.arange(0.0, side, tile):
            for y0 in np.arange(0.0, side, tile):
                x1, y1 = min(x0 + tile, side), min(y0 + tile, side)
                if x1 <= x0 or y1 <= y0:
                    continue
                m = int(_counts(rng, (x1 - x0) * (y1 - y0) * rho))
                x = F32(x0) + rng.random(m, dtype=F32) * F32(x1 - x0)
                y = F32(y0) + rng.random(m, dtype=F32) * F32(y1 - y0)
                k = self._keep(x, y)
                x, y = x[k], y[k]
                k = ~self._covered(x, y, (x0, y0, x1, y1))
                x, y = x[k], y[k]
                z, cls, rgb, _ = self._ground(x, y)
                self._emit(x, y, z, rgb, cls)
        self._emit_kerbs(rho)
        self._emit_boxes(self.buildings, rho, wall_factor=0.35, cls=CLASS_BUILDING, windows=True)
        self._emit_boxes(self.cars, rho, wall_factor=0.5, cls=CLASS_OTHER, windows=False)
        self._emit_crowns(self.trees, rho, CLASS_HIGH_VEG, colour_sigma=16.0, trunk=True)
        self._emit_crowns(self.bushes, rho, CLASS_MED_VEG, colour_sigma=14.0, trunk=False)
        self._emit_beds(rho)
        self._emit_poles(rho)

    def _emit_kerbs(self, rho):
        """The vertical kerb faces along every road edge (a nadir camera sees them obliquely)."""
        rng = self.rng_sample
        B, W, WB, side = self.BLOCK, self.WM, self.WB, self.side
        segs = []   # x0, y0, x1, y1
        for by in range(self.nb):
            for sgn in (+1, -1):
                y = by * B + self.ROAD_V + sgn * W
                if not 0 <= y <= side:
                    continue
                cuts = []
                for bx in range(self.nb):
                    bb = by if sgn > 0 else by - 1
                    if bb >= 0:
                        c = bx * B + self.xb[bx, bb]
                        cuts.append((c - WB, c + WB))
                x = 0.0
                for c0, c1 in sorted(cuts) + [(side, side)]:
                    if c0 > x:
                        segs.append((x, y, min(c0, side), y))
                    x = max(x, c1)
            for bx in range(self.nb):
                for sgn in (+1, -1):
                    x = bx * B + self.xb[bx, by] + sgn * WB
                    ya, yb = by * B + self.ROAD_V + W, min((by + 1) * B + self.ROAD_V - W, side)
                    if 0 <= x <= side and ya < yb:
                        segs.append((x, ya, x, yb))
        segs = np.array(segs, dtype=np.float64).reshape(-1, 4)
        length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
        idx = _repeat_index(_counts(rng, length * self.kerb * rho * 0.6))
        t = rng.random(len(idx), dtype=F32)
        s = segs[idx].astype(F32)
        x = s[:, 0] + t * (s[:, 2] - s[:, 0])
        y = s[:, 1] + t * (s[:, 3] - s[:, 1])
        k = self._keep(x, y)
        x, y = x[k], y[k]
        _, _, _, _, dm, db, _ = self._roads(x, y)
        edge = self._terrain(x, y) - F32(0.02) * np.where(dm - F32(W) <= db - F32(WB), F32(W), F32(WB))
        z = edge + rng.random(len(x), dtype=F32) * F32(self.kerb)
        self._emit(x, y, z, _colour(self.KERB_STONE, len(x), rng, 5.0), CLASS_GROUND)

    def _emit_beds(self, rho):
        b = self.beds
        if b.n == 0:
            return
        rng = self.rng_sample
        idx = _repeat_index(_counts(rng, 4 * b.hx * b.hy * rho))
        x = (b.cx[idx] + (rng.random(len(idx)) * 2 - 1) * b.hx[idx]).astype(F32)
        y = (b.cy[idx] + (rng.random(len(idx)) * 2 - 1) * b.hy[idx]).astype(F32)
        k = self._keep(x, y)
        x, y, idx = x[k], y[k], idx[k]
        n = len(x)
        z = (b.ground[idx] + b.h[idx] * rng.uniform(0.5, 1.0, n)).astype(F32)
        flowers = np.array([[200, 60, 70], [220, 190, 60], [190, 120, 190], [230, 230, 230]], dtype=F32)
        rgb = _colour((60, 105, 45), n, rng, 14.0)
        fl = rng.random(n) < 0.35
        rgb[fl] = flowers[rng.integers(0, len(flowers), int(fl.sum()))]
        self._emit(x, y, z, rgb, CLASS_LOW_VEG)

    def _emit_poles(self, rho):
        p = self.poles
        if p.n == 0:
            return
        rng = self.rng_sample
        r = F32(0.09)
        idx = _repeat_index(_counts(rng, (2 * np.pi * 0.09 * p.h * 0.5 + 0.6 * 0.3 * 3) * rho))
        n = len(idx)
        a = rng.random(n, dtype=F32) * F32(2 * np.pi)
        head = rng.random(n) < 0.6 * 0.3 * 3 / (2 * np.pi * 0.09 * p.h[idx] * 0.5 + 0.54)
        x = p.x[idx].astype(F32) + np.where(head, rng.uniform(-0.3, 0.3, n).astype(F32), r * np.cos(a))
        y = p.y[idx].astype(F32) + np.where(head, rng.uniform(-0.15, 0.15, n).astype(F32), r * np.sin(a))
        z = (p.ground[idx] + np.where(head, p.h[idx], rng.random(n) * p.h[idx])).astype(F32)
        k = self._keep(x, y)
        self._emit(x[k], y[k], z[k], _colour((112, 114, 118), int(k.sum()), rng, 6.0), CLASS_OTHER)

    def _finish(self, xyz, rgb, inten, cls):
        rng = self.rng_noise
        n = len(xyz)
        # cast shadows: darker and slightly bluer
        row, col = self.shadow_raster.index(xyz[:, 0], xyz[:, 1])
        shade = xyz[:, 2] < self.shadow[row, col] - F32(0.15)
        rgb[shade] *= np.array([0.46, 0.49, 0.57], dtype=F32)
        # photogrammetric noise: 2-5 cm surface thickness (varies over the scene), colour noise
        sigma = F32(0.0175) + F32(0.0075) * np.tanh(self.sigma_noise(xyz[:, 0], xyz[:, 1]))
        xyz += rng.standard_normal((n, 3), dtype=F32) * (sigma * F32(0.6))[:, None]
        rgb += rng.standard_normal((n, 3), dtype=F32) * F32(5.0)
        rgb += (rng.standard_normal(n, dtype=F32) * F32(4.0))[:, None]
        np.clip(rgb, 0, 255, out=rgb)
        return xyz, rgb, inten, cls

    def _final_intensity(self, rgb, inten):
        # photogrammetry has no sensor intensity: carry the colour luminance (x 257)
        rgb = np.rint(rgb)
        return (F32(0.299) * rgb[:, 0] + F32(0.587) * rgb[:, 1] + F32(0.114) * rgb[:, 2]) * F32(257.0)


_TILE_ROOFS = np.array([[158, 78, 58], [128, 86, 66], [176, 102, 72], [110, 60, 50]], dtype=F32)
_GREY_ROOFS = np.array([[128, 128, 126], [150, 148, 142], [92, 94, 98]], dtype=F32)
_DARK_ROOFS = np.array([[52, 54, 60], [64, 60, 58]], dtype=F32)
_GREEN_ROOFS = np.array([[70, 112, 60], [88, 122, 70], [60, 96, 58]], dtype=F32)


class _AlsRoofScene(_Scene):
    """Blocks of 100 m with 7 m streets along x and y, 3 x 3 lots: detached houses (gable, hip,
    flat roofs; chimneys; attached annexes; garden sheds), some large flat-roofed buildings (HVAC
    units, some green roofs), gardens with trees (some touching the houses), hedges, low shrubs,
    cars and vans. ALS look: flight-strip density pattern, few wall points, returns inside crowns,
    orthophoto colour."""
    KIND_ID = 2
    BLOCK = 100.0
    STREET, HALF = 6.0, 3.5
    OUTLIER_RANGE = (1.0, 8.0)
    HIGH_SCALE = 5.0
    UNDER_CANOPY_HIDDEN = 0.55

    def _layout(self):
        r = self.rng_layout
        B, nb = self.BLOCK, self.nb
        self.z0 = 40.0
        self.terrain_noise = _SmoothNoise(r, 450.0, n_waves=4)
        self.terrain_amp = r.uniform(1.5, 4.0)
        self.grass_noise = _SmoothNoise(r, 8.0)
        self.colour_noise = _SmoothNoise(r, 25.0)
        self.density_noise = _SmoothNoise(r, 60.0)
        # flight strips along x: 230 m wide, 170 m apart -> overlap bands of double density
        self.strip_offset = r.uniform(0, 170.0)
        self.sun_az = r.uniform(0, 2 * np.pi)
        self.sun_tan = math.tan(math.radians(r.uniform(35, 55)))
        self.lean = r.normal(0, 0.03, 2)          # orthophoto building lean per metre of height
        rows = dict(b=[], t=[], h=[], c=[], low=[])
        for bx in range(nb):
            for by in range(nb):
                if bx * B < self.side and by * B < self.side:
                    self._layout_block(r, bx, by, rows)
        kb = ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge", "roof", "roof_rgb", "inten", "over")
        self.buildings = _Boxes.from_rows(rows["b"], kb)
        self.cars = _Boxes.from_rows(rows["c"], kb)
        self.trees = _Boxes.from_rows(rows["t"], ("cx", "cy", "ground", "cz", "R", "rz", "rgb", "inten"))
        self.hedges = _Boxes.from_rows(rows["h"], ("cx", "cy", "hx", "hy", "ang", "ground", "height"))
        self.shrubs = _Boxes.from_rows(rows["low"], ("cx", "cy", "hx", "hy", "ang", "ground", "height"))
        self._footprints = (self.buildings, self.cars, self.hedges, self.shrubs)
        self._canopies = (self.trees,)
        self._build_rasters()

    def _terrain(self, x, y):
        return F32(self.z0) + F32(self.terrain_amp) * self.terrain_noise(x, y)

    def _ground_height(self, x, y):
        return float(self._terrain(np.array([x], F32), np.array([y], F32))[0])

    def _is_street(self, x, y):
        B = F32(self.BLOCK)
        u, v = x % B, y % B
        return (np.abs(u - F32(self.STREET)) < F32(self.HALF)) | (np.abs(v - F32(self.STREET)) < F32(self.HALF))

    def _box(self, rows, key, cx, cy, hx, hy, ang, base, eave, ridge, roof, rgb, inten, over=0.0):
        rows[key].append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=base, eave=eave, ridge=ridge,
                              roof=roof, roof_rgb=rgb, inten=inten, over=over))

    def _layout_block(self, r, bx, by, rows):
        B = self.BLOCK
        ox, oy = bx * B, by * B
        first = bx == 0 and by == 0
        lot = (B - 2 * (self.HALF + 1.5)) / 3
        big_done = False
        for i in range(3):
            for j in range(3):
                u0, v0 = self.STREET + self.HALF + 1.5 + i * lot, self.STREET + self.HALF + 1.5 + j * lot
                if ox + u0 > self.side or oy + v0 > self.side:
                    continue
                kind = r.choice(["house", "house", "house", "house", "big", "garden"])
                if first:
                    kind = ("big", "house", "house", "house", "big", "house", "garden", "house", "house")[i * 3 + j]
                    if (i, j) == (1, 1):
                        kind = "big_green"
                if kind.startswith("big") and (big_done and not first):
                    kind = "house"
                cx, cy = ox + u0 + lot / 2, oy + v0 + lot / 2
                if kind.startswith("big"):
                    big_done = True
                    self._big(r, rows, cx, cy, lot, green=(kind == "big_green" or r.random() < 0.2))
                elif kind == "house":
                    self._house(r, rows, cx, cy, lot, first)
                else:
                    for _ in range(int(r.integers(2, 5))):
                        self._tree(r, rows, cx + r.uniform(-lot / 3, lot / 3), cy + r.uniform(-lot / 3, lot / 3))
                # hedge along the street side or a side boundary of the lot
                if r.random() < 0.6 or first:
                    length = r.uniform(6.0, lot - 2)
                    if r.random() < 0.5:
                        hx, hy, ang, hc = length / 2, r.uniform(0.4, 0.6), 0.0, (cx, oy + v0 + 0.8)
                    else:
                        hx, hy, ang, hc = length / 2, r.uniform(0.4, 0.6), np.pi / 2, (ox + u0 + 0.8, cy)
                    rows["h"].append(dict(cx=hc[0], cy=hc[1], hx=hx, hy=hy, ang=ang,
                                          ground=self._ground_height(*hc), height=r.uniform(1.5, 2.5)))
                for _ in range(int(r.integers(0, 3)) + (1 if first else 0)):
                    sx, sy = cx + r.uniform(-lot / 2.5, lot / 2.5), cy - lot / 2 + r.uniform(1.5, 3.5)
                    rows["low"].append(dict(cx=sx, cy=sy, hx=r.uniform(0.8, 2.0), hy=r.uniform(0.6, 1.4), ang=0.0,
                                            ground=self._ground_height(sx, sy), height=r.uniform(0.2, 0.6)))
                # a vehicle on the street in front of the lot
                if r.random() < 0.5 or first:
                    van = r.random() < 0.2
                    hl, hw, h = (3.0, 1.1, 2.5) if van else (r.uniform(2.1, 2.4), 0.9, r.uniform(1.4, 1.6))
                    vx, vy = cx + r.uniform(-lot / 3, lot / 3), oy + self.STREET + self.HALF - 1.1
                    g = self._ground_height(vx, vy)
                    rgb = _CAR_COLOURS[r.integers(0, len(_CAR_COLOURS))]
                    self._box(rows, "c", vx, vy, hl, hw, 0.0, g, g + h, g + h, 0, rgb, r.uniform(800, 2500))

    def _roof_style(self, r, green=False):
        if green:
            return _GREEN_ROOFS[r.integers(0, len(_GREEN_ROOFS))], 2500.0
        p = r.random()
        if p < 0.55:
            return _TILE_ROOFS[r.integers(0, len(_TILE_ROOFS))], r.uniform(1500, 2100)
        if p < 0.85:
            return _GREY_ROOFS[r.integers(0, len(_GREY_ROOFS))], r.uniform(1800, 3200)
        return _DARK_ROOFS[r.integers(0, len(_DARK_ROOFS))], r.uniform(500, 1000)

    def _house(self, r, rows, cx, cy, lot, first):
        w, d = r.uniform(8.0, 16.0), r.uniform(7.0, 13.0)
        ang = r.normal(0, 0.12) + (np.pi / 2 if r.random() < 0.3 else 0.0)
        hx, hy = max(w, d) / 2, min(w, d) / 2
        cx, cy = cx + r.uniform(-2, 2), cy + r.uniform(-2, 2)
        base = self._ground_height(cx, cy) - 0.1
        roof = int(r.choice([0, 1, 1, 2, 2]))
        eave = base + r.uniform(3.0, 7.0)
        rgb, inten = self._roof_style(r, green=(roof == 0 and r.random() < 0.15))
        ridge = eave + (hy * math.tan(math.radians(r.uniform(30, 45))) if roof else 0.0)
        ridge = min(ridge, base + 20.0)
        self._box(rows, "b", cx, cy, hx, hy, ang, base, eave, ridge, roof, rgb, inten, 0.0 if roof == 0 else 0.5)
        if roof and (r.random() < 0.7 or first):          # chimney near the ridge
            lx, ly = r.uniform(-hx * 0.6, hx * 0.6), r.uniform(-0.8, 0.8)
            zr = float(_roof_height(np.array([lx], F32), np.array([ly], F32),
                                    dict(hx=F32(hx), hy=F32(hy), eave=F32(eave), ridge=F32(ridge), roof=F32(roof)))[0])
            qx, qy = _to_world(np.array([lx], F32), np.array([ly], F32), F32(cx), F32(cy), np.float32(ang))
            s = r.uniform(0.3, 0.5)
            top = zr + r.uniform(1.0, 1.5)
            self._box(rows, "b", float(qx[0]), float(qy[0]), s, s, ang, zr - 0.5, top, top, 0,
                      np.array([120, 70, 55]), 1400.0)
        elif roof == 0:
            self._superstructures(r, rows, cx, cy, hx, hy, ang, eave, int(r.integers(1, 3)))
        # attached annex (garage) on a short side, garden shed in a corner (often < 10 m2)
        if r.random() < 0.5 or first:
            ax, ay = r.uniform(1.5, 3.0), r.uniform(1.5, 3.0)
            lx = hx + ax
            qx, qy = _to_world(np.array([lx], F32), np.array([0.0], F32), F32(cx), F32(cy), np.float32(ang))
            ab = self._ground_height(float(qx[0]), float(qy[0])) - 0.1
            top = ab + r.uniform(2.5, 3.3)
            rgb, inten = self._roof_style(r)
            self._box(rows, "b", float(qx[0]), float(qy[0]), ax, ay, ang, ab, top, top, 0, rgb, inten)
        if r.random() < 0.6 or first:
            sx, sy = cx - lot / 2 + 2.5, cy + lot / 2 - 2.5
            a, b = r.uniform(0.8, 1.6), r.uniform(0.8, 1.6)
            sb = self._ground_height(sx, sy) - 0.05
            self._box(rows, "b", sx, sy, max(a, b), min(a, b), r.uniform(0, np.pi), sb, sb + r.uniform(1.9, 2.3),
                      sb + r.uniform(2.3, 2.7), 1, _GREY_ROOFS[r.integers(0, 3)], 1600.0, 0.15)
        # trees: one touching / overhanging the house, maybe more in the garden
        if r.random() < 0.65 or first:
            a = r.uniform(0, 2 * np.pi)
            R = r.uniform(2.5, 4.5)
            dist = max(hx, hy) * 0.8 + R * 0.5
            self._tree(r, rows, cx + dist * math.cos(a), cy + dist * math.sin(a), R=R,
                       top=ridge + r.uniform(-1.5, 3.0))
        for _ in range(int(r.integers(0, 3))):
            self._tree(r, rows, cx + r.uniform(-lot / 2.3, lot / 2.3), cy + lot / 2 - r.uniform(1.5, 3))

    def _big(self, r, rows, cx, cy, lot, green):
        w, d = r.uniform(18.0, min(lot - 2, 27.0)), r.uniform(15.0, min(lot - 2, 27.0))
        hx, hy = max(w, d) / 2, min(w, d) / 2
        ang = r.normal(0, 0.05)
        base = self._ground_height(cx, cy) - 0.2
        top = base + r.uniform(8.0, 20.0)
        rgb, inten = self._roof_style(r, green=green)
        if not green and r.random() < 0.3:
            rgb, inten = np.array([175, 178, 182]), 3300.0    # metal
        self._box(rows, "b", cx, cy, hx, hy, ang, base, top, top, 0, rgb, inten)
        self._superstructures(r, rows, cx, cy, hx, hy, ang, top, int(r.integers(1, 4)))
        if r.random() < 0.5:
            self._tree(r, rows, cx + (hx + 2.0) * (1 if r.random() < 0.5 else -1), cy, R=r.uniform(3, 5))

    def _superstructures(self, r, rows, cx, cy, hx, hy, ang, roof_z, count):
        for _ in range(count):
            a, b = r.uniform(0.6, min(2.0, hx / 2)), r.uniform(0.6, min(1.8, hy / 2))
            lx, ly = r.uniform(-hx + a + 0.5, hx - a - 0.5), r.uniform(-hy + b + 0.5, hy - b - 0.5)
            qx, qy = _to_world(np.array([lx], F32), np.array([ly], F32), F32(cx), F32(cy), np.float32(ang))
            top = roof_z + r.uniform(1.0, 2.5)
            self._box(rows, "b", float(qx[0]), float(qy[0]), a, b, ang, roof_z - 0.2, top, top, 0,
                      _GREY_ROOFS[r.integers(0, 3)], r.uniform(1500, 3000))

    def _tree(self, r, rows, x, y, R=None, top=None):
        if not (0 <= x <= self.side and 0 <= y <= self.side):
            return
        R = r.uniform(2.0, 5.0) if R is None else R
        rz = R * r.uniform(0.8, 1.2)
        g = self._ground_height(x, y)
        top = g + r.uniform(6.0, 18.0) if top is None else max(top, g + 2 * rz + 1.5)
        rows["t"].append(dict(cx=x, cy=y, ground=g, cz=top - rz, R=R, rz=rz,
                              rgb=r.uniform([40, 75, 30], [90, 130, 60]), inten=r.uniform(1100, 2000)))

    # ---------------------------------------------------------------- rasters: shadows, orthophoto
    def _build_rasters(self):
        ras = _Raster(self.side, max(0.25, self.side / 2500.0))
        shape = ras.xc.shape
        xc, yc = ras.xc.ravel(), ras.yc.ravel()
        top = self._terrain(xc, yc).reshape(shape)
        rng = np.random.default_rng(self.rng_layout.integers(0, 2 ** 63))
        ortho = np.empty(shape + (3,), dtype=F32)
        gn = self.grass_noise(xc, yc).reshape(shape)
        ortho[:] = np.array([92, 118, 62], dtype=F32) + (gn * F32(9))[..., None]
        ortho += (self.colour_noise(xc, yc).reshape(shape) * F32(8))[..., None]
        dry = gn > F32(1.0)
        ortho[dry] = (128, 122, 84)
        street = self._is_street(xc, yc).reshape(shape)
        ortho[street] = (86, 86, 88)
        ortho += rng.standard_normal(ortho.shape, dtype=F32) * F32(4.0)
        for objs in (self.cars, self.buildings):
            for i in range(objs.n):
                b = {k: F32(getattr(objs, k)[i]) for k in ("cx", "cy", "hx", "hy", "ang", "eave", "ridge", "roof", "over")}
                rad = math.hypot(b["hx"], b["hy"]) + 3.0
                w = ras.window(b["cx"] - rad, b["cy"] - rad, b["cx"] + rad, b["cy"] + rad)
                if w is None:
                    continue
                lx, ly = _to_local(ras.xc[w], ras.yc[w], b["cx"], b["cy"], b["ang"])
                inside = (np.abs(lx) <= b["hx"] + b["over"]) & (np.abs(ly) <= b["hy"] + b["over"])
                h = _roof_height(lx, ly, b)
                top[w] = np.where(inside, np.maximum(top[w], h), top[w])
                # the orthophoto shows the roof displaced by the building lean
                shift = (float(b["ridge"]) - float(objs.base[i])) * self.lean
                lx, ly = _to_local(ras.xc[w] - F32(shift[0]), ras.yc[w] - F32(shift[1]), b["cx"], b["cy"], b["ang"])
                seen = (np.abs(lx) <= b["hx"] + b["over"]) & (np.abs(ly) <= b["hy"] + b["over"])
                ortho[w][seen] = objs.roof_rgb[i] + rng.standard_normal((int(seen.sum()), 3), dtype=F32) * F32(5)
                if objs is self.buildings and objs.roof[i] != 0:   # shading of the roof planes
                    slope_side = np.where(objs.roof[i] == 1, np.sign(ly), np.sign(ly))
                    ortho[w][seen] *= (F32(1.0) + F32(0.08) * slope_side[seen])[:, None]
        for objs in (self.shrubs, self.hedges):
            for i in range(objs.n):
                cx, cy, hx, hy, ang = (getattr(objs, k)[i] for k in ("cx", "cy", "hx", "hy", "ang"))
                rad = math.hypot(hx, hy)
                w = ras.window(cx - rad, cy - rad, cx + rad, cy + rad)
                if w is None:
                    continue
                lx, ly = _to_local(ras.xc[w], ras.yc[w], F32(cx), F32(cy), ang)
                inside = (np.abs(lx) <= hx) & (np.abs(ly) <= hy)
                top[w] = np.where(inside, np.maximum(top[w], F32(objs.ground[i] + objs.height[i])), top[w])
                ortho[w][inside] = np.array([55, 92, 42], dtype=F32) + rng.standard_normal((int(inside.sum()), 3), dtype=F32) * F32(14)
        t = self.trees
        for i in range(t.n):
            cx, cy, R, cz, rz = t.cx[i], t.cy[i], t.R[i], t.cz[i], t.rz[i]
            w = ras.window(cx - R, cy - R, cx + R, cy + R)
            if w is None:
                continue
            q = 1 - ((ras.xc[w] - cx) ** 2 + (ras.yc[w] - cy) ** 2) / R ** 2
            inside = q > 0
            top[w] = np.maximum(top[w], np.where(inside, cz + rz * np.sqrt(np.maximum(q, 0)), -np.inf).astype(F32))
            m = int(inside.sum())
            leaf = t.rgb[i].astype(F32) * (F32(1.0) + F32(0.25) * rng.standard_normal(m, dtype=F32))[:, None] \
                + rng.standard_normal((m, 3), dtype=F32) * F32(18)
            ortho[w][inside] = leaf
        shadow = _shadow_height(top, ras.cell, self.sun_az, self.sun_tan, pool=max(1, round(0.5 / ras.cell)))
        ortho[top < shadow - F32(0.2)] *= np.array([0.5, 0.52, 0.6], dtype=F32)
        self.ortho_raster, self.ortho = ras, np.clip(ortho, 0, 255)

    def _density(self, x, y):
        # strips 230 m wide every 170 m: 1 or 2 strips cover a point; +-30 % local variation
        p = (y + F32(self.strip_offset)) % F32(170.0)
        cover = F32(1.0) + (p < F32(60.0)).astype(F32)
        return cover * (F32(0.8) + F32(0.2) * np.tanh(self.density_noise(x, y))) / F32(2.0)

    # ---------------------------------------------------------------- sampling
    def _emit_all(self, rho):
        rng = self.rng_sample
        side, tile = self.side, self.BLOCK / 4
        for x0 in np.arange(0.0, side, tile):
            for y0 in np.arange(0.0, side, tile):
                x1, y1 = min(x0 + tile, side), min(y0 + tile, side)
                if x1 <= x0 or y1 <= y0:
                    continue
                m = int(_counts(rng, (x1 - x0) * (y1 - y0) * rho))
                x = F32(x0) + rng.random(m, dtype=F32) * F32(x1 - x0)
                y = F32(y0) + rng.random(m, dtype=F32) * F32(y1 - y0)
                k = self._keep(x, y)
                x, y = x[k], y[k]
                k = ~self._covered(x, y, (x0, y0, x1, y1))
                x, y = x[k], y[k]
                street = self._is_street(x, y)
                n = len(x)
                z = self._terrain(x, y) + np.where(street, F32(0), F32(0.03) * self.grass_noise(x, y))
                inten = np.where(street, F32(650), F32(2500)) * (F32(1) + F32(0.25) * rng.standard_normal(n, dtype=F32))
                cls = np.where(street, CLASS_ROAD, CLASS_GROUND).astype(np.uint8)
                self._emit(x, y, z, np.zeros((n, 3), F32), cls, inten)
        self._emit_boxes(self.buildings, rho, wall_factor=0.06, cls=CLASS_BUILDING, windows=False)
        self._emit_boxes(self.cars, rho, wall_factor=0.2, cls=CLASS_OTHER, windows=False)
        self._emit_crowns(self.trees, rho, CLASS_HIGH_VEG, colour_sigma=0.0, trunk=False, area_factor=1.6,
                          top_bias=0.6, thickness=0.9)
        self._emit_vegetation_boxes(self.hedges, rho, CLASS_MED_VEG, 1700.0)
        self._emit_vegetation_boxes(self.shrubs, rho, CLASS_LOW_VEG, 2200.0)

    def _emit_vegetation_boxes(self, v, rho, cls, inten):
        """Hedges and shrubs: points through the top half of a box, denser at the top."""
        if v.n == 0:
            return
        rng = self.rng_sample
        idx = _repeat_index(_counts(rng, 4 * v.hx * v.hy * rho * 1.4))
        n = len(idx)
        lx = ((rng.random(n) * 2 - 1) * v.hx[idx]).astype(F32)
        ly = ((rng.random(n) * 2 - 1) * v.hy[idx]).astype(F32)
        x, y = _to_world(lx, ly, v.cx[idx].astype(F32), v.cy[idx].astype(F32), v.ang[idx])
        z = (v.ground[idx] + v.height[idx] * (1 - 0.6 * rng.random(n) ** 2)).astype(F32)
        k = self._keep(x, y)
        inten_pts = F32(inten) * (F32(1) + F32(0.35) * rng.standard_normal(int(k.sum()), dtype=F32))
        self._emit(x[k], y[k], z[k], np.zeros((int(k.sum()), 3), F32), cls, inten_pts)

    def _finish(self, xyz, rgb, inten, cls):
        rng = self.rng_noise
        n = len(xyz)
        row, col = self.ortho_raster.index(xyz[:, 0], xyz[:, 1])
        rgb = self.ortho[row, col] + rng.standard_normal((n, 3), dtype=F32) * F32(3.0)
        np.clip(rgb, 0, 255, out=rgb)
        xyz += rng.standard_normal((n, 3), dtype=F32) * F32(0.025)
        np.clip(inten, 0, 65535, out=inten)
        return xyz, rgb, inten, cls
