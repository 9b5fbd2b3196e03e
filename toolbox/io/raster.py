"""Raster I/O with rasterio: validated input references, the GeoTIFF profile and overview
rules (tiled, DEFLATE with a predictor, CRS, nodata). The tiles of a grid (windows with a halo)
are :func:`toolbox.raster.tile.iter_tiles`'s.

Every GeoTIFF output is written by :class:`toolbox.raster.writer.RasterWriter` (whole arrays:
:func:`toolbox.raster.writer.write_raster`) with the profile of :func:`geotiff_profile`.

Conventions: arrays are ``(bands, rows, cols)`` or ``(rows, cols)``; windows are rasterio
``Window(col_off, row_off, width, height)``; row 0 is the top (north) edge.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError

DEFAULT_BLOCK = 512


def gdal_cache_max(mb: int) -> int:
    """``GDAL_CACHEMAX`` for ``rasterio.Env``: bytes. rasterio hands an integer to
    ``GDALSetCacheMax`` as bytes (``GDAL_CACHEMAX=256`` is a 256-byte cache, which makes every
    windowed read decompress its blocks again), so megabytes are converted here."""
    return int(mb) * 2**20


@dataclass
class RasterInfo:
    """A validated reference to a raster: path and the metadata read without loading pixels."""

    path: Path
    width: int
    height: int
    count: int
    dtypes: tuple[str, ...]
    crs: Any  # pyproj.CRS or None
    transform: Any  # affine.Affine
    nodata: float | None
    georeferenced: bool
    #: per band, GDAL's colour interpretation in lower case ("gray", "red", "palette"...);
    #: "palette" for any band with a colour table
    colours: tuple[str, ...] = ()
    #: per band, GDAL's unit type of its values ("m", "ft", "US survey foot"; "" when unset)
    units: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"'{self.path}'"

    def as_text(self) -> str:
        return str(self.path)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        t = self.transform
        xs = [t.c, t.c + t.a * self.width]
        ys = [t.f, t.f + t.e * self.height]
        return (min(xs), min(ys), max(xs), max(ys))

    @property
    def res(self) -> tuple[float, float]:
        return (abs(self.transform.a), abs(self.transform.e))


def open_raster_info(value: Any, name: str = "INPUT", role: str = "photo") -> RasterInfo:
    """Open a raster's metadata; :class:`ParameterError` naming ``name`` when it is unreadable,
    when a band stores scaled codes, or when it has no georeferencing and ``role`` (one of
    :data:`toolbox.parameters.sources.RASTER_ROLES`) is not "photo"
    (:func:`require_georeferenced`)."""
    import rasterio
    from pyproj import CRS

    if isinstance(value, RasterInfo):
        return value
    if not isinstance(value, (str, Path)):
        raise ParameterError(name, f"must be a raster path, got {value!r}")
    path = Path(value).expanduser()
    if not path.exists():
        if re.match(r"^[A-Za-z0-9_]{2,}:", str(value)):  # GPKG:file.gpkg:table, NETCDF:...
            raise ParameterError(name, f"'{value}' is a GDAL subdataset name, not a file: "
                                 f"extract it first: gdal_translate '{value}' extracted.tif")
        raise ParameterError(name, f"file '{value}' does not exist")
    from toolbox.io.gpkg_summary import unread_wal

    refused = unread_wal(path)  # a GeoPackage's -wal GDAL would leave out
    if refused:
        raise ParameterError(name, refused)
    try:
        with warnings.catch_warnings():  # a plain photo is fine: ``georeferenced`` says so
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            src = rasterio.open(path)
        with src:
            if src.count == 0 and src.subdatasets:  # a GeoPackage of several raster tables
                listed = ", ".join(f"'{sub}'" for sub in src.subdatasets[:3])
                raise ParameterError(name, f"'{value}' holds {len(src.subdatasets)} rasters "
                                     f"({listed}{', ...' if len(src.subdatasets) > 3 else ''})"
                                     f": extract one first: gdal_translate "
                                     f"'{src.subdatasets[0]}' extracted.tif")
            damage = _last_blocks_missing(src, path.stat().st_size)
            if damage:
                raise ParameterError(name, f"'{value}' is truncated or damaged: {damage}")
            _refuse_scaled(src, name, value)
            if role != "photo":
                require_georeferenced(src, name, value)
            else:  # a photo is warped under one mask
                require_one_nodata(src, name, value)
            crs = CRS.from_wkt(src.crs.to_wkt()) if src.crs else None
            return RasterInfo(path, src.width, src.height, src.count, tuple(src.dtypes), crs,
                              dataset_transform(src),
                              src.nodata, not src.transform.is_identity,
                              _band_colours(src), tuple(u or "" for u in src.units))
    except rasterio.errors.RasterioIOError as exc:
        raise ParameterError(name, f"cannot read '{value}' as a raster: "
                             f"{str(exc).splitlines()[0]}") from None


def require_georeferenced(src: Any, name: str, path: Any) -> None:
    """:class:`ParameterError` naming ``name`` when the open dataset ``src`` has no geotransform
    (GDAL then gives the identity: its cells would be taken as map coordinates 0, 1, 2...):
    with ground control points or RPCs, the gdalwarp command that writes a georeferenced
    raster from them. Checked before any north-up test (the identity looks south-up)."""
    if not src.transform.is_identity:
        return
    gcps = src.gcps[0]
    if gcps:
        how = (f" (only {len(gcps)} ground control points): warp it first: gdalwarp "
               f"'{path}' warped.tif")
    elif src.rpcs:
        how = (" (only RPCs): warp it first: gdalwarp -rpc -to RPC_DEM=dem.tif "
               f"'{path}' warped.tif")
    else:
        how = ": its cells have no map position; give a georeferenced raster"
    raise ParameterError(name, f"'{path}' has no georeferencing{how}")


def _band_colours(src: Any) -> tuple[str, ...]:
    """Each band's colour interpretation (lower case), "palette" for a band with a colour
    table whatever its interpretation."""
    colours = []
    for band, interp in enumerate(src.colorinterp, start=1):
        try:
            src.colormap(band)
            colours.append("palette")
        except ValueError:  # no colour table
            colours.append(interp.name.lower())
    return tuple(colours)


def require_height_band(info: RasterInfo, name: str, band: int = 1,
                        band_name: str | None = None) -> None:
    """:class:`ParameterError` naming ``name`` when band ``band`` of ``info`` (read as heights)
    holds colours: a paletted band (colour codes) or a photo's red, green or blue channel, or
    complex numbers (a SAR product: read as heights, the imaginary parts were dropped with a
    numpy warning). ``band_name`` is the parameter that chose the band (BAND), if any."""
    colour = info.colours[band - 1] if band <= len(info.colours) else "gray"
    dtype = info.dtypes[band - 1] if band <= len(info.dtypes) else ""
    if dtype.startswith("complex"):
        chosen = f" (chosen by {band_name})" if band_name else ""
        raise ParameterError(name, f"{info} band {band}{chosen} holds complex numbers ({dtype}), "
                             "not heights; give a DEM of heights (its real part: gdal_translate "
                             f"-ot Float32 -b {band} '{info.path}' real.tif)")
    if colour == "palette":
        what = "has a colour table (palette): its values are colour codes, not heights"
    elif colour in ("red", "green", "blue"):
        what = (f"has colour interpretation {colour.capitalize()}: a photo's colour channel, "
                "not heights")
    else:
        return
    chosen = f" (chosen by {band_name})" if band_name else ""
    raise ParameterError(name, f"{info} band {band}{chosen} {what}; give a DEM of heights")


#: GDAL band unit types of heights (lower case) -> metres per unit
HEIGHT_UNITS = {
    **dict.fromkeys(("m", "metre", "metres", "meter", "meters"), 1.0),
    **dict.fromkeys(("ft", "foot", "feet", "international foot", "foot (international)",
                     "intl foot"), 0.3048),
    **dict.fromkeys(("us survey foot", "us survey feet", "ftus", "us-ft", "us_ft", "survey foot",
                     "foot_us", "us foot", "us feet", "foot (us survey)"), 1200 / 3937),
    **dict.fromkeys(("cm", "centimetre", "centimetres", "centimeter", "centimeters"), 0.01),
    **dict.fromkeys(("mm", "millimetre", "millimetres", "millimeter", "millimeters"), 0.001),
    **dict.fromkeys(("dm", "decimetre", "decimetres", "decimeter", "decimeters"), 0.1),
    **dict.fromkeys(("km", "kilometre", "kilometres", "kilometer", "kilometers"), 1000.0),
}


def require_height_unit(info: RasterInfo, name: str, band: int, algorithm_id: str,
                        length_units: str = "metre", factor_name: str | None = None) -> None:
    """:class:`ParameterError` naming ``name`` when band ``band`` of the DEM ``info`` states
    (GDAL's band unit type) heights in a length unit the algorithm would take for another: an
    algorithm in metres (``length_units`` "metre") given heights in feet, or one whose x, y and
    heights share a unit ("one": slopes, volumes) given heights in another unit than the CRS's
    x, y. Heights read as metres in silence would give orthos, slopes, volumes off by 3.28.
    A unit that is not a length GDAL names (or none) passes, as do algorithms whose heights
    keep their own unit ("horizontal": contours, TINs). ``factor_name``: the algorithm's
    parameter that converts heights (Z_FACTOR), offered in the message."""
    unit = info.units[band - 1].strip() if band <= len(info.units) else ""
    factor = HEIGHT_UNITS.get(unit.lower())
    if factor is None or length_units not in ("metre", "one"):
        return
    expected, expected_name = 1.0, "metres"
    if length_units == "one":
        axes = [a for a in (info.crs.axis_info if info.crs is not None else [])
                if a.direction in ("east", "north") and a.unit_conversion_factor > 0]
        if not axes:
            return
        expected = axes[0].unit_conversion_factor
        expected_name = f"the {axes[0].unit_name} of its CRS's x, y"
    if abs(factor / expected - 1.0) < 1e-5:  # an international foot for a US one: 2 ppm
        return
    ratio = factor / expected
    raise ParameterError(name, f"{info} band {band} holds heights in '{unit}' (its band unit), "
                         f"but {algorithm_id} reads heights in {expected_name}: convert them "
                         f"first: gdal_calc.py -A '{info.path}' --A_band={band} "
                         f"--calc=\"A*{ratio:.12g}\" --type=Float32 --outfile=heights.tif"
                         + (f" (or give {factor_name} {ratio:.12g})" if factor_name else ""))


#: a rotation term moving the raster's far corner by less than this fraction of a cell is zero
NEGLIGIBLE_ROTATION = 1e-9


def without_negligible_rotation(transform: Any, width: int, height: int) -> Any:
    """``transform`` with its rotation terms set to zero when they are negligible for a raster
    of ``width`` x ``height`` cells: ``|b| * height`` below :data:`NEGLIGIBLE_ROTATION` of a
    cell's width and ``|d| * width`` below that of a cell's height (the far corner moves by
    less than that). Reprojections and GIS exports write terms like 1e-15 for a north-up grid:
    read as rotated, such a raster would be refused. ``transform`` itself otherwise."""
    from affine import Affine

    b, d = transform.b, transform.d
    if (b == 0 and d == 0) or not (
            abs(b) * max(int(height), 1) < NEGLIGIBLE_ROTATION * abs(transform.a)
            and abs(d) * max(int(width), 1) < NEGLIGIBLE_ROTATION * abs(transform.e)):
        return transform
    return Affine(transform.a, 0.0, transform.c, 0.0, transform.e, transform.f)


def dataset_transform(src: Any) -> Any:
    """The geotransform of the open dataset ``src``, its negligible rotation terms zero
    (:func:`without_negligible_rotation`)."""
    return without_negligible_rotation(src.transform, src.width, src.height)


def north_up_transform(transform: Any, width: int, height: int) -> Any:
    """The north-up geotransform of the same cells as ``transform`` (no rotation) for a raster
    of ``width`` x ``height`` cells stored south-up or east to west: the same grid with its
    rows (columns) in the other order; ``transform`` itself when already north-up."""
    from affine import Affine

    a, c, e, f = transform.a, transform.c, transform.e, transform.f
    if a < 0:
        c, a = c + a * width, -a
    if e > 0:
        f, e = f + e * height, -e
    return Affine(a, transform.b, c, transform.d, e, f)


def require_north_up(transform: Any, name: str, path: Any, flips_ok: bool = False) -> None:
    """:class:`ParameterError` naming ``name`` unless the raster at ``path`` (geotransform
    ``transform``) is north-up: no rotation, columns west to east, rows north to south. With
    ``flips_ok`` (an algorithm that reads a south-up or east-to-west raster right) only a
    rotated one is refused. The message gives the gdalwarp command that writes it north-up."""
    if transform.b != 0 or transform.d != 0:
        how = f"rotated (geotransform rotation terms {transform.b:g}, {transform.d:g})"
    elif flips_ok:
        return
    elif transform.e > 0:
        how = "stored south-up (rows going north)"
    elif transform.a < 0:
        how = "stored east to west (columns going west)"
    else:
        return
    raise ParameterError(name, f"'{path}' is {how}; this needs a north-up raster: gdalwarp "
                         f"'{path}' north_up.tif writes one")


def _refuse_scaled(src: Any, name: str, value: Any) -> None:
    """A band with a scale or offset stores codes, not values (heights = code x scale +
    offset): the toolbox reads stored values, so such a raster is refused with the command
    that writes the values (contours, slopes and orthos of the codes would be wrong in
    silence)."""
    for band, (scale, offset) in enumerate(zip(src.scales, src.offsets, strict=True), start=1):
        if (scale or 1.0) != 1.0 or (offset or 0.0) != 0.0:
            raise ParameterError(name, f"'{value}' band {band} has scale {scale:g} and offset "
                                 f"{offset:g} (its values are codes x scale + offset); write "
                                 "the values first: gdal_translate -unscale -ot Float32 "
                                 f"'{value}' unscaled.tif")


def require_one_nodata(src: Any, name: str, value: Any) -> None:
    """:class:`ParameterError` naming ``name`` when the data bands (an alpha band aside) of the
    open dataset ``src`` have different nodata values, or some one and others none (a VRT's
    bands may each have their own). A warp or a cut marks the empty cells of all the bands at
    once (one alpha band; a GeoTIFF holds one nodata value): band 1's mask would be taken for
    every band in silence, and gdalwarp's per-band result (each band's nodata cells filled
    with 0 under one alpha) has no mask that says which values are empty."""
    from rasterio.enums import ColorInterp

    bands = [b for b, interp in enumerate(src.colorinterp, start=1)
             if not (interp == ColorInterp.alpha and src.count > 1)]
    values = [src.nodatavals[b - 1] for b in bands]
    if len({"none" if v is None else f"{v:g}" for v in values}) <= 1:  # NaN equals NaN
        return
    listed = ", ".join(f"band {b}: {'none' if v is None else f'{v:g}'}"
                       for b, v in zip(bands, values, strict=True))
    raise ParameterError(name, f"'{value}' has a nodata value per band ({listed}); its output "
                         "marks the empty cells of all bands at once: give every band the same "
                         f"nodata (gdal_translate -a_nodata VALUE '{value}' one_nodata.tif) or "
                         "none (-a_nodata none)")


def masked_by_nodata_only(src: Any, band: int) -> bool:
    """True when GDAL's mask of ``band`` (1-based) of the open dataset ``src`` is its nodata
    value or nothing (every cell valid), False for a mask band or an alpha band."""
    from rasterio.enums import MaskFlags

    return src.mask_flag_enums[band - 1] in ([MaskFlags.all_valid], [MaskFlags.nodata])


def read_dataset_masked(src: Any, indexes: Any = None, window: Any = None,
                        out_shape: tuple[int, int] | None = None,
                        resampling: Any = None) -> np.ma.MaskedArray:
    """Bands ``indexes`` (all by default) of the open dataset ``src`` masked where GDAL's
    dataset mask is 0 (every band at its nodata, alpha 0, or a mask band's 0), one mask for
    all the bands. ``out_shape`` (rows, cols): a decimated read (``resampling``, nearest by
    default), the mask likewise.

    Not rasterio's ``masked=True``: it masks each band by its own nodata, so a valid pixel with
    one band at the nodata value (pure blue (0, 0, 255), a dark shadow (0, 3, 8) of an RGB
    with nodata 0) lost that band (drawn 255: white, or called no data in a grey mean)."""
    from rasterio.enums import Resampling

    indexes = list(range(1, src.count + 1)) if indexes is None else indexes
    extra = {} if out_shape is None else {
        "out_shape": (len(indexes), *out_shape), "resampling": resampling or Resampling.nearest}
    data = src.read(indexes, window=window, **extra)
    mask = src.dataset_mask(window=window, out_shape=out_shape) == 0
    return np.ma.MaskedArray(data, mask=np.broadcast_to(mask, data.shape).copy())


def read_filled(src: Any, band: int, window: Any = None, dtype: str = "float64") -> np.ndarray:
    """Band ``band`` of open dataset ``src`` (``window``: all of it by default) as ``dtype``
    with NaN where rasterio's ``masked=True`` read masks it, the same array.

    A band whose only mask is its nodata value (or none) is read once and compared with it:
    the masked read would read the band again for its mask (a 2000 x 2000 DEM: 0.17 against
    0.09 s with its decompression). Any other mask (mask band, alpha) is read as rasterio does.
    """
    if not masked_by_nodata_only(src, band):
        return src.read(band, window=window, masked=True).astype(dtype).filled(np.nan)
    raw = src.read(band, window=window)
    z = raw.astype(dtype)
    if src.nodatavals[band - 1] is not None:  # GDAL's test: equal to nodata in the band's type
        nodata = float(src.nodatavals[band - 1])
        if raw.dtype.kind == "f":
            z[np.isnan(raw) if math.isnan(nodata) else raw == raw.dtype.type(nodata)] = np.nan
        elif nodata.is_integer() and np.iinfo(raw.dtype).min <= nodata <= np.iinfo(raw.dtype).max:
            z[raw == int(nodata)] = np.nan
    return z


def has_valid_pixel(path: str | Path) -> bool:
    """True when some pixel of the raster is valid (not nodata or masked, finite for floats).
    Read block by block until one is found: cheap for a normal raster."""
    import rasterio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        try:
            with rasterio.open(path) as src:
                for _, window in src.block_windows(1):
                    data = src.read(window=window, masked=True)
                    valid = ~np.ma.getmaskarray(data)
                    if data.dtype.kind == "f":
                        valid &= np.isfinite(data.filled(0))
                    if valid.any():
                        return True
        except rasterio.errors.RasterioError as exc:  # a header that opens, blocks that do not
            raise InputDataError(f"cannot read '{path}': the file is truncated or corrupt "
                                 f"({str(exc).splitlines()[0]})") from None
    return False


def _last_blocks_missing(src: Any, size: int) -> str | None:
    """For a GeoTIFF, whether the last block of a band lies beyond the end of the file (a copy
    or download cut short: blocks are written in order). Cheap: a few TIFF tags."""
    if src.driver != "GTiff":
        return None
    rows, cols = src.block_shapes[0]
    bx, by = -(-src.width // cols) - 1, -(-src.height // rows) - 1
    for band in range(1, src.count + 1):
        offset = src.get_tag_item(f"BLOCK_OFFSET_{bx}_{by}", "TIFF", bidx=band)
        count = src.get_tag_item(f"BLOCK_SIZE_{bx}_{by}", "TIFF", bidx=band)
        if offset is not None and count is not None and int(offset) + int(count) > size:
            return (f"block {bx},{by} of band {band} ends at byte {int(offset) + int(count):,}, "
                    f"the file has {size:,}")
        if src.interleaving is None or src.interleaving.name == "PIXEL":
            break
    return None


def deflate_level(dtype: Any) -> int:
    """DEFLATE level: 1 for 8-bit rasters (photos, orthos: level 6 saved 3 % of an NGI ortho's
    size for twice the CPU time of writing it), 6 (GDAL's default) for the others."""
    return 1 if np.dtype(dtype).itemsize == 1 else 6


def predictor_for(dtype: Any) -> int:
    """TIFF predictor: 3 (floating point) for floats, 2 (horizontal) for integers."""
    return 3 if np.dtype(dtype).kind == "f" else 2


def geotiff_profile(width: int, height: int, count: int, dtype: Any, crs: Any, transform: Any,
                    nodata: float | None = None, block: int = DEFAULT_BLOCK,
                    compress: str = "DEFLATE", **extra: Any) -> dict:
    """The rasterio profile of a GeoTIFF output (the one rule, written by
    :class:`toolbox.raster.writer.RasterWriter`): tiled (``block`` pixels, also when the raster
    is smaller), compressed by ``compress``.

    DEFLATE, LZW, ZSTD and LZMA get a predictor: 2 (horizontal differencing) for integers, 3
    (floating point) for floats; DEFLATE's level is :func:`deflate_level`. BIGTIFF is used when
    the file may exceed 4 GB. ``extra`` overrides any creation option.
    """
    dtype = np.dtype(dtype)
    check_nodata_fits(nodata, dtype)
    compress = str(compress).upper()
    profile = {
        "driver": "GTiff", "width": int(width), "height": int(height), "count": int(count),
        "dtype": dtype.name, "crs": None if crs is None else _rio_crs(crs),
        "transform": transform, "nodata": nodata, "tiled": True, "blockxsize": int(block),
        "blockysize": int(block), "compress": compress.lower(), "bigtiff": "if_safer",
        "interleave": "pixel" if count > 1 else "band",
    }
    if compress in ("DEFLATE", "LZW", "ZSTD", "LZMA"):
        profile["predictor"] = predictor_for(dtype)
    if compress == "DEFLATE":
        profile["zlevel"] = deflate_level(dtype)
    profile.update(extra)
    return profile


def check_nodata_fits(nodata: float | None, dtype: Any, name: str = "NODATA") -> None:
    """:class:`ParameterError` naming ``name`` when ``nodata`` cannot be stored in ``dtype``
    (-9999 in a uint8 photo, 1e308 in float32, 2.5 in an integer band)."""
    if nodata is None:
        return
    dtype = np.dtype(dtype)
    value = float(nodata)
    if np.isnan(value):
        if dtype.kind != "f":
            raise ParameterError(name, f"NaN does not fit the {dtype.name} output (integer cells "
                                 "have no NaN): give a number")
        return
    if dtype.kind == "f":
        limit = float(np.finfo(dtype).max)
        ok = np.isinf(value) or abs(value) <= limit
        expected = f"between {_exact(-limit)} and {_exact(limit)}"
    elif dtype.kind in "iu":
        info = np.iinfo(dtype)
        ok = info.min <= value <= info.max and value == int(value)
        expected = f"a whole number from {info.min} to {info.max}"
    else:
        return
    if not ok:
        raise ParameterError(name, f"{_exact(value)} does not fit the {dtype.name} output cells "
                             f"(expected {expected})")


def nodata_clashes(values: Any, nodata: float | None, dtype: Any) -> int:
    """Cells of ``values`` (a float array, NaN where a kernel has no value) that hold a value
    but are stored as exactly ``nodata`` in ``dtype``: they read back as no data (a sea-level
    DEM with NODATA 0)."""
    if values is None or nodata is None or math.isnan(float(nodata)):
        return 0
    stored = np.asarray(values).astype(dtype, copy=False)
    return int(np.count_nonzero(stored == np.asarray(nodata).astype(dtype)))


def nodata_clash_warning(count: int, nodata: float, name: str = "NODATA") -> str:
    """The warning of :func:`nodata_clashes`: ``count`` computed cells lost to ``nodata``."""
    return (f"{count} cell(s) were computed as exactly {_exact(float(nodata))}, the {name} "
            "value, so they read as no data (GDAL, QGIS): give a value outside the results "
            f"as {name} (e.g. -9999)")


def _exact(value: float) -> str:
    """``value`` short (``-9999``, ``1e+39``) unless that loses digits (``3.4028235677973366e+38``)."""
    short = f"{value:g}"
    return short if float(short) == value else repr(value)


def _rio_crs(crs: Any):
    from rasterio.crs import CRS as RioCRS

    if isinstance(crs, RioCRS):
        return crs
    return RioCRS.from_wkt(crs.to_wkt()) if hasattr(crs, "to_wkt") else RioCRS.from_user_input(crs)


def overview_levels(width: int, height: int, tile: int = DEFAULT_BLOCK) -> list[int]:
    """Overview factors 2, 4, 8... until the smallest level fits in one ``tile`` (as GDAL's COG
    driver): none for a raster that fits in one tile."""
    factors, f = [], 1
    while math.ceil(width / f) > tile or math.ceil(height / f) > tile:
        f *= 2
        factors.append(f)
    return factors


def verify_written_raster(path: str | Path, check_empty: bool = True) -> str | None:
    """Check a raster just written: ``None`` when sound, ``"empty"`` when no cell is valid (all
    nodata or masked; only looked for with ``check_empty``), else a description of the damage (a
    GeoTIFF block beyond the end of the file, as a full disk leaves it; an unreadable block).

    Cheap: block offsets are read from the TIFF directory, and pixels only until the first valid
    cell is found.
    """
    import rasterio

    path = Path(path)
    size = path.stat().st_size
    try:
        with rasterio.open(path) as src:
            if src.driver == "GTiff":
                bands = [1] if src.interleaving is None or src.interleaving.name == "PIXEL" \
                    else list(range(1, src.count + 1))
                rows, cols = src.block_shapes[0]
                nby, nbx = -(-src.height // rows), -(-src.width // cols)
                for band in bands:
                    for by in range(nby):
                        for bx in range(nbx):
                            offset = src.get_tag_item(f"BLOCK_OFFSET_{bx}_{by}", "TIFF", bidx=band)
                            count = src.get_tag_item(f"BLOCK_SIZE_{bx}_{by}", "TIFF", bidx=band)
                            if offset is None or count is None:
                                continue
                            if int(offset) + int(count) > size or (int(offset) == 0
                                                                   and int(count) > 0):
                                return (f"block {bx},{by} of band {band} lies beyond the end of "
                                        "the file (truncated write)")
            if not check_empty:
                return None
            for _, window in src.block_windows(1):
                if src.dataset_mask(window=window).any():
                    return None
            return "empty"
    except rasterio.errors.RasterioError as exc:
        return f"the written raster cannot be read back: {str(exc).splitlines()[0]}"
