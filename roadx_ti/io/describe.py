"""What a user checks first about a point cloud, gathered chunk by chunk for ``info``: point
density and spacing over occupied cells (roadx_ti.footprint), which of colour / intensity / NIR /
return numbers are present and whether their values vary, the classes with their ASPRS names;
and the same as text for a person (``info --text``)."""
from __future__ import annotations

import math

import numpy as np

from ..footprint import Occupancy

# ASPRS LAS 1.4 standard classes (R15)
ASPRS_CLASSES = {0: "never classified", 1: "unclassified", 2: "ground", 3: "low vegetation",
                 4: "medium vegetation", 5: "high vegetation", 6: "building", 7: "low point (noise)",
                 8: "model key-point", 9: "water", 10: "rail", 11: "road surface", 12: "overlap",
                 13: "wire guard", 14: "wire conductor", 15: "transmission tower", 16: "wire connector",
                 17: "bridge deck", 18: "high noise", 19: "overhead structure", 20: "ignored ground",
                 21: "snow", 22: "temporal exclusion"}       # LAS 1.4 R15
FIELDS = ("rgb", "intensity", "nir", "return_number", "number_of_returns")


class Survey:
    """Accumulates the facts of ``add``ed chunks (world xy, per-point fields by name)."""

    def __init__(self, present=()):
        self.present = set(present)       # fields the format has, even if every value is zero
        self.occupancy = Occupancy()
        self.ranges: dict[str, list] = {}
        self.multi_return = 0

    def add(self, xy: np.ndarray, fields: dict) -> None:
        self.occupancy.add(xy)
        for name, values in fields.items():
            if values is None or len(values) == 0:
                continue
            self.present.add(name)
            lo, hi = int(np.min(values)), int(np.max(values))
            old = self.ranges.get(name)
            self.ranges[name] = [lo, hi] if old is None else [min(old[0], lo), max(old[1], hi)]
        count = fields.get("number_of_returns")
        if count is not None:
            self.multi_return += int(np.count_nonzero(np.asarray(count) > 1))

    def facts(self, point_count: int) -> dict:
        d = self.occupancy.density()
        out = {"point_density": _finite(d["density"]), "point_spacing": _finite(d["spacing"]),
               "occupied_area": _finite(d["occupied_area"]), "density_cell": d["cell"],
               "density_method": "points per occupied cell area (cells of density_cell map units, "
                                 "doubled until they hold 4 points on average)"}
        fields = {}
        for name in FIELDS:
            lo_hi = self.ranges.get(name)
            fields[name] = {"present": name in self.present,
                            "varies": bool(lo_hi is not None and lo_hi[0] != lo_hi[1]),
                            "min": lo_hi[0] if lo_hi else None, "max": lo_hi[1] if lo_hi else None}
        fields["return_number"]["multiple_returns"] = self.multi_return if "number_of_returns" in self.present else None
        out["fields"] = fields
        return out


def _finite(v):
    return float(v) if v is not None and math.isfinite(v) else None


def classes(histogram: dict) -> list[dict]:
    """[{'class', 'name', 'points'}] of a {class: count} histogram."""
    return [{"class": int(c), "name": ASPRS_CLASSES.get(int(c), "user defined" if int(c) >= 64 else "reserved"),
             "points": int(k)} for c, k in sorted(histogram.items())]


def _field_text(f: dict) -> str:
    if not f["present"]:
        return "absent"
    if f["min"] is None:
        return "present, no points"
    if not f["varies"]:
        return "present, all zero (no data)" if f["min"] == 0 else f"present, every value {f['min']}"
    return f"present, {f['min']} .. {f['max']}"


def text(info: dict) -> str:
    """``info``'s dict as lines for a person (a file that could not be read: its error)."""
    if "error" in info:
        return f"file   {info['path']}\nerror  {info['error']}"
    rows = [("file", info["path"])]
    fmt = info["format"]
    if info.get("point_format") is not None:
        fmt += f" (LAS {info['version']}, point format {info['point_format']})"
    rows += [("format", fmt), ("points", f"{info['point_count']:,}"),
             ("CRS", info.get("crs") or "none (the file names no coordinate reference system)")]
    if info.get("bounds"):
        lo, hi = info["bounds"]["min"], info["bounds"]["max"]
        rows.append(("bounds", "  ".join(f"{a} {lo[k]:.2f} .. {hi[k]:.2f}" for k, a in enumerate("xyz"))))
    if info.get("point_density") is not None:
        rows.append(("density", f"{info['point_density']:.3g} points per m2 over {info['occupied_area']:,.0f} m2 "
                                f"of occupied {info['density_cell']:g} m cells; spacing {info['point_spacing']:.3g} m"))
    f = info["fields"]
    colour = info.get("color", "none")
    rows.append(("colour", {"none": "absent", "all-zero": "RGB fields present, all zero (no colour)"}.get(
        colour, f"RGB {colour}, {f['rgb']['min']} .. {f['rgb']['max']}")))
    rows += [("intensity", _field_text(f["intensity"])), ("NIR", _field_text(f["nir"]))]
    r = f["return_number"]
    if r["present"] and r["max"]:
        multi = r.get("multiple_returns")
        share = f", {100 * multi / info['point_count']:.1f} % of points in pulses of several returns" \
            if multi is not None and info["point_count"] else ""
        rows.append(("returns", f"return numbers {r['min']} .. {r['max']}{share}"))
    else:
        rows.append(("returns", "absent" if not r["present"] else "present, all zero"))
    rows.append(("classes", "; ".join(f"{c['class']} {c['name']}: {c['points']:,}" for c in info["classes"])
                 or "none"))
    if info.get("extra_dimensions"):
        rows.append(("extra dims", ", ".join(info["extra_dimensions"])))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k.ljust(width)}  {v}" for k, v in rows)
