"""uav-road-v1: the UAV street scene of sessions 1-5 (straight roads on a 70 m block grid),
kept bit for bit so that earlier figures stay reproducible (``--kind uav-road-v1``)."""
from __future__ import annotations

import math

import numpy as np

from roadx_ti.synthetic.base import (
    CAR_COLOURS,
    CLASS_BUILDING,
    CLASS_GROUND,
    CLASS_HIGH_VEG,
    CLASS_MED_VEG,
    CLASS_OTHER,
    CLASS_ROAD,
    F32,
    Boxes,
    PhotoScene,
    Raster,
    SmoothNoise,
    integer_counts,
    noisy_colour,
    repeat_index,
    shadow_height,
    smoothstep,
    top_surface,
)

_WALL_COLOURS = np.array([[205, 190, 165], [222, 216, 204], [150, 85, 65], [160, 158, 152],
                          [190, 170, 130]], dtype=F32)
_PITCHED_ROOF_COLOURS = np.array([[150, 70, 50], [125, 82, 62], [72, 74, 80], [165, 95, 60]], dtype=F32)
_FLAT_ROOF_COLOURS = np.array([[130, 125, 115], [58, 58, 62], [200, 200, 196], [104, 103, 100]], dtype=F32)


class UavRoadV1Scene(PhotoScene):
    """Blocks of 70 m: a main road along x (11 m carriageway with parking lanes) at v = 10 m in
    every block row, a branch road along y (8 m) from it to the next row's main road (a T-junction
    at each end), 3 m sidewalks behind 10-15 cm kerbs, and four lots per block: buildings, gardens,
    and in some blocks (always the first) a hillside."""
    KIND_ID = 1
    KIND = "uav-road-v1"
    ORIGIN = (500000.0, 4500000.0, 0.0)
    NOMINAL_DENSITY = 200.0      # points per m2 of scene footprint
    OUTLIER_FRACTION = 0.005
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
        self.density_noise = SmoothNoise(r, 40.0)
        self.sigma_noise = SmoothNoise(r, 30.0)
        self.asphalt_noise = SmoothNoise(r, 6.0)
        self.grass_noise = SmoothNoise(r, 3.0)
        self.sun_az = r.uniform(0, 2 * np.pi)
        self.sun_tan = math.tan(math.radians(r.uniform(38, 55)))

        self.hill = np.zeros((nb, nb, 6))         # u0, u1, v0, v1, H, ramp
        buildings, trees, cars, poles, bushes, beds = [], [], [], [], [], []
        for bx in range(nb):
            for by in range(nb):
                self._layout_block(r, bx, by, buildings, trees, cars, poles, bushes, beds)
        keys_b = ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge", "roof", "roof_rgb", "wall_rgb")
        self.buildings = Boxes.from_rows(buildings, keys_b)
        self.trees = Boxes.from_rows(trees, ("cx", "cy", "ground", "cz", "R", "rz", "trunk", "rgb"))
        self.bushes = Boxes.from_rows(bushes, ("cx", "cy", "ground", "cz", "R", "rz", "trunk", "rgb"))
        self.cars = Boxes.from_rows(cars, ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge",
                                            "roof", "roof_rgb", "wall_rgb"))
        self.poles = Boxes.from_rows(poles, ("x", "y", "ground", "h"))
        self.beds = Boxes.from_rows(beds, ("cx", "cy", "hx", "hy", "ground", "h"))
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
                         roof_rgb=CAR_COLOURS[r.integers(0, len(CAR_COLOURS))],
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
        s = (smoothstep((u - u0) / ru) * smoothstep((u1 - u) / ru)
             * smoothstep((v - v0) / rv) * smoothstep((v1 - v) / rv))
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

    # ---------------------------------------------------------------- shadows and density
    def _build_shadow_raster(self):
        ras = Raster(self.side, 0.5)
        ground = self._ground(ras.xc.ravel(), ras.yc.ravel(), colour=False).reshape(ras.xc.shape)
        top = top_surface(ras, ground, (self.buildings, self.cars), (self.trees, self.bushes))
        self.shadow_raster = ras
        self.shadow = shadow_height(top, ras.cell, self.sun_az, self.sun_tan, pool=max(1, round(0.5 / ras.cell)))

    def _density(self, x, y):
        # 100..400 pts/m2 around the mean: a factor of 4 between the sparsest and densest areas
        t = 0.5 + 0.5 * np.tanh(self.density_noise(x, y))
        return F32(0.25) + F32(0.75) * t

    # ---------------------------------------------------------------- sampling
    def _emit_all(self, rho):
        for x, y in self._ground_candidates(rho):
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
        idx = repeat_index(integer_counts(rng, length * self.kerb * rho * 0.6))
        t = rng.random(len(idx), dtype=F32)
        s = segs[idx].astype(F32)
        x = s[:, 0] + t * (s[:, 2] - s[:, 0])
        y = s[:, 1] + t * (s[:, 3] - s[:, 1])
        k = self._keep(x, y)
        x, y = x[k], y[k]
        _, _, _, _, dm, db, _ = self._roads(x, y)
        edge = self._terrain(x, y) - F32(0.02) * np.where(dm - F32(W) <= db - F32(WB), F32(W), F32(WB))
        z = edge + rng.random(len(x), dtype=F32) * F32(self.kerb)
        self._emit(x, y, z, noisy_colour(self.KERB_STONE, len(x), rng, 5.0), CLASS_GROUND)

    def _emit_poles(self, rho):
        p = self.poles
        if p.n == 0:
            return
        rng = self.rng_sample
        r = F32(0.09)
        idx = repeat_index(integer_counts(rng, (2 * np.pi * 0.09 * p.h * 0.5 + 0.6 * 0.3 * 3) * rho))
        n = len(idx)
        a = rng.random(n, dtype=F32) * F32(2 * np.pi)
        head = rng.random(n) < 0.6 * 0.3 * 3 / (2 * np.pi * 0.09 * p.h[idx] * 0.5 + 0.54)
        x = p.x[idx].astype(F32) + np.where(head, rng.uniform(-0.3, 0.3, n).astype(F32), r * np.cos(a))
        y = p.y[idx].astype(F32) + np.where(head, rng.uniform(-0.15, 0.15, n).astype(F32), r * np.sin(a))
        z = (p.ground[idx] + np.where(head, p.h[idx], rng.random(n) * p.h[idx])).astype(F32)
        k = self._keep(x, y)
        self._emit(x[k], y[k], z[k], noisy_colour((112, 114, 118), int(k.sum()), rng, 6.0), CLASS_OTHER)

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

