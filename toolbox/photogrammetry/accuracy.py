"""Accuracy and design rules of the seeds, at the scale they mean.

- Orthophoto / rectified-photo accuracy (thesis S002 par. 2.6.6): the RMS over the whole product
  should not exceed ±0.3 mm at the map scale for small scales and ±0.5 mm for large scales. The
  thesis does not say where "large" starts; the toolbox takes 1:5,000 and larger (denominator
  <= 5,000) as large scales.
- Flight design (S002 par. 1.3.5, Table 3): forward overlap about 60 %, side overlap about 20 %,
  and the photo scale that suits each map scale (c = 150 mm).
"""

from __future__ import annotations

from toolbox.errors import ParameterError

LARGE_SCALE_LIMIT = 5000  # map scale denominators up to this are "large scales"
FORWARD_OVERLAP_PCT = 60.0
SIDE_OVERLAP_PCT = 20.0

# Table 3 (S002 l.324-331): map scale -> photo scale range (denominators)
PHOTO_SCALE_TABLE = {
    500: (3000, 4000), 1000: (5000, 6000), 2000: (7500, 9000), 5000: (12000, 18000),
    10000: (18000, 25000), 25000: (25000, 40000), 50000: (40000, 50000),
}


def check_map_scale(map_scale: float, name: str = "MAP_SCALE") -> float:
    if not map_scale > 0:
        raise ParameterError(name, f"must be a scale denominator > 0 (5000 for 1:5000), "
                             f"got {map_scale}")
    return float(map_scale)


def planimetric_tolerance_mm(map_scale: float, name: str = "MAP_SCALE") -> float:
    """Allowed RMS on the map sheet, mm: 0.5 for large scales, 0.3 for small ones."""
    return 0.5 if check_map_scale(map_scale, name) <= LARGE_SCALE_LIMIT else 0.3


def planimetric_tolerance_m(map_scale: float) -> float:
    """Allowed planimetric RMS on the ground, metres (tolerance on paper x scale)."""
    return planimetric_tolerance_mm(map_scale) * 1e-3 * map_scale


def judge_planimetry(rms_m: float, map_scale: float) -> dict:
    """The seeds' rule applied to a planimetric RMS (metres) at ``map_scale``."""
    tol = planimetric_tolerance_m(map_scale)
    return {"map_scale": map_scale, "rule": "S002 par. 2.6.6: RMS <= "
            f"{planimetric_tolerance_mm(map_scale):g} mm at the map scale",
            "tolerance_m": tol, "rms_m": rms_m, "rms_on_map_mm": rms_m / map_scale * 1e3,
            "passes": bool(rms_m <= tol)}


def photo_scale_range(map_scale: float) -> tuple[int, int] | None:
    """Table 3's photo-scale range for a map scale listed there, else None."""
    return PHOTO_SCALE_TABLE.get(int(round(map_scale)))


def judge_photo_scale(photo_scale: float, map_scale: float) -> dict:
    """Is the photo scale (denominator H/c) inside Table 3's range for the map scale? A photo
    scale larger (smaller denominator) than the range is accepted (more detail than needed)."""
    rng = photo_scale_range(map_scale)
    if rng is None:
        return {"map_scale": map_scale, "photo_scale": photo_scale, "table_range": None,
                "passes": None, "note": "map scale not in Table 3 (1:500 ... 1:50,000)"}
    return {"map_scale": map_scale, "photo_scale": photo_scale, "table_range": list(rng),
            "passes": bool(photo_scale <= rng[1])}
