"""tin:to_raster - the TIN surface sampled at cell centres into a GeoTIFF (no smoothing)."""

from __future__ import annotations

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs, crs_label, same_crs
from toolbox.io.grid import GridSpec
from toolbox.io.raster import DEFAULT_BLOCK, build_overviews, geotiff_profile, iter_windows
from toolbox.parameters import (
    Boolean,
    Crs,
    Enum,
    ExtentParameter,
    Number,
    Output,
    OutputRaster,
    RasterLayer,
    VectorLayer,
)
from toolbox.registry import register
from toolbox.terrain.tin.kernels import rasterize_tin, triangles_by_tile
from toolbox.terrain.tin.store import TIN_HELP, read_tin


def tin_grid(xy: np.ndarray, crs, cell_size: float | None, extent=None, template=None
             ) -> GridSpec:
    """Output grid: the template's, or ``extent`` (default: the nodes' bounds) snapped outwards
    to multiples of ``cell_size``."""
    if template is not None:
        return GridSpec.from_raster(template)
    bounds = extent.bounds if extent is not None else (
        *xy.min(axis=0), *xy.max(axis=0))
    return GridSpec.from_bounds(bounds, cell_size, crs)


@register
class ToRaster(Algorithm):
    """Rasterise a TIN: every cell gets the height of the TIN's plane at the cell centre
    (thesis eq. [43]-[44]; cell values belong to cell centres, par. 2.5.2), exactly, with no
    smoothing or resampling. Cells whose centre lies outside the TIN are NODATA.

    Grid: TEMPLATE's grid, or EXTENT (default: the TIN's bounds) snapped outwards to multiples of
    CELL_SIZE. CRS (default: the TIN's) reprojects the TIN's nodes before rasterising (the
    triangles are kept; a warning says so). The raster is computed and written tile by tile
    (only the triangles touching each tile are drawn), so memory stays bounded for any size.
    """

    id = "tin:to_raster"
    display_name = "TIN to raster"
    group = "TIN"
    short_help = "GeoTIFF of the TIN surface at cell centres (plane values, no smoothing)."
    parameters = [
        VectorLayer("TIN", TIN_HELP, geometry_types=["polygon"]),
        Number("CELL_SIZE", "cell size, CRS units (not needed with TEMPLATE)", optional=True,
               min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "output extent 'xmin,ymin,xmax,ymax' (default: the TIN's)",
                        optional=True),
        RasterLayer("TEMPLATE", "raster whose grid (extent, cells, CRS) to copy", optional=True),
        Crs("CRS", "output CRS (default: the TIN's)", optional=True),
        Number("NODATA", "value of cells outside the TIN", default=-9999.0),
        Enum("DATA_TYPE", "cell type", options=["float32", "float64"], default="float32"),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        OutputRaster("OUTPUT", "DEM GeoTIFF"),
    ]
    outputs = [Output("STATISTICS", "grid size, cells with data, height range", "json")]

    def check(self, params):
        if params["TEMPLATE"] is None and params["CELL_SIZE"] is None:
            raise self.fail("CELL_SIZE", "is required unless TEMPLATE is given")
        if params["TEMPLATE"] is not None:
            for name in ("CELL_SIZE", "EXTENT"):
                if params[name] is not None:
                    raise self.fail(name, "cannot be combined with TEMPLATE (the template "
                                    "fixes the grid)")
            t = params["TEMPLATE"].transform
            if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
                raise self.fail("TEMPLATE", f"must be a north-up raster, {params['TEMPLATE']} "
                                "is rotated or flipped")

    def process(self, params, feedback: Feedback):
        import rasterio

        tin_crs = params["TIN"].crs
        template = params["TEMPLATE"]
        out_crs = params["CRS"] or (template.crs if template is not None else None) or tin_crs
        if template is not None and params["CRS"] is not None and template.crs is not None \
                and not same_crs(params["CRS"], template.crs):
            raise InputDataError(f"CRS is {crs_label(params['CRS'])} but TEMPLATE is in "
                                 f"{crs_label(template.crs)}")
        extent = params["EXTENT"]
        if extent is not None and extent.crs is not None:
            common_crs({"EXTENT": extent.crs}, out_crs)
        with feedback.timed("read"):
            xyz, triangles, _ = read_tin(params["TIN"])
        if tin_crs is not None and out_crs is not None and not same_crs(tin_crs, out_crs):
            from pyproj import Transformer

            tr = Transformer.from_crs(tin_crs, out_crs, always_xy=True)
            x, y = tr.transform(xyz[:, 0], xyz[:, 1])
            xyz = np.column_stack([x, y, xyz[:, 2]])
            feedback.push_warning(f"TIN nodes reprojected from {crs_label(tin_crs)} to "
                                  f"{crs_label(out_crs)}; triangles kept as they are")
        grid = tin_grid(xyz[:, :2], out_crs, params["CELL_SIZE"], extent, template)
        cell_x, cell_y = grid.cell_size
        x0, y0 = grid.transform.c, grid.transform.f
        tile = DEFAULT_BLOCK
        with feedback.timed("index"):
            order, start, ntx = triangles_by_tile(xyz[:, :2], triangles, x0, y0, cell_x, cell_y,
                                                  grid.width, grid.height, tile)
        dtype = np.dtype(params["DATA_TYPE"])
        nodata = params["NODATA"]
        profile = geotiff_profile(grid.width, grid.height, 1, dtype, out_crs, grid.transform,
                                  nodata=nodata)
        windows = list(iter_windows(grid.width, grid.height, tile))
        filled, zmin, zmax = 0, np.inf, -np.inf
        with rasterio.Env(COMPRESS_OVERVIEW="DEFLATE"), \
                rasterio.open(params["OUTPUT"], "w", **profile) as dst, feedback.timed("rasterise"):
            for w in feedback.iterate(windows, start=0, end=90, message="rasterising"):
                core = w.core
                k = (int(core.row_off) // tile) * ntx + int(core.col_off) // tile
                z = rasterize_tin(xyz, triangles[order[start[k]:start[k + 1]]],
                                  x0 + core.col_off * cell_x, y0 - core.row_off * cell_y,
                                  cell_x, cell_y, int(core.width), int(core.height))
                valid = ~np.isnan(z)
                if valid.any():
                    filled += int(valid.sum())
                    zmin, zmax = min(zmin, float(z[valid].min())), max(zmax, float(z[valid].max()))
                dst.write(np.where(valid, z, nodata).astype(dtype), 1, window=core)
            if params["OVERVIEWS"]:
                build_overviews(dst)
        if filled == 0:
            feedback.push_warning("no cell centre lies inside the TIN: the raster is all NODATA")
        stats = {"width": grid.width, "height": grid.height, "cell_size": [cell_x, cell_y],
                 "bounds": list(grid.bounds), "crs": crs_label(out_crs), "cells_with_data": filled,
                 "cells_nodata": grid.width * grid.height - filled}
        if filled:
            stats.update(z_min=zmin, z_max=zmax)
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
