"""tin:to_raster - the TIN surface sampled at cell centres into a GeoTIFF (no smoothing)."""

from __future__ import annotations

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Crs, Enum, ExtentParameter, Integer, Number, RasterLayer
from toolbox.parameters.outputs import Output, OutputRaster
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.grid import grid_request
from toolbox.ui.tin import tin_parameter


@register
class ToRaster(Algorithm):
    """Rasterise a TIN: every cell gets the height of the TIN's plane at the cell centre
    (thesis eq. [43]-[44]; cell values belong to cell centres, par. 2.5.2), exactly, with no
    smoothing or resampling. Cells whose centre lies outside the TIN are NODATA.

    Grid (the rules of every raster output): TEMPLATE's grid (cut to EXTENT on its lattice when
    both are given); else CELL_SIZE over EXTENT as given (origin at its xmin/ymax, the east and
    south edges rounded up to whole cells), by default over the TIN's bounds snapped outwards to
    multiples of CELL_SIZE; MAX_CELLS guards the size. CRS (default: the TIN's) reprojects the
    TIN's nodes before rasterising (the triangles are kept; a warning says so); their heights
    are not converted, so a CRS or TEMPLATE stating another height datum than the TIN's is
    refused (one stated on one side only is taken as the other's). The raster is
    computed tile by tile on local threads (only the triangles touching each tile are drawn)
    and written as a tiled, DEFLATE GeoTIFF with overviews (COG: a Cloud Optimized GeoTIFF),
    so memory stays bounded for any size.
    """

    length_units = "horizontal"  # x, y in one unit (metres or feet); heights in their own

    id = "tin:to_raster"
    display_name = "TIN to raster"
    group = "TIN"
    short_help = "GeoTIFF of the TIN surface at cell centres (plane values, no smoothing)."
    parameters = [
        tin_parameter(),
        Number("CELL_SIZE", "cell size, CRS units (not needed with TEMPLATE)", optional=True,
               min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "output extent 'xmin,ymin,xmax,ymax' (default: the TIN's)",
                        optional=True),
        RasterLayer("TEMPLATE", "raster whose grid (extent, cells, CRS) to copy", optional=True),
        Integer("MAX_CELLS", "refuse outputs with more cells than this (default: "
                "TOOLBOX_MAX_CELLS or 1e9)", optional=True, min_value=1),
        Crs("CRS", "output CRS (default: the TIN's)", optional=True),
        Number("NODATA", "value of cells outside the TIN", default=-9999.0),
        Enum("DATA_TYPE", "cell type", options=["float32", "float64"], default="float32"),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        scheduler_parameter(),
        OutputRaster("OUTPUT", "DEM GeoTIFF"),
    ]
    outputs = [Output("STATISTICS", "grid size, cells with data, height range", "json")]

    def check(self, params):
        from toolbox.io.raster import check_nodata_fits

        grid_request(params).check()
        check_nodata_fits(params["NODATA"], params["DATA_TYPE"])

    def process(self, params, feedback: Feedback):
        from functools import partial

        from toolbox.io.crs import crs_label, one_crs, one_horizontal_crs, same_crs
        from toolbox.io.raster import nodata_clash_warning, nodata_clashes
        from toolbox.raster.engine import process_raster
        from toolbox.raster.writer import RasterWriter
        from toolbox.terrain.gridding.tin_raster import TinTiles, tin_tile
        from toolbox.terrain.tin.store import read_tin

        tin_crs = params["TIN"].crs
        template = params["TEMPLATE"]
        out_crs = params["CRS"] or (template.crs if template is not None else None) or tin_crs
        if template is not None and params["CRS"] is not None and template.crs is not None \
                and not one_crs(template.crs, params["CRS"], template.bounds):
            raise InputDataError(f"CRS is {crs_label(params['CRS'])} but TEMPLATE is in "
                                 f"{crs_label(template.crs)}")
        with feedback.timed("read"):
            xyz, triangles, _ = read_tin(params["TIN"])
        nodes = (*xyz[:, :2].min(axis=0), *xyz[:, :2].max(axis=0))
        if tin_crs is not None and out_crs is not None and not same_crs(tin_crs, out_crs):
            from toolbox.io.crs import check_same_heights

            # the nodes move in x, y only: heights of another datum would be relabelled
            check_same_heights("TIN", tin_crs, "CRS" if params["CRS"] is not None
                               else "TEMPLATE", out_crs)
        # two definitions of one CRS (an ESRI WKT and its EPSG code) move no node
        if tin_crs is not None and out_crs is not None and \
                not one_horizontal_crs(tin_crs, out_crs, nodes):
            from pyproj import Transformer

            from toolbox.io.crs import note_transformation

            cell = params.get("CELL_SIZE")
            note_transformation(feedback, tin_crs, out_crs, nodes,
                                float(cell) if cell else None, "TIN nodes")
            tr = Transformer.from_crs(tin_crs, out_crs, always_xy=True)
            x, y = tr.transform(xyz[:, 0], xyz[:, 1])
            xyz = np.column_stack([x, y, xyz[:, 2]])
            feedback.push_warning(f"TIN nodes reprojected from {crs_label(tin_crs)} to "
                                  f"{crs_label(out_crs)}; triangles kept as they are")
        bounds = (*xyz[:, :2].min(axis=0), *xyz[:, :2].max(axis=0))
        grid = grid_request(params).grid(bounds, out_crs)
        tile_size = 512
        origin = (float(grid.transform.c), float(grid.transform.f))
        local = np.column_stack([xyz[:, 0] - origin[0], xyz[:, 1] - origin[1], xyz[:, 2]])
        with feedback.timed("index"):
            tiles = TinTiles(local, triangles, grid, tile_size, origin)
        summary = {"filled": 0, "zmin": np.inf, "zmax": -np.inf, "clashes": 0}

        def collect(tile, z, info):
            if z is None:
                return
            clashes = nodata_clashes(z, params["NODATA"], params["DATA_TYPE"])
            if clashes:  # stored as NODATA: no value in the file
                summary["clashes"] += clashes
                z = np.where(z.astype(params["DATA_TYPE"]) == params["NODATA"], np.nan, z)
            valid = ~np.isnan(z)
            if valid.any():
                summary["filled"] += int(valid.sum())
                summary["zmin"] = min(summary["zmin"], float(z[valid].min()))
                summary["zmax"] = max(summary["zmax"], float(z[valid].max()))

        writer = RasterWriter(params["OUTPUT"], grid, 1, params["DATA_TYPE"], params["NODATA"],
                              cog=params["COG"], overviews=params["OVERVIEWS"],
                              band_descriptions=["height (TIN, the plane of each triangle)"])
        with feedback.timed("rasterise"), writer:
            process_raster(grid, None, partial(tin_tile, origin), writer, tile_size=tile_size,
                           plan=tiles.plan, collect=collect, feedback=feedback, end=90,
                           executor=executor_of(params))
        if summary["clashes"]:
            feedback.push_warning(nodata_clash_warning(summary["clashes"], params["NODATA"]))
        filled = summary["filled"]
        cell_x, cell_y = grid.cell_size
        if filled == 0:
            feedback.push_warning("no cell centre lies inside the TIN: the raster is all NODATA")
        stats = {"width": grid.width, "height": grid.height, "cell_size": [cell_x, cell_y],
                 "bounds": list(grid.bounds), "crs": crs_label(out_crs), "cells_with_data": filled,
                 "cells_nodata": grid.width * grid.height - filled}
        if filled:
            stats.update(z_min=summary["zmin"], z_max=summary["zmax"])
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
