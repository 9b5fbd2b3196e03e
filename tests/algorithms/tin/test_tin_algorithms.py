"""tin:delaunay, tin:interpolate, tin:to_raster and tin:volume through the runner and the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import geopandas as gpd
import numpy as np
import pandas as pd
import pyogrio
import pytest
import shapely

import toolbox
from toolbox.errors import InputDataError, ParameterError

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_799_500.0


def plane(x, y):
    """Known truth of the test points: z = 300 + 0.05 (x - X0) - 0.02 (y - Y0)."""
    return 300.0 + 0.05 * (np.asarray(x) - X0) - 0.02 * (np.asarray(y) - Y0)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tin")
    rng = np.random.default_rng(31)
    xy = np.column_stack([rng.uniform(0, 200, 600) + X0, rng.uniform(0, 200, 600) + Y0])
    corners = np.array([[X0, Y0], [X0 + 200, Y0], [X0 + 200, Y0 + 200], [X0, Y0 + 200]])
    xy = np.vstack([corners, xy])
    z = plane(xy[:, 0], xy[:, 1])
    points = gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z), crs=CRS)
    points.to_file(folder / "points.gpkg", layer="points")
    points_2d = gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy), crs=CRS)
    points_2d.to_file(folder / "points_2d.gpkg")
    # two breaklines on the plane that cross at (100, 100) without a shared vertex
    line_xy = [np.array([[20.0, 20.0], [180.0, 180.0]]), np.array([[20.0, 180.0], [180.0, 20.0]])]
    lines = [shapely.linestrings(p[:, 0] + X0, p[:, 1] + Y0, plane(p[:, 0] + X0, p[:, 1] + Y0))
             for p in line_xy]
    gpd.GeoDataFrame({"kind": ["a", "b"]}, geometry=lines, crs=CRS).to_file(
        folder / "breaklines.gpkg")
    gpd.GeoDataFrame({"kind": ["a"]}, geometry=[shapely.force_2d(lines[0])], crs=CRS).to_file(
        folder / "lines_2d.gpkg")
    boundary = shapely.Polygon([(X0 + 10, Y0 + 10), (X0 + 190, Y0 + 10), (X0 + 190, Y0 + 190),
                                (X0 + 10, Y0 + 190)],
                               [[(X0 + 60, Y0 + 60), (X0 + 80, Y0 + 60), (X0 + 70, Y0 + 80)]])
    gpd.GeoDataFrame({"n": [1]}, geometry=[boundary], crs=CRS).to_file(folder / "boundary.gpkg")
    gpd.GeoDataFrame({"n": [1]}, geometry=[boundary], crs="EPSG:32632").to_file(
        folder / "boundary_utm.gpkg")
    tin = folder / "tin.gpkg"
    result = toolbox.run("tin:delaunay", {"INPUT": folder / "points.gpkg",
                                          "BREAKLINES": folder / "breaklines.gpkg",
                                          "BOUNDARY": folder / "boundary.gpkg", "OUTPUT": tin})
    return {"folder": folder, "tin": tin, "boundary": boundary, "stats": result["STATISTICS"]}


def read(path, layer):
    return gpd.read_file(path, layer=layer)


def test_delaunay_writes_triangles_nodes_edges_with_topology(data):
    tin = data["tin"]
    assert [row[0] for row in pyogrio.list_layers(tin)] == ["triangles", "nodes", "edges",
                                                            "layer_styles"]
    tri, nodes, edges = read(tin, "triangles"), read(tin, "nodes"), read(tin, "edges")
    assert tri.crs.to_epsg() == nodes.crs.to_epsg() == edges.crs.to_epsg() == 3003
    assert set(tri.geom_type) == {"Polygon"} and tri.geometry.has_z.all()
    assert nodes.geometry.has_z.all() and edges.geometry.has_z.all()
    for col in ("node1", "node2", "node3", "nbr1", "nbr2", "nbr3", "area_2d", "area_3d",
                "slope_deg", "slope_pct", "aspect_deg"):
        assert col in tri.columns
    stats = data["stats"]
    assert len(tri) == stats["triangles"] and len(nodes) == stats["nodes"]
    assert len(edges) == stats["edges"]
    # the TIN covers exactly the boundary (with its hole); nothing outside
    union = shapely.union_all(tri.geometry.values)
    assert shapely.symmetric_difference(union, data["boundary"]).area < 1e-6
    # a plane: every triangle has the same slope and aspect
    expected_slope = np.degrees(np.arctan(np.hypot(0.05, 0.02)))
    np.testing.assert_allclose(tri.slope_deg, expected_slope, atol=1e-6)
    np.testing.assert_allclose(tri.aspect_deg, np.degrees(np.arctan2(-0.05, 0.02)) % 360,
                               atol=1e-5)
    np.testing.assert_allclose(tri.area_3d, tri.area_2d / np.cos(np.radians(expected_slope)),
                               rtol=1e-9)
    # neighbour ids are symmetric
    nbrs = tri.set_index("id")[["nbr1", "nbr2", "nbr3"]]
    for tid, row in nbrs.iterrows():
        for other in row.dropna().astype(int):
            assert tid in set(nbrs.loc[other].dropna().astype(int))
    # edges: once each, left/right consistent with the triangles' neighbour ids
    assert not edges[["node_from", "node_to"]].apply(sorted, axis=1).duplicated().any()
    inner = edges.dropna(subset=["right_tri"])
    for left, right in zip(inner.left_tri.astype(int), inner.right_tri.astype(int), strict=True):
        assert right in set(nbrs.loc[left].dropna().astype(int))


def test_delaunay_reports_the_breakline_crossing_and_flags_breakline_edges(data):
    stats, tin = data["stats"], data["tin"]
    assert stats["crossings"]["count"] == 1
    assert stats["crossings"]["max_z_disagreement"] == pytest.approx(0.0, abs=1e-9)
    nodes = read(tin, "nodes")
    crossing = nodes[nodes.source == "crossing"]
    assert len(crossing) == 1
    p = crossing.geometry.iloc[0]
    assert (p.x, p.y) == (pytest.approx(X0 + 100), pytest.approx(Y0 + 100))
    assert p.z == pytest.approx(float(plane(X0 + 100, Y0 + 100)))
    edges = read(tin, "edges")
    flagged = edges[edges.breakline]
    # each breakline is split at the crossing (and where mass points lie on it): its flagged
    # edges add up to its length inside the boundary (line a crosses the hole)
    on_line = shapely.union_all(read(data["folder"] / "breaklines.gpkg", None).geometry.values)
    inside = shapely.intersection(shapely.force_2d(on_line), data["boundary"]).length
    assert inside < 2 * np.hypot(160, 160) - 10
    assert flagged.length_2d.sum() == pytest.approx(inside, rel=1e-9)
    assert shapely.within(flagged.geometry.values, on_line.buffer(1e-6)).all()


def test_interpolate_gives_plane_heights_and_nodata_outside(data, tmp_path):
    queries = np.array([[X0 + 30, Y0 + 40], [X0 + 150.5, Y0 + 120.25], [X0 + 70, Y0 + 66],
                        [X0 + 500, Y0 + 50]])  # the third is in the hole, the fourth far away
    frame = gpd.GeoDataFrame({"name": list("abcd")}, geometry=shapely.points(queries), crs=CRS)
    frame.to_file(tmp_path / "q.gpkg", layer="queries")
    out = tmp_path / "q_z.gpkg"
    result = toolbox.run("tin:interpolate", {"INPUT": tmp_path / "q.gpkg", "TIN": data["tin"],
                                             "OUTPUT": out})
    stats = result["STATISTICS"]
    assert (stats["inside"], stats["outside"]) == (2, 2)
    got = read(out, "queries")
    assert list(got.name) == list("abcd") and got.crs.to_epsg() == 3003
    np.testing.assert_allclose(got.z_tin[:2], plane(queries[:2, 0], queries[:2, 1]), atol=1e-9)
    assert (got.z_tin[2:] == -9999.0).all()
    np.testing.assert_allclose(got.geometry.z, got.z_tin)


def test_interpolate_reports_dz_of_3d_check_points(data, tmp_path):
    pts = np.array([[X0 + 30, Y0 + 40], [X0 + 120, Y0 + 90]])
    z = plane(pts[:, 0], pts[:, 1]) + np.array([0.3, -0.4])
    gpd.GeoDataFrame({"id": [1, 2]}, geometry=shapely.points(pts[:, 0], pts[:, 1], z),
                     crs=CRS).to_file(tmp_path / "checks.gpkg")
    result = toolbox.run("tin:interpolate", {"INPUT": tmp_path / "checks.gpkg",
                                             "TIN": data["tin"], "FIELD": "h_tin",
                                             "OUTPUT": tmp_path / "checks_z.gpkg"})
    stats = result["STATISTICS"]
    assert stats["dz_rmse"] == pytest.approx(np.sqrt((0.09 + 0.16) / 2), abs=1e-9)
    got = read(tmp_path / "checks_z.gpkg", None)
    np.testing.assert_allclose(got.dz, [0.3, -0.4], atol=1e-9)


def test_interpolate_keeps_features_without_geometry_with_nodata(data, tmp_path):
    """Null and empty points stay in the output, in place, with NODATA and a warning naming
    them; the others get the plane's height (a multipoint is exploded in place)."""
    from toolbox.feedback import Feedback

    a, b, c = (X0 + 30, Y0 + 40), (X0 + 120, Y0 + 90), (X0 + 150.5, Y0 + 120.25)
    geoms = [shapely.Point(a), None, shapely.MultiPoint([b, c]), shapely.from_wkt("POINT EMPTY"),
             shapely.Point(c)]
    gpd.GeoDataFrame({"name": list("vwxyz")}, geometry=geoms, crs=CRS).to_file(
        tmp_path / "q.gpkg", layer="queries")
    out, feedback = tmp_path / "q_z.gpkg", Feedback()
    stats = toolbox.run("tin:interpolate", {"INPUT": tmp_path / "q.gpkg", "TIN": data["tin"],
                                            "OUTPUT": out}, feedback=feedback)["STATISTICS"]
    got = read(out, "queries")
    assert list(got.name) == list("vwxxyz")
    xy = np.array([a, b, c, c])
    np.testing.assert_allclose(got.z_tin[[0, 2, 3, 5]], plane(xy[:, 0], xy[:, 1]), atol=1e-9)
    assert list(got.z_tin[[1, 4]]) == [-9999.0, -9999.0]
    assert list(got.geometry.isna()) == [False, True, False, False, True, False]
    assert (stats["points"], stats["inside"], stats["no_geometry"]) == (4, 4, 2)
    assert ("2 of 5 feature(s) (rows 2, 4, counting from 1) have no geometry (null or empty): "
            "kept without geometry, height set to NODATA") in feedback.warnings


def test_to_raster_is_the_plane_at_cell_centres(data, tmp_path):
    import rasterio

    out = tmp_path / "tin.tif"
    result = toolbox.run("tin:to_raster", {"TIN": data["tin"], "CELL_SIZE": 2.5,
                                           "DATA_TYPE": "float64", "OUTPUT": out})
    with rasterio.open(out) as src:
        z = src.read(1)
        t = src.transform
        assert src.crs.to_epsg() == 3003 and src.nodata == -9999.0
    assert (t.c, t.f, t.a) == (X0 + 10, Y0 + 190, 2.5)  # the TIN's bounds, snapped
    cx = t.c + (np.arange(z.shape[1]) + 0.5) * t.a
    cy = t.f + (np.arange(z.shape[0]) + 0.5) * t.e
    gx, gy = np.meshgrid(cx, cy)
    inside = shapely.contains_xy(data["boundary"], gx, gy)
    np.testing.assert_allclose(z[inside], plane(gx, gy)[inside], atol=1e-9)
    outside = ~shapely.intersects_xy(data["boundary"], gx, gy)
    assert (z[outside] == -9999.0).all() and outside.sum() > 0  # the hole
    assert result["STATISTICS"]["cells_with_data"] == int((z != -9999.0).sum())


def test_to_raster_from_any_triangle_layer_and_on_a_template(data, tmp_path):
    import rasterio

    # a bare layer of 3D triangles (no nodes layer) works as a TIN
    tri = read(data["tin"], "triangles")[["geometry"]]
    tri.to_file(tmp_path / "bare.gpkg", layer="faces")
    first = tmp_path / "first.tif"
    toolbox.run("tin:to_raster", {"TIN": data["tin"], "CELL_SIZE": 7, "OUTPUT": first})
    second = tmp_path / "second.tif"
    toolbox.run("tin:to_raster", {"TIN": tmp_path / "bare.gpkg", "TEMPLATE": first,
                                  "OUTPUT": second})
    with rasterio.open(first) as a, rasterio.open(second) as b:
        assert a.transform == b.transform and a.shape == b.shape
        np.testing.assert_array_equal(a.read(1), b.read(1))


def test_volume_against_a_plane_is_exact(data, tmp_path):
    # above z0 = 300 - 10: h = 10 + 0.05 x - 0.02 y (local), positive everywhere in the box
    report = tmp_path / "volume.json"
    result = toolbox.run("tin:volume", {"TIN": data["tin"], "REFERENCE_Z": 290.0,
                                        "REPORT": report})
    stats = result["STATISTICS"]
    region = data["boundary"]
    area = region.area
    c = region.centroid
    expected = area * float(plane(c.x, c.y) - 290.0)  # linear: area x value at centroid
    assert stats["cut_volume"] == pytest.approx(expected, rel=1e-10)
    assert stats["fill_volume"] == 0.0 and stats["area"] == pytest.approx(area, rel=1e-12)
    assert json.loads(report.read_text())["cut_volume"] == pytest.approx(expected, rel=1e-10)


def _triangles(path, triangles) -> str:
    """A layer of plain triangle polygons (no node fields) in ``path``: a TIN as other
    programs export it; a triangle is a list of (dx, dy, z) or a geometry (None, empty)."""
    geoms = [t if t is None or isinstance(t, shapely.Geometry) else
             shapely.Polygon([(X0 + dx, Y0 + dy, z) for dx, dy, z in t]) for t in triangles]
    gpd.GeoDataFrame({"n": range(len(geoms))}, geometry=geoms, crs=CRS).to_file(path)
    return path


def _square(z_a=None, z_b=None):
    """The 10 x 10 m square at (X0, Y0) on the plane, as triangles A (0,0)(10,0)(10,10) and B
    (0,0)(10,10)(0,10); ``z_a``/``z_b`` replace the Z of (10, 10) in A/B."""
    top = float(plane(X0 + 10, Y0 + 10))
    a = [(0, 0, float(plane(X0, Y0))), (10, 0, float(plane(X0 + 10, Y0))),
         (10, 10, top if z_a is None else z_a)]
    b = [(0, 0, float(plane(X0, Y0))), (10, 10, top if z_b is None else z_b),
         (0, 10, float(plane(X0, Y0 + 10)))]
    return a, b


def test_triangle_polygons_at_one_xy_take_the_mean_height_whatever_their_order(tmp_path):
    """Corners 0.4 mm above and below the plane at one XY: the node is their mean (the plane),
    so the volume is the plane's exact one, 100 m2 x (plane at the centre - 290), in both
    feature orders (the first corner's Z made it depend on the order)."""
    top = float(plane(X0 + 10, Y0 + 10))
    a, b = _square(top + 0.0004, top - 0.0004)
    exact = 100.0 * (float(plane(X0 + 5, Y0 + 5)) - 290.0)
    for name, order in (("ab", [a, b]), ("ba", [b, a])):
        tin = _triangles(tmp_path / f"{name}.gpkg", order)
        stats = toolbox.run("tin:volume", {"TIN": tin, "REFERENCE_Z": 290.0})["STATISTICS"]
        assert stats["net_volume"] == pytest.approx(exact, abs=1e-7), name


REFUSED_TINS = {  # name: (the triangles of _square with one defect, the message)
    "nan_z": (lambda a, b: [a[:2] + [(10, 10, np.nan)], b],
              r"TIN: 1 of 2 feature\(s\) \(row 1, counting from 1\) have NaN/inf coordinates "
              r"or Z"),
    "step": (lambda a, b: [a[:2] + [(10, 10, a[2][2] + 5)], b],
             r"TIN is not a single-valued surface: 1 vertex position\(s\) have different "
             r"heights in different triangles \(more than 0\.001\), the largest at "
             r"X 1688010\.000 Y 4799510\.000: Z 300\.300 in row 2 and 305\.300 in row 1, "
             r"counting from 1"),
    "no_geometry": (lambda a, b: [a, None, shapely.from_wkt("POLYGON Z EMPTY"), b],
                    r"TIN: 2 of 4 feature\(s\) \(rows 2, 3, counting from 1\) have no geometry "
                    r"\(null or empty\)"),
}


@pytest.mark.parametrize("name", REFUSED_TINS)
def test_triangle_polygons_that_are_not_a_surface_are_refused_by_row(tmp_path, name):
    """A NaN Z, one XY with two heights (a step of 5 m), a null and an empty feature: refused
    naming the rows (counting from 1), no output written."""
    make, message = REFUSED_TINS[name]
    tin = _triangles(tmp_path / "tin.gpkg", make(*_square()))
    out = tmp_path / "tin.tif"
    with pytest.raises(InputDataError, match=message):
        toolbox.run("tin:to_raster", {"TIN": tin, "CELL_SIZE": 1, "OUTPUT": out})
    assert not out.exists()


def test_breakline_rows_in_messages_are_input_features(data, tmp_path):
    """A NaN Z on the 2nd vertex of the 3rd feature, after a null one and a 2-part line: the
    message names feature 3, not a vertex or a part."""
    line = [(X0 + 20, Y0 + 20, 301.0), (X0 + 40, Y0 + 30, np.nan), (X0 + 60, Y0 + 20, 302.0)]
    two = shapely.MultiLineString([[(X0 + 20, Y0 + 150, 300.0), (X0 + 40, Y0 + 150, 300.0)],
                                   [(X0 + 60, Y0 + 150, 300.0), (X0 + 80, Y0 + 150, 300.0)]])
    gpd.GeoDataFrame({"n": [1, 2, 3]}, geometry=[None, two, shapely.LineString(line)],
                     crs=CRS).to_file(tmp_path / "lines.gpkg")
    out = tmp_path / "x.gpkg"
    with pytest.raises(InputDataError, match=r"BREAKLINES: 1 feature\(s\) \(row 3, counting "
                                             r"from 1\) have NaN/inf coordinates or Z"):
        toolbox.run("tin:delaunay", {"INPUT": data["folder"] / "points.gpkg",
                                     "BREAKLINES": tmp_path / "lines.gpkg", "OUTPUT": out})
    assert not out.exists()


def _dem_below_the_plane(data, tmp_path):
    """A DEM 1 m below the plane on a 2 m grid and a mask: (DEM, mask file, the true cut
    volume = 1 m x the 4 m2 cells whose centre is inside the mask and the TIN)."""
    import rasterio
    from affine import Affine

    cell = 2.0
    t = Affine(cell, 0, X0, 0, -cell, Y0 + 200)
    cx = X0 + (np.arange(100) + 0.5) * cell
    cy = Y0 + 200 - (np.arange(100) + 0.5) * cell
    gx, gy = np.meshgrid(cx, cy)
    dem = tmp_path / "dem.tif"
    with rasterio.open(dem, "w", driver="GTiff", width=100, height=100, count=1,
                       dtype="float64", crs=CRS, transform=t, nodata=-9999.0) as dst:
        dst.write(plane(gx, gy) - 1.0, 1)
    mask = shapely.box(X0 + 40, Y0 + 40, X0 + 120, Y0 + 100)
    gpd.GeoDataFrame({"n": [1]}, geometry=[mask], crs=CRS).to_file(tmp_path / "mask.gpkg")
    inside = shapely.contains_xy(mask, gx, gy) & shapely.contains_xy(data["boundary"], gx, gy)
    return dem, tmp_path / "mask.gpkg", inside.sum() * cell * cell


def test_volume_against_a_dem_inside_a_mask(data, tmp_path):
    dem, mask, cut = _dem_below_the_plane(data, tmp_path)
    report = tmp_path / "volume.csv"
    result = toolbox.run("tin:volume", {"TIN": data["tin"], "REFERENCE_DEM": dem,
                                        "MASK": mask, "REPORT": report})
    stats = result["STATISTICS"]
    assert stats["cut_volume"] == pytest.approx(cut, rel=1e-9)
    assert stats["fill_volume"] == 0.0
    assert "cut_volume," in report.read_text()


def test_volume_scheduler_local_is_not_overridden_by_the_environment(data, tmp_path,
                                                                     monkeypatch):
    """SCHEDULER local runs the DEM's tiles on local threads: a DASK_SCHEDULER_ADDRESS naming
    no cluster (nothing listens on port 9) is not contacted (issue 31)."""
    dem, mask, cut = _dem_below_the_plane(data, tmp_path)
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")
    stats = toolbox.run("tin:volume", {"TIN": data["tin"], "REFERENCE_DEM": dem,
                                       "MASK": mask, "SCHEDULER": "local"})["STATISTICS"]
    assert stats["cut_volume"] == pytest.approx(cut, rel=1e-9)
    assert stats["fill_volume"] == 0.0


def test_bad_inputs_give_clear_errors(data, tmp_path):
    folder = data["folder"]
    with pytest.raises(ParameterError, match="INPUT is required unless BREAKLINES"):
        toolbox.run("tin:delaunay", {"OUTPUT": tmp_path / "x.gpkg"})
    with pytest.raises(InputDataError, match="INPUT has no Z"):
        toolbox.run("tin:delaunay", {"INPUT": folder / "points_2d.gpkg",
                                     "OUTPUT": tmp_path / "x.gpkg"})
    # ... unless a Z field is named
    ok = toolbox.run("tin:delaunay", {"INPUT": folder / "points_2d.gpkg", "Z_FIELD": "h",
                                      "OUTPUT": tmp_path / "ok.gpkg"})
    assert ok["STATISTICS"]["nodes"] == 604
    # duplicate-ok: each refusal written out (algorithm, inputs, message) on purpose
    with pytest.raises(InputDataError, match="BREAKLINES has no Z in its geometry"):
        toolbox.run("tin:delaunay", {"INPUT": folder / "points.gpkg",
                                     "BREAKLINES": folder / "lines_2d.gpkg",
                                     "OUTPUT": tmp_path / "x.gpkg"})
    with pytest.raises(InputDataError, match="EPSG:32632"):
        toolbox.run("tin:delaunay", {"INPUT": folder / "points.gpkg",
                                     "BOUNDARY": folder / "boundary_utm.gpkg",
                                     "OUTPUT": tmp_path / "x.gpkg"})
    line = gpd.GeoDataFrame({"h": [1.0]}, geometry=[shapely.LineString(
        [(X0, Y0, 1), (X0 + 1, Y0 + 1, 1), (X0 + 2, Y0 + 2, 1)])], crs=CRS)
    line.to_file(tmp_path / "collinear.gpkg")
    with pytest.raises(InputDataError, match="collinear"):
        toolbox.run("tin:delaunay", {"BREAKLINES": tmp_path / "collinear.gpkg",
                                     "OUTPUT": tmp_path / "x.gpkg"})
    with pytest.raises(ParameterError, match="MAX_EDGE is only used with HULL=concave"):
        toolbox.run("tin:delaunay", {"INPUT": folder / "points.gpkg", "MAX_EDGE": 5,
                                     "OUTPUT": tmp_path / "x.gpkg"})
    with pytest.raises(ParameterError, match="REFERENCE_Z or REFERENCE_DEM"):
        toolbox.run("tin:volume", {"TIN": data["tin"]})
    with pytest.raises(ParameterError, match="CELL_SIZE is required unless TEMPLATE"):
        toolbox.run("tin:to_raster", {"TIN": data["tin"], "OUTPUT": tmp_path / "x.tif"})
    assert not (tmp_path / "x.gpkg").exists() and not (tmp_path / "x.tif").exists()


def test_cli_run_reports_merged_duplicates(data, tmp_path):
    pts = read(data["folder"] / "points.gpkg", "points")
    dup = pts.iloc[:3].copy()
    dup["geometry"] = shapely.points(shapely.get_x(dup.geometry.values),
                                     shapely.get_y(dup.geometry.values),
                                     shapely.get_z(dup.geometry.values) + 2.0)
    gpd.GeoDataFrame(np.concatenate([pts.values, dup.values]), columns=pts.columns,
                     geometry="geometry", crs=CRS).to_file(tmp_path / "dups.gpkg")
    report = tmp_path / "run.json"
    proc = subprocess.run(
        [sys.executable, "-m", "toolbox.cli", "run", "tin:delaunay", "--INPUT",
         str(tmp_path / "dups.gpkg"), "--DUPLICATES", "max", "--HULL", "concave", "--OUTPUT",
         str(tmp_path / "dups_tin.gpkg"), "--run-report", str(report)],
        capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    run = json.loads(report.read_text())
    stats = run["outputs"]["STATISTICS"]
    assert stats["duplicates"]["duplicates_removed"] == 3
    assert stats["duplicates"]["max_z_spread"] == pytest.approx(2.0)
    assert any("3 duplicate point(s) merged" in w for w in run["warnings"])
    nodes = read(tmp_path / "dups_tin.gpkg", "nodes")
    assert (nodes.merged == 2).sum() == 3


def test_to_raster_takes_the_extent_as_given_and_writes_a_cog(data, tmp_path):
    import rasterio

    from toolbox.raster.writer import cog_problems

    extent = f"{X0 + 21.3},{Y0 + 33.1},{X0 + 121.3},{Y0 + 150.6}"
    out = toolbox.run("tin:to_raster", {"TIN": data["tin"], "CELL_SIZE": 0.25, "EXTENT": extent,
                                        "COG": True, "OUTPUT": tmp_path / "c.tif"})
    with rasterio.open(out["OUTPUT"]) as src:
        t = src.transform
        assert (t.c, t.f) == (X0 + 21.3, Y0 + 150.6) and src.shape == (470, 400)
        z = src.read(1)
    assert cog_problems(out["OUTPUT"]) == []
    gx, gy = np.meshgrid(t.c + (np.arange(400) + 0.5) * 0.25, t.f - (np.arange(470) + 0.5) * 0.25)
    inside = shapely.contains_xy(data["boundary"], gx, gy)
    np.testing.assert_allclose(z[inside], plane(gx, gy)[inside], atol=1e-3)
    with pytest.raises(ParameterError, match="over the limit of 1,000 cells"):
        toolbox.run("tin:to_raster", {"TIN": data["tin"], "CELL_SIZE": 0.25, "MAX_CELLS": 1000,
                                      "OUTPUT": tmp_path / "big.tif"})


def test_delaunay_reads_points_with_the_fast_reader_like_the_general_one(data, tmp_path,
                                                                        monkeypatch):
    """One point reader for TIN and gridding: a PointZ GeoPackage (Arrow/WKB fast path) and the
    same points with a null, an empty and a multipoint feature (general path) give equal values
    and, with Z_FIELD and breaklines, the same TIN."""
    import toolbox.io.vector_points as vector

    folder = data["folder"]
    points = gpd.read_file(folder / "points.gpkg", layer="points")
    extra = gpd.GeoDataFrame(
        {"h": [1e6, 2e6, plane(X0 + 3.5, Y0 + 7.25)]},
        geometry=[None, shapely.Point(), shapely.MultiPoint([(X0 + 3.5, Y0 + 7.25,
                                                             plane(X0 + 3.5, Y0 + 7.25))])],
        crs=CRS)
    mixed = pd.concat([points, extra], ignore_index=True)
    mixed.to_file(tmp_path / "mixed.gpkg")
    present = ~(shapely.is_missing(mixed.geometry.values) | shapely.is_empty(mixed.geometry.values))
    simple = gpd.GeoDataFrame({"h": mixed.h.to_numpy()[present]},
                              geometry=shapely.force_3d(shapely.get_parts(mixed.geometry.values[present])),
                              crs=CRS)
    simple.to_file(tmp_path / "simple.gpkg")
    paths = []
    real = vector._points_from_arrow
    monkeypatch.setattr(vector, "_points_from_arrow", lambda ref, z: paths.append(
        (ref.path.name, real(ref, z) is not None)) or real(ref, z))
    for z_field in (None, "h"):
        fast = vector.read_points_xyz(tmp_path / "simple.gpkg", z_field)
        general = vector.read_points_xyz(tmp_path / "mixed.gpkg", z_field)
        assert np.array_equal(fast, general) and len(fast) == len(points) + 1
        np.testing.assert_allclose(fast[:, 2], plane(fast[:, 0], fast[:, 1]), atol=1e-9)
    assert paths == [("simple.gpkg", True), ("mixed.gpkg", False)] * 2
    tins = {}
    for name in ("simple", "mixed"):
        out = tmp_path / f"tin_{name}.gpkg"
        toolbox.run("tin:delaunay", {"INPUT": tmp_path / f"{name}.gpkg", "Z_FIELD": "h",
                                     "BREAKLINES": folder / "breaklines.gpkg", "OUTPUT": out})
        tins[name] = (read(out, "nodes"), read(out, "triangles"), read(out, "edges"))
    assert paths[-2:] == [("simple.gpkg", True), ("mixed.gpkg", False)]
    (nodes_a, tri_a, edges_a), (nodes_b, tri_b, edges_b) = tins["simple"], tins["mixed"]
    assert nodes_a.drop(columns="geometry").equals(nodes_b.drop(columns="geometry"))
    assert np.array_equal(shapely.get_coordinates(nodes_a.geometry, include_z=True),
                          shapely.get_coordinates(nodes_b.geometry, include_z=True))
    assert tri_a[["node1", "node2", "node3"]].equals(tri_b[["node1", "node2", "node3"]])
    # the breaklines still reach the TIN: crossing nodes and breakline edges
    assert set(nodes_a.source) == {"point", "breakline", "crossing"}
    assert edges_a.breakline.sum() == edges_b.breakline.sum() > 0
