"""Squaring, alignment and sampling on shapes with a known truth."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from toolbox.attribution.editing import (
    align_vertices,
    corner_angles,
    densify,
    ring_area,
    sample_by_distance,
    sample_by_vectors,
    square_rings,
)
from toolbox.errors import InputDataError

E0, N0 = 1688400.0, 4799800.0


def _rotate(points, degrees, centre=(0.0, 0.0)):
    t = np.radians(degrees)
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    return (np.asarray(points, float) - centre) @ rot.T + centre


def _true_buildings():
    """True shapes (local metres): a 20 x 10 and a 10 x 10 building sharing a wall (rotated
    30 degrees), an L-shaped building (rotated 62 degrees), a 12 x 8 one (rotated -17) and a
    trapezoid with a 20-degree wall (rotated 5 degrees: its oblique wall stays oblique)."""
    a = _rotate([(0, 0), (20, 0), (20, 10), (0, 10)], 30)
    b = np.array([a[1], _rotate([(30, 0)], 30)[0], _rotate([(30, 10)], 30)[0], a[2]])
    ell = _rotate([(0, 0), (16, 0), (16, 6), (6, 6), (6, 14), (0, 14)], 62) + (60, 0)
    small = _rotate([(0, 0), (12, 0), (12, 8), (0, 8)], -17) + (0, 40)
    trap = _rotate([(0, 0), (14, 0), (14 - 8 * np.tan(np.radians(20)), 8), (0, 8)], 5) + (40, 40)
    return [a, b, ell, small, trap]


def _distort(shapes, sigma=0.04, seed=7):
    """Each distinct vertex moved by N(0, sigma) clipped at 2 sigma (shared ones move together)."""
    rng = np.random.default_rng(seed)
    moves = {}
    out = []
    for s in shapes:
        d = []
        for p in s:
            key = tuple(np.round(p, 6))
            if key not in moves:
                moves[key] = np.clip(rng.normal(0, sigma, 2), -2 * sigma, 2 * sigma)
            d.append(p + moves[key])
        out.append(np.array(d))
    return out


def _closed(s, z=330.0):
    ring = np.vstack([s, s[:1]])
    return np.column_stack([ring, np.full(len(ring), z)])


def test_squaring_right_angles_area_shared_vertices():
    truth = _true_buildings()
    plotted = _distort(truth)
    rings = [_closed(s) for s in plotted]
    result = square_rings(rings, np.arange(len(rings)), tolerance=0.2, angle_tolerance=3.0,
                          area_tolerance=0.01)
    assert result.squared.tolist() == [True] * 5 and result.reasons == {}
    for k in range(4):  # every corner of the four rectilinear buildings exactly 90 degrees
        np.testing.assert_allclose(corner_angles(result.rings[k]), 90.0, atol=1e-7)
    # the trapezoid: its three right corners squared, the oblique wall's corners not forced
    angles = corner_angles(result.rings[4])
    np.testing.assert_allclose(angles[[0, 3]], 90.0, atol=1e-7)
    np.testing.assert_allclose(angles[[1, 2]], [70.0, 110.0], atol=1.0)
    for k, ring in enumerate(result.rings):
        before, after = abs(ring_area(rings[k])), abs(ring_area(ring))
        assert abs(after - before) / before < 0.01  # area preserved within 1 %
        true_area = abs(ring_area(np.vstack([truth[k], truth[k][:1]])))
        assert abs(after - true_area) / true_area < 0.02  # 4 cm noise on 10 m walls: ~1-2 %
        # closer to the true shape than the plotted one, no vertex moved beyond 0.2
        err_before = np.linalg.norm(plotted[k] - truth[k], axis=1)
        err_after = np.linalg.norm(ring[:-1, :2] - truth[k], axis=1)
        assert np.sqrt(np.mean(err_after ** 2)) < np.sqrt(np.mean(err_before ** 2))
        assert np.linalg.norm(ring[:-1, :2] - rings[k][:-1, :2], axis=1).max() <= 0.2
        assert (ring[:, 2] == 330.0).all()  # Z kept
    # the shared wall: a's corners 1, 2 are b's 0, 3 exactly
    assert np.array_equal(result.rings[0][1], result.rings[1][0])
    assert np.array_equal(result.rings[0][2], result.rings[1][3])
    # the pair shares one orientation, the estimated one within 0.2 degrees of 30
    assert result.orientation[0] == result.orientation[1]
    assert abs(result.orientation[0] - 30.0) < 0.2
    assert abs(result.orientation[4] - 5.0) < 0.5  # the oblique wall does not pull it
    assert result.corner_error < 1e-7


def test_squaring_never_moves_beyond_tolerance():
    truth = _true_buildings()
    plotted = _distort(truth)
    plotted[3] = plotted[3].copy()
    plotted[3][2] += (0.5, -0.3)  # one corner 0.58 m off: squaring would move it too far
    rings = [_closed(s) for s in plotted]
    result = square_rings(rings, np.arange(5), tolerance=0.2, angle_tolerance=5.0,
                          area_tolerance=0.01)
    assert result.squared.tolist() == [True, True, True, False, True]
    assert "squaring tolerance 0.2" in result.reasons[3]
    np.testing.assert_array_equal(result.rings[3], rings[3])  # left as it was
    moves = np.hypot(*(result.after - result.before).T)
    assert moves.max() <= 0.2


def test_square_algorithm_with_parameter_file(tmp_path):
    plotted = _distort(_true_buildings())
    frame = gpd.GeoDataFrame({"code": ["FAB01002"] * 5, "name": list("ABCDE")},
                             geometry=[shapely.Polygon(_closed(s) + (E0, N0, 0))
                                       for s in plotted], crs="EPSG:3003")
    src = tmp_path / "buildings.gpkg"
    frame.to_file(src, layer="FAB01002", driver="GPKG")
    params = tmp_path / "parametri.txt"
    params.write_text("tolleranza planimetrica di squadratura = 0.2\n"
                      "tolleranza angolare di squadratura = 3\n"
                      "numero di cifre decimali = 3\n"
                      "traslazione delle coordinate = 1688000 4799000\n"
                      "passo di spline = 2\n")
    out = tmp_path / "squared.gpkg"
    feedback = toolbox.Feedback()
    stats = toolbox.run("attribution:square", {"INPUT": f"{src}|layername=FAB01002",
                                               "PARAMETERS": params, "OUTPUT": out},
                        feedback=feedback)["STATISTICS"]
    assert stats["squared"] == 5 and stats["largest_corner_error_deg"] < 1e-6
    assert stats["tolerance_sources"] == {"tolerance": "file", "angle_tolerance": "file",
                                          "area_tolerance": "default", "precision": "file"}
    # entries for other steps (the translation the importer applied, the spline step): one
    # information message, no warning on every step sharing the file
    info = next(t for lvl, t in feedback.messages
                if lvl == "info" and "not used by attribution:square" in t)
    assert "'traslazione delle coordinate' (line 4)" in info and "'passo di spline'" in info
    assert "coordinate translation is not applied" in info
    assert not [w for w in feedback.warnings if "PARAMETERS" in w]
    squared = gpd.read_file(out, layer="FAB01002")
    assert squared["name"].tolist() == list("ABCDE") and squared["squared"].all()
    moved = gpd.read_file(out, layer="moved_vertices")
    assert len(moved) == stats["moved_vertices"] > 0
    assert moved["displacement"].max() <= 0.2
    np.testing.assert_allclose(moved["displacement"], np.hypot(moved["dx"], moved["dy"]))
    # each moved vertex is where the squared building has it
    verts = shapely.points(np.vstack([shapely.get_coordinates(g) for g in squared.geometry]))
    pts = np.asarray(moved.geometry.values, dtype=object)
    assert (shapely.distance(pts[:, None], verts[None, :]).min(axis=1) < 1e-6).all()
    assert set(moved["feature"]) >= {"1;2"}  # the shared wall's vertices belong to A and B


def test_align_projects_nearly_collinear_vertices_and_keeps_shared_ones():
    # a wall along y = 0 plotted with +-3 cm wobble, then a real corner, then a short leg
    coords = np.array([(0, 0, 1), (10, 0.03, 1), (20, -0.02, 1), (30, 0.01, 1), (40, 0, 1),
                       (40, 10, 1), (41, 20, 1)], float)
    fixed = np.zeros(len(coords), bool)
    fixed[[0, -1]] = True
    out = align_vertices(coords, 0.05, fixed)
    np.testing.assert_allclose(out[1:4, 1], 0.0, atol=1e-12)  # onto the chord y = 0
    np.testing.assert_array_equal(out[1:4, 0], coords[1:4, 0])  # projected: x unchanged
    np.testing.assert_array_equal(out[4:], coords[4:])  # the corner is not nearly collinear
    assert np.abs(out - coords).max() <= 0.05
    fixed[2] = True  # shared with another line: it stays, and ends the runs
    out = align_vertices(coords, 0.05, fixed)
    np.testing.assert_array_equal(out[2], coords[2])
    for k, (a, b) in ((1, (0, 2)), (3, (2, 4))):  # the orthogonal projection onto each chord
        chord = shapely.LineString(coords[[a, b], :2])
        foot = chord.interpolate(chord.project(shapely.Point(coords[k, :2])))
        np.testing.assert_allclose(out[k, :2], [foot.x, foot.y], atol=1e-12)


def test_align_algorithm_keeps_connections(tmp_path):
    wall = shapely.LineString([(E0, N0), (E0 + 10, N0 + 0.04), (E0 + 20, N0 - 0.03),
                               (E0 + 30, N0)])
    branch = shapely.LineString([(E0 + 10, N0 + 0.04), (E0 + 10, N0 + 10)])  # shares a vertex
    src = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"code": ["MUR01001", "MUR01001"]}, geometry=[wall, branch],
                     crs="EPSG:3003").to_file(src, layer="walls", driver="GPKG")
    out = tmp_path / "aligned.gpkg"
    stats = toolbox.run("attribution:align", {"INPUT": src, "TOLERANCE": 0.05, "OUTPUT": out}
                        )["STATISTICS"]
    aligned = gpd.read_file(out, layer="walls")
    c = shapely.get_coordinates(aligned.geometry.iloc[0])
    assert c[1].tolist() == [E0 + 10, N0 + 0.04]  # shared: fixed
    chord = shapely.LineString([c[1], c[3]])  # onto the chord (10, .04)-(30, 0), orthogonally
    foot = chord.interpolate(chord.project(shapely.Point(E0 + 20, N0 - 0.03)))
    assert c[2].tolist() == pytest.approx([foot.x, foot.y], abs=1e-6)
    assert stats["moved_vertices"] == 1
    assert shapely.get_coordinates(aligned.geometry.iloc[1])[0].tolist() == c[1].tolist()


def test_sampling_by_vectors_distance_and_densify():
    straight = np.column_stack([np.arange(0, 20.5, 0.5), np.zeros(41), np.zeros(41)])
    keep = sample_by_vectors(straight, 5.0, 10.0)
    assert keep.tolist() == [0, 10, 20, 30, 40]  # every 5 m on a straight line
    corner = np.vstack([straight[:21], np.column_stack([np.full(10, 10.0),
                                                        np.arange(0.5, 5.5, 0.5), np.zeros(10)])])
    keep = sample_by_vectors(corner, 50.0, 10.0)
    # the corner (10, 0) is recorded when travel turns north; then (10, 0.5), since the line
    # through the last two recorded vertices still points east
    assert keep.tolist() == [0, 20, 21, 30]
    line = np.array([(0, 0, 100), (10.5, 0, 110.5)])
    np.testing.assert_allclose(sample_by_distance(line, 2.0),
                               [(x, 0, 100 + x) for x in (0, 2, 4, 6, 8, 10, 10.5)])
    dense, added = densify(np.array([(0, 0, 0), (10, 0, 10), (10, 3, 10)], float), 3.0)
    np.testing.assert_allclose(dense, [(0, 0, 0), (2.5, 0, 2.5), (5, 0, 5), (7.5, 0, 7.5),
                                       (10, 0, 10), (10, 3, 10)])
    assert added.tolist() == [False, True, True, True, False, False]


def test_sample_algorithm_on_a_contour_with_tolerance(tmp_path):
    t = np.linspace(0, np.pi, 181)
    arc = shapely.LineString(np.column_stack([E0 + 50 * np.cos(t), N0 + 50 * np.sin(t),
                                              np.full(181, 325.0)]))
    line = shapely.LineString([(E0, N0 - 10, 320), (E0 + 30, N0 - 10, 320)])
    src = tmp_path / "contours.gpkg"
    gpd.GeoDataFrame({"code": ["CUR01001"] * 2}, geometry=[arc, line], crs="EPSG:3003"
                     ).to_file(src, layer="contours", driver="GPKG")
    out = tmp_path / "sampled.gpkg"
    stats = toolbox.run("attribution:sample", {"INPUT": src, "METHOD": "vectors",
                                               "DISTANCE": 10.0, "ANGLE": 5.0,
                                               "TOLERANCE": 0.5, "OUTPUT": out})["STATISTICS"]
    sampled = gpd.read_file(out, layer="contours")
    kept = shapely.get_coordinates(sampled.geometry.iloc[0], include_z=True)
    # radius 50, one vertex a degree (0.873 m): the direction of travel turns 1 degree per
    # vertex, so vertices are recorded every few degrees, long before 10 m
    assert len(kept) < 181 / 2 and (kept[:, 2] == 325.0).all()
    chord = np.hypot(*np.diff(kept[:, :2], axis=0).T)
    assert chord.max() <= 10.0
    # no recorded chord spans more than 7 degrees: sagitta 50 (1 - cos 3.5 deg) = 0.093 m
    spans = np.degrees(np.diff(np.arctan2(kept[:, 1] - N0, kept[:, 0] - E0)))
    assert spans.max() <= 7.0 + 1e-6
    assert stats["largest_deviation"] < 50 * (1 - np.cos(np.radians(3.5)))
    moved = gpd.read_file(out, layer="moved_vertices")
    assert len(moved) == 181 - len(kept) and (moved["change"] == "removed").all()
    tight = toolbox.run("attribution:sample", {"INPUT": src, "METHOD": "distance",
                                               "DISTANCE": 20.0, "TOLERANCE": 0.5,
                                               "OUTPUT": tmp_path / "tight.gpkg"})["STATISTICS"]
    assert tight["left_unchanged"] == ["1"]  # 20 m chords on r = 50 miss by ~1 m: left


EDITS = ["attribution:square", "attribution:align", "attribution:sample"]


def _edit(tmp_path, algorithm, geoms, **params):
    """Run ``algorithm`` on a layer ``features`` of ``geoms``; the output layer and the stats."""
    src, out = tmp_path / "in.gpkg", tmp_path / "out.gpkg"
    gpd.GeoDataFrame({"name": [f"f{i + 1}" for i in range(len(geoms))]}, geometry=geoms,
                     crs="EPSG:3003").to_file(src, layer="features", driver="GPKG")
    stats = toolbox.run(algorithm, {"INPUT": src, "OUTPUT": out, **params})["STATISTICS"]
    return gpd.read_file(out, layer="features"), stats


@pytest.mark.parametrize("algorithm", EDITS)
def test_editing_keeps_every_part_and_hole_of_a_multipolygon(tmp_path, algorithm):
    shell, hole, other, single = _distort([
        _rotate([(0, 0), (30, 0), (30, 20), (0, 20)], 30),
        _rotate([(10, 5), (20, 5), (20, 11), (10, 11)], 30),
        _rotate([(0, 0), (12, 0), (12, 8), (0, 8)], 30) + (60, 0),
        _rotate([(0, 0), (10, 0), (10, 10), (0, 10)], 30) + (0, 60)])
    multi = shapely.MultiPolygon([shapely.Polygon(shell + (E0, N0), [hole + (E0, N0)]),
                                  shapely.Polygon(other + (E0, N0))])
    plain = shapely.Polygon(single + (E0, N0))
    edited, _ = _edit(tmp_path, algorithm, [multi, plain])
    g = edited.geometry.iloc[0]
    assert g.geom_type == "MultiPolygon" and g.is_valid
    assert [len(p.interiors) for p in g.geoms] == [1, 0]
    for new, old in zip(g.geoms, multi.geoms, strict=True):  # area kept within 1 % per part
        assert new.area == pytest.approx(old.area, rel=0.01)
    assert edited.geometry.iloc[1].is_valid
    assert edited.geometry.iloc[1].area == pytest.approx(plain.area, rel=0.01)


@pytest.mark.parametrize("algorithm", EDITS)
def test_editing_keeps_each_feature_dimension(tmp_path, algorithm):
    a, b = _distort([_rotate([(0, 0), (20, 0), (20, 10), (0, 10)], 30),
                     _rotate([(0, 0), (20, 0), (20, 10), (0, 10)], 30) + (40, 0)])
    with_z = shapely.Polygon(_closed(a, 5.0) + (E0, N0, 0))
    without = shapely.Polygon(b + (E0, N0))
    edited, _ = _edit(tmp_path, algorithm, [with_z, without])
    assert shapely.has_z(edited.geometry.values).tolist() == [True, False]
    z = shapely.get_coordinates(edited.geometry.iloc[0], include_z=True)[:, 2]
    assert (z == 5.0).all()
    assert edited.geometry.iloc[1].area == pytest.approx(without.area, rel=0.01)


@pytest.mark.parametrize("algorithm", ["attribution:align", "attribution:sample"])
def test_editing_keeps_multilinestring_parts_apart(tmp_path, algorithm):
    first = [(E0, N0, 200.0), (E0 + 50, N0 + 0.02, 201.0), (E0 + 100, N0, 202.0)]
    second = [(E0, N0 + 20, 210.0), (E0 + 50, N0 + 20.02, 211.0), (E0 + 100, N0 + 20, 212.0)]
    flat = shapely.LineString([(E0, N0 + 50), (E0 + 50, N0 + 50.02), (E0 + 100, N0 + 50)])
    edited, _ = _edit(tmp_path, algorithm, [shapely.MultiLineString([first, second]), flat])
    g = edited.geometry.iloc[0]
    assert g.geom_type == "MultiLineString" and len(g.geoms) == 2
    for part, old in zip(g.geoms, (first, second), strict=True):  # ends and Z where they were
        c = shapely.get_coordinates(part, include_z=True)
        np.testing.assert_allclose(c[[0, -1]], np.array(old)[[0, -1]])
        np.testing.assert_allclose(c[:, 2], np.array(old)[:, 2])
    assert not shapely.has_z(edited.geometry.iloc[1])


def test_square_keeps_null_and_empty_buildings(tmp_path):
    a, b = (shapely.Polygon(s + (E0, N0)) for s in _distort(
        [_rotate([(0, 0), (20, 0), (20, 10), (0, 10)], 30),
         _rotate([(0, 0), (12, 0), (12, 8), (0, 8)], 30) + (40, 0)]))
    edited, stats = _edit(tmp_path, "attribution:square", [a, None, shapely.Polygon(), b, None])
    geoms = edited.geometry.values
    assert geoms[1] is None and geoms[4] is None and geoms[2].is_empty
    assert edited["squared"].tolist() == [True, False, False, True, False]
    for g in (geoms[0], geoms[3]):  # squared: right corners
        np.testing.assert_allclose(corner_angles(shapely.get_coordinates(g.exterior)), 90.0,
                                   atol=1e-6)
    assert sorted(stats["not_squared"]) == [2, 3, 5]
    assert all("no geometry" in edited["squaring_note"].iloc[i] for i in (1, 2, 4))
    assert edited["orientation"].isna().tolist() == [False, True, True, False, True]


def test_editing_refuses_a_nan_z(tmp_path):
    ring = _closed(_rotate([(0, 0), (20, 0), (20, 10), (0, 10)], 30), 5.0) + (E0, N0, 0)
    ring[2, 2] = np.nan
    with pytest.raises(InputDataError, match="INPUT feature 2 has a NaN/inf Z"):
        _edit(tmp_path, "attribution:square", [shapely.Polygon(ring[:, :2] + (0, 50)),
                                               shapely.Polygon(ring)])
    assert not (tmp_path / "out.gpkg").exists()


@pytest.mark.parametrize("algorithm", EDITS)
def test_editing_writes_a_shapefile_with_style_files(tmp_path, algorithm):
    """OUTPUT .shp (offered by the help) was refused as a corrupt INPUT (the moved vertices'
    style went into the file through SQLite). Now the edited layer in out.shp with the input's
    features, moved_vertices beside it as out_moved_vertices.shp, each with its .qml."""
    buildings = [shapely.Polygon(_closed(s) + (E0, N0, 0)) for s in _distort(_true_buildings())]
    src, out = tmp_path / "in.gpkg", tmp_path / "out.shp"
    gpd.GeoDataFrame({"name": list("ABCDE")}, geometry=buildings,
                     crs="EPSG:3003").to_file(src, layer="features", driver="GPKG")
    toolbox.run(algorithm, {"INPUT": src, "OUTPUT": out})
    edited = gpd.read_file(out)
    assert edited["name"].tolist() == list("ABCDE") and edited.crs.to_epsg() == 3003
    assert shapely.is_valid(edited.geometry.values).all()
    moved = out.with_name("out_moved_vertices.shp")
    assert gpd.read_file(moved).crs.to_epsg() == 3003
    assert "<qgis" in moved.with_suffix(".qml").read_text(encoding="utf-8")
