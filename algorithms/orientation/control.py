"""orientation:control - a control-point measurement template predicted from approximate
orientations, with image chips."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Integer, Number, RasterLayer
from toolbox.parameters.outputs import Output, OutputFile, OutputFolder
from toolbox.registry import register
from toolbox.ui.photogrammetry import project_parameter, table_parameters


@register
class ControlTemplate(Algorithm):
    """Predict where each ground control point falls on every photo and write a measurement
    template with image chips, for the operator to confirm or move.

    CONTROL lists surveyed points (``id``, ``X``, ``Y``, ``Z``; CSV or GeoPackage table,
    LAYER). Each is projected through the collinearity equations (approximate exterior
    orientation, interior orientation, principal point, distortion) onto every photo of
    PROJECT that has an image; points farther than MARGIN pixels inside the frame are listed.

    OUTPUT is the image-measurement CSV (``point_id``, ``photo``, ``col_px``, ``row_px``: pixel
    centres at +0.5) that orientation:intersect / resection / the bundle read, with the
    predicted positions and a ``status`` column (``predicted``) and the chip file; the operator
    edits the positions and the status (e.g. to ``measured``). CHIPS: one PNG per point and
    photo, CHIP_SIZE pixels around the prediction (red cross). Points on no photo are reported;
    none on any photo is an error.

    ORTHO (optional, a reference orthophoto in the project's CRS; one without a CRS is taken
    to be in it, with a warning, when its grid holds a CONTROL point) measures the points
    automatically: around each prediction the photo pixels are cast to the ground on the plane
    of the point's Z through the approximate orientation and the orthophoto is sampled there
    (the ortho chip as the photo would show it), then the photo is searched over SEARCH pixels
    by normalised cross-correlation, the peak finished by least-squares matching. With DEM the
    pixels are cast onto the terrain instead of the plane (recommended: relief around the point
    otherwise biases the match, by up to 2 px on the demo landscape; DEM or MEASURED without
    ORTHO is refused). A point is
    ``matched`` (its measured position written, with ``score`` = the NCC peak) when the peak
    reaches MIN_SCORE, is not on the search's edge and no second peak comes within 0.05 of it;
    otherwise it keeps its predicted position with the reason as status (``low_correlation``,
    ``ambiguous``, ``on_border``, ``flat``, ``off_ortho``, ``off_photo``, ``diverged``) and is
    counted in a warning. The template then gains the columns ``score``, ``runner_up``,
    ``shift_px``, ``predicted_col_px``, ``predicted_row_px``; MEASURED (optional) holds only the
    matched rows (``point_id``, ``photo``, ``col_px``, ``row_px``, ``sigma_px``), ready for
    orientation:bundle's CONTROL_INPUT. The chip is MATCH_SIZE pixels square (half size).
    """

    id = "orientation:control"
    display_name = "Control-point measurement template"
    group = "Orientation"
    short_help = "Predict control points' image positions and write a template with chips."
    parameters = [
        project_parameter("orientation project (YAML) with images and approximate orientations"),
        *table_parameters("CONTROL", "ground control points: id, X, Y, Z"),
        Number("MARGIN", "keep predictions at least this far inside the frame, px", default=0.0,
               min_value=0.0),
        Integer("CHIP_SIZE", "chip half size, px", default=48, min_value=8, max_value=2048),
        RasterLayer("ORTHO", "reference orthophoto (project CRS): measure the points "
                    "automatically", optional=True),
        RasterLayer("DEM", "with ORTHO: terrain heights (project CRS) to cast the ortho chip "
                    "into the photo; without it the plane of the point's Z (relief biases the "
                    "match)", optional=True, role="heights"),
        Integer("MATCH_SIZE", "with ORTHO: correlation chip half size, px", default=15,
                min_value=4, max_value=200),
        Integer("SEARCH", "with ORTHO: search radius around the prediction, px", default=20,
                min_value=2, max_value=500),
        Number("MIN_SCORE", "with ORTHO: smallest NCC peak of a matched point", default=0.7,
               min_value=0.0, max_value=1.0),
        OutputFile("OUTPUT", "measurement template (CSV)", extensions=[".csv"]),
        OutputFolder("CHIPS", "folder of PNG chips", optional=True),
        OutputFile("MEASURED", "with ORTHO: the matched measurements only (CSV for "
                   "orientation:bundle CONTROL_INPUT)", extensions=[".csv"], optional=True),
    ]
    outputs = [Output("STATISTICS", "predictions, points on no photo", "json")]

    def planned_files(self, params):
        """CHIPS: PNG files whose names come from the data (checked as a pattern)."""
        return {"CHIPS": ["*.png"]} if params.get("CHIPS") is not None else {}

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import numpy as np

        from toolbox.errors import InputDataError
        from toolbox.matching.chips import predict, write_chip
        from toolbox.matching.images import ImageSource
        from toolbox.matching.ortho_match import match_point
        from toolbox.photogrammetry.photo import fit_image_size
        from toolbox.photogrammetry.surface import surface_for_photo
        from toolbox.photogrammetry.tables import ground_points, load_project_parameter, write_csv

        project = load_project_parameter(params["PROJECT"])
        ids, xyz, _ = ground_points(params["CONTROL"], params["LAYER"], crs=project.crs)
        ortho = None
        if params["ORTHO"] is not None:
            from toolbox.io.crs import crs_label, one_crs
            from toolbox.matching.ortho_match import OrthoReference
            from toolbox.ortho.vertical import horizontal_part, project_raster_crs

            ortho = OrthoReference.open(params["ORTHO"].path)
            ortho_crs, crs = (None if c is None else horizontal_part(c)
                              for c in (params["ORTHO"].crs, project.crs))
            if ortho_crs is None and crs is not None:  # as report:ortho_check has it
                from toolbox.io.crs import unlabelled_raster

                unlabelled_raster("ORTHO", params["ORTHO"].bounds, project.crs, "PROJECT",
                                  xyz[:, :2], "CONTROL", feedback.push_warning)
            elif crs is not None and not one_crs(ortho_crs, crs, params["ORTHO"].bounds):
                raise self.fail("ORTHO", f"is in {crs_label(params['ORTHO'].crs)}, not in the "
                                f"project's CRS ({crs_label(project.crs)}): reproject it first")
            if params["DEM"] is not None:  # horizontal parts, and height datums stated by both
                project_raster_crs(project.crs, params["DEM"].crs,
                                   bounds=params["DEM"].bounds)
        elif params["MEASURED"] is not None:
            raise self.fail("MEASURED", "needs ORTHO (the matched points are written there)")
        elif params["DEM"] is not None:  # it only casts the ortho chip: unused without ORTHO
            raise self.fail("DEM", f"'{params['DEM'].path}' needs ORTHO (the DEM casts the "
                            "orthophoto's chip into the photo; without ORTHO nothing is matched): "
                            "give ORTHO or leave DEM out")
        photos = [p for p in project.photos.values()
                  if p.image is not None and p.exterior is not None]
        if not photos:
            raise self.fail("PROJECT", "has no photo with both an image and an exterior "
                            "orientation")
        rows, seen, matched, flags = [], set(), [], {}
        for photo in feedback.iterate(photos):
            if not photo.image.exists():
                raise InputDataError(f"PROJECT: the image {photo.image} of photo {photo.id!r} "
                                     "does not exist")
            source = ImageSource.open(photo.image, f"photo {photo.id!r}")
            # predictions and chips are in the raster's pixels: they must be the camera's
            photo = fit_image_size(photo, source.width, source.height, photo.image)
            surface = None
            if ortho is not None and params["DEM"] is not None:
                surface = surface_for_photo(params["DEM"], photo)
            for p in predict(photo, source, ids, xyz, params["MARGIN"]):
                seen.add(p.point_id)
                chip = ""
                if params["CHIPS"] is not None:
                    path = params["CHIPS"] / f"{p.point_id}_{p.photo}.png"
                    write_chip(path, source, p, params["CHIP_SIZE"])
                    chip = path.name
                row = [p.point_id, p.photo, round(p.col_px, 3), round(p.row_px, 3),
                       "predicted", chip, *(round(float(v), 3) for v in p.xyz)]
                if ortho is not None:
                    m = match_point(photo, source, ortho, np.array([p.col_px, p.row_px]),
                                    float(p.xyz[2]), params["MATCH_SIZE"], params["SEARCH"],
                                    params["MIN_SCORE"], surface=surface)
                    row[2:5] = [round(m.col_px, 3), round(m.row_px, 3), m.status]
                    row += [_num(m.score), _num(m.runner_up), round(m.shift_px, 3),
                            round(p.col_px, 3), round(p.row_px, 3)]
                    if m.status == "matched":
                        matched.append([p.point_id, p.photo, row[2], row[3], 0.5])
                    else:
                        flags[m.status] = flags.get(m.status, 0) + 1
                rows.append(row)
        unseen = [i for i in ids if i not in seen]
        if not rows:
            raise InputDataError(f"CONTROL: none of the {len(ids)} points falls on a photo of "
                                 "PROJECT (check the CRS and the orientations)")
        if unseen:
            feedback.push_warning(f"{len(unseen)} control point(s) on no photo: "
                                  f"{', '.join(unseen[:10])}")
        columns = ["point_id", "photo", "col_px", "row_px", "status", "chip", "X", "Y", "Z"]
        if ortho is not None:
            columns += ["score", "runner_up", "shift_px", "predicted_col_px", "predicted_row_px"]
            if flags:
                feedback.push_warning(f"{sum(flags.values())} of {len(rows)} prediction(s) not "
                                      "matched on ORTHO (kept predicted): " + ", ".join(
                                          f"{n} {k}" for k, n in sorted(flags.items())))
        write_csv(params["OUTPUT"], columns, rows)
        if params["MEASURED"] is not None:
            write_csv(params["MEASURED"], ["point_id", "photo", "col_px", "row_px", "sigma_px"],
                      matched)
        stats = {"predictions": len(rows), "points": len(ids), "points_on_no_photo": unseen,
                 "photos": len(photos)}
        if ortho is not None:
            stats.update({"matched": len(matched), "not_matched": flags})
        return {"OUTPUT": params["OUTPUT"], "CHIPS": params["CHIPS"],
                "MEASURED": params["MEASURED"], "STATISTICS": stats}


def _num(value: float) -> float | None:
    return round(float(value), 4) if value == value else None
