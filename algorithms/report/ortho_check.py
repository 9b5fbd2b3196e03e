"""report:ortho_check - an orthophoto's planimetric accuracy measured on check points."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import File, Number, RasterLayer, String
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register
from toolbox.ui.photogrammetry import TABLE_EXTENSIONS, project_parameter


@register
class OrthoCheck(Algorithm):
    """Measure where each check point lies on the orthophoto ``ORTHO`` and compare with its
    surveyed position (S002 §2.6.6: RMS <= 0.3 to 0.5 mm x the scale denominator).

    ``CHECK_POINTS``: surveyed points (``id``, ``X``, ``Y``, ``Z``; with a ``role`` column only
    the ``check`` rows). ``MEASUREMENTS``: their image measurements (``point_id``, ``photo``,
    ``col_px``, ``row_px``, pixel centres at +0.5, or ``x_mm``, ``y_mm`` in the fiducial
    system, read through the photo's interior orientation), the operator's pointing of each
    target on the photos of ``PROJECT``. ``ORTHO`` without a CRS is taken to be in PROJECT's,
    with a warning, when its grid holds a check point (refused when it holds none), as in
    orientation:control.

    Method (an actual measurement on the orthophoto, not a prediction): around each point a
    reference chip is resampled from the photo onto a north-up ground grid at the orthophoto's
    cell size, centred by construction on the target the operator measured (the orientation
    only gives the chip its scale and rotation); the chip is found on the orthophoto by
    normalised cross-correlation with a sub-pixel peak within ``SEARCH`` m. The offset is where
    the orthophoto shows the target minus where it was surveyed. Chips come from ``PHOTO``, or
    per point from the measuring photo where it lies nearest the image centre. A match scoring
    under ``MIN_SCORE``, or at the edge of the search area, is reported and not counted. The
    chip takes the ground around a point on ``DEM`` (the orthophoto's: its relief, through the
    point's height), else on the plane of the point's height (relief around the point then
    biases the match); with ``DEM`` each point's Z is compared with it and points more than 2
    cells off are warned about: the orthophoto shows the DEM's ground, so their offsets include
    that height difference's relief displacement.

    ``OUTPUT``: one CSV row per point (offsets dx, dy and their length in m, score, status);
    ``STATISTICS``: counts, RMSE east, north and planimetric of the matched points (read by
    ``report:quality``'s orthophoto section).
    """

    id = "report:ortho_check"
    display_name = "Orthophoto accuracy on check points"
    group = "Reports"
    short_help = "Measure check points on an orthophoto by chip matching: offsets and RMSE."
    parameters = [
        RasterLayer("ORTHO", "orthophoto (or mosaic) to check"),
        project_parameter("orientation project the check points were measured in"),
        File("CHECK_POINTS", "surveyed check points: id, X, Y, Z (role=check rows if a role "
             "column)", extensions=TABLE_EXTENSIONS),
        File("MEASUREMENTS", "their image measurements: point_id, photo, col_px, row_px (or "
             "x_mm, y_mm)",
             extensions=TABLE_EXTENSIONS),
        String("PHOTO", "photo to take the chips from (default: per point, the most central "
               "measuring photo)", optional=True),
        Number("CHIP", "reference chip half size, m (0: 12 orthophoto cells)", default=0.0,
               min_value=0.0),
        Number("SEARCH", "largest offset looked for, m (0: 8 orthophoto cells)", default=0.0,
               min_value=0.0),
        Number("MIN_SCORE", "smallest correlation accepted (-1..1)", default=0.6,
               min_value=-1.0, max_value=1.0),
        RasterLayer("DEM", "the orthophoto's DEM: the chips follow it; points off it in "
                    "height are flagged",
                    optional=True, role="heights"),
        OutputFile("OUTPUT", "per-point offsets (CSV)", extensions=[".csv"]),
    ]
    outputs = [Output("STATISTICS", "points, matched, RMSE east/north/planimetric (m)", "json")]

    def check(self, params):
        from toolbox.io.raster import require_north_up

        # south-up or east to west: matched as they lie (through the inverse transform)
        require_north_up(params["ORTHO"].transform, "ORTHO", params["ORTHO"].path, flips_ok=True)

    def process(self, params, feedback: Feedback):
        from pathlib import Path

        from toolbox.cartography.quality_ortho import summary
        from toolbox.cartography.quality_ortho_job import OrthoCheckRequest, measure_checks, write_results

        req = OrthoCheckRequest(Path(params["ORTHO"].path), Path(params["PROJECT"]),
                                Path(params["CHECK_POINTS"]), Path(params["MEASUREMENTS"]),
                                params.get("PHOTO"), params["CHIP"], params["SEARCH"],
                                params["MIN_SCORE"],
                                Path(params["DEM"].path) if params.get("DEM") else None)
        results, settings = measure_checks(req, feedback)
        write_results(Path(params["OUTPUT"]), results)
        stats = summary(results) | settings | {"ortho": Path(params["ORTHO"].path).name,
                                               "method": "chip matching (NCC) of the photo "
                                                         "around the measured target"}
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
