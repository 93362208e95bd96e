"""Length units of a survey: every length of the configs is in metres, so a survey whose CRS
counts in feet (US State Plane surveys: EPSG:2263 and the like, often with NAVD88 heights in
feet) runs in metres and is written back in its own units.

``metre_factors(crs)`` reads the CRS (a rasterio CRS) for the metres per unit of its horizontal
axes and of its heights (the vertical CRS's unit in a compound CRS; without one, heights count in
the horizontal unit, as LAS files in feet do). ``in_metres(cloud, factors)`` is the cloud the
stages see (coordinates and origin scaled; the records, and so the file written, are untouched);
``surface_in_units`` takes a ground surface back to the file's units for the DTM export.
A geographic CRS (degrees) with coordinates that are degrees has no metric run: InputError.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

_UNIT = re.compile(r'(?:LENGTHUNIT|UNIT)\["([^"]+)",\s*([0-9.eE+-]+)')
_VERTICAL = re.compile(r"VERT_CS\[|VERTCRS\[|VERTICALCRS\[")


@dataclass(frozen=True)
class Factors:
    horizontal: float     # metres per unit of x and y
    vertical: float       # metres per unit of z
    name: str             # the horizontal unit's name, for messages

    @property
    def metric(self) -> bool:
        return self.horizontal == 1.0 and self.vertical == 1.0

    @property
    def xyz(self) -> np.ndarray:
        return np.array([self.horizontal, self.horizontal, self.vertical])


METRES = Factors(1.0, 1.0, "metre")
# per-point outputs that are lengths (Stage.writes): written back in the file's height unit
LENGTH_DIMS = ("height_above_ground",)


def metre_factors(crs) -> Factors:
    """Factors of ``crs`` (a rasterio CRS or None; None, geographic or unreadable: METRES, the
    caller checks degrees with ``geographic_problem``)."""
    if crs is None or not crs.is_projected:
        return METRES
    name, horizontal = crs.linear_units_factor
    horizontal = float(horizontal)
    vertical = horizontal
    wkt = crs.to_wkt()
    found = _VERTICAL.search(wkt)
    if found:
        unit = _UNIT.search(wkt, found.end())
        if unit:
            vertical = float(unit.group(2))
    # units within a part per million of the metre are the metre (a WKT's rounding)
    horizontal = 1.0 if abs(horizontal - 1.0) < 1e-6 else horizontal
    vertical = 1.0 if abs(vertical - 1.0) < 1e-6 else vertical
    return Factors(horizontal, vertical, str(name))


def geographic_problem(crs, lon_reach: float, lat_reach: float) -> str | None:
    """Why a survey whose CRS ``crs`` is geographic cannot run, its x / y reaching ``lon_reach`` /
    ``lat_reach`` (largest absolute values): degrees (the stages' lengths are metres), or a
    geographic record over projected coordinates (a DTM of impossible longitudes / latitudes);
    None for a projected CRS or none. One text for the untiled run and the catalog check."""
    if crs is None or not crs.is_geographic:
        return None
    if lon_reach <= 360.0 and lat_reach <= 90.0:
        return (f"coordinates are longitude / latitude degrees ({crs.to_string()}); the stages' lengths are "
                "metres: reproject it to a projected CRS first, e.g. pdal translate IN OUT reprojection "
                "--filters.reprojection.out_srs=EPSG:<UTM zone>")
    return (f"its CRS is geographic ({crs.to_string()}), but its coordinates are not longitude / latitude degrees "
            "(beyond +-360 / +-90): the CRS record is wrong; set the right one first, e.g. pdal translate IN OUT "
            "--writers.las.a_srs=EPSG:<code>")


def looks_like_degrees(cloud) -> bool:
    """True for a cloud with no CRS whose x and y read as longitude / latitude: all within
    +-180 / +-90, spanning under half a unit in plan (55 km in degrees, 0.5 m in metres) while its
    heights span 20 times more (a street or a roof in metres spans more than 0.5 m)."""
    if cloud.n < 2:
        return False
    world = cloud.xyz[:, :2].astype(np.float64) + cloud.origin[:2]
    if not (np.all(np.abs(world[:, 0]) <= 180.0) and np.all(np.abs(world[:, 1]) <= 90.0)):
        return False
    plan = float(np.ptp(world, axis=0).max())
    return 0 < plan < 0.5 and float(np.ptp(cloud.xyz[:, 2])) > 20 * plan


def in_metres(cloud, factors: Factors):
    """``cloud`` with coordinates and origin in metres (a new Cloud sharing every other array;
    the same cloud when the factors are metres)."""
    if factors.metric:
        return cloud
    scale = factors.xyz
    return replace(cloud, xyz=(cloud.xyz.astype(np.float64) * scale).astype(np.float32),
                   origin=cloud.origin * scale)


def surface_in_units(surface, factors: Factors):
    """A GroundSurface (stages.base) made in metres, back in the file's units (grids scaled)."""
    if factors.metric:
        return surface
    h, v = factors.horizontal, factors.vertical

    def grid(g):
        return replace(g, cloth_z=(g.cloth_z.astype(np.float64) / v).astype(np.float32), x0=g.x0 / h,
                       y0=g.y0 / h, resolution=g.resolution / h)

    parts = [grid(g) for g in surface.parts]
    largest = next((p for p, g in zip(parts, surface.parts) if g is surface.largest), grid(surface.largest))
    return replace(surface, largest=largest, origin=surface.origin / factors.xyz, parts=parts)
