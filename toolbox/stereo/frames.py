"""Digital frames described by an interior model (Orthority's ``pinhole``, or ``brown`` /
``opencv`` without distortion) as the metric frame camera the stereo steps work with.

A distortion-free model camera of square pixels is exactly a frame camera: principal distance
c = f_px x p mm, pixel size p (the spec's sensor size / image size, else a nominal 0.01 mm:
only c / p matters), principal point ((cx - W/2)·p, (H/2 - cy)·p) in image coordinates (x
right, y up, origin at the image centre). Models with distortion are refused with one line.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from toolbox.errors import InputDataError

NOMINAL_PIXEL_MM = 0.01


def as_frame_photo(photo: Any) -> Any:
    """``photo`` itself when its camera is a frame camera; else the same photo with the frame
    camera equivalent to its distortion-free model camera."""
    from toolbox.cameras.intrinsics import Intrinsics
    from toolbox.photogrammetry.camera import Camera

    model = photo.camera
    if not isinstance(model, Intrinsics):
        return photo
    if model.kind == "fisheye" or any(abs(v) > 0 for v in model.coefficients.values()):
        terms = {k: v for k, v in model.coefficients.items() if v}
        raise InputDataError(f"photo {photo.id!r}: camera {model.name!r} is a {model.kind} "
                             f"model with distortion ({terms or 'fisheye'}): the epipolar "
                             "steps take frame cameras and distortion-free models only")
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
