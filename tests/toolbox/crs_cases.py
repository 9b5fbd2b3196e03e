"""Shared by the tests of one CRS under two definitions: the ESRI WKT of EPSG:6707, a GeoTIFF
writer, and a one-photo orientation project in EPSG:6707."""

from __future__ import annotations

import warnings

import numpy as np
import rasterio
import yaml

ESRI_6707 = (  # gdalsrsinfo --single-line -o wkt_esri EPSG:6707 (GDAL 3.6.2)
    'PROJCS["RDN2008_TM32",GEOGCS["GCS_RDN2008",DATUM["D_Rete_Dinamica_Nazionale_2008",'
    'SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],'
    'UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],'
    'PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],'
    'PARAMETER["Central_Meridian",9.0],PARAMETER["Scale_Factor",0.9996],'
    'PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]')


def write_raster(path, data, crs, transform, nodata=None):
    """A GeoTIFF of ``data`` ((rows, cols) or (bands, rows, cols)) labelled ``crs`` (any
    definition rasterio takes, or None)."""
    data = np.asarray(data)
    data = data[None] if data.ndim == 2 else data
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                           count=data.shape[0], dtype=data.dtype, crs=crs, transform=transform,
                           nodata=nodata) as dst:
            dst.write(data)
    return path


def write_one_photo_project(folder, n: int, exterior: tuple) -> None:
    """``folder/project.yaml``: photo ``p1`` (``p1.tif``, n x n pixels) of a 153 mm camera with
    a 230 mm frame, at ``exterior`` (X0, Y0, Z0 m; omega, phi, kappa rad), in EPSG:6707."""
    camera = {"name": "c", "principal_distance_mm": 153.0, "image_size_px": [n, n],
              "pixel_size_mm": 230.0 / n, "frame_size_mm": [230.0, 230.0]}
    names = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    (folder / "project.yaml").write_text(yaml.safe_dump({
        "format": "orientation-project", "version": 1, "crs": "EPSG:6707", "angle_unit": "rad",
        "cameras": [camera], "photos": [{"id": "p1", "camera": "c", "image": "p1.tif",
                                         "exterior": dict(zip(names, exterior, strict=True))}]},
        sort_keys=False))
