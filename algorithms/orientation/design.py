"""orientation:design - flight plan, control layout and predicted precision of a block."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Crs, Enum, ExtentParameter, Integer, Number, String, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.photogrammetry import report_output


@register
class BlockDesign(Algorithm):
    """Plan a photogrammetric block and predict its precision (002 par. 1.3.5; 004 sl. 17-29).

    Area: AREA (polygons, their union) or EXTENT, in a projected CRS (metres). Photo scale:
    PHOTO_SCALE, or from MAP_SCALE by 002's Table 3 (middle of the printed range, c = 150 mm);
    flying height above ground ``H = c·m_b``. Strips run along AZIMUTH (degrees clockwise from
    grid north; default the area's long side), spaced ``(1 - SIDE_OVERLAP)·L_across``, photos
    ``(1 - FORWARD_OVERLAP)·L_along`` apart (FORMAT: frame ``across x along`` in mm), enough for
    stereo cover of the area with one photo more at each strip end; the report also gives the
    minimum count of 002 eq. [3], ``S / ((1 - R1)(1 - R2)·L²)``.

    Control (004 sl. 19-24): planimetric (XY, ids PCP...) points along the long edges every
    EDGE_INTERVAL models, full (XYZ, GCP...) points at both ends of every strip and where a
    height line meets an edge point, height (Z, HCP...) points on lines across the block every
    HEIGHT_INTERVAL models (one per side-overlap line); each location as a pair of points
    (PAIRS, sl. 22: blunders then show), ids ending a/b.

    Predicted precision: a covariance analysis of the planned block adjusted by independent
    models (planimetric with 4 parameters per model for X, Y; spatial with 7 and the projection
    centres for Z), model coordinates with ``m_b·IMAGE_SIGMA`` in X, Y and
    ``m_b·(H/B)·√2·IMAGE_SIGMA`` in height, control exact. Tie-point sigmas (mean and largest,
    m, per coordinate), isolated points 33 % worse (sl. 22), METHOD bundle halves them (sl. 29).
    MAX_SIGMA_XY / MAX_SIGMA_Z (a tender's requirement, m) are checked against the worst
    isolated point: verdict pass or fail in the report.

    OUTPUT layers: ``photo_centres`` (Point Z at the flying altitude TERRAIN_HEIGHT + H: photo,
    strip, number), ``footprints`` (ground cover of each photo on flat terrain), ``control``
    (Point: id, kind XYZ/XY/Z, reason, pair). REPORT (JSON): the plan's figures, the control and the
    prediction.
    """

    id = "orientation:design"
    display_name = "Block design and precision prediction"
    group = "Orientation"
    short_help = "Flight plan (strips, photo centres, count), control layout and predicted " \
                 "precision of a photogrammetric block, checked against a tender."
    parameters = [
        VectorLayer("AREA", "project area (polygons)", geometry_types=["polygon"],
                    optional=True),
        ExtentParameter("EXTENT", "project area 'xmin,ymin,xmax,ymax EPSG:3003' (CRS optional) "
                        "instead of AREA",
                        optional=True),
        Crs("CRS", "CRS of EXTENT or AREA when they name none (one naming another CRS is "
            "refused); projected, metres",
            optional=True),
        Number("MAP_SCALE", "map scale number (1000 for 1:1000): photo scale by 002 Table 3",
               optional=True, min_value=1),
        Number("PHOTO_SCALE", "photo scale number (instead of MAP_SCALE)", optional=True,
               min_value=1),
        Number("PRINCIPAL_DISTANCE", "camera principal distance, mm", default=150.0,
               min_value=0, min_exclusive=True),
        String("FORMAT", "frame size 'across x along' the flight, mm (one number: square)",
               default="230x230"),
        Number("FORWARD_OVERLAP", "forward overlap, %", default=60.0, min_value=50,
               max_value=95),
        Number("SIDE_OVERLAP", "side overlap, %", default=25.0, min_value=0, max_value=90),
        Number("TERRAIN_HEIGHT", "mean ground height, m", default=0.0),
        Number("AZIMUTH", "flight direction, degrees clockwise from grid north (default: along "
               "the area's long side)", optional=True),
        Integer("EDGE_INTERVAL", "models between planimetric control points along the long edges",
                default=4, min_value=1),
        Integer("HEIGHT_INTERVAL", "models between height-control lines", default=4,
                min_value=1),
        Boolean("PAIRS", "each control location as a pair of points", default=True),
        Number("IMAGE_SIGMA", "image measurement sigma, µm", default=6.0, min_value=0,
               min_exclusive=True),
        Enum("METHOD", "adjustment the prediction is for", options=("bundle", "models"),
             default="bundle"),
        Number("MAX_SIGMA_XY", "tender: largest planimetric sigma allowed, m", optional=True,
               min_value=0, min_exclusive=True),
        Number("MAX_SIGMA_Z", "tender: largest height sigma allowed, m", optional=True,
               min_value=0, min_exclusive=True),
        OutputVector("OUTPUT", "GeoPackage: photo_centres, footprints, control", layers=[
            Layer("photo_centres", "Point Z", [("photo", "string"), ("strip", "integer"),
                                               ("number", "integer")], "planned exposures"),
            Layer("footprints", "Polygon", [("photo", "string"), ("strip", "integer")],
                  "ground cover of each photo on flat terrain"),
            Layer("control", "Point", [("point_id", "string"), ("kind", "string"),
                                       ("reason", "string"), ("pair", "integer")],
                  "planned control points")]),
        report_output(),
    ]
    outputs = [Output("STATISTICS", "strips, photos, models, control, predicted sigmas, "
                      "verdict", "dict")]

    def check(self, params: dict[str, Any]) -> None:
        if (params.get("AREA") is None) == (params.get("EXTENT") is None):
            raise self.fail("EXTENT", "or AREA: give exactly one of them")
        if (params.get("MAP_SCALE") is None) == (params.get("PHOTO_SCALE") is None):
            raise self.fail("PHOTO_SCALE", "or MAP_SCALE: give exactly one of them")
        _format(params["FORMAT"])
        self._plan(params)  # the size guard: refused here, before the run (and in --validate)

    def _plan(self, params: dict[str, Any]) -> tuple:
        """``(plan, spec, crs, scale, scale_range)``; a block larger than the precision
        analysis can take is refused naming the scale parameter, before any photo is laid."""
        import shapely

        from toolbox.io.crs import common_crs
        from toolbox.io.vector import read_vector
        from toolbox.triangulation.flightplan import (
            BlockTooLarge,
            FlightSpec,
            photo_scale_for_map,
            plan_flight,
        )
        from toolbox.triangulation.prediction import MAX_MODEL_UNKNOWNS

        if params["EXTENT"] is not None:
            area = shapely.box(*params["EXTENT"].bounds)
            crs = common_crs({"EXTENT": params["EXTENT"].crs}, params["CRS"])
        else:
            frame = read_vector(params["AREA"], name="AREA")
            polys = frame.geometry[frame.geometry.notna()]
            if polys.empty:
                raise self.fail("AREA", "has no polygon")
            # a bow-tie: its lobes; overlapping parts of a multi-polygon united (not cut out)
            area = shapely.union_all(shapely.make_valid(polys.values, method="structure",
                                                        keep_collapsed=False))
            crs = common_crs({"AREA": frame.crs}, params["CRS"])
        if crs is not None and crs.is_geographic:
            raise self.fail("CRS" if params["EXTENT"] is not None else "AREA",
                            f"must be a projected CRS in metres, got {crs.name}")
        scale_range = None
        if params["PHOTO_SCALE"] is not None:
            scale = params["PHOTO_SCALE"]
        else:
            scale, scale_range = photo_scale_for_map(params["MAP_SCALE"])
        spec = FlightSpec(scale, params["PRINCIPAL_DISTANCE"], _format(params["FORMAT"]),
                          params["FORWARD_OVERLAP"] / 100, params["SIDE_OVERLAP"] / 100,
                          params["TERRAIN_HEIGHT"], params["AZIMUTH"], params["EDGE_INTERVAL"],
                          params["HEIGHT_INTERVAL"], params["PAIRS"])
        try:
            plan = plan_flight(area, spec, max_models=MAX_MODEL_UNKNOWNS // 7)
        except BlockTooLarge as exc:
            name = "PHOTO_SCALE" if params["PHOTO_SCALE"] is not None else "MAP_SCALE"
            x0, y0, x1, y1 = area.bounds
            raise self.fail(name, f"{params[name]:g} (photo scale 1:{scale:g}) over the "
                            f"{x1 - x0:,.0f} x {y1 - y0:,.0f} m area: {exc} the precision "
                            f"analysis takes; use a larger {name} number or a smaller EXTENT "
                            "or AREA (plan the block in parts)") from None
        return plan, spec, crs, scale, scale_range

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import math

        import geopandas as gpd
        import shapely

        from toolbox.io.vector_write import write_layers
        from toolbox.photogrammetry.tables import write_json
        from toolbox.triangulation.prediction import predict, summary, verdict

        plan, spec, crs, scale, scale_range = self._plan(params)
        feedback.set_progress(30)
        pred = predict(plan)
        stats = summary(pred, params["IMAGE_SIGMA"] / 1000.0, params["METHOD"])
        stats["worst_xy_point"] = plan.to_ground([stats.pop("worst_xy_point_uv")])[0].tolist()
        check = verdict(stats, params["MAX_SIGMA_XY"], params["MAX_SIGMA_Z"])
        feedback.set_progress(80)
        names = [f"{s + 1}_{k + 1:03d}" for s, k in zip(plan.photo_strip, plan.photo_index,
                                                         strict=True)]
        altitude = spec.terrain_height + plan.flying_height
        xy = plan.photo_xy
        centres = gpd.GeoDataFrame(
            {"photo": names, "strip": plan.photo_strip + 1, "number": plan.photo_index + 1},
            geometry=shapely.points(xy[:, 0], xy[:, 1], altitude), crs=crs)
        across, along = plan.ground_side
        corners = [(-along / 2, -across / 2), (along / 2, -across / 2), (along / 2, across / 2),
                   (-along / 2, across / 2)]
        prints = [shapely.Polygon(plan.to_ground(uv + corners)) for uv in plan.photo_uv]
        footprints = gpd.GeoDataFrame({"photo": names, "strip": plan.photo_strip + 1},
                                      geometry=prints, crs=crs)
        cxy = plan.control_xy
        pair = 2 if spec.pairs else 1
        ids = [{"XYZ": "GCP", "XY": "PCP", "Z": "HCP"}[k] + f"{i // pair + 1:03d}"
               + ("ab"[i % 2] if spec.pairs else "") for i, k in enumerate(plan.control_kind)]
        control = gpd.GeoDataFrame(
            {"point_id": ids, "kind": plan.control_kind, "reason": plan.control_reason,
             "pair": [i // pair + 1 for i in range(len(ids))]},
            geometry=shapely.points(cxy[:, 0], cxy[:, 1]), crs=crs)
        write_layers(params["OUTPUT"], {"photo_centres": centres, "footprints": footprints,
                                        "control": control}, crs=crs,
                     geometry_types={"photo_centres": "Point Z", "footprints": "Polygon",
                                     "control": "Point"})
        statistics = {
            "photo_scale": scale, "photo_scale_range_table3": scale_range,
            "flying_height_above_ground_m": plan.flying_height, "flying_altitude_m": altitude,
            "azimuth_deg": math.degrees(plan.azimuth),
            "ground_side_across_along_m": list(plan.ground_side), "base_m": plan.base,
            "strip_spacing_m": plan.spacing, "area_m2": plan.area_m2,
            "strips": plan.n_strips, "photos": len(plan.photo_uv), "models": len(plan.models),
            "minimum_photos_eq3": plan.minimum_photos,
            "control_points": {k: plan.control_kind.count(k) for k in ("XYZ", "XY", "Z")},
            "prediction": stats, **check}
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {
                "algorithm": self.id, **statistics,
                "units": "metres; sigmas per coordinate (XY = sqrt((sX² + sY²)/2))",
                "rules": {"isolated_points": "tie-point sigma x 4/3 (004 sl. 22)",
                          "bundle": "s_M halved (004 sl. 29)",
                          "verdict": "worst isolated point against MAX_SIGMA_XY / MAX_SIGMA_Z"},
                "analysis": {"unknowns": pred.unknowns, "equations": pred.equations}})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"],
                "STATISTICS": statistics}


def _format(text: str) -> tuple[float, float]:
    """``"230x230"`` or ``"230"`` -> (across, along) mm."""
    from toolbox.errors import ParameterError

    parts = [p for p in str(text).lower().replace("*", "x").split("x") if p.strip()]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) == 1:
        values = values * 2
    if len(values) != 2 or not all(0 < v < 1000 for v in values):
        raise ParameterError("FORMAT", f"must be 'ACROSSxALONG' in mm (e.g. 230x230), got "
                             f"{text!r}")
    return values  # type: ignore[return-value]
