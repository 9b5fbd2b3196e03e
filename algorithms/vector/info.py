"""vector:info - what a vector file holds: layers, geometry types, counts, CRS, fields, extent, Z."""

from __future__ import annotations

import json

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.io.crs import crs_label
from toolbox.io.vector import is_parquet, open_layer, read_vector
from toolbox.parameters import Output, OutputFile, VectorLayer
from toolbox.registry import register


def layer_summary(frame) -> dict:
    """Feature count, geometry types, bounds and Z range of a GeoDataFrame."""
    import shapely

    geoms = frame.geometry.values
    summary = {"features": len(frame),
               "geometry_types": sorted(set(frame.geom_type.dropna())),
               "empty_or_null": int((frame.geometry.isna() | frame.geometry.is_empty).sum()),
               "invalid": int((~frame.geometry.is_valid & frame.geometry.notna()).sum()),
               "bounds": [float(v) for v in frame.total_bounds] if len(frame) else None,
               "has_z": bool(len(frame)) and bool(frame.geometry.has_z.any())}
    if summary["has_z"]:
        z = shapely.get_coordinates(geoms, include_z=True)[:, 2]
        z = z[np.isfinite(z)]
        summary["z_range"] = [float(z.min()), float(z.max())] if len(z) else None
    return summary


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
        VectorLayer("INPUT", "vector file (all its layers are described)"),
        OutputFile("OUTPUT", "JSON file to write the description to", extensions=[".json"],
                   optional=True),
    ]
    outputs = [Output("INFO", "the description (layers, counts, CRS, fields, extent)", "json")]

    def process(self, params, feedback):
        import pyogrio

        ref = params["INPUT"]
        single = ref.path is None or is_parquet(ref.path)  # a frame, or one GeoParquet layer
        names = [ref.layer or ref.info.get("layer_name")] if single else [
            str(row[0]) for row in pyogrio.list_layers(ref.path)]
        layers = []
        for name in feedback.iterate(names):
            layer = ref if single else open_layer(f"{ref.path}|layername={name}")
            frame = read_vector(layer)
            layers.append({"name": name, "crs": crs_label(layer.crs),
                           "fields": layer.field_types, **layer_summary(frame)})
        info = {"path": None if ref.path is None else str(ref.path), "layers": layers}
        if params["OUTPUT"] is not None:
            params["OUTPUT"].write_text(json.dumps(info, indent=2) + "\n")
        return {"INFO": info, "OUTPUT": params["OUTPUT"]}
