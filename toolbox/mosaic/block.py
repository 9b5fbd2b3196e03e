"""The block of orthos as a whole: open and check the inputs, trace footprints, choose centres,
the mosaic grid, and the cut polygons / seamlines as GeoDataFrames (read and write)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.mosaic.sources import (
    OrthoSource,
    aligned,
    open_source,
    shadowed_alpha_message,
    valid_footprint,
)
from toolbox.raster.datasets import ThreadDatasets

CENTRES = ("nadir", "footprint")
FOOTPRINT_CELLS = 2048  # footprints are traced on masks decimated to this size
#: GDAL's block cache while the block is open (MB): the rasters kept open fill it with every
#: block they read, up to GDAL's default of 5 % of the RAM (a 10000 x 10000 seam's peak went
#: 753 -> 2276 MB); the overlapping reads it serves are a few rows of blocks apart
BLOCK_CACHE_MB = 64


def open_block(paths: list, name: str = "INPUT", feedback: Any = None,
               threads: int | None = None) -> tuple[list, Any]:
    """Open the orthos, check they are of one kind (:func:`check_same_kind`) and share one CRS,
    and trace their valid-data footprints. Returns ``(sources, pyproj CRS or None)``; the
    rasters stay open for the sources' reads until :func:`close_block` (closed here if this fails).
    ``threads``: GDAL's threads decoding the blocks of one read (GDAL_NUM_THREADS, while the
    block is open): for a caller whose reads span many blocks one at a time (the footprints'
    whole masks), not for one reading tiles on its own threads."""
    from pyproj import CRS

    from toolbox.io.crs import common_crs

    sources = []
    datasets = BlockDatasets(threads)
    try:
        for k, p in enumerate(paths):
            src = open_source(Path(p), k, datasets)  # INPUT in its refusals
            if src.name in {s.name for s in sources}:
                raise ParameterError(name, f"two inputs are named '{src.name}' (the file name "
                                     "identifies an ortho in the cut polygons): rename one")
            if sources:
                check_same_kind(sources[0], src, name)
            if feedback is not None and src.alpha_band is not None and src.nodata is not None:
                feedback.push_warning(shadowed_alpha_message(src))
            src.footprint = valid_footprint(src, FOOTPRINT_CELLS)
            sources.append(src)
            if feedback is not None:
                feedback.check_canceled()
        crs = common_crs({f"{name}[{s.index + 1}] ({s.name})":
                          CRS.from_wkt(s.crs.to_wkt()) if s.crs else None for s in sources},
                         bounds={f"{name}[{s.index + 1}] ({s.name})": s.bounds
                                 for s in sources})
    except BaseException:
        datasets.close()
        raise
    return sources, crs


def name_order(sources: list[OrthoSource]) -> list[int]:
    """Positions of ``sources`` in file-name order (the names are unique: :func:`open_block`):
    the order a block is partitioned and mosaicked in, so that no tie (a cell centre on a
    shared cut edge, two orthos with one centre, the fallback source of a cell) depends on
    the order the orthos were given in."""
    return sorted(range(len(sources)), key=lambda k: sources[k].name)


def check_same_kind(first: OrthoSource, other: OrthoSource, name: str = "INPUT") -> None:
    """:class:`ParameterError` naming ``name`` unless ``other`` has the band count and the data
    type of ``first``: a mosaic (and a seam's cost, which compares their values) takes their
    values as they are, so a Byte and a UInt16 ortho would be mixed raw (one half black)."""
    bands, other_bands = len(first.data_bands), len(other.data_bands)
    if bands != other_bands:
        raise ParameterError(name, f"'{first.path}' has {bands} bands but '{other.path}' has "
                             f"{other_bands}: mosaic orthos of one kind")
    if first.dtype != other.dtype:
        types = _gdal_type(first.dtype), _gdal_type(other.dtype)
        raise ParameterError(name, f"'{first.path}' is {types[0]} but '{other.path}' is "
                             f"{types[1]}: the orthos must share a data type; convert one "
                             f"with gdal_translate -ot {types[0]} -scale <its range> <the "
                             f"{types[0]} range> '{other.path}' converted.tif")


def _gdal_type(dtype: str) -> str:
    """GDAL's name of a numpy data type: Byte, UInt16, Int16, Float32..."""
    if dtype == "uint8":
        return "Byte"
    return "U" + dtype[1:].capitalize() if dtype.startswith("u") else dtype.capitalize()


def close_block(sources: list[OrthoSource]) -> None:
    """Close the rasters that :func:`open_block` keeps open for the sources' reads and restore
    GDAL's block cache size."""
    for datasets in {id(s.datasets): s.datasets for s in sources
                     if s.datasets is not None}.values():
        datasets.close()


class BlockDatasets(ThreadDatasets):
    """The block's rasters kept open (:class:`~toolbox.raster.datasets.ThreadDatasets`) with
    GDAL's block cache capped at :data:`BLOCK_CACHE_MB` from creation to :meth:`close` (the
    mosaic writer's own cache setting nests inside). Made and closed in one thread."""

    def __init__(self, threads: int | None = None) -> None:
        import rasterio

        from toolbox.io.raster import gdal_cache_max

        super().__init__()
        options = {"GDAL_CACHEMAX": gdal_cache_max(BLOCK_CACHE_MB)}
        if threads is not None and threads > 1:
            options["GDAL_NUM_THREADS"] = str(threads)
        self._cache = rasterio.Env(**options)
        self._cache.__enter__()

    def close(self) -> None:
        super().close()
        cache, self._cache = self._cache, None
        if cache is not None:
            cache.__exit__(None, None, None)


def centres_of(sources: list[OrthoSource], how: str, points: dict | None = None,
               feedback: Any = None) -> list[tuple[float, float]]:
    """Centre of each ortho's Voronoi cell: its nadir point (``points[name]``, else the ortho's
    tags) or its footprint centre (``how="footprint"``, and the fallback, with a warning)."""
    out = []
    for s in sources:
        nadir = (points or {}).get(s.name) or s.nadir
        if how == "nadir" and nadir is None:
            if feedback is not None:
                feedback.push_warning(f"{s.name}: no nadir point (tags NADIR_X/NADIR_Y or "
                                      "NADIR_POINTS): its footprint centre is used")
        out.append(tuple(nadir) if how == "nadir" and nadir is not None else s.centre)
    return out


def read_in_crs(layer, crs: Any, name: str):
    """A vector layer of the block in the orthos' CRS ``crs``: reprojected when it is in
    another one, taken to be in ``crs`` when it has none or another definition of it (an ESRI
    WKT: :func:`toolbox.io.crs.one_crs`, nothing moves)."""
    from toolbox.io.vector import read_vector

    return frame_in_crs(read_vector(layer, crs=crs, name=name), crs, name)


def frame_in_crs(frame, crs: Any, what: str):
    """``frame`` in ``crs``: as it is without a CRS on either side, or in ``crs`` itself; taken
    to be in ``crs`` when it is another definition of it (:func:`toolbox.io.crs.one_crs`,
    nothing moves); else reprojected, with a note naming ``what``."""
    if crs is None or frame.crs is None or frame.crs is crs:
        return frame
    from toolbox.io.crs import note_transformation, one_crs

    if one_crs(frame.crs, crs, frame.total_bounds):
        return frame.set_crs(crs, allow_override=True)
    note_transformation(None, frame.crs, crs, frame.total_bounds, what=what)
    return frame.to_crs(crs)


def nadir_points_from_layer(layer, field: str | None, sources: list[OrthoSource],
                            name: str = "NADIR_POINTS", crs: Any = None) -> dict:
    """``{ortho name: (x, y)}`` from a point layer (in the orthos' CRS ``crs``: reprojected
    from another): matched by ``field`` (ortho file names) or, without it, by feature order."""
    import shapely

    from toolbox.io.vector import single_points

    frame = read_in_crs(layer, crs, name)
    points = single_points(frame.geometry.values, name)
    bad = [row for row, g in enumerate(points, start=1)
           if g is None or g.is_empty or g.geom_type != "Point"]
    if bad:
        raise ParameterError(name, f"must hold one point per feature: feature row(s) "
                             f"{', '.join(map(str, bad[:5]))} are empty, null or not points")
    xy = [tuple(p) for p in shapely.get_coordinates(points).tolist()]
    if field is None:
        if len(xy) != len(sources):
            raise ParameterError(name, f"has {len(xy)} points for {len(sources)} orthos; give "
                                 "one per ortho in input order, or name the matching field")
        return {s.name: p for s, p in zip(sources, xy, strict=True)}
    keys = [str(v) for v in frame[field]]
    found = dict(zip(keys, xy, strict=True))
    missing = [s.name for s in sources if s.name not in found]
    if missing:
        raise ParameterError(name, f"has no point whose {field} is {', '.join(missing)}")
    return found


def mosaic_grid(sources: list[OrthoSource], crs: Any, cell: float | None, area,
                feedback: Any = None):
    """The mosaic grid: cells of ``cell`` (default: the finest input's) over ``area``'s bounds,
    aligned with the first input of that cell size. Warns when inputs must be resampled."""
    from affine import Affine

    from toolbox.io.grid import GridSpec, cell_slack

    finest = min(sources, key=lambda s: s.res[0])
    cell = cell or finest.res[0]
    ref = next((s for s in sources if math.isclose(s.res[0], cell) and
                math.isclose(s.res[1], cell)), None)
    ox, oy = (ref.transform.c, ref.transform.f) if ref is not None else (0.0, 0.0)
    x0, y0, x1, y1 = area.bounds
    eps = cell_slack(cell, x0, y0, x1, y1, ox, oy)  # an edge on the lattice up to rounding
    x0 = ox + math.floor((x0 - ox) / cell + eps) * cell
    y1 = oy + math.ceil((y1 - oy) / cell - eps) * cell
    cols = max(1, math.ceil((x1 - x0) / cell - eps))
    rows = max(1, math.ceil((y1 - y0) / cell - eps))
    from toolbox.io.grid import max_cells_default

    if cols * rows > max_cells_default():
        raise ParameterError("CELL_SIZE", f"{cell:g} gives a {cols} x {rows} mosaic, over the "
                             f"limit of {max_cells_default():,} cells (raise TOOLBOX_MAX_CELLS)")
    grid = GridSpec(Affine(cell, 0, x0, 0, -cell, y1), cols, rows, crs)
    off = [s.name for s in sources if not aligned(s, grid.transform)]
    if off and feedback is not None:
        feedback.push_warning(f"{', '.join(off)} not on the mosaic grid ({cell:g} cells): "
                              "resampled onto it")
    return grid


def cells_table(sources: list[OrthoSource], cells: list, output: Any = None) -> tuple:
    """The cut polygons as ``(fields, geometries)`` (one row per ortho with a non-empty cell;
    :func:`toolbox.io.vector_write.write_table_layers`): ``source_id``, ``source``, ``path``
    (the ortho's path relative to the folder of ``output``, the file written, not a machine
    path) and ``area``; MultiPolygons."""
    from shapely.geometry import MultiPolygon

    rows = [(s, c) for s, c in zip(sources, cells, strict=True) if not c.is_empty]
    fields = {"source_id": np.array([s.index + 1 for s, _ in rows], dtype="int64"),
              "source": np.array([s.name for s, _ in rows], dtype=object),
              "path": np.array([relative_path(s.path, output) for s, _ in rows], dtype=object),
              "area": np.array([float(c.area) for _, c in rows], dtype="float64")}
    return fields, [c if c.geom_type == "MultiPolygon" else MultiPolygon([c]) for _, c in rows]


def relative_path(path: Any, output: Any) -> str:
    """``path`` relative to the folder of ``output`` (``/``-separated); the file name alone when
    there is no output or no relative path (another drive)."""
    import os

    from toolbox.io.staging import final_folder

    if output is None:
        return Path(path).name
    try:
        rel = os.path.relpath(Path(path).absolute(), final_folder(output))
    except ValueError:
        return Path(path).name
    return Path(rel).as_posix()


def seams_table(sources: list[OrthoSource], seams: list, methods: dict | None = None,
                default_method: str = "voronoi") -> tuple:
    """Seamlines ``(i, j, line)`` (see :mod:`toolbox.mosaic.index_seams`) as ``(fields,
    geometries)`` (:func:`toolbox.io.vector_write.write_table_layers`): ``a_id``, ``b_id``,
    ``a``, ``b``, ``method`` (per pair from ``methods``, else ``default_method``) and
    ``length``; MultiLineStrings. Without seams every field is float64, as in an empty
    GeoDataFrame (:func:`seams_frame`)."""
    from shapely.geometry import MultiLineString

    if not seams:
        return {name: np.array([], dtype="float64")
                for name in ("a_id", "b_id", "a", "b", "method", "length")}, []
    fields = {"a_id": np.array([i + 1 for i, _, _ in seams], dtype="int64"),
              "b_id": np.array([j + 1 for _, j, _ in seams], dtype="int64"),
              "a": np.array([sources[i].name for i, _, _ in seams], dtype=object),
              "b": np.array([sources[j].name for _, j, _ in seams], dtype=object),
              "method": np.array([(methods or {}).get((i, j), default_method)
                                  for i, j, _ in seams], dtype=object),
              "length": np.array([float(line.length) for _, _, line in seams],
                                 dtype="float64")}
    return fields, [MultiLineString(list(getattr(line, "geoms", [line])))
                    for _, _, line in seams]


def seams_frame(sources: list[OrthoSource], seams: list, crs: Any, methods: dict | None = None,
                default_method: str = "voronoi"):
    """GeoDataFrame of seamlines ``(i, j, line)``: :func:`seams_table`'s columns."""
    import geopandas as gpd

    fields, geoms = seams_table(sources, seams, methods, default_method)
    return gpd.GeoDataFrame(fields, geometry=gpd.GeoSeries(geoms, crs=crs), crs=crs)


def seam_methods(layer: Any, sources: list[OrthoSource]) -> dict:
    """``{(i, j): method}`` from the ``seamlines`` layer next to a cut-polygons layer (the
    GeoPackage mosaic:seamlines writes); empty when there is none."""
    import pyogrio

    path = getattr(layer, "path", layer)  # a VectorLayerRef, a path or 'path|layername=...'
    if not isinstance(path, (str, Path)):
        return {}
    path = Path(str(path).split("|", 1)[0])
    try:
        if "seamlines" not in {str(n) for n, _ in pyogrio.list_layers(path)}:
            return {}
        frame = pyogrio.read_dataframe(path, layer="seamlines", read_geometry=False)
    except Exception:  # noqa: BLE001 - not a GeoPackage with that layer: no methods known
        return {}
    if not {"a", "b", "method"} <= set(frame.columns):
        return {}
    index = {s.name: s.index for s in sources}
    out = {}
    for a, b, method in zip(frame["a"], frame["b"], frame["method"], strict=True):
        if a in index and b in index:
            out[tuple(sorted((index[a], index[b])))] = str(method)
    return out


def cells_from_layer(layer, field: str, sources: list[OrthoSource],
                     name: str = "CUTLINES", crs: Any = None, feedback: Any = None) -> list:
    """Cut polygon per source from a polygon layer (in the orthos' CRS ``crs``: reprojected
    from another) whose ``field`` holds the ortho names (or 1-based source ids); several
    features of one source are united; sources without a feature get an empty cell. Features
    without geometry and sources left without a polygon are warned about on ``feedback``."""
    import shapely

    frame = read_in_crs(layer, crs, name)
    if field not in frame.columns:
        raise ParameterError(name, f"has no field '{field}'; fields are: "
                             f"{', '.join(c for c in frame.columns if c != 'geometry')}")
    by_name = {s.name: s.index for s in sources}
    parts: dict[int, list] = {}
    no_geometry = []
    for row, (value, geom) in enumerate(zip(frame[field], frame.geometry, strict=True), 1):
        key = str(value)
        if key in by_name:
            k = by_name[key]
        elif key.isdigit() and 1 <= int(key) <= len(sources):
            k = int(key) - 1
        else:
            raise InputDataError(f"{name}: feature with {field} = {key!r} matches no input "
                                 f"ortho (names: {', '.join(by_name)})")
        if geom is not None and not geom.is_empty:
            parts.setdefault(k, []).append(  # overlapping parts united, not cut out
                shapely.make_valid(geom, method="structure", keep_collapsed=False))
        else:
            no_geometry.append(f"row {row} ({sources[k].name})")
    if feedback is not None:
        if no_geometry:
            feedback.push_warning(f"{name}: {len(no_geometry)} feature(s) without geometry, "
                                  f"ignored: {', '.join(no_geometry[:5])}")
        left = [s.name for s in sources if s.index not in parts]
        if left:
            feedback.push_warning(f"{name}: no cut polygon for {', '.join(left)}: used only "
                                  "where the cut polygons' orthos have no data")
    return [shapely.union_all(parts[k]) if k in parts else shapely.Polygon()
            for k in range(len(sources))]


def union_area(sources: list[OrthoSource]):
    import shapely

    return shapely.union_all([s.footprint for s in sources])

