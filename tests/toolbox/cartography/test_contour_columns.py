"""The contour layer's columns built with numpy (WKB, length, closed) against shapely's
geometries of the same vertices: the same LineString Z, bit for bit, and the same lengths."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from toolbox.cartography.contour_io import canonical_order, contour_columns
from toolbox.cartography.contours import Contour, dem_contours
from toolbox.demo.samples.terrain import terrain


def test_wkb_and_fields_match_shapely():
    z, t = terrain()
    contours = dem_contours(z.astype("float64"), np.arange(290.0, 345.0, 2.0), t.c + 2,
                            t.f - 2, 4.0, -4.0, tile=64)
    contours.append(Contour(300.0, np.array([[0.0, 0.0], [3.0, 4.0]])))  # 2 vertices, length 5
    # the layer's order and ring starts (tests/toolbox/test_round18_contourorder.py)
    counts = np.array([len(c.xy) for c in contours])
    order, source = canonical_order(np.concatenate([c.xy for c in contours]), counts,
                                    np.array([c.level for c in contours]))
    xy, ends = np.concatenate([c.xy for c in contours])[source], np.cumsum(counts[order])
    contours = [Contour(contours[i].level, xy[e - counts[i]:e])
                for i, e in zip(order.tolist(), ends.tolist(), strict=True)]
    wkb, fields = contour_columns(contours, 2.0, 0.0, 5)
    ref = [shapely.linestrings(np.column_stack([c.xy, np.full(len(c.xy), c.level)]))
           for c in contours]
    ours = shapely.from_wkb(wkb)
    assert len(ours) == len(contours) > 100
    assert shapely.has_z(ours).all()
    assert all(shapely.equals_exact(a, b, tolerance=0.0) for a, b in zip(ours, ref, strict=True))
    np.testing.assert_allclose(fields["length"], shapely.length(ref), rtol=1e-12)
    assert fields["length"][np.flatnonzero(fields["elev"] == 300.0)[0]] == pytest.approx(5.0, abs=1e-12)
    closed = [bool(shapely.is_closed(g)) and len(c.xy) > 2 for g, c in zip(ref, contours,
                                                                            strict=True)]
    assert fields["closed"].tolist() == [int(c) for c in closed] and 0 < sum(closed) < len(ref)
    assert fields["elev"].tolist() == [c.level for c in contours]
    index = fields["index"].astype(bool)
    assert index.any() and (np.mod(fields["elev"][index], 10.0) == 0).all()


def test_no_contours_give_empty_columns():
    wkb, fields = contour_columns([], 5.0, 0.0, 5)
    assert len(wkb) == 0 and all(len(v) == 0 for v in fields.values())
