"""als-roof: an airborne LiDAR suburb with orthophoto colour (METHODS.md P test bed)."""
from __future__ import annotations

import math

import numpy as np

from roadx_ti.synthetic.base import (
    CAR_COLOURS,
    CLASS_BUILDING,
    CLASS_GROUND,
    CLASS_HIGH_VEG,
    CLASS_LOW_VEG,
    CLASS_MED_VEG,
    CLASS_OTHER,
    CLASS_ROAD,
    F32,
    Boxes,
    Raster,
    Scene,
    SmoothNoise,
    integer_counts,
    repeat_index,
    roof_height,
    shadow_height,
    to_local,
    to_world,
)

_TILE_ROOFS = np.array([[158, 78, 58], [128, 86, 66], [176, 102, 72], [110, 60, 50]], dtype=F32)
_GREY_ROOFS = np.array([[128, 128, 126], [150, 148, 142], [92, 94, 98]], dtype=F32)
_DARK_ROOFS = np.array([[52, 54, 60], [64, 60, 58]], dtype=F32)
_GREEN_ROOFS = np.array([[70, 112, 60], [88, 122, 70], [60, 96, 58]], dtype=F32)


class AlsRoofScene(Scene):
    """Blocks of 100 m with 7 m streets along x and y, 3 x 3 lots: detached houses (gable, hip,
    flat roofs; chimneys; attached annexes; garden sheds), some large flat-roofed buildings (HVAC
    units, some green roofs), gardens with trees (some touching the houses), hedges, low shrubs,
    cars and vans. ALS look: flight-strip density pattern, few wall points, returns inside crowns,
    orthophoto colour."""
    KIND_ID = 2
    KIND = "als-roof"
    ORIGIN = (870000.0, 6618000.0, 0.0)
    NOMINAL_DENSITY = 15.0      # points per m2 of scene footprint
    OUTLIER_FRACTION = 0.0008
    BLOCK = 100.0
    STREET, HALF = 6.0, 3.5
    OUTLIER_RANGE = (1.0, 8.0)
    HIGH_SCALE = 5.0
    UNDER_CANOPY_HIDDEN = 0.55
    # Truth of the garden sheds (2.6-10.2 m2, alone in a lot corner): "other" (1), the convention of
    # IGN Lidar HD's classification in the shared tiles, whose isolated small planar structures
    # (5-11 m2, 1.9-2.5 m above ground) are class 1 while every class-6 part belongs to a building
    # (ACCURACY.md, roof notes); the roof pipeline's minimum roof area (10 m2) follows the same.
    SHED_CLASS = CLASS_OTHER

    def _layout(self):
        r = self.rng_layout
        B, nb = self.BLOCK, self.nb
        self.z0 = 40.0
        self.terrain_noise = SmoothNoise(r, 450.0, n_waves=4)
        self.terrain_amp = r.uniform(1.5, 4.0)
        self.grass_noise = SmoothNoise(r, 8.0)
        self.colour_noise = SmoothNoise(r, 25.0)
        self.density_noise = SmoothNoise(r, 60.0)
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
        kb = ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge", "roof", "roof_rgb", "inten", "over", "cls")
        self.buildings = Boxes.from_rows(rows["b"], kb)
        self.cars = Boxes.from_rows(rows["c"], kb)
        self.trees = Boxes.from_rows(rows["t"], ("cx", "cy", "ground", "cz", "R", "rz", "rgb", "inten"))
        self.hedges = Boxes.from_rows(rows["h"], ("cx", "cy", "hx", "hy", "ang", "ground", "height"))
        self.shrubs = Boxes.from_rows(rows["low"], ("cx", "cy", "hx", "hy", "ang", "ground", "height"))
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

    def _box(self, rows, key, cx, cy, hx, hy, ang, base, eave, ridge, roof, rgb, inten, over=0.0, cls=CLASS_BUILDING):
        rows[key].append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=base, eave=eave, ridge=ridge,
                              roof=roof, roof_rgb=rgb, inten=inten, over=over, cls=cls))

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
                    rgb = CAR_COLOURS[r.integers(0, len(CAR_COLOURS))]
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
            zr = float(roof_height(np.array([lx], F32), np.array([ly], F32),
                                    dict(hx=F32(hx), hy=F32(hy), eave=F32(eave), ridge=F32(ridge), roof=F32(roof)))[0])
            qx, qy = to_world(np.array([lx], F32), np.array([ly], F32), F32(cx), F32(cy), np.float32(ang))
            s = r.uniform(0.3, 0.5)
            top = zr + r.uniform(1.0, 1.5)
            self._box(rows, "b", float(qx[0]), float(qy[0]), s, s, ang, zr - 0.5, top, top, 0,
                      np.array([120, 70, 55]), 1400.0)
        elif roof == 0:
            self._superstructures(r, rows, cx, cy, hx, hy, ang, eave, int(r.integers(1, 3)))
        # attached annex (garage) on a short side, garden shed in a corner (2.6-10.2 m2: SHED_CLASS)
        if r.random() < 0.5 or first:
            ax, ay = r.uniform(1.5, 3.0), r.uniform(1.5, 3.0)
            lx = hx + ax
            qx, qy = to_world(np.array([lx], F32), np.array([0.0], F32), F32(cx), F32(cy), np.float32(ang))
            ab = self._ground_height(float(qx[0]), float(qy[0])) - 0.1
            top = ab + r.uniform(2.5, 3.3)
            rgb, inten = self._roof_style(r)
            self._box(rows, "b", float(qx[0]), float(qy[0]), ax, ay, ang, ab, top, top, 0, rgb, inten)
        if r.random() < 0.6 or first:
            sx, sy = cx - lot / 2 + 2.5, cy + lot / 2 - 2.5
            a, b = r.uniform(0.8, 1.6), r.uniform(0.8, 1.6)
            sb = self._ground_height(sx, sy) - 0.05
            self._box(rows, "b", sx, sy, max(a, b), min(a, b), r.uniform(0, np.pi), sb, sb + r.uniform(1.9, 2.3),
                      sb + r.uniform(2.3, 2.7), 1, _GREY_ROOFS[r.integers(0, 3)], 1600.0, 0.15, cls=self.SHED_CLASS)
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
            qx, qy = to_world(np.array([lx], F32), np.array([ly], F32), F32(cx), F32(cy), np.float32(ang))
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
        ras = Raster(self.side, max(0.25, self.side / 2500.0))
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
                lx, ly = to_local(ras.xc[w], ras.yc[w], b["cx"], b["cy"], b["ang"])
                inside = (np.abs(lx) <= b["hx"] + b["over"]) & (np.abs(ly) <= b["hy"] + b["over"])
                h = roof_height(lx, ly, b)
                top[w] = np.where(inside, np.maximum(top[w], h), top[w])
                # the orthophoto shows the roof displaced by the building lean
                shift = (float(b["ridge"]) - float(objs.base[i])) * self.lean
                lx, ly = to_local(ras.xc[w] - F32(shift[0]), ras.yc[w] - F32(shift[1]), b["cx"], b["cy"], b["ang"])
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
                lx, ly = to_local(ras.xc[w], ras.yc[w], F32(cx), F32(cy), ang)
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
        shadow = shadow_height(top, ras.cell, self.sun_az, self.sun_tan, pool=max(1, round(0.5 / ras.cell)))
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
        for x, y in self._ground_candidates(rho):
            street = self._is_street(x, y)
            n = len(x)
            z = self._terrain(x, y) + np.where(street, F32(0), F32(0.03) * self.grass_noise(x, y))
            inten = np.where(street, F32(650), F32(2500)) * (F32(1) + F32(0.25) * rng.standard_normal(n, dtype=F32))
            cls = np.where(street, CLASS_ROAD, CLASS_GROUND).astype(np.uint8)
            self._emit(x, y, z, np.zeros((n, 3), F32), cls, inten)
        self._emit_boxes(self.buildings, rho, wall_factor=0.06, cls=self.buildings.cls.astype(np.uint8), windows=False)
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
        idx = repeat_index(integer_counts(rng, 4 * v.hx * v.hy * rho * 1.4))
        n = len(idx)
        lx = ((rng.random(n) * 2 - 1) * v.hx[idx]).astype(F32)
        ly = ((rng.random(n) * 2 - 1) * v.hy[idx]).astype(F32)
        x, y = to_world(lx, ly, v.cx[idx].astype(F32), v.cy[idx].astype(F32), v.ang[idx])
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



class AlsRoofV1Scene(AlsRoofScene):
    """als-roof of earlier releases, bit for bit: its garden sheds labelled building (6)."""
    KIND = "als-roof-v1"
    SHED_CLASS = CLASS_BUILDING
