"""What every synthetic scene shares: seeded random streams, sampling surfaces by area, the
density field, occlusion by footprints and canopies, boxes (buildings, cars) and crowns, cast
shadows, outliers, and the file order of the points. A scene module subclasses ``Scene``."""
from __future__ import annotations

import math

import numpy as np

F32 = np.float32

CLASS_OTHER, CLASS_GROUND, CLASS_LOW_VEG, CLASS_MED_VEG, CLASS_HIGH_VEG = 1, 2, 3, 4, 5
CLASS_BUILDING, CLASS_LOW_NOISE, CLASS_ROAD, CLASS_HIGH_NOISE = 6, 7, 11, 18

CAR_COLOURS = np.array([[180, 30, 30], [30, 60, 150], [225, 225, 225], [25, 25, 28], [160, 162, 165],
                        [70, 72, 75], [200, 170, 40], [40, 110, 60], [120, 20, 30]], dtype=F32)

def smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


class SmoothNoise:
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


def integer_counts(rng, expected):
    """Integer counts with the given expectation (floor plus a Bernoulli remainder)."""
    expected = np.maximum(np.asarray(expected, dtype=np.float64), 0.0)
    base = np.floor(expected)
    return (base + (rng.random(expected.shape) < expected - base)).astype(np.int64)


def repeat_index(counts):
    return np.repeat(np.arange(len(counts)), counts)


def noisy_colour(base, n, rng, sigma):
    """n colours around ``base`` (3,) or (n,3) with per-point Gaussian noise (8-bit units)."""
    base = np.broadcast_to(np.asarray(base, dtype=F32), (n, 3))
    return base + rng.standard_normal((n, 3), dtype=F32) * F32(sigma)


def ellipsoid_shell(rng, n, top_bias, thickness):
    """Unit-ellipsoid offsets: points near the surface, biased to the upper half (what a nadir
    view or the first LiDAR returns see of a crown)."""
    d = rng.standard_normal((n, 3), dtype=F32)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), F32(1e-6))
    flip = (d[:, 2] < 0) & (rng.random(n, dtype=F32) < top_bias)
    d[flip, 2] *= -1
    d *= (1.0 - thickness * rng.random(n, dtype=F32) ** 2)[:, None]
    return d


class Raster:
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


def shadow_height(top, cell, sun_azimuth, sun_tan_elev, pool=1):
    """S[p] = max over t > 0 of top[p + t * sun_dir] - t * tan(elevation): a point at p lies in a
    cast shadow when its height is below S[p]. ``top`` is the highest surface per cell; ``pool``
    computes on a coarser grid (max-pooled) and expands the result back."""
    if pool > 1:
        n0 = top.shape[0]
        m = -(-n0 // pool) * pool
        padded = np.full((m, m), -np.inf, dtype=F32)
        padded[:n0, :n0] = top
        coarse = padded.reshape(m // pool, pool, m // pool, pool).max(axis=(1, 3))
        s = shadow_height(coarse, cell * pool, sun_azimuth, sun_tan_elev)
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


def top_surface(ras, ground, box_sets, crown_sets):
    """Highest surface per cell of raster ``ras``: the ``ground`` heights raised by the roofs of
    each box set (buildings, cars; roof_height over the footprint and a 0.4 m margin) and by the
    ellipsoid caps of each crown set (trees, bushes: centre cx, cy, radius R, cap centre cz and
    half height rz). The input to shadow_height."""
    top = ground
    for boxes in box_sets:
        for i in range(boxes.n):
            b = {k: np.asarray(getattr(boxes, k)[i]) for k in ("cx", "cy", "hx", "hy", "ang", "eave",
                                                               "ridge", "roof")}
            rad = math.hypot(b["hx"], b["hy"]) + 0.5
            w = ras.window(b["cx"] - rad, b["cy"] - rad, b["cx"] + rad, b["cy"] + rad)
            if w is None:
                continue
            lx, ly = to_local(ras.xc[w], ras.yc[w], F32(b["cx"]), F32(b["cy"]), b["ang"])
            inside = (np.abs(lx) <= b["hx"] + 0.4) & (np.abs(ly) <= b["hy"] + 0.4)
            h = roof_height(lx, ly, {k: F32(v) for k, v in b.items()})
            top[w] = np.where(inside, np.maximum(top[w], h), top[w])
    for t in crown_sets:
        for i in range(t.n):
            cx, cy, R, cz, rz = t.cx[i], t.cy[i], t.R[i], t.cz[i], t.rz[i]
            w = ras.window(cx - R, cy - R, cx + R, cy + R)
            if w is None:
                continue
            q = 1 - ((ras.xc[w] - cx) ** 2 + (ras.yc[w] - cy) ** 2) / R ** 2
            h = np.where(q > 0, cz + rz * np.sqrt(np.maximum(q, 0)), -np.inf).astype(F32)
            top[w] = np.maximum(top[w], h)
    return top


class Boxes:
    """Struct of arrays for rotated rectangles (centre, half sizes, angle) and their attributes."""

    def __init__(self, **cols):
        n = len(next(iter(cols.values()))) if cols else 0
        self.n = n
        for k, v in cols.items():
            setattr(self, k, np.asarray(v))

    @staticmethod
    def from_rows(rows, keys):
        if not rows:
            return Boxes(**{k: np.zeros((0,) if not k.endswith("rgb") else (0, 3)) for k in keys})
        return Boxes(**{k: np.array([r[k] for r in rows], dtype=np.float64) for k in keys})


def to_local(x, y, cx, cy, ang):
    c, s = np.cos(ang).astype(F32), np.sin(ang).astype(F32)
    dx, dy = x - cx, y - cy
    return dx * c + dy * s, -dx * s + dy * c


def to_world(lx, ly, cx, cy, ang):
    c, s = np.cos(ang).astype(F32), np.sin(ang).astype(F32)
    return cx + lx * c - ly * s, cy + lx * s + ly * c


def roof_height(lx, ly, b):
    """Roof height over local coordinates for box rows ``b`` (arrays aligned with lx): flat (0),
    gable (1, ridge along local x) or hip (2)."""
    hx, hy = b["hx"], b["hy"]
    rise = b["ridge"] - b["eave"]
    tanp = rise / np.maximum(hy, F32(0.1))
    gable = b["eave"] + (hy - np.abs(ly)) * tanp
    hip = b["eave"] + np.minimum(hx - np.abs(lx), hy - np.abs(ly)) * tanp
    return np.where(b["roof"] == 0, b["ridge"], np.where(b["roof"] == 1, gable, hip))



class Scene:
    """A scene kind: subclasses set KIND (the name ``generate`` takes), KIND_ID (seeds its random
    streams), ORIGIN (float64 projected-CRS corner), OUTLIER_FRACTION and BLOCK, and implement
    ``_layout``, ``_density`` and ``_emit_all``."""
    BLOCK = 100.0
    NOMINAL_DENSITY = 100.0

    @classmethod
    def side_for(cls, n_points: int, seed: int) -> float:
        """Edge of the square scene (m) for ``n_points``: at the nominal density, never smaller
        than one block (so tiny clouds get a lower density)."""
        return max(math.sqrt(n_points / cls.NOMINAL_DENSITY), cls.BLOCK)

    def __init__(self, side, seed):
        self.side = float(side)
        ss = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, self.KIND_ID])
        self.rng_layout, self.rng_sample, self.rng_pick, self.rng_noise = [
            np.random.default_rng(s) for s in ss.spawn(4)]
        self.nb = int(math.ceil(self.side / self.BLOCK))
        self._layout()

    # subclasses: _layout(), _density(x, y) -> accept probability, _emit_all(rho)

    def _ground_candidates(self, rho):
        """Ground-level sample positions, tile by tile (BLOCK / 4): uniform at ``rho`` per m2, thinned
        by the density field and by what covers the ground. Yields (x, y) per tile; a scene draws
        its own per-point values between tiles (the random streams stay in one order)."""
        rng = self.rng_sample
        side, tile = self.side, self.BLOCK / 4
        for x0 in np.arange(0.0, side, tile):
            for y0 in np.arange(0.0, side, tile):
                x1, y1 = min(x0 + tile, side), min(y0 + tile, side)
                if x1 <= x0 or y1 <= y0:
                    continue
                m = int(integer_counts(rng, (x1 - x0) * (y1 - y0) * rho))
                x = F32(x0) + rng.random(m, dtype=F32) * F32(x1 - x0)
                y = F32(y0) + rng.random(m, dtype=F32) * F32(y1 - y0)
                k = self._keep(x, y)
                x, y = x[k], y[k]
                k = ~self._covered(x, y, (x0, y0, x1, y1))
                yield x[k], y[k]

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
                    lx, ly = to_local(x[sel], y[sel], F32(objs.cx[i]), F32(objs.cy[i]), ang)
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
        Walls get ``wall_factor`` of the surface density (nadir views and ALS see few); ``cls``: one
        class, or one per box."""
        if boxes.n == 0:
            return
        rng = self.rng_sample
        f = {k: getattr(boxes, k).astype(F32) for k in ("cx", "cy", "hx", "hy", "ang", "base", "eave",
                                                       "ridge", "roof")}
        over = np.where(f["roof"] == 0, F32(0), F32(0.4)) if not hasattr(boxes, "over") \
            else boxes.over.astype(F32)
        # roof (top face), sampled by plan area
        idx = repeat_index(integer_counts(rng, 4 * (f["hx"] + over) * (f["hy"] + over) * rho))
        b = {k: v[idx] for k, v in f.items()}
        lx = (rng.random(len(idx), dtype=F32) * 2 - 1) * (b["hx"] + over[idx])
        ly = (rng.random(len(idx), dtype=F32) * 2 - 1) * (b["hy"] + over[idx])
        x, y = to_world(lx, ly, b["cx"], b["cy"], b["ang"])
        k = self._keep(x, y)
        z = roof_height(lx[k], ly[k], {kk: v[k] for kk, v in b.items()})
        rgb = noisy_colour(boxes.roof_rgb[idx[k]], int(k.sum()), rng, 7.0)
        self._emit(x[k], y[k], z, rgb, cls if np.ndim(cls) == 0 else cls[idx[k]], self._material_intensity(boxes, idx[k], 1.0))
        # walls, sampled by area along the perimeter, cut by the roof line
        per = 4 * (f["hx"] + f["hy"])
        hmax = f["ridge"] - f["base"]
        idx = repeat_index(integer_counts(rng, per * hmax * rho * wall_factor))
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
        x, y = to_world(lx, ly, b["cx"], b["cy"], b["ang"])
        k = (z <= roof_height(lx, ly, b)) & self._keep(x, y)
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
        self._emit(x, y, z, noisy_colour(base_rgb, len(x), rng, 7.0), cls if np.ndim(cls) == 0 else cls[idx],
                   self._material_intensity(boxes, idx, 0.6))

    def _emit_beds(self, rho):
        """Flower beds (``self.beds``: boxes with ground and height): low green with flowers."""
        b = self.beds
        if b.n == 0:
            return
        rng = self.rng_sample
        idx = repeat_index(integer_counts(rng, 4 * b.hx * b.hy * rho))
        x = (b.cx[idx] + (rng.random(len(idx)) * 2 - 1) * b.hx[idx]).astype(F32)
        y = (b.cy[idx] + (rng.random(len(idx)) * 2 - 1) * b.hy[idx]).astype(F32)
        k = self._keep(x, y)
        x, y, idx = x[k], y[k], idx[k]
        n = len(x)
        z = (b.ground[idx] + b.h[idx] * rng.uniform(0.5, 1.0, n)).astype(F32)
        flowers = np.array([[200, 60, 70], [220, 190, 60], [190, 120, 190], [230, 230, 230]], dtype=F32)
        rgb = noisy_colour((60, 105, 45), n, rng, 14.0)
        fl = rng.random(n) < 0.35
        rgb[fl] = flowers[rng.integers(0, len(flowers), int(fl.sum()))]
        self._emit(x, y, z, rgb, CLASS_LOW_VEG)

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
        idx = repeat_index(integer_counts(rng, np.pi * t.R ** 2 * area_factor * rho))
        d = ellipsoid_shell(rng, len(idx), top_bias=top_bias, thickness=thickness)
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
            idx = repeat_index(integer_counts(rng, 2 * np.pi * 0.18 * h * rho * 0.3))
            a = rng.random(len(idx), dtype=F32) * F32(2 * np.pi)
            x = t.cx[idx].astype(F32) + r * np.cos(a)
            y = t.cy[idx].astype(F32) + r * np.sin(a)
            z = t.ground[idx].astype(F32) + rng.random(len(idx), dtype=F32) * h[idx]
            k = self._keep(x, y)
            self._emit(x[k], y[k], z[k], noisy_colour((92, 72, 55), int(k.sum()), rng, 10.0), cls,
                       self._material_intensity(t, idx[k], 0.8))

    def _file_order(self, xyz):
        """Points in 10 m tiles, row by row, shuffled inside a tile (like a tiled export)."""
        tile = 10.0
        nt = int(math.ceil(self.side / tile)) + 1
        col = np.clip((xyz[:, 0] / tile).astype(np.int64), 0, nt - 1)
        row = np.clip((xyz[:, 1] / tile).astype(np.int64), 0, nt - 1)
        key = ((row * nt + col) << 32) | self.rng_pick.integers(0, 1 << 32, len(xyz), dtype=np.int64)
        return np.argsort(key)


class PhotoScene(Scene):
    """A photogrammetric street scene (uav-road, uav-road-v1): point heights from the scene's own
    ``_ground`` surface, and an intensity that carries the colour luminance (x 257), as
    photogrammetry has no sensor intensity."""

    def _ground_height(self, x, y):
        scalar = np.ndim(x) == 0
        z = self._ground(np.atleast_1d(np.asarray(x, dtype=F32)), np.atleast_1d(np.asarray(y, dtype=F32)),
                         colour=False)
        return float(z[0]) if scalar else z

    def _final_intensity(self, rgb, inten):
        rgb = np.rint(rgb)
        return (F32(0.299) * rgb[:, 0] + F32(0.587) * rgb[:, 1] + F32(0.114) * rgb[:, 2]) * F32(257.0)
