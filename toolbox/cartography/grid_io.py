"""Map grid layers (GeoDataFrames) for an extent or for every sheet of a sheet layer."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from toolbox.cartography.grid import ground_step, map_grid


@dataclass(frozen=True)
class SheetSource:
    """The sheets: every polygon of ``sheets`` (a vector layer; ids from its ``sheet_id``
    field, else 1, 2, ...), or one sheet on ``extent`` (``.bounds``, ``.crs``; without a CRS
    it takes ``crs``)."""

    extent: Any = None
    sheets: Any = None
    sheet_id: str | None = None
    crs: Any = None


@dataclass(frozen=True)
class MapGridRequest:
    """A map grid at ``scale`` (1:scale): a node every ``map_step`` mm on paper, ``style``
    crosses (arms ``cross_size`` mm) or lines, over ``sheets``."""

    sheets: SheetSource
    scale: float
    map_step: float
    style: str = "crosses"
    cross_size: float = 4.0


def sheet_polygons(source: SheetSource) -> tuple[list[tuple[str, Any]], Any]:
    """``[(sheet id, polygon)]`` and the CRS of the sheets."""
    import shapely

    from toolbox.io.vector import read_vector

    if source.sheets is not None:
        frame = read_vector(source.sheets, name="SHEETS")
        field = source.sheet_id
        ids = [str(v) for v in frame[field]] if field else [str(i + 1) for i in range(len(frame))]
        return list(zip(ids, frame.geometry.values)), frame.crs
    extent = source.extent
    crs = extent.crs if extent.crs is not None else source.crs
    return [("1", shapely.box(*extent.bounds))], crs


def guard_grid(sheets: list, step: float, style: str, scale: float, map_step: float) -> None:
    """Refuse before drawing when the grid nodes (crosses) or lines of every sheet together are
    too many (a huge extent, or a tiny MAP_STEP)."""
    from toolbox.limits import check_size

    total, width, height = 0.0, 0.0, 0.0
    for _, polygon in sheets:
        if polygon is None or polygon.is_empty:
            continue
        xmin, ymin, xmax, ymax = polygon.bounds
        nx, ny = (xmax - xmin) / step + 1, (ymax - ymin) / step + 1
        total += nx * ny if style == "crosses" else nx + ny
        width, height = max(width, xmax - xmin), max(height, ymax - ymin)
    check_size("features", total, "MAP_STEP",
               f"{map_step:g} mm at 1:{scale:g} ({step:g} ground units) over {len(sheets):,} "
               f"sheet(s) up to {width:,.0f} x {height:,.0f}",
               "use a larger MAP_STEP or a smaller EXTENT", "grid " + (
                   "crosses" if style == "crosses" else "lines"))


def grid_frames(request: MapGridRequest):
    """(grid GeoDataFrame, labels GeoDataFrame, ground step, CRS) of a map grid."""
    import geopandas as gpd
    import shapely

    step = ground_step(request.scale, request.map_step)
    arm = ground_step(request.scale, request.cross_size) / 2.0
    sheets, crs = sheet_polygons(request.sheets)
    guard_grid(sheets, step, request.style, request.scale, request.map_step)
    rows, label_rows = [], []
    for sheet_id, polygon in sheets:
        grid = map_grid(polygon.bounds, step, request.style, arm)
        for geom, kind, value in zip(grid.geometries, grid.kinds, grid.values):
            clipped = shapely.intersection(geom, polygon)
            if not clipped.is_empty:
                rows.append({"sheet": sheet_id, "kind": kind, "value": value,
                             "geometry": clipped})
        for label in grid.labels:
            label_rows.append({"sheet": sheet_id, **label,
                               "geometry": shapely.points(label["x"], label["y"])})
    columns = ["sheet", "kind", "value", "geometry"]
    grid_frame = gpd.GeoDataFrame(rows or None, columns=columns, geometry="geometry", crs=crs)
    label_columns = ["sheet", "text", "axis", "value", "edge", "geometry"]
    labels = gpd.GeoDataFrame([{k: r[k] for k in label_columns} for r in label_rows] or None,
                              columns=label_columns, geometry="geometry", crs=crs)
    if request.style == "crosses" and len(grid_frame):  # one MultiLineString per node
        grid_frame["geometry"] = [g if g.geom_type == "MultiLineString" else
                                  shapely.multilinestrings([g]) for g in grid_frame.geometry]
    return grid_frame, labels, step, crs
