"""attribution:merge - the model merge ("fusione") on its own: adjacent models into one set."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, File, String
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.attribution import RestitutionFiles
from toolbox.ui.parameter_file import file_backed

USED_ENTRIES = ("snap_tolerance", "height_snap_tolerance", "coordinate_offset",
                "coordinate_unit")


@register
class MergeModels(Algorithm):
    """Merge the restitution of adjacent stereo models into one set covering the sheet
    ("fusione", thesis S002 §2.2.3), without coding it (``attribution:apply`` does the same merge
    when given several INPUT files, then codes the result).

    An entity of a later model with the same code as one of an earlier model, within
    SNAP_TOLERANCE of it everywhere (Hausdorff distance in plan) and HEIGHT_SNAP_TOLERANCE in
    height at its ends, is a duplicate and is removed: the copy of the model given first in INPUT
    is kept (a warning counts them). Open lines of the same code from different
    models whose ends meet within both tolerances are joined (the meeting vertex is the mean of
    the two ends), repeatedly; ends meeting in plan but not in height are reported, not joined.

    OUTPUT has ``points``, ``lines`` and ``polygons`` (code, model, entity, colour, source, file,
    line; Z kept) and ``merge`` (one point per event: duplicate_removed, joined, join_refused).
    Entities without coordinates cannot be placed: they are counted in STATISTICS. The
    PARAMETERS file gives the reattach tolerances and the coordinate translation (added to every
    input coordinate).
    """

    id = "attribution:merge"
    display_name = "Merge models"
    group = "Attribution"
    short_help = ("Merge adjacent stereo models: lines joined across the model edge within the "
                  "reattach tolerances, duplicates removed, both reported.")
    parameters = [
        RestitutionFiles("INPUT", "restitution file of each model (repeat the option)"),
        String("CODE_FIELD", "code field of OGR inputs", optional=True),
        File("PARAMETERS", "parameter file ('file dei parametri')", optional=True),
        Crs("CRS", "CRS of inputs that carry none (ASCII, DXF)", optional=True),
        file_backed("SNAP_TOLERANCE", "planimetric reattach tolerance", "snap_tolerance"),
        file_backed("HEIGHT_SNAP_TOLERANCE", "altimetric reattach tolerance",
                    "height_snap_tolerance"),
        OutputVector("OUTPUT", "GeoPackage: points, lines, polygons, merge", layers=[
            Layer("*", "Geometry", [("code", "string", "restitution code")],
                  "merged entities, one layer per geometry kind"),
            Layer("merge", "Point Z", [("kind", "string"), ("code", "string")],
                  "joins, duplicates removed, refused joins", optional=True)]),
    ]
    outputs = [Output("STATISTICS", "models, duplicates removed, joins, refused joins", "dict")]

    def check(self, params):
        from toolbox.errors import ParameterError

        if len(params["INPUT"]) < 2:
            raise ParameterError("INPUT", f"needs the files of at least two models, got "
                                 f"{len(params['INPUT'])}")

    def process(self, params, feedback: Feedback):
        import geopandas as gpd
        import shapely

        from toolbox.attribution.model_merge import (
            duplicates_warning,
            events_frame,
            merge_models,
            merge_snap_warning,
        )
        from toolbox.attribution.sources import read_sources, translated
        from toolbox.io.parameter_file import optional_parameter_file, resolve
        from toolbox.io.vector_write import write_layers

        file = optional_parameter_file(params.get("PARAMETERS"))
        snap, _ = resolve(params.get("SNAP_TOLERANCE"), file, "snap_tolerance")
        zsnap, _ = resolve(params.get("HEIGHT_SNAP_TOLERANCE"), file, "height_snap_tolerance")
        frames, _ = read_sources(
            params["INPUT"], params.get("CRS"), feedback,
            coordinates=params.get("COORDINATES"), code_field=params.get("CODE_FIELD"))
        if file is not None:
            file.warn_unused(USED_ENTRIES, feedback, self.id)
            file.check_unit(frames[0].crs, feedback)
            frames = [translated(f, file) for f in frames]
        warning = merge_snap_warning(frames, snap)
        if warning:
            feedback.push_warning(warning)
        result = merge_models(frames, snap, zsnap)
        warning = duplicates_warning(result.statistics)
        if warning:
            feedback.push_warning(warning)
        merged = result.entities
        crs = merged.crs
        types = shapely.get_type_id(merged.geometry.values)
        keep = ["code", "model", "entity", "colour", "source", "file", "line", "kind"]
        layers, gtypes = {}, {}
        for name, ids, gtype in (("points", (0,), "Point"), ("lines", (1, 2), "LineString"),
                                 ("polygons", (3,), "Polygon")):
            sel = merged[[t in ids for t in types]]
            if len(sel):
                layers[name] = gpd.GeoDataFrame(sel[keep], geometry=sel.geometry, crs=crs)
                gtypes[name] = gtype + (" Z" if bool(sel.geometry.has_z.any()) else "")
        layers["merge"] = events_frame(result.events, crs)
        gtypes["merge"] = "Point Z"
        write_layers(params["OUTPUT"], layers, crs=crs, geometry_types=gtypes)
        from toolbox.attribution.output import MERGE_STYLE, store_style
        from toolbox.styles.qml import qml_document
        from toolbox.styles.sld import sld_document

        # GeoPackage: its layer_styles table; a one-layer format (.shp, .fgb, .geojson,
        # .parquet): <merge layer file stem>.qml/.sld beside that file (sqlite on a FlatGeobuf
        # failed the run, blaming an input as corrupt)
        store_style(params["OUTPUT"], list(layers), "merge", qml_document(MERGE_STYLE),
                    sld_document(MERGE_STYLE), fields=list(layers["merge"].columns.drop(
                        layers["merge"].geometry.name)))
        stats = dict(result.statistics)
        stats["without_coordinates"] = int(merged.geometry.isna().sum())
        stats["layers"] = {k: len(v) for k, v in layers.items()}
        stats["tolerances"] = {"snap": snap, "height_snap": zsnap}
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
