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

from dataclasses import dataclass, replace
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


#: how far (fraction of the raster's longer side) a fiducial mark may lie outside the raster
FIDUCIAL_MARGIN = 0.05


def size_hint(actual: tuple[int, int], declared: tuple[int, int]) -> str:
    """What a raster of size ``actual`` is likely to be for a camera of size ``declared``: turned
    90 degrees, a scaled copy (a preview), a crop; '' when nothing fits."""
    (w, h), (cw, ch) = actual, declared
    if (w, h) == (ch, cw):
        return " (the raster is turned 90 degrees: give it in the camera's orientation)"
    if abs(w * ch - h * cw) <= max(cw, ch) and w != cw:  # same shape, other size
        return (f" (a copy scaled by {w / cw:.4g}, e.g. a preview: give the full-size photo the "
                "camera was calibrated on)")
    if w <= cw and h <= ch:
        return " (a crop: give the whole photo)"
    return ""


def fit_image_size(photo: Photo, width: int, height: int, image: Any) -> Photo:
    """The photo checked against the raster ``image`` (``width`` x ``height`` px) it is read from.

    A camera that states its size (every camera model; a film camera's ``image_size_px``) must
    have the raster's: another size (a preview, a crop, a photo turned 90 degrees) is an
    InputDataError naming both sizes, as its pixels would be read in another pixel frame. A film
    camera without ``image_size_px`` takes the raster's size (the photo returned has it), after
    a check that its fiducial marks, through the interior orientation, lie on the raster (a
    fiducial fit measured on another scan is refused)."""
    size = getattr(photo.camera, "image_size_px", None)
    actual = (int(width), int(height))
    if size is not None:
        if tuple(size) != actual:
            raise InputDataError(
                f"photo {photo.id!r}: the raster '{image}' is {actual[0]} x {actual[1]} px but the "
                f"camera {photo.camera.name!r} says {size[0]} x {size[1]}"
                f"{size_hint(actual, tuple(size))}: wrong image or camera")
        return photo
    if photo.is_model:  # pragma: no cover - models always have im_size
        return photo
    transform = photo.interior
    marks = photo.camera.fiducials_mm
    if transform is not None and marks:
        ids = list(marks)
        xy = np.array([marks[k] for k in ids], dtype="float64").reshape(-1, 2)
        px = np.column_stack([xy, np.ones(len(xy))]) @ transform.fiducial_to_pixel.T
        px = px[:, :2] / px[:, 2:]
        margin = FIDUCIAL_MARGIN * max(actual)
        out = ~((px[:, 0] >= -margin) & (px[:, 0] <= actual[0] + margin)
                & (px[:, 1] >= -margin) & (px[:, 1] <= actual[1] + margin))
        if out.any():
            k = int(np.flatnonzero(out)[0])
            raise InputDataError(
                f"photo {photo.id!r}: its interior orientation puts fiducial {ids[k]!r} at "
                f"({px[k, 0]:.1f}, {px[k, 1]:.1f}) px, off the raster '{image}' ({actual[0]} x "
                f"{actual[1]} px): the fiducials were measured on another scan (another size, "
                "a crop or turned); measure them on this one, or give the camera image_size_px")
    return replace(photo, camera=replace(photo.camera, image_size_px=actual))


def off_image(photos: Any, photo_ids: Any, xy: Any) -> np.ndarray:
    """Which pixel measurements (``xy`` (M, 2), ``(col, row)``) lie off their photo's image, more
    than half a pixel past its edge (``photos``: ``{id: Photo}``; photos not in it, or whose
    camera states no image size, are never off)."""
    xy = np.asarray(xy, dtype="float64").reshape(-1, 2)
    size = np.full((len(xy), 2), np.inf)
    for k, pid in enumerate(photo_ids):
        photo = photos.get(pid) if hasattr(photos, "get") else None
        wh = None if photo is None else getattr(photo.camera, "image_size_px", None)
        if wh is not None:
            size[k] = wh
    with np.errstate(invalid="ignore"):
        return ~((xy >= -0.5) & (xy <= size + 0.5)).all(axis=1)


def check_measured_pixels(photos: Any, point_ids: Any, photo_ids: Any, xy: Any,
                          name: str = "INPUT") -> None:
    """Pixel measurements must lie on their photo's image (:func:`off_image`): a point off the
    image was measured on another raster (a scaled, cropped or turned copy, or another photo's)
    and its ray would be used in silence. InputDataError naming ``name``, the point, its pixel
    and the camera's size."""
    off = np.flatnonzero(off_image(photos, photo_ids, xy))
    if len(off):
        k = int(off[0])
        pid, (col, row) = photo_ids[k], np.asarray(xy, dtype="float64").reshape(-1, 2)[k]
        photo = photos[pid]
        w, h = photo.camera.image_size_px
        turned = 0 <= col <= h and 0 <= row <= w
        raise InputDataError(
            f"{name}: point {point_ids[k]!r} of photo {pid!r} is measured at ({col:g}, {row:g}) "
            f"px, off the {w} x {h} px image of camera {photo.camera.name!r}"
            + (f" ({len(off)} points in all)" if len(off) > 1 else "") + ": it was measured on "
            "another raster (" + ("turned 90 degrees? " if turned else "")
            + "a scaled or cropped copy, or another photo's)")
