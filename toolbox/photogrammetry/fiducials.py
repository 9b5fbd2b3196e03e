"""Interior orientation of a photo: the pixel <-> image (fiducial mm) transform.

For scanned film the transform is fitted on the fiducial marks: their measured pixel positions
are mapped onto the calibrated mm coordinates by least squares, affine (6 parameters) or
homography (8), as the Siena reports do (domain brief section 2 and 16; fit by
:mod:`toolbox.transforms.plane`). Residuals are fitted minus calibrated (mm); the reports'
"Sigma globale" is the variance ``Σv²/(2n - 6)`` (mm²). A digital frame camera has no marks: its
transform follows from the pixel size and the image size (:meth:`InteriorOrientation.from_pixel_size`).

The pixel -> fiducial matrix ``P`` acts on homogeneous ``[col, row, 1]``:
``[x·w, y·w, w]ᵀ = P·[col, row, 1]ᵀ``, ``P[2, 2] = 1`` (``w = 1`` unless homography).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.transforms.plane import TRANSFORMS, Transform2D, apply_homography

#: transformation names accepted (lowercase) -> canonical; OMOGRAFICA is Z-Map's (Italian) name
TRANSFORMATION_NAMES = {
    "affine": "affine", "affinity": "affine", "affine6": "affine",
    "homography": "homography", "omografica": "homography", "projective": "homography",
    "similarity": "similarity", "conformal": "similarity", "helmert": "similarity",
}


def transformation_name(value: Any, where: str = "transformation") -> str:
    """Canonical transformation name (affine, homography, similarity) for ``value``."""
    key = str(value).strip().lower() if value is not None else ""
    if key not in TRANSFORMATION_NAMES:
        raise InputDataError(f"{where} must be affine, homography (omografica) or similarity, "
                             f"got {value!r}")
    return TRANSFORMATION_NAMES[key]


@dataclass(frozen=True, eq=False)
class InteriorOrientation:
    """Pixel <-> image (fiducial mm) transform of one photo, with its fit statistics.

    Attributes
    ----------
    pixel_to_fiducial : (3, 3) array
        ``P`` with ``P[2, 2] = 1``.
    transformation : str
        ``affine``, ``homography``, ``similarity`` or ``pixel_size`` (digital camera).
    marks : tuple of str
        Mark ids used in the fit (empty for ``pixel_size``).
    residuals_mm : (n, 2) array or None
        Fitted minus calibrated mark coordinates.
    sigma0_mm : float or None
        ``sqrt(Σv²/r)``; None when the redundancy r is 0.
    redundancy : int
    """

    pixel_to_fiducial: np.ndarray
    transformation: str
    marks: tuple[str, ...] = ()
    residuals_mm: np.ndarray | None = None
    sigma0_mm: float | None = None
    redundancy: int = 0
    fiducial_to_pixel: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        p = np.asarray(self.pixel_to_fiducial, dtype="float64")
        if p.shape != (3, 3) or not np.isfinite(p).all() or p[2, 2] == 0:
            raise InputDataError(f"a pixel -> fiducial matrix must be a finite 3 x 3 matrix with "
                                 f"[2, 2] != 0, got {p.tolist()}")
        if abs(np.linalg.det(p)) < 1e-300:
            raise InputDataError("the pixel -> fiducial matrix is singular")
        p = p / p[2, 2]
        inv = np.linalg.inv(p)
        object.__setattr__(self, "pixel_to_fiducial", p)
        object.__setattr__(self, "fiducial_to_pixel", inv / inv[2, 2])

    # -- construction ------------------------------------------------------------------------------
    @classmethod
    def fit(cls, calibrated_mm: Mapping[str, Any], measured_px: Mapping[str, Any],
            transformation: str = "affine", photo: str = "") -> InteriorOrientation:
        """Least-squares fit of measured mark pixels ``{id: (col, row)}`` onto the calibrated
        mark coordinates ``{id: (x, y)}`` (mm).

        Marks are matched by id; a measured mark absent from the calibration is an error.
        Raises :class:`InputDataError` (naming the photo) for too few or collinear marks.
        """
        kind = transformation_name(transformation)
        label = f"photo {photo!r}: " if photo else ""
        unknown = [m for m in measured_px if m not in calibrated_mm]
        if unknown:
            raise InputDataError(f"{label}fiducial mark(s) {', '.join(map(repr, unknown))} are not "
                                 f"in the camera's calibrated marks "
                                 f"({', '.join(map(repr, calibrated_mm)) or 'none'})")
        marks = tuple(measured_px)
        px = np.array([measured_px[m] for m in marks], dtype="float64").reshape(-1, 2)
        mm = np.array([calibrated_mm[m] for m in marks], dtype="float64").reshape(-1, 2)
        transform_cls = TRANSFORMS[kind]
        needed = transform_cls.min_points_for(transform_cls.n_params)
        if len(marks) < needed:
            raise InputDataError(f"{label}a {kind} interior orientation needs at least {needed} "
                                 f"fiducial marks, got {len(marks)}")
        # rows grow down, fiducial y up: a similarity is fitted on (col, -row) (it mirrors back
        # by itself for a mirrored scan; with two marks the unmirrored scan is assumed)
        flip = np.diag([1.0, -1.0, 1.0]) if kind == "similarity" else np.eye(3)
        try:
            fitted: Transform2D = transform_cls.estimate(px * np.diag(flip)[:2], mm)
        except InputDataError as exc:
            raise InputDataError(f"{label}fiducial marks: {exc}") from None
        fit = fitted.fit
        sigma = None if fit.redundancy == 0 or not np.isfinite(fit.sigma0) else float(fit.sigma0)
        return cls(fitted.params @ flip, kind, marks, fit.residuals, sigma, int(fit.redundancy))

    @classmethod
    def from_pixel_size(cls, width: int, height: int, pixel_size_mm: float,
                        principal_point_px: tuple[float, float] | None = None
                        ) -> InteriorOrientation:
        """Digital frame camera: ``x = (col - cx)·s``, ``y = -(row - cy)·s`` with ``(cx, cy)``
        the image centre ``(width/2, height/2)`` unless given (pixel-corner convention)."""
        if not pixel_size_mm > 0:
            raise InputDataError(f"pixel size must be > 0 mm, got {pixel_size_mm!r}")
        cx, cy = (width / 2.0, height / 2.0) if principal_point_px is None else principal_point_px
        s = float(pixel_size_mm)
        matrix = np.array([[s, 0.0, -cx * s], [0.0, -s, cy * s], [0.0, 0.0, 1.0]])
        return cls(matrix, "pixel_size")

    # -- use ---------------------------------------------------------------------------------------
    def pixel_to_image(self, colrow: np.ndarray) -> np.ndarray:
        """(…, 2) pixel ``(col, row)`` -> image ``(x, y)`` mm."""
        return apply_homography(self.pixel_to_fiducial, colrow)

    def image_to_pixel(self, xy_mm: np.ndarray) -> np.ndarray:
        """(…, 2) image ``(x, y)`` mm -> pixel ``(col, row)``."""
        return apply_homography(self.fiducial_to_pixel, xy_mm)

    @property
    def pixel_size_mm(self) -> float:
        """Mean pixel size: ``sqrt(|det|)`` of the linear part (at the image origin)."""
        return float(np.sqrt(abs(np.linalg.det(self.pixel_to_fiducial[:2, :2]))))

    @property
    def variance_mm2(self) -> float | None:
        """``Σv²/r`` (mm²), the Siena reports' "Sigma globale"; None when r = 0."""
        return None if self.sigma0_mm is None else self.sigma0_mm ** 2

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"transformation": self.transformation,
                               "pixel_to_fiducial": self.pixel_to_fiducial.tolist(),
                               "fiducial_to_pixel": self.fiducial_to_pixel.tolist(),
                               "pixel_size_mm": self.pixel_size_mm}
        if self.marks:
            out.update(marks=list(self.marks), redundancy=self.redundancy,
                       sigma0_mm=self.sigma0_mm, variance_mm2=self.variance_mm2,
                       residuals_mm={m: [float(v) for v in r]
                                     for m, r in zip(self.marks, self.residuals_mm, strict=True)})
        return out
