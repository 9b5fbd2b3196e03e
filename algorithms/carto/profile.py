"""carto:profile - elevation profiles and cross sections along polylines."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, Field, Integer, Number, RasterLayer, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputFile, OutputVector
from toolbox.registry import register
from toolbox.ui.tin import tin_parameter


@register
class Profile(Algorithm):
    """Elevation profiles and cross sections ("sezioni e profili", S002 §2.2.3).

    Every line of ``INPUT`` is a polyline P1...Pn. ``MODE``:

    - ``step``: heights every ``STEP`` metres of chainage (and at the end), from the ``DEM``
      (bilinear between cell centres; the outer half cell holds the edge's value, as
      ``gdalwarp -r bilinear``) or the ``TIN`` (plane of the triangle);
    - ``contours``: heights where the polyline crosses the ``CONTOURS`` lines, sorted by
      chainage; the ends P1, Pn have no height and are dropped (the thesis' sections from
      contour lines, with no stereo model);
    - ``sections``: the polyline is an axis; sections perpendicular to it every ``SPACING``
      metres (and at its end), ``2·HALF_WIDTH`` long, sampled every ``STEP`` metres;
      ``distance`` is the offset across the axis, negative on its left.

    Output: layers ``profile_points`` (PointZ: ``profile``, ``line``, ``part``, ``section``,
    ``chainage``, ``distance``, ``z``) and ``profile_lines`` (LineString Z per profile or
    section); ``PLOT`` draws them (PNG or SVG). ``line`` is the INPUT feature's 1-based row
    (QGIS' attribute table order) and ``part`` the part of a multi-line (1-based; each part is
    a profile of its own, its chainage from its start; ``profile`` reads ``3.2`` for part 2 of
    feature 3); features without geometry get no profile (a warning names them).
    """

    id = "carto:profile"
    display_name = "Profiles and cross sections"
    group = "Cartography"
    short_help = "Profiles along polylines (constant step or contour crossings), cross sections."
    parameters = [
        VectorLayer("INPUT", "polylines (profile lines or section axes)",
                    geometry_types=["line"]),
        RasterLayer("DEM", "DEM raster", optional=True, role="heights"),
        tin_parameter("TIN triangles (instead of DEM)", optional=True),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        Enum("MODE", "sampling", options=["step", "contours", "sections"], default="step"),
        Number("STEP", "sampling distance along profiles and sections, m", default=10.0,
               min_value=0, min_exclusive=True),
        VectorLayer("CONTOURS", "contour lines (MODE contours)", geometry_types=["line"],
                    optional=True),
        Field("ELEV_FIELD", "elevation field of CONTOURS (default: elev)", parent="CONTOURS",
              numeric=True, optional=True),
        Number("SPACING", "distance between sections along the axis, m (MODE sections)",
               default=50.0, min_value=0, min_exclusive=True),
        Number("HALF_WIDTH", "half width of each section, m (MODE sections)", default=50.0,
               min_value=0, min_exclusive=True),
        OutputVector("OUTPUT", "GeoPackage (layers profile_points, profile_lines)", layers=[
            Layer("profile_points", "Point Z", [("profile", "string"),
                                                ("line", "integer", "INPUT feature, 1-based"),
                                                ("part", "integer", "part of a multi-line"),
                                                ("chainage", "real", "distance along the line's part"),
                                                ("z", "real", "height")],
                  "the sampled stations"),
            Layer("profile_lines", "LineString Z", [("profile", "string"), ("line", "integer"),
                                                    ("part", "integer"), ("length", "real"),
                                                    ("z_min", "real"), ("z_max", "real")],
                  "each profile or section as a 3D line")]),
        OutputFile("PLOT", "plot of the profiles (.png or .svg)", extensions=[".png", ".svg"],
                   optional=True),
    ]
    outputs = [Output("STATISTICS", "profiles, points, height range", "dict")]

    def check(self, params):
        if params["MODE"] == "contours":
            if params.get("CONTOURS") is None:
                raise self.fail("CONTOURS", "is required with MODE contours")
            if not params.get("ELEV_FIELD") and "elev" not in params["CONTOURS"].fields:
                raise self.fail("ELEV_FIELD", f"is required: {params['CONTOURS']} has no "
                                "'elev' field")
        elif (params.get("DEM") is None) == (params.get("TIN") is None):
            raise self.fail("DEM", f"or TIN: give exactly one of them with MODE "
                            f"{params['MODE']}")
        if params.get("DEM") is not None:  # south-up or east to west: sampled as they lie
            from toolbox.io.raster import require_north_up

            require_north_up(params["DEM"].transform, "DEM", params["DEM"].path, flips_ok=True)

    # duplicate-ok: process() imports its libraries lazily (toolbox list/help stay light); the
    # lists of lazy imports after a check() look alike across algorithms
    def process(self, params, feedback: Feedback):
        import numpy as np

        from toolbox.cartography.profile_io import (
            Surface,
            guard_profile_size,
            layer_title,
            line_parts,
            plot_profiles,
            profile_frames,
            sample_profiles,
        )
        from toolbox.io.crs import common_crs
        from toolbox.io.vector import read_vector
        from toolbox.io.vector_write import write_layers

        lines_frame = read_vector(params["INPUT"], name="INPUT")
        crs = common_crs({name: getattr(params.get(name), "crs", None)
                          for name in ("INPUT", "DEM", "TIN", "CONTOURS")})  # mixed: refused
        lines = line_parts(lines_frame, feedback.push_warning)
        guard_profile_size([line.xy for line in lines], params["MODE"], params["STEP"],
                           params["SPACING"], params["HALF_WIDTH"])
        surface, contours = None, None
        if params["MODE"] == "contours":
            cframe = read_vector(params["CONTOURS"], name="CONTOURS")
            contours = (cframe.geometry.values,
                        np.asarray(cframe[params.get("ELEV_FIELD") or "elev"], dtype="float64"))
        else:
            surface = Surface(params.get("DEM"), params["BAND"], params.get("TIN"))
        profiles = sample_profiles(lines, params["MODE"], params["STEP"], surface, contours,
                                   params["SPACING"], params["HALF_WIDTH"])
        points, line_layer = profile_frames(profiles, crs)
        write_layers(params["OUTPUT"], {"profile_points": points, "profile_lines": line_layer},
                     crs=crs, geometry_types={"profile_points": "Point Z",
                                              "profile_lines": "LineString Z"})
        plotted = 0
        if params.get("PLOT"):
            what = "sections along" if params["MODE"] == "sections" else "profiles of"
            plotted = plot_profiles(profiles, params["PLOT"],
                                    f"{what} {layer_title(params['INPUT'])}")
            if plotted < len(profiles):
                feedback.push_info(f"PLOT shows the first {plotted} of {len(profiles)} "
                                   "profiles/sections (all are in OUTPUT)")
        z = np.concatenate([p.z for p in profiles]) if profiles else np.empty(0)
        missing = int(np.isnan(z).sum())
        if missing:
            feedback.push_warning(f"{missing} stations fall outside the surface (no height)")
        good = z[np.isfinite(z)]
        stats = {"profiles": len(profiles), "plotted": plotted, "points": int(z.size),
                 "no_height": missing,
                 "z_min": float(good.min()) if good.size else None,
                 "z_max": float(good.max()) if good.size else None}
        return {"OUTPUT": params["OUTPUT"], "PLOT": params.get("PLOT"), "STATISTICS": stats}
