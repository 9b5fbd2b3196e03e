"""mosaic:cut - clip a mosaic (or any raster or vector) to map sheets."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Field, File, Number, VectorLayer
from toolbox.parameters.outputs import Output, OutputFolder
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter


class RasterOrVector(File):
    """A raster or vector file, or one layer of a vector file in QGIS's layer-source syntax
    (``path|layername=NAME``, validated as a :class:`VectorLayer`)."""

    def validate(self, value, ctx):
        if isinstance(value, str) and "|" in value:
            return VectorLayer(self.name).validate(value, ctx)
        return super().validate(value, ctx)


@register
class MosaicCut(Algorithm):
    """Clip a raster or a vector layer to map sheets, one file per sheet named by its id (the
    thesis' "taglio" of the merged models to the map unit).

    Sheets come from SHEETS (a polygon layer; ids from ID_FIELD, else the feature number) or
    from a sheet grid: SCALE (the map scale denominator) and the paper SHEET_WIDTH x
    SHEET_HEIGHT in cm give the ground size of a sheet (e.g. 1:2000, 50 x 40 cm -> 1000 x 800 m);
    sheet (i, j) spans ORIGIN_X + i·W .. ORIGIN_X + (i+1)·W (and likewise north) and is named
    "i_j". Rasters are clipped on their own grid over the sheet's bounds (outside the sheet
    polygon: nodata or alpha 0; a raster without either gets NaN nodata if it holds floats,
    else an alpha band, so its valid zeros stay valid) as tiled GeoTIFFs <id>.tif; vectors are
    clipped (GEOS) into
    <id>.gpkg, every layer of the file (or the one of "path|layername=NAME") under its own
    name, each feature keeping the pieces of its own kind (a polygon along a sheet edge gives
    no line). Sheets holding no data are skipped. OUTPUT is a folder; it also receives
    sheets.gpkg, the sheet index (layer sheets: sheet_id, file, written). The sheet files are
    written all or none
    (staged, moved into OUTPUT on success); an existing one is replaced only with --overwrite,
    other files of OUTPUT are left alone. Sheets are cut in parallel on local threads or on a
    Dask cluster (SCHEDULER or DASK_SCHEDULER_ADDRESS; the workers write the sheet files, so
    OUTPUT must be on storage they share; a raster INPUT is read by the workers too, a vector
    layer is read once and each sheet's task carries its own features).
    """

    id = "mosaic:cut"
    display_name = "Cut to map sheets"
    group = "Mosaic"
    short_help = "Clip a raster or vector to map sheets (grid or polygons), one file per sheet."
    parameters = [
        RasterOrVector("INPUT", "raster (GeoTIFF...) or vector file (GeoPackage, Shapefile...: "
                       "all its layers, or one as 'path|layername=NAME') to clip"),
        VectorLayer("SHEETS", "sheet polygons (default: a grid from SCALE and the sheet size)",
                    geometry_types=["polygon"], optional=True),
        Field("ID_FIELD", "field of SHEETS with the sheet ids (default: feature number)",
              parent="SHEETS", optional=True),
        Number("SCALE", "map scale denominator for the sheet grid (e.g. 2000)", optional=True,
               min_value=1),
        Number("SHEET_WIDTH", "paper sheet width, cm", default=50.0, min_value=0,
               min_exclusive=True),
        Number("SHEET_HEIGHT", "paper sheet height, cm", default=40.0, min_value=0,
               min_exclusive=True),
        Number("ORIGIN_X", "sheet grid origin, easting", default=0.0),
        Number("ORIGIN_Y", "sheet grid origin, northing", default=0.0),
        scheduler_parameter("the sheets"),
        OutputFolder("OUTPUT", "folder for the sheet files"),
    ]
    outputs = [Output("STATISTICS", "sheets written and skipped", "dict")]

    def check(self, params):
        if params["SHEETS"] is None and params["SCALE"] is None:
            raise self.fail("SCALE", "is required without SHEETS (the sheet grid needs a scale)")
        if params["SHEETS"] is not None and params["SCALE"] is not None:
            raise self.fail("SCALE", "does not apply with SHEETS (the sheets are given)")

    def planned_files(self, params):
        from toolbox.mosaic.sheets import sheet_ids_unique

        _, kind, _, sheets = _sheets(params)
        suffix = ".tif" if kind == "raster" else ".gpkg"
        names = sheet_ids_unique([sid for sid, _ in sheets])
        return {"OUTPUT": [f"{name}{suffix}" for name in names] + ["sheets.gpkg"]}

    def process(self, params, feedback: Feedback):
        import geopandas as gpd

        from toolbox.executor import map_tiles
        from toolbox.io.vector_write import write_layers
        from toolbox.mosaic.sheets import (
            RasterSheet,
            clip_raster_sheet,
            clip_vector_sheet,
            sheet_ids_unique,
            vector_sheets,
        )

        source, kind, crs, sheets = _sheets(params)
        folder = params["OUTPUT"]
        names = sheet_ids_unique([sid for sid, _ in sheets])
        todo = [(sid, geom, folder / f"{name}{'.tif' if kind == 'raster' else '.gpkg'}")
                for (sid, geom), name in zip(sheets, names, strict=True)
                if geom is not None and not geom.is_empty]
        if kind == "raster":
            func, tasks = clip_raster_sheet, (RasterSheet(str(source), geom, str(target))
                                              for _, geom, target in todo)
        else:  # each task carries only its sheet's features
            func, tasks = clip_vector_sheet, vector_sheets(source, [(geom, target)
                                                                    for _, geom, target in todo])
        written = list(map_tiles(func, tasks, executor=executor_of(params), feedback=feedback,
                                 total=len(todo)))
        rows = [{"sheet_id": sid, "file": target.name if done else "", "written": bool(done),
                 "geometry": geom} for (sid, geom, target), done in zip(todo, written, strict=True)]
        write_layers(folder / "sheets.gpkg",
                     {"sheets": gpd.GeoDataFrame(rows, geometry="geometry", crs=crs)})
        done = [r["file"] for r in rows if r["written"]]
        return {"OUTPUT": folder, "STATISTICS": {
            "kind": kind, "sheets": len(rows), "written": len(done),
            "skipped_empty": len(rows) - len(done), "files": done}}


def _sheets(params):
    """``(source, kind, crs, [(sheet id, polygon)])`` of a run; too many sheets are refused
    before any is made."""
    import math

    from toolbox.errors import InputDataError
    from toolbox.limits import check_size
    from toolbox.mosaic.sheets import sheet_grid

    source, kind, crs, bounds = _open_input(params["INPUT"])
    if crs is not None:  # a File parameter: the runner's CRS check does not see into it
        from toolbox.io.crs import check_input_crs, parse_crs

        check_input_crs("mosaic:cut", "INPUT", parse_crs(crs, "INPUT"))
    if params["SHEETS"] is not None:
        from toolbox.mosaic.block import read_in_crs

        frame = read_in_crs(params["SHEETS"], crs, "SHEETS")  # reprojected from another CRS
        field = params["ID_FIELD"]
        raw = [str(v) for v in frame[field]] if field else \
            [str(k + 1) for k in range(len(frame))]
        check_size("sheets", len(frame), "SHEETS", f"has {len(frame):,} features, which",
                   "cut to fewer sheets")
        sheets = list(zip(raw, frame.geometry, strict=True))
        import shapely

        from toolbox.io.vector import no_geometry

        if no_geometry(frame.geometry.values).all():
            raise InputDataError(f"SHEETS has no sheet to cut by: its {len(frame)} feature(s) "
                                 "have no geometry (null or empty)")
        box = shapely.box(*bounds)
        if not any(g is not None and g.intersects(box) for _, g in sheets):
            sb = frame.total_bounds
            raise InputDataError(f"no sheet of SHEETS ({sb[0]:.0f}..{sb[2]:.0f}, "
                                 f"{sb[1]:.0f}..{sb[3]:.0f}) meets INPUT ({bounds[0]:.0f}.."
                                 f"{bounds[2]:.0f}, {bounds[1]:.0f}..{bounds[3]:.0f}): nothing "
                                 "to cut; are they of the same area and CRS?")
    else:
        side = params["SCALE"] / 100.0
        width, height = params["SHEET_WIDTH"] * side, params["SHEET_HEIGHT"] * side
        count = (math.floor((bounds[2] - params["ORIGIN_X"]) / width)
                 - math.floor((bounds[0] - params["ORIGIN_X"]) / width) + 1) * \
            (math.floor((bounds[3] - params["ORIGIN_Y"]) / height)
             - math.floor((bounds[1] - params["ORIGIN_Y"]) / height) + 1)
        check_size("sheets", count, "SHEET_WIDTH",
                   f"x SHEET_HEIGHT {params['SHEET_WIDTH']:g} x {params['SHEET_HEIGHT']:g} cm at "
                   f"1:{params['SCALE']:g} ({width:g} x {height:g} ground units) over the "
                   f"input's {bounds[2] - bounds[0]:,.0f} x {bounds[3] - bounds[1]:,.0f}",
                   "use larger sheets (SHEET_WIDTH, SHEET_HEIGHT) or a larger SCALE")
        sheets = sheet_grid(bounds, width, height, (params["ORIGIN_X"], params["ORIGIN_Y"]))
    if not sheets:
        raise InputDataError("no sheet meets the input's extent")
    if kind == "raster":  # each sheet is written over its whole bounds, on the input's cells
        import rasterio

        with rasterio.open(source) as src:
            cell_w, cell_h = abs(src.transform.a), abs(src.transform.e)
        name = "SHEETS" if params["SHEETS"] is not None else "SHEET_WIDTH"
        largest = max(((b[2] - b[0]) / cell_w) * ((b[3] - b[1]) / cell_h)
                      for b in (g.bounds for _, g in sheets if g is not None))
        check_size("cells", largest * len(sheets), name, f"({len(sheets):,} sheets over the "
                   f"input's {cell_w:g} x {cell_h:g} cells)", "use smaller or fewer sheets")
    return source, kind, crs, sheets


def _open_input(value):
    """``(source, "raster"|"vector", crs, bounds)``: a raster path, or the vector layers to cut
    (``{name: GeoDataFrame}``, in the first one's CRS): the layer a layer source names, else
    every layer of the file."""
    import warnings

    import numpy as np
    import rasterio

    from toolbox.errors import InputDataError, ParameterError
    from toolbox.io.vector import VectorLayerRef, open_layer, read_vector
    from toolbox.mosaic.sheets import bounds_union

    refs = [value] if isinstance(value, VectorLayerRef) else None
    if refs is None:
        from toolbox.io.gdal_errors import handled_gdal_errors

        with handled_gdal_errors(rasterio.errors.RasterioIOError):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
                with rasterio.open(value) as src:
                    if src.count > 0:  # sheets are cut on the input's cells, north-up
                        from toolbox.io.raster import (
                            dataset_transform,
                            require_georeferenced,
                            require_north_up,
                            require_one_nodata,
                        )

                        require_georeferenced(src, "INPUT", value)
                        require_one_nodata(src, "INPUT", value)
                        require_north_up(dataset_transform(src), "INPUT", value)
                        return value, "raster", src.crs, tuple(src.bounds)
        try:
            first = open_layer(str(value), "INPUT")
        except Exception as exc:  # neither GDAL nor OGR reads it
            raise ParameterError("INPUT", f"'{value}' is neither a raster nor a vector layer: "
                                 f"{str(exc).splitlines()[0]}") from None
        others, first.default_of = first.default_of, ()  # all are cut: none taken by default
        refs = [first, *(open_layer(f"{value}|layername={name}", "INPUT") for name in others)]
    from toolbox.mosaic.block import frame_in_crs

    layers, crs = {}, None
    for ref in refs:
        frame = read_vector(ref, name="INPUT")
        crs = frame.crs if crs is None else crs
        name = ref.layer or ref.info["layer_name"]
        layers[name] = frame_in_crs(frame, crs, f"INPUT layer {name}")
    bounds = [b for b in (f.total_bounds for f in layers.values()) if np.isfinite(b).all()]
    if not bounds:
        raise InputDataError(f"INPUT '{value}' has no features with a geometry: nothing to cut")
    return layers, "vector", crs, bounds_union(bounds)
