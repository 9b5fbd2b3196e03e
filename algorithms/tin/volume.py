"""tin:volume - cut and fill between a TIN and a reference plane or a DEM, inside a polygon."""

from __future__ import annotations

import json

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs, crs_label
from toolbox.io.raster import DEFAULT_BLOCK
from toolbox.io.vector import read_area
from toolbox.parameters import Integer, Number, RasterLayer, VectorLayer
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register
from toolbox.terrain.tin.cutfill import CutFill, grid_cut_fill, plane_cut_fill
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.tin import tin_parameter


def dem_cut_fill(xyz: np.ndarray, triangles: np.ndarray, info, band: int, mask,
                 feedback: Feedback, executor=None) -> tuple[CutFill, dict]:
    """Cut/fill of the TIN against a DEM on the DEM's own grid, tile by tile on the raster
    engine (tiles without triangles are not read)."""
    from functools import partial

    from toolbox.io.grid import GridSpec
    from toolbox.io.raster import north_up_transform
    from toolbox.raster.engine import RasterInput, process_raster
    from toolbox.terrain.tin.kernels import triangles_by_tile

    t = north_up_transform(info.transform, info.width, info.height)  # south-up: read flipped
    cell_x, cell_y = abs(t.a), abs(t.e)
    tile_size = DEFAULT_BLOCK
    order, start, ntx = triangles_by_tile(xyz[:, :2], triangles, t.c, t.f, cell_x, cell_y,
                                          info.width, info.height, tile_size)
    grid = GridSpec(t, info.width, info.height, info.crs)
    total = CutFill()
    no_dem = 0

    def plan(tile):
        k = (int(tile.window.row_off) // tile_size) * ntx + int(tile.window.col_off) // tile_size
        tri = triangles[order[start[k]:start[k + 1]]]
        return {"triangles": tri} if len(tri) else None

    def collect(tile, _array, part):
        nonlocal total, no_dem
        if part is not None:
            total += part[0]
            no_dem += part[1]

    process_raster(grid, {"dem": RasterInput(info.path, bands=(band,), dtype="float64")},
                   partial(_cut_fill_tile, xyz, mask, cell_x * cell_y),
                   lambda tile, array: None, tile_size=tile_size, plan=plan, collect=collect,
                   executor=executor, feedback=feedback, start=10, end=100)
    return total, {"cell_size": [cell_x, cell_y], "cells_without_dem": no_dem}


def coarse_dem_warning(xyz: np.ndarray, triangles: np.ndarray, info, mask, counted: float,
                       extra: dict) -> str | None:
    """A warning when the DEM's cells counted (centre inside the TIN) cover an area more than
    10 % away from the TIN's own inside the DEM (and MASK): cells coarse for the TIN, whose
    midpoint rule then misstates areas and volumes in proportion."""
    import shapely

    from toolbox.terrain.tin.cutfill import plane_cut_fill

    cell_x, cell_y = extra["cell_size"]
    counted += extra["cells_without_dem"] * cell_x * cell_y
    frame = shapely.box(*info.bounds)
    lo, hi = xyz[:, :2].min(axis=0), xyz[:, :2].max(axis=0)
    if mask is None and shapely.contains(frame, shapely.box(*lo, *hi)):
        region = None  # every triangle inside the DEM: nothing to clip
    else:
        region = frame if mask is None else shapely.intersection(frame, mask)
    # the TIN's area in the region: all of it fill below a plane under its lowest node
    exact = plane_cut_fill(xyz, triangles, float(xyz[:, 2].min()) - 1.0, region).area
    if abs(counted - exact) <= 0.1 * exact:
        return None
    return (f"the DEM's cells ({cell_x:g} x {cell_y:g}) are coarse for this TIN: the cells "
            f"whose centre lies on it cover {counted:,.2f} square units where the TIN covers "
            f"{exact:,.2f} (inside the DEM{' and MASK' if mask is not None else ''}), and the "
            "volumes are off in proportion; resample REFERENCE_DEM to cells much smaller than "
            "the TIN")


def _cut_fill_tile(xyz, mask, cell_area, tile, arrays) -> tuple[None, tuple[CutFill, int]]:
    """Engine kernel: (no raster, (cut/fill of the tile, TIN cells without DEM))."""
    from rasterio.features import geometry_mask

    from toolbox.terrain.tin.kernels import rasterize_tin

    t = tile.core_transform
    rows, cols = tile.shape
    tin_z = rasterize_tin(xyz, arrays["triangles"], t.c, t.f, t.a, -t.e, cols, rows)
    dem = arrays["dem"][0]
    inside = None if mask is None else ~geometry_mask([mask], (rows, cols), t,
                                                       all_touched=False)
    covered = ~np.isnan(tin_z) if inside is None else ~np.isnan(tin_z) & inside
    return None, (grid_cut_fill(tin_z, dem, cell_area, inside), int((covered & np.isnan(dem)).sum()))


@register
class Volume(Algorithm):
    """Cut and fill volumes and areas between a TIN and a reference: a horizontal plane
    (REFERENCE_Z) or a second surface (REFERENCE_DEM), optionally inside MASK polygons.

    Convention: h = TIN - reference; *cut* is where the TIN is above the reference (material to
    remove), *fill* where it is below; volumes are positive, net = cut - fill.

    - Plane: exact. h is linear in each triangle, so each triangle splits along its zero line;
      the volume of each part is its area times h at its centroid. Triangles crossed by MASK are
      clipped exactly.
    - DEM: the TIN is sampled at the DEM's cell centres (tin:to_raster's kernel) and each cell
      counts cell area x (TIN - DEM), the midpoint rule at the DEM's resolution; cells count
      when their centre is inside MASK and both surfaces have a value (cells of the TIN without
      DEM are reported). The DEM's tiles run on local threads or, with SCHEDULER, on a Dask
      cluster.

    Result: STATISTICS and, with REPORT, a small JSON or CSV report (volumes, areas, reference,
    method).
    """

    length_units = "one"  # x, y and heights in one unit (metres or feet): slopes mix them

    id = "tin:volume"
    display_name = "TIN cut/fill volume"
    group = "TIN"
    short_help = "Cut/fill volumes and areas between a TIN and a plane or a DEM, in a polygon."
    parameters = [
        tin_parameter(),
        Number("REFERENCE_Z", "reference plane elevation (height units)", optional=True),
        RasterLayer("REFERENCE_DEM", "reference surface: a DEM raster", optional=True,
                    role="heights"),
        Integer("BAND", "band of REFERENCE_DEM", default=1, min_value=1),
        VectorLayer("MASK", "polygon(s): compute inside them only", geometry_types=["polygon"],
                    optional=True),
        OutputFile("REPORT", "report file (.json or .csv)", extensions=[".json", ".csv"],
                   optional=True),
        scheduler_parameter("the DEM's tiles (REFERENCE_DEM)"),
    ]
    outputs = [Output("STATISTICS", "cut, fill and net volumes; cut, fill and total areas",
                      "json")]

    def check(self, params):
        given = [n for n in ("REFERENCE_Z", "REFERENCE_DEM") if params[n] is not None]
        if len(given) != 1:
            raise self.fail("REFERENCE_Z", "or REFERENCE_DEM: give exactly one reference, got "
                            f"{' and '.join(given) if given else 'neither'}")
        dem = params["REFERENCE_DEM"]
        if dem is not None:
            t = dem.transform
            if t.b != 0 or t.d != 0 or not dem.georeferenced:
                raise self.fail("REFERENCE_DEM", f"must be a georeferenced raster without "
                                f"rotation, got "
                                f"{dem}")

    def process(self, params, feedback: Feedback):
        from toolbox.terrain.tin.store import read_tin

        named = {"TIN": params["TIN"].crs}
        if params["MASK"] is not None:
            named["MASK"] = params["MASK"].crs
        if params["REFERENCE_DEM"] is not None:
            named["REFERENCE_DEM"] = params["REFERENCE_DEM"].crs
        crs = common_crs(named)
        executor = executor_of(params)  # a bad address is refused before any work
        with feedback.timed("read"):
            xyz, triangles, _ = read_tin(params["TIN"])
            mask = None if params["MASK"] is None else read_area(params["MASK"], "MASK")
        feedback.set_progress(10, "computing volumes")
        with feedback.timed("volume"):
            if params["REFERENCE_Z"] is not None:
                result = plane_cut_fill(xyz, triangles, params["REFERENCE_Z"], mask)
                extra = {"method": "exact (plane)", "reference": {"z": params["REFERENCE_Z"]}}
            else:
                result, extra = dem_cut_fill(xyz, triangles, params["REFERENCE_DEM"],
                                             params["BAND"], mask, feedback, executor)
                extra.update(method="grid (DEM cell centres)",
                             reference={"dem": params["REFERENCE_DEM"].as_text(),
                                        "band": params["BAND"]})
                if extra["cells_without_dem"]:
                    feedback.push_warning(f"{extra['cells_without_dem']} cell(s) of the TIN have "
                                          "no DEM value and were left out")
                coarse = coarse_dem_warning(xyz, triangles, params["REFERENCE_DEM"], mask,
                                            result.area, extra)
                if coarse:
                    feedback.push_warning(coarse)
        if result.area == 0:
            feedback.push_warning("the TIN and the reference do not overlap (inside MASK): "
                                  "all volumes are 0")
        stats = result.as_dict() | extra | {"crs": crs_label(crs), "masked": mask is not None}
        if params["REPORT"] is not None:
            _write_report(params["REPORT"], stats)
        return {"STATISTICS": stats, "REPORT": params["REPORT"]}


def _write_report(path, stats: dict) -> None:
    if path.suffix.lower() == ".json":
        path.write_text(json.dumps(stats, indent=2) + "\n")
        return
    import csv
    import io

    rows = [("quantity", "value", "unit")]
    units = {"volume": "cubic units", "area": "square units"}
    for key in ("cut_volume", "fill_volume", "net_volume", "cut_area", "fill_area", "area"):
        rows.append((key, f"{stats[key]:.6f}", units[key.rsplit("_", 1)[-1]]))
    rows.append(("method", stats["method"], ""))
    reference = stats["reference"]
    rows.append(("reference", f"z={reference['z']:g}" if "z" in reference else
                 f"{reference['dem']} band {reference['band']}", ""))
    text = io.StringIO()  # RFC 4180: a DEM path holding a comma or a quote is quoted
    csv.writer(text, lineterminator="\n").writerows(rows)
    path.write_text(text.getvalue())
