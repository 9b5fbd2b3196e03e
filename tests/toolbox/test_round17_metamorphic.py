"""Round 17, metamorphic relations: results that must not change when the input is only
reordered. The stereo pairs of a strip listed out of flight order (orientation:precision,
orientation:footprints)."""

from __future__ import annotations

import geopandas as gpd
import pytest

import toolbox

X0, Y0 = 1688000.0, 4799000.0
BASE = 552.0  # c = 150 mm, 900 m above Z = 100: side 1380 m, forward overlap 60 %


def strip_project(path, order, strip=True):
    """Two strips of four nadir photos (a0..a3, b0..b3 every BASE m, strips 1104 m apart),
    listed in ``order`` (indexes into a0..a3, b0..b3)."""
    photos = [(f"a{i}", "1", X0 + BASE * i, Y0) for i in range(4)] + \
             [(f"b{i}", "2", X0 + BASE * i, Y0 + 1104.0) for i in range(4)]
    lines = ["version: 1", "crs: EPSG:3003", "angle_unit: rad", "cameras:",
             "  - {name: cam, principal_distance_mm: 150.0, frame_size_mm: [230.0, 230.0],",
             "     image_size_px: [11500, 11500], pixel_size_mm: 0.02}", "photos:"]
    for pid, name, x, y in (photos[k] for k in order):
        lines.append(f"  - {{id: {pid}, camera: cam, strip: '{name}', exterior: {{X0: {x}, "
                     f"Y0: {y}, Z0: 1000.0, omega: 0.0, phi: 0.0, kappa: 0.0}}}}")
    path.write_text("\n".join(lines) + "\n")
    return path


NEIGHBOURS = {frozenset(p) for s in "ab" for p in
              [(f"{s}0", f"{s}1"), (f"{s}1", f"{s}2"), (f"{s}2", f"{s}3")]}


@pytest.mark.parametrize("order", [[2, 0, 3, 1, 6, 4, 7, 5], [1, 3, 0, 2, 5, 7, 4, 6]])
def test_precision_pairs_neighbours_of_a_strip_listed_out_of_order(tmp_path, order):
    """Photos listed out of flight order (by name, or as another tool wrote them): the stereo
    pairs are still the neighbours along the strip, base 552 m, not photos two or three
    spacings apart (a 1656 m base of photos that do not even overlap, sigma Z 3 x too good)."""
    out = toolbox.run("orientation:precision", {
        "PROJECT": strip_project(tmp_path / "p.yaml", order), "MEAN_HEIGHT": 100.0,
        "OUTPUT": tmp_path / "pr.json"})
    pairs = out["PRECISION"]
    assert {frozenset((r["photo_a"], r["photo_b"])) for r in pairs} == NEIGHBOURS
    assert [r["base_m"] for r in pairs] == pytest.approx([BASE] * 6)


def test_footprints_forward_overlap_of_a_strip_listed_out_of_order(tmp_path):
    out = toolbox.run("orientation:footprints", {
        "PROJECT": strip_project(tmp_path / "p.yaml", [2, 0, 3, 1, 6, 4, 7, 5]),
        "MEAN_HEIGHT": 100.0, "POINTS_PER_SIDE": 2, "OUTPUT": tmp_path / "fp.gpkg"})
    overlaps = gpd.read_file(out["OUTPUT"], layer="overlaps")
    forward = overlaps[overlaps["kind"] == "forward"]
    assert {frozenset(p) for p in zip(forward["photo_a"], forward["photo_b"])} == NEIGHBOURS
    assert forward["pct_of_a"].to_numpy() == pytest.approx(60.0)
    fp = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert fp["forward_overlap_pct"].dropna().to_numpy() == pytest.approx([60.0] * 6)
    assert not out["STATISTICS"]["design"]["failures"]


@pytest.mark.parametrize("order", [list(range(8)), [3, 2, 1, 0, 7, 6, 5, 4]])
def test_a_strip_in_flight_order_keeps_its_pairs_and_direction(tmp_path, order):
    from toolbox.photogrammetry.project import load_project

    project = load_project(strip_project(tmp_path / "p.yaml", order))
    listed = [p for p in project.photos]
    assert [(a.id, b.id) for a, b in project.consecutive_pairs()] == \
        [(listed[k], listed[k + 1]) for k in (0, 1, 2, 4, 5, 6)]
