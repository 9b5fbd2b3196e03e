"""Terrain derivatives of a DEM with Horn's 3x3 weights: slope, aspect and shaded relief.

Kernels are arrays in, arrays out: each takes a ``(rows+2, cols+2)`` array (the cells to compute
plus a one-cell halo) and returns ``(rows, cols)``. Rows go north to south, columns west to east;
NaN cells give NaN. The formulas are those of ``gdaldem`` (Horn 1981):

    dz/dx = ((c + 2f + i) - (a + 2d + g)) / (8 cell_x)      eastward
    dz/dy = ((a + 2b + c) - (g + 2h + i)) / (8 cell_y)      northward

for the window ``a b c / d e f / g h i``. :func:`shade_raster` runs a kernel over a GeoTIFF in
tiles with that halo, so any size works in bounded memory.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

ASPECT_FLAT = -9999.0  # aspect of a flat cell (no downslope direction), as gdaldem


def horn_gradient(z: np.ndarray, cell_x: float, cell_y: float,
                  z_factor: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(dz/dx eastward, dz/dy northward) of the inner cells of a padded array, Horn's weights."""
    zz = z * z_factor
    a, b, c = zz[:-2, :-2], zz[:-2, 1:-1], zz[:-2, 2:]
    d, f = zz[1:-1, :-2], zz[1:-1, 2:]
    g, h, i = zz[2:, :-2], zz[2:, 1:-1], zz[2:, 2:]
    dz_dx = ((c + 2 * f + i) - (a + 2 * d + g)) / (8.0 * cell_x)
    dz_dy = ((a + 2 * b + c) - (g + 2 * h + i)) / (8.0 * cell_y)
    return dz_dx, dz_dy


def slope(z: np.ndarray, cell_x: float, cell_y: float, z_factor: float = 1.0,
          units: str = "degrees") -> np.ndarray:
    """Steepest slope of the inner cells: ``atan(|grad z|)`` in degrees, or ``100·|grad z|`` in
    percent (``units="percent"``)."""
    dz_dx, dz_dy = horn_gradient(z, cell_x, cell_y, z_factor)
    rise = np.hypot(dz_dx, dz_dy)
    if units == "percent":
        return 100.0 * rise
    if units != "degrees":
        raise ValueError(f"units must be 'degrees' or 'percent', got {units!r}")
    return np.degrees(np.arctan(rise))


def aspect(z: np.ndarray, cell_x: float, cell_y: float) -> np.ndarray:
    """Direction the slope faces (downhill), degrees clockwise from north in [0, 360);
    :data:`ASPECT_FLAT` where the gradient is zero."""
    dz_dx, dz_dy = horn_gradient(z, cell_x, cell_y)
    out = np.degrees(np.arctan2(-dz_dx, -dz_dy)) % 360.0
    out[(dz_dx == 0) & (dz_dy == 0)] = ASPECT_FLAT
    return out


def hillshade(z: np.ndarray, cell_x: float, cell_y: float, azimuth: float = 315.0,
              altitude: float = 45.0, z_factor: float = 1.0) -> np.ndarray:
    """Illumination in [0, 1] of the inner cells of ``z`` (Lambert's cosine law).

    ``azimuth`` is the sun's direction clockwise from north and ``altitude`` its height above
    the horizon, both in degrees.
    """
    dz_dx, dz_dy = horn_gradient(z, cell_x, cell_y, z_factor)
    zenith = np.radians(90.0 - altitude)
    az = np.radians(azimuth)
    # unit normal (-dz/dx, -dz/dy, 1)/n; sun direction (sin az cos alt, cos az cos alt, sin alt)
    norm = np.sqrt(1.0 + dz_dx**2 + dz_dy**2)
    shade = (np.cos(zenith) - np.sin(zenith) * (dz_dx * np.sin(az) + dz_dy * np.cos(az))) / norm
    return np.clip(shade, 0.0, 1.0)


def hillshade_byte(shade: np.ndarray) -> np.ndarray:
    """Illumination [0, 1] as Byte: 1 (dark) to 255 (lit), 0 for NaN (nodata)."""
    return np.where(np.isnan(shade), 0, 1 + np.round(np.nan_to_num(shade) * 254)).astype("uint8")


def pad_to_halo(z: np.ndarray, tile) -> np.ndarray:
    """Give ``z`` (read over ``tile.padded``) a full one-cell halo around ``tile.core``.

    Where the raster ends the surface is extrapolated linearly (``2·edge - inner``), exact on
    planes; a one-cell-wide raster repeats its edge.
    """
    core, padded = tile.core, tile.padded
    top = 1 - (core.row_off - padded.row_off)
    left = 1 - (core.col_off - padded.col_off)
    bottom = 1 - ((padded.row_off + padded.height) - (core.row_off + core.height))
    right = 1 - ((padded.col_off + padded.width) - (core.col_off + core.width))
    if min(z.shape) < 2:
        return np.pad(z, ((top, bottom), (left, right)), mode="edge")
    return np.pad(z, ((top, bottom), (left, right)), mode="reflect", reflect_type="odd")


def shade_raster(info, band: int, output: str | Path,
                 kernel: Callable[[np.ndarray, float, float], np.ndarray], dtype: str,
                 nodata: float, feedback, tile_size: int = 512, overviews: bool = True) -> dict:
    """Run a 3x3 ``kernel(z_padded, cell_x, cell_y) -> values`` over a DEM in tiles.

    ``info`` is a :class:`~toolbox.io.raster.RasterInfo`; DEM nodata becomes NaN before the
    kernel (so cells next to nodata are nodata) and NaN results become ``nodata``. Returns
    counts of valid and nodata cells.
    """
    import rasterio

    from toolbox.io.raster import build_overviews, geotiff_profile, iter_windows

    cell_x, cell_y = info.res
    tiles = list(iter_windows(info.width, info.height, tile_size, halo=1))
    profile = geotiff_profile(info.width, info.height, 1, dtype, info.crs, info.transform,
                              nodata=nodata)
    valid = 0
    with rasterio.Env(COMPRESS_OVERVIEW="DEFLATE"), rasterio.open(info.path) as src, \
            rasterio.open(output, "w", **profile) as dst:
        for tile in feedback.iterate(tiles, start=0, end=95):
            z = src.read(band, window=tile.padded, masked=True)
            z = pad_to_halo(z.astype("float64").filled(np.nan), tile)
            values = kernel(z, cell_x, cell_y)
            if np.dtype(dtype).kind == "f":
                good = np.isfinite(values)
                values = np.where(good, values, nodata).astype(dtype)
            else:
                good = values != nodata
            valid += int(good.sum())
            dst.write(values, 1, window=tile.core)
        if overviews:
            build_overviews(dst)
    return {"cells": info.width * info.height, "valid_cells": valid,
            "nodata_cells": info.width * info.height - valid, "tiles": len(tiles)}


def check_dem_params(params: dict) -> None:
    """``BAND`` within the bands of the DEM ``INPUT``, and the DEM georeferenced (the kernels
    need its cell size)."""
    from toolbox.errors import InputDataError, ParameterError

    info = params["INPUT"]
    if params["BAND"] > info.count:
        raise ParameterError("BAND", f"must be <= {info.count} (bands of {info}), got "
                             f"{params['BAND']}")
    if not info.georeferenced:
        raise InputDataError(f"INPUT {info} has no georeferencing: cell size unknown")
