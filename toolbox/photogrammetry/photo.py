"""One oriented photo: camera + interior orientation + exterior orientation, ground <-> pixel.

The chain, ground to pixel (the indirect method of orthorectification, brief section 15)::

    (X, Y, Z) --collinearity--> ideal camera (x̄, ȳ) --+distortion, +PP--> image mm (x, y)
              --fiducial -> pixel (interior orientation)--> pixel (col, row)

and back, pixel to ground, on a height or on a DEM (monoplotting). Every step is one fused,
compiled pass (:mod:`toolbox.photogrammetry.collinearity`).

A photo whose camera is an interior *model* (:class:`toolbox.cameras.Intrinsics`: pinhole,
Brown, OpenCV, fisheye; a project camera with ``model:``) has no fiducial system: its *image*
coordinates are the ideal normalised ones (x right, y up, principal distance 1, principal point
at 0), so the ground <-> image methods run the same collinearity kernels with ``c = 1`` and no
distortion, and the pixel methods go through the model (:meth:`Photo.sensor`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.cameras import FilmFrame, FrameCamera, Intrinsics
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
    camera : Camera or Intrinsics
        The film (or metric digital) camera, or an interior model (see the module docstring).
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
    camera: Camera | Intrinsics
    exterior: ExteriorOrientation | None = None
    interior: InteriorOrientation | None = None
    image: Path | None = None
    strip: str | None = None

    # -- parts ---------------------------------------------------------------------------------
    @property
    def crs(self) -> Any:
        return None if self.exterior is None else self.exterior.crs

    @property
    def is_model(self) -> bool:
        """True when the camera is an interior model rather than the film camera."""
        return isinstance(self.camera, Intrinsics)

    def sensor(self) -> FrameCamera | FilmFrame:
        """The posed camera (:class:`toolbox.cameras.CameraModel`: project, unproject...)."""
        eo = self.require_exterior()
        return FrameCamera(self.camera, eo) if self.is_model else FilmFrame(self)

    def require_exterior(self) -> ExteriorOrientation:
        if self.exterior is None:
            raise InputDataError(f"photo {self.id!r} has no exterior orientation")
        return self.exterior

    @property
    def pixel_transform(self) -> InteriorOrientation | None:
        """The interior orientation, or one from the camera's pixel and image size, or None."""
        if self.interior is not None or self.is_model:
            return self.interior
        cam = self.camera
        if cam.pixel_size_mm is not None and cam.image_size_px is not None:
            return InteriorOrientation.from_pixel_size(*cam.image_size_px, cam.pixel_size_mm)
        return None

    def require_pixel_transform(self) -> InteriorOrientation:
        if self.is_model:
            raise InputDataError(f"photo {self.id!r}: its camera {self.camera.name!r} is a "
                                 f"{self.camera.kind} model without a fiducial system; this "
                                 "step handles film cameras only")
        transform = self.pixel_transform
        if transform is None:
            raise InputDataError(f"photo {self.id!r} has no interior orientation (fiducial fit) and "
                                 f"its camera {self.camera.name!r} gives no pixel and image size: "
                                 "pixel coordinates cannot be converted to image mm")
        return transform

    def _args(self) -> dict[str, Any]:
        eo = self.require_exterior()
        cam = self.camera
        if self.is_model:  # ideal normalised image coordinates
            return {"centre": eo.centre, "rotation": eo.rotation, "principal_distance": 1.0,
                    "principal_point": (0.0, 0.0), "distortion": None}
        return {"centre": eo.centre, "rotation": eo.rotation, "principal_distance": cam.c,
                "principal_point": cam.principal_point_mm, "distortion": cam.distortion}

    # -- ground -> image ---------------------------------------------------------------------------
    def ground_to_image(self, points, behind: str = "raise") -> np.ndarray:
        """Ground (…, 3) -> measured image coordinates (…, 2), mm in the fiducial system."""
        return collinearity.ground_to_image(points, behind=behind, **self._args())

    def ground_to_pixel(self, points, behind: str = "raise", out: np.ndarray | None = None
                        ) -> np.ndarray:
        """Ground (…, 3) -> pixel ``(col, row)`` (…, 2)."""
        if self.is_model:
            shape = np.shape(points[0]) if isinstance(points, tuple) else np.shape(points)[:-1]
            pixels = self.sensor().project(points)
            if behind == "raise" and np.isnan(pixels[:, 0]).any():
                raise InputDataError(f"photo {self.id!r}: {int(np.isnan(pixels[:, 0]).sum())} "
                                     "ground point(s) have no image (behind the camera or "
                                     "outside the model's field)")
            if out is not None:
                out[...] = pixels
            return pixels.reshape(shape + (2,))
        f2p = self.require_pixel_transform().fiducial_to_pixel
        return collinearity.ground_to_image(points, fiducial_to_pixel=f2p, behind=behind, out=out,
                                            **self._args())

    # -- image -> ground ---------------------------------------------------------------------------
    def image_to_ground(self, points, z, invalid: str = "raise") -> np.ndarray:
        """Image mm (…, 2) -> ground (…, 3) on the height(s) ``z``."""
        return collinearity.image_to_ground(points, z, invalid=invalid, **self._args())

    def pixel_to_ground(self, points, z, invalid: str = "raise") -> np.ndarray:
        """Pixels (…, 2) -> ground (…, 3) on the height(s) ``z``."""
        if self.is_model:
            return self.image_to_ground(self._normalised(points), z, invalid=invalid)
        p2f = self.require_pixel_transform().pixel_to_fiducial
        return collinearity.image_to_ground(points, z, pixel_to_fiducial=p2f, invalid=invalid,
                                            **self._args())

    def monoplot_image(self, points, surface, **options) -> collinearity.MonoplotResult:
        """Image mm (…, 2) -> ground on a DEM; see :func:`collinearity.monoplot`."""
        return collinearity.monoplot(points, surface, **self._args(), **options)

    def monoplot_pixels(self, points, surface, **options) -> collinearity.MonoplotResult:
        """Pixels (…, 2) -> ground on a DEM; see :func:`collinearity.monoplot`."""
        if self.is_model:
            return self.monoplot_image(self._normalised(points), surface, **options)
        p2f = self.require_pixel_transform().pixel_to_fiducial
        return collinearity.monoplot(points, surface, pixel_to_fiducial=p2f, **self._args(),
                                     **options)

    def _normalised(self, points) -> np.ndarray:
        """A model camera's pixels (…, 2) -> its ideal normalised image coordinates (…, 2)."""
        px = np.stack(points, axis=-1) if isinstance(points, tuple) else np.asarray(points, float)
        return self.camera.pixel_to_normalised(px.reshape(-1, 2)).reshape(px.shape)

    # -- frame -----------------------------------------------------------------------------------
    def frame_outline_mm(self, points_per_side: int = 1) -> np.ndarray:
        """Outline of the imaged area in image mm, counter-clockwise from the top-left corner.

        From the camera's frame size when known; else the image's pixel corners through the
        pixel transform; else the bounding box of the fiducial marks. For a model camera, the
        image's pixel corners in ideal normalised coordinates.
        """
        if self.is_model:
            w, h = self.camera.image_size_px
            corners_px = np.array([[0.0, 0.0], [0.0, h], [w, h], [w, 0.0]])
            outline = self._normalised(outline_points(corners_px, points_per_side))
            if np.isnan(outline).any():
                raise InputDataError(f"photo {self.id!r}: the edge of its image looks 90 "
                                     "degrees or more off the optical axis (or past the lens "
                                     "model's field): it has no footprint on the ground")
            return outline
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
