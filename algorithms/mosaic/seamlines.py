"""mosaic:seamlines - cut polygons and seamlines of a block of orthophotos."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, Field, Integer, Number, RasterLayer, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.mosaic import SEAM_FIELDS, orthos_parameter

METHODS = ("voronoi", "least_cost")
CENTRES = ("nadir", "footprint")
#: the fields naming an ortho in cut_polygons, footprints and centres
SOURCE_FIELDS = (("source_id", "integer", "1-based input number of the ortho"),
                 ("source", "string", "ortho file name"))


@register
class MosaicSeamlines(Algorithm):
    """Cut the mosaic area into one polygon per ortho (thesis S002 §3.8, "linee di taglio").

    The area is the union of the orthos' valid data (alpha band, nodata or mask, traced on the
    mask decimated to at most 2048 cells a side).

    METHOD=voronoi (the thesis' LPV, locus of nearest points): each ground point goes to the
    ortho whose centre is nearest among the orthos that have data there; the seams lie on the
    perpendicular bisectors of the centres. CENTRES=nadir takes the nadir points from
    NADIR_POINTS (matched by NADIR_FIELD = the ortho file names, or by order) or from the
    orthos' tags NADIR_X/NADIR_Y (X0/Y0); CENTRES=footprint uses the footprint centroids.

    METHOD=least_cost (PPD, paths by dynamic programming): each Voronoi seam is re-routed along
    the minimum-cost path between its two ends inside the overlap of its two orthos, over a cost
    per unit length ``0.1 + w_d·|a−b|/range + w_g·max(|∇a|,|∇b|)/range + w_c·|d_a − d_b|/D +
    w_s·S`` (radiometric difference and Sobel gradient of the two orthos, and a pull towards the
    bisector of the two centres: d = distance to a centre, D between them; it keeps each cell
    near its own nadir where the images give no reason to leave; S = 1 within STRUCTURE_RADIUS
    of a strong, structured difference: a connected group of cells where the two orthos'
    gradients differ by over 10 % of the value range, e.g. facades seen differently, so that
    without a DSM or BUILDINGS the seam still goes round a building rather than through its
    roof where both orthos happen to agree; w_s = STRUCTURE_WEIGHT), plus BUILDING_COST inside
    BUILDINGS footprints and HEIGHT_COST per metre of HEIGHTS (a DSM − DEM raster) above 0.5 m;
    FORBIDDEN polygons are never crossed. The path is the least-cost 8-connected path over cells
    of SEAM_CELL_SIZE (a compiled A*, as scikit-image's MCP_Geometric counts a path's cost);
    above 250,000 cells it is routed on an overview of block means first, then at full
    resolution within about 32 cells of that path (the exact optimum in the benchmark and
    within 0.4 % of it on random surfaces). Overlaps of more than MAX_CELLS cells are read on an
    overview first, then refined at full resolution in a corridor, chunk by chunk. Where two
    cut polygons share several separate boundary pieces only the longest is re-routed; a seam
    whose ends are not connected inside the overlap stays Voronoi (both with a warning or note
    in STATISTICS). On a Dask cluster (SCHEDULER or DASK_SCHEDULER_ADDRESS) seams that share
    no cut polygon are routed at the same time (each worker reads the two orthos of its seam, so
    they must be on storage the workers share), in waves that give the one-by-one result
    exactly: the file is the local run's. Locally the seams are routed one after the other.
    The orthos are partitioned in file-name order, so the cut polygons do not depend on the
    order they are given in.

    OUTPUT (GeoPackage): layer cut_polygons (source_id = 1-based input number, source = ortho
    file name, path relative to the output's folder, area in CRS units²) forms an exact
    partition of the area (no gaps, no overlaps); layer seamlines (a_id, b_id = the 1-based
    input numbers of the two orthos, the lower first; a, b = their file names; method; length
    in CRS units); layers footprints and centres (source_id, source).

    The seamlines are exactly the boundaries between different sources in the source index of
    the mosaic mosaic:build makes from these cut polygons at its default cell size (each cell
    takes the ortho whose polygon holds its centre, or the first ortho with data there): cell
    edges, in steps of one cell where a seam runs diagonally, so a zero-area sliver of a cut
    polygon gives no seam and every seam of the mosaic is there. ``method`` says how the seam
    was made: least_cost for a re-routed seam, voronoi for one left on the Voronoi partition
    (a nadir bisector or a footprint edge). Move a seam in QGIS by editing the cut polygons
    (keeping them a partition), then run mosaic:build with CUTLINES.
    """

    id = "mosaic:seamlines"
    display_name = "Mosaic seamlines"
    group = "Mosaic"
    short_help = "Cut polygons and seamlines of a block of orthos (Voronoi or least-cost)."
    parameters = [
        orthos_parameter(),
        Enum("METHOD", "voronoi (nearest centre) or least_cost (minimum-cost paths)",
             options=METHODS, default="least_cost"),
        Enum("CENTRES", "Voronoi centres: nadir points or footprint centres", options=CENTRES,
             default="nadir"),
        VectorLayer("NADIR_POINTS", "nadir points (default: the orthos' NADIR_X/NADIR_Y tags)",
                    geometry_types=["point"], optional=True),
        Field("NADIR_FIELD", "field of NADIR_POINTS holding the ortho file names (default: "
              "points in input order)", parent="NADIR_POINTS", optional=True),
        Number("SEAM_CELL_SIZE", "cell of the least-cost grid, CRS units (default: the finest "
               "ortho's)", optional=True, min_value=0, min_exclusive=True),
        Number("DIFFERENCE_WEIGHT", "weight of the radiometric difference", default=1.0,
               min_value=0),
        Number("GRADIENT_WEIGHT", "weight of the image gradient", default=1.0, min_value=0),
        Number("CENTRE_WEIGHT", "weight of the pull towards the Voronoi line (the bisector)",
               default=0.5, min_value=0),
        Number("STRUCTURE_WEIGHT", "extra cost near strong, structured differences between the "
               "two orthos (facades, displaced edges)", default=1.0, min_value=0),
        Number("STRUCTURE_RADIUS", "how far from such a difference its extra cost reaches, CRS "
               "units (about half the largest building)", default=20.0, min_value=0),
        VectorLayer("BUILDINGS", "building footprints the seams should avoid",
                    geometry_types=["polygon"], optional=True),
        Number("BUILDING_COST", "extra cost inside BUILDINGS", default=10.0, min_value=0),
        RasterLayer("HEIGHTS", "DSM minus DEM heights, metres (seams avoid what stands up)",
                    optional=True, role="heights"),
        Number("HEIGHT_COST", "extra cost per metre of HEIGHTS above 0.5 m", default=1.0,
               min_value=0),
        VectorLayer("FORBIDDEN", "areas no seam may cross", geometry_types=["polygon"],
                    optional=True),
        Integer("MAX_CELLS", "largest least-cost grid before overview + corridor",
                default=4_000_000, min_value=10_000),
        scheduler_parameter("the seams"),
        OutputVector("OUTPUT", "GeoPackage: cut_polygons, seamlines, footprints, centres", layers=[
            Layer("cut_polygons", "MultiPolygon", [*SOURCE_FIELDS,
                                                   ("path", "string", "ortho path relative to "
                                                    "the output's folder"),
                                                   ("area", "real", "area, CRS units²")],
                  "one polygon per ortho: an exact partition of the mosaic (editable)"),
            Layer("seamlines", "MultiLineString", SEAM_FIELDS,
                  "the seams between neighbouring orthos"),
            Layer("footprints", "MultiPolygon", SOURCE_FIELDS, "valid data of each ortho"),
            Layer("centres", "Point", SOURCE_FIELDS,
                  "the nadir points (or footprint centres) of the Voronoi partition")]),
    ]
    outputs = [Output("STATISTICS", "areas, partition check and per-seam notes", "dict")]

    def check(self, params):
        if params["METHOD"] != "least_cost" or params["SEAM_CELL_SIZE"] is None:
            return
        from toolbox.limits import check_size

        cell = params["SEAM_CELL_SIZE"]
        area = sum((i.bounds[2] - i.bounds[0]) * (i.bounds[3] - i.bounds[1])
                   for i in params["INPUT"])
        check_size("cells", area / cell ** 2, "SEAM_CELL_SIZE",
                   f"{cell:g} over the {area:,.0f} square units of the orthos",
                   "use a larger SEAM_CELL_SIZE (or leave it empty: the orthos' cell)")

    def process(self, params, feedback: Feedback):
        import numpy as np
        import shapely

        from toolbox.io.vector_write import write_table_layers
        from toolbox.mosaic.block import (
            cells_table,
            centres_of,
            close_block,
            mosaic_grid,
            nadir_points_from_layer,
            name_order,
            open_block,
            seams_table,
            union_area,
        )
        from toolbox.mosaic.build import MosaicPlan
        from toolbox.mosaic.index_seams import partition_seams
        from toolbox.mosaic.partition import partition_errors, voronoi_cells
        from toolbox.mosaic.seams import CostWeights, PairCost, least_cost_cells
        from toolbox.mosaic.sources import open_source

        executor = executor_of(params)
        with feedback.timed("footprints"):  # GDAL decodes a footprint's blocks on the threads
            sources, crs = open_block([i.path for i in params["INPUT"]], "INPUT", feedback,
                                      executor.workers if executor.kind == "local" else 1)
        try:
            points = None
            if params["NADIR_POINTS"] is not None:
                points = nadir_points_from_layer(params["NADIR_POINTS"], params["NADIR_FIELD"],
                                                 sources, crs=crs)
            centres = centres_of(sources, params["CENTRES"], points, feedback)
            footprints = [s.footprint for s in sources]
            # the partition is made with the orthos in name order (unique names), then put back
            # in input order: the seams' routes (and the rounding of the polygons they start
            # from) would otherwise depend on the order the orthos are given in
            order = name_order(sources)
            with feedback.timed("voronoi"):
                cells = voronoi_cells([footprints[k] for k in order], [centres[k] for k in order])
            feedback.set_progress(20)
            seam_report = []
            if params["METHOD"] == "least_cost" and len(sources) > 1:
                weights = CostWeights(difference=params["DIFFERENCE_WEIGHT"],
                                      gradient=params["GRADIENT_WEIGHT"],
                                      centre=params["CENTRE_WEIGHT"],
                                      structure=params["STRUCTURE_WEIGHT"],
                                      structure_radius=params["STRUCTURE_RADIUS"],
                                      building=params["BUILDING_COST"], height=params["HEIGHT_COST"])
                buildings = _polygons(params["BUILDINGS"], crs, "BUILDINGS")
                forbidden = _polygons(params["FORBIDDEN"], crs, "FORBIDDEN")
                heights = None if params["HEIGHTS"] is None else \
                    open_source(params["HEIGHTS"].path, -1, sources[0].datasets, name="HEIGHTS")
                cell = params["SEAM_CELL_SIZE"] or min(s.res[0] for s in sources)

                def cost_for(i, j):
                    i, j = order[i], order[j]
                    return PairCost(sources[i], sources[j], crs, weights, buildings, forbidden,
                                    heights, (centres[i], centres[j]))

                with feedback.timed("least_cost"):
                    cells, seam_report = least_cost_cells(cells, [footprints[k] for k in order],
                                                          cost_for, cell, params["MAX_CELLS"],
                                                          feedback.step(20, 95), executor)
                for entry in seam_report:  # input numbers, the lower first
                    entry["a"], entry["b"] = sorted((order[entry["a"]], order[entry["b"]]))
                for entry in seam_report:
                    if entry["method"] != "least_cost":
                        feedback.push_warning(f"seam {sources[entry['a']].name} / "
                                              f"{sources[entry['b']].name} kept on the Voronoi "
                                              f"line: {entry.get('note', '')}")
            cells = [cells[order.index(k)] for k in range(len(sources))]  # input order
            area = union_area(sources)
            gap, overlap = partition_errors(cells, area)
            methods = {(e["a"], e["b"]): e["method"] for e in seam_report}
            with feedback.timed("seams"):  # the seams of the mosaic mosaic:build makes of the cells
                # in name order as mosaic:build plans them (a cell centre on a shared edge goes
                # to the first by name), the pairs back in input numbers
                named = [sources[k] for k in order]
                grid = mosaic_grid(named, crs, None, area)
                plan = MosaicPlan(named, [cells[k] for k in order], grid,
                                  len(sources[0].data_bands), sources[0].dtype)
                seams = sorted((*sorted((order[i], order[j])), line)
                               for i, j, line in partition_seams(plan))
            ids = {"source_id": np.array([s.index + 1 for s in sources], dtype="int64"),
                   "source": np.array([s.name for s in sources], dtype=object)}
            write_table_layers(params["OUTPUT"], {
                "cut_polygons": cells_table(sources, cells, params["OUTPUT"]),
                "seamlines": seams_table(sources, seams, methods),
                "footprints": (ids, [f if f.geom_type == "MultiPolygon"
                                     else shapely.MultiPolygon([f]) for f in footprints]),
                "centres": (ids, [shapely.Point(c) for c in centres])}, crs,
                geometry_types={"cut_polygons": "MultiPolygon", "seamlines": "MultiLineString",
                                "footprints": "MultiPolygon", "centres": "Point"})
            return {"OUTPUT": params["OUTPUT"], "STATISTICS": {
                "method": params["METHOD"], "orthos": len(sources), "executor": executor.describe(),
                "area": float(area.area), "partition_gap_area": gap, "max_overlap_area": overlap,
                "cut_areas": {s.name: float(c.area) for s, c in zip(sources, cells, strict=True)},
                "seam_grid_cell": grid.cell_size[0],
                "seams": [{**e, "a": sources[e["a"]].name, "b": sources[e["b"]].name}
                          for e in seam_report]}}
        finally:
            close_block(sources)


def _polygons(layer, crs, name: str) -> list:
    """The polygons of an optional layer, in ``crs``."""
    if layer is None:
        return []
    from toolbox.mosaic.block import read_in_crs

    frame = read_in_crs(layer, crs, name)
    return [g for g in frame.geometry if g is not None and not g.is_empty]
