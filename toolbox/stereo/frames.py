"""Digital frames described by an interior model (Orthority's ``pinhole``, ``brown`` or
``opencv``) as the metric frame camera the stereo steps work with.

A model camera of square pixels without its distortion is exactly a frame camera: principal
distance c = f_px x p mm, pixel size p (the spec's sensor size / image size, else a nominal
0.01 mm: only c / p matters), principal point ((cx - W/2)·p, (H/2 - cy)·p) in image coordinates
(x right, y up, origin at the image centre). That frame camera gives the geometry of the
normalised (epipolar) images, which are distortion-free; their pixels are then fetched through
the model camera itself, distortion included (``resample_image``'s ``pixel_photo``). Fisheye
models and non-square pixels are refused with one line.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from toolbox.errors import InputDataError

NOMINAL_PIXEL_MM = 0.01


def as_frame_photo(photo: Any) -> Any:
    """``photo`` itself when its camera is a frame camera; else the same photo with the frame
    camera of its model camera without the distortion."""
    from toolbox.cameras.intrinsics import Intrinsics
    from toolbox.photogrammetry.camera import Camera

    model = photo.camera
    if not isinstance(model, Intrinsics):
        return photo
    if model.kind == "fisheye":
        raise InputDataError(f"photo {photo.id!r}: camera {model.name!r} is a fisheye model: "
                             "the epipolar steps take frame cameras and pinhole, brown or "
                             "opencv models")
    (fx, fy), (cx, cy) = model.focal_px, model.principal_point_px
    if abs(fx - fy) > 1e-9 * fx:
        raise InputDataError(f"photo {photo.id!r}: camera {model.name!r} has non-square pixels "
                             f"(fx {fx:g}, fy {fy:g} px): the epipolar steps need square ones")
    w, h = model.image_size_px
    sensor = model.spec.get("sensor_size") if isinstance(model.spec, dict) else None
    pixel = float(sensor[0]) / w if sensor else NOMINAL_PIXEL_MM
    camera = Camera(model.name, fx * pixel, ((cx - w / 2.0) * pixel, (h / 2.0 - cy) * pixel),
                    image_size_px=(int(w), int(h)), pixel_size_mm=pixel,
                    frame_size_mm=(w * pixel, h * pixel))
    return replace(photo, camera=camera, interior=None)
