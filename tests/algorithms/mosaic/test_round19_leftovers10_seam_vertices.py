"""mosaic:seamlines METHOD=least_cost: the cut polygons held segments of rounding length where a
path met the overlap's edge (2.8e-14 m near the origin, 4.7e-10 m at Siena's coordinates), so one
block gave polygons of 10 / 13 / 9 vertices near the origin and 9 / 15 / 11 translated to
(1,688,000, 4,799,500). Vertices closer than 1e-6 of a seam cell are now one vertex, in all the
polygons at once: the same shapes with the same vertex counts at both places, still an exact
partition (the union's area is the sum of the areas, no two polygons overlap)."""

from __future__ import annotations

import numpy as np
import pyogrio
import pytest
import shapely

import toolbox
import toolbox.demo.samples.mosaic as samples

LOCAL = "+proj=tmerc +lat_0=0 +lon_0=9 +k=0.9996 +x_0=0 +y_0=0 +ellps=intl +units=m"
SPECS = [{"name": f"o{k}", "bounds": (200 * k, 0, 200 * k + 300, 260),
          "nadir": (200 * k + 150, 130)} for k in range(3)]


def _cut_polygons(folder, origin, monkeypatch):
    monkeypatch.setattr(samples, "ORIGIN", origin)
    monkeypatch.setattr(samples, "CRS", LOCAL)
    orthos, _ = samples.make_block(folder, SPECS)
    out = toolbox.run("mosaic:seamlines", {"INPUT": [str(o.path) for o in orthos],
                                           "METHOD": "least_cost",
                                           "OUTPUT": str(folder / "seams.gpkg")})
    frame = pyogrio.read_dataframe(out["OUTPUT"], layer="cut_polygons")
    return [shapely.affinity.translate(g, -origin[0], -origin[1]) for g in frame.geometry]


def _shortest_segment(geom):
    parts = shapely.get_parts(geom)
    rings = [np.asarray(r.coords) for p in parts for r in (p.exterior, *p.interiors)]
    return min(np.hypot(*np.diff(r, axis=0).T).min() for r in rings)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_cut_polygons_have_the_same_vertices_wherever_the_block_lies(tmp_path, monkeypatch):
    here = _cut_polygons(tmp_path / "origin", (0.0, 0.0), monkeypatch)
    there = _cut_polygons(tmp_path / "siena", (1_688_000.0, 4_799_500.0), monkeypatch)
    cell = 1.0  # the orthos' (the seam cells')
    assert [shapely.get_num_coordinates(g) for g in here] == \
        [shapely.get_num_coordinates(g) for g in there]
    for a, b in zip(here, there, strict=True):
        assert _shortest_segment(a) > 1e-6 * cell and _shortest_segment(b) > 1e-6 * cell
        assert shapely.hausdorff_distance(a, b) < 1e-6 * cell
    for cells in (here, there):  # an exact partition of the three orthos' union
        assert all(shapely.is_valid(cells))
        union = shapely.union_all(cells)
        assert union.area == pytest.approx(sum(g.area for g in cells), abs=1e-9)
        boxes = shapely.union_all([shapely.box(*s["bounds"]) for s in SPECS])
        assert union.symmetric_difference(boxes).area < 1e-6
        assert max(cells[i].intersection(cells[j]).area
                   for i in range(3) for j in range(i + 1, 3)) == 0.0
