"""The rectification accuracy rule: relief displacement at the image edge (thesis par. 2.6.2-2.6.4).

A point ``ΔZ`` above or below the reference plane is displaced radially from the principal point
by (thesis eq. [49], domain brief section 15)::

    Δρ = ΔZ · ρ / (c · m_b)

with ``ρ`` its radial distance from the principal point in the image, ``c`` the principal
distance and ``m_b`` the scale number at which the rectification is made (for a rectified photo
at the photo's own scale, ``m_b = H / c`` with ``H`` the flying height above the reference
plane). Table 4 of the thesis inverts it for a tolerated displacement of 1 mm at ``ρ = 100 mm``:
``ΔZ_max = 1 mm · c · m_b / ρ`` (1.5 m for c = 150 mm at 1:1000 ... 75 m for c = 300 mm at
1:25000). Units below: ``ΔZ`` and ``H`` in metres, ``ρ``, ``c`` and ``Δρ`` in millimetres.

Conventions of this module (ours, stated because the sources leave them open):

- the reference plane is the *mid* height of the terrain, so the largest departure is
  ``ΔZ = height range / 2``;
- the edge radius defaults to the half diagonal of a 230 x 230 mm aerial frame (162.6 mm);
  Table 4 itself uses 100 mm;
- the displacement on the ground is ``Δρ · m_b`` = ``ΔZ · ρ / c``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

FRAME_HALF_DIAGONAL_MM = 230.0 * math.sqrt(2.0) / 2.0  # 162.63 mm, standard 23 x 23 cm frame
TABLE4_RHO_MM = 100.0
TABLE4_TOLERANCE_MM = 1.0


def relief_displacement(delta_z: float, rho: float, principal_distance: float,
                        scale_number: float) -> float:
    """Radial displacement ``Δρ`` (mm, in the image at scale 1:m_b) of a point ``delta_z`` metres
    off the reference plane at ``rho`` mm from the principal point (eq. [49])."""
    return 1000.0 * delta_z * rho / (principal_distance * scale_number)


def max_height_departure(tolerance: float, principal_distance: float, scale_number: float,
                         rho: float = TABLE4_RHO_MM) -> float:
    """Largest departure from the reference plane (m) keeping ``Δρ <= tolerance`` (mm) at
    ``rho`` mm (Table 4: ``ΔZ_max = tolerance · c · m_b / ρ``)."""
    return tolerance * principal_distance * scale_number / rho / 1000.0


@dataclass
class ReliefCheck:
    """Result of the flatness rule for one photo (all lengths as named: _m metres, _mm mm)."""

    principal_distance_mm: float
    flying_height_m: float
    scale_number: float  # m_b = H / c
    height_range_m: float
    max_departure_m: float  # ΔZ = range / 2 (reference plane at mid height)
    edge_radius_mm: float
    displacement_image_mm: float  # Δρ at the edge
    displacement_ground_m: float  # Δρ · m_b
    tolerance_mm: float
    allowed_departure_m: float  # ΔZ_max for the tolerance at the edge
    flat_enough: bool
    pixel_size_m: float | None = None  # ground size of a pixel (to express Δρ in pixels)
    displacement_pixels: float | None = None  # Δρ on the ground / pixel_size_m
    rule_scale_number: float | None = None  # the scale the tolerance applies at (MAP_SCALE or m_b)
    displacement_rule_mm: float | None = None  # Δρ on the ground / rule scale, mm

    def as_dict(self) -> dict:
        return asdict(self)

    def message(self) -> str:
        """One line for the user; the warning text when the terrain is not flat enough."""
        core = (f"relief displacement at the image edge (rho = {self.edge_radius_mm:.1f} mm): "
                f"{self.displacement_image_mm:.2f} mm in the image, "
                f"{self.displacement_ground_m:.2f} m on the ground"
                + (f" ({self.displacement_pixels:.1f} pixels of {self.pixel_size_m:.3g} m)"
                   if self.displacement_pixels is not None else "")
                + f" for a height range of {self.height_range_m:g} m (±{self.max_departure_m:g} m "
                f"about the mid plane), c = {self.principal_distance_mm:g} mm, "
                f"H = {self.flying_height_m:g} m, photo 1:{self.scale_number:.0f}; "
                f"{self.displacement_rule_mm:.2f} mm at 1:{self.rule_scale_number:.0f}")
        if self.flat_enough:
            return core + f", within the {self.tolerance_mm:g} mm tolerance"
        return (f"the terrain is not flat enough for rectification: {core}, over the "
                f"{self.tolerance_mm:g} mm tolerance at 1:{self.rule_scale_number:.0f} "
                f"(thesis eq. [49] and Table 4 allow "
                f"±{self.allowed_departure_m:.2f} m here); use orthorectification with a DEM "
                "instead")


def relief_check(principal_distance: float, flying_height: float, height_range: float,
                 edge_radius: float = FRAME_HALF_DIAGONAL_MM,
                 tolerance: float = TABLE4_TOLERANCE_MM,
                 pixel_size: float | None = None, map_scale: float | None = None
                 ) -> ReliefCheck:
    """Apply eq. [49] at the image edge and compare with the tolerance (Table 4 rule).

    Parameters
    ----------
    principal_distance : float
        ``c``, mm (> 0).
    flying_height : float
        ``H``, metres above the terrain's reference (mid) plane (> 0); ``m_b = 1000·H / c``.
    height_range : float
        ``Z_max - Z_min`` of the terrain in the photo, metres (>= 0).
    edge_radius : float
        ``ρ`` at the image edge, mm (default: half diagonal of a 23 x 23 cm frame).
    tolerance : float
        Tolerated ``Δρ``, mm at the rectification scale (Table 4: 1 mm).
    pixel_size : float, optional
        Ground size of a pixel (of the photo or of the output), metres, to express the
        displacement in pixels.
    map_scale : float, optional
        Scale number of the product (e.g. 5000 for a 1:5000 map). The thesis' ``m_b`` is the scale
        at which the rectification is made and Table 4 is indexed by it: the tolerance then
        applies on the map, ``ΔZ_max = tolerance · c · m_map / ρ``. Without it the photo scale
        ``H / c`` is used (a rectified photo at its own scale).
    """
    for label, value in (("principal_distance", principal_distance),
                         ("flying_height", flying_height), ("edge_radius", edge_radius),
                         ("tolerance", tolerance)):
        if not value > 0:
            raise ValueError(f"{label} must be > 0, got {value}")
    if not height_range >= 0:
        raise ValueError(f"height_range must be >= 0, got {height_range}")
    scale = 1000.0 * flying_height / principal_distance
    departure = height_range / 2.0
    d_image = relief_displacement(departure, edge_radius, principal_distance, scale)
    d_ground = d_image * scale / 1000.0
    if map_scale is not None and not map_scale > 0:
        raise ValueError(f"map_scale must be > 0, got {map_scale}")
    rule_scale = scale if map_scale is None else float(map_scale)
    allowed = max_height_departure(tolerance, principal_distance, rule_scale, edge_radius)
    return ReliefCheck(
        principal_distance, flying_height, scale, height_range, departure, edge_radius, d_image,
        d_ground, tolerance, allowed, bool(departure <= allowed), pixel_size,
        None if pixel_size is None else d_ground / pixel_size, rule_scale,
        1000.0 * d_ground / rule_scale)
