"""tin:delaunay - TIN by (constrained) Delaunay triangulation of mass points and breaklines."""

from __future__ import annotations

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs, crs_label
from toolbox.io.pointcloud import cloud_filter
from toolbox.io.vector import feature_rows, read_area, read_vector, vector_driver
from toolbox.io.vector_points import input_rows, skip_no_geometry, vertices_xyz
from toolbox.parameters import Boolean, Crs, Enum, Field, Number, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.terrain.points import read_mass_points
from toolbox.ui.gridding import point_input_parameters

DUPLICATE_RULES = ("mean", "first", "min", "max", "error")


def read_breaklines(ref, z_field: str | None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(L, 3)`` and part index ``(L,)`` of a line layer (multi-lines exploded).

    Z comes from the geometry, or from ``z_field`` (one height per line, e.g. contours).
    Missing Z, NaN Z or non-line features raise :class:`InputDataError` naming BREAKLINES.
    """
    import shapely

    frame = read_vector(ref, name="BREAKLINES")
    frame = skip_no_geometry(frame, "BREAKLINES")
    if len(frame) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    frame = frame.explode(index_parts=False)  # the index stays the input row (messages)
    kinds = shapely.get_type_id(frame.geometry.values)
    if not np.isin(kinds, [1, 2]).all():
        raise InputDataError(f"BREAKLINES {ref} must contain lines, found "
                             f"{', '.join(sorted(set(frame.geom_type[~np.isin(kinds, [1, 2])])))}")
    if z_field is not None and frame[z_field].isna().any():
        bad = input_rows(frame)[frame[z_field].isna().to_numpy()]
        raise InputDataError(f"BREAKLINES field {z_field!r} is empty for {len(np.unique(bad))} "
                             f"line(s) ({feature_rows(bad)}): every breakline needs a height")
    xyz, index = vertices_xyz(frame, z_field, name="BREAKLINES")
    return xyz, index


@register
class Delaunay(Algorithm):
    """Triangulated irregular network (TIN) of mass points and breaklines.

    Method (thesis S002 par. 2.5.1): Delaunay triangulation, whose
    triangles' circumcircles contain no other point, made with CDT (pythoncdt, MPL-2.0; or
    Shewchuk's Triangle with ``TOOLBOX_TRIANGULATOR=triangle``, docs/algorithms/tin.md). With
    breaklines (ridges, road edges, contour lines: LineStringZ, or lines with a height field)
    the triangulation is a *constrained* Delaunay triangulation: every breakline vertex becomes
    a node and every breakline segment a triangle edge, so the surface never cuts across a
    breakline.

    Quality rules, all reported in STATISTICS (and as warnings):

    - points with the same XY (within DUPLICATE_TOLERANCE) are merged: Z = the DUPLICATES rule
      (mean, first, min, max; "error" refuses them); breakline vertices count before mass points
      for "first";
    - breaklines that cross without a shared vertex are split at the crossing; the new node's Z
      is interpolated along each breakline (their mean if the two disagree; the largest
      disagreement is reported);
    - fewer than 3 distinct points, collinear points, breaklines without Z: clear errors.

    BOUNDARY clips hard: the polygon (inside the points' convex hull) becomes part of the TIN,
    its vertices nodes with Z from the unclipped TIN, and no triangle lies outside it. HULL =
    concave erodes long border triangles (longer outer edge than MAX_EDGE, default 3 x the
    median edge length) without orphaning nodes.

    Output, one GeoPackage: ``triangles`` (PolygonZ: id, node1-3, neighbour ids nbr1-3 across
    the edge facing each node, edge1-3, area_2d, area_3d, slope_deg, slope_pct, aspect_deg),
    ``nodes`` (PointZ: id, source, merged, z) and ``edges`` (LineStringZ, each once: node_from,
    node_to, left_tri, right_tri, breakline flag, lengths; EDGES=false skips this layer).
    A new GeoPackage is written in bulk: GDAL creates the layers, the features and a packed
    R-tree go into the file as SQLite pages built with numpy (the same rows GDAL writes, several
    times faster); other formats stream through Arrow.

    Licence: the optional Triangle is free for non-commercial use only; commercial use needs a
    licence from its author (docs/algorithms/tin.md, "Licence"); the default CDT has no such
    limit.
    """

    length_units = "horizontal"  # x, y in one unit (metres or feet); heights in their own

    id = "tin:delaunay"
    display_name = "TIN (Delaunay, with breaklines)"
    group = "TIN"
    short_help = ("Constrained Delaunay TIN of 3D points and breaklines, clipped to a boundary; "
                  "triangles, nodes and edges with topology.")
    parameters = [
        *point_input_parameters("mass points (PointZ, or points with a Z field, or a "
                                "LAS/LAZ/COPC point cloud)"),
        VectorLayer("BREAKLINES", "breaklines: LineStringZ, or lines with a height field "
                    "(contours)", geometry_types=["line"], optional=True),
        Field("BREAKLINES_Z_FIELD", "height field of BREAKLINES (default: geometry Z)",
              parent="BREAKLINES", numeric=True, optional=True,
              deprecated_names=["BREAKLINE_Z_FIELD"]),
        VectorLayer("BOUNDARY", "polygon(s): hard clip, no triangle outside",
                    geometry_types=["polygon"], optional=True),
        Enum("HULL", "outer border: convex hull, or concave (long border triangles removed)",
             options=["convex", "concave"], default="convex"),
        Number("MAX_EDGE", "HULL=concave: remove border triangles whose outer edge is longer "
               "(CRS units; default 3 x the median edge length)", optional=True, min_value=0,
               min_exclusive=True),
        Enum("DUPLICATES", "Z of points sharing an XY position", options=list(DUPLICATE_RULES),
             default="mean"),
        Number("DUPLICATE_TOLERANCE", "points closer than this in plan are the same position "
               "(CRS units; 0 = equal XY)", default=0.0, min_value=0),
        Crs("CRS", "CRS of inputs that have none (e.g. CSV); must match those that do",
            optional=True),
        Boolean("EDGES", "write the edges layer (about half the writing time of a large TIN; "
                "the triangles layer keeps neighbour and edge ids either way)", default=True),
        Boolean("SPATIAL_INDEX", "write GeoPackage spatial indexes (faster display of large "
                "TINs in QGIS; adds about a third to the writing time)", default=True),
        # duplicate-ok: declared layers and fields (a spec read by the docs and QGIS, not logic)
        OutputVector("OUTPUT", "TIN GeoPackage (layers triangles, nodes, edges); .parquet "
                     "(a third of the size) or .fgb write one file per layer", layers=[
            Layer("triangles", "Polygon Z", [
                ("id", "integer", "triangle id"), ("node1", "integer", "first node id"),
                ("node2", "integer", "second node id"), ("node3", "integer", "third node id"),
                ("nbr1", "integer", "neighbour across the edge opposite node1 (0: none)"),
                ("edge1", "integer", "edge id opposite node1"),
                ("area_2d", "real", "plan area, CRS units²"),
                ("area_3d", "real", "surface area, CRS units²"),
                ("slope_deg", "real", "slope, degrees"), ("slope_pct", "real", "slope, %"),
                ("aspect_deg", "real", "aspect, degrees clockwise from north")],
                "triangles with their nodes, neighbours and edges (nbr2/3, edge2/3 likewise)",
                style="tin_slope"),
            Layer("nodes", "Point Z", [
                ("id", "integer", "node id"), ("source", "string", "points, breaklines, ..."),
                ("merged", "integer", "input points merged into the node"),
                ("z", "real", "height")], "the TIN's vertices"),
            Layer("edges", "LineString Z", [
                ("id", "integer", "edge id"), ("node_from", "integer", "start node id"),
                ("node_to", "integer", "end node id"),
                ("left_tri", "integer", "triangle on the left (0: none)"),
                ("right_tri", "integer", "triangle on the right (0: none)"),
                ("breakline", "boolean", "the edge lies on a breakline"),
                ("length_2d", "real", "plan length"), ("length_3d", "real", "3D length")],
                "triangle edges (not written when EDGES is false)", optional=True)]),
    ]
    outputs = [Output("STATISTICS", "counts, merges, crossings, clipping, areas", "json")]

    def check(self, params):
        if params["INPUT"] is None and params["BREAKLINES"] is None:
            raise self.fail("INPUT", "is required unless BREAKLINES is given: a TIN needs mass "
                            "points, breaklines or both")
        if params["INPUT"] is not None:
            cloud_filter(params["INPUT"], params["CLASSES"], params["RETURNS"], params["CRS"])
        if params["MAX_EDGE"] is not None and params["HULL"] != "concave":
            raise self.fail("MAX_EDGE", f"is only used with HULL=concave, got HULL="
                            f"{params['HULL']}")

    def process(self, params, feedback: Feedback):
        from toolbox.terrain.tin.build import SOURCES, TinBuildError, build_tin
        from toolbox.terrain.tin.store import NodesAhead, write_tin

        named = {k: params[k].crs for k in ("INPUT", "BREAKLINES", "BOUNDARY")
                 if params[k] is not None}
        crs = common_crs(named, params["CRS"])
        if crs is None:
            feedback.push_warning("the inputs have no CRS: the TIN has none (set CRS to give it)")
        with feedback.timed("read"):
            points, cloud = np.zeros((0, 3)), None
            if params["INPUT"] is not None:  # the gridding algorithms' reader: one for both
                points, cloud = read_mass_points(params["INPUT"], params["Z_FIELD"],
                                                 params["CLASSES"], params["RETURNS"],
                                                 params["CRS"])
            line_xyz, line_index = np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
            if params["BREAKLINES"] is not None:
                line_xyz, line_index = read_breaklines(params["BREAKLINES"],
                                                       params["BREAKLINES_Z_FIELD"])
            boundary = None if params["BOUNDARY"] is None else read_area(params["BOUNDARY"], "BOUNDARY")
        feedback.set_progress(10, "triangulating")
        feedback.check_canceled()
        from concurrent.futures import ThreadPoolExecutor

        from toolbox.io.gpkg_bulk import import_gdal_writer

        helper = ThreadPoolExecutor(1, thread_name_prefix="tin-helper")
        if vector_driver(params["OUTPUT"]) != "Parquet":  # GeoParquet: pyarrow alone writes it
            helper.submit(import_gdal_writer)  # while the triangulation runs (CDT lets go the GIL)
        # a new GeoPackage's nodes layer, when the nodes are known first, is written then too
        ahead = NodesAhead(params["OUTPUT"], crs, params["SPATIAL_INDEX"], params["EDGES"],
                           helper)
        with helper, feedback.timed("triangulate"):
            try:
                model = build_tin(points, line_xyz, line_index, boundary=boundary,
                                  concave=params["HULL"] == "concave",
                                  concave_max_edge=params["MAX_EDGE"],
                                  duplicate_rule=params["DUPLICATES"],
                                  duplicate_tolerance=params["DUPLICATE_TOLERANCE"],
                                  nodes_ready=ahead)
            except TinBuildError as exc:
                raise InputDataError(f"cannot build the TIN: {exc}") from None
            points = line_xyz = line_index = None  # the model holds its nodes: free the inputs
        _report_quality(model.report, feedback)
        feedback.set_progress(35, "writing")
        # the summary beside the writing, whose single-threaded steps leave a core idle
        with ThreadPoolExecutor(1, thread_name_prefix="tin-summary") as pool:
            summary = pool.submit(_surface_summary, model)
            counts = write_tin(params["OUTPUT"], model, crs, params["SPATIAL_INDEX"],
                               feedback.step(35, 100), edges_layer=params["EDGES"], ahead=ahead)
        stats = dict(model.report)
        if cloud is not None:
            stats["point_cloud"] = cloud
        stats.update(edges=counts["edges"], crs=crs_label(crs),
                     node_sources={name: int((model.source == i).sum())
                                   for i, name in enumerate(SOURCES)},
                     **summary.result())
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}


def _report_quality(report: dict, feedback: Feedback) -> None:
    dup = report["duplicates"]
    if dup["duplicates_removed"]:
        feedback.push_warning(
            f"{dup['duplicates_removed']} duplicate point(s) merged into {dup['duplicate_groups']}"
            f" node(s) (rule: {dup['rule']}; largest Z spread {dup['max_z_spread']:.6g})")
    cross = report["crossings"]
    if cross["count"]:
        feedback.push_warning(
            f"{cross['count']} breakline crossing(s) without a shared vertex: split there, Z "
            f"interpolated along the breaklines (largest disagreement "
            f"{cross['max_z_disagreement']:.6g})")
    clip = report.get("boundary")
    if clip and clip["boundary_area_outside_data_hull"] > 0:
        feedback.push_warning(
            f"BOUNDARY extends {clip['boundary_area_outside_data_hull']:.6g} square units beyond "
            "the points' convex hull; the TIN stops at the hull there")
    if clip and clip["nodes_dropped_outside"]:
        feedback.push_info(f"{clip['nodes_dropped_outside']} point(s) outside BOUNDARY dropped")


def _surface_summary(model) -> dict:
    from toolbox.terrain.tin.topology import triangle_areas

    area_2d = area_3d = 0.0
    step = 1 << 18  # by chunks: bounded memory (and cache: 1 << 20 took 1.8x the CPU time)
    for lo in range(0, len(model.triangles), step):
        flat, space = triangle_areas(model.xyz, model.triangles[lo:lo + step])
        area_2d, area_3d = area_2d + float(flat.sum()), area_3d + float(space.sum())
    return {"area_2d": area_2d, "area_3d": area_3d,
            "z_min": float(model.xyz[:, 2].min()), "z_max": float(model.xyz[:, 2].max()),
            "bounds": [float(v) for v in (*model.xyz[:, :2].min(axis=0),
                                          *model.xyz[:, :2].max(axis=0))]}
