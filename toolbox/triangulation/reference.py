"""Adjusted orientations against a reference solution, in the terms an adjustment log states.

An adjustment log such as Z-Map's (002 par. 3.5, block run l.2520-3218) states no precision of
its projection centres: it states the residuals of its control points, on the ground ("Residui
punti di controllo", ResX/Y/Z in metres, at most 0.153 / 0.160 / 0.346 m in the block run) and
in the images (back-projection "dx/dy(pix)" in scan pixels of 0.014 mm, at most 4.674 px =
65.4 µm). Two orientations of a block agree within those residuals when they image the ground
alike, which is what the residuals measure:

- back-projection: each ground point projected through both orientations of a photo; the
  difference (adjusted - reference) in image µm and in pixels;
- ground: each ground point seen by two photos or more is intersected, through the adjusted
  orientations, from its reference image positions (where the reference puts it in the
  photos); the difference from the point (adjusted - reference) in metres.

The projection centres are compared too, with the adjustment's own standard deviations: a centre
and its tilt are correlated (X0 with phi, Y0 with omega at these narrow bases), so centres can
differ by more than the ground does and the orientations still map the ground alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.errors import ParameterError
from toolbox.photogrammetry.forward_intersection import intersect_measured


def parse_tolerance(text: str | None, name: str = "REFERENCE_TOLERANCE"
                    ) -> tuple[float, float, float, float] | None:
    """``'x, y, z, image_um'`` (m, m, m, µm) -> a tuple of 4 positive numbers, or None."""
    if text is None or not str(text).strip():
        return None
    try:
        values = tuple(float(v) for v in str(text).replace(";", ",").split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(np.isfinite(v) and v > 0 for v in values):
        raise ParameterError(name, f"must be four positive numbers 'x, y, z, image_um' (ground "
                             f"m, image µm), got {text!r}")
    return values  # type: ignore[return-value]


def _inside(photo: Any, pixels: np.ndarray) -> np.ndarray:
    """Which pixels lie on the photo: its image size, or, for a film camera without one (a
    scan of any size), its frame outline (frame_size_mm, else the fiducials' box) in pixels."""
    size = photo.camera.image_size_px
    if size is None:
        import shapely

        outline = photo.require_pixel_transform().image_to_pixel(photo.frame_outline_mm())
        with np.errstate(invalid="ignore"):
            return shapely.contains_xy(shapely.Polygon(outline), pixels[:, 0], pixels[:, 1])
    width, height = size
    return ((pixels[:, 0] > 0) & (pixels[:, 0] < width) & (pixels[:, 1] > 0)
            & (pixels[:, 1] < height))


def compare(adjusted: dict[str, Any], reference: dict[str, Any], points: dict[str, np.ndarray],
            std: dict[str, np.ndarray] | None = None,
            tolerance: tuple[float, float, float, float] | None = None) -> dict[str, Any]:
    """Compare two orientations of the same photos (``{id: Photo}``, same cameras and interior
    orientations) on ground ``points`` (``{id: (X, Y, Z)}``).

    Returns ``{"photos": [...], "points": [...], "summary": {...}}``: per photo the centre and
    angle differences (adjusted - reference; with ``std``, ``{photo: (6,) standard deviations}``,
    the largest centre difference in standard deviations) and the largest back-projection
    difference; per point the ground difference; the summary holds the largest values, the
    ``tolerance`` (x, y, z m, image µm) and ``agrees`` (None without a tolerance) and ``line``,
    one sentence for a report.
    """
    ids = [p for p in adjusted if p in reference and reference[p].exterior is not None]
    names = list(points)
    xyz = np.array([points[n] for n in names], dtype="float64").reshape(-1, 3)
    photos, seen = [], {n: [] for n in names}
    worst_um = worst_px = 0.0
    for pid in ids:
        a, r = adjusted[pid], reference[pid]
        ref_px = r.ground_to_pixel(xyz, behind="nan")
        inside = _inside(r, ref_px)
        d_px = a.ground_to_pixel(xyz, behind="nan") - ref_px
        d_um = (a.ground_to_image(xyz, behind="nan") - r.ground_to_image(xyz, behind="nan")) * 1e3
        for k in np.flatnonzero(inside):
            seen[names[k]].append((pid, ref_px[k]))
        ea, er = a.exterior, r.exterior
        d_eo = np.array([*(ea.centre - er.centre), ea.omega - er.omega, ea.phi - er.phi,
                         ea.kappa - er.kappa])
        row = {"photo": pid, "dX0": d_eo[0], "dY0": d_eo[1], "dZ0": d_eo[2], "domega": d_eo[3],
               "dphi": d_eo[4], "dkappa": d_eo[5], "points": int(inside.sum()),
               "max_image_um": float(np.abs(d_um[inside]).max()) if inside.any() else None,
               "max_image_px": float(np.abs(d_px[inside]).max()) if inside.any() else None}
        if std is not None and pid in std:
            s = np.asarray(std[pid], dtype="float64")[:3]
            row["max_centre_in_std"] = float(np.max(np.abs(d_eo[:3]) / s))
        if inside.any():
            worst_um = max(worst_um, row["max_image_um"])
            worst_px = max(worst_px, row["max_image_px"])
        photos.append({k: (float(v) if isinstance(v, np.floating) else v) for k, v in row.items()})
    rows = []
    multi = [k for k, name in enumerate(names) if len(seen[names[k]]) >= 2]
    if multi:  # each point intersected through ours from where the reference images it
        rays = [(n, pid, px) for n, k in enumerate(multi) for pid, px in seen[names[k]]]
        got = intersect_measured([adjusted[pid] for _, pid, _ in rays],
                                 np.array([px for _, _, px in rays]),
                                 np.array([n for n, _, _ in rays]), len(multi)).xyz
        for n, k in enumerate(multi):
            d = got[n] - xyz[k]
            rows.append({"id": names[k], "photos": len(seen[names[k]]), "dX": float(d[0]),
                         "dY": float(d[1]), "dZ": float(d[2])})
    ground = np.array([[r["dX"], r["dY"], r["dZ"]] for r in rows]).reshape(-1, 3)
    worst = np.abs(ground).max(axis=0) if len(ground) else np.full(3, np.nan)
    centres = max((np.linalg.norm([p["dX0"], p["dY0"], p["dZ0"]]) for p in photos), default=0.0)
    summary = {"photos": len(photos), "points": len(rows),
               "max_ground_m": [float(v) for v in worst], "max_image_um": worst_um,
               "max_image_px": worst_px, "max_centre_m": float(centres),
               "tolerance": list(tolerance) if tolerance else None, "agrees": None}
    if tolerance is not None:
        summary["agrees"] = bool(len(rows) and (worst <= np.array(tolerance[:3])).all()
                                 and worst_um <= tolerance[3])
    verdict = {None: "", True: ": agrees within the tolerance",
               False: ": DIFFERS beyond the tolerance"}[summary["agrees"]]
    tol = (f" (tolerance {tolerance[0]:g} / {tolerance[1]:g} / {tolerance[2]:g} m, "
           f"{tolerance[3]:g} µm)" if tolerance else "")
    in_std = [p["max_centre_in_std"] for p in photos if "max_centre_in_std" in p]
    summary["line"] = (
        f"against the reference, {len(photos)} photos, {len(rows)} points: ground at most "
        f"{worst[0]:.3f} / {worst[1]:.3f} / {worst[2]:.3f} m (X / Y / Z), back-projection at "
        f"most {worst_um:.1f} µm ({worst_px:.3f} px){tol}; centres at most {centres:.2f} m"
        + (f" ({max(in_std):.1f} of their std)" if in_std else "") + verdict)
    return {"photos": photos, "points": rows, "summary": summary}
