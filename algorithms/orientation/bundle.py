"""orientation:bundle - bundle block adjustment (aerial triangulation) with self-calibration."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Enum, File, Integer, Number, String
from toolbox.parameters.outputs import Layer, Output, OutputFile, OutputVector
from toolbox.registry import register
from toolbox.ui.photogrammetry import (
    PROJECT_EXTENSIONS,
    TABLE_EXTENSIONS,
    ground_residuals_layer,
    measurement_parameters,
    report_output,
)


@register
class BundleAdjustment(Algorithm):
    """Bundle block adjustment: the exterior orientation of every photo of a block, the ground
    coordinates of its tie points and, optionally, the cameras' calibration, in one least-squares
    adjustment of all collinearity equations (004; 002 par. 1.6).

    INPUT: image measurements of tie, control and check points, one row per point per photo
    (``point_id``, ``photo``, ``col_px``/``row_px`` or ``x_mm``/``y_mm``, optional ``sigma_px``
    or ``sigma_mm``), as orientation:intersect and the matcher write them. Pixels are converted to
    image mm through each photo's interior orientation (fiducial fit for scanned film, pixel size
    for digital cameras); a photo whose camera is a ``model`` (pinhole or brown, e.g. a drone's
    from orientation:convert) is observed in pixels through the Brown model itself
    (``col = f·xd + cx``, OpenCV's k1-k3, p1, p2), an opencv or fisheye model through its own
    projection with its interior held fixed; CONTROL_INPUT (optional) adds the
    control/check measurements when INPUT holds tie points only. CONTROL: ``id``, ``X``, ``Y``,
    ``Z``, optional ``role`` (control/check),
    ``sigma_xy``, ``sigma_z`` (m): leave X and Y empty for a height point, Z empty for a
    planimetric one. Check points are adjusted as tie points and only compared. GNSS (optional):
    antenna positions ``photo``, ``X``, ``Y``, ``Z`` (optional sigmas, ``strip``, ``time``), at
    the projection centre or offset by LEVER_ARM (camera frame, rotated with the photo);
    GNSS_SHIFT / GNSS_DRIFT add an unknown offset ``s`` / drift ``d·t`` per strip (the ``strip``
    column, else the project's strips; ``time``, else the photo's place in its strip, centred;
    with both, the shift is at the strip's mean time, reported as ``at_time``, so that GPS or
    POSIX seconds do not weaken the adjustment): the datum then needs a full and a second
    height control point. IMU (optional): attitudes
    ``photo``, ``omega``, ``phi``, ``kappa`` (photogrammetric convention, IMU_ANGLE_UNIT,
    optional ``sigma``) observing the angles of ``R·R(b)``; BORESIGHT estimates the 3 boresight
    angles ``b`` (else zero). IMU angles are data-snooped like the other observations.

    Unknowns: 6 exterior parameters per photo, 3 coordinates per point and, per camera, the
    SELF_CALIBRATION parameters: ``c``, ``x0``, ``y0`` (principal point, mm), ``k1``-``k3``
    (radial, ``Δr = k1·r³ + k2·r⁵ + k3·r⁷``, mm), ``p1``, ``p2`` (Brown's decentring, mm⁻¹;
    the correction form of :mod:`toolbox.photogrammetry.camera`), each ``free`` or
    ``weighted:SIGMA`` around the project's value (e.g. ``c, k1`` or ``c:weighted:0.01``), for
    every camera or, with ``@CAMERA``, for one (``x0@wild 303.55``; it overrides). For a Brown
    camera ``f``, ``cx``, ``cy`` (px; aliases of c, x0, y0) and OpenCV's ``k1``-``k3``, ``p1``,
    ``p2``.

    START: ``project`` uses PROJECT's exterior orientations; ``control`` computes them (photos with
    >= 4 control points resected, then tie points intersected and the other photos resected in
    turn; when that cannot reach every photo, the near-vertical block is solved at once as plane
    similarities on the XY control, or, without it, chained in a free frame and put on the GNSS
    centres); ``auto``: project when every photo has one, else control. A block that common
    points do not connect is refused, component by component.

    Solver: Levenberg-Marquardt on a sparse normal matrix reduced on the points (Schur
    complement), coordinates shifted to the block's centroid. Datum: at least 2 planimetric and
    3 height control points (2 full + 1 Z) or GNSS centres on >= 3 photos, else an error naming
    what is missing; a near-singular normal matrix is an error naming the weak parameters.
    Blunders: optional Huber stage (ROBUST), then Baarda's data snooping (SNOOPING): the
    observation of largest |w| > CRITICAL_W is removed and the block adjusted again, until none
    is left; rejected observations are listed with w and redundancy number.

    Outputs: OUTPUT, the orientation project (YAML) with the adjusted orientations (and
    calibration: c, principal point and the polynomial k1, k2, k3, p1, p2 of a film camera;
    a Brown camera is written whole, as a brown model), which ortho:batch reads;
    POINTS (GeoPackage): projection_centres (with standard deviations), points (tie,
    control, check with sigma X/Y/Z), image_residuals (per measurement: µm, px, w-test,
    redundancy number, rejected) and ground_residuals (surveyed -> adjusted, control and check);
    REPORT (JSON): sigma0 a posteriori, redundancy, photos and cameras with standard deviations,
    control/check residuals and RMSE, rejected observations. Its ``rms_image_residual_um`` /
    ``_px`` are per coordinate, sqrt(Σ(vx² + vy²) / 2n) over the n active measurements
    (orientation:check's ``rmse_um`` is of the residual vectors' lengths, √2 times as large).

    REFERENCE (optional): another solution's exterior orientations (e.g. the Z-Map log's), with
    this adjustment's cameras, compared in the terms an adjustment log states its residuals in:
    CONTROL's full points back-projected through both (difference in image µm and px), and
    intersected through the adjusted orientations from their reference image positions
    (ground difference, m); centre and angle differences with the centres' standard
    deviations. With REFERENCE_TOLERANCE (x, y, z m, image µm: e.g. the log's largest control
    residuals) the report says whether they agree ("reference" in REPORT and STATISTICS).
    """

    id = "orientation:bundle"
    display_name = "Bundle block adjustment"
    group = "Orientation"
    short_help = "Aerial triangulation: all photos and tie points in one adjustment, with " \
                 "self-calibration, GNSS, blunder detection and precision."
    parameters = [
        *measurement_parameters("orientation project (YAML): cameras, interior orientations, "
                                "optional approximate exterior orientations"),
        File("CONTROL_INPUT", "image measurements of the control/check points when INPUT holds "
             "only tie points (e.g. orientation:tiepoints' output); same columns and units",
             extensions=TABLE_EXTENSIONS, optional=True),
        File("CONTROL", "surveyed points: id, X, Y, Z (blank X/Y: height point, blank Z: "
             "planimetric), optional role control/check, sigma_xy, sigma_z (m)",
             extensions=TABLE_EXTENSIONS),
        File("GNSS", "GNSS projection centres: photo, X, Y, Z, optional sigma_xy, sigma_z (m)",
             extensions=TABLE_EXTENSIONS, optional=True),
        String("LEVER_ARM", "GNSS antenna offset from the projection centre in the camera frame, "
               "m: 'x, y, z' (x, y along the image axes, z away from the ground)", optional=True),
        Boolean("GNSS_SHIFT", "estimate a GNSS shift per strip (3 unknowns each)",
                default=False),
        Boolean("GNSS_DRIFT", "estimate a GNSS drift per strip (3 unknowns each, per time "
                "unit)", default=False),
        File("IMU", "IMU attitudes: photo, omega, phi, kappa, optional sigma (IMU_ANGLE_UNIT)",
             extensions=TABLE_EXTENSIONS, optional=True),
        Enum("IMU_ANGLE_UNIT", "angle unit of IMU", options=("deg", "rad", "gon"),
             default="deg"),
        Number("IMU_SIGMA", "default sigma of an IMU angle, in IMU_ANGLE_UNIT", default=0.005,
               min_value=0, min_exclusive=True),
        Boolean("BORESIGHT", "estimate the boresight angles between camera and IMU",
                default=False),
        Enum("START", "approximate values: auto, project (PROJECT's exteriors) or control "
             "(resection and intersection chained)", options=("auto", "project", "control"),
             default="auto"),
        String("SELF_CALIBRATION", "calibration unknowns, e.g. 'c, k1' or 'c:weighted:0.01, "
               "x0@CAMERA' (c, x0, y0, k1, k2, k3, p1, p2; @CAMERA: that camera only)",
               optional=True),
        Number("SIGMA_PX", "a priori sigma of a pixel measurement without sigma_px, px",
               default=0.5, min_value=0, min_exclusive=True),
        Number("SIGMA_MM", "a priori sigma of an image-mm measurement without sigma_mm, mm",
               default=0.005, min_value=0, min_exclusive=True),
        Number("CONTROL_SIGMA_XY", "default sigma of control X, Y, m", default=0.02,
               min_value=0, min_exclusive=True),
        Number("CONTROL_SIGMA_Z", "default sigma of control Z, m", default=0.03, min_value=0,
               min_exclusive=True),
        Number("GNSS_SIGMA_XY", "default sigma of GNSS X0, Y0, m", default=0.10, min_value=0,
               min_exclusive=True),
        Number("GNSS_SIGMA_Z", "default sigma of GNSS Z0, m", default=0.15, min_value=0,
               min_exclusive=True),
        Boolean("ROBUST", "Huber reweighting stage before the least squares", default=False),
        Boolean("SNOOPING", "Baarda data snooping: reject and repeat", default=True),
        Number("CRITICAL_W", "w-test critical value (3.29: alpha 0.1 %)", default=3.29,
               min_value=1.0),
        Number("THRESHOLD_PX", "flag image residuals above this, pixels (Z-Map's green/red "
               "check; pixel measurements)", default=1.0, min_value=0, min_exclusive=True),
        Integer("MAX_ITERATIONS", "Levenberg-Marquardt iterations per adjustment", default=50,
                min_value=1, max_value=1000),
        File("REFERENCE", "orientation project whose exterior orientations the adjusted ones are "
             "compared with (e.g. a previous adjustment's), on CONTROL's points",
             extensions=PROJECT_EXTENSIONS, optional=True),
        String("REFERENCE_TOLERANCE", "agreement with REFERENCE: 'x, y, z, image_um' (ground m, "
               "image µm), e.g. the reference log's stated control residuals", optional=True),
        OutputFile("OUTPUT", "orientation project (YAML) with the adjusted orientations",
                   extensions=[".yaml", ".yml"]),
        OutputVector("POINTS", "GeoPackage: projection centres, points, residuals",
                     optional=True, layers=[
                         Layer("projection_centres", "Point Z", [
                             ("photo", "string"), ("X0", "real"), ("Y0", "real"), ("Z0", "real"),
                             ("omega", "real", "rad"), ("phi", "real"), ("kappa", "real"),
                             ("std_X0", "real", "m"), ("std_omega", "real", "rad")],
                             "adjusted projection centres with standard deviations"),
                         Layer("points", "Point Z", [
                             ("point_id", "string"), ("role", "string", "tie/control/check"),
                             ("n_photos", "integer"), ("sigma_x_m", "real"),
                             ("sigma_y_m", "real"), ("sigma_z_m", "real"),
                             ("ellipse_a_m", "real", "standard error ellipse, semi-major axis"),
                             ("ellipse_b_m", "real", "semi-minor axis"),
                             ("ellipse_angle_deg", "real", "major axis from east, CCW")],
                             "adjusted ground points with precision"),
                         Layer("image_residuals", "Point Z", [
                             ("point_id", "string"), ("photo", "string"),
                             ("res_x_um", "real", "computed - observed"), ("res_y_um", "real"),
                             ("res_px", "real"), ("w_x", "real", "w-test"),
                             ("r_x", "real", "redundancy number"),
                             ("rejected", "boolean"),
                             ("flagged", "boolean", "residual over THRESHOLD_PX")],
                             "one row per measurement, at its point"),
                         ground_residuals_layer("surveyed -> adjusted control and check points")]),
        report_output(),
    ]
    outputs = [Output("STATISTICS", "sigma0, redundancy, rejected observations, check RMSE",
                      "dict")]

    def check(self, params: dict[str, Any]) -> None:
        from toolbox.triangulation.reference import parse_tolerance

        parse_tolerance(params["REFERENCE_TOLERANCE"])
        if params["REFERENCE_TOLERANCE"] is not None and params["REFERENCE"] is None:
            raise self.fail("REFERENCE_TOLERANCE", "needs REFERENCE (the orientations to "
                            "compare with)")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import numpy as np

        from toolbox.io.vector_write import write_layers
        from toolbox.photogrammetry.photo import check_measured_pixels
        from toolbox.photogrammetry.project import save_project
        from toolbox.photogrammetry.rotation import to_radians
        from toolbox.photogrammetry.tables import load_project_parameter, write_json
        from toolbox.triangulation import approximations, outputs
        from toolbox.triangulation.adjust import adjust, check_datum, validate
        from toolbox.triangulation.block import Options
        from toolbox.triangulation.inputs import (
            BlockRequest,
            build_block,
            parse_lever_arm,
            read_attitudes,
            read_centres,
            read_control,
            read_measurements,
        )

        project = load_project_parameter(params["PROJECT"])
        measurements = read_measurements(params["INPUT"], params["LAYER"],
                                         params["COORDINATES"])
        if measurements.kind == "pixel":
            check_measured_pixels(project.photos, measurements.point_ids, measurements.photo_ids,
                                  measurements.xy)
        if params["CONTROL_INPUT"] is not None:
            extra = read_measurements(params["CONTROL_INPUT"], None, params["COORDINATES"],
                                      "CONTROL_INPUT")
            if extra.kind == "pixel":
                check_measured_pixels(project.photos, extra.point_ids, extra.photo_ids, extra.xy,
                                      "CONTROL_INPUT")
            if extra.kind != measurements.kind:
                raise self.fail("CONTROL_INPUT", f"has {extra.kind} coordinates but INPUT has "
                                f"{measurements.kind} coordinates: give both in pixels or both "
                                "in image mm")
            measurements = measurements.concatenate(extra)
        control = read_control(params["CONTROL"])
        centres = read_centres(params["GNSS"]) if params["GNSS"] is not None else None
        for name, xy in (("CONTROL", control.xyz[:, :2]),
                         ("GNSS", None if centres is None else centres.xyz[:, :2])):
            if xy is not None and project.crs is not None:
                self._check_crs(name, params[name], project.crs, xy, feedback)
        if (params["GNSS_SHIFT"] or params["GNSS_DRIFT"]) and centres is None:
            raise self.fail("GNSS_SHIFT" if params["GNSS_SHIFT"] else "GNSS_DRIFT",
                            "needs GNSS projection centres (GNSS)")
        if params["BORESIGHT"] and params["IMU"] is None:
            raise self.fail("BORESIGHT", "needs IMU attitudes (IMU)")
        attitudes = read_attitudes(params["IMU"], params["IMU_ANGLE_UNIT"]) \
            if params["IMU"] is not None else None
        request = BlockRequest(project, measurements, control, centres,
                               params["SELF_CALIBRATION"] or "", params["SIGMA_PX"],
                               params["SIGMA_MM"], params["CONTROL_SIGMA_XY"],
                               params["CONTROL_SIGMA_Z"], params["GNSS_SIGMA_XY"],
                               params["GNSS_SIGMA_Z"], parse_lever_arm(params["LEVER_ARM"]),
                               params["GNSS_SHIFT"], params["GNSS_DRIFT"], attitudes,
                               to_radians(params["IMU_SIGMA"], params["IMU_ANGLE_UNIT"]),
                               params["BORESIGHT"])
        block, info = build_block(request)
        unmeasured = [i for i in control.ids if i not in set(block.point_ids)]
        if unmeasured:
            info["notes"] = [f"{len(unmeasured)} CONTROL point(s) not measured in INPUT, not "
                             f"used: {', '.join(unmeasured[:10])}"]
            feedback.push_warning(info["notes"][0])
        validate(block)
        approximations.require_connected(block)
        check_datum(block)
        notes = list(info.get("notes", []))
        start = params["START"]
        missing = [p for p in block.photo_ids if project.photos[p].exterior is None]
        if start == "project" and missing:
            raise self.fail("START", f"project: photo(s) {', '.join(missing[:5])} have no exterior "
                      "orientation in PROJECT (use START=control)")
        if start == "project" or (start == "auto" and not missing):
            eos = [project.photos[p].exterior for p in block.photo_ids]
            exterior = np.array([[*e.centre, e.omega, e.phi, e.kappa] for e in eos])
            approximations.check_start_angle_unit(block, exterior)
            points = approximations.from_exteriors(block, exterior)
            notes.append("approximate values: PROJECT's exterior orientations")
        else:
            with feedback.timed("approximate values"):
                exterior, points, chain = approximations.by_resection(block)
            notes += chain
        if attitudes is not None:
            approximations.check_attitude_unit(block, exterior, params["IMU_ANGLE_UNIT"])
        feedback.set_progress(20)
        options = Options(max_iterations=params["MAX_ITERATIONS"], robust=params["ROBUST"],
                          snooping=params["SNOOPING"], critical_w=params["CRITICAL_W"])
        with feedback.timed("bundle adjustment"):
            solution = adjust(block, exterior, points, options, feedback)
        feedback.set_progress(80)
        for note in solution.notes:
            if note.startswith("weak geometry"):
                feedback.push_warning(note)
        for rj in solution.rejections:
            feedback.push_warning(f"rejected {rj.kind} observation (w = {rj.w:.2f})")
        ground = outputs.ground_comparison(block, solution, control, info["checks"])
        adjusted = outputs.adjusted_project(project, block, solution)
        save_project(adjusted, params["OUTPUT"], relative_images=False)
        if params["POINTS"] is not None:
            write_layers(params["POINTS"], outputs.layers(block, solution, info, ground,
                                                          project.crs, params["THRESHOLD_PX"]),
                         crs=project.crs, geometry_types=outputs.GEOMETRY_TYPES)
        document = outputs.report(block, solution, info, ground, notes + solution.notes,
                                  params["THRESHOLD_PX"])
        if params["REFERENCE"] is not None:
            document["reference"] = self._reference(params, adjusted, control, document)
            feedback.push_info(f"REFERENCE: {document['reference']['summary']['line']}")
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {"algorithm": self.id, **document})
        stats = {k: document["summary"][k] for k in
                 ("sigma0", "redundancy", "iterations", "photos", "points", "rejected",
                  "flagged")}
        stats.update({k: v for k, v in document["summary"].items() if k.endswith("_rmse_m")})
        if "reference" in document:
            stats["reference"] = document["reference"]["summary"]
        return {"OUTPUT": params["OUTPUT"], "POINTS": params["POINTS"],
                "REPORT": params["REPORT"], "STATISTICS": stats}

    def _reference(self, params: dict[str, Any], adjusted, control, document: dict) -> dict:
        """The adjusted orientations against REFERENCE's (with the adjusted cameras) on
        CONTROL's full points (toolbox.triangulation.reference)."""
        from dataclasses import replace

        import numpy as np

        from toolbox.photogrammetry.tables import load_project_parameter
        from toolbox.triangulation.reference import compare, parse_tolerance

        tolerance = parse_tolerance(params["REFERENCE_TOLERANCE"])
        other = load_project_parameter(params["REFERENCE"], "REFERENCE").photos
        ours = adjusted.photos
        common = [p for p in ours if p in other and other[p].exterior is not None]
        if not common:
            raise self.fail("REFERENCE", f"has no exterior orientation of the adjusted photos "
                            f"({', '.join(list(ours)[:5])}), got {params['REFERENCE']}")
        reference = {p: replace(ours[p], exterior=other[p].exterior) for p in common}
        points = {i: xyz for i, xyz in zip(control.ids, control.xyz, strict=True)
                  if np.isfinite(xyz).all()}
        std = {r["photo"]: [r["std_X0"] or np.nan, r["std_Y0"] or np.nan, r["std_Z0"] or np.nan]
               for r in document["photos"]}
        return compare({p: ours[p] for p in common}, reference, points, std, tolerance)

    def _check_crs(self, name: str, path, crs, xy, feedback: Feedback) -> None:
        """A table whose own CRS (GeoPackage layer, or a CSV's ``.prj`` beside it) is not
        PROJECT's, or whose coordinates lie far outside PROJECT's CRS area (e.g. lon/lat
        numbers): a one-line error naming ``name``."""
        from pathlib import Path

        from toolbox.io.crs import check_coordinates_in_area, parse_crs, read_prj, same_crs

        path = Path(path)
        own = None
        if path.suffix.lower() in (".gpkg", ".sqlite"):
            try:
                import pyogrio

                own = pyogrio.read_info(path).get("crs")
            except Exception:  # noqa: BLE001 - an unreadable CRS is judged by the coordinates
                own = None
        elif path.with_suffix(".prj").is_file():
            own = read_prj(path.with_suffix(".prj"), name)  # a Windows-1252 one too
        target = parse_crs(crs, "PROJECT")
        if own:
            own_crs = parse_crs(own, name)
            if not same_crs(own_crs, target):
                self._check_heights(name, own_crs, target, feedback, xy)
        check_coordinates_in_area(name, target, xy, feedback.push_warning)

    def _check_heights(self, name: str, own, target, feedback: Feedback, xy) -> None:
        """``own`` (the table's CRS) is not PROJECT's ``target``: the same horizontal CRS with
        a height datum stated on one side only (``EPSG:3003+5214`` against ``EPSG:3003``) is
        taken as it is, with a warning; two different height datums, or another horizontal
        CRS, a one-line error saying which. Horizontal CRSs whose definitions differ are the
        same when the table's points ``xy`` move by at most 1 mm from one to the other (an ESRI
        ``.prj`` of EPSG:6707 does not equal EPSG:6707's definition)."""
        from toolbox.io.crs import PRJ_TOLERANCE_M, centroid_shift, crs_label, same_crs
        from toolbox.ortho.vertical import datum_label, horizontal_part, same_datum, vertical_part

        if not same_crs(horizontal_part(own), horizontal_part(target)) and \
                not centroid_shift(own, target, xy)[0] <= PRJ_TOLERANCE_M:
            raise self.fail(name, f"is in {crs_label(own)} but PROJECT is in "
                            f"{crs_label(target)}: reproject it to PROJECT's CRS first")
        ours, theirs = vertical_part(target), vertical_part(own)
        if ours is not None and theirs is not None and not same_datum(ours, theirs):
            raise self.fail(name, f"heights are {datum_label(theirs)} but PROJECT's are "
                            f"{datum_label(ours)}: convert its heights to PROJECT's datum first")
        if (ours is None) != (theirs is None):
            feedback.push_warning(f"{name} heights are {datum_label(theirs)}, PROJECT's "
                                  f"{datum_label(ours)}: taken as the same datum")
