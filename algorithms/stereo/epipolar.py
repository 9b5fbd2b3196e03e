"""stereo:epipolar - epipolar (normalised) resampling of a stereo pair from its orientations."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, Number, RasterLayer, String
from toolbox.parameters.outputs import Output, OutputFile, OutputRaster
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.photogrammetry import project_parameter


@register
class EpipolarPair(Algorithm):
    """Epipolar (normalised, "normal case") images of a stereo pair (S002 par. 3.7).

    Both photos of the pair LEFT-RIGHT of an orientation PROJECT are re-projected through their
    projection centres onto one image plane parallel to the base: the common rotation Rn has its
    x axis along the base (C_right - C_left), its z axis the mean of the photos' z axes; the
    normalised principal distance is the left camera's and the pixel the left image's (or
    PIXEL_SIZE_MM). Rows are then epipolar lines: a ground point has the same row in both
    images, and its disparity d = col_left - col_right gives its position
    (P = C_left + |B| / px · Rn (xn, yn, -c), px = d·pixel + x_min_left - x_min_right; the normal
    case Z = c·B / p). Radial distortion and the interior orientation are removed on the way
    (each output pixel's ray goes through the collinearity equations into the original image;
    cv2.remap by windows of 2048 pixels on the raster engine, bounded memory; local threads, or
    a Dask cluster with SCHEDULER).

    Outputs: the two images (GeoTIFF with an alpha band; their transform maps pixels to the
    normalised image coordinates in mm, no CRS) and TRANSFORM, a JSON with Rn, the normalised
    principal distance, the pixel, the centres, the base, each image's x_min and the common
    y_max, and the formulas above, so that a disparity maps back to object space.

    Refused: pairs whose footprints at TERRAIN_HEIGHT overlap by less than MIN_OVERLAP of the
    smaller one; with SIGMA_Z, pairs whose base is too short for it: sigma_Z = m_b (Z/B)
    sigma_p (S002 eq. [35]-[40], sigma_p = SIGMA_PARALLAX_UM, Z = mean flying height above
    TERRAIN_HEIGHT).
    """

    id = "stereo:epipolar"
    display_name = "Epipolar images of a stereo pair"
    group = "Stereo"
    short_help = ("Normalised (epipolar) images of a stereo pair from its orientations, "
                  "distortion removed, with the transform back to object space (JSON).")
    parameters = [
        project_parameter("orientation project (YAML) with the two photos oriented"),
        String("LEFT", "photo id of the left photo (the base runs from it to RIGHT)"),
        String("RIGHT", "photo id of the right photo"),
        RasterLayer("LEFT_IMAGE", "image of LEFT (default: the project's image path)",
                    optional=True, role="photo"),
        RasterLayer("RIGHT_IMAGE", "image of RIGHT (default: the project's image path)",
                    optional=True, role="photo"),
        Number("TERRAIN_HEIGHT", "mean terrain height (CRS height units) for the overlap and "
               "base/height checks"),
        Number("MIN_OVERLAP", "least overlap of the footprints at TERRAIN_HEIGHT, as a "
               "fraction of the smaller one", default=0.3, min_value=0, max_value=1),
        Number("SIGMA_Z", "requested height precision (m): refuse pairs whose base is too short "
               "for it", optional=True, min_value=0, min_exclusive=True),
        Number("SIGMA_PARALLAX_UM", "sigma of the x-parallax, micrometres (S000: 5)",
               default=5.0, min_value=0, min_exclusive=True),
        Number("PIXEL_SIZE_MM", "pixel of the normalised images, mm (default: the left image's)",
               optional=True, min_value=0, min_exclusive=True),
        Enum("RESAMPLING", "resampling of the photos", options=["nearest", "bilinear", "cubic",
             "lanczos"], default="bilinear"),
        scheduler_parameter("the windows"),
        OutputRaster("OUTPUT_LEFT", "normalised left image (GeoTIFF + alpha)"),
        OutputRaster("OUTPUT_RIGHT", "normalised right image (GeoTIFF + alpha)"),
        OutputFile("TRANSFORM", "the pair's normalised geometry (JSON)", extensions=[".json"]),
    ]
    outputs = [Output("STATISTICS", "sizes, base, overlap, precision", "dict")]

    def check(self, params: dict[str, Any]) -> None:
        if params["LEFT"] == params["RIGHT"]:
            raise self.fail("RIGHT", f"must differ from LEFT, got {params['RIGHT']!r} twice")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.photogrammetry.tables import load_project_parameter
        from toolbox.stereo.epipolar import (
            check_pair,
            epipolar_geometry,
            pair_report,
            photo_image,
            resample_image,
        )

        executor = executor_of(params)  # a bad address is refused before any work
        project = load_project_parameter(params["PROJECT"])
        from toolbox.stereo.frames import as_frame_photo

        originals = (project.photo(params["LEFT"]), project.photo(params["RIGHT"]))
        photos = tuple(as_frame_photo(photo) for photo in originals)  # distortion removed
        for photo in photos:
            photo.require_exterior()
        images = (photo_image(photos[0], params["LEFT_IMAGE"], "LEFT_IMAGE"),
                  photo_image(photos[1], params["RIGHT_IMAGE"], "RIGHT_IMAGE"))
        report = pair_report(*photos, params["TERRAIN_HEIGHT"], params["SIGMA_PARALLAX_UM"])
        check_pair(report, (photos[0].id, photos[1].id), params["MIN_OVERLAP"],
                   params["SIGMA_Z"])
        geometry = epipolar_geometry(*photos, pixel_mm=params["PIXEL_SIZE_MM"])
        feedback.push_info(f"normalised images {geometry.widths[0]} and {geometry.widths[1]} x "
                           f"{geometry.height} pixels of {geometry.pixel_mm * 1000:.2f} um")
        for side, name in enumerate(("OUTPUT_LEFT", "OUTPUT_RIGHT")):
            feedback.check_canceled()
            resample_image(geometry, photos[side], side, images[side], params[name],
                           params["RESAMPLING"], feedback.step(50 * side, 50 * side + 50),
                           pixel_photo=originals[side], executor=executor)
        geometry.write(params["TRANSFORM"])
        stats = {"left": photos[0].id, "right": photos[1].id,
                 "widths": list(geometry.widths), "height": geometry.height,
                 "pixel_mm": geometry.pixel_mm,
                 "principal_distance_mm": geometry.principal_distance_mm,
                 **report.as_dict()}
        return {"OUTPUT_LEFT": params["OUTPUT_LEFT"], "OUTPUT_RIGHT": params["OUTPUT_RIGHT"],
                "TRANSFORM": params["TRANSFORM"], "STATISTICS": stats}
