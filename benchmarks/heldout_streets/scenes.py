"""Street scenes made independently of roadx_ti.synthetic (written by a separate session that did
not read the project's generator): UAV-photogrammetry-like point clouds (the surfaces seen from
the sky, some wall and side points) of layouts and looks the project's generator lacks: a
roundabout, a boulevard with a planted median, a curved country lane without kerbs, an old-town
alley with flush stone paving, a parking lot, a 7 % street, a red curve with cross-fall, a tree
avenue; and (a second session) kerbs hidden by cars parked bumper to bumper,
an urban canyon in deep shadow, sidewalks darker than the asphalt beside a raised cycle track,
20 points/m2 with 7 cm noise, doubled flight strips with an exposure seam and holes, a wide
junction with kerbed islands, speed bumps and a raised table, a hillside road with a retaining
wall above and a steep bank below. Truth classes: 11 road surface (drivable, with parking lanes / lots and markings),
2 other ground, 6 building, 5 vegetation, 1 other (cars, poles, pedestrians, umbrellas).

    python benchmarks/heldout_streets/scenes.py NAME [NAME ...] | all

writes OUTDIR/NAME.laz and NAME.meta.npz (scene parts, shadow flags) with OUTDIR the environment's
or benchmarks/out/heldout_streets. run.py generates, runs and scores them.
"""
from __future__ import annotations

import sys
import time

import numpy as np
import laspy
from scipy.ndimage import map_coordinates
from scipy.spatial import cKDTree

import os
from pathlib import Path

OUTDIR = os.environ.get("OUTDIR", str(Path(__file__).resolve().parents[1] / "out" / "heldout_streets"))
DSCALE = float(os.environ.get("DSCALE", "1"))
ROAD, GROUND, BUILDING, VEG, OTHER = 11, 2, 6, 5, 1


def ms_dscale():
    return DSCALE


# ----------------------------------------------------------------------------- helpers
class Noise:
    """Value noise: bilinear interpolation of a random grid (cell size c), frozen per instance."""

    def __init__(self, rng, W, H, cell, pad=40.0):
        self.cell, self.pad = cell, pad
        nx = int((W + 2 * pad) / cell) + 3
        ny = int((H + 2 * pad) / cell) + 3
        self.g = rng.normal(0.0, 1.0, (ny, nx))

    def __call__(self, x, y):
        return map_coordinates(self.g, [(np.asarray(y) + self.pad) / self.cell,
                                        (np.asarray(x) + self.pad) / self.cell], order=1, mode="nearest")


def cellhash(ix, iy, salt=0):
    h = (np.asarray(ix, np.int64) * 73856093) ^ (np.asarray(iy, np.int64) * 19349663) ^ (salt * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    h = h ^ (h >> 16)
    return (h % 100003).astype(np.float64) / 100003.0


def rot(x, y, cx, cy, ang):
    """Coordinates of (x, y) in a frame centred at (cx, cy) rotated by ang (u along, v across)."""
    c, s = np.cos(ang), np.sin(ang)
    dx, dy = x - cx, y - cy
    return c * dx + s * dy, -s * dx + c * dy


def smooth01(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


class Polyline:
    """Centre line sampled every 0.2 m; local(x, y) -> lateral offset (left +), arc length s."""

    def __init__(self, pts, step=0.2):
        pts = np.asarray(pts, float)
        seg = np.diff(pts, axis=0)
        L = np.hypot(seg[:, 0], seg[:, 1])
        cum = np.concatenate([[0], np.cumsum(L)])
        s = np.arange(0, cum[-1] + 1e-9, step)
        self.x = np.interp(s, cum, pts[:, 0])
        self.y = np.interp(s, cum, pts[:, 1])
        tx = np.gradient(self.x)
        ty = np.gradient(self.y)
        n = np.hypot(tx, ty)
        self.tx, self.ty, self.s = tx / n, ty / n, s
        self.length = cum[-1]
        self.tree = cKDTree(np.c_[self.x, self.y])
        self._cache = None

    def local(self, x, y):
        key = (len(x), x[:8].tobytes(), x[-8:].tobytes(), y[:8].tobytes(), y[-8:].tobytes())
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        _, i = self.tree.query(np.c_[x, y], workers=2)
        dx, dy = x - self.x[i], y - self.y[i]
        along = dx * self.tx[i] + dy * self.ty[i]
        lat = -dx * self.ty[i] + dy * self.tx[i]
        s = self.s[i] + along
        # beyond the ends: distance grows along the tangent
        out = (s < 0) | (s > self.length)
        res = (lat, s, out)
        self._cache = (key, res)
        return res

    def sdf_band(self, half, cap=True):
        def f(x, y):
            lat, s, out = self.local(x, y)
            d = np.abs(lat) - half
            if cap:
                d = np.where(s < 0, np.maximum(d, -s), d)
                d = np.where(s > self.length, np.maximum(d, s - self.length), d)
            return d
        return f


def arc_pts(cx, cy, r, a0, a1, n=200):
    a = np.linspace(a0, a1, n)
    return np.c_[cx + r * np.cos(a), cy + r * np.sin(a)]


def bezier(p0, p1, p2, p3, n=300):
    t = np.linspace(0, 1, n)[:, None]
    p0, p1, p2, p3 = map(np.asarray, (p0, p1, p2, p3))
    return (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t ** 2 * p2 + t ** 3 * p3


def sdf_circle(cx, cy, r):
    return lambda x, y: np.hypot(x - cx, y - cy) - r


def sdf_annulus(cx, cy, r0, r1):
    def f(x, y):
        d = np.hypot(x - cx, y - cy)
        return np.maximum(r0 - d, d - r1)
    return f


def sdf_box(cx, cy, hl, hw, ang=0.0):
    def f(x, y):
        u, v = rot(x, y, cx, cy, ang)
        return np.maximum(np.abs(u) - hl, np.abs(v) - hw)
    return f


def sdf_union(*fs):
    return lambda x, y: np.min([f(x, y) for f in fs], axis=0)


def sdf_sub(a, b):
    return lambda x, y: np.maximum(a(x, y), -b(x, y))


def sdf_inter(a, b):
    return lambda x, y: np.maximum(a(x, y), b(x, y))


# ----------------------------------------------------------------------------- materials
class Mat:
    def __init__(self, sc):
        self.sc = sc
        self.rng = sc.rng
        self.n3 = Noise(sc.rng, sc.W, sc.H, 3.0)
        self.n1 = Noise(sc.rng, sc.W, sc.H, 0.6)
        self.n10 = Noise(sc.rng, sc.W, sc.H, 12.0)

    def grain(self, n, s):
        return self.rng.normal(0, s, (n, 1))

    def asphalt(self, base, wear=0.06, grain=0.035):
        base = np.asarray(base, float)

        def f(x, y):
            k = 1 + wear * self.n3(x, y) + 0.5 * wear * self.n10(x, y) + 0.03 * self.n1(x, y)
            return base * k[:, None] * (1 + self.grain(len(x), grain)) + self.rng.normal(0, 0.008, (len(x), 3))
        return f

    def concrete_slabs(self, base, a=5.0, b=None, ang=0.0, joint=0.012, jdark=0.7):
        base = np.asarray(base, float)
        b = a if b is None else b

        def f(x, y):
            u, v = rot(x, y, 0, 0, ang)
            iu, iv = np.floor(u / a), np.floor(v / b)
            h = cellhash(iu, iv, 7)
            k = (0.94 + 0.12 * h) * (1 + 0.03 * self.n1(x, y))
            fu, fv = u - iu * a, v - iv * b
            j = (np.minimum(fu, a - fu) < joint) | (np.minimum(fv, b - fv) < joint)
            k = np.where(j, k * jdark, k)
            return base * k[:, None] * (1 + self.grain(len(x), 0.025))
        return f

    def pavers(self, base, a=0.2, b=0.1, ang=0.0, var=0.25, joint=0.006, jdark=0.6, tint=None, herring=False):
        base = np.asarray(base, float)
        tint = None if tint is None else np.asarray(tint, float)

        def f(x, y):
            u, v = rot(x, y, 0, 0, ang)
            if herring:   # alternate blocks of rotated pavers
                blk = (np.floor(u / (2 * a)) + np.floor(v / (2 * a))) % 2 == 1
                u, v = np.where(blk, v, u), np.where(blk, u, v)
            row = np.floor(v / b)
            u2 = u + (row % 2) * a / 2
            col = np.floor(u2 / a)
            h = cellhash(col, row, 3)
            k = 1 - var / 2 + var * h
            fu, fv = u2 - col * a, v - row * b
            j = (np.minimum(fu, a - fu) < joint) | (np.minimum(fv, b - fv) < joint)
            k = np.where(j, k * jdark, k)
            c = base * k[:, None]
            if tint is not None:
                sel = cellhash(col, row, 11) < 0.25
                c[sel] = tint * k[sel, None]
            return c * (1 + self.grain(len(x), 0.02))
        return f

    def cobbles(self, base, a=0.12, var=0.35):
        return self.pavers(base, a=a, b=a, var=var, joint=0.014, jdark=0.45)

    def grass(self, base=(0.30, 0.42, 0.17), dry=0.0):
        base = np.asarray(base, float)

        def f(x, y):
            n = self.n3(x, y)
            k = 1 + 0.12 * n + 0.08 * self.n1(x, y)
            c = base * k[:, None] * (1 + self.grain(len(x), 0.08))
            brown = np.array([0.45, 0.40, 0.25])
            w = np.clip(dry + 0.25 * self.n10(x, y), 0, 0.8)[:, None]
            c = c * (1 - w) + brown * w * k[:, None]
            return c + self.rng.normal(0, 0.02, (len(x), 3))
        return f

    def field(self, base=(0.36, 0.40, 0.18), soil=(0.45, 0.36, 0.26), period=0.75, ang=0.3):
        base, soil = np.asarray(base, float), np.asarray(soil, float)

        def f(x, y):
            u, v = rot(x, y, 0, 0, ang)
            w = (0.5 + 0.5 * np.sin(2 * np.pi * v / period)) ** 2
            c = base * w[:, None] + soil * (1 - w[:, None])
            return c * (1 + 0.1 * self.n3(x, y))[:, None] * (1 + self.grain(len(x), 0.06))
        return f

    def gravel(self, base=(0.55, 0.52, 0.47)):
        base = np.asarray(base, float)
        return lambda x, y: base * (1 + 0.05 * self.n3(x, y))[:, None] * (1 + self.grain(len(x), 0.12))

    def solid(self, rgb, g=0.03):
        rgb = np.asarray(rgb, float)
        return lambda x, y: rgb * (1 + self.grain(len(x), g))


# ----------------------------------------------------------------------------- scene
class Scene:
    def __init__(self, name, seed, W, H, density, hnoise, cnoise, rgbmode, sun_az, sun_el, rot_deg,
                 origin, z0, shadow=(0.42, 0.47, 0.60)):
        self.name, self.seed = name, seed
        self.rng = np.random.default_rng(seed)
        self.W, self.H = W, H
        self.density, self.hnoise, self.cnoise = density, hnoise, cnoise
        self.rgbmode = rgbmode
        self.sun_az, self.sun_el = np.radians(sun_az), np.radians(sun_el)
        self.rot = np.radians(rot_deg)
        self.origin, self.z0 = origin, z0
        self.shadow = np.asarray(shadow)
        self.layers = []      # ground layers: dict(sdf, cls, mat, dz, rim, eps)
        self.objects = []     # objects with .bbox, .top(x, y, ground) and .extra(sc)
        self.terrain = lambda x, y: np.zeros_like(x)
        self.M = Mat(self)

    # ground layers ------------------------------------------------------------
    def layer(self, sdf, cls, mat, dz=None, rim=None, rim_w=0.15, rim_out=False, eps=0.04, rimdz=None, name=None):
        """dz: absolute offset to the terrain (float or f(x, y)); None keeps the current height.
        rim: colour function for a band of rim_w inside the edge (or outside: rim_out, the kerb of a
        road on the sidewalk side, where the point keeps its class and height)."""
        self.layers.append(dict(sdf=sdf, cls=cls, mat=mat, dz=dz, rim=rim, rim_w=rim_w, rim_out=rim_out, eps=eps,
                                name=name or f"L{len(self.layers)}:{'road' if cls == ROAD else 'ground'}"))

    def ground(self, x, y, colour=True):
        n = len(x)
        dz = np.zeros(n)
        cls = np.full(n, GROUND, np.uint8)
        rgb = np.zeros((n, 3)) + 0.4 if colour else None
        part = np.zeros(n, np.int16)
        kerbband = np.zeros(n, bool)
        for li, L in enumerate(self.layers):
            d = L["sdf"](x, y)
            ins = d < 0
            if L["dz"] is not None:
                near = d < L["eps"]
                if near.any():
                    tgt = L["dz"](x[near], y[near]) if callable(L["dz"]) else np.full(near.sum(), L["dz"])
                    w = smooth01(0.5 - d[near] / (2 * L["eps"]))
                    dz[near] = dz[near] + (tgt - dz[near]) * w
            cls[ins] = L["cls"]
            part[ins] = li
            kerbband[ins] = False
            if colour:
                if ins.any():
                    rgb[ins] = L["mat"](x[ins], y[ins])
                if L["rim"] is not None:
                    band = ((d >= 0) & (d < L["rim_w"]) & (cls != ROAD)) if L["rim_out"] else (ins & (d > -L["rim_w"]))
                    if band.any():
                        rgb[band] = L["rim"](x[band], y[band])
                        kerbband |= band
        z = self.terrain(x, y) + dz
        if colour:
            self._part, self._kerb = part, kerbband
        return z, cls, rgb

    def ground_z(self, x, y):
        x, y = np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float))
        return self.ground(x, y, colour=False)[0]

    # objects -------------------------------------------------------------------
    def add(self, obj):
        obj.prepare(self)
        self.objects.append(obj)

    # generation ----------------------------------------------------------------
    def generate(self):
        t0 = time.time()
        rng = self.rng
        W, H = self.W, self.H
        n0 = int(self.density * DSCALE * W * H * 1.15)
        x = rng.uniform(0, W, n0)
        y = rng.uniform(0, H, n0)
        dn = Noise(rng, W, H, 15.0)
        keep = rng.uniform(0, 1, n0) < (0.87 + 0.13 * np.clip(dn(x, y), -1, 1))   # density variation
        x, y = x[keep], y[keep]
        z, cls, rgb = self.ground(x, y)
        part, kerbb = self._part, self._kerb
        oid = np.full(len(x), -1, np.int32)
        order = np.argsort(x)
        xs = x[order]
        for k, ob in enumerate(self.objects):
            x0, x1, y0, y1 = ob.bbox
            i0, i1 = np.searchsorted(xs, [x0, x1])
            idx = order[i0:i1]
            idx = idx[(y[idx] >= y0) & (y[idx] <= y1)]
            if len(idx) == 0:
                continue
            zt, ct, rt = ob.top(x[idx], y[idx])
            up = np.isfinite(zt) & (zt > z[idx])
            idx, zt, rt = idx[up], zt[up], rt[up]
            z[idx] = zt
            cls[idx] = ct if np.isscalar(ct) else ct[up]
            rgb[idx] = rt
            oid[idx] = k
        # extra points (walls, car sides, pole sides)
        ex = [ob.extra(self) for ob in self.objects]
        ex = [e for e in ex if e is not None and len(e[0])]
        if ex:
            x = np.concatenate([x] + [e[0] for e in ex])
            y = np.concatenate([y] + [e[1] for e in ex])
            z = np.concatenate([z] + [e[2] for e in ex])
            cls = np.concatenate([cls] + [np.full(len(e[0]), e[3], np.uint8) for e in ex])
            part = np.concatenate([part] + [np.full(len(e[0]), -2, np.int16) for e in ex])
            kerbb = np.concatenate([kerbb] + [np.zeros(len(e[0]), bool) for e in ex])
            oid = np.concatenate([oid] + [np.full(len(e[0]), -2, np.int32) for e in ex])
            rgb = np.concatenate([rgb] + [e[4] for e in ex])
        # shadows from a DSM of the top surface (vegetation cells porous: dappled shade)
        cs = 0.5
        nx, ny = int(W / cs) + 1, int(H / cs) + 1
        ix = np.clip((x / cs).astype(int), 0, nx - 1)
        iy = np.clip((y / cs).astype(int), 0, ny - 1)
        flat = iy * nx + ix
        dsm = np.full(nx * ny, -1e9)
        veg = cls == VEG
        np.maximum.at(dsm, flat[~veg], z[~veg])
        vd = np.full(nx * ny, -1e9)
        np.maximum.at(vd, flat[veg], z[veg])
        holes = rng.uniform(0, 1, nx * ny) < 0.22
        vd[holes] -= 3.0
        dsm = np.maximum(dsm, vd).reshape(ny, nx)
        dx, dy = np.cos(self.sun_az), np.sin(self.sun_az)   # direction to the sun (from +x, ccw)
        tan = np.tan(self.sun_el)
        span = z.max() - np.percentile(z, 2)
        steps = np.arange(0.6, span / tan + 0.5, 0.4)
        sh = np.zeros(len(x), bool)
        for t in steps:
            px = np.clip(((x + t * dx) / cs).astype(int), 0, nx - 1)
            py = np.clip(((y + t * dy) / cs).astype(int), 0, ny - 1)
            inside = (x + t * dx >= 0) & (x + t * dx < W) & (y + t * dy >= 0) & (y + t * dy < H)
            sh |= inside & (dsm[py, px] > z + t * tan + 0.25)
        rgb[sh] *= self.shadow
        # noise
        z = z + rng.normal(0, self.hnoise, len(z))
        rgb = rgb * (1 + rng.normal(0, 0.02, (len(z), 1))) + rng.normal(0, self.cnoise, rgb.shape)
        # photogrammetric outliers: a few floating / sunken points
        no = int(len(z) * 0.0008)
        io = rng.choice(len(z), no, replace=False)
        z[io] += rng.normal(0, 1.0, no)
        part = np.where(oid == -1, part, np.where(oid == -2, -2, -1))
        self.x, self.y, self.z, self.cls, self.rgb, self.sh = x, y, z, cls, np.clip(rgb, 0, 1), sh
        self.part, self.kerbb = part, kerbb
        self.gen_s = time.time() - t0
        return self

    def write(self, path):
        c, s = np.cos(self.rot), np.sin(self.rot)
        X = self.origin[0] + c * self.x - s * self.y
        Y = self.origin[1] + s * self.x + c * self.y
        Z = self.z0 + self.z
        # tile-like order: 25 m blocks, random inside
        blk = (np.floor(Y / 25) * 100000 + np.floor(X / 25))
        o = np.lexsort((self.rng.uniform(0, 1, len(X)), blk))
        self.order = o
        if os.environ.get("NOLAZ"):
            return len(X)
        hdr = laspy.LasHeader(point_format=7, version="1.4")
        hdr.scales = np.array([0.001, 0.001, 0.001])
        hdr.offsets = np.array([np.floor(X.min() / 1000) * 1000, np.floor(Y.min() / 1000) * 1000, 0.0])
        las = laspy.LasData(hdr)
        las.x, las.y, las.z = X[o], Y[o], Z[o]
        las.classification = self.cls[o]
        rgb = self.rgb[o]
        if self.rgbmode == "x257":
            v = np.round(rgb * 255).astype(np.uint16) * 257
        elif self.rgbmode == "x256":
            v = np.round(rgb * 255).astype(np.uint16) << 8
        else:  # full 16-bit
            v = np.round(rgb * 65535).astype(np.uint16)
        las.red, las.green, las.blue = v[:, 0], v[:, 1], v[:, 2]
        las.gps_time = np.arange(len(X), dtype=float) * 1e-4
        las.return_number = np.ones(len(X), np.uint8)
        las.number_of_returns = np.ones(len(X), np.uint8)
        las.write(path)
        return len(X)


# ----------------------------------------------------------------------------- objects
class Building:
    def __init__(self, cx, cy, L, Wd, ang, h, roof="flat", rise=3.0, roof_col=(0.55, 0.27, 0.2),
                 wall_col=(0.8, 0.76, 0.68), ridge_along=True, base=None, parapet=0.0, units=0, wall_frac=0.06):
        self.cx, self.cy, self.L, self.Wd, self.ang, self.h = cx, cy, L, Wd, ang, h
        self.roof, self.rise, self.roof_col, self.wall_col = roof, rise, np.asarray(roof_col), np.asarray(wall_col)
        self.ridge_along, self.base, self.parapet, self.units, self.wall_frac = ridge_along, base, parapet, units, wall_frac

    def prepare(self, sc):
        r = np.hypot(self.L, self.Wd) / 2 + 0.1
        self.bbox = (self.cx - r, self.cx + r, self.cy - r, self.cy + r)
        if self.base is None:
            u = np.array([-1, 1, 1, -1, 0]) * self.L / 2
            v = np.array([-1, -1, 1, 1, 0]) * self.Wd / 2
            c, s = np.cos(self.ang), np.sin(self.ang)
            self.base = float(sc.ground_z(self.cx + c * u - s * v, self.cy + s * u + c * v).min())
        rng = sc.rng
        self.sun = (np.cos(sc.sun_az - self.ang), np.sin(sc.sun_az - self.ang))
        self.ulist = [(rng.uniform(-0.35, 0.35) * self.L, rng.uniform(-0.3, 0.3) * self.Wd,
                       rng.uniform(0.8, 2.5), rng.uniform(0.8, 2.0), rng.uniform(0.8, 1.8)) for _ in range(self.units)]
        self.M = sc.M

    def top(self, x, y):
        u, v = rot(x, y, self.cx, self.cy, self.ang)
        ins = (np.abs(u) <= self.L / 2) & (np.abs(v) <= self.Wd / 2)
        z = np.full(len(x), np.nan)
        zt = self.base + self.h
        rgb = np.zeros((len(x), 3)) + self.roof_col
        if self.roof == "flat":
            zz = np.full(len(x), zt)
            if self.parapet > 0:
                edge = np.minimum(self.L / 2 - np.abs(u), self.Wd / 2 - np.abs(v)) < 0.3
                zz = np.where(edge, zt + self.parapet, zz)
                rgb[edge] = self.wall_col * 0.9
            for (uu, vv, a, b, hh) in self.ulist:
                m = (np.abs(u - uu) < a / 2) & (np.abs(v - vv) < b / 2)
                zz = np.where(m, zt + hh, zz)
                rgb[m] = np.array([0.7, 0.7, 0.72])
            rgb *= (1 + 0.05 * self.M.n3(x, y))[:, None]
        else:
            a_, b_ = (v, self.Wd / 2) if self.ridge_along else (u, self.L / 2)
            if self.roof == "gable":
                zz = zt + self.rise * (1 - np.abs(a_) / b_)
                side = np.sign(a_)
            else:  # shed
                zz = zt + self.rise * (0.5 + 0.5 * a_ / b_)
                side = np.ones(len(x))
            # tiles: rows along the slope
            row = np.floor(np.abs(a_) / 0.33)
            col = np.floor((u if self.ridge_along else v) / 0.25 + 0.5 * (row % 2))
            k = 0.9 + 0.2 * cellhash(col, row, 5)
            k = np.where((np.abs(a_) % 0.33) < 0.03, k * 0.75, k)
            # sun on the two roof planes
            nrm = self.sun[1] if self.ridge_along else self.sun[0]
            lam = 1 + 0.18 * side * nrm
            rgb = rgb * (k * lam)[:, None]
        z[ins] = zz[ins]
        return z, BUILDING, rgb

    def extra(self, sc):
        rng = sc.rng
        per = 2 * (self.L + self.Wd)
        n = int(per * self.h * sc.density * ms_dscale() * self.wall_frac)
        t = rng.uniform(0, per, n)
        L, Wd = self.L, self.Wd
        u = np.where(t < L, t - L / 2, np.where(t < L + Wd, L / 2, np.where(t < 2 * L + Wd, L / 2 - (t - L - Wd), -L / 2)))
        v = np.where(t < L, -Wd / 2, np.where(t < L + Wd, t - L - Wd / 2 - 0, np.where(t < 2 * L + Wd, Wd / 2, Wd / 2 - (t - 2 * L - Wd))))
        u = u + rng.normal(0, 0.03, n)
        v = v + rng.normal(0, 0.03, n)
        h = rng.uniform(0, 1, n) ** 0.8 * self.h        # fewer points low on the walls
        c, s = np.cos(self.ang), np.sin(self.ang)
        xw = self.cx + c * u - s * v
        yw = self.cy + s * u + c * v
        ok = (xw > 0) & (xw < sc.W) & (yw > 0) & (yw < sc.H)
        # windows
        win = ((np.abs(((u + v) % 3.0) - 1.5) < 0.6) & ((h % 3.0) > 1.0) & ((h % 3.0) < 2.3))
        rgb = np.zeros((n, 3)) + self.wall_col * (0.85 + 0.1 * rng.uniform(0, 1, (n, 1)))
        rgb[win] = np.array([0.2, 0.23, 0.27])
        # which side: facing the sun or not
        nrm = np.where(t < L, -1, np.where(t < L + Wd, 1, np.where(t < 2 * L + Wd, 1, -1)))
        facing = np.where((t < L) | ((t >= L + Wd) & (t < 2 * L + Wd)), nrm * self.sun[1], nrm * self.sun[0])
        rgb[facing < 0] *= sc.shadow
        gz = self.base + h
        return xw[ok], yw[ok], gz[ok], BUILDING, rgb[ok]


class Tree:
    def __init__(self, cx, cy, r, top, crown_base=None, col=(0.20, 0.32, 0.12), cls=VEG, lump=0.35):
        self.cx, self.cy, self.r, self.topz = cx, cy, r, top
        self.cb = crown_base if crown_base is not None else top * 0.45
        self.col, self.cls, self.lump = np.asarray(col), cls, lump

    def prepare(self, sc):
        self.bbox = (self.cx - self.r, self.cx + self.r, self.cy - self.r, self.cy + self.r)
        self.base = float(sc.ground_z(self.cx, self.cy)[0])
        self.nz = Noise(sc.rng, sc.W, sc.H, max(0.4, self.r / 3))
        self.M = sc.M
        self.sun = (np.cos(sc.sun_az), np.sin(sc.sun_az))
        self.rng = sc.rng

    def top(self, x, y):
        d = np.hypot(x - self.cx, y - self.cy) / self.r
        rr = self.r * (1 + 0.15 * self.nz(x, y))          # ragged outline
        d = np.hypot(x - self.cx, y - self.cy) / rr
        z = np.full(len(x), np.nan)
        ins = d < 1
        hc = self.topz - self.cb
        zz = self.base + self.cb + hc * np.sqrt(np.clip(1 - d ** 2, 0, 1)) ** 0.8 + self.lump * self.nz(x * 1.7, y * 1.7)
        z[ins] = zz[ins]
        # lit side brighter, clumps
        lit = ((x - self.cx) * self.sun[0] + (y - self.cy) * self.sun[1]) / self.r
        k = (0.85 + 0.25 * lit + 0.3 * self.nz(x * 2.3, y * 2.3)) * (1 + self.rng.normal(0, 0.15, len(x)))
        rgb = self.col * np.clip(k, 0.3, 1.8)[:, None]
        return z, self.cls, rgb

    def extra(self, sc):
        return None


class Car:
    PALETTE = [(0.85, 0.85, 0.86), (0.12, 0.12, 0.13), (0.45, 0.46, 0.48), (0.6, 0.62, 0.64), (0.55, 0.08, 0.07),
               (0.1, 0.2, 0.45), (0.9, 0.9, 0.88), (0.25, 0.3, 0.25), (0.75, 0.6, 0.2), (0.3, 0.15, 0.1)]

    def __init__(self, cx, cy, ang, L=4.4, Wd=1.8, h=1.5, col=None, van=False):
        self.cx, self.cy, self.ang, self.L, self.Wd, self.h, self.col, self.van = cx, cy, ang, L, Wd, h, col, van

    def prepare(self, sc):
        r = np.hypot(self.L, self.Wd) / 2 + 0.1
        self.bbox = (self.cx - r, self.cx + r, self.cy - r, self.cy + r)
        self.base = float(sc.ground_z(self.cx, self.cy)[0])
        if self.col is None:
            self.col = Car.PALETTE[sc.rng.integers(len(Car.PALETTE))]
        self.col = np.asarray(self.col)
        self.rng = sc.rng

    def prof(self, u):
        L = self.L
        if self.van:
            return np.where(u > 0.4 * L, self.h * 0.75, self.h)
        # hood (front), cabin, boot
        return np.where(u > 0.22 * L, 0.95, np.where(u < -0.38 * L, 1.0, self.h))

    def top(self, x, y):
        u, v = rot(x, y, self.cx, self.cy, self.ang)
        ins = (np.abs(u) <= self.L / 2) & (np.abs(v) <= self.Wd / 2)
        zz = self.base + self.prof(u) * (1 - 0.25 * (np.abs(v) / (self.Wd / 2)) ** 4)
        z = np.where(ins, zz, np.nan)
        rgb = np.zeros((len(x), 3)) + self.col
        if not self.van:
            glass = (u < 0.22 * self.L) & (u > -0.38 * self.L) & ((np.abs(v) > 0.55) | (u > 0.12 * self.L) | (u < -0.28 * self.L))
            rgb[glass] = np.array([0.08, 0.09, 0.11])
        rgb *= (1 + self.rng.normal(0, 0.05, (len(x), 1)))
        return z, OTHER, rgb

    def extra(self, sc):
        n = int(2 * (self.L + self.Wd) * 0.9 * sc.density * ms_dscale() * 0.2)
        rng = sc.rng
        side = rng.integers(0, 2, n) * 2 - 1
        u = rng.uniform(-self.L / 2, self.L / 2, n)
        v = side * self.Wd / 2
        h = rng.uniform(0.25, 0.95, n)
        c, s = np.cos(self.ang), np.sin(self.ang)
        rgb = np.zeros((n, 3)) + self.col * 0.8
        rgb[h < 0.5] = np.array([0.07, 0.07, 0.07])  # wheels / sills
        return self.cx + c * u - s * v, self.cy + s * u + c * v, self.base + h, OTHER, rgb


class Disc:
    """Pole (lamp / sign), pedestrian, bollard, umbrella: a small disc top + side points."""

    def __init__(self, cx, cy, r, h, col=(0.4, 0.4, 0.42), side=True, cls=OTHER):
        self.cx, self.cy, self.r, self.h, self.col, self.side, self.cls = cx, cy, r, h, np.asarray(col), side, cls

    def prepare(self, sc):
        self.bbox = (self.cx - self.r, self.cx + self.r, self.cy - self.r, self.cy + self.r)
        self.base = float(sc.ground_z(self.cx, self.cy)[0])
        self.rng = sc.rng

    def top(self, x, y):
        d = np.hypot(x - self.cx, y - self.cy)
        z = np.where(d < self.r, self.base + self.h, np.nan)
        return z, self.cls, np.zeros((len(x), 3)) + self.col * (1 + self.rng.normal(0, 0.05, (len(x), 1)))

    def extra(self, sc):
        if not self.side:
            return None
        n = max(3, int(2 * np.pi * max(self.r, 0.1) * self.h * sc.density * ms_dscale() * 0.25))
        a = sc.rng.uniform(0, 2 * np.pi, n)
        rr = min(self.r, 0.12)
        h = sc.rng.uniform(0.05, self.h, n)
        return (self.cx + rr * np.cos(a), self.cy + rr * np.sin(a), self.base + h, self.cls,
                np.zeros((n, 3)) + self.col * 0.8)


class Fountain(Disc):
    pass


# ----------------------------------------------------------------------------- scenes
def markings_dashed(pl, lat0, w=0.15, dash=3.0, gap=6.0):
    def f(x, y):
        lat, s, out = pl.local(x, y)
        d = np.abs(lat - lat0) - w / 2
        on = (s % (dash + gap)) < dash
        return np.where(on & ~out, d, 1.0)
    return f


def markings_solid(pl, lat0, w=0.15, s0=-1e9, s1=1e9):
    def f(x, y):
        lat, s, out = pl.local(x, y)
        d = np.abs(lat - lat0) - w / 2
        return np.where((s > s0) & (s < s1) & ~out, d, 1.0)
    return f


def zebra(pl, s0, half, bar=0.5, gap=0.5, depth=3.0):
    def f(x, y):
        lat, s, out = pl.local(x, y)
        inside = (np.abs(lat) < half - 0.3) & (s > s0) & (s < s0 + depth) & ((lat + 50) % (bar + gap) < bar)
        return np.where(inside, -1.0, 1.0)
    return f


def manholes(sc, pts, r=0.32):
    fs = [sdf_circle(px, py, r) for px, py in pts]
    return sdf_union(*fs)


def patches(sc, rng, pl, half, n, size=(1.0, 4.0)):
    fs = []
    for _ in range(n):
        s = rng.uniform(5, pl.length - 5)
        i = min(int(s / 0.2), len(pl.x) - 1)
        lat = rng.uniform(-half + 1, half - 1)
        cx, cy = pl.x[i] - lat * pl.ty[i], pl.y[i] + lat * pl.tx[i]
        fs.append(sdf_box(cx, cy, rng.uniform(*size), rng.uniform(0.5, 1.5), np.arctan2(pl.ty[i], pl.tx[i])))
    return sdf_union(*fs)


def point_on(pl, s, lat):
    i = int(np.clip(s / 0.2, 0, len(pl.x) - 1))
    return pl.x[i] - lat * pl.ty[i], pl.y[i] + lat * pl.tx[i], np.arctan2(pl.ty[i], pl.tx[i])


WHITE = (0.88, 0.88, 0.86)
YELLOW = (0.85, 0.72, 0.2)


def scene_roundabout():
    sc = Scene("roundabout", 101, 110, 110, 90, 0.02, 0.018, "x257", 135, 40, 17, (412345.0, 5401234.0), 231.0)
    rng, M = sc.rng, sc.M
    C = (55.0, 55.0)
    tn = Noise(rng, 110, 110, 25)
    sc.terrain = lambda x, y: 0.004 * x + 0.15 * tn(x, y)
    asph = M.asphalt((0.36, 0.36, 0.37))
    side = M.concrete_slabs((0.62, 0.61, 0.58), a=1.5, ang=0.3)
    kerb = M.solid((0.72, 0.71, 0.68))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass(), dz=0.0)
    arms = [np.radians(a) for a in (10, 100, 190, 283)]
    pls = []
    for a in arms:
        pl = Polyline([C, (C[0] + 90 * np.cos(a), C[1] + 90 * np.sin(a))])
        pls.append(pl)
        sc.layer(pl.sdf_band(3.5 + 3.2), GROUND, side, dz=0.0, name="sidewalk (arm)")
    sc.layer(sdf_circle(*C, 20.0), GROUND, side, dz=0.0, name="sidewalk (ring)")
    road_dz = -0.13
    for pl in pls:
        sc.layer(pl.sdf_band(3.6), ROAD, asph, dz=road_dz, rim=kerb, rim_out=True, name="road arm")
    sc.layer(sdf_circle(*C, 17.0), ROAD, asph, dz=lambda x, y: road_dz + 0.02 * (np.hypot(x - C[0], y - C[1]) - 10) / 7,
             rim=kerb, rim_out=True, name="ring carriageway")
    # central island: grass, kerb, with an inner ring of cobbles (not drivable: raised 15 cm)
    sc.layer(sdf_circle(*C, 10.0), GROUND, M.cobbles((0.55, 0.5, 0.45)), dz=0.03, rim=kerb, name="island cobble ring")
    sc.layer(sdf_circle(*C, 8.5), GROUND, M.grass((0.28, 0.45, 0.16)), dz=0.2, name="island lawn")
    # splitter islands on each arm
    for pl in pls:
        def spl(x, y, pl=pl):
            lat, s, out = pl.local(x, y)
            wdt = np.clip((s - 18) / 10, 0, 1) * 1.2 + 0.2
            return np.where((s > 18) & (s < 32), np.abs(lat) - wdt, np.maximum(np.abs(lat) - 0.2, np.minimum(np.abs(s - 18), np.abs(s - 32))))
        sc.layer(spl, GROUND, M.pavers((0.6, 0.45, 0.4), ang=0.5), dz=0.0, rim=kerb, rim_w=0.12, name="splitter island")
        sc.layer(zebra(pl, 34, 3.6), ROAD, M.solid(WHITE), dz=None)
        sc.layer(lambda x, y, pl=pl: np.where(pl.local(x, y)[1] > 33, markings_dashed(pl, 0.0, dash=3, gap=3)(x, y), 1.0), ROAD, M.solid(WHITE))
        # give-way line at the ring
        def gw(x, y, pl=pl):
            lat, s, out = pl.local(x, y)
            return np.where((lat > 0.2) & (lat < 3.4) & (np.abs(s - 17.6) < 0.2) & ((s * 0 + lat) % 1.0 < 0.5), -1.0, 1.0)
        sc.layer(gw, ROAD, M.solid(WHITE))
    sc.layer(sdf_annulus(*C, 13.4, 13.55), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(C[0] + 13 * np.cos(a), C[1] + 13 * np.sin(a)) for a in (0.5, 2.0, 4.4)] +
                      [(C[0] + 45 * np.cos(arms[1]) + 1.5, C[1] + 45 * np.sin(arms[1]))]),
             ROAD, M.solid((0.22, 0.22, 0.23), 0.15))
    sc.layer(patches(sc, rng, pls[0], 3.6, 2, (1, 3)), ROAD, M.asphalt((0.25, 0.25, 0.26)))
    # island content
    sc.add(Tree(C[0] + 2, C[1] - 1, 4.0, 9.0))
    for a in np.linspace(0, 2 * np.pi, 9)[:-1]:
        sc.add(Tree(C[0] + 6.5 * np.cos(a), C[1] + 6.5 * np.sin(a), 0.8, 1.1, crown_base=0.3, col=(0.22, 0.36, 0.14), lump=0.1))
    # buildings in the quadrants between arms
    for k in range(4):
        amid = (arms[k] + ((arms[(k + 1) % 4] - arms[k]) % (2 * np.pi)) / 2)
        for j in range(3):
            rr = 34 + 14 * j + rng.uniform(-2, 2)
            aa = amid + rng.uniform(-0.25, 0.25)
            bx, by = C[0] + rr * np.cos(aa), C[1] + rr * np.sin(aa)
            if rng.uniform() < 0.5:
                sc.add(Building(bx, by, rng.uniform(10, 16), rng.uniform(8, 12), aa + np.pi / 2, rng.uniform(8, 16),
                                roof="flat", roof_col=(0.5, 0.5, 0.52), parapet=0.6, units=2))
            else:
                sc.add(Building(bx, by, rng.uniform(10, 14), rng.uniform(8, 10), aa + np.pi / 2, rng.uniform(6, 10),
                                roof="gable", rise=3.5, roof_col=(0.55, 0.26, 0.2)))
        for j in range(2):
            rr = 24 + rng.uniform(0, 4)
            aa = amid + rng.uniform(-0.12, 0.12)
            sc.add(Tree(C[0] + rr * np.cos(aa), C[1] + rr * np.sin(aa), rng.uniform(3, 5), rng.uniform(8, 12)))
    # cars on the ring and arms
    for a in rng.uniform(0, 2 * np.pi, 5):
        sc.add(Car(C[0] + 14.5 * np.cos(a), C[1] + 14.5 * np.sin(a), a + np.pi / 2))
    for pl in pls:
        for _ in range(2):
            s = rng.uniform(20, 50)
            lat = rng.choice([-1.8, 1.8])
            cx, cy, an = point_on(pl, s, lat)
            sc.add(Car(cx, cy, an))
        cx, cy, an = point_on(pl, 30, 5.5)
        sc.add(Disc(cx, cy, 0.15, 7.0))
        cx, cy, an = point_on(pl, 36, -6)
        sc.add(Disc(cx, cy, 0.28, 1.7, col=(0.3, 0.25, 0.5)))
    return sc


def scene_boulevard():
    sc = Scene("boulevard_median", 202, 150, 62, 110, 0.03, 0.02, "x256", 160, 30, -32, (446120.0, 5311870.0), 118.0)
    rng, M = sc.rng, sc.M
    cy = 31.0
    sc.terrain = lambda x, y: 0.002 * x
    pl = Polyline([(-5, cy), (155, cy)])
    asph = M.asphalt((0.30, 0.30, 0.31), wear=0.08)
    park = M.asphalt((0.34, 0.33, 0.32))
    kerb = M.solid((0.7, 0.7, 0.68))
    walk = M.pavers((0.55, 0.52, 0.50), a=0.2, b=0.1, var=0.3, herring=True, tint=(0.5, 0.35, 0.3))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, walk, dz=0.0)
    # side street crossing to the north at x=80
    ss = Polyline([(80, cy), (80, 70)])
    sc.layer(ss.sdf_band(4 + 3), GROUND, M.concrete_slabs((0.6, 0.59, 0.57), a=1.2), dz=0.0)
    sc.layer(pl.sdf_band(12.0), ROAD, park, dz=-0.12, rim=kerb, rim_out=True, name="parking lanes")
    sc.layer(ss.sdf_band(4.0), ROAD, asph, dz=-0.12, rim=kerb, rim_out=True, name="side street")
    sc.layer(sdf_union(sdf_box(75, cy + 10.75, 60, 1.25), sdf_box(75, cy - 10.75, 60, 1.25)), ROAD, park)
    lanes = lambda x, y: np.abs(pl.local(x, y)[0]) - 9.5
    sc.layer(lanes, ROAD, asph, name="main lanes", dz=lambda x, y: -0.12 + 0.02 * (9.5 - np.abs(pl.local(x, y)[0])) / 7 * 0.5)
    # parking bay ticks
    def bays(x, y):
        lat, s, out = pl.local(x, y)
        return np.where((np.abs(lat) > 9.6) & (np.abs(lat) < 11.9) & ((s % 5.5) < 0.12), -1.0, 1.0)
    sc.layer(bays, ROAD, M.solid(WHITE))
    for l0 in (-6.0, 6.0):
        sc.layer(markings_dashed(pl, l0, dash=3, gap=6), ROAD, M.solid(WHITE))
    for l0 in (-9.4, 9.4, -2.7, 2.7):
        sc.layer(markings_solid(pl, l0), ROAD, M.solid(WHITE))
    # median, planted, with gap at the side street
    med = sdf_sub(pl.sdf_band(2.5), sdf_box(80, cy, 6, 5))
    sc.layer(med, GROUND, M.grass((0.26, 0.40, 0.15)), dz=0.05, rim=kerb, name="median lawn")
    sc.layer(zebra(pl, 68, 9.5, depth=4), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(20, cy + 4.5), (55, cy - 7.5), (110, cy + 7.0), (80, 50)]), ROAD, M.solid((0.2, 0.2, 0.21), 0.2))
    sc.layer(patches(sc, rng, pl, 9, 4, (1.5, 5)), ROAD, M.asphalt((0.22, 0.22, 0.23)))
    # trees on the median and sidewalks
    for x in np.arange(6, 150, 9.0):
        if abs(x - 80) > 7:
            sc.add(Tree(x + rng.uniform(-1, 1), cy + rng.uniform(-0.4, 0.4), rng.uniform(3.5, 5.0), rng.uniform(9, 13), col=(0.19, 0.31, 0.12)))
    for x in np.arange(10, 150, 14.0):
        for sgn in (-1, 1):
            if abs(x - 80) > 8 and rng.uniform() < 0.7:
                sc.add(Tree(x + rng.uniform(-1, 1), cy + sgn * 13.6, rng.uniform(2.5, 4.0), rng.uniform(7, 10), col=(0.23, 0.34, 0.13)))
    # tall buildings on both sides
    for sgn in (-1, 1):
        x = -2.0
        while x < 152:
            L = rng.uniform(14, 30)
            if sgn > 0 and x < 88 and x + L > 72:
                x = 88.0
                continue
            d = rng.uniform(12, 16)
            h = rng.uniform(12, 21)
            roof = "flat" if rng.uniform() < 0.7 else "gable"
            sc.add(Building(x + L / 2, cy + sgn * (17.2 + d / 2), L - 0.3, d, 0, h, roof=roof, rise=4,
                            roof_col=(0.45, 0.45, 0.47) if roof == "flat" else (0.5, 0.3, 0.25), parapet=0.8,
                            units=int(rng.integers(0, 4)), wall_col=tuple(rng.uniform(0.6, 0.9, 3)), ridge_along=False))
            x += L
    # parked cars in the parking lanes, moving cars in lanes
    for sgn in (-1, 1):
        for s in np.arange(3, 148, 5.5):
            if rng.uniform() < 0.65 and abs(s - 80) > 6:
                cx, cy2, an = point_on(pl, s + 2.75, sgn * 10.75)
                sc.add(Car(cx, cy2, an, L=rng.uniform(4.0, 4.8)))
        for _ in range(6):
            cx, cy2, an = point_on(pl, rng.uniform(5, 145), sgn * rng.choice([4.25, 7.75]))
            sc.add(Car(cx, cy2, an, van=rng.uniform() < 0.2, h=rng.uniform(1.45, 2.2)))
    for _ in range(12):
        sc.add(Disc(rng.uniform(0, 150), cy + rng.choice([-1, 1]) * rng.uniform(13, 16.5), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.7, 3))))
    for x in np.arange(4, 150, 25.0):
        sc.add(Disc(x, cy + 12.5, 0.12, 8.0))
        sc.add(Disc(x + 12, cy - 12.5, 0.12, 8.0))
    return sc


def scene_rural(variant="nokerb"):
    if variant == "dense":
        sc = Scene("rural_nokerb_dense120", 313, 120, 100, 120, 0.05, 0.025, "full16", 200, 50, 0, (512870.0, 5234560.0), 412.0)
    else:
        sc = Scene("rural_curved_" + variant, 303, 220, 160, 30, 0.05, 0.025, "full16", 200, 50, 0, (512870.0, 5234560.0), 412.0)
    rng, M = sc.rng, sc.M
    tn = Noise(rng, 220, 160, 45)
    tn2 = Noise(rng, 220, 160, 15)
    pts = bezier((-10, 20), (80, 10), (120, 160), (235, 140))
    pl = Polyline(pts)
    base = lambda x, y: 0.02 * x + 1.2 * tn(x, y) + 0.15 * tn2(x, y)
    # road follows the smooth terrain along its centre line (cut/fill), verge blends in
    def terrain(x, y):
        lat, s, out = pl.local(x, y)
        i = np.clip((s / 0.2).astype(int), 0, len(pl.x) - 1)
        zc = 0.02 * pl.x[i] + 1.2 * tn(pl.x[i], pl.y[i])
        w = smooth01((np.abs(lat) - 5.0) / 6.0)
        return zc * (1 - w) + base(x, y) * w
    sc.terrain = terrain
    fieldA = M.field(ang=0.5)
    fieldB = M.field(base=(0.55, 0.50, 0.30), soil=(0.50, 0.42, 0.30), period=0.4, ang=1.2)
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, fieldA, dz=0.0)
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] < 0, -1.0, 1.0) * np.where(x > 100, 1, -1), GROUND, fieldB)
    # verge (grass) and ditch
    def ditch_dz(x, y):
        a = np.abs(pl.local(x, y)[0])
        return -0.45 * np.clip(1 - np.abs(a - 7.2) / 1.2, 0, 1)
    sc.layer(pl.sdf_band(8.5), GROUND, M.grass((0.34, 0.44, 0.2), dry=0.2), dz=ditch_dz, eps=0.5, name="grass verge+ditch")
    rd = M.asphalt((0.33, 0.33, 0.33), wear=0.1)
    if variant == "kerb12":   # control: the same road 12 cm below a kerb (verge level)
        sc.layer(pl.sdf_band(3.0), ROAD, rd, name="rural road", dz=lambda x, y: -0.12 + 0.02 * (3 - np.abs(pl.local(x, y)[0])) / 3,
                 rim=M.solid((0.7, 0.7, 0.68)), rim_out=True)
    else:
        sc.layer(pl.sdf_band(3.0), ROAD, rd, name="rural road", dz=lambda x, y: 0.03 + 0.02 * (3 - np.abs(pl.local(x, y)[0])) / 3, eps=0.3)
    # ragged worn edge: a few grass tufts into the asphalt edge
    en = Noise(rng, 220, 160, 0.7)
    sc.layer(lambda x, y: np.where((np.abs(pl.local(x, y)[0]) > 2.85) & (en(x, y) > 0.9), -1.0, 1.0), GROUND, M.grass((0.36, 0.44, 0.22), dry=0.4))
    sc.layer(markings_dashed(pl, 0.0, w=0.12, dash=3, gap=9), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(pl, 2.7, w=0.12), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(pl, -2.7, w=0.12), ROAD, M.solid(WHITE))
    sc.layer(patches(sc, rng, pl, 3, 5, (1, 6)), ROAD, M.asphalt((0.24, 0.24, 0.25)))
    # farmstead: yard of gravel (not road) next to buildings, away from the road
    sc.layer(sdf_box(160, 60, 25, 18, 0.2), GROUND, M.gravel(), dz=0.0, name="farm gravel yard")
    sc.add(Building(150, 58, 30, 14, 0.2, 5.0, roof="gable", rise=4.0, roof_col=(0.55, 0.57, 0.58), ridge_along=True))
    sc.add(Building(172, 68, 14, 10, 0.2, 6.0, roof="gable", rise=4.5, roof_col=(0.62, 0.3, 0.22)))
    sc.add(Building(168, 44, 10, 8, 1.0, 3.0, roof="shed", rise=1.0, roof_col=(0.4, 0.38, 0.36)))
    # tree rows and a copse, crowns over the road
    for s in np.arange(10, pl.length - 10, 11.0):
        if rng.uniform() < 0.75:
            lat = rng.choice([-1, 1]) * rng.uniform(4.5, 6.5)
            cx, cy, _ = point_on(pl, s, lat)
            sc.add(Tree(cx, cy, rng.uniform(3.5, 6.0), rng.uniform(9, 15)))
    for _ in range(25):
        sc.add(Tree(rng.uniform(20, 70), rng.uniform(100, 150), rng.uniform(3, 6), rng.uniform(8, 18), col=(0.17, 0.28, 0.11)))
    for _ in range(15):
        sc.add(Tree(rng.uniform(110, 210), rng.uniform(90, 110), rng.uniform(0.8, 1.8), 2.0, crown_base=0.3, col=(0.25, 0.35, 0.15), lump=0.2))
    for s, lat in ((40, -1.5), (150, 1.5), (220, -1.5)):
        cx, cy, an = point_on(pl, s, lat)
        sc.add(Car(cx, cy, an))
    for s in np.arange(15, pl.length, 50):
        cx, cy, _ = point_on(pl, s, 3.9)
        sc.add(Disc(cx, cy, 0.08, 1.1, col=(0.85, 0.85, 0.85)))
    return sc


def scene_oldtown(gardens=False):
    sc = Scene("oldtown_alley" + ("_gardens" if gardens else ""), 404, 72, 46, 340, 0.015, 0.02, "x257", 250, 38, 73, (357410.0, 5644020.0), 54.0)
    rng, M = sc.rng, sc.M
    pts = [(-5, 20), (20, 21.5), (38, 19), (56, 22), (77, 24)]
    pl = Polyline(pts)
    sc.terrain = lambda x, y: 0.012 * x + 0.01 * np.sin(x / 7)
    setts = M.cobbles((0.50, 0.47, 0.43), a=0.11)
    gutter = M.concrete_slabs((0.40, 0.40, 0.41), a=0.5, b=0.3)
    slabs = M.concrete_slabs((0.72, 0.68, 0.60), a=0.6, b=0.6, ang=0.1, joint=0.008, jdark=0.8)
    if gardens:   # control: courtyards / back areas are gardens; only the piazza is flush stone paving
        sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.30, 0.42, 0.18)), dz=0.08, name="back gardens")
        sc.layer(sdf_box(58, 11, 9.5, 9.5), GROUND, slabs, dz=0.0, name="stone slab piazza")
    else:
        sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, slabs, dz=0.0, name="stone slabs (piazza/courtyards)")
    # a side lane to the north at x~38
    sl = Polyline([(38, 19), (41, 50)])
    sc.layer(sl.sdf_band(1.7), ROAD, setts, name="side lane", dz=lambda x, y: -0.02 - 0.015 * (1.7 - np.abs(sl.local(x, y)[0])) / 1.7)
    # alley: 4.4 m, V-profile towards a central gutter (no kerb, no sidewalk)
    sc.layer(pl.sdf_band(2.2), ROAD, setts, name="alley setts", dz=lambda x, y: -0.02 - 0.03 * (2.2 - np.abs(pl.local(x, y)[0])) / 2.2)
    sc.layer(pl.sdf_band(0.2), ROAD, gutter, name="alley gutter")
    sc.layer(manholes(sc, [(15, 21.2), (47, 20.7)], r=0.3), ROAD, M.solid((0.25, 0.24, 0.24), 0.2))
    # the small piazza (pedestrian, flush stone slabs) south of the alley at x 50-66: class 2
    # (already the base layer); separate it with bollards
    # buildings: continuous rows both sides, gaps for side lane and piazza
    def row(side, x0, x1, skip):
        x = x0
        while x < x1:
            L = rng.uniform(6, 11)
            if any(a < x + L and x < b for a, b in skip):
                x = min(b for a, b in skip if a < x + L and x < b) + 0.01
                continue
            cxs = x + L / 2
            _, s, _ = pl.local(np.array([cxs]), np.array([20.0]))
            lat_edge = 2.3
            px, py, an = point_on(pl, float(s[0]), side * (lat_edge + 5))
            d = rng.uniform(8, 11)
            px, py, an = point_on(pl, float(s[0]), side * (lat_edge + d / 2 - 0.5))   # eaves overhang 0.5 m
            h = rng.uniform(7, 14)
            sc.add(Building(px, py, L - 0.15, d, an, h, roof="gable", rise=rng.uniform(3, 5),
                            roof_col=tuple(np.array([0.55, 0.28, 0.2]) * rng.uniform(0.75, 1.15)),
                            wall_col=tuple(rng.uniform(0.65, 0.92, 3)), ridge_along=True, wall_frac=0.1))
            x += L
    row(+1, -4, 76, [(36, 43.5)])
    row(-1, -4, 76, [(49, 67)])
    # buildings around the piazza
    sc.add(Building(58, 3.5, 16, 7, 0.0, 11, roof="gable", rise=4, ridge_along=True, roof_col=(0.5, 0.3, 0.22)))
    sc.add(Building(46, 7, 5, 10, 0.0, 9, roof="gable", rise=3, ridge_along=False, roof_col=(0.6, 0.32, 0.2)))
    sc.add(Building(70, 8, 6, 12, 0.0, 10, roof="gable", rise=3.5, ridge_along=False, roof_col=(0.45, 0.26, 0.2)))
    # piazza: fountain, umbrellas, people, a tree; bollards along the alley edge
    sc.add(Disc(58, 12.5, 1.6, 0.7, col=(0.6, 0.6, 0.62)))
    sc.add(Tree(63, 14, 3.2, 8.0))
    for _ in range(6):
        sc.add(Disc(rng.uniform(51, 56), rng.uniform(9, 16), 1.3, 2.3, col=tuple(rng.uniform(0.5, 0.95, 3)), side=False))
    for _ in range(10):
        sc.add(Disc(rng.uniform(50, 66), rng.uniform(8, 18), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    for x in np.arange(50.5, 66, 1.8):
        _, s, _ = pl.local(np.array([x]), np.array([20.0]))
        bx, by, _ = point_on(pl, float(s[0]), -2.5)
        sc.add(Disc(bx, by, 0.12, 0.9, col=(0.25, 0.25, 0.27)))
    # a parked small car, a delivery van, people in the alley
    for s, lat, van in ((12, 1.1, False), (30, -1.0, True)):
        cx, cy, an = point_on(pl, s, lat)
        sc.add(Car(cx, cy, an, L=3.8 if not van else 5.2, Wd=1.7 if not van else 2.0, h=1.5 if not van else 2.3, van=van))
    for _ in range(6):
        cx, cy, _ = point_on(pl, rng.uniform(2, 70), rng.uniform(-1.8, 1.8))
        sc.add(Disc(cx, cy, 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


def scene_parking():
    sc = Scene("parking_lot_plaza", 505, 130, 100, 80, 0.025, 0.02, "x256", 120, 55, 8, (603215.0, 4923880.0), 301.0)
    rng, M = sc.rng, sc.M
    sc.terrain = lambda x, y: -0.003 * y
    conc = M.concrete_slabs((0.66, 0.65, 0.62), a=5.0, b=4.5, joint=0.015, jdark=0.55)   # light concrete road
    lot = M.asphalt((0.27, 0.27, 0.28), wear=0.05)
    walk = M.concrete_slabs((0.70, 0.69, 0.66), a=1.5)
    pav = M.pavers((0.58, 0.50, 0.44), a=0.25, b=0.125, var=0.3)
    kerb = M.solid((0.78, 0.78, 0.76))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass(), dz=0.05)
    road = Polyline([(-5, 15), (135, 15)])
    sc.layer(sdf_box(65, 11, 70, 8), GROUND, walk, dz=0.0, name="sidewalk S")   # sidewalks on both sides y 3..19 (road overrides)
    sc.layer(sdf_box(65, 21.5, 70, 1.5), GROUND, walk, dz=0.0, name="sidewalk N")
    sc.layer(road.sdf_band(5.0), ROAD, conc, dz=lambda x, y: -0.12 + 0.025 * (5 - np.abs(road.local(x, y)[0])) / 5 * 2, rim=kerb, rim_out=True, name="concrete road")
    # lot: x 12..112, y 23..70, flush driveways through the sidewalk at x 25-33 and x 90-98
    lot_sdf = sdf_box(62, 46.5, 50, 23.5)
    drives = sdf_union(sdf_box(29, 21.5, 4, 2.6), sdf_box(94, 21.5, 4, 2.6))
    sc.layer(sdf_union(lot_sdf, drives), ROAD, lot, dz=-0.1, rim=kerb, rim_out=True, name="parking lot")
    # bay markings: rows along x, stalls 2.5 m
    def stalls(x, y):
        on = np.zeros(len(x), bool)
        for yr in (27.5, 38.5, 47.5, 58.5):
            on |= (np.abs(y - yr) < 2.5) & ((x - 14) % 2.5 < 0.12) & (x > 14) & (x < 110)
        for yl in (25.0, 41.0, 45.0, 61.0):
            on |= (np.abs(y - yl) < 0.06) & (x > 14) & (x < 110)
        return np.where(on, -1.0, 1.0)
    sc.layer(stalls, ROAD, M.solid(WHITE))
    # landscaped islands with trees, kerbed
    for yi in (43.0,):
        sc.layer(sdf_box(62, yi, 45, 1.0), GROUND, M.grass((0.3, 0.44, 0.18)), dz=0.05, rim=kerb, rim_w=0.15, name="lot lawn island")
    # front of the supermarket: pedestrian paver plaza (not road), kerb 12 cm
    sc.layer(sdf_box(62, 74, 50, 4.0), GROUND, pav, dz=0.02, rim=kerb, rim_w=0.15, name="paver plaza (pedestrian)")
    sc.layer(markings_dashed(road, 0, dash=3, gap=6), ROAD, M.solid(WHITE))
    sc.layer(zebra(road, 60, 5, depth=4), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(20, 13), (70, 17), (50, 33), (80, 52)]), ROAD, M.solid((0.3, 0.3, 0.3), 0.2))
    sc.layer(patches(sc, rng, road, 5, 3, (1, 3)), ROAD, M.asphalt((0.3, 0.3, 0.31)))
    sc.add(Building(62, 89, 90, 20, 0.0, 7.0, roof="flat", roof_col=(0.75, 0.75, 0.73), parapet=0.5, units=8))
    sc.add(Building(122, 60, 14, 30, 0.0, 9.0, roof="gable", rise=3, roof_col=(0.4, 0.42, 0.45), ridge_along=False))
    for x in np.arange(22, 110, 12):
        sc.add(Tree(x, 43 + rng.uniform(-0.3, 0.3), rng.uniform(2.5, 4), rng.uniform(6, 9)))
    for x in np.arange(5, 130, 15):
        sc.add(Tree(x, 4.5 + rng.uniform(-0.5, 0.5), rng.uniform(3, 4.5), rng.uniform(8, 11)))
    # parked cars in the stalls
    for yr in (27.5, 38.5, 47.5, 58.5):
        for x in np.arange(14, 110, 2.5):
            if rng.uniform() < 0.55:
                sc.add(Car(x + 1.25 + rng.uniform(-0.15, 0.15), yr + rng.uniform(-0.2, 0.2), np.pi / 2 + rng.uniform(-0.05, 0.05),
                           van=rng.uniform() < 0.1, h=rng.uniform(1.4, 1.9)))
    for _ in range(4):
        sc.add(Car(rng.uniform(10, 120), 15 + rng.choice([-2.5, 2.5]), 0.0))
    for _ in range(3):
        sc.add(Car(rng.uniform(20, 100), 33, 0.0))
    for _ in range(15):
        sc.add(Disc(rng.uniform(15, 110), rng.uniform(71, 78), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    for x in np.arange(10, 130, 30):
        sc.add(Disc(x, 20.5, 0.15, 8))
    return sc


def scene_slope():
    sc = Scene("slope_street_7pct", 606, 120, 52, 200, 0.02, 0.018, "full16", 300, 45, 60, (488930.0, 5530450.0), 505.0)
    rng, M = sc.rng, sc.M
    cy = 26.0
    pl = Polyline([(-5, cy), (125, cy)])
    # 7 % grade along the street, gardens rising 10 % away from the street on the north side
    sc.terrain = lambda x, y: 0.07 * x + np.where(y > cy + 7.5, 0.10 * (y - cy - 7.5), np.where(y < cy - 7.5, 0.03 * (y - cy + 7.5), 0))
    asph = M.asphalt((0.25, 0.25, 0.26))
    walk = M.concrete_slabs((0.64, 0.63, 0.6), a=1.0)
    kerb = M.solid((0.7, 0.7, 0.7))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.3, 0.43, 0.18)), dz=0.0)
    sc.layer(pl.sdf_band(3.25 + 2.2), GROUND, walk, dz=0.0, name="sidewalk")
    # driveways (concrete, class 2) from sidewalk into gardens
    for x in np.arange(8, 120, 17):
        for sgn in (-1, 1):
            sc.layer(sdf_box(x, cy + sgn * 8.5, 1.6, 3.1), GROUND, M.concrete_slabs((0.58, 0.57, 0.55), a=2.5), dz=None, name="driveway")
    sc.layer(pl.sdf_band(3.25), ROAD, asph, dz=lambda x, y: -0.15 + 0.025 * (3.25 - np.abs(pl.local(x, y)[0])) / 3.25 * 3,
             rim=kerb, rim_out=True, name="sloped road")
    sc.layer(markings_dashed(pl, 0.0, dash=2, gap=4), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(15, cy + 0.8), (60, cy - 1.0), (100, cy + 1.2)]), ROAD, M.solid((0.18, 0.18, 0.19), 0.2))
    sc.layer(patches(sc, rng, pl, 3.25, 3, (1, 3)), ROAD, M.asphalt((0.33, 0.33, 0.33)))
    # houses, pitched roofs, stepping with the slope
    for sgn in (-1, 1):
        for x in np.arange(0, 120, 17):
            bx = x + 8.5 + rng.uniform(-1, 1)
            L, D = rng.uniform(9, 12), rng.uniform(8, 10)
            by = cy + sgn * (11 + D / 2 + rng.uniform(0, 1.5))
            sc.add(Building(bx, by, L, D, rng.uniform(-0.05, 0.05), rng.uniform(5.5, 7.5), roof="gable", rise=rng.uniform(2.5, 4.0),
                            roof_col=tuple(np.array(rng.choice([[0.55, 0.27, 0.2], [0.3, 0.3, 0.33], [0.45, 0.35, 0.3]])) * rng.uniform(0.85, 1.1)),
                            ridge_along=rng.uniform() < 0.6))
            # hedge along the garden front and a garden tree overhanging the street
            hx = x + rng.uniform(2, 6)
            for k in range(3):
                sc.add(Tree(hx + k * 1.1, cy + sgn * 5.9, 0.7, 1.2, crown_base=0.2, col=(0.2, 0.33, 0.12), lump=0.08))
            if rng.uniform() < 0.6:
                sc.add(Tree(x + 14 + rng.uniform(-1, 1), cy + sgn * 7.5, rng.uniform(3.5, 5.5), rng.uniform(7, 11)))
    for x in np.arange(5, 118, 6.0):
        if rng.uniform() < 0.5:
            cx, cyy, an = point_on(pl, x + 5, -2.1)
            sc.add(Car(cx, cyy, an))
    cx, cyy, an = point_on(pl, 70, 1.6)
    sc.add(Car(cx, cyy, an + np.pi))
    for x in np.arange(10, 120, 30):
        sc.add(Disc(x, cy + 3.8, 0.12, 6.5))
    for _ in range(6):
        sc.add(Disc(rng.uniform(0, 120), cy + rng.choice([-1, 1]) * rng.uniform(4, 5.2), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


def scene_crossfall():
    sc = Scene("crossfall_curve_red", 707, 140, 88, 100, 0.04, 0.025, "x257", 30, 42, -75, (372210.0, 5812140.0), 88.0)
    rng, M = sc.rng, sc.M
    # arc of radius 70 centred north of the scene
    C = (70.0, 100.0)
    pts = arc_pts(C[0], C[1], 70, np.radians(180), np.radians(360))
    pl = Polyline(pts)
    sc.terrain = lambda x, y: 0.03 * x
    red = M.asphalt((0.46, 0.33, 0.30), wear=0.07)
    walk_in = M.pavers((0.52, 0.52, 0.54), a=0.3, b=0.15, var=0.2)
    walk_out = M.concrete_slabs((0.63, 0.62, 0.6), a=1.2)
    kerb = M.solid((0.7, 0.68, 0.66))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.32, 0.44, 0.2), dry=0.1), dz=0.0)
    # lat > 0: left of travel direction (towards the centre C: inside of the curve)
    def half_out(s):
        return 4.0 + 3.0 * smooth01(1 - np.abs(s - 75) / 18)      # bus bay on the outside
    def road_sdf(x, y):
        lat, s, out = pl.local(x, y)
        d = np.where(lat >= 0, lat - 4.0, -lat - half_out(s))
        return np.where(out, 1.0, d)
    # one-sided cross-fall 4 % falling to the inside (lat +4 lowest): inside kerb 2 cm, outside kerb 10 cm
    def road_dz(x, y):
        lat = pl.local(x, y)[0]
        return -0.02 - 0.04 * (lat - 4.0)
    def out_walk_dz(x, y):
        lat, s, _ = pl.local(x, y)
        ho = half_out(s)
        return -0.02 + 0.04 * (ho + 4.0) + 0.10 + 0.02 * (-lat - ho)
    def out_walk_sdf(x, y):
        lat, s, out = pl.local(x, y)
        return np.where(lat < 0, -lat - (half_out(s) + 4.0), 1.0)
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] > 0, np.abs(pl.local(x, y)[0]) - 7.5, 1.0), GROUND, walk_in, dz=0.0, name="inner paver walk (2 cm kerb)")
    sc.layer(out_walk_sdf, GROUND, walk_out, dz=out_walk_dz, eps=0.3, name="outer concrete walk (10 cm kerb)")
    sc.layer(road_sdf, ROAD, red, dz=road_dz, rim=kerb, rim_out=True, name="red crossfall road")
    sc.layer(markings_dashed(pl, 0.0, dash=4, gap=8), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(pl, 3.8), ROAD, M.solid(WHITE))
    def busmark(x, y):
        lat, s, out = pl.local(x, y)
        return np.where((lat < -4.0) & (lat > -6.9) & (np.abs(s - 75) < 10) & (((s + lat) % 2.0) < 0.2), -1.0, 1.0)
    sc.layer(busmark, ROAD, M.solid(YELLOW))
    sc.layer(patches(sc, rng, pl, 4, 5, (1, 4)), ROAD, M.asphalt((0.30, 0.29, 0.30)))
    mh = [point_on(pl, s, l)[:2] for s, l in ((20, 1.5), (60, -2), (110, 2))]
    sc.layer(manholes(sc, mh), ROAD, M.solid((0.2, 0.2, 0.2), 0.2))
    # buildings outside the curve (south), lawn with trees inside
    for s in np.arange(5, pl.length, 16):
        if abs(s - 75) < 14:
            continue
        d = rng.uniform(10, 14)
        px, py, an = point_on(pl, s, -(8.5 + d / 2))
        sc.add(Building(px, py, rng.uniform(11, 15), d, an, rng.uniform(6, 18),
                        roof=rng.choice(["flat", "gable"]), rise=3.5, roof_col=tuple(rng.uniform(0.3, 0.6, 3)), parapet=0.5, units=2))
    for s in np.arange(8, pl.length, 12):
        if rng.uniform() < 0.7:
            px, py, _ = point_on(pl, s, rng.uniform(9, 11))
            sc.add(Tree(px, py, rng.uniform(3.5, 5.5), rng.uniform(9, 14)))
    for _ in range(20):
        sc.add(Tree(rng.uniform(20, 120), rng.uniform(70, 88), rng.uniform(1, 4), rng.uniform(2, 10)))
    # bus shelter, bus in the bay, cars
    px, py, an = point_on(pl, 75, -8.5)
    sc.add(Building(px, py, 6, 1.8, an, 2.6, roof="flat", roof_col=(0.5, 0.6, 0.65)))
    px, py, an = point_on(pl, 77, -5.5)
    sc.add(Car(px, py, an, L=12, Wd=2.5, h=3.1, van=True, col=(0.85, 0.8, 0.2)))
    for _ in range(6):
        px, py, an = point_on(pl, rng.uniform(5, pl.length - 5), rng.choice([-2.0, 2.0]))
        sc.add(Car(px, py, an))
    for s in np.arange(10, pl.length, 28):
        px, py, _ = point_on(pl, s, -7.2)
        sc.add(Disc(px, py, 0.12, 8))
    for _ in range(8):
        px, py, _ = point_on(pl, rng.uniform(0, pl.length), rng.choice([-6.5, 5.5]) + rng.uniform(-1, 1))
        sc.add(Disc(px, py, 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


def scene_avenue():
    sc = Scene("tree_avenue_T", 808, 100, 100, 45, 0.03, 0.022, "x256", 110, 28, 38, (455870.0, 5109920.0), 340.0,
               shadow=(0.38, 0.43, 0.56))
    rng, M = sc.rng, sc.M
    tn = Noise(rng, 100, 100, 30)
    sc.terrain = lambda x, y: 0.2 * tn(x, y) - 0.01 * y
    main = Polyline([(-5, 35), (105, 35)])
    side = Polyline([(52, 35), (52, 105)])
    asph = M.asphalt((0.38, 0.38, 0.38), wear=0.07)
    walk = M.asphalt((0.44, 0.43, 0.42), wear=0.05)    # asphalt footpath behind a verge
    kerb = M.solid((0.68, 0.68, 0.66))
    verge = M.grass((0.32, 0.43, 0.19), dry=0.15)
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.28, 0.42, 0.17)), dz=0.1)
    # main: road 8 m, kerb 8 cm, verge 3 m, footpath 2 m
    sc.layer(main.sdf_band(4 + 3 + 2), GROUND, walk, dz=0.03, name="asphalt footpath")
    sc.layer(side.sdf_band(3 + 2), GROUND, M.concrete_slabs((0.6, 0.6, 0.58), a=1.5), dz=0.0, name="side sidewalk")
    sc.layer(sdf_sub(main.sdf_band(4 + 3), sdf_box(52, 40, 5.01, 5)), GROUND, verge, dz=0.05, name="grass verge")
    sc.layer(main.sdf_band(4.0), ROAD, asph, dz=lambda x, y: -0.08 + 0.02 * (4 - np.abs(main.local(x, y)[0])) / 4 * 2, rim=kerb, rim_out=True, name="main road")
    sc.layer(side.sdf_band(3.0), ROAD, asph, dz=-0.1, rim=kerb, rim_out=True, name="side road")
    sc.layer(markings_dashed(main, 0, dash=3, gap=6), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(side, 0, s0=2, s1=60), ROAD, M.solid(YELLOW))
    sc.layer(manholes(sc, [(30, 36), (52, 60), (80, 34)]), ROAD, M.solid((0.22, 0.22, 0.22), 0.2))
    # big trees in the verges, crowns over the road
    for sgn in (-1, 1):
        for x in np.arange(3 + (sgn > 0) * 6, 100, 12.0):
            if abs(x - 52) < 6 and sgn > 0:
                continue
            sc.add(Tree(x + rng.uniform(-1, 1), 35 + sgn * 6.0, rng.uniform(4, 6), rng.uniform(14, 20), col=(0.18, 0.29, 0.11)))
    for y in np.arange(50, 100, 12.0):
        sc.add(Tree(52 + rng.choice([-1, 1]) * 5.8, y, rng.uniform(3, 4.5), rng.uniform(8, 12)))
    # houses
    for x in np.arange(5, 100, 16):
        sc.add(Building(x + rng.uniform(-2, 2), 12 + rng.uniform(-2, 2), rng.uniform(9, 12), rng.uniform(8, 10), rng.uniform(-0.1, 0.1),
                        rng.uniform(5, 7), roof="gable", rise=3.5, roof_col=tuple(rng.uniform(0.3, 0.6, 3)), ridge_along=rng.uniform() < 0.5))
        if abs(x + 8 - 52) > 12:
            sc.add(Building(x + 8 + rng.uniform(-1, 1), 60 + rng.uniform(0, 20), rng.uniform(9, 12), rng.uniform(8, 10), 0.0,
                            rng.uniform(5, 8), roof=rng.choice(["gable", "flat"]), rise=3, roof_col=tuple(rng.uniform(0.3, 0.6, 3))))
    for _ in range(5):
        px, py, an = point_on(main, rng.uniform(5, 105), rng.choice([-2, 2]))
        sc.add(Car(px, py, an))
    for _ in range(3):
        px, py, an = point_on(side, rng.uniform(10, 65), 1.8)
        sc.add(Car(px, py, an))
    for _ in range(6):
        px, py, _ = point_on(main, rng.uniform(0, 110), rng.choice([-8, 8]))
        sc.add(Disc(px, py, 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


SCENES = {f().name if False else k: f for k, f in {
    "roundabout": scene_roundabout,
    "boulevard_median": scene_boulevard,
    "rural_curved_nokerb": scene_rural,
    "rural_curved_kerb12": lambda: scene_rural("kerb12"),
    "rural_nokerb_dense120": lambda: scene_rural("dense"),
    "oldtown_alley": scene_oldtown,
    "oldtown_alley_gardens": lambda: scene_oldtown(True),
    "parking_lot_plaza": scene_parking,
    "slope_street_7pct": scene_slope,
    "crossfall_curve_red": scene_crossfall,
    "tree_avenue_T": scene_avenue,
}.items()}


# ============================================================================= scenes2 additions
# Eight more scenes (written for /tmp/indep2, not derived from roadx_ti.synthetic): parked cars
# hiding kerbs, urban canyon in deep shadow, dark sidewalks + raised cycle track, sparse noisy
# survey, photogrammetric artefacts, wide multi-lane junction, speed bumps / raised table /
# lowered kerbs, hillside road with retaining wall.  Scene2 adds an optional post-processing hook
# (artefacts applied to the finished cloud); the original Scene class is unchanged.
class Scene2(Scene):
    post = None

    def generate(self):
        super().generate()
        if self.post is not None:
            self.post(self)
        return self

    def subset(self, keep):
        for a in ("x", "y", "z", "cls", "rgb", "sh", "part", "kerbb"):
            setattr(self, a, getattr(self, a)[keep])

    def append(self, idx, dx=0.0, dy=0.0, dz=0.0, kc=1.0):
        self.x = np.concatenate([self.x, self.x[idx] + dx])
        self.y = np.concatenate([self.y, self.y[idx] + dy])
        self.z = np.concatenate([self.z, self.z[idx] + dz + self.rng.normal(0, self.hnoise, len(idx))])
        self.cls = np.concatenate([self.cls, self.cls[idx]])
        self.rgb = np.concatenate([self.rgb, np.clip(self.rgb[idx] * kc + self.rng.normal(0, self.cnoise, (len(idx), 3)), 0, 1)])
        self.sh = np.concatenate([self.sh, self.sh[idx]])
        self.part = np.concatenate([self.part, self.part[idx]])
        self.kerbb = np.concatenate([self.kerbb, self.kerbb[idx]])


class Wall:
    """Vertical face (retaining wall) along a polyline between z_lo(x, y) and z_hi(x, y): side points only."""

    def __init__(self, pts, zlo, zhi, cls=OTHER, col=(0.62, 0.6, 0.56), frac=0.3):
        self.pts, self.zlo, self.zhi, self.cls, self.col, self.frac = np.asarray(pts, float), zlo, zhi, cls, np.asarray(col), frac
        self.bbox = (-1e6, -1e6 + 1, -1e6, -1e6 + 1)      # no top surface

    def prepare(self, sc):
        pass

    def top(self, x, y):
        return np.full(len(x), np.nan), self.cls, np.zeros((len(x), 3))

    def extra(self, sc):
        rng = sc.rng
        seg = np.diff(self.pts, axis=0)
        L = np.hypot(seg[:, 0], seg[:, 1])
        cum = np.concatenate([[0], np.cumsum(L)])
        hmean = float(np.mean(self.zhi(self.pts[:, 0], self.pts[:, 1]) - self.zlo(self.pts[:, 0], self.pts[:, 1])))
        n = int(cum[-1] * hmean * sc.density * DSCALE * self.frac)
        t = rng.uniform(0, cum[-1], n)
        x = np.interp(t, cum, self.pts[:, 0]) + rng.normal(0, 0.02, n)
        y = np.interp(t, cum, self.pts[:, 1]) + rng.normal(0, 0.02, n)
        lo, hi = self.zlo(x, y), self.zhi(x, y)
        z = lo + rng.uniform(0, 1, n) * (hi - lo)
        blk = cellhash(np.floor(t / 0.6), np.floor((z - lo) / 0.3), 21)      # stone blocks
        rgb = self.col * (0.8 + 0.3 * blk)[:, None] * (1 + rng.normal(0, 0.04, (n, 1)))
        return x, y, z, self.cls, rgb


def smear_around_cars(sc, cars, band=0.3, drop=0.5):
    """Post hook part: photogrammetric smear next to vehicle bodies (occluded strip beside a car):
    half of the ground points within `band` of a car outline vanish, the rest are lifted towards the body."""
    rng = sc.rng
    keep = np.ones(len(sc.x), bool)
    gnd = sc.part >= 0
    for c in cars:
        u, v = rot(sc.x, sc.y, c.cx, c.cy, c.ang)
        du = np.abs(u) - c.L / 2
        dv = np.abs(v) - c.Wd / 2
        d = np.maximum(du, dv)
        m = gnd & (d > 0) & (d < band)
        if not m.any():
            continue
        r = rng.uniform(0, 1, len(sc.x))
        keep &= ~(m & (r < drop))
        lift = m & (r >= drop)
        sc.z[lift] += (1 - d[lift] / band) * c.h * 0.7 * rng.uniform(0, 1, lift.sum()) ** 3
    sc.subset(keep)


def scene_parked(smear=True):
    """1. Residential street, parking lanes on both sides filled bumper to bumper: kerb visible only in a few gaps."""
    sc = Scene2("parked_bumper2bumper" + ("" if smear else "_nosmear"), 901, 140, 56, 130, 0.025, 0.02, "full16", 150, 45, 25, (512040.0, 5402110.0), 180.0)
    rng, M = sc.rng, sc.M
    cy = 28.0
    pl = Polyline([(-5, cy), (145, cy)])
    sc.terrain = lambda x, y: 0.004 * x
    asph = M.asphalt((0.31, 0.31, 0.32), wear=0.07)
    walk = M.concrete_slabs((0.62, 0.61, 0.58), a=1.2)
    kerb = M.solid((0.72, 0.71, 0.69))
    half = 4.6     # 2 m parking lane + 2.6 m lane on each side... (lanes 2 x 2.6 ~ 5.2, parking 2 x 2.0)
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.29, 0.42, 0.17)), dz=0.06, name="front lawns")
    sc.layer(pl.sdf_band(half + 2.5), GROUND, walk, dz=0.0, name="sidewalk")
    for x0 in (18.0, 61.0, 103.0):
        for sgn in (-1, 1):
            sc.layer(sdf_box(x0 + sgn * 6, cy + sgn * (half + 2.5 + 3), 1.5, 3.0), GROUND, M.concrete_slabs((0.55, 0.54, 0.52), a=2.0),
                     dz=0.02, name="garden driveway")
    sc.layer(pl.sdf_band(half), ROAD, asph, dz=lambda x, y: -0.12 + 0.03 * (half - np.abs(pl.local(x, y)[0])) / half,
             rim=kerb, rim_out=True, name="street incl. parking lanes")
    sc.layer(markings_dashed(pl, 0.0, w=0.12, dash=2, gap=6), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(25, cy + 0.7), (77, cy - 1.1), (120, cy + 1.0)]), ROAD, M.solid((0.2, 0.2, 0.21), 0.2))
    sc.layer(patches(sc, rng, pl, half, 4, (1, 3)), ROAD, M.asphalt((0.24, 0.24, 0.25)))
    cars = []
    gaps = {1: [(40.0, 46.5), (96.0, 101.0)], -1: [(70.0, 76.0)]}
    for sgn in (-1, 1):
        s = rng.uniform(-3, 0)
        while s < 142:
            g = [b for a, b in gaps[sgn] if a <= s < b]
            if g:
                s = g[0]
                continue
            van = rng.uniform() < 0.12
            L = rng.uniform(5.0, 5.6) if van else rng.uniform(3.9, 4.9)
            Wd = rng.uniform(1.95, 2.05) if van else rng.uniform(1.75, 1.88)
            lat = sgn * (half - Wd / 2 - rng.uniform(0.06, 0.18))
            c = Car(s + L / 2, cy + lat, rng.uniform(-0.015, 0.015), L=L, Wd=Wd, van=van,
                    h=rng.uniform(2.0, 2.5) if van else rng.uniform(1.4, 1.65))
            sc.add(c)
            cars.append(c)
            s += L + rng.uniform(0.3, 0.9)
    for sv in (30.0, 88.0):
        c = Car(sv, cy - 1.3, 0.0)
        sc.add(c)
    for sgn in (-1, 1):
        for x in np.arange(8 + 5 * (sgn > 0), 140, 19.0):
            sc.add(Tree(x + rng.uniform(-1, 1), cy + sgn * (half + 1.9), rng.uniform(2.5, 4.0), rng.uniform(7, 10)))
        for x in np.arange(0, 140, 14.0):
            bx = x + 7 + rng.uniform(-1, 1)
            D = rng.uniform(9, 11)
            sc.add(Building(bx, cy + sgn * (half + 2.5 + 6.5 + D / 2), rng.uniform(9, 11.5), D, 0.0, rng.uniform(6, 8), roof="gable",
                            rise=rng.uniform(2.5, 4), roof_col=tuple(np.array([0.5, 0.27, 0.2]) * rng.uniform(0.7, 1.2)), ridge_along=rng.uniform() < 0.5))
    for x in np.arange(12, 140, 30.0):
        sc.add(Disc(x, cy + half + 0.5, 0.12, 7.0))
    for _ in range(5):
        sc.add(Disc(rng.uniform(0, 140), cy + rng.choice([-1, 1]) * rng.uniform(5.2, 6.8), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    if smear:
        sc.post = lambda s: smear_around_cars(s, cars)
    return sc


def scene_canyon():
    """2. Urban canyon, 4-6 storeys both sides, low sun: most of the street in deep bluish shadow."""
    sc = Scene2("urban_canyon_shadow", 902, 130, 64, 120, 0.02, 0.018, "x257", -78, 17, -60, (391220.0, 5819470.0), 36.0,
                shadow=(0.24, 0.28, 0.42))
    rng, M = sc.rng, sc.M
    cy = 32.0
    pl = Polyline([(-5, cy), (135, cy)])
    cs_ = Polyline([(70, cy), (70, 70)])
    sc.terrain = lambda x, y: 0.006 * x
    asph = M.asphalt((0.34, 0.34, 0.35), wear=0.06)
    walk = M.concrete_slabs((0.63, 0.62, 0.6), a=0.8)
    kerb = M.solid((0.7, 0.7, 0.69))
    half, sw = 5.0, 2.6
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.concrete_slabs((0.55, 0.54, 0.52), a=2.0), dz=0.0, name="courtyards")
    sc.layer(pl.sdf_band(half + sw), GROUND, walk, dz=0.0, name="sidewalk")
    sc.layer(cs_.sdf_band(3.5 + 2.2), GROUND, walk, dz=0.0, name="sidewalk (cross street)")
    sc.layer(pl.sdf_band(half), ROAD, asph, dz=lambda x, y: -0.12 + 0.025 * (half - np.abs(pl.local(x, y)[0])) / half, rim=kerb, rim_out=True,
             name="canyon street")
    sc.layer(cs_.sdf_band(3.5), ROAD, asph, dz=-0.12, rim=kerb, rim_out=True, name="cross street")
    sc.layer(markings_dashed(pl, 0.0, dash=3, gap=5), ROAD, M.solid(WHITE))
    sc.layer(zebra(pl, 58, half, depth=4), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(22, cy + 1.2), (95, cy - 0.8), (70, 50)]), ROAD, M.solid((0.2, 0.2, 0.2), 0.2))
    sc.layer(patches(sc, rng, pl, half, 4, (1, 4)), ROAD, M.asphalt((0.27, 0.27, 0.28)))
    for sgn in (-1, 1):
        x = -3.0
        while x < 133:
            L = rng.uniform(12, 24)
            if sgn > 0 and x < 76 and x + L > 64:
                x = 76.0
                continue
            if sgn < 0 and x < 50 and x + L > 38:      # a gap on the sunny side: one patch of sun on the street
                x = 50.0
                continue
            D = rng.uniform(13, 17)
            storeys = int(rng.integers(4, 7))
            h = storeys * 3.2 + rng.uniform(0.5, 1.5)
            sc.add(Building(x + L / 2, cy + sgn * (half + sw + D / 2 + 0.05), L - 0.2, D, 0.0, h,
                            roof="flat" if rng.uniform() < 0.75 else "gable", rise=3.5, parapet=0.7, units=int(rng.integers(0, 4)),
                            roof_col=tuple(rng.uniform(0.35, 0.6, 3)), wall_col=tuple(rng.uniform(0.55, 0.9, 3)), ridge_along=True, wall_frac=0.08))
            x += L
    for s in np.arange(4, 128, 6.0):
        if rng.uniform() < 0.6 and abs(s - 60) > 5 and abs(s - 70) > 7:
            sc.add(Car(s, cy - half + 1.1, 0.0))
    for _ in range(4):
        sc.add(Car(rng.uniform(5, 125), cy + 1.6, np.pi, van=rng.uniform() < 0.3, h=rng.uniform(1.45, 2.3)))
    for x in np.arange(8, 130, 20.0):
        sc.add(Disc(x, cy + half + 0.45, 0.12, 6.5))
        sc.add(Disc(x + 10, cy - half - 0.45, 0.12, 6.5))
    for _ in range(14):
        sc.add(Disc(rng.uniform(0, 130), cy + rng.choice([-1, 1]) * rng.uniform(5.6, 7.3), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    for x in np.arange(15, 130, 25.0):
        sc.add(Tree(x, cy + half + 1.3, 1.8, 6.0))
    return sc


def scene_darkwalk():
    """3. Dark grey paver sidewalks next to light faded asphalt (10 cm kerbs); a light raised cycle track (5 cm) on one side."""
    sc = Scene2("dark_sidewalk_cycletrack", 903, 120, 52, 150, 0.02, 0.02, "x256", 220, 48, 100, (455010.0, 5127730.0), 260.0)
    rng, M = sc.rng, sc.M
    cy = 26.0
    pl = Polyline([(-5, cy), (125, cy)])
    side = Polyline([(64, cy), (64, -5)])
    sc.terrain = lambda x, y: -0.005 * x + 0.002 * y
    asph = M.asphalt((0.56, 0.55, 0.53), wear=0.08, grain=0.05)      # light, faded
    dark = M.pavers((0.27, 0.27, 0.28), a=0.3, b=0.15, var=0.18, joint=0.005, jdark=0.75)
    track = M.asphalt((0.70, 0.62, 0.54), wear=0.05)                   # light beige cycle track
    kerb = M.solid((0.48, 0.48, 0.49))
    half = 3.4
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.3, 0.42, 0.18)), dz=0.05, name="lawns")
    # north (lat > 0): road | 5 cm kerb | cycle track 1.9 m | 5 cm step | dark sidewalk 2.6 m
    # south: road | 10 cm kerb | dark sidewalk 3 m; side street to the south with dark sidewalks
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] > 0, pl.local(x, y)[0] - (half + 1.9 + 2.6), -pl.local(x, y)[0] - (half + 3.0)),
             GROUND, dark, dz=0.0, name="dark paver sidewalk")
    sc.layer(side.sdf_band(3.0 + 2.6), GROUND, dark, dz=0.0, name="dark sidewalk (side street)")
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] > 0, np.abs(pl.local(x, y)[0] - (half + 0.95)) - 0.95, 1.0), GROUND, track,
             dz=-0.05, rim=M.solid((0.6, 0.6, 0.6)), rim_w=0.12, name="raised cycle track")
    sc.layer(side.sdf_band(3.0), ROAD, asph, dz=-0.10, rim=kerb, rim_out=True, name="side street")
    sc.layer(pl.sdf_band(half), ROAD, asph, dz=lambda x, y: -0.10 + 0.02 * (half - np.abs(pl.local(x, y)[0])) / half,
             rim=kerb, rim_out=True, name="light asphalt street")
    sc.layer(markings_dashed(pl, 0.0, dash=3, gap=6), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(side, 0.0, s0=3, s1=14), ROAD, M.solid(WHITE))
    # cycle symbols / edge line on the track (painted white, still class 2)
    sc.layer(lambda x, y: np.where((pl.local(x, y)[0] > half) & (np.abs(pl.local(x, y)[1] % 25 - 12) < 0.6) &
                                   (np.abs(pl.local(x, y)[0] - (half + 0.95)) < 0.4), -1.0, 1.0), GROUND, M.solid(WHITE), name="track symbol")
    sc.layer(manholes(sc, [(20, cy + 1.0), (90, cy - 1.3)]), ROAD, M.solid((0.3, 0.3, 0.3), 0.2))
    sc.layer(patches(sc, rng, pl, half, 5, (1, 3)), ROAD, M.asphalt((0.40, 0.40, 0.40)))
    for x in np.arange(0, 120, 15.0):
        sc.add(Building(x + 7.5 + rng.uniform(-1, 1), cy + half + 4.5 + 4 + 6, rng.uniform(11, 14), rng.uniform(9, 12), 0.0, rng.uniform(9, 15),
                        roof="flat", parapet=0.5, units=2, roof_col=tuple(rng.uniform(0.35, 0.65, 3))))
    for x in np.arange(0, 120, 16.0):
        if abs(x + 8 - 64) > 10:
            sc.add(Building(x + 8 + rng.uniform(-1, 1), cy - half - 3 - 3 - 5, rng.uniform(10, 13), rng.uniform(8, 10), 0.0, rng.uniform(6, 9),
                            roof="gable", rise=3, roof_col=tuple(np.array([0.5, 0.3, 0.25]) * rng.uniform(0.8, 1.2))))
    for x in np.arange(6, 120, 13.0):
        sc.add(Tree(x, cy - half - 2.3, rng.uniform(2.2, 3.5), rng.uniform(6, 9)))
    for _ in range(5):
        sc.add(Car(rng.uniform(5, 115), cy + rng.choice([-1.6, 1.6]), 0.0))
    for _ in range(4):
        sc.add(Disc(rng.uniform(0, 120), cy + half + 0.95, 0.3, 1.6, col=tuple(rng.uniform(0.1, 0.8, 3))))  # cyclists
    for _ in range(8):
        sc.add(Disc(rng.uniform(0, 120), cy + rng.choice([-1, 1]) * rng.uniform(5.8, 7.6), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


def scene_sparse():
    """4. Low density and high noise: 20 points/m2, height noise 7 cm, kerbs 11 cm, suburban T and curve."""
    sc = Scene2("sparse_noisy_20ppm", 904, 230, 120, 20, 0.07, 0.03, "x257", 60, 40, 145, (602110.0, 5500870.0), 127.0)
    rng, M = sc.rng, sc.M
    tn = Noise(rng, 230, 120, 40)
    sc.terrain = lambda x, y: 0.01 * x + 0.4 * tn(x, y)
    main = Polyline(bezier((-10, 40), (70, 30), (150, 70), (240, 60)))
    side = Polyline([(110, 48), (105, 125)])
    asph = M.asphalt((0.33, 0.33, 0.34), wear=0.08)
    walk = M.concrete_slabs((0.6, 0.59, 0.57), a=1.5)
    kerb = M.solid((0.7, 0.7, 0.68))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.3, 0.43, 0.18), dry=0.1), dz=0.03)
    sc.layer(main.sdf_band(3.5 + 2.0), GROUND, walk, dz=0.0, name="sidewalk")
    sc.layer(side.sdf_band(3.0 + 1.8), GROUND, walk, dz=0.0, name="sidewalk (side)")
    sc.layer(side.sdf_band(3.0), ROAD, asph, dz=-0.11, rim=kerb, rim_out=True, name="side road")
    sc.layer(main.sdf_band(3.5), ROAD, asph, dz=lambda x, y: -0.11 + 0.02 * (3.5 - np.abs(main.local(x, y)[0])) / 3.5,
             rim=kerb, rim_out=True, name="main road")
    sc.layer(markings_dashed(main, 0.0, dash=3, gap=6), ROAD, M.solid(WHITE))
    sc.layer(patches(sc, rng, main, 3.5, 6, (1, 4)), ROAD, M.asphalt((0.26, 0.26, 0.27)))
    for s in np.arange(5, main.length, 16.0):
        for sgn in (-1, 1):
            px, py, an = point_on(main, s + rng.uniform(-2, 2), sgn * rng.uniform(13, 16))
            if abs(px - 108) < 12 and sgn > 0:
                continue
            sc.add(Building(px, py, rng.uniform(9, 13), rng.uniform(8, 11), an + rng.uniform(-0.1, 0.1), rng.uniform(5, 8), roof="gable",
                            rise=rng.uniform(2.5, 4), roof_col=tuple(rng.uniform(0.3, 0.6, 3)), ridge_along=rng.uniform() < 0.5))
            if rng.uniform() < 0.5:
                px, py, an = point_on(main, s + 8, sgn * rng.uniform(6.5, 8))
                sc.add(Tree(px, py, rng.uniform(3, 5), rng.uniform(8, 13)))
    for s in np.arange(12, side.length, 16.0):
        for sgn in (-1, 1):
            px, py, an = point_on(side, s, sgn * rng.uniform(11, 13))
            sc.add(Building(px, py, rng.uniform(9, 12), rng.uniform(8, 10), an, rng.uniform(5, 7), roof="gable", rise=3,
                            roof_col=tuple(rng.uniform(0.3, 0.6, 3))))
    for _ in range(8):
        px, py, an = point_on(main, rng.uniform(5, main.length - 5), rng.choice([-1.8, 1.8]))
        sc.add(Car(px, py, an))
    for _ in range(3):
        px, py, an = point_on(side, rng.uniform(10, 70), 1.9)
        sc.add(Car(px, py, an))
    return sc


def scene_artefacts():
    """5. Photogrammetric artefacts: misaligned overlapping strips (doubled surface), exposure seam, holes."""
    sc = Scene2("photogrammetry_artefacts", 905, 120, 70, 110, 0.025, 0.02, "x257", 200, 45, 200, (367880.0, 5702340.0), 72.0)
    rng, M = sc.rng, sc.M
    cy = 35.0
    pl = Polyline([(-5, cy), (125, cy)])
    sc.terrain = lambda x, y: -0.004 * x + 0.003 * y
    asph = M.asphalt((0.33, 0.33, 0.34), wear=0.07)
    park = M.pavers((0.42, 0.41, 0.40), a=0.2, b=0.1, var=0.2)
    walk = M.concrete_slabs((0.64, 0.63, 0.6), a=1.0)
    kerb = M.solid((0.72, 0.71, 0.69))
    half = 5.5
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.3, 0.42, 0.17)), dz=0.05, name="lawns")
    sc.layer(pl.sdf_band(half + 3.0), GROUND, walk, dz=0.0, name="sidewalk")
    sc.layer(pl.sdf_band(half), ROAD, asph, dz=lambda x, y: -0.12 + 0.025 * (half - np.abs(pl.local(x, y)[0])) / half,
             rim=kerb, rim_out=True, name="street")
    sc.layer(lambda x, y: np.where(np.abs(pl.local(x, y)[0]) > half - 2.0, np.abs(pl.local(x, y)[0]) - half, 1.0), ROAD, park,
             name="paved parking strips")
    sc.layer(markings_dashed(pl, 0.0, dash=3, gap=6), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(pl, 3.5), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(pl, -3.5), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [(18, cy + 1.0), (66, cy - 1.5), (101, cy + 0.5)]), ROAD, M.solid((0.2, 0.2, 0.2), 0.2))
    trees, metal = [], []
    for sgn in (-1, 1):
        for x in np.arange(5 + 4 * (sgn > 0), 120, 11.0):
            t = Tree(x + rng.uniform(-1, 1), cy + sgn * (half + 1.2), rng.uniform(3.0, 4.5), rng.uniform(8, 12))
            sc.add(t)
            trees.append(t)
        x = 0.0
        while x < 118:
            L = rng.uniform(12, 20)
            D = rng.uniform(10, 14)
            shiny = rng.uniform() < 0.35
            b = Building(x + L / 2, cy + sgn * (half + 3.0 + 4 + D / 2), L - 1.5, D, 0.0, rng.uniform(6, 12), roof="flat" if shiny else "gable",
                         rise=3, parapet=0.3, roof_col=(0.78, 0.8, 0.82) if shiny else tuple(rng.uniform(0.3, 0.6, 3)), ridge_along=True)
            sc.add(b)
            if shiny:
                metal.append(b)
            x += L
    for s in np.arange(3, 118, 5.5):
        for sgn in (-1, 1):
            if rng.uniform() < 0.5:
                sc.add(Car(s + 2.5, cy + sgn * (half - 1.0), 0.0))
    for _ in range(3):
        sc.add(Car(rng.uniform(5, 115), cy + rng.choice([-1.7, 1.7]), 0.0))

    def post(s):
        r = s.rng
        # holes: no points in the crowns (and the ground just around) of 5 trees, on 3 specular roofs
        keep = np.ones(len(s.x), bool)
        for t in [trees[i] for i in r.choice(len(trees), 5, replace=False)]:
            keep &= np.hypot(s.x - t.cx, s.y - t.cy) > t.r * 1.05
        for b in metal[:3]:
            u, v = rot(s.x, s.y, b.cx, b.cy, b.ang)
            keep &= ~((np.abs(u) < b.L / 2 - 0.3) & (np.abs(v) < b.Wd / 2 - 0.3) & (s.z > b.base + b.h - 0.5))
        s.subset(keep)
        # second flight strip over the eastern half: 60 % of the points again, 5 cm higher, 7/-5 cm in plan, other exposure
        s.strip = (s.x > 60).copy()
        idx = np.flatnonzero(s.strip & (r.uniform(0, 1, len(s.x)) < 0.6))
        s.append(idx, dx=0.07, dy=-0.05, dz=0.05, kc=0.96)
        # exposure seam: +15 % on one side of an oblique straight line
        side_ = s.y > 0.45 * s.x + 12
        s.rgb[side_] = np.clip(s.rgb[side_] * 1.15, 0, 1)
    sc.post = post
    return sc


def scene_junction():
    """6. Wide 4-arm junction, 3 approach + 2 exit lanes per arm, kerbed divider and corner islands, zebras, stop lines."""
    sc = Scene2("wide_junction_islands", 906, 160, 160, 38, 0.03, 0.02, "x256", 135, 50, 12, (689030.0, 5335420.0), 281.0)
    rng, M = sc.rng, sc.M
    C = np.array([80.0, 80.0])
    sc.terrain = lambda x, y: 0.003 * x - 0.002 * y
    asph = M.asphalt((0.30, 0.30, 0.31), wear=0.06)
    walk = M.concrete_slabs((0.62, 0.61, 0.58), a=1.5, ang=0.0)
    kerb = M.solid((0.73, 0.72, 0.7))
    isl = M.pavers((0.58, 0.48, 0.42), a=0.2, b=0.1, var=0.25)
    vin, vout = 9.6, 6.5       # inbound (3 x 3.2) right of the centre, outbound (2 x 3.25) left; 2.5 m divider
    vmed = 1.25
    angs = [0.0, np.pi / 2, np.pi, 3 * np.pi / 2]
    # arm frames: u outwards, v to the left of the outward direction; inbound lanes (towards C) at v > 0
    def arm_band(a):
        def f(x, y):
            u, v = rot(x, y, C[0], C[1], a)
            return np.maximum(-u, np.maximum(v - (vmed + vin), -(v + vmed + vout)))
        return f
    def road_sdf():
        fs = [arm_band(a) for a in angs]
        fs.append(sdf_box(C[0], C[1], vmed + vin, vmed + vin))
        # corner fillets (R 9 m; 20 m with a slip lane at two corners)
        for k, a in enumerate(angs):
            a2 = a + np.pi / 2
            R = 28.0 if k in (0, 2) else 9.0
            # corner between arm a (its +v side: inbound edge at v = vmed+vin) and arm a2 (its -v side: outbound edge)
            e1 = vmed + vin          # arm a edge offset (in a2's direction)
            e2 = vmed + vout         # arm a2 edge offset (in a's direction)
            ca, sa = np.cos(a), np.sin(a)
            c2, s2 = np.cos(a2), np.sin(a2)
            P = C + e2 * np.array([ca, sa]) + e1 * np.array([c2, s2])
            Q = P + R * np.array([ca, sa]) + R * np.array([c2, s2])
            def fil(x, y, P=P, Q=Q, R=R, a=a):
                u, v = rot(x, y, P[0], P[1], a)
                box = np.maximum(np.maximum(-u, u - R), np.maximum(-v, v - R))
                return np.maximum(box, -(np.hypot(x - Q[0], y - Q[1]) - R))
            fs.append(fil)
        return sdf_union(*fs), fs
    rsdf, _ = road_sdf()
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.3, 0.43, 0.18)), dz=0.08, name="lawns")
    sc.layer(lambda x, y: rsdf(x, y) - 4.0, GROUND, walk, dz=0.0, name="sidewalk")
    sc.layer(rsdf, ROAD, asph, dz=lambda x, y: -0.13 + 0.015 * np.clip(1 - np.abs(np.hypot(x - C[0], y - C[1])) / 80, 0, 1), rim=kerb,
             rim_out=True, name="junction carriageway")
    # islands: divider on each arm (u 28..60, nose rounded), triangles at the slip-lane corners
    for k, a in enumerate(angs):
        def div(x, y, a=a):
            u, v = rot(x, y, C[0], C[1], a)
            w = vmed * smooth01((u - 27.5) / 4.0) + 0.25
            return np.maximum(np.abs(v) - w, np.maximum(27.5 - u, u - 62))
        sc.layer(div, GROUND, isl, dz=0.0, rim=kerb, rim_w=0.15, name="divider island")
        if k in (0, 2):
            a2 = a + np.pi / 2
            e1, e2 = vmed + vin, vmed + vout
            d1, d2 = np.array([np.cos(a), np.sin(a)]), np.array([np.cos(a2), np.sin(a2)])
            P = C + e2 * d1 + e1 * d2
            def tri(x, y, P=P, d1=d1, d2=d2):
                px, py = x - P[0], y - P[1]
                a_ = px * d1[0] + py * d1[1]
                b_ = px * d2[0] + py * d2[1]
                # triangle a>=1.5, b>=1.5, a+b <= 10.5 (then a ~4.2 m slip lane to the outer kerb, R 28 m)
                return np.maximum(np.maximum(1.5 - a_, 1.5 - b_), (a_ + b_ - 10.5) / np.sqrt(2))
            sc.layer(tri, GROUND, M.grass((0.28, 0.42, 0.16)), dz=0.05, rim=kerb, rim_w=0.15, name="corner island")
    # markings
    def marks(x, y):
        on = np.zeros(len(x), bool)
        for a in angs:
            u, v = rot(x, y, C[0], C[1], a)
            inb = (v > vmed) & (v < vmed + vin)
            outb = (v < -vmed) & (v > -vmed - vout)
            on |= (u > 22.5) & (u < 26.5) & (v > -vmed - vout + 0.4) & (v < vmed + vin - 0.4) & (((v + 30) % 1.0) < 0.5)   # zebra
            on |= inb & (np.abs(u - 27.4) < 0.25)                                       # stop line
            for lv in (vmed + 3.2, vmed + 6.4):
                on |= (np.abs(v - lv) < 0.075) & (u > 27.5) & ((u < 45) | (((u - 45) % 9) < 3))
            on |= (np.abs(v + vmed + 3.25) < 0.075) & (u > 27.5) & (((u - 27.5) % 9) < 3)
            on |= (np.abs(np.abs(v) - 0.2) < 0.075) & (u > 62)                           # double centre line
            # arrows (shaft + head) in each inbound lane
            for lc in (vmed + 1.6, vmed + 4.8, vmed + 8.0):
                on |= (np.abs(v - lc) < 0.08) & (u > 31) & (u < 35)
                on |= (u > 29.5) & (u < 31) & (np.abs(v - lc) < 0.45 * (u - 29.5))
        return np.where(on, -1.0, 1.0)
    sc.layer(marks, ROAD, M.solid(WHITE), name="markings")
    sc.layer(manholes(sc, [(C[0] + 5, C[1] - 3), (C[0] + 40, C[1] + 5), (C[0] - 3, C[1] - 45)]), ROAD, M.solid((0.2, 0.2, 0.2), 0.2))
    # corner blocks: buildings and trees
    for qx in (-1, 1):
        for qy in (-1, 1):
            for j in range(3):
                bx = C[0] + qx * rng.uniform(38, 68)
                by = C[1] + qy * rng.uniform(38, 68)
                if rsdf(np.array([bx]), np.array([by]))[0] < 16:
                    continue
                sc.add(Building(bx, by, rng.uniform(12, 20), rng.uniform(10, 16), rng.uniform(-0.05, 0.05), rng.uniform(8, 20), roof="flat",
                                parapet=0.6, units=int(rng.integers(0, 4)), roof_col=tuple(rng.uniform(0.35, 0.65, 3))))
            for j in range(8):
                tx, ty = C[0] + qx * rng.uniform(24, 75), C[1] + qy * rng.uniform(22, 30)
                if rsdf(np.array([tx]), np.array([ty]))[0] < 2.5:
                    continue
                sc.add(Tree(tx, ty, rng.uniform(2.5, 4), rng.uniform(7, 11)))
    for a in angs:
        ca, sa = np.cos(a), np.sin(a)
        for lc in (vmed + 1.6, vmed + 4.8, vmed + 8.0):
            for k in range(int(rng.integers(1, 3))):
                u = 30.5 + k * 7 + rng.uniform(0, 1.5)
                sc.add(Car(C[0] + u * ca - lc * sa, C[1] + u * sa + lc * ca, a + np.pi, van=rng.uniform() < 0.15, h=rng.uniform(1.4, 2.2)))
        for _ in range(2):
            u = rng.uniform(35, 75)
            lc = -(vmed + rng.choice([1.6, 4.9]))
            sc.add(Car(C[0] + u * ca - lc * sa, C[1] + u * sa + lc * ca, a))
        for u in (20.0, 45.0, 70.0):
            for lv in (vmed + vin + 1.0, -(vmed + vout + 1.0)):
                sc.add(Disc(C[0] + u * ca - lv * sa, C[1] + u * sa + lv * ca, 0.12, 7.5))
        for _ in range(3):
            u = rng.uniform(20, 75)
            lv = rng.choice([vmed + vin + 2.5, -(vmed + vout + 2.5)])
            sc.add(Disc(C[0] + u * ca - lv * sa, C[1] + u * sa + lv * ca, 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


def scene_bumps():
    """7. Speed hump, speed bump, raised table crossing (+9 cm over 1.5 m ramps: still road), lowered kerbs at driveways."""
    sc = Scene2("speedbumps_table_driveways", 907, 110, 44, 220, 0.015, 0.016, "full16", 300, 55, 135, (420550.0, 5520330.0), 199.0)
    rng, M = sc.rng, sc.M
    cy = 22.0
    pl = Polyline([(0, cy), (110.01, cy)])
    sc.terrain = lambda x, y: 0.012 * x
    asph = M.asphalt((0.32, 0.32, 0.33), wear=0.06)
    walk = M.pavers((0.6, 0.58, 0.55), a=0.2, b=0.1, var=0.2)
    kerb = M.solid((0.74, 0.73, 0.71))
    half, sw = 3.25, 2.2

    def hump(s):
        z = 0.08 * np.sin(np.pi * np.clip((s - 18) / 3.8, 0, 1)) ** 2            # round-top hump 3.8 m, 8 cm
        z += 0.07 * np.sin(np.pi * np.clip((s - 84) / 0.6, 0, 1))                # short bump 0.6 m, 7 cm
        tb = np.clip((s - 48.5) / 1.5, 0, 1) * np.clip((57.5 - s) / 1.5, 0, 1)    # table: ramps 1.5 m, top 48.5+1.5 .. 56
        return z + 0.09 * np.clip(tb * 1.0, 0, 1) * 1.0
    def road_dz(x, y):
        lat, s, _ = pl.local(x, y)
        return -0.12 + 0.025 * (half - np.abs(lat)) / half + hump(s)
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.3, 0.42, 0.18)), dz=0.05, name="front gardens")
    sc.layer(pl.sdf_band(half + sw), GROUND, walk, dz=0.0, name="sidewalk")
    drives = []
    for sgn in (-1, 1):
        s = rng.uniform(3, 8)
        while s < 106:
            if not (45 < s < 61):
                drives.append((s, sgn))
            s += rng.uniform(10, 15)
    for s0, sgn in drives:
        w = rng.uniform(1.6, 2.0)
        # driveway across the garden (concrete) and the lowered kerb: the sidewalk ramps down to 2 cm over 0.8 m
        sc.layer(sdf_box(s0, cy + sgn * (half + sw + 4), w, 4.0), GROUND, M.concrete_slabs((0.56, 0.55, 0.53), a=2.0), dz=0.02, name="driveway")
        def ramp(x, y, s0=s0, w=w, sgn=sgn):
            lat, s, _ = pl.local(x, y)
            return np.maximum(np.abs(s - s0) - w - 0.5, np.where(sgn * lat > 0, np.abs(sgn * lat - half - 0.45) - 0.45, 1.0))
        def ramp_dz(x, y, s0=s0, w=w):
            lat, s, _ = pl.local(x, y)
            t = np.clip((np.abs(lat) - half) / 0.8, 0, 1) * 1.0
            k = np.clip((w + 0.5 - np.abs(s - s0)) / 0.5, 0, 1)      # kerb drops over 0.5 m at the ends
            return (-0.10 * (1 - t)) * k
        sc.layer(ramp, GROUND, walk, dz=ramp_dz, eps=0.05, name="lowered kerb ramp")
    # on the table the sidewalk meets the carriageway nearly flush (kerb 3 cm)
    sc.layer(pl.sdf_band(half), ROAD, asph, dz=road_dz, rim=kerb, rim_out=True, name="street (humps, table)")
    def paint(x, y):
        lat, s, out = pl.local(x, y)
        on = (np.abs(lat) < half - 0.1) & (s > 50.5) & (s < 55.5) & (((lat + 20) % 1.0) < 0.5)       # zebra on the table
        on |= (np.abs(lat) < half) & (((s > 48.5) & (s < 50)) | ((s > 56) & (s < 57.5))) & (np.abs(((lat + 20) % 1.0) - 0.5) < 0.25 * np.minimum(np.abs(s - 48.5), np.abs(s - 57.5)))
        on |= (np.abs(lat) < half) & (s > 84) & (s < 84.6) & (((lat + 20) % 0.8) < 0.4)                # striped bump
        on |= (np.abs(lat) < half) & (s > 18) & (s < 21.8) & (np.abs(((lat + 20) % 1.6) - 0.8) < 0.15)
        return np.where(on, -1.0, 1.0)
    sc.layer(paint, ROAD, M.solid(WHITE), name="markings")
    sc.layer(manholes(sc, [(33, cy + 1.0), (70, cy - 1.2), (100, cy + 0.6)]), ROAD, M.solid((0.2, 0.2, 0.2), 0.2))
    sc.layer(patches(sc, rng, pl, half, 3, (1, 3)), ROAD, M.asphalt((0.25, 0.25, 0.26)))
    for s0, sgn in drives:
        sc.add(Building(s0 + rng.uniform(4, 6), cy + sgn * (half + sw + 9 + 4), rng.uniform(8, 10), 8, 0.0, rng.uniform(6, 8), roof="gable", rise=3,
                        roof_col=tuple(np.array([0.5, 0.28, 0.2]) * rng.uniform(0.8, 1.2)), ridge_along=rng.uniform() < 0.5))
        if rng.uniform() < 0.5:
            sc.add(Car(s0, cy + sgn * (half + sw + 3), np.pi / 2))
    for s in np.arange(8, 105, 9.0):
        if rng.uniform() < 0.45 and not (44 < s < 62) and all(abs(s - d) > 3.5 for d, g in drives if g < 0):
            sc.add(Car(s, cy - half + 1.0, 0.0))
    sc.add(Car(35, cy + 1.6, np.pi))
    for x in np.arange(10, 110, 22.0):
        sc.add(Tree(x, cy + half + sw + 1.5, rng.uniform(3, 4), rng.uniform(7, 10)))
    for x in (47.0, 59.0):
        for sgn in (-1, 1):
            sc.add(Disc(x, cy + sgn * (half + 0.35), 0.1, 0.9, col=(0.25, 0.25, 0.27)))
    for _ in range(6):
        sc.add(Disc(rng.uniform(0, 110), cy + rng.choice([-1, 1]) * rng.uniform(3.8, 5.2), 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


def scene_hillside(gentle=False):
    """8. Road on a hillside at 11 %: retaining wall uphill behind a narrow sidewalk, steep grass bank downhill, no sidewalk there.
    gentle (control): the same road with a 1 m wall, a 10 % slope above it and a 2 m bank (70 % over 3 m, then 5 %)."""
    sc = Scene2("hillside_11pct_wall" + ("_gentle" if gentle else ""), 908, 130, 60, 90, 0.025, 0.02, "x257", 250, 40, 250, (651120.0, 5191450.0), 612.0)
    rng, M = sc.rng, sc.M
    pl = Polyline(bezier((-5, 24), (40, 22), (90, 30), (135, 28)))
    half, sw = 3.1, 1.8
    wn = Noise(rng, 130, 60, 20)
    up_slope, bank_w, below = (0.10, 3.0, 0.05) if gentle else (0.32, 9.0, 0.12)
    def wall_h(x, y):
        return (1.0 + 0.2 * wn(x, y)) if gentle else (2.8 + 0.6 * wn(x, y))
    def terrain(x, y):
        lat, s, _ = pl.local(x, y)
        z = 0.11 * s
        up = lat > half + sw
        z = z + np.where(up, wall_h(x, y) + up_slope * np.clip(lat - half - sw - 0.35, 0, None), 0.0)
        dn = lat < -(half + 0.6)
        z = z + np.where(dn, -0.7 * np.clip(-lat - half - 0.6, 0, bank_w) - below * np.clip(-lat - half - 0.6 - bank_w, 0, None), 0.0)
        return z
    sc.terrain = terrain
    asph = M.asphalt((0.35, 0.35, 0.36), wear=0.08)
    walk = M.concrete_slabs((0.62, 0.61, 0.58), a=1.0)
    kerb = M.solid((0.7, 0.7, 0.69))
    sc.layer(lambda x, y: np.full(len(x), -1.0), GROUND, M.grass((0.31, 0.43, 0.18), dry=0.15), dz=0.0, name="hillside grass")
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] < 0, -pl.local(x, y)[0] - (half + 0.6), 1.0), GROUND, M.gravel(), dz=0.0,
             name="gravel shoulder (downhill)")
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] > 0, np.abs(pl.local(x, y)[0] - (half + sw / 2)) - sw / 2, 1.0), GROUND, walk, dz=0.0,
             name="sidewalk (uphill)")
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] > 0, np.abs(pl.local(x, y)[0] - (half + 0.075)) - 0.075, 1.0), GROUND, kerb, dz=None,
             name="kerb stone (uphill)")
    sc.layer(lambda x, y: np.where(pl.local(x, y)[0] > 0, np.abs(pl.local(x, y)[0] - (half + sw + 0.175)) - 0.175, 1.0), OTHER,
             M.solid((0.66, 0.64, 0.6)), dz=None, name="wall coping")
    # road: cross-fall 2 % towards the uphill gutter (12 cm under the sidewalk), flush with the downhill shoulder
    sc.layer(pl.sdf_band(half), ROAD, asph, dz=lambda x, y: -0.02 * (pl.local(x, y)[0] + half), name="hill road", eps=0.04)
    sc.layer(markings_dashed(pl, 0.0, dash=3, gap=6), ROAD, M.solid(WHITE))
    sc.layer(markings_solid(pl, -(half - 0.2), w=0.12), ROAD, M.solid(WHITE))
    sc.layer(manholes(sc, [point_on(pl, 30, 1.0)[:2], point_on(pl, 95, -1.0)[:2]]), ROAD, M.solid((0.2, 0.2, 0.2), 0.2))
    sc.layer(patches(sc, rng, pl, half, 4, (1, 3)), ROAD, M.asphalt((0.27, 0.27, 0.28)))
    # wall face
    i = np.arange(0, len(pl.x), 5)
    wx = pl.x[i] - (half + sw) * pl.ty[i]
    wy = pl.y[i] + (half + sw) * pl.tx[i]
    sc.add(Wall(np.c_[wx, wy], lambda x, y: 0.11 * pl.local(x, y)[1],
                lambda x, y: 0.11 * pl.local(x, y)[1] + wall_h(x, y), frac=0.35))
    # guard-rail posts on the downhill shoulder, houses uphill, trees downhill
    for s in np.arange(1, pl.length, 2.0):
        px, py, _ = point_on(pl, s, -(half + 0.45))
        sc.add(Disc(px, py, 0.08, 0.75, col=(0.7, 0.7, 0.72)))
    for s in np.arange(8, pl.length, 18.0):
        px, py, an = point_on(pl, s + rng.uniform(-2, 2), half + sw + 14 + rng.uniform(0, 3))
        if py < 56:
            sc.add(Building(px, py, rng.uniform(9, 12), rng.uniform(8, 10), an, rng.uniform(6, 8), roof="gable", rise=3,
                            roof_col=tuple(np.array([0.5, 0.3, 0.22]) * rng.uniform(0.8, 1.2))))
        px, py, an = point_on(pl, s + 9, half + sw + 5 + rng.uniform(0, 2))
        sc.add(Tree(px, py, rng.uniform(2.5, 4), rng.uniform(6, 10)))
    for s in np.arange(4, pl.length, 9.0):
        if rng.uniform() < 0.6:
            px, py, an = point_on(pl, s, -(half + 4 + rng.uniform(0, 8)))
            sc.add(Tree(px, py, rng.uniform(2.5, 5), rng.uniform(7, 13)))
    for _ in range(3):
        px, py, an = point_on(pl, rng.uniform(5, pl.length - 5), rng.choice([-1.6, 1.6]))
        sc.add(Car(px, py, an))
    for _ in range(3):
        px, py, an = point_on(pl, rng.uniform(5, pl.length - 5), half + sw / 2)
        sc.add(Disc(px, py, 0.25, 1.7, col=tuple(rng.uniform(0.1, 0.8, 3))))
    return sc


SCENES.update({
    "parked_bumper2bumper": scene_parked,
    "urban_canyon_shadow": scene_canyon,
    "dark_sidewalk_cycletrack": scene_darkwalk,
    "sparse_noisy_20ppm": scene_sparse,
    "photogrammetry_artefacts": scene_artefacts,
    "wide_junction_islands": scene_junction,
    "speedbumps_table_driveways": scene_bumps,
    "hillside_11pct_wall": scene_hillside,
    "parked_bumper2bumper_nosmear": lambda: scene_parked(False),
    "hillside_11pct_wall_gentle": lambda: scene_hillside(True),
})
NEW_SCENES = ["parked_bumper2bumper", "urban_canyon_shadow", "dark_sidewalk_cycletrack", "sparse_noisy_20ppm",
              "photogrammetry_artefacts", "wide_junction_islands", "speedbumps_table_driveways", "hillside_11pct_wall"]




def main(argv):
    names = list(SCENES) if argv == ["all"] else (NEW_SCENES if argv == ["new"] else argv)
    os.makedirs(OUTDIR, exist_ok=True)
    for nm in names:
        t0 = time.time()
        sc = SCENES[nm]().generate()
        n = sc.write(f"{OUTDIR}/{nm}.laz")
        road = np.mean(sc.cls == ROAD)
        area = sc.W * sc.H
        print(f"{nm}: {n} points, {n / area:.0f} pts/m2 over {area:.0f} m2, road {100 * road:.1f} %, "
              f"shadowed {100 * sc.sh.mean():.1f} %, classes {dict(zip(*np.unique(sc.cls, return_counts=True)))}, "
              f"{time.time() - t0:.1f} s", flush=True)
        o = sc.order
        np.savez_compressed(f"{OUTDIR}/{nm}.meta.npz", x=sc.x[o], y=sc.y[o], cls=sc.cls[o], sh=sc.sh[o], part=sc.part[o],
                            kerb=sc.kerbb[o], names=np.array([L["name"] for L in sc.layers]), W=sc.W, H=sc.H)


if __name__ == "__main__":
    main(sys.argv[1:])
