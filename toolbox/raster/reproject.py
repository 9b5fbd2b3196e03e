"""Reading a raster onto another grid: the one reprojection of the toolbox.

:func:`read_onto` warps bands of an open rasterio dataset onto a grid given by its affine
transform, size and CRS with GDAL's warper (``rasterio.warp.reproject``: only the source blocks
under the grid are read); :func:`mask_onto` gives where that grid has data (the source's nodata,
alpha band or internal mask, by nearest neighbour); :func:`default_grid` is GDAL's suggested grid
of a whole raster in another CRS (``gdalwarp`` without ``-tr``/``-te``). The raster engine's
inputs, the mosaic's sources and the ortho's DEM surface in another CRS all read through them.

Conventions: arrays are ``(bands, rows, cols)``; ``transform`` is the grid's affine (row 0 at
the top); ``crs`` None means the source's CRS (and two local rasters share any CRS).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: the warper's approximation error, in source pixels (GDAL's default 0.125; 0.01 keeps the
#: result within resampling noise of the exact transformation, at the same speed here)
TOLERANCE_PX = 0.01


def read_onto(src: Any, transform: Any, width: int, height: int, crs: Any = None, *,
              indexes: Any = None, resampling: str = "bilinear", dtype: Any = None,
              fill: float | None = None, src_nodata: Any = "source") -> np.ndarray:
    """Bands of ``src`` resampled onto the grid ``transform`` x (``width``, ``height``) in
    ``crs``.

    Parameters
    ----------
    src : rasterio dataset
        An open source.
    transform, width, height, crs
        The grid (``crs``: a pyproj or rasterio CRS, WKT or EPSG string; None: the source's).
    indexes : int or sequence of int, optional
        1-based bands (default: every band but an alpha band).
    resampling : str
        A rasterio resampling name (``nearest``, ``bilinear``, ``cubic``...).
    dtype : dtype, optional
        Result type (default: the first band's).
    fill : float, optional
        Value of the cells without data (outside the source, at its nodata or transparent);
        default NaN for floats, else the source's nodata (0 without one).
    src_nodata : float or None, optional
        The source's nodata value (default: each band's own; None: every value is data).

    Returns
    -------
    numpy.ndarray
        ``(len(indexes), height, width)``.
    """
    import rasterio
    from rasterio.enums import Resampling
    from rasterio.warp import reproject

    try:
        method = Resampling[resampling]
    except KeyError:
        raise ValueError(f"unknown resampling {resampling!r}") from None
    alpha = _alpha_band(src)
    if indexes is None:
        indexes = [b for b in src.indexes if b != alpha]
    indexes = [int(indexes)] if np.isscalar(indexes) else [int(b) for b in indexes]
    dtype = np.dtype(dtype or src.dtypes[indexes[0] - 1])
    if src_nodata == "source":
        own = {str(src.nodatavals[b - 1]) for b in indexes}  # str: NaN equals NaN
        if len(own) > 1:  # bands with nodata of their own (a VRT's): one warp per band
            return np.concatenate([read_onto(src, transform, width, height, crs, indexes=[b],
                                             resampling=resampling, dtype=dtype, fill=fill)
                                   for b in indexes])
        src_nodata = src.nodatavals[indexes[0] - 1]
    if fill is None:
        fill = math.nan if dtype.kind == "f" else (
            src_nodata if src_nodata is not None and not math.isnan(src_nodata) else 0)
    src_crs, dst_crs = _crs_pair(src.crs, crs, src.bounds)
    out = np.full((len(indexes), int(height), int(width)), fill, dtype=dtype)
    reproject(rasterio.band(src, indexes), out, src_transform=src.transform, src_crs=src_crs,
              src_nodata=src_nodata, dst_transform=transform, dst_crs=dst_crs, dst_nodata=fill,
              resampling=method, init_dest_nodata=True, tolerance=TOLERANCE_PX,
              src_alpha=alpha or 0)
    return out


def mask_onto(src: Any, transform: Any, width: int, height: int, crs: Any = None,
              src_nodata: Any = "source") -> np.ndarray:
    """Where the grid has data from ``src`` (bool ``(height, width)``): its nearest source cell
    is inside the source and valid (not nodata, opaque, inside an internal mask). The first data
    band is warped by nearest neighbour with NaN for no data."""
    first = read_onto(src, transform, width, height, crs, indexes=_first_data_band(src),
                      resampling="nearest", dtype="float64", fill=math.nan,
                      src_nodata=src_nodata)[0]
    return ~np.isnan(first)


def default_grid(src: Any, crs: Any) -> tuple[Any, int, int]:
    """GDAL's suggested grid ``(transform, width, height)`` of the whole ``src`` in ``crs``
    (about the source's resolution: ``gdalwarp -t_srs`` without a cell size or extent)."""
    from rasterio.warp import calculate_default_transform

    src_crs, dst_crs = _crs_pair(src.crs, crs, src.bounds)
    transform, width, height = calculate_default_transform(
        src_crs, dst_crs, src.width, src.height, *src.bounds)
    return transform, int(width), int(height)


def _alpha_band(src: Any) -> int | None:
    """The 1-based index of the source's alpha band, None without one."""
    from rasterio.enums import ColorInterp

    for k, interp in enumerate(src.colorinterp, start=1):
        if interp == ColorInterp.alpha and src.count > 1:
            return k
    return None


def _first_data_band(src: Any) -> int:
    alpha = _alpha_band(src)
    return next(b for b in src.indexes if b != alpha)


def _crs_pair(src_crs: Any, crs: Any, bounds: Any = None) -> tuple[Any, Any]:
    """(source CRS, grid CRS) as rasterio CRSs: a missing one is the other's; both missing
    (local systems): any one CRS for both, only the transforms matter. A source CRS that is
    another definition of the grid's (an ESRI WKT: :func:`toolbox.io.crs.one_crs` on the
    source's ``bounds``) is the grid's: resampled, not reprojected."""
    from toolbox.io.raster import _rio_crs

    dst = _rio_crs(crs) if crs is not None else None
    source = src_crs if src_crs else dst
    if source is None:
        source = _rio_crs("EPSG:3857")
    if dst is not None and source is not dst:
        from toolbox.io.crs import one_crs_of_wkt

        if one_crs_of_wkt(source.to_wkt(), dst.to_wkt(),
                          None if bounds is None else tuple(bounds)):
            source = dst
    return source, dst if dst is not None else source
