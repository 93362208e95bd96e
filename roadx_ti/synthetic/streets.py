"""uav-road: UAV photogrammetric streets whose look is drawn per seed (the road pipeline's test bed).

What varies per seed, as it varies between real surveys and streets:
- density 50-300 points/m2 (log-uniform; the point count then sets the area), +-40 % over the
  scene; height noise (surface thickness) 1.5-5 cm; per-point colour noise 3-8 grey levels;
- a road network in any orientation: roads along two directions, gently curved, some ending at
  T-junctions; per road a carriageway of 5.5-11 m, parking lanes on none, one or both sides, and
  sidewalks of 1.5-4.5 m behind kerbs of 8-16 cm, lowered to 1-2 cm at pedestrian crossings
  (zebra markings) near junctions and mid-block;
- asphalt light or dark (grey 50-140) with a shade per road, wear texture and repair patches;
  sidewalks within 6-15 grey levels of the asphalt, lighter or darker (only the kerb tells them
  apart), kerb stones lighter; lane markings;
- lots behind the sidewalks: lawns, paved yards (grey, at lot level), hedges, flat and pitched
  buildings (some flush with the sidewalk), street trees whose crowns hang over the carriageway
  (the road under them is partly hidden), parked cars and cars in the travel lanes, lamp posts;
- a low or high sun: cast shadows across road and sidewalk, 40-70 % darker and bluer.

Truth: 11 carriageway and parking lanes with their markings; 2 sidewalks, kerbs, lawns, yards;
3/4/5 vegetation, 6 buildings, 1 cars and posts, 7/18 noise.
"""
from __future__ import annotations

import math

import numpy as np

from roadx_ti.synthetic.base import (
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

_CAR_COLOURS = np.array([[180, 30, 30], [30, 60, 150], [225, 225, 225], [25, 25, 28], [160, 162, 165],
                         [70, 72, 75], [200, 170, 40], [40, 110, 60], [120, 20, 30], [110, 112, 116]],
                        dtype=F32)
_WALL_COLOURS = np.array([[205, 190, 165], [222, 216, 204], [150, 85, 65], [160, 158, 152],
                          [190, 170, 130], [120, 118, 112]], dtype=F32)
_PITCHED_ROOF_COLOURS = np.array([[150, 70, 50], [125, 82, 62], [72, 74, 80], [165, 95, 60],
                                  [96, 96, 100]], dtype=F32)
_FLAT_ROOF_COLOURS = np.array([[130, 125, 115], [58, 58, 62], [200, 200, 196], [104, 103, 100],
                               [86, 86, 88]], dtype=F32)


CROWN = 6.0        # m: the camber rises over at most this distance from a road edge


def street_look(seed: int) -> dict:
    """The per-seed look of a scene (drawn before the scene's size is known: density sets it)."""
    r = np.random.default_rng(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, StreetScene.KIND_ID, 7]))
    dark = r.random() < 0.5
    asphalt = r.uniform(50, 85) if dark else r.uniform(100, 140)
    return dict(
        density=float(50.0 * 6.0 ** r.random()),            # points per m2, 50..300
        height_noise=float(r.uniform(0.015, 0.05)),          # m, surface thickness (1 sigma)
        colour_noise=float(r.uniform(3.0, 8.0)),             # grey levels per channel
        asphalt=float(asphalt),
        sidewalk_offset=float(r.choice([-1.0, 1.0]) * r.uniform(6.0, 15.0)),
        kerb=float(r.uniform(0.08, 0.16)),
        angle=float(r.uniform(0.0, np.pi / 2)),
        shadow_factor=float(r.uniform(0.3, 0.6)),            # shadowed brightness = 1 - this
        sun_elevation=float(r.uniform(25.0, 60.0)),
        parking_occupancy=float(r.uniform(0.3, 0.85)),
    )


class StreetScene(PhotoScene):
    KIND = "uav-road"
    KIND_ID = 3
    ORIGIN = (500000.0, 4500000.0, 0.0)
    OUTLIER_FRACTION = 0.004
    BLOCK = 25.0             # smallest scene edge (m)
    OUTLIER_RANGE = (0.3, 3.0)
    HIGH_SCALE = 3.0
    UNDER_CANOPY_HIDDEN = 0.6
    GRASS = (78, 112, 52)

    @classmethod
    def side_for(cls, n_points: int, seed: int) -> float:
        # walls and crowns add about what footprints and canopies hide: plan density ~ drawn density
        return max(math.sqrt(n_points / street_look(seed)["density"]), cls.BLOCK)

    # ---------------------------------------------------------------- layout
    def _layout(self):
        r = self.rng_layout
        look = street_look(self._seed)
        self.look = look
        side = self.side
        self.z0 = 50.0
        self.kerb = look["kerb"]
        self.ang = look["angle"]
        self.cos_a, self.sin_a = math.cos(self.ang), math.sin(self.ang)
        # (u, v): the road network's frame, rotated by ang; it covers the square's rotated extent
        corners = np.array([[0, 0], [side, 0], [0, side], [side, side]], dtype=np.float64)
        cu, cv = self._uv(corners[:, 0], corners[:, 1])
        self.u_range = (float(cu.min()), float(cu.max()))
        self.v_range = (float(cv.min()), float(cv.max()))
        self.grade = r.uniform(0.0, 0.05, 2) * r.choice([-1, 1], 2)     # mean grades along u, v
        self.relief = SmoothNoise(r, 160.0, n_waves=4)
        self.relief_amp = r.uniform(0.3, 1.5)
        self.camber = r.uniform(0.01, 0.025)
        self.density_noise = SmoothNoise(r, 35.0)
        self.sigma_noise = SmoothNoise(r, 25.0)
        self.wear_noise = SmoothNoise(r, r.uniform(4.0, 8.0))
        self.wear_amp = r.uniform(3.0, 7.0)
        self.grass_noise = SmoothNoise(r, 3.0)
        self.sun_az = r.uniform(0, 2 * np.pi)
        self.sun_tan = math.tan(math.radians(look["sun_elevation"]))
        self._layout_roads(r)
        buildings, trees, cars, poles, hedges, yards, beds = [], [], [], [], [], [], []
        self._layout_lots(r, buildings, trees, hedges, yards, beds)
        self._layout_street_objects(r, trees, cars, poles)
        keys_b = ("cx", "cy", "hx", "hy", "ang", "base", "eave", "ridge", "roof", "roof_rgb", "wall_rgb")
        self.buildings = Boxes.from_rows(buildings, keys_b)
        self.cars = Boxes.from_rows(cars, keys_b)
        self.trees = Boxes.from_rows(trees, ("cx", "cy", "ground", "cz", "R", "rz", "trunk", "rgb"))
        self.hedges = Boxes.from_rows(hedges, ("cx", "cy", "ground", "cz", "R", "rz", "trunk", "rgb"))
        self.poles = Boxes.from_rows(poles, ("x", "y", "ground", "h"))
        self.beds = Boxes.from_rows(beds, ("cx", "cy", "hx", "hy", "ground", "h"))
        self.yards = yards
        self._footprints = (self.buildings, self.cars, self.beds)
        self._canopies = (self.trees, self.hedges)
        self._build_shadow_raster()

    def __init__(self, side, seed):
        self._seed = int(seed)
        super().__init__(side, seed)

    def _uv(self, x, y):
        return x * self.cos_a + y * self.sin_a, -x * self.sin_a + y * self.cos_a

    def _xy(self, u, v):
        return u * self.cos_a - v * self.sin_a, u * self.sin_a + v * self.cos_a

    def _layout_roads(self, r):
        """Two families of roads: 'main' along u (centre v = f(u)) and 'cross' along v (centre
        u = g(v)), some cross roads spanning only between two main roads (T-junctions)."""
        look = self.look
        roads = []
        for family, (lo, hi), (alo, ahi) in (("main", self.v_range, self.u_range),
                                             ("cross", self.u_range, self.v_range)):
            # one road near the middle (a main road always; a cross road mostly), the others at
            # a spacing of 45-85 m (main) or 55-110 m (cross) on both sides of it
            spacing = (45.0, 85.0) if family == "main" else (55.0, 110.0)
            middle = (lo + hi) / 2 + r.uniform(-1, 1) * min(15.0, (hi - lo) / 6)
            if family == "cross" and r.random() < 0.3:
                middle += r.uniform(*spacing) / 2
            positions = [middle]
            while positions[-1] < hi - 5.0:
                positions.append(positions[-1] + r.uniform(*spacing))
            while positions[0] > lo + 5.0:
                positions.insert(0, positions[0] - r.uniform(*spacing))
            for pos in positions:
                if not lo - 8.0 < pos < hi + 8.0:
                    continue
                half = r.uniform(2.75, 5.5)
                park = [r.uniform(2.0, 2.5) if r.random() < 0.5 else 0.0 for _ in range(2)]
                walk = [r.uniform(1.5, 4.5) for _ in range(2)]
                roads.append(dict(
                    family=family, pos=pos, amp=r.uniform(0.0, 5.0) if r.random() < 0.6 else 0.0,
                    period=r.uniform(120.0, 300.0), phase=r.uniform(0, 2 * np.pi),
                    half=half, park=park, walk=walk,
                    shade=float(np.clip(look["asphalt"] + r.uniform(-8.0, 8.0), 35.0, 160.0)),
                    kerb=float(np.clip(self.kerb + r.uniform(-0.015, 0.015), 0.08, 0.16)),
                    span=(alo - 50.0, ahi + 50.0)))
        mains = sorted((rd["pos"] for rd in roads if rd["family"] == "main"))
        for rd in roads:   # some cross roads run only between two neighbouring main roads
            if rd["family"] == "cross" and len(mains) >= 2 and r.random() < 0.5:
                i = int(r.integers(0, len(mains) - 1))
                rd["span"] = (mains[i], mains[i + 1])
        self.roads = roads
        # crossings: along-road positions of lowered kerbs (both sides of the road)
        for rd in roads:
            others = [o for o in roads if o["family"] != rd["family"]]
            marks = []
            for o in others:   # crossing on each approach of a junction, 2-6 m back from it
                if rd["family"] == "main":
                    at = o["pos"]
                    inside = o["span"][0] <= rd["pos"] <= o["span"][1] + 1.0
                else:
                    at = o["pos"]
                    inside = rd["span"][0] - 1.0 <= at <= rd["span"][1] + 1.0
                if not inside:
                    continue
                reach = o["half"] + max(o["park"]) + max(o["walk"])
                for sgn in (-1.0, 1.0):
                    if r.random() < 0.8:
                        marks.append(at + sgn * (reach + r.uniform(2.0, 6.0)))
            lo, hi = rd["span"] if rd["family"] == "cross" else self.u_range
            s = lo + r.uniform(20.0, 60.0)
            while s < hi:    # mid-block crossings
                if r.random() < 0.5:
                    marks.append(s)
                s += r.uniform(40.0, 90.0)
            rd["crossings"] = np.array(sorted(marks), dtype=np.float64)
            rd["crossing_half"] = r.uniform(1.2, 2.2)

    # road geometry at points -------------------------------------------------------------
    def _road_frame(self, x, y):
        """Per point: for the nearest road of each family its lateral offset, along-road
        coordinate and index; then the road the point belongs to or is nearest to."""
        u, v = self._uv(x.astype(np.float64), y.astype(np.float64))
        n = len(x)
        best = dict(off=np.full(n, np.inf), along=np.zeros(n), road=np.full(n, -1, np.int64),
                    edge=np.full(n, np.inf), signed=np.zeros(n))
        for index, rd in enumerate(self.roads):
            if rd["family"] == "main":
                along, across = u, v
            else:
                along, across = v, u
            centre = rd["pos"] + rd["amp"] * np.sin(2 * np.pi * along / rd["period"] + rd["phase"])
            slope = rd["amp"] * 2 * np.pi / rd["period"] * np.cos(2 * np.pi * along / rd["period"] + rd["phase"])
            signed = (across - centre) / np.sqrt(1.0 + slope * slope)     # ~perpendicular offset
            lo, hi = rd["span"]
            valid = (along >= lo) & (along <= hi)
            edge_off = rd["half"] + np.where(signed > 0, rd["park"][1], rd["park"][0])
            outside = np.where(valid, np.abs(signed) - edge_off, np.inf)   # > 0 beyond the kerb
            take = outside < best["edge"]
            best["edge"] = np.where(take, outside, best["edge"])
            best["off"] = np.where(take, np.abs(signed), best["off"])
            best["signed"] = np.where(take, signed, best["signed"])
            best["along"] = np.where(take, along, best["along"])
            best["road"] = np.where(take, index, best["road"])
        return best

    def _terrain(self, x, y):
        u, v = self._uv(x, y)
        return (F32(self.z0) + F32(self.grade[0]) * u.astype(F32) + F32(self.grade[1]) * v.astype(F32)
                + F32(self.relief_amp) * self.relief(x, y))

    def _ground(self, x, y, colour=True):
        """Height, class, colour of the ground-level surface (carriageway, sidewalk, lots)."""
        f = self._road_frame(x, y)
        n = len(x)
        roads = self.roads
        ridx = np.maximum(f["road"], 0)
        half = np.array([rd["half"] for rd in roads])[ridx]
        park_l = np.array([rd["park"][0] for rd in roads])[ridx]
        park_r = np.array([rd["park"][1] for rd in roads])[ridx]
        walk_w = np.where(f["signed"] > 0, np.array([rd["walk"][1] for rd in roads])[ridx],
                          np.array([rd["walk"][0] for rd in roads])[ridx])
        e = f["edge"]
        road = e < 0
        walk = ~road & (e < walk_w)
        # lowered kerbs: crossing bands along the road
        lowered = np.zeros(n)
        in_band = np.zeros(n, bool)
        for index, rd in enumerate(roads):
            sel = np.flatnonzero(f["road"] == index)
            if not len(sel) or not len(rd["crossings"]):
                continue
            s = f["along"][sel]
            pos = np.searchsorted(rd["crossings"], s)
            d = np.minimum(np.abs(s - rd["crossings"][np.clip(pos - 1, 0, len(rd["crossings"]) - 1)]),
                           np.abs(s - rd["crossings"][np.clip(pos, 0, len(rd["crossings"]) - 1)]))
            lowered[sel] = smoothstep((rd["crossing_half"] + 0.8 - d) / 0.8)
            in_band[sel] = d < rd["crossing_half"]
        kerb = np.array([rd["kerb"] for rd in roads])[ridx] * (1.0 - 0.88 * lowered)
        T = self._terrain(x, y).astype(np.float64)
        # camber: the surface rises with the distance inside the carriageway from its nearest
        # edge (-e, continuous through junctions of roads of different widths), up to the crown
        camber = self.camber
        z_edge = T - camber * CROWN
        z_road = z_edge + camber * np.minimum(np.maximum(-e, 0.0), CROWN)
        z_walk = z_edge + kerb + 0.015 * np.maximum(e, 0)
        lot_step = 0.03
        z_lot = z_edge + kerb + 0.015 * walk_w + lot_step
        z = np.where(road, z_road, np.where(walk, z_walk, z_lot)).astype(F32)
        if not colour:
            return z
        rng = self.rng_sample
        cls = np.where(road, CLASS_ROAD, CLASS_GROUND).astype(np.uint8)
        shade = np.array([rd["shade"] for rd in roads], dtype=F32)[ridx]
        wear = self.wear_noise(x, y) * F32(self.wear_amp)
        grey = shade + wear
        rgb = np.repeat(grey[:, None], 3, axis=1).astype(F32)
        rgb += np.array([-1.0, 0.0, 2.0], dtype=F32)            # asphalt is slightly bluish
        # repair patches: darker or lighter rectangles of new asphalt
        if self.patches:
            uu, vv = self._uv(x, y)
            for (pu, pv, hu, hv, dg) in self.patches:
                inside = road & (np.abs(uu - pu) < hu) & (np.abs(vv - pv) < hv)
                rgb[inside] += F32(dg)
        # markings: centre line (dashed), lane edge lines at the parking lanes, zebras, stop lines
        off, sgn_off, along = f["off"], f["signed"], f["along"]
        centre = road & (off < 0.075) & ((along % 6.0) < 3.0) & ~in_band
        lane_edge = road & (np.abs(off - half) < 0.07) & ((park_l > 0) | (park_r > 0)) & \
            (np.where(sgn_off > 0, park_r, park_l) > 0)
        zebra = road & in_band & ((off % 1.0) < 0.5) & (off < half)
        white = centre | lane_edge | zebra
        worn = rng.random(n) < 0.15
        yellow_centre = np.array([rd["family"] == "main" and i % 2 == 0 for i, rd in enumerate(roads)])[ridx]
        rgb[white & ~worn] = np.array([222, 222, 216], dtype=F32)
        rgb[centre & yellow_centre & ~worn] = np.array([214, 176, 52], dtype=F32)
        # sidewalks: slabs within a few grey levels of the asphalt, joints, kerb stones
        walk_grey = shade + F32(self.look["sidewalk_offset"]) + wear * F32(0.5)
        walk_rgb = np.repeat(walk_grey[:, None], 3, axis=1).astype(F32) + np.array([1.0, 0.0, -1.0], dtype=F32)
        joint = (np.abs(((along % 1.2) - 0.6)) > 0.57) | (np.abs((e % 1.2) - 0.6) > 0.57)
        walk_rgb[joint] -= F32(9.0)
        stone = walk & (e < 0.15)
        walk_rgb[stone] = np.repeat((shade[stone] + F32(32.0))[:, None], 3, axis=1)
        rgb = np.where(walk[:, None], walk_rgb, rgb)
        # lots: lawn, with paved yards (grey, lot level) where the layout put them
        lot = ~road & ~walk
        gn = self.grass_noise(x, y)
        grass = np.asarray(self.GRASS, dtype=F32) + (gn * F32(10.0))[:, None] \
            + rng.standard_normal((n, 3), dtype=F32) * F32(9.0)
        yard = np.zeros(n, bool)
        yard_grey = np.zeros(n, F32)
        for (cx, cy, hx, hy, g) in self.yards:
            inside = lot & (np.abs(x - cx) < hx) & (np.abs(y - cy) < hy)
            yard |= inside
            yard_grey[inside] = g
        grass[yard] = np.repeat(yard_grey[yard][:, None], 3, axis=1)
        rgb = np.where(lot[:, None], grass, rgb)
        z = z + np.where(lot & ~yard, F32(0.02) * gn + F32(0.012) * rng.standard_normal(n, dtype=F32), F32(0))
        return z, cls, rgb, road

    # lots and objects --------------------------------------------------------------------
    def _layout_lots(self, r, buildings, trees, hedges, yards, beds):
        """Lots on a 16-30 m grid of the scene: whatever part of a lot is off the streets gets a
        building, a yard, trees or a hedge (placement is checked against the road frame)."""
        side = self.side
        self.patches = []
        # repair patches on the carriageways (placed by rejection on road points)
        n_patch = int(r.poisson(side * side / 900.0))
        if n_patch:
            px, py = r.uniform(0, side, n_patch * 4), r.uniform(0, side, n_patch * 4)
            f = self._road_frame(px, py)
            on_road = np.flatnonzero(f["edge"] < -1.0)[:n_patch]
            for i in on_road:
                pu, pv = self._uv(px[i], py[i])
                self.patches.append((float(pu), float(pv), r.uniform(1.0, 4.0), r.uniform(0.8, 2.5),
                                     r.choice([-1.0, 1.0]) * r.uniform(8.0, 18.0)))
        step = r.uniform(14.0, 28.0)
        for gx in np.arange(step / 2, side + step / 2, step):
            for gy in np.arange(step / 2, side + step / 2, step):
                cx, cy = gx + r.uniform(-3, 3), gy + r.uniform(-3, 3)
                f = self._road_frame(np.array([cx]), np.array([cy]))
                rd = self.roads[int(f["road"][0])]
                walk = rd["walk"][1 if f["signed"][0] > 0 else 0]
                room = float(f["edge"][0]) - walk - 0.3    # from the sidewalk's outer edge
                if room < 1.0:
                    continue
                p = r.random()
                if p < 0.4 and room > 3.5:      # some buildings flush with the sidewalk
                    self._building(r, buildings, cx, cy, min(room, step / 2 - 1.0))
                elif p < 0.55 and room > 2.0:
                    h = min(room, step / 2) * r.uniform(0.5, 0.9)
                    yards.append((cx, cy, h, h * r.uniform(0.5, 1.0), float(r.uniform(95, 165))))
                elif p < 0.75:
                    for _ in range(int(r.integers(1, 3))):
                        self._tree(r, trees, cx + r.uniform(-4, 4), cy + r.uniform(-4, 4))
                elif p < 0.85:
                    R, h = r.uniform(0.8, 1.5), r.uniform(1.0, 2.2)
                    g = self._ground_height(cx, cy)
                    hedges.append(dict(cx=cx, cy=cy, ground=g, cz=g + h / 2, R=R, rz=h / 2, trunk=0.0,
                                       rgb=r.uniform([40, 70, 30], [70, 100, 50])))
                else:
                    hx, hy = min(r.uniform(1.0, 3.5), room), min(r.uniform(0.6, 1.5), room)
                    beds.append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ground=float(self._ground_height(cx, cy)),
                                     h=r.uniform(0.15, 0.45)))

    def _building(self, r, buildings, cx, cy, room):
        # half-diagonal <= room: the footprint stays off every sidewalk whatever its angle
        w, d = (min(r.uniform(6.0, max(6.5, 1.41 * room)), 1.41 * room) for _ in range(2))
        ang = self.ang + (np.pi / 2 if r.random() < 0.5 else 0.0) + r.normal(0, 0.05)
        hx, hy = max(w, d) / 2, min(w, d) / 2
        base = float(self._ground_height(cx, cy)) - 0.05
        if r.random() < 0.5:
            top = base + r.uniform(3.0, 18.0)
            buildings.append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=base, eave=top, ridge=top, roof=0,
                                  roof_rgb=_FLAT_ROOF_COLOURS[r.integers(0, len(_FLAT_ROOF_COLOURS))],
                                  wall_rgb=_WALL_COLOURS[r.integers(0, len(_WALL_COLOURS))]))
        else:
            eave = base + r.uniform(3.0, 9.0)
            rise = hy * math.tan(math.radians(r.uniform(25, 42)))
            buildings.append(dict(cx=cx, cy=cy, hx=hx, hy=hy, ang=ang, base=base, eave=eave, ridge=eave + rise,
                                  roof=int(r.choice([1, 2])),
                                  roof_rgb=_PITCHED_ROOF_COLOURS[r.integers(0, len(_PITCHED_ROOF_COLOURS))],
                                  wall_rgb=_WALL_COLOURS[r.integers(0, len(_WALL_COLOURS))]))

    def _tree(self, r, trees, x, y, street=False):
        if not (-3 <= x <= self.side + 3 and -3 <= y <= self.side + 3):
            return
        R = r.uniform(2.5, 5.0) if street else r.uniform(2.0, 4.5)
        rz = R * r.uniform(0.7, 1.0)
        trunk = r.uniform(2.8, 5.0)
        g = float(self._ground_height(x, y))
        trees.append(dict(cx=x, cy=y, ground=g, cz=g + trunk + rz, R=R, rz=rz, trunk=trunk,
                          rgb=r.uniform([45, 80, 30], [85, 120, 60])))

    def _layout_street_objects(self, r, trees, cars, poles):
        """Along every road: street trees at the sidewalk's outer edge (crowns over the road),
        parked cars in the parking lanes, a few cars in the travel lanes, lamp posts."""
        look = self.look
        for index, rd in enumerate(self.roads):
            lo, hi = self._extent(rd)
            for side_i, sgn in enumerate((-1.0, 1.0)):
                park = rd["park"][side_i]
                edge = rd["half"] + park
                if r.random() < 0.6:                          # street trees on this side
                    gap = r.uniform(8.0, 16.0)
                    for s in np.arange(lo + r.uniform(2.0, 10.0), hi, gap):
                        at = self._road_xy(rd, s, sgn * (edge + rd["walk"][side_i] * r.uniform(0.5, 0.9)))
                        if at is not None and self._off_roads(*at):
                            self._tree(r, trees, *at, street=True)
                if park > 0:                                   # parked cars
                    s = lo + r.uniform(0.0, 5.0)
                    while s < hi:
                        L = r.uniform(3.9, 4.9)
                        if r.random() < look["parking_occupancy"]:
                            at = self._road_xy(rd, s + L / 2, sgn * (rd["half"] + park / 2))
                            if at is not None and self._on_road(index, *at):
                                self._car(r, cars, rd, *at, L / 2)
                        s += L + r.uniform(0.6, 3.0)
                for s in np.arange(lo + r.uniform(5.0, 25.0), hi, r.uniform(20.0, 35.0)):   # lamp posts
                    at = self._road_xy(rd, s, sgn * (edge + rd["walk"][side_i] - 0.4))
                    if at is not None and self._off_roads(*at):
                        poles.append(dict(x=at[0], y=at[1], ground=float(self._ground_height(*at)),
                                          h=r.uniform(6, 9)))
            s = lo + r.uniform(5.0, 40.0)
            while s < hi:                                         # cars in the travel lanes
                if r.random() < 0.5:
                    L = r.uniform(4.0, 4.8)
                    at = self._road_xy(rd, s, r.choice([-1.0, 1.0]) * rd["half"] * r.uniform(0.35, 0.65))
                    if at is not None and self._on_road(index, *at):
                        self._car(r, cars, rd, *at, L / 2)
                s += r.uniform(25.0, 70.0)

    def _extent(self, rd):
        """Along-road range of road rd inside the scene's rotated extent."""
        lo, hi = self.u_range if rd["family"] == "main" else self.v_range
        return max(lo, rd["span"][0]), min(hi, rd["span"][1])

    def _road_xy(self, rd, along, offset):
        """x, y of along-road coordinate ``along`` and lateral ``offset`` on road rd (arrays or
        scalars); scalars give None off the scene."""
        centre = rd["pos"] + rd["amp"] * np.sin(2 * np.pi * np.asarray(along) / rd["period"] + rd["phase"])
        u, v = (along, centre + offset) if rd["family"] == "main" else (centre + offset, along)
        x, y = self._xy(u, v)
        if np.ndim(x):
            return x, y
        if -2 <= x <= self.side + 2 and -2 <= y <= self.side + 2:
            return float(x), float(y)
        return None

    def _off_roads(self, x, y):
        return float(self._road_frame(np.array([x]), np.array([y]))["edge"][0]) > 0.3

    def _on_road(self, index, x, y):
        f = self._road_frame(np.array([x]), np.array([y]))
        return int(f["road"][0]) == index and float(f["edge"][0]) < -0.9

    def _car(self, r, cars, rd, x, y, hl):
        hw = r.uniform(0.85, 0.95)
        g = float(self._ground_height(x, y))
        h = r.uniform(1.4, 1.7)
        # direction of the road at the car: the frame angle (+90 degrees for cross roads)
        ang = self.ang + (np.pi / 2 if rd["family"] == "cross" else 0.0)
        cars.append(dict(cx=x, cy=y, hx=hl, hy=hw, ang=ang, base=g, eave=g + h, ridge=g + h, roof=0,
                         roof_rgb=_CAR_COLOURS[r.integers(0, len(_CAR_COLOURS))], wall_rgb=np.zeros(3)))

    # ---------------------------------------------------------------- shadows and density
    def _build_shadow_raster(self):
        ras = Raster(self.side, 0.5)
        ground = self._ground(ras.xc.ravel(), ras.yc.ravel(), colour=False).reshape(ras.xc.shape)
        top = top_surface(ras, ground, (self.buildings, self.cars), (self.trees, self.hedges))
        self.shadow_raster = ras
        self.shadow = shadow_height(top, ras.cell, self.sun_az, self.sun_tan)

    def _density(self, x, y):
        # 0.4..1.0 of the densest: +-40 % around the mean density, over ~35 m
        return F32(0.7) + F32(0.3) * np.tanh(self.density_noise(x, y))

    # ---------------------------------------------------------------- sampling
    def _emit_all(self, rho):
        for x, y in self._ground_candidates(rho):
            z, cls, rgb, _ = self._ground(x, y)
            self._emit(x, y, z, rgb, cls)
        self._emit_kerbs(rho)
        self._emit_boxes(self.buildings, rho, wall_factor=0.35, cls=CLASS_BUILDING, windows=True)
        self._emit_boxes(self.cars, rho, wall_factor=0.5, cls=CLASS_OTHER, windows=False)
        self._emit_crowns(self.trees, rho, CLASS_HIGH_VEG, colour_sigma=16.0, trunk=True)
        self._emit_crowns(self.hedges, rho, CLASS_MED_VEG, colour_sigma=14.0, trunk=False)
        self._emit_beds(rho)
        self._emit_poles(rho)

    def _emit_kerbs(self, rho):
        """The vertical kerb faces along every road edge (a nadir camera sees them obliquely),
        where the edge is a kerb: not inside another road (junctions)."""
        rng = self.rng_sample
        for index, rd in enumerate(self.roads):
            lo, hi = self._extent(rd)
            if hi <= lo:
                continue
            for side_i, sgn in enumerate((-1.0, 1.0)):
                count = int(integer_counts(rng, (hi - lo) * rd["kerb"] * rho * 0.6))
                along = lo + rng.random(count) * (hi - lo)
                offset = sgn * (rd["half"] + rd["park"][side_i] + rng.random(count) * 0.02)
                x, y = self._road_xy(rd, along, offset)
                x, y = x.astype(F32), y.astype(F32)
                inside = (x >= 0) & (x <= self.side) & (y >= 0) & (y <= self.side)
                x, y = x[inside], y[inside]
                f = self._road_frame(x, y)
                k = (f["road"] == index) & (f["edge"] >= -0.005) & self._keep(x, y)
                x, y = x[k], y[k]
                if not len(x):
                    continue
                z_top = self._ground(x, y, colour=False)
                z = z_top - rng.random(len(x), dtype=F32) * F32(rd["kerb"])
                rgb = noisy_colour(np.full(3, rd["shade"] + 32.0, F32), len(x), rng, 5.0)
                self._emit(x, y, z, rgb, CLASS_GROUND)

    def _emit_poles(self, rho):
        p = self.poles
        if p.n == 0:
            return
        rng = self.rng_sample
        idx = repeat_index(integer_counts(rng, (2 * np.pi * 0.09 * p.h * 0.5 + 1.0) * rho))
        n = len(idx)
        a = rng.random(n, dtype=F32) * F32(2 * np.pi)
        head = rng.random(n) < 1.0 / (2 * np.pi * 0.09 * p.h[idx] * 0.5 + 1.0)
        x = p.x[idx].astype(F32) + np.where(head, rng.uniform(-0.3, 0.3, n).astype(F32), F32(0.09) * np.cos(a))
        y = p.y[idx].astype(F32) + np.where(head, rng.uniform(-0.3, 0.3, n).astype(F32), F32(0.09) * np.sin(a))
        z = (p.ground[idx] + np.where(head, p.h[idx], rng.random(n) * p.h[idx])).astype(F32)
        k = self._keep(x, y)
        self._emit(x[k], y[k], z[k], noisy_colour((112, 114, 118), int(k.sum()), rng, 6.0), CLASS_OTHER)

    def _finish(self, xyz, rgb, inten, cls):
        rng = self.rng_noise
        n = len(xyz)
        look = self.look
        row, col = self.shadow_raster.index(xyz[:, 0], xyz[:, 1])
        shade = xyz[:, 2] < self.shadow[row, col] - F32(0.15)
        f = F32(1.0 - look["shadow_factor"])
        rgb[shade] *= np.array([f * 0.95, f, f * 1.12], dtype=F32)
        sigma = F32(look["height_noise"]) * (F32(1.0) + F32(0.3) * np.tanh(self.sigma_noise(xyz[:, 0], xyz[:, 1])))
        xyz[:, 2] += rng.standard_normal(n, dtype=F32) * sigma
        xyz[:, :2] += rng.standard_normal((n, 2), dtype=F32) * (sigma * F32(0.5))[:, None]
        c = F32(look["colour_noise"])
        rgb += rng.standard_normal((n, 3), dtype=F32) * c
        rgb += (rng.standard_normal(n, dtype=F32) * c * F32(0.8))[:, None]
        np.clip(rgb, 0, 255, out=rgb)
        return xyz, rgb, inten, cls

