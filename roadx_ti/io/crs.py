"""The CRS of a cloud read from LAS, as a rasterio CRS (rasterio bundles GDAL and PROJ): the WKT
record as it is, or the EPSG codes of the GeoTIFF keys (horizontal, + vertical when present)."""
from __future__ import annotations

import logging

from roadx_ti.quiet_logs import quieted

from .las import crs_records

log = logging.getLogger(__name__)


def of_header(header):
    """rasterio CRS of a LAS header, or None when it has no (usable) CRS record."""
    wkt, codes = crs_records(header)
    if not wkt and not codes:
        return None             # before importing rasterio (GDAL, PROJ): 0.2 s of every such run
    import rasterio
    from rasterio.crs import CRS
    from rasterio.errors import CRSError

    try:
        # inside an Env, GDAL's own message ('ERROR 1: missing [') goes to Python logging, quiet
        # here, instead of straight to stderr beside the one warning below
        with rasterio.Env(), quieted(["rasterio._err"], logging.CRITICAL):
            if wkt:
                return CRS.from_wkt(wkt)
            return CRS.from_user_input("+".join(f"EPSG:{c}" for c in codes) if len(codes) > 1
                                       else f"EPSG:{codes[0]}")
    except CRSError as exc:
        log.warning("the input's CRS record cannot be read (%s); it is left out of the outputs",
                    " ".join(str(exc).split()))
    return None


def of_path(path):
    """rasterio CRS of a LAS/LAZ file's header, or None."""
    import laspy
    with laspy.open(path) as reader:
        return of_header(reader.header)


def of_cloud(cloud):
    """rasterio CRS of a cloud (LAS input only), or None."""
    if cloud.las is not None:
        return of_header(cloud.las.header)
    if cloud.records_file:
        return of_path(cloud.records_file)
    return None
