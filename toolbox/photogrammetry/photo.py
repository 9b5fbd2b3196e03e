"""One oriented photo: camera + interior orientation + exterior orientation, ground <-> pixel.

The chain, ground to pixel (the indirect method of orthorectification, brief section 15)::

    (X, Y, Z) --collinearity--> ideal camera (x̄, ȳ) --+distortion, +PP--> image mm (x, y)
              --fiducial -> pixel (interior orientation)--> pixel (col, row)

and back, pixel to ground, on a height or on a DEM (monoplotting). Every step is one fused,
compiled pass (:mod:`toolbox.photogrammetry.collinearity`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.photogrammetry import collinearity
from toolbox.photogrammetry.camera import Camera, outline_points
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.fiducials import InteriorOrientation


@dataclass(frozen=True, eq=False)
class Photo:
    """An oriented photo.

    Attributes
    ----------
    id : str
    camera : Camera
    exterior : ExteriorOrientation or None
        None until an orientation is attached; ground-side methods then raise.
    interior : InteriorOrientation or None
        Pixel <-> image mm; when None, one is derived from the camera's pixel and image size
        (digital camera) if both are known.
    image : Path or None
        The image file (need not exist for geometry-only work).
    strip : str or None
        Flight strip label; consecutive photos of a strip form stereo pairs.
    """

    id: str
    camera: Camera
    exterior: ExteriorOrientation | None = None
    interior: InteriorOrientation | None = None
    image: Path | None = None
    strip: str | None = None

    # -- parts ---------------------------------------------------------------------------------
    @property
    def crs(self) -> Any:
        return None if self.exterior is None else self.exterior.crs

    def require_exterior(self) -> ExteriorOrientation:
        if self.exterior is None:
            raise InputDataError(f"photo {self.id!r} has no exterior orientation")
        return self.exterior

    @property
    def pixel_transform(self) -> InteriorOrientation | None:
        """The interior orientation, or one from the camera's pixel and image size, or None."""
        if self.interior is not None:
            return self.interior
        cam = self.camera
        if cam.pixel_size_mm is not None and cam.image_size_px is not None:
            return InteriorOrientation.from_pixel_size(*cam.image_size_px, cam.pixel_size_mm)
        return None

    def require_pixel_transform(self) -> InteriorOrientation:
        transform = self.pixel_transform
        if transform is None:
            raise InputDataError(f"photo {self.id!r} has no interior orientation (fiducial fit) and "
                                 f"its camera {self.camera.name!r} gives no pixel and image size: "
                                 "pixel coordinates cannot be converted to image mm")
        return transform

    def _args(self) -> dict[str, Any]:
        eo = self.require_exterior()
        cam = self.camera
        return {"centre": eo.centre, "rotation": eo.rotation, "principal_distance": cam.c,
                "principal_point": cam.principal_point_mm, "distortion": cam.distortion}

    # -- ground -> image ---------------------------------------------------------------------------
    def ground_to_image(self, points, behind: str = "raise") -> np.ndarray:
        """Ground (…, 3) -> measured image coordinates (…, 2), mm in the fiducial system."""
        return collinearity.ground_to_image(points, behind=behind, **self._args())

    def ground_to_pixel(self, points, behind: str = "raise", out: np.ndarray | None = None
                        ) -> np.ndarray:
        """Ground (…, 3) -> pixel ``(col, row)`` (…, 2)."""
        f2p = self.require_pixel_transform().fiducial_to_pixel
        return collinearity.ground_to_image(points, fiducial_to_pixel=f2p, behind=behind, out=out,
                                            **self._args())

    # -- image -> ground ---------------------------------------------------------------------------
    def image_to_ground(self, points, z, invalid: str = "raise") -> np.ndarray:
        """Image mm (…, 2) -> ground (…, 3) on the height(s) ``z``."""
        return collinearity.image_to_ground(points, z, invalid=invalid, **self._args())

    def pixel_to_ground(self, points, z, invalid: str = "raise") -> np.ndarray:
        """Pixels (…, 2) -> ground (…, 3) on the height(s) ``z``."""
        p2f = self.require_pixel_transform().pixel_to_fiducial
        return collinearity.image_to_ground(points, z, pixel_to_fiducial=p2f, invalid=invalid,
                                            **self._args())

    def monoplot_image(self, points, surface, **options) -> collinearity.MonoplotResult:
        """Image mm (…, 2) -> ground on a DEM; see :func:`collinearity.monoplot`."""
        return collinearity.monoplot(points, surface, **self._args(), **options)

    def monoplot_pixels(self, points, surface, **options) -> collinearity.MonoplotResult:
        """Pixels (…, 2) -> ground on a DEM; see :func:`collinearity.monoplot`."""
        p2f = self.require_pixel_transform().pixel_to_fiducial
        return collinearity.monoplot(points, surface, pixel_to_fiducial=p2f, **self._args(),
                                     **options)

    # -- frame -----------------------------------------------------------------------------------
    def frame_outline_mm(self, points_per_side: int = 1) -> np.ndarray:
        """Outline of the imaged area in image mm, counter-clockwise from the top-left corner.

        From the camera's frame size when known; else the image's pixel corners through the
        pixel transform; else the bounding box of the fiducial marks.
        """
        outline = self.camera.frame_outline_mm(points_per_side)
        if outline is not None:
            return outline
        transform = self.pixel_transform
        size = self.camera.image_size_px
        if transform is not None and size is not None:
            w, h = size
            corners_px = np.array([[0.0, 0.0], [0.0, h], [w, h], [w, 0.0]])
            return transform.pixel_to_image(outline_points(corners_px, points_per_side))
        marks = np.array(list(self.camera.fiducials_mm.values()), dtype="float64").reshape(-1, 2)
        if len(marks) >= 2 and np.ptp(marks[:, 0]) > 0 and np.ptp(marks[:, 1]) > 0:
            (x0, y0), (x1, y1) = marks.min(axis=0), marks.max(axis=0)
            return outline_points(np.array([[x0, y1], [x0, y0], [x1, y0], [x1, y1]]),
                                  points_per_side)
        raise InputDataError(f"photo {self.id!r}: the image format is unknown (give the camera "
                             f"{self.camera.name!r} a frame_size_mm, or image_size_px with an "
                             "interior orientation or pixel size)")
