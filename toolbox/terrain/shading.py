"""Terrain derivatives of a DEM with Horn's 3x3 weights: slope, aspect and shaded relief.

Kernels are arrays in, arrays out: each takes a ``(rows+2, cols+2)`` array (the cells to compute
plus a one-cell halo) and returns ``(rows, cols)``. Rows go north to south, columns west to east
for positive ``cell_x``, ``cell_y``; a raster running the other way passes them negative
(:func:`signed_cell`: a south-up DEM has ``cell_y < 0``). NaN cells give NaN. The formulas
are those of ``gdaldem`` (Horn 1981):

    dz/dx = ((c + 2f + i) - (a + 2d + g)) / (8 cell_x)      eastward
    dz/dy = ((a + 2b + c) - (g + 2h + i)) / (8 cell_y)      northward

for the window ``a b c / d e f / g h i``. :func:`shade_raster` runs a kernel over a GeoTIFF on the
shared raster engine (tiles with that halo), so any size works in bounded memory.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

ASPECT_FLAT = -9999.0  # aspect of a flat cell (no downslope direction), as gdaldem


def horn_gradient(z: np.ndarray, cell_x: float, cell_y: float,
                  z_factor: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(dz/dx eastward, dz/dy northward), float64, of the inner cells of a padded array (any
    float dtype), Horn's weights.

    Horn's 3x3 weights are separable: a [1 2 1] smoothing across the difference direction,
    then a central difference, ``(c + 2f + i) - (a + 2d + g)`` = ``v[j+1] - v[j-1]`` with
    ``v = 2·row + above + below`` (the same sums in the same order as written out). The
    centre cell ``e`` has no weight, but a NaN centre makes its cell NaN (a nodata cell has no
    slope, as in gdaldem).
    """
    v = np.multiply(z[1:-1], 2.0, dtype=np.float64)  # (rows, cols + 2): 2d + a + g, ...
    v += z[:-2]
    v += z[2:]
    dz_dx = v[:, 2:] - v[:, :-2]
    dz_dx *= z_factor / (8.0 * cell_x)
    u = np.multiply(z[:, 1:-1], 2.0, dtype=np.float64)  # (rows + 2, cols): 2b + a + c, ...
    u += z[:, :-2]
    u += z[:, 2:]
    dz_dy = u[:-2] - u[2:]
    dz_dy *= z_factor / (8.0 * cell_y)
    hole = np.isnan(z[1:-1, 1:-1])
    if hole.any():
        dz_dx[hole] = np.nan
        dz_dy[hole] = np.nan
    return dz_dx, dz_dy


def slope(z: np.ndarray, cell_x: float, cell_y: float, z_factor: float = 1.0,
          units: str = "degrees") -> np.ndarray:
    """Steepest slope of the inner cells, float32: ``atan(|grad z|)`` in degrees, or
    ``100·|grad z|`` in percent (``units="percent"``)."""
    if units not in ("degrees", "percent"):
        raise ValueError(f"units must be 'degrees' or 'percent', got {units!r}")
    dz_dx, dz_dy = horn_gradient(z, cell_x, cell_y, z_factor)
    rise = np.multiply(dz_dx, dz_dx, out=dz_dx)  # |grad z| (np.hypot is ~10x slower)
    rise += np.square(dz_dy, out=dz_dy)
    np.sqrt(rise, out=rise)
    out = np.empty(rise.shape, np.float32)
    if units == "percent":
        return np.multiply(rise, 100.0, out=out)
    return np.degrees(np.arctan(rise, out=rise), out=out)


def aspect(z: np.ndarray, cell_x: float, cell_y: float) -> np.ndarray:
    """Direction the slope faces (downhill), float32 degrees clockwise from north in
    [0, 360); :data:`ASPECT_FLAT` where the gradient is zero."""
    dz_dx, dz_dy = horn_gradient(z, cell_x, cell_y)
    flat = dz_dx == 0
    flat &= dz_dy == 0
    # 0 - x, not -x: a north-facing cell (dz/dx = 0) gets 0 degrees, not -0 (arctan2(-0.0, y))
    angle = np.arctan2(np.subtract(0.0, dz_dx, out=dz_dx), np.negative(dz_dy, out=dz_dy),
                       out=dz_dx)
    out = np.degrees(angle, out=np.empty(angle.shape, np.float32))  # (-180, 180]
    np.add(out, np.float32(360.0), out=out, where=out < 0)  # [0, 360) (np.mod is ~10x slower)
    out[flat] = ASPECT_FLAT
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
    # unit normal (-dz/dx, -dz/dy, 1)/n; sun direction (sin az cos alt, cos az cos alt, sin alt):
    # shade = (cos(zenith) - sin(zenith)·(dz/dx·sin(az) + dz/dy·cos(az))) / n
    norm = np.multiply(dz_dx, dz_dx)
    norm += np.square(dz_dy)
    norm += 1.0
    np.sqrt(norm, out=norm)
    shade = np.multiply(dz_dx, np.sin(zenith) * np.sin(az), out=dz_dx)
    shade += np.multiply(dz_dy, np.sin(zenith) * np.cos(az), out=dz_dy)
    np.subtract(np.cos(zenith), shade, out=shade)
    shade /= norm
    return np.clip(shade, 0.0, 1.0, out=shade)


def hillshade_byte(shade: np.ndarray) -> np.ndarray:
    """Illumination [0, 1] as Byte: 1 (dark) to 255 (lit), 0 for NaN (nodata)."""
    grey = np.multiply(shade, 254.0)
    np.rint(grey, out=grey)  # round half to even, as np.round
    grey += 1.0
    np.copyto(grey, 0.0, where=np.isnan(grey))
    return grey.astype("uint8")


def hillshade_bytes(z: np.ndarray, cell_x: float, cell_y: float, azimuth: float = 315.0,
                    altitude: float = 45.0, z_factor: float = 1.0) -> np.ndarray:
    """:func:`hillshade` as Byte (:func:`hillshade_byte`): the kernel of ``dem:hillshade``."""
    return hillshade_byte(hillshade(z, cell_x, cell_y, azimuth, altitude, z_factor))


def extrapolate_edges(z: np.ndarray, tile, width: int, height: int) -> np.ndarray:
    """Replace the halo cells of ``z`` (read over ``tile.haloed_window``, one-cell halo) that
    lie beyond a ``width`` x ``height`` raster by the surface extrapolated linearly
    (``2·edge - inner``, in float64), exact on planes; along an axis where the raster is one
    cell wide the edge is repeated (no slope that way), each axis on its own: a 1 x N profile
    of a plane keeps its gradient along the row up to the ends."""
    w, h = tile.window, tile.halo
    top = max(0, h - int(w.row_off))
    left = max(0, h - int(w.col_off))
    bottom = max(0, int(w.row_off + w.height) + h - height)
    right = max(0, int(w.col_off + w.width) + h - width)
    if not (top or bottom or left or right):
        return z
    inside = z[top:z.shape[0] - bottom, left:z.shape[1] - right].astype(np.float64)
    for axis, pad in enumerate(((top, bottom), (left, right))):
        if pad == (0, 0):
            continue
        pads = [(0, 0), (0, 0)]
        pads[axis] = pad
        inside = np.pad(inside, pads, mode="reflect", reflect_type="odd") \
            if inside.shape[axis] >= 2 else np.pad(inside, pads, mode="edge")
    return inside


def shade_tile(kernel: Callable[..., np.ndarray], raster_size: tuple[int, int],
               cell: tuple[float, float], tile, arrays: dict) -> np.ndarray:
    """The engine kernel: the tile's haloed DEM (nodata as NaN) with its edges extrapolated,
    through ``kernel(z, cell_x, cell_y)``; (rows, cols) out."""
    z = extrapolate_edges(arrays["dem"][0], tile, *raster_size)
    return kernel(z, *cell)


def shade_raster(info, band: int, output: str | Path,
                 kernel: Callable[[np.ndarray, float, float], np.ndarray], dtype: str,
                 nodata: float, feedback, tile_size: int = 512, overviews: bool = True,
                 cog: bool = False, executor=None, description: str | None = None,
                 unit: str | None = None) -> dict:
    """Run a 3x3 ``kernel(z_padded, cell_x, cell_y) -> values`` over a DEM on the raster
    engine (:func:`toolbox.raster.engine.process_raster`, one-cell halo) into a tiled
    GeoTIFF (:class:`toolbox.raster.writer.RasterWriter`, a COG with ``cog``).

    ``info`` is a :class:`~toolbox.io.raster.RasterInfo`; the DEM is read as float32 when that
    holds its values exactly, else float64; DEM nodata becomes NaN before the kernel (so
    cells next to nodata are nodata) and NaN results become ``nodata``. The kernel must be
    picklable (a module-level function or a ``functools.partial`` of one) to run on a Dask
    cluster. ``description`` and ``unit`` (GDAL's unit type: "degree", "percent") name the
    output band's values for GDAL and QGIS. Returns counts of valid and nodata cells and the
    number of tiles.

    ``executor`` defaults to the Dask cluster of ``DASK_SCHEDULER_ADDRESS`` when it is set,
    else one tile thread: a 3x3 kernel costs less than reading and writing
    its tile, and GDAL's compression threads already run beside it; a second tile thread was
    measured slower on 2 cores (1612 x 1376: 0.19 s against 0.36 s; 8000 x 8000: 6.4 s
    against 6.9 s), its temporaries page-faulting in the thread's own malloc arena.
    """
    from functools import partial

    from toolbox.executor import resolve_executor
    from toolbox.io.grid import GridSpec
    from toolbox.raster.engine import RasterInput, process_raster
    from toolbox.raster.writer import RasterWriter

    grid = GridSpec(info.transform, info.width, info.height, info.crs)
    # float32 holds every value of these types exactly (the kernels compute in float64); the
    # DEM is then read without a conversion pass
    exact32 = info.dtypes[band - 1] in ("float32", "uint8", "int8", "uint16", "int16")
    dem = RasterInput(info.path, bands=(band,), dtype="float32" if exact32 else "float64",
                      boundary="nodata")
    cell = signed_cell(info.transform)
    tile_kernel = partial(shade_tile, kernel, (info.width, info.height), cell)
    floating = np.dtype(dtype).kind == "f"
    valid = [0]

    def count(tile, values, _info):
        if values is not None:
            valid[0] += int((np.isfinite(values) if floating else values != nodata).sum())

    with RasterWriter(output, grid, 1, dtype, nodata=nodata, overviews=overviews,
                      cog=cog, band_descriptions=[description] if description else None,
                      band_units=[unit] if unit else None) as writer:
        result = process_raster(grid, {"dem": dem}, tile_kernel, writer, tile_size=tile_size,
                                halo=1, executor=executor or resolve_executor(None, 1),
                                feedback=feedback, collect=count,
                                end=95)
    cells = info.width * info.height
    return {"cells": cells, "valid_cells": valid[0], "nodata_cells": cells - valid[0],
            "tiles": result["tiles"], "executor": result["executor"]}


def signed_cell(transform) -> tuple[float, float]:
    """``(cell_x, cell_y)`` for the kernels, whose formulas take columns west to east and rows
    north to south: negative when the raster runs the other way (``cell_y < 0`` for a
    south-up raster, whose rows go south to north), so the gradient keeps its map direction
    (a south-up DEM's aspect and shading would otherwise be mirrored north-south, as
    gdaldem's are)."""
    return float(transform.a), float(-transform.e)


def check_georeferenced(info) -> None:
    """The DEM ``info`` (a :class:`~toolbox.io.raster.RasterInfo`) is not rotated: the kernels
    need its cell size along map east and north. (Georeferenced: checked when INPUT, a
    heights raster, is validated; BAND within its bands: by the runner for every algorithm.)"""
    from toolbox.errors import InputDataError

    t = info.transform
    if t.b != 0 or t.d != 0:
        raise InputDataError(f"INPUT {info} has a rotated geotransform (row/column rotation "
                             f"{t.b:g}, {t.d:g}); warp it to a north-up grid first (gdalwarp)")
