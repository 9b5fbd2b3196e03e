"""Map sheets ("taglio" to the map unit): a sheet grid from a scale and a paper sheet size, and
clipping of rasters and vectors to one sheet.

Sheet grid: a sheet covers ``width_cm/100 · scale`` x ``height_cm/100 · scale`` ground metres;
sheet ``(i, j)`` spans ``x0 + i·W .. x0 + (i+1)·W`` and ``y0 + j·H .. y0 + (j+1)·H`` from the
grid origin (x0, y0); its id is ``"{i}_{j}"`` (column east, row north; stable whatever is clipped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


def sheet_grid(bounds, width: float, height: float,
               origin: tuple[float, float] = (0.0, 0.0)) -> list[tuple[str, Any]]:
    """``(id, box)`` of every grid sheet meeting ``bounds`` (ground units)."""
    import shapely

    ox, oy = origin
    i0 = math.floor((bounds[0] - ox) / width)
    i1 = math.ceil((bounds[2] - ox) / width)
    j0 = math.floor((bounds[1] - oy) / height)
    j1 = math.ceil((bounds[3] - oy) / height)
    out = []
    for j in range(j0, max(j1, j0 + 1)):
        for i in range(i0, max(i1, i0 + 1)):
            box = shapely.box(ox + i * width, oy + j * height, ox + (i + 1) * width,
                              oy + (j + 1) * height)
            if box.intersection(shapely.box(*bounds)).area > 0 or \
                    (bounds[0] == bounds[2] or bounds[1] == bounds[3]):
                out.append((f"{i}_{j}", box))
    return out


def safe_name(text: str) -> str:
    """A file-name-safe sheet id (letters, digits, ``-_.``; others become ``_``)."""
    name = "".join(c if c.isalnum() or c in "-_." else "_" for c in str(text)).strip(".")
    return name or "sheet"


@dataclass(frozen=True)
class RasterSheet:
    """One sheet to cut from a raster (picklable: it runs on a Dask worker as well)."""

    source: str
    sheet: Any  # shapely polygon
    output: str


def clip_raster_sheet(task: RasterSheet) -> bool:
    """:func:`clip_raster` of one :class:`RasterSheet`."""
    return clip_raster(Path(task.source), task.sheet, Path(task.output))


def clip_raster(path: Path, sheet, output: Path, block: int = 2048) -> bool:
    """Write the part of raster ``path`` inside polygon ``sheet`` to ``output`` on the raster's
    own grid, over the sheet's bounds (cells outside the raster or the polygon are nodata, or
    alpha 0). Returns False (and writes nothing) when the sheet holds no valid data.
    The valid cells are GDAL's dataset mask's (a cell where any band is valid, or the alpha
    band's); a raster whose bands have different nodata values is refused
    (:func:`toolbox.io.raster.require_one_nodata`).

    A raster without nodata or alpha band (every value valid, or a mask band) gets NaN as
    nodata when it holds floats, else an alpha band: a nodata of 0 would turn its valid zeros
    (sea level, black pixels) into no data."""
    import rasterio
    from rasterio.features import geometry_mask
    from rasterio.windows import Window, from_bounds

    from toolbox.io.grid import GridSpec
    from toolbox.io.raster import dataset_transform, require_one_nodata
    from toolbox.raster.writer import RasterWriter, copy_band_metadata, empty_marker

    with rasterio.open(path) as src:
        require_one_nodata(src, "INPUT", path)
        t = dataset_transform(src)
        win = from_bounds(*sheet.bounds, transform=t)
        col0, row0 = math.floor(win.col_off + 1e-6), math.floor(win.row_off + 1e-6)
        cols = max(1, math.ceil(win.col_off + win.width - 1e-6) - col0)
        rows = max(1, math.ceil(win.row_off + win.height - 1e-6) - row0)
        if col0 >= src.width or row0 >= src.height or col0 + cols <= 0 or row0 + rows <= 0:
            return False
        grid = GridSpec(t @ rasterio.Affine.translation(col0, row0), cols, rows, src.crs)
        bands = [i for i, ci in enumerate(src.colorinterp) if ci.name == "alpha"]
        alpha = bool(bands)
        nodata, added = src.nodata, False  # added: an alpha band of ours
        if src.nodata is None and not alpha:
            nodata, added = empty_marker(src.dtypes[0])
        # the writer's alpha band is the last one; a source's alpha elsewhere stays a band
        # whose colour interpretation is copied below
        last_alpha = added or (alpha and bands[0] == src.count - 1 and src.count > 1)
        if added:
            bands = [src.count]
        with RasterWriter(output, grid, src.count + added, src.dtypes[0],
                          None if alpha or added else nodata, alpha=last_alpha) as dst:
            if added:
                from rasterio.enums import ColorInterp

                dst.dataset.colorinterp = [*src.colorinterp, ColorInterp.alpha]
            else:
                dst.dataset.colorinterp = src.colorinterp
            copy_band_metadata(src, dst.dataset)  # scale/offset, units, palette, descriptions
            any_valid = False
            for r in range(0, rows, block):
                for c in range(0, cols, block):
                    w = Window(col0 + c, row0 + r, min(block, cols - c), min(block, rows - r))
                    data = src.read(window=w, boundless=True, fill_value=nodata or 0)
                    # GDAL's dataset mask: a cell is empty only when every band is (or
                    # alpha 0); band 1's mask dropped the valid dark pixels of an RGB
                    valid = src.dataset_mask(window=w, boundless=True) > 0
                    wt = rasterio.windows.transform(w, t)
                    valid &= ~geometry_mask([sheet], out_shape=valid.shape, transform=wt)
                    any_valid |= bool(valid.any())
                    if added:
                        opaque = np.iinfo(data.dtype).max
                        data = np.concatenate([data, np.where(valid, opaque, 0).astype(
                            data.dtype)[np.newaxis]])
                    elif alpha:
                        data[bands[0]][~valid] = 0
                    else:
                        data[:, ~valid] = nodata
                    dst.write(Window(c, r, w.width, w.height), data)
            if not any_valid:  # a sheet without valid data: its file is not kept
                dst.discard()
    return any_valid


@dataclass(frozen=True)
class VectorSheet:
    """One sheet to cut from vector layers (picklable: it runs on a Dask worker as well):
    ``layers`` maps each layer's name to its features whose bounding box meets the sheet, in
    layer order."""

    layers: dict[str, Any]  # name -> GeoDataFrame
    sheet: Any  # shapely polygon
    output: str


def vector_sheets(layers: dict[str, Any], sheets: list):
    """One :class:`VectorSheet` per ``(polygon, output path)`` of ``sheets``, lazily: each
    carries the features of every frame of ``layers`` whose bounding box meets its polygon
    (spatial index), in the layer's order, so that the clipped file is the one of the whole
    layer."""
    indexes = {name: frame.sindex for name, frame in layers.items()}
    for polygon, output in sheets:
        yield VectorSheet({name: frame.iloc[np.sort(indexes[name].query(polygon))]
                           for name, frame in layers.items()}, polygon, str(output))


def clip_vector_sheet(task: VectorSheet) -> bool:
    """:func:`clip_vector` of one :class:`VectorSheet`; True when the sheet file was written."""
    return clip_vector(task.layers, task.sheet, Path(task.output)) > 0


def clip_vector(layers: dict[str, Any], sheet, output: Path) -> int:
    """Write the features of each frame of ``layers`` clipped to polygon ``sheet`` into
    GeoPackage ``output``, as layers of the same names (those with features in the sheet).
    A clipped feature keeps only the pieces of its own kind: a polygon along the sheet's edge
    also meets it in lines and points, which are dropped. Returns the feature count (0:
    nothing written)."""
    import geopandas as gpd

    from toolbox.io.vector import _GEOMETRY_FAMILIES
    from toolbox.io.vector_write import geometry_kinds, write_layers

    clipped = {}
    for name, frame in layers.items():
        inside = frame[frame.intersects(sheet)]
        if inside.empty:
            continue
        part = gpd.clip(inside, sheet, keep_geom_type=True)
        kinds = geometry_kinds(inside)
        if len(kinds) == 1:  # geopandas keeps other kinds when a sheet has nothing else
            part = part[part.geom_type.isin(_GEOMETRY_FAMILIES[kinds.pop()])]
        part = part[~part.geometry.is_empty]
        if not part.empty:
            clipped[name] = part
    if clipped:
        write_layers(output, clipped)
    return sum(len(frame) for frame in clipped.values())


def sheet_ids_unique(ids: list[str]) -> list[str]:
    """Make file-safe ids unique by appending ``-2``, ``-3``... to repeats."""
    seen: dict[str, int] = {}
    out = []
    for raw in ids:
        name = safe_name(raw)
        seen[name] = seen.get(name, 0) + 1
        out.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    return out


def bounds_union(bounds: list) -> tuple[float, float, float, float]:
    b = np.asarray(bounds, dtype=float)
    return (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())
