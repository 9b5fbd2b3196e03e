"""orientation:footprints - photo footprints on a DEM, nadir and principal points, overlaps."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.ortho.vertical import project_raster_crs
from toolbox.parameters import Integer, Number
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.photogrammetry.coverage import Footprint, overlaps, photo_footprint
from toolbox.photogrammetry.surface import dem_height_range, surface_for_photo
from toolbox.photogrammetry.tables import load_project_parameter
from toolbox.registry import register
from toolbox.ui.photogrammetry import dem_parameters, project_parameter


@register
class Footprints(Algorithm):
    """Ground footprints of oriented photos, with nadir points, principal points and overlaps.

    Each photo's image format (the camera's ``frame_size_mm``, else the image's pixel corners
    through its interior orientation) is densified to POINTS_PER_SIDE points per side and
    projected on the terrain by monoplotting on the DEM (rays marched down from the DEM's top and
    refined to 1e-10 m; collinearity, domain brief section 4), or on the plane Z = MEAN_HEIGHT
    without a DEM. Rays that miss the DEM fall back to the plane (MEAN_HEIGHT, default the DEM's
    mean height) and are counted in ``vertices_off_dem``; such a footprint is ``partial``.
    The DEM is read only in the window each photo can see.

    Output GeoPackage layers: ``footprints`` (PolygonZ: photo, camera, strip, status,
    vertices_off_dem, area_m2, mean_height_m, flying_height_m = Z0 - mean height, photo_scale =
    flying height / c, ground_pixel_m, forward_overlap_pct with the next photo of its strip),
    ``nadir_points`` and ``principal_points`` (PointZ, with on_dem), ``projection_centres``
    (PointZ, X0/Y0/Z0 and the angles in radians) and ``overlaps`` (Polygon: photo_a, photo_b,
    kind forward/side/other, pct_of_a, pct_of_b = intersection area / footprint area). Forward
    pairs are neighbouring photos along a strip (whatever order the project lists them in;
    photos without a strip: consecutive in project order); side pairs are photos of two
    strips where one is the photo of its strip that overlaps the other most (a block's diagonal
    neighbours are other, not held to SIDE_OVERLAP).

    Design rules (thesis S002 par. 1.3.5 and Table 3): every forward pair must overlap by at
    least FORWARD_OVERLAP % (default 60) and every photo must overlap a photo of a neighbouring
    strip by at least SIDE_OVERLAP % (default 20; only checked when the project has several
    strips); with MAP_SCALE the photo scale H / c must lie within Table 3's range for that map
    scale (1:500 ... 1:50,000; a larger photo scale passes). Failures are flagged in the
    ``footprints`` layer (forward_ok, side_overlap_pct, side_ok, photo_scale_ok) and in the
    ``overlaps`` layer (meets_rule), listed in STATISTICS ``design`` and given as warnings.
    """

    id = "orientation:footprints"
    display_name = "Photo footprints"
    group = "Orientation"
    short_help = "Footprints of oriented photos on a DEM, nadir/principal points, overlap %."
    parameters = [
        project_parameter(),
        *dem_parameters(optional=True),
        Number("MEAN_HEIGHT", "plane height without a DEM; fallback plane with one (default: the "
               "DEM's mean), CRS units", optional=True),
        Integer("POINTS_PER_SIDE", "footprint vertices per side of the image format", default=8,
                min_value=1, max_value=1000),
        Number("FORWARD_OVERLAP", "least forward overlap of consecutive photos, % (thesis: 60)",
               default=60.0, min_value=0, max_value=100),
        Number("SIDE_OVERLAP", "least side overlap between strips, % (thesis: 20)", default=20.0,
               min_value=0, max_value=100),
        Number("MAP_SCALE", "map scale number to check the photo scale against Table 3 (e.g. "
               "5000)", optional=True, min_value=1),
        OutputVector("OUTPUT", "GeoPackage of footprints, points and overlaps", layers=[
            Layer("footprints", "Polygon Z", [
                ("photo", "string", "photo id"), ("camera", "string", "camera id"),
                ("strip", "string", "strip id"), ("status", "string", "on the DEM or plane"),
                ("area_m2", "real", "ground area, m²"),
                ("mean_height_m", "real", "mean terrain height, m"),
                ("flying_height_m", "real", "flying height above it, m"),
                ("photo_scale", "real", "scale number 1:n"),
                ("ground_pixel_m", "real", "ground size of a pixel, m"),
                ("forward_overlap_pct", "real", "overlap with the next photo of the strip, %"),
                ("forward_ok", "boolean", "forward overlap >= FORWARD_OVERLAP"),
                ("side_overlap_pct", "real", "largest overlap with a photo of another strip, %"),
                ("side_ok", "boolean", "side overlap >= SIDE_OVERLAP (several strips only)"),
                ("photo_scale_ok", "boolean", "photo scale within Table 3 for MAP_SCALE")],
                "ground footprint of each photo", style="footprints"),
            Layer("nadir_points", "Point Z", [("photo", "string", "photo id"),
                                              ("on_dem", "boolean", "found on the DEM")]),
            Layer("principal_points", "Point Z", [("photo", "string", "photo id"),
                                                  ("on_dem", "boolean", "found on the DEM")]),
            Layer("projection_centres", "Point Z", [
                ("photo", "string", "photo id"), ("X0", "real"), ("Y0", "real"), ("Z0", "real"),
                ("omega_rad", "real"), ("phi_rad", "real"), ("kappa_rad", "real")]),
            Layer("overlaps", "Polygon", [
                ("photo_a", "string"), ("photo_b", "string"),
                ("kind", "string", "forward (same strip), side (side neighbours) or other"),
                ("pct_of_a", "real", "share of A's footprint, %"),
                ("pct_of_b", "real", "share of B's footprint, %"),
                ("meets_rule", "boolean", "forward/side overlap meets its minimum")],
                "overlaps of photo pairs")]),
    ]
    outputs = [Output("STATISTICS", "photos, partial footprints, forward/side overlap ranges",
                      "json")]

    def check(self, params: dict[str, Any]) -> None:
        if params["DEM"] is not None:  # the footprints would fall back to the plane, per photo
            from toolbox.io.raster import require_north_up

            require_north_up(params["DEM"].transform, "DEM", params["DEM"].path)
        if params["DEM"] is None and params["MEAN_HEIGHT"] is None:
            raise self.fail("MEAN_HEIGHT", "is required when no DEM is given (the plane the "
                            "footprints are projected on), got nothing")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        project = load_project_parameter(params["PROJECT"])
        dem = params["DEM"]
        crs = project_raster_crs(project.crs, None if dem is None else dem.crs,
                                 bounds=None if dem is None else dem.bounds)
        photos = project.oriented()
        for pid in (p for p in project.photos if project.photos[p].exterior is None):
            feedback.push_warning(f"photo {pid} has no exterior orientation: skipped")
        if not photos:
            raise InputDataError(f"PROJECT {params['PROJECT']} has no photo with an exterior "
                                 "orientation")
        z_range = None if dem is None else dem_height_range(dem, params["BAND"])
        footprints: list[Footprint] = []
        for photo in feedback.iterate(photos, start=0, end=90):
            surface = None
            if dem is not None:
                try:
                    surface = surface_for_photo(dem, photo, params["BAND"], z_range)
                except InputDataError as exc:
                    feedback.push_warning(f"photo {photo.id}: {exc}; footprint on the plane")
            plane = params["MEAN_HEIGHT"]
            if plane is None:
                plane = float(np.nanmean(surface.z)) if surface is not None else \
                    0.5 * (z_range[0] + z_range[1])
            with feedback.timed("footprints"):
                footprints.append(photo_footprint(photo, surface, plane,
                                                  params["POINTS_PER_SIDE"]))
        consecutive = {(a.id, b.id) for a, b in project.consecutive_pairs()}
        pairs = overlaps(footprints, consecutive)
        layers, stats = self._layers(footprints, pairs, consecutive, dem is not None, crs)
        stats["design"] = design_rules(layers, params["FORWARD_OVERLAP"], params["SIDE_OVERLAP"],
                                       params["MAP_SCALE"], len(project.strips()) > 1)
        for problem in stats["design"]["failures"]:
            feedback.push_warning(problem)
        from toolbox.io.vector_write import write_layers

        write_layers(params["OUTPUT"], layers, crs=crs,
                     geometry_types={"footprints": "Polygon Z", "nadir_points": "Point Z",
                                     "principal_points": "Point Z",
                                     "projection_centres": "Point Z", "overlaps": "Polygon"})
        for fp in footprints if dem is not None else []:
            if fp.vertices_off_dem:
                feedback.push_warning(f"photo {fp.photo.id}: {fp.vertices_off_dem} footprint "
                                      f"vertices miss the DEM; placed on the plane Z = "
                                      f"{fp.plane_height:.2f} (at the DEM's edge where the ray "
                                      "runs over the horizon or the plane is above the camera)")
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}

    @staticmethod
    def _layers(footprints, pairs, consecutive, with_dem: bool, crs):
        import geopandas as gpd
        import shapely

        forward = {}
        for ov in pairs:
            if ov.kind == "forward":
                a, b = (ov.a, ov.b) if (ov.a, ov.b) in consecutive else (ov.b, ov.a)
                pct = ov.percent_of_a if a == ov.a else ov.percent_of_b
                forward[a] = pct
        rows, nadirs, pps, centres = [], [], [], []
        for fp in footprints:
            photo, eo = fp.photo, fp.photo.require_exterior()
            height = eo.z0 - fp.mean_height
            focal_px = getattr(photo.camera, "focal_px", None)
            if focal_px is not None:  # a camera model (px): the ground pixel, no film scale
                scale, ground_pixel = None, height / (sum(focal_px) / 2.0)
            else:
                scale = height * 1000.0 / photo.camera.c
                transform = photo.pixel_transform
                pixel = transform.pixel_size_mm if transform is not None else \
                    photo.camera.pixel_size_mm
                ground_pixel = None if pixel is None else scale * pixel / 1000.0
            status = "plane" if not with_dem else ("partial" if fp.vertices_off_dem else "complete")
            rows.append({"photo": photo.id, "camera": photo.camera.name, "strip": photo.strip,
                         "status": status, "vertices_off_dem": fp.vertices_off_dem,
                         "area_m2": fp.polygon.area, "mean_height_m": fp.mean_height,
                         "flying_height_m": height, "photo_scale": scale,
                         "ground_pixel_m": ground_pixel,
                         "forward_overlap_pct": forward.get(photo.id),
                         "geometry": shapely.Polygon(fp.vertices)})
            for target, point in ((nadirs, fp.nadir), (pps, fp.principal_point)):
                target.append({"photo": photo.id, "on_dem": point.on_dem, "status": point.status,
                               "geometry": shapely.Point(point.xyz)})
            centres.append({"photo": photo.id, "X0": eo.x0, "Y0": eo.y0, "Z0": eo.z0,
                            "omega_rad": eo.omega, "phi_rad": eo.phi, "kappa_rad": eo.kappa,
                            "geometry": shapely.Point(eo.centre)})
        overlap_rows = [{"photo_a": ov.a, "photo_b": ov.b, "kind": ov.kind,
                         "pct_of_a": ov.percent_of_a, "pct_of_b": ov.percent_of_b,
                         "geometry": shapely.force_2d(ov.geometry)} for ov in pairs]

        def frame(records, columns):
            if records:
                return gpd.GeoDataFrame(records, geometry="geometry", crs=crs)
            return gpd.GeoDataFrame({c: [] for c in columns}, geometry=[], crs=crs)

        layers = {"footprints": frame(rows, []), "nadir_points": frame(nadirs, []),
                  "principal_points": frame(pps, []), "projection_centres": frame(centres, []),
                  "overlaps": frame(overlap_rows, ["photo_a", "photo_b", "kind", "pct_of_a",
                                                   "pct_of_b"])}
        fwd = [ov.percent_of_a for ov in pairs if ov.kind == "forward"] + \
            [ov.percent_of_b for ov in pairs if ov.kind == "forward"]
        side = [ov.percent_of_a for ov in pairs if ov.kind == "side"] + \
            [ov.percent_of_b for ov in pairs if ov.kind == "side"]
        stats = {"photos": len(footprints),
                 "partial_footprints": sum(1 for fp in footprints if fp.vertices_off_dem)
                 if with_dem else 0,
                 "forward_overlap_pct": [min(fwd), max(fwd)] if fwd else None,
                 "side_overlap_pct": [min(side), max(side)] if side else None,
                 "overlapping_pairs": len(pairs)}
        return layers, stats


def design_rules(layers: dict, forward_min: float, side_min: float, map_scale: float | None,
                 several_strips: bool) -> dict:
    """Flag the footprints and overlaps that break the flight-design rules (in place)."""
    import pandas as pd

    from toolbox.photogrammetry.accuracy import judge_photo_scale

    def flags(values):  # nullable booleans, so GeoPackage stores them as booleans, not text
        return pd.array(values, dtype="boolean")

    fp, ov = layers["footprints"], layers["overlaps"]
    failures = []
    side = {}
    for row in ov.itertuples():
        if row.kind == "side":
            side[row.photo_a] = max(side.get(row.photo_a, 0.0), row.pct_of_a)
            side[row.photo_b] = max(side.get(row.photo_b, 0.0), row.pct_of_b)
    ov["meets_rule"] = flags([bool(pa >= (forward_min if k == "forward" else side_min) and
                             pb >= (forward_min if k == "forward" else side_min))
                        if k in ("forward", "side") else None
                        for k, pa, pb in zip(ov["kind"], ov["pct_of_a"], ov["pct_of_b"],
                                             strict=True)])
    forward_ok, side_pct, side_ok, scale_ok = [], [], [], []
    for row in fp.itertuples():
        fwd = row.forward_overlap_pct
        ok = None if fwd is None or fwd != fwd else bool(fwd >= forward_min)
        forward_ok.append(ok)
        if ok is False:
            failures.append(f"photo {row.photo}: forward overlap {fwd:.1f} % < {forward_min:g} %")
        pct = side.get(row.photo)
        side_pct.append(pct)
        s_ok = None if not several_strips else bool(pct is not None and pct >= side_min)
        side_ok.append(s_ok)
        if s_ok is False:
            failures.append(f"photo {row.photo}: side overlap "
                            f"{0.0 if pct is None else pct:.1f} % < {side_min:g} %")
        if map_scale is None:
            scale_ok.append(None)
            continue
        judged = judge_photo_scale(row.photo_scale, map_scale)
        scale_ok.append(judged["passes"])
        if judged["passes"] is False:
            lo, hi = judged["table_range"]
            failures.append(f"photo {row.photo}: photo scale 1:{row.photo_scale:.0f} is smaller "
                            f"than Table 3's 1:{lo:,}-1:{hi:,} for a 1:{map_scale:g} map")
    fp["forward_ok"], fp["side_ok"] = flags(forward_ok), flags(side_ok)
    fp["side_overlap_pct"] = pd.array(side_pct, dtype="Float64")
    fp["photo_scale_ok"] = flags(scale_ok)
    return {"forward_overlap_min_pct": forward_min, "side_overlap_min_pct": side_min,
            "map_scale": map_scale, "failures": failures, "passes": not failures}
