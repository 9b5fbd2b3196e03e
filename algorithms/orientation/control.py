"""orientation:control - a control-point measurement template predicted from approximate
orientations, with image chips."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import File, Integer, Number, Output, OutputFile, OutputFolder, String
from toolbox.registry import register
from toolbox.ui.photogrammetry import TABLE_EXTENSIONS


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
    none on any photo is an error. Automatic matching of the chips against a reference
    orthophoto is not done.
    """

    id = "orientation:control"
    display_name = "Control-point measurement template"
    group = "Orientation"
    short_help = "Predict control points' image positions and write a template with chips."
    parameters = [
        File("PROJECT", "orientation project (YAML) with images and approximate orientations",
             extensions=[".yaml", ".yml"]),
        File("CONTROL", "ground control points: id, X, Y, Z", extensions=TABLE_EXTENSIONS),
        String("LAYER", "GeoPackage layer of CONTROL (default: the first)", optional=True),
        Number("MARGIN", "keep predictions at least this far inside the frame, px", default=0.0,
               min_value=0.0),
        Integer("CHIP_SIZE", "chip half size, px", default=48, min_value=8, max_value=2048),
        OutputFile("OUTPUT", "measurement template (CSV)", extensions=[".csv"]),
        OutputFolder("CHIPS", "folder of PNG chips", optional=True),
    ]
    outputs = [Output("STATISTICS", "predictions, points on no photo", "json")]

    def planned_files(self, params):
        """CHIPS: PNG files whose names come from the data (checked as a pattern)."""
        return {"CHIPS": ["*.png"]} if params.get("CHIPS") is not None else {}

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.errors import InputDataError
        from toolbox.matching.chips import predict, write_chip
        from toolbox.matching.images import ImageSource
        from toolbox.photogrammetry.tables import ground_points, load_project_parameter, write_csv

        project = load_project_parameter(params["PROJECT"])
        ids, xyz, _ = ground_points(params["CONTROL"], params["LAYER"])
        photos = [p for p in project.photos.values()
                  if p.image is not None and p.exterior is not None]
        if not photos:
            raise self.fail("PROJECT", "has no photo with both an image and an exterior "
                            "orientation")
        rows, seen = [], set()
        for photo in feedback.iterate(photos):
            if not photo.image.exists():
                raise InputDataError(f"PROJECT: the image {photo.image} of photo {photo.id!r} "
                                     "does not exist")
            source = ImageSource.open(photo.image, f"photo {photo.id!r}")
            for p in predict(photo, source, ids, xyz, params["MARGIN"]):
                seen.add(p.point_id)
                chip = ""
                if params["CHIPS"] is not None:
                    path = params["CHIPS"] / f"{p.point_id}_{p.photo}.png"
                    write_chip(path, source, p, params["CHIP_SIZE"])
                    chip = path.name
                rows.append([p.point_id, p.photo, round(p.col_px, 3), round(p.row_px, 3),
                             "predicted", chip, *(round(float(v), 3) for v in p.xyz)])
        unseen = [i for i in ids if i not in seen]
        if not rows:
            raise InputDataError(f"CONTROL: none of the {len(ids)} points falls on a photo of "
                                 "PROJECT (check the CRS and the orientations)")
        if unseen:
            feedback.push_warning(f"{len(unseen)} control point(s) on no photo: "
                                  f"{', '.join(unseen[:10])}")
        write_csv(params["OUTPUT"], ["point_id", "photo", "col_px", "row_px", "status", "chip",
                                     "X", "Y", "Z"], rows)
        stats = {"predictions": len(rows), "points": len(ids), "points_on_no_photo": unseen,
                 "photos": len(photos)}
        return {"OUTPUT": params["OUTPUT"], "CHIPS": params["CHIPS"], "STATISTICS": stats}
