"""Exterior orientation of one photo: projection centre (X0, Y0, Z0) and attitude (omega, phi,
kappa), with the angle unit and CRS made explicit.

Angles are stored in radians whatever unit they were read in (the unit read is kept in
``source_unit`` for reports); ``rotation`` is ``R(omega, phi, kappa)`` of
:mod:`toolbox.photogrammetry.rotation` (domain brief section 3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.photogrammetry.rotation import (
    angle_unit,
    angles_from_matrix,
    check_within_turn,
    from_radians,
    rotation_matrix,
    to_radians,
)


@dataclass(frozen=True)
class ExteriorOrientation:
    """Projection centre and attitude of one photo.

    Attributes
    ----------
    photo : str
        Photo id.
    x0, y0, z0 : float
        Projection centre in the ground CRS (metres for projected CRSs; Z0 a height).
    omega, phi, kappa : float
        Attitude angles in **radians** (convert with :meth:`from_angles` / :meth:`angles`).
    crs : pyproj.CRS or None
        CRS of the projection centre (and of everything ground-side of this photo).
    source_unit : str
        The unit the angles were given in (``rad``, ``deg`` or ``gon``); informative only.
    """

    photo: str
    x0: float
    y0: float
    z0: float
    omega: float
    phi: float
    kappa: float
    crs: Any = None
    source_unit: str = "rad"
    _rotation: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        values = (self.x0, self.y0, self.z0, self.omega, self.phi, self.kappa)
        if not all(isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v)
                   for v in values):
            raise InputDataError(f"exterior orientation of photo {self.photo!r} must have finite "
                                 f"X0, Y0, Z0, omega, phi, kappa; got {values}")
        object.__setattr__(self, "_rotation", rotation_matrix(self.omega, self.phi, self.kappa))
        self._rotation.setflags(write=False)

    # -- construction ------------------------------------------------------------------------------
    @classmethod
    def from_angles(cls, photo: str, x0: float, y0: float, z0: float, omega: float, phi: float,
                    kappa: float, unit: str = "rad", crs: Any = None,
                    name: str = "ANGLE_UNIT") -> ExteriorOrientation:
        """Build from angles in ``unit`` (rad, deg, gon; aliases accepted). An unknown unit raises
        :class:`~toolbox.errors.ParameterError` naming ``name``."""
        unit = angle_unit(unit, name)
        check_within_turn([omega, phi, kappa], unit, name,
                          "" if f"photo {photo}" in name else f"photo {photo}")
        o, p, k = (to_radians(float(a), unit) for a in (omega, phi, kappa))
        return cls(str(photo), float(x0), float(y0), float(z0), o, p, k, crs, unit)

    @classmethod
    def from_matrix(cls, photo: str, centre, rotation, crs: Any = None,
                    tolerance: float = 1e-6) -> ExteriorOrientation:
        """Build from a projection centre and a rotation matrix (checked for orthonormality)."""
        omega, phi, kappa = angles_from_matrix(rotation, tolerance)
        x0, y0, z0 = (float(v) for v in np.asarray(centre, dtype="float64").ravel()[:3])
        return cls(str(photo), x0, y0, z0, omega, phi, kappa, crs, "rad")

    def with_crs(self, crs: Any) -> ExteriorOrientation:
        return replace(self, crs=crs)

    # -- views -------------------------------------------------------------------------------------
    @property
    def centre(self) -> np.ndarray:
        """Projection centre ``[X0, Y0, Z0]``."""
        return np.array([self.x0, self.y0, self.z0])

    @property
    def rotation(self) -> np.ndarray:
        """``R(omega, phi, kappa)``, (3, 3), read-only."""
        return self._rotation

    def angles(self, unit: str = "rad") -> tuple[float, float, float]:
        """``(omega, phi, kappa)`` in ``unit``."""
        return tuple(from_radians(a, unit) for a in (self.omega, self.phi, self.kappa))

    def as_dict(self, unit: str = "rad") -> dict[str, Any]:
        """JSON-friendly: photo, X0, Y0, Z0, omega, phi, kappa (in ``unit``), angle_unit, crs."""
        from toolbox.io.crs import crs_label

        o, p, k = self.angles(unit)
        return {"photo": self.photo, "X0": self.x0, "Y0": self.y0, "Z0": self.z0, "omega": o,
                "phi": p, "kappa": k, "angle_unit": angle_unit(unit),
                "crs": None if self.crs is None else crs_label(self.crs)}
