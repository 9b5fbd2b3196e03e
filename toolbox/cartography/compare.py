"""Line-by-line agreement of two contour sets (ours and a reference such as gdal_contour)."""

from __future__ import annotations

import numpy as np


def contour_agreement(ours, reference, tolerance: float, clip=None,
                      elev_field: str = "elev") -> dict:
    """Share of each set's length lying within ``tolerance`` of the other's lines of the same
    level (1.0 = the same lines). ``clip`` (xmin, ymin, xmax, ymax) restricts the reference,
    e.g. to the cell-centre extent when it runs on to the raster edge."""
    import shapely

    box = shapely.box(*clip) if clip is not None else None
    matched_ours = matched_ref = total_ours = total_ref = 0.0
    levels = sorted(set(ours[elev_field]) | set(reference[elev_field]))
    for level in levels:
        a = shapely.union_all(ours.geometry.values[np.asarray(ours[elev_field] == level)])
        b = shapely.union_all(reference.geometry.values[
            np.asarray(reference[elev_field] == level)])
        if box is not None:
            b = shapely.intersection(b, box)
        a, b = shapely.force_2d(a), shapely.force_2d(b)
        total_ours += a.length
        total_ref += b.length
        matched_ours += a.length - shapely.difference(a, b.buffer(tolerance)).length
        matched_ref += b.length - shapely.difference(b, a.buffer(tolerance)).length
    return {"levels": levels, "ours_length": total_ours, "reference_length": total_ref,
            "ours_matched": matched_ours / total_ours if total_ours else 1.0,
            "reference_matched": matched_ref / total_ref if total_ref else 1.0}
