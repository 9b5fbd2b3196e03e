"""Map grid layers (GeoDataFrames) for an extent or for every sheet of a sheet layer."""

from __future__ import annotations

from typing import Any

from toolbox.cartography.grid import ground_step, map_grid


def sheet_polygons(params: dict) -> tuple[list[tuple[str, Any]], Any]:
    """``[(sheet id, polygon)]`` and the CRS from ``EXTENT`` or ``SHEETS`` (+ ``SHEET_ID``)."""
    import shapely

    from toolbox.io.vector import read_vector

    if params.get("SHEETS") is not None:
        frame = read_vector(params["SHEETS"], name="SHEETS")
        field = params.get("SHEET_ID")
        ids = [str(v) for v in frame[field]] if field else [str(i + 1) for i in range(len(frame))]
        return list(zip(ids, frame.geometry.values)), frame.crs
    extent = params["EXTENT"]
    crs = extent.crs if extent.crs is not None else params.get("CRS")
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


def grid_frames(params: dict):
    """(grid GeoDataFrame, labels GeoDataFrame, ground step, CRS) for the algorithm's params."""
    import geopandas as gpd
    import shapely

    step = ground_step(params["SCALE"], params["MAP_STEP"])
    arm = ground_step(params["SCALE"], params["CROSS_SIZE"]) / 2.0
    sheets, crs = sheet_polygons(params)
    guard_grid(sheets, step, params["STYLE"], params["SCALE"], params["MAP_STEP"])
    rows, label_rows = [], []
    for sheet_id, polygon in sheets:
        grid = map_grid(polygon.bounds, step, params["STYLE"], arm)
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
    if params["STYLE"] == "crosses" and len(grid_frame):  # one MultiLineString per node
        grid_frame["geometry"] = [g if g.geom_type == "MultiLineString" else
                                  shapely.multilinestrings([g]) for g in grid_frame.geometry]
    return grid_frame, labels, step, crs
