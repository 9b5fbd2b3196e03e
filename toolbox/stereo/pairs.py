"""Which photos of an oriented block form stereo pairs: footprint overlap at a terrain height,
base/height ratio and the angle between the optical axes."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import ToolboxError
from toolbox.stereo.epipolar import PairReport, pair_report


@dataclass(frozen=True)
class PairRules:
    """Thresholds of a suitable pair."""

    terrain_height: float
    min_overlap: float = 0.3
    min_base_ratio: float = 0.1
    max_base_ratio: float = 2.0
    max_angle_deg: float = 30.0
    sigma_parallax_um: float = 5.0


def axis_angle_deg(left: Any, right: Any) -> float:
    """Angle between the two photos' optical axes, degrees."""
    a, b = left.exterior.rotation[:, 2], right.exterior.rotation[:, 2]
    return math.degrees(math.acos(float(np.clip(a @ b, -1.0, 1.0))))


def select_pairs(photos: list[Any], rules: PairRules
                 ) -> tuple[list[tuple[Any, Any, PairReport]], list[str]]:
    """Every suitable pair (in project order) and, for the others, why not (one line each)."""
    pairs, skipped = [], []
    for i, left in enumerate(photos):
        for right in photos[i + 1:]:
            name = f"{left.id}-{right.id}"
            angle = axis_angle_deg(left, right)
            if angle > rules.max_angle_deg:
                skipped.append(f"{name}: optical axes {angle:.1f} deg apart (MAX_ANGLE "
                               f"{rules.max_angle_deg:g})")
                continue
            try:
                report = pair_report(left, right, rules.terrain_height, rules.sigma_parallax_um)
            except ToolboxError as exc:
                skipped.append(f"{name}: {exc}")
                continue
            if report.overlap < rules.min_overlap:
                skipped.append(f"{name}: overlap {100 * report.overlap:.0f} % (MIN_OVERLAP "
                               f"{rules.min_overlap:g})")
            elif not rules.min_base_ratio <= report.base_ratio <= rules.max_base_ratio:
                skipped.append(f"{name}: base/height {report.base_ratio:.2f} (MIN_BASE_RATIO "
                               f"{rules.min_base_ratio:g}, MAX_BASE_RATIO "
                               f"{rules.max_base_ratio:g})")
            else:
                pairs.append((left, right, report))
    return pairs, skipped


def overlap_bounds(left: Any, right: Any, height: float) -> tuple[float, float, float, float]:
    """Bounds (xmin, ymin, xmax, ymax) of the pair's shared footprint at ``height``."""
    import shapely

    from toolbox.stereo.epipolar import OUTLINE_POINTS

    feet = []
    for photo in (left, right):
        ground = photo.image_to_ground(photo.frame_outline_mm(OUTLINE_POINTS), height)
        feet.append(shapely.make_valid(shapely.Polygon(ground[:, :2])))
    return tuple(float(v) for v in feet[0].intersection(feet[1]).bounds)
