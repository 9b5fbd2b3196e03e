"""vector:info - what a vector file holds: layers, geometry types, counts, CRS, fields, extent, Z."""

from __future__ import annotations

import json
import re
import warnings

from toolbox.algorithm import Algorithm
from toolbox.io.gpkg_summary import GpkgSummary
from toolbox.parameters import Output, OutputFile, VectorLayer
from toolbox.registry import register

EPSG_CODE = re.compile(r"EPSG:\d+")


def geometry_summary(geoms) -> dict:
    """Feature count, geometry types, empty or null and invalid geometries, bounds (min x, min
    y, max x, max y, CRS units) and Z range of an object array of shapely geometries (None
    where a feature has none), as geopandas reports them for the layer."""
    import numpy as np
    import shapely

    from toolbox.io.vector_write import geometry_type_names

    missing = shapely.is_missing(geoms)
    summary = {"features": len(geoms),
               "geometry_types": sorted(geometry_type_names(geoms)),
               "empty_or_null": int((missing | shapely.is_empty(geoms)).sum()),
               "invalid": int((~shapely.is_valid(geoms) & ~missing).sum()),
               "bounds": None,
               "has_z": bool(shapely.has_z(geoms).any())}
    if len(geoms):
        box = shapely.bounds(geoms)
        if np.isfinite(box).all(axis=1).any():  # else no geometry at all: no bounds, as empty
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                summary["bounds"] = [float(np.nanmin(box[:, 0])), float(np.nanmin(box[:, 1])),
                                     float(np.nanmax(box[:, 2])), float(np.nanmax(box[:, 3]))]
    if summary["has_z"]:
        z = shapely.get_coordinates(geoms, include_z=True)[:, 2]
        z = z[np.isfinite(z)]
        summary["z_range"] = [float(z.min()), float(z.max())] if len(z) else None
    return summary


def layer_crs_label(layer) -> str:
    """``EPSG:3003`` (the code OGR read, without loading pyproj: about a fifth of a small run),
    ``none`` for a file layer without a CRS, else :func:`~toolbox.io.crs.crs_label` of the layer's CRS."""
    crs = layer.info.get("crs")
    if isinstance(crs, str) and EPSG_CODE.fullmatch(crs):
        return crs
    if crs is None:  # a table, or a layer without a CRS
        return "none"
    from toolbox.io.crs import crs_label

    return crs_label(layer.crs)


@register
class VectorInfo(Algorithm):
    """Describe a vector layer: every layer of the file with its geometry types, feature count, CRS,
    fields and types, extent, Z presence and Z range, and the number of invalid or empty geometries.
    The result is returned as ``INFO`` (printed as JSON by the CLI) and optionally written to a
    JSON file.
    """

    id = "vector:info"
    display_name = "Vector layer information"
    group = "Vector"
    short_help = "Layers, geometry types, counts, CRS, fields, extent and Z range of a vector file."
    projected_crs_only = False  # describes any layer, lon/lat included
    parameters = [
        # a GeoPackage of points: described at validation by the standard library's sqlite3
        # (toolbox.io.gpkg_summary), the same description without numpy, pyogrio or shapely
        VectorLayer("INPUT", "vector file (all its layers are described)", summarise=True),
        OutputFile("OUTPUT", "JSON file to write the description to", extensions=[".json"],
                   optional=True),
    ]
    outputs = [Output("INFO", "the description (layers, counts, CRS, fields, extent)", "json")]

    def process(self, params, feedback):
        ref = params["INPUT"]
        if isinstance(ref, GpkgSummary):
            layers = ref.layers
        else:
            layers = self._read_layers(ref, feedback)
        from toolbox.io.paths import absolute_paths

        # absolute as in the run report (a relative path names nothing elsewhere)
        info = {"path": None if ref.path is None else absolute_paths(str(ref.path)),
                "layers": layers}
        if params["OUTPUT"] is not None:
            from toolbox.report import to_jsonable

            # standard JSON (RFC 8259 has no NaN or Infinity: jq and JSON.parse reject them)
            params["OUTPUT"].write_text(json.dumps(to_jsonable(info), indent=2,
                                                   allow_nan=False) + "\n")
        return {"INFO": info, "OUTPUT": params["OUTPUT"]}

    @staticmethod
    def _read_layers(ref, feedback) -> list[dict]:
        """Every layer of ``ref``'s file described through OGR and shapely."""
        from toolbox.io.vector import is_parquet, layer_names, layers_geometries, read_geometries

        single = ref.path is None or is_parquet(ref.path)  # a frame, or one GeoParquet layer
        # every layer: a few reads of all (a file of 200 layers took 200 reads, each opening it)
        names = [] if single else layer_names(ref.path)
        read = [read_geometries(ref)] if single else layers_geometries(ref, layers=names)
        total = 1 if single else len(names)
        layers = []
        for layer, geoms in feedback.iterate(read, total=total):
            name = ref.layer or ref.info.get("layer_name") if single else layer.layer
            layers.append({"name": name, "crs": layer_crs_label(layer),
                           "fields": layer.field_types, **geometry_summary(geoms)})
        return layers
