"""Map grid layers (GeoDataFrames) for an extent or for every sheet of a sheet layer."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from toolbox.cartography.grid import ground_step, map_grid


@dataclass(frozen=True)
class SheetSource:
    """The sheets: every polygon of ``sheets`` (a vector layer; ids from its ``sheet_id``
    field, else 1, 2, ...), or one sheet on ``extent`` (``.bounds``, ``.crs``). ``crs`` (the
    CRS parameter) labels sheets or an extent that name none; one that names another CRS is
    refused (:func:`toolbox.io.crs.common_crs`)."""

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


def sheet_polygons(source: SheetSource, warn=None) -> tuple[list[tuple[str, Any]], Any]:
    """``[(sheet id, polygon)]`` and the CRS of the sheets (see :func:`sheet_polygon`): their
    own, else ``source.crs``; both given and different: an InputDataError naming both."""
    import shapely

    from toolbox.io.crs import common_crs
    from toolbox.io.vector import read_vector

    if source.sheets is not None:
        frame = read_vector(source.sheets, name="SHEETS")
        if not len(frame):
            from toolbox.errors import ParameterError

            raise ParameterError("SHEETS", f"{source.sheets} has no features: no sheet to draw")
        field = source.sheet_id
        ids = [str(v) for v in frame[field]] if field else [str(i + 1) for i in range(len(frame))]
        return [(sheet_id, sheet_polygon(geom, row, sheet_id if field else None, warn))
                for row, (sheet_id, geom) in enumerate(zip(ids, frame.geometry.values), 1)
                ], common_crs({"SHEETS": frame.crs}, source.crs,
                              {"SHEETS": frame.total_bounds})
    extent = source.extent
    return [("1", shapely.box(*extent.bounds))], common_crs({"EXTENT": extent.crs}, source.crs,
                                                            {"EXTENT": extent.bounds})


def sheet_polygon(geom, row: int, sheet_id: str | None = None, warn=None):
    """The area of SHEETS feature ``row`` (1-based; ``sheet_id`` its SHEET_ID): one that
    crosses itself is repaired as topology:overlay repairs it (GEOS ``make_valid``, with a
    warning through ``warn``); a null or empty one, or one without area, is refused."""
    import shapely

    from toolbox.errors import ParameterError
    from toolbox.topology.setops import repaired_parts

    which = f"feature {row}" + (f" (sheet {sheet_id!r})" if sheet_id is not None else "")
    if geom is None or geom.is_empty:
        raise ParameterError("SHEETS", f"{which} has {'no' if geom is None else 'an empty'} "
                             "geometry: every sheet must be a polygon with an area")
    if not geom.is_valid:
        reason = shapely.is_valid_reason(geom)
        parts = repaired_parts(geom)
        geom = shapely.multipolygons(parts) if len(parts) else shapely.Polygon()
        if warn is not None and geom.area > 0:
            warn(f"SHEETS {which} is not a valid polygon ({reason}): repaired (GEOS make_valid)"
                 f", {geom.area:,.2f} square units in {len(parts)} part(s)")
    if not geom.area > 0:
        raise ParameterError("SHEETS", f"{which} has no area (a polygon collapsed to a line or "
                             "a point): every sheet must be a polygon with an area")
    return geom


def guard_grid(sheets: list, step: float, style: str, scale: float, map_step: float) -> None:
    """Refuse before drawing when the grid nodes (crosses) or lines of every sheet together are
    too many (a huge extent, or a tiny MAP_STEP)."""
    from toolbox.limits import check_size

    total, width, height = 0.0, 0.0, 0.0
    for _, polygon in sheets:
        xmin, ymin, xmax, ymax = polygon.bounds
        nx, ny = (xmax - xmin) / step + 1, (ymax - ymin) / step + 1
        total += nx * ny if style == "crosses" else nx + ny
        width, height = max(width, xmax - xmin), max(height, ymax - ymin)
    check_size("features", total, "MAP_STEP",
               f"{map_step:g} mm at 1:{scale:g} ({step:g} ground units) over {len(sheets):,} "
               f"sheet(s) up to {width:,.0f} x {height:,.0f}",
               "use a larger MAP_STEP or a smaller EXTENT", "grid " + (
                   "crosses" if style == "crosses" else "lines"))


def grid_frames(request: MapGridRequest, warn=None):
    """(grid GeoDataFrame, labels GeoDataFrame, ground step, CRS) of a map grid; every grid
    feature is a MultiLineString: its line pieces inside the sheet (a line touching the
    sheet's outline at a point is no piece)."""
    import geopandas as gpd
    import shapely

    step = ground_step(request.scale, request.map_step)
    arm = ground_step(request.scale, request.cross_size) / 2.0
    sheets, crs = sheet_polygons(request.sheets, warn)
    guard_grid(sheets, step, request.style, request.scale, request.map_step)
    rows, label_rows = [], []
    for sheet_id, polygon in sheets:
        grid = map_grid(polygon.bounds, step, request.style, arm)
        for geom, kind, value in zip(grid.geometries, grid.kinds, grid.values):
            pieces = shapely.get_parts(shapely.get_parts(shapely.intersection(geom, polygon)))
            lines = [p for p in pieces if p.geom_type == "LineString" and p.length > 0]
            if lines:
                rows.append({"sheet": sheet_id, "kind": kind, "value": value,
                             "geometry": shapely.multilinestrings(lines)})
        for label in grid.labels:
            label_rows.append({"sheet": sheet_id, **label,
                               "geometry": shapely.points(label["x"], label["y"])})
    if not rows and warn is not None:  # the labels along the edges may still be there
        warn(f"no grid {'line' if request.style == 'lines' else 'cross'} (every {step:g} m, "
             f"{request.map_step:g} mm at 1:{request.scale:g}) falls inside the "
             f"{'sheets' if request.sheets.sheets is not None else 'EXTENT'}: the grid layer is "
             f"empty" + (f"; {len(label_rows)} label(s) of the grid lines crossing it written "
                         "(grid_labels)" if label_rows else ", and so are its labels"))
    columns = ["sheet", "kind", "value", "geometry"]
    grid_frame = gpd.GeoDataFrame(rows or None, columns=columns, geometry="geometry", crs=crs)
    label_columns = ["sheet", "text", "axis", "value", "edge", "geometry"]
    labels = gpd.GeoDataFrame([{k: r[k] for k in label_columns} for r in label_rows] or None,
                              columns=label_columns, geometry="geometry", crs=crs)
    return grid_frame, labels, step, crs
