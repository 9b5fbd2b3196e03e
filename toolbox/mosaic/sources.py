"""Orthophotos as mosaic sources: metadata, valid-data footprints, nadir points and windowed reads
onto the mosaic grid.

Valid data is GDAL's dataset mask: an alpha band, a nodata value or an internal mask, whichever
the file has. An alpha band is never mosaicked as data. Nadir points are read from the ortho's
tags ``NADIR_X``/``NADIR_Y`` (or the projection centre ``X0``/``Y0``) or given by the caller.
"""

from __future__ import annotations

import math
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

NADIR_TAGS = (("NADIR_X", "NADIR_Y"), ("X0", "Y0"), ("PROJECTION_CENTRE_X", "PROJECTION_CENTRE_Y"))


@dataclass
class OrthoSource:
    """One ortho of the block: ``index`` is its position in the input list (0-based)."""

    index: int
    path: Path
    name: str
    width: int
    height: int
    transform: Any  # affine.Affine
    crs: Any  # rasterio CRS or None
    dtype: str
    data_bands: list[int]  # 1-based band indexes mosaicked as data
    alpha_band: int | None
    nodata: float | None
    nadir: tuple[float, float] | None = None
    footprint: Any = field(default=None, repr=False)  # shapely polygon of valid data
    #: the block's open rasters (:class:`~toolbox.raster.datasets.ThreadDatasets`, shared by the
    #: sources of :func:`toolbox.mosaic.block.open_block`), or None: each read opens the file
    datasets: Any = field(default=None, repr=False, compare=False)
    #: every cell is valid data (set by :func:`valid_footprint` when it read the whole mask at
    #: full resolution): the grid-aligned reads then skip the mask (GDAL would compute it again)
    all_valid: bool = field(default=False, repr=False, compare=False)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        t = self.transform
        xs = (t.c, t.c + t.a * self.width)
        ys = (t.f, t.f + t.e * self.height)
        return (min(xs), min(ys), max(xs), max(ys))

    @property
    def res(self) -> tuple[float, float]:
        return (abs(self.transform.a), abs(self.transform.e))

    @property
    def centre(self) -> tuple[float, float]:
        """Footprint centre (centroid of the valid data), else the raster's centre."""
        if self.footprint is not None and not self.footprint.is_empty:
            c = self.footprint.centroid
            return (c.x, c.y)
        x0, y0, x1, y1 = self.bounds
        return ((x0 + x1) / 2, (y0 + y1) / 2)


# GDAL's dataset mask of an ortho with a nodata value and an alpha band is the nodata value's:
# rasterio says so in a warning at every mask read; the mosaic says it once per input instead
# (:func:`shadowed_alpha_message`, warned by toolbox.mosaic.block.open_block)
warnings.filterwarnings("ignore", message="The dataset's nodata attribute is shadowing the alpha",
                        module=r"toolbox\.mosaic\.")


def shadowed_alpha_message(source: OrthoSource) -> str:
    """What the mosaic does with an ortho that has both a nodata value and an alpha band."""
    return (f"{source.name}: has both a nodata value ({source.nodata:g}) and an alpha band "
            f"(band {source.alpha_band}): its empty cells are those where every band, the alpha "
            f"band too, holds {source.nodata:g} (GDAL's mask: the nodata value wins); cells "
            "the alpha band alone marks transparent are mosaicked. To let the alpha band "
            f"decide, remove the nodata value: gdal_edit.py -unsetnodata '{source.path}'")


def opened(source: OrthoSource):
    """The source's raster for reading (a context manager): this thread's dataset kept open by
    ``source.datasets`` (GDAL's block cache then serves the blocks that the footprint, the
    seams' costs and the mosaic's overlapping tiles read again), else opened and closed here."""
    return _opened(source.path, source.datasets)


@contextmanager
def _opened(path: Path, datasets: Any):
    if datasets is not None:
        yield datasets.get(path)
        return
    import rasterio

    with rasterio.open(path) as src:
        yield src


def open_source(path: str | Path, index: int, datasets: Any = None,
                name: str = "INPUT") -> OrthoSource:
    """Read an ortho's metadata (no pixels); with ``datasets`` (a
    :class:`~toolbox.raster.datasets.ThreadDatasets`) the raster stays open there for the
    source's reads. Raises :class:`InputDataError` for rotated grids, and
    :class:`~toolbox.errors.ParameterError` naming ``name`` for bands with different nodata
    values (the mosaic has one mask for all bands: :func:`toolbox.io.raster.require_one_nodata`)."""
    from rasterio.enums import ColorInterp

    path = Path(path)
    with _opened(path, datasets) as src:
        from toolbox.io.raster import dataset_transform, require_one_nodata

        require_one_nodata(src, name, path)
        t = dataset_transform(src)
        if t.b != 0 or t.d != 0:
            raise InputDataError(f"'{path}' has a rotated geotransform; mosaic inputs must be "
                                 "north-up (warp it first)")
        alpha = next((i + 1 for i, ci in enumerate(src.colorinterp) if ci == ColorInterp.alpha),
                     None)
        bands = [b for b in range(1, src.count + 1) if b != alpha]
        if not bands:
            raise InputDataError(f"'{path}' has no data band besides its alpha band")
        tags = src.tags()
        nadir = None
        for kx, ky in NADIR_TAGS:
            if kx in tags and ky in tags:
                try:
                    nadir = (float(tags[kx]), float(tags[ky]))
                    break
                except ValueError:
                    continue
        return OrthoSource(index, path, path.stem, src.width, src.height, t, src.crs,
                           src.dtypes[bands[0] - 1], bands, alpha, src.nodata, nadir,
                           datasets=datasets)


def valid_footprint(source: OrthoSource, max_size: int = 1024, simplify: float | None = None):
    """Polygon of the ortho's valid data, traced on its mask decimated to at most ``max_size``
    cells a side (the mask of a decimated read is valid where the nearest full-res cell is).

    The outline follows cell edges at the decimated resolution, simplified by ``simplify`` ground
    units (default: one decimated cell); holes smaller than 4 decimated cells are dropped. A
    whole mask read at full resolution without a no-data cell sets ``source.all_valid``.
    """
    import shapely
    from affine import Affine
    from rasterio.features import shapes

    factor = max(1, math.ceil(max(source.width, source.height) / max_size))
    w, h = math.ceil(source.width / factor), math.ceil(source.height / factor)
    with opened(source) as src:
        mask = src.dataset_mask(out_shape=(h, w)) > 0
    if mask.all():  # what tracing gives, without tracing: the raster's outline
        source.all_valid = factor == 1
        return shapely.box(*source.bounds)
    t = source.transform @ Affine.scale(source.width / w, source.height / h)
    polys = [shapely.geometry.shape(g) for g, v in shapes(mask.astype("uint8"), mask=mask,
                                                             transform=t, connectivity=8) if v]
    if not polys:
        raise InputDataError(f"'{source.path}' has no valid data")
    cell = max(abs(t.a), abs(t.e))
    geom = shapely.union_all(polys)
    geom = _drop_small_holes(geom, 4 * cell * cell)
    geom = geom.simplify(cell if simplify is None else simplify, preserve_topology=True)
    return shapely.make_valid(geom).buffer(0)


def _drop_small_holes(geom, min_area: float):
    import shapely
    from shapely.geometry import MultiPolygon, Polygon

    parts = []
    for poly in getattr(geom, "geoms", [geom]):
        if isinstance(poly, Polygon):
            holes = [r for r in poly.interiors if Polygon(r).area >= min_area]
            parts.append(Polygon(poly.exterior, holes))
    return parts[0] if len(parts) == 1 else shapely.union_all(MultiPolygon(parts))


def aligned(source: OrthoSource, grid_transform: Any, tol: float = 1e-6) -> bool:
    """True when the source's cells coincide with the mosaic grid's (same size, offsets whole
    cells): it is then read without resampling."""
    t, g = source.transform, grid_transform
    if abs(t.a - g.a) > tol * abs(g.a) or abs(t.e - g.e) > tol * abs(g.e):
        return False
    dx, dy = (t.c - g.c) / g.a, (t.f - g.f) / g.e
    return abs(dx - round(dx)) < 1e-6 and abs(dy - round(dy)) < 1e-6


#: data types whose every value float32 holds exactly: read as float32 by GDAL, no copy
EXACT_IN_FLOAT32 = frozenset({"uint8", "int8", "uint16", "int16", "float32"})


def read_window(source: OrthoSource, grid_transform: Any, grid_crs: Any, window: Any,
                resampling: str = "bilinear") -> tuple[np.ndarray, np.ndarray]:
    """Read ``source`` onto a window of the mosaic grid.

    Returns ``(data, valid)``: float32 ``(bands, rows, cols)`` and a bool mask ``(rows, cols)``
    (False outside the ortho or where its mask says no data). Aligned sources are read cell for
    cell; others are resampled by :func:`toolbox.raster.reproject.read_onto` (``resampling``
    for data, nearest for the mask: :func:`~toolbox.raster.reproject.mask_onto`).
    """
    from rasterio.windows import transform as window_transform

    rows, cols = int(window.height), int(window.width)
    with opened(source) as src:
        if aligned(source, grid_transform):
            part = _inside(source, grid_transform, window)
            if part is not None and _whole(part[1], rows, cols) and \
                    source.dtype in EXACT_IN_FLOAT32:  # the window inside the ortho
                # in the file's type (a copy out of GDAL's block cache), then to float32 by
                # numpy: GDAL's conversion cost 1.7 against 1.1 ms of CPU for a 1000 x 1000
                # RGB window; the same values (exact types)
                data = src.read(source.data_bands, window=part[0]).astype("float32",
                                                                          copy=False)
                valid = np.ones((rows, cols), dtype=bool) if source.all_valid else \
                    src.dataset_mask(window=part[0]) > 0
                return data, valid
            data = np.zeros((len(source.data_bands), rows, cols), dtype="float32")
            valid = np.zeros((rows, cols), dtype=bool)
            if part is not None:
                inner, sl = part
                data[(slice(None), *sl)] = src.read(source.data_bands, window=inner)
                valid[sl] = True if source.all_valid else src.dataset_mask(window=inner) > 0
            return data, valid
        from toolbox.raster.reproject import mask_onto, read_onto

        t = window_transform(window, grid_transform)
        data = read_onto(src, t, cols, rows, grid_crs, indexes=source.data_bands,
                         resampling=resampling,
                         fill=0 if source.nodata is None else source.nodata).astype("float32")
        return data, mask_onto(src, t, cols, rows, grid_crs)


def read_valid(source: OrthoSource, grid_transform: Any, grid_crs: Any, window: Any,
               out: np.ndarray | None = None) -> np.ndarray:
    """Only the ``valid`` mask of :func:`read_window` (no data bands read where GDAL's mask
    does not need them: an alpha band or an internal mask); written into ``out`` when given
    (a bool array of the window's shape, all False), returned."""
    from rasterio.windows import transform as window_transform

    rows, cols = int(window.height), int(window.width)
    if aligned(source, grid_transform):
        valid = np.zeros((rows, cols), dtype=bool) if out is None else out
        part = _inside(source, grid_transform, window)
        if part is not None:
            if source.all_valid:
                valid[part[1]] = True
            else:
                with opened(source) as src:
                    valid[part[1]] = src.dataset_mask(window=part[0]) > 0
        return valid
    with opened(source) as src:
        from toolbox.raster.reproject import mask_onto

        valid = mask_onto(src, window_transform(window, grid_transform), cols, rows, grid_crs)
    if out is None:
        return valid
    out[...] = valid
    return out


def _whole(slices: tuple[slice, slice], rows: int, cols: int) -> bool:
    """True when the slices of :func:`_inside` cover the whole ``rows`` x ``cols`` window."""
    return (slices[0].start, slices[0].stop, slices[1].start, slices[1].stop) == (0, rows, 0, cols)


def _inside(source: OrthoSource, grid_transform: Any, window: Any) -> tuple | None:
    """For a source aligned with the grid: :func:`~toolbox.raster.engine.part_inside` of
    ``window`` (grid cells) in the source."""
    from toolbox.raster.engine import part_inside

    off_c = round((grid_transform.c - source.transform.c) / grid_transform.a)
    off_r = round((grid_transform.f - source.transform.f) / grid_transform.e)
    return part_inside(int(window.col_off) + off_c, int(window.row_off) + off_r,
                       int(window.width), int(window.height), source.width, source.height)
