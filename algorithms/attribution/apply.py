"""attribution:apply - restitution entities + code file -> coded, styled GeoPackage."""

from __future__ import annotations

import glob

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Crs, Enum, File, String
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.attribution import CODED, RestitutionFiles
from toolbox.ui.parameter_file import file_backed

#: parameter-file entries this algorithm uses (the others are named in an information message)
USED_ENTRIES = ("closure_tolerance", "snap_tolerance", "height_snap_tolerance", "decimals",
                "coordinate_offset", "coordinate_unit")


@register
class ApplyCodes(Algorithm):
    """Turn restitution entities into the coded, symbolised deliverable (thesis S002 §2.2.1,
    §2.2.2, §3.6).

    INPUT is the restitution: the ASCII export (``CODE <code> [colour] [source]`` / ``E N Z``
    lines / ``END``), a DXF (layers are codes; 3D polylines, lines, points, blocks as symbols with
    insertion, rotation and scale, texts as label points; arcs, circles, bulged polylines,
    ellipses and splines as chords within 0.01 drawing units; mirrored (OCS) entities in world
    coordinates), or any vector layer with a code field
    (CODE_FIELD). With COORDINATES, INPUT is the descriptions table of the two-table form.
    Several INPUT files are adjacent stereo models, merged first ("fusione": lines meeting across
    the model edge within the reattach tolerances joined, duplicates removed, both reported in
    the ``merge`` layer; of two duplicates the one of the model given first in INPUT is kept, and
    a warning counts those dropped).

    CODES gives each code its description, geometry type and colour index; COLOURS the RGB
    percentages of each index. Every entity gets code, description, colour (hex, R, G, B),
    source, vertices, length or area and perimeter, Z min/max/mean (Z stays in the geometry).
    LAYOUT=code writes one layer per code (Z-Map's way), LAYOUT=type one layer per geometry type
    (points, lines, polygons) with a code field. Outlines of polygon codes are closed when their
    ends miss by at most the closure tolerance.

    Nothing is dropped silently: entities without a code, with an unknown code, a geometry that
    does not match the code's type, or degenerate (a line with one vertex, an unclosed polygon
    beyond the closure tolerance, a polygon of zero area) go to the ``unresolved`` layer (a point
    at the first vertex, the entity as read in ``geometry_wkt``) with the reason; STATISTICS
    counts them per code and lists the declared codes not used. Texts go to ``labels``.

    Every layer gets a QGIS style (QML) and an SLD from the code and colour files, stored as its
    default style in the GeoPackage's ``layer_styles`` table (QGIS opens it styled); with
    STYLE_FILES they are also written beside OUTPUT as ``OUTPUT.<layer>.qml`` / ``.sld`` (with
    the GeoPackage, all or none; existing ones are replaced only with --overwrite).

    PARAMETERS (the "file dei parametri"): closure tolerance, planimetric and altimetric reattach
    tolerances (merge), number of decimals (coordinates rounded), coordinate translation (added
    to every input coordinate), coordinate unit (checked against CRS); its other entries (for
    other steps) are named in an information message, unknown names in a warning. Explicit
    parameters win over the file.
    """

    id = "attribution:apply"
    display_name = "Apply code file"
    group = "Attribution"
    short_help = ("Restitution (ASCII, two tables, DXF, OGR; several models merged) + code and "
                  "colour files -> coded GeoPackage with embedded QGIS styles and an unresolved "
                  "layer.")
    parameters = [
        RestitutionFiles("INPUT", "restitution file(s); repeat for adjacent models"),
        File("COORDINATES", "coordinates table of the two-table form (INPUT is then the "
             "descriptions table)", optional=True),
        String("CODE_FIELD", "code field of an OGR input (default: code, codice, cod, layer)",
               optional=True),
        File("CODES", "code file ('file dei codici')"),
        File("COLOURS", "colour file ('file dei colori': INDEX %R %G %B)", optional=True),
        File("PARAMETERS", "parameter file ('file dei parametri')", optional=True),
        Crs("CRS", "CRS of inputs that carry none (ASCII, two tables, DXF)", optional=True),
        Enum("LAYOUT", "one layer per code, or one per geometry type with a code field",
             options=["code", "type"], default="code"),
        file_backed("CLOSURE_TOLERANCE", "largest gap closed in a polygon outline, CRS units",
                    "closure_tolerance"),
        file_backed("SNAP_TOLERANCE", "planimetric reattach tolerance of the model merge",
                    "snap_tolerance"),
        file_backed("HEIGHT_SNAP_TOLERANCE", "altimetric reattach tolerance of the model merge",
                    "height_snap_tolerance"),
        Boolean("STYLE_FILES", "also write each layer's QML and SLD beside OUTPUT",
                default=False),
        OutputVector("OUTPUT", "GeoPackage: coded layers, unresolved, labels, merge; styled",
                     layers=[CODED,
                             Layer("unresolved", "Point Z", [("code", "string"),
                                                             ("reason", "string", "why")],
                                   "entities not resolved, with the reason (never dropped)"),
                             Layer("labels", "Point Z", [("text", "string")],
                                   "DXF texts as label points", optional=True),
                             Layer("merge", "Point Z", [("kind", "string"), ("code", "string")],
                                   "model-merge events", optional=True)]),
    ]
    outputs = [Output("STATISTICS", "counts per code and reason, unused codes, merge report",
                      "dict")]

    def check(self, params):
        from toolbox.io.code_file import read_code_file, read_colour_file
        from toolbox.io.parameter_file import optional_parameter_file
        from toolbox.styles.symbology import check_symbology

        # bad auxiliary files (and a code file's bad symbology) fail before any work
        check_symbology(read_code_file(params["CODES"], "CODES"))
        if params.get("COLOURS") is not None:
            read_colour_file(params["COLOURS"], "COLOURS")
        optional_parameter_file(params.get("PARAMETERS"))

    def planned_files(self, params):
        if not params["STYLE_FILES"]:
            return {}
        name = glob.escape(params["OUTPUT"].name)  # layers known once read: any sidecar
        return {"OUTPUT": [f"{name}.*.qml", f"{name}.*.sld"]}

    def process(self, params, feedback: Feedback):
        from toolbox.attribution.coding import attribute
        from toolbox.attribution.model_merge import (
            duplicates_warning,
            events_frame,
            merge_models,
            merge_snap_warning,
        )
        from toolbox.attribution.output import MERGE_STYLE, write_attribution
        from toolbox.attribution.sources import check_coordinates, read_sources, translated
        from toolbox.io.code_file import read_code_file, read_colour_file
        from toolbox.io.parameter_file import optional_parameter_file, resolve

        table = read_code_file(params["CODES"], "CODES")
        colours = (read_colour_file(params["COLOURS"], "COLOURS")
                   if params.get("COLOURS") is not None else None)
        file = optional_parameter_file(params.get("PARAMETERS"))
        closure, _ = resolve(params.get("CLOSURE_TOLERANCE"), file, "closure_tolerance")
        snap, _ = resolve(params.get("SNAP_TOLERANCE"), file, "snap_tolerance")
        zsnap, _ = resolve(params.get("HEIGHT_SNAP_TOLERANCE"), file, "height_snap_tolerance")
        decimals = None if file is None else file.values.get("decimals")  # None: not rounded
        frames, reports = read_sources(
            params["INPUT"], params.get("CRS"), feedback,
            coordinates=params.get("COORDINATES"), code_field=params.get("CODE_FIELD"))
        feedback.set_progress(20, f"read {sum(len(f) for f in frames)} entities")
        if file is not None:
            file.warn_unused(USED_ENTRIES, feedback, self.id)
            file.check_unit(frames[0].crs, feedback)
            if file.offset != (0.0, 0.0):
                frames = [translated(f, file) for f in frames]
                feedback.push_info(f"PARAMETERS: coordinate translation {file.offset[0]:.10g} "
                                   f"{file.offset[1]:.10g} added to every coordinate")
        check_coordinates(frames, self.id, file is not None and file.offset != (0.0, 0.0))
        merge = None
        if len(frames) > 1:
            warning = merge_snap_warning(frames, snap)
            if warning:
                feedback.push_warning(warning)
            merge = merge_models(frames, snap, zsnap)
            entities = merge.entities
            feedback.push_info("merge: {models} models, {duplicates_removed} duplicates "
                               "removed, {joins} lines joined across the model edges".format(
                                   **merge.statistics))
            warning = duplicates_warning(merge.statistics)
            if warning:
                feedback.push_warning(warning)
        else:
            entities = frames[0]
        feedback.set_progress(40, "attributing")
        result = attribute(entities, table, colours, closure, params["LAYOUT"], decimals)
        stats = result.statistics
        if stats["unresolved"]:
            feedback.push_warning(f"{stats['unresolved']} entities unresolved: "
                                  + ", ".join(f"{n} {r}" for r, n in
                                              sorted(stats["unresolved_by_reason"].items())))
        if stats["unused_codes"]:
            feedback.push_warning(f"{len(stats['unused_codes'])} codes of CODES not used: "
                                  + ", ".join(stats["unused_codes"][:20]))
        feedback.set_progress(70, "writing")
        with feedback.timed("write"):
            extra = {} if merge is None else {
                "merge": (events_frame(merge.events, entities.crs), MERGE_STYLE)}
            styles = write_attribution(params["OUTPUT"], result, table, colours, entities.crs,
                                       sidecar=params["STYLE_FILES"], extra=extra)
        stats["tolerances"] = {"closure": closure, "snap": snap, "height_snap": zsnap,
                               "decimals": decimals}
        stats["readers"] = reports
        stats["styled_layers"] = sorted(styles)
        if merge is not None:
            stats["merge"] = merge.statistics
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
