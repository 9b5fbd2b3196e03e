"""tin:interpolate - height of the TIN surface at points (plane of the containing triangle)."""

from __future__ import annotations

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs
from toolbox.io.vector import feature_rows, no_geometry, read_vector
from toolbox.io.vector_write import write_layers
from toolbox.parameters import Boolean, Number, String, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.tin import tin_parameter


@register
class Interpolate(Algorithm):
    """Height of a TIN at points: the plane through the three nodes of the triangle containing
    each point (thesis S002 par. 2.5.1 eq. [43]-[44]), evaluated exactly.

    The output is the input layer with a height field (FIELD) added and PointZ geometries whose
    Z is that height. Points outside the TIN get NODATA in both and are counted in STATISTICS
    (and a warning). When the input points already have a Z, a field ``dz`` = input Z - TIN Z is
    added and its RMSE reported: a check of the TIN against control points (points that are
    nodes of the TIN, same X, Y and Z, are no check of it: left out, counted and named in a
    warning). Multipoints are
    exploded into single points; features without a geometry (null or empty) are kept, without
    geometry and with NODATA, and named in a warning.
    """

    length_units = "horizontal"  # x, y in one unit (metres or feet); heights in their own

    id = "tin:interpolate"
    display_name = "Interpolate heights on a TIN"
    group = "TIN"
    short_help = "Z of points from the TIN surface (plane of the containing triangle)."
    parameters = [
        VectorLayer("INPUT", "points to give a height", geometry_types=["point"]),
        tin_parameter(),
        String("FIELD", "name of the height field to add", default="z_tin"),
        Boolean("REPLACE_FIELD", "replace FIELD (and dz) when INPUT already has a field of that "
                "name (otherwise an error: an input column is never overwritten silently)",
                default=False),
        Number("NODATA", "height written for points outside the TIN", default=-9999.0),
        OutputVector("OUTPUT", "points with the height field and PointZ geometry", layers=[
            Layer("{INPUT}", "Point Z", [("{FIELD}", "real", "TIN height (NODATA outside)")],
                  "INPUT's points and fields, named like INPUT's layer; with a field dz = input "
                  "Z - TIN Z when the points have a Z")]),
    ]
    outputs = [Output("STATISTICS", "points inside/outside, height range, dz RMSE", "json")]

    def check(self, params):
        name = params["FIELD"].strip()
        if not name or not name.replace("_", "a").isalnum():
            raise self.fail("FIELD", f"must be a field name (letters, digits, _), got "
                            f"{params['FIELD']!r}")
        if params.get("REPLACE_FIELD"):
            return
        existing = {f.lower(): f for f in params["INPUT"].fields}
        if name.lower() in existing:
            raise self.fail("FIELD", f"{name!r} is already a field of INPUT "
                            f"({existing[name.lower()]!r}); choose another name or pass "
                            "--REPLACE_FIELD to replace it")
        if "dz" in existing and " Z" in (params["INPUT"].geometry_type or ""):
            raise self.fail("FIELD", "INPUT has Z and already a field 'dz' (the check difference "
                            "written here); rename it or pass --REPLACE_FIELD to replace it")

    def process(self, params, feedback: Feedback):
        import pandas as pd
        import shapely

        from toolbox.terrain.tin.kernels import interpolate_tin
        from toolbox.terrain.tin.store import read_tin

        crs = common_crs({"INPUT": params["INPUT"].crs, "TIN": params["TIN"].crs})
        with feedback.timed("read"):
            xyz, triangles, _ = read_tin(params["TIN"])
            frame = read_vector(params["INPUT"], name="INPUT")
        frame = frame.reset_index(drop=True)  # the index: the input row, kept through explode
        geoms = frame.geometry.values
        missing = no_geometry(geoms)
        if missing.all():
            raise InputDataError(f"INPUT {params['INPUT']} has no points")
        parts = shapely.get_num_geometries(geoms)
        if np.any(parts > 1):
            feedback.push_info(f"{int((parts > 1).sum())} multipoint(s) exploded")
        points = frame[~missing].explode(index_parts=False)
        if missing.any():  # kept in place, without geometry (explode drops them)
            feedback.push_warning(f"{int(missing.sum())} of {len(frame)} feature(s) "
                                  f"({feature_rows(np.flatnonzero(missing))}) have no geometry "
                                  "(null or empty): kept without geometry, height set to NODATA")
            frame = frame.set_geometry(np.where(missing, None, geoms), crs=frame.crs)
            points = pd.concat([points, frame[missing]]).sort_index(kind="stable")
        frame = points.reset_index(drop=True)
        geoms = frame.geometry.values
        present = ~shapely.is_missing(geoms)
        has_z = bool(shapely.has_z(geoms[present]).all())
        coords = np.full((len(frame), 3 if has_z else 2), np.nan)
        coords[present] = shapely.get_coordinates(geoms[present], include_z=has_z)
        feedback.set_progress(30, "interpolating")
        with feedback.timed("interpolate"):
            z = np.full(len(frame), np.nan)
            z[present] = interpolate_tin(xyz, triangles, coords[present, 0], coords[present, 1])
        no_z = np.isnan(z)  # outside the TIN or without geometry
        outside = no_z & present
        nodata = params["NODATA"]
        field = params["FIELD"].strip()
        frame = frame.drop(columns=[c for c in frame.columns  # REPLACE_FIELD: GPKG names ignore case
                                    if str(c).lower() in (field.lower(), "dz") and
                                    c != frame.geometry.name and (has_z or str(c).lower() != "dz")])
        frame[field] = np.where(no_z, nodata, z)
        stats = {"points": int(present.sum()), "inside": int((~no_z).sum()),
                 "outside": int(outside.sum()), "no_geometry": int((~present).sum()),
                 "nodata": nodata}
        if (~no_z).any():
            stats.update(z_min=float(np.nanmin(z)), z_max=float(np.nanmax(z)))
        if has_z:
            dz = coords[:, 2] - z
            frame["dz"] = np.where(no_z, nodata, dz)
            # a point that is a node of the TIN (same X, Y and Z) has dz = 0 by construction:
            # the TIN was built from it, so it is no independent check of the TIN
            node = _tin_nodes(xyz, coords, ~no_z)
            if node.any():
                feedback.push_warning(
                    f"{int(node.sum())} point(s) of INPUT are nodes of the TIN (same X, Y, Z; "
                    f"{feature_rows(np.flatnonzero(node))}): dz 0 by construction, not checks "
                    "of the TIN; left out of dz_mean, dz_rmse and dz_max_abs")
            stats["dz_points"] = int((~no_z & ~node).sum())
            stats["dz_at_tin_nodes"] = int(node.sum())
            if (~no_z & ~node).any():
                good = dz[~no_z & ~node]
                stats.update(dz_mean=float(good.mean()), dz_rmse=float(np.sqrt(np.mean(good**2))),
                             dz_max_abs=float(np.abs(good).max()))
        if outside.any():
            feedback.push_warning(f"{int(outside.sum())} of {int(present.sum())} point(s) lie "
                                  f"outside the TIN: height set to NODATA ({nodata:g})")
        geoms = np.full(len(frame), None, dtype=object)
        geoms[present] = shapely.points(coords[present, 0], coords[present, 1],
                                        frame[field].to_numpy()[present])
        frame = frame.set_geometry(geoms)
        if crs is not None:
            frame = frame.set_crs(crs, allow_override=True)
        layer = params["INPUT"].layer or params["INPUT"].info.get("layer_name") or "points"
        with feedback.timed("write"):
            write_layers(params["OUTPUT"], {layer: frame}, geometry_types={layer: "Point Z"})
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}


def _tin_nodes(xyz: np.ndarray, coords: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """(N,) True where a point (inside the TIN) is one of its nodes: X, Y, Z equal to within
    1e-9 of the coordinates' magnitude."""
    from scipy.spatial import cKDTree

    out = np.zeros(len(coords), dtype=bool)
    idx = np.flatnonzero(inside & np.isfinite(coords).all(axis=1))
    if not len(idx) or not len(xyz):
        return out
    tol = 1e-9 * max(1.0, float(np.abs(xyz).max()))
    dist, k = cKDTree(xyz[:, :2]).query(coords[idx, :2], distance_upper_bound=tol)
    hit = np.isfinite(dist)
    same_z = np.zeros(len(idx), dtype=bool)
    same_z[hit] = np.abs(xyz[k[hit], 2] - coords[idx[hit], 2]) <= tol
    out[idx[same_z]] = True
    return out
