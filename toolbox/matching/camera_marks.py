"""Fiducial marks of the usual aerial film cameras, drawn from their published geometry.

Each family is ``f(x, y) -> bool`` (mark pixels, coordinates in mm from the mark's centre, y
up), bright on dark (the search also tries the inverse), with a different shape for the corner
and the side marks where the camera has one. ``size`` and ``line`` (mm) scale the drawing;
:data:`DEFAULTS` holds the sizes where a source gives them.

Sources (what each one confirms, and what it does not):

- ``wild_rc8``: OrientAL's Wild RC8 detector (TU Wien, ``oriental/relOri/fiducials``): "bright
  disc with dark X on it", the X reaching 1.366 mm from the centre along x and y, lines
  0.06 mm wide, the mark's background 1.6 mm from the centre (its template's half width; the
  disc's exact diameter is not given: 3.2 mm is assumed). Four corner marks (RC5/RC8 style,
  spymicmac's "corner-only fiducials"); the same mark is drawn at side marks.
- ``wild_rc10``: spymicmac's documentation ("example fiducial marker patterns", Wild
  Heerbrugg, corner + mid-side) and its ``match_wild_rc``: "crosshair" marks, a cross inscribed
  in a ring, turned by 45 degrees in the corners (an x) and upright at the sides (a +), the
  cross running across the ring. No size is published (spymicmac's templates are in pixels,
  7 px ring and 3 px bars by default): ``size`` (ring outer diameter) and ``line`` (bar width)
  must be given; the ring is drawn ``2 x line`` wide, an assumption from those default pixel
  proportions.
- ``zeiss_rmk_top``: OrientAL's Zeiss RMK TOP detector, measured on 15.5 µm scans: a ring of
  1.55 mm centre-line diameter and 0.3 mm width, a central disc of 0.15 mm, four spokes
  0.15 mm wide from 0.3 mm off the centre out to the ring's centre-line radius plus its width;
  spokes on the axes (a +) at the side marks, on the diagonals (an x) at the corner marks.
  ``size`` = ring outer diameter (1.85 mm), ``line`` = ring width (0.3 mm); the disc and
  spokes are ``line / 2``.
- ``zeiss_rmk_a``: OrientAL's Zeiss RMK A detector: four side marks, bright discs "whose
  radius varies from camera to camera"; spymicmac ("Zeiss RMK cameras") measures the side mark
  at "the small dot near the tip" of a wedge. Drawn as the disc alone (``size`` = its
  diameter, to be given): the wedge's shape is not published. The later RMK corner crosses
  have no published size either: give a TEMPLATE cut from a scan for those.

Not covered: Wild RC20/RC30 and RMK corner marks (no public description of their shape or
size was found); a template image cut from one scan serves them.
"""

from __future__ import annotations

import numpy as np

#: family -> (size, line) in mm where a source gives them; None: the user must give it
DEFAULTS: dict[str, tuple[float | None, float | None]] = {
    "wild_rc8": (3.2, 0.06),
    "wild_rc10": (None, None),
    "zeiss_rmk_top": (1.85, 0.3),
    "zeiss_rmk_a": (None, 0.06),  # line unused: the mark is a disc
}


def mark_kind(x_mm: float, y_mm: float) -> str:
    """``corner`` when a calibrated mark lies near a diagonal of the frame, else ``side``."""
    ax, ay = abs(x_mm), abs(y_mm)
    return "corner" if min(ax, ay) >= 0.5 * max(ax, ay) else "side"


def _bar(u, v, half_length, width):
    return (np.abs(u) <= half_length) & (np.abs(v) <= width / 2.0)


def _plus(x, y, half_length, width, diagonal: bool):
    if diagonal:
        x, y = (x + y) / np.sqrt(2.0), (y - x) / np.sqrt(2.0)
    return _bar(x, y, half_length, width) | _bar(y, x, half_length, width)


def camera_mark(family: str, size: float, line: float, kind: str):
    """``f(x, y) -> bool`` of ``family``'s mark of ``kind`` (corner or side), mm."""
    half, corner = size / 2.0, kind == "corner"

    def wild_rc8(x, y):
        disc = np.hypot(x, y) <= half
        return disc & ~_plus(x, y, size, line, diagonal=True)

    def wild_rc10(x, y):
        r = np.hypot(x, y)
        ring = (r <= half) & (r >= half - 2 * line)
        return ring | (_plus(x, y, half, line, diagonal=corner) & (r <= half))

    def zeiss_rmk_top(x, y):
        r = np.hypot(x, y)
        ring = (r <= half) & (r >= half - line)
        disc = r <= line / 4.0
        reach = (size - line) / 2.0 + line
        spokes = _plus(x, y, reach, line / 2.0, diagonal=corner) & (r >= line)
        return ring | disc | spokes

    def zeiss_rmk_a(x, y):
        return np.hypot(x, y) <= half

    return {"wild_rc8": wild_rc8, "wild_rc10": wild_rc10, "zeiss_rmk_top": zeiss_rmk_top,
            "zeiss_rmk_a": zeiss_rmk_a}[family]
