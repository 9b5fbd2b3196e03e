"""Reading the DEM inputs: the fast point reader agrees with the general one; points, contour
vertices and crossing breaklines together."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely

import toolbox
from toolbox.errors import InputDataError
from toolbox.io.vector import read_vector
from toolbox.io.vector_points import points_xyz, read_points_xyz
from toolbox.terrain.gridding.inputs import has_duplicate_xy
from toolbox.terrain.gridding.tin_constrained import constrained_tin

X0, Y0 = 1_688_000.0, 4_799_500.0


@pytest.fixture
def layers(tmp_path):
    rng = np.random.default_rng(9)
    xy = np.column_stack([X0 + rng.uniform(0, 50, 40), Y0 + rng.uniform(0, 50, 40)])
    z = rng.uniform(280, 340, 40)
    paths = {}
    paths["pointz"] = tmp_path / "pz.gpkg"
    gpd.GeoDataFrame({"h": z + 1}, geometry=shapely.points(xy[:, 0], xy[:, 1], z),
                     crs="EPSG:3003").to_file(paths["pointz"])
    paths["point2d"] = tmp_path / "p2.gpkg"
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy), crs="EPSG:3003").to_file(
        paths["point2d"])
    paths["multi"] = tmp_path / "mp.gpkg"
    gpd.GeoDataFrame({"h": [1.0, 2.0]}, geometry=[shapely.MultiPoint([(X0, Y0, 5), (X0 + 1, Y0, 6)]),
                                                  shapely.MultiPoint([(X0, Y0 + 1, 7)])],
                     crs="EPSG:3003").to_file(paths["multi"])
    paths["csv"] = tmp_path / "p.csv"
    paths["csv"].write_text("x,y,z\n" + "\n".join(f"{a},{b},{c}" for a, b, c in
                                                    zip(xy[:, 0], xy[:, 1], z, strict=True)))
    return paths


def test_fast_point_reader_matches_the_general_one(layers):
    for name, z_field in (("pointz", None), ("pointz", "h"), ("point2d", "h"), ("multi", None),
                          ("multi", "h"), ("csv", None)):
        fast = read_points_xyz(layers[name], z_field)
        slow = points_xyz(read_vector(layers[name]), z_field)
        assert np.array_equal(fast, slow), (name, z_field)
    with pytest.raises(InputDataError, match="no Z"):
        read_points_xyz(layers["point2d"])


def test_geoparquet_points_are_decoded_without_a_geodataframe(layers, tmp_path, monkeypatch):
    """GeoParquet points (WKB) take the WKB decoder, not the GeoDataFrame reader (10 M points
    peaked at 3.6 GB through it): the same XYZ as GeoPandas/shapely read from the file."""
    import toolbox.io.vector_points as vp

    frames = {name: gpd.read_file(layers[name]) for name in ("pointz", "point2d")}
    paths = {}
    for name, frame in frames.items():
        paths[name] = tmp_path / f"{name}.parquet"
        frame.to_parquet(paths[name])
    expected = {(name, z): points_xyz(gpd.read_parquet(paths[name]), z)
                for name, z in (("pointz", None), ("pointz", "h"), ("point2d", "h"))}
    monkeypatch.setattr(vp, "read_vector", lambda *a, **k: pytest.fail("general path taken"))
    for (name, z_field), oracle in expected.items():
        np.testing.assert_array_equal(read_points_xyz(paths[name], z_field), oracle)


def test_duplicate_check():
    xyz = np.array([[0.0, 0.0, 1], [1.0, 0.0, 2], [0.0, 1.0, 3]])
    assert not has_duplicate_xy(xyz)
    assert has_duplicate_xy(np.vstack([xyz, [[1.0, 0.0, 9]]]))
    assert not has_duplicate_xy(np.array([[0.0, 1.0, 1], [1.0, 0.0, 1]]))  # swapped x, y


def test_crossing_breaklines_are_split_with_interpolated_heights():
    xyz = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0], [0.0, 10.0, 0.0],
                    [2.0, 5.0, 10.0], [8.0, 5.0, 20.0],    # breakline A along y = 5
                    [5.0, 2.0, 30.0], [5.0, 8.0, 30.0]])   # breakline B along x = 5
    nodes, tri, info = constrained_tin(xyz, np.array([[4, 5], [6, 7]]))
    assert info["crossings"] == 1 and len(nodes) == 9
    # at (5, 5): A gives 15, B gives 30 -> mean 22.5, disagreement 15
    assert nodes[8].tolist() == [5.0, 5.0, 22.5] and info["crossing_z_disagreement"] == 15.0
    assert tri.max() == 8


def test_points_contours_and_breaklines_together(tmp_path):
    # plane z = 300 + 0.2 u: points, contour lines (x = const) and a breakline across them
    rng = np.random.default_rng(10)
    uv = rng.uniform(0, 100, (200, 2))
    xy = uv + [X0, Y0]
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], 300 + 0.2 * uv[:, 0]),
                     crs="EPSG:3003").to_file(tmp_path / "pts.gpkg")
    contours = gpd.GeoDataFrame({"elev": [300 + 0.2 * u for u in (0, 50, 100)]},
                                geometry=[shapely.LineString([(X0 + u, Y0), (X0 + u, Y0 + 100)])
                                          for u in (0, 50, 100)], crs="EPSG:3003")
    contours.to_file(tmp_path / "contours.gpkg")
    ridge = gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 5, Y0 + 60, 301.0),
                                                           (X0 + 95, Y0 + 60, 319.0)])],
                             crs="EPSG:3003")
    ridge.to_file(tmp_path / "bl.gpkg")
    out = toolbox.run("dem:tin_linear", {"INPUT": tmp_path / "pts.gpkg",
                                         "LINES": tmp_path / "contours.gpkg",
                                         "LINES_Z_FIELD": "elev",
                                         "BREAKLINES": tmp_path / "bl.gpkg", "CELL_SIZE": 2,
                                         "OUTPUT": tmp_path / "dem.tif"})
    stats = out["STATISTICS"]
    assert stats["inputs"] == {"points": 200, "lines_vertices": 6, "breaklines_vertices": 2}
    # LINES give points only: the breakline crossing the middle contour is no constraint crossing
    assert stats["method"]["crossings"] == 0 and stats["breakline_segments"] == 1
    with rasterio.open(tmp_path / "dem.tif") as src:
        z = src.read(1, masked=True)
        t = src.transform
    gx = t.c + (np.arange(z.shape[1]) + 0.5) * t.a
    assert z.count() == 50 * 50
    assert np.abs(z - (300 + 0.2 * (gx[None, :] - X0))).max() < 1e-3


def test_duplicate_check_stays_linear_on_clustered_points(monkeypatch):
    """The compiled duplicate check compares points pair by pair inside a bin; bins are sized for
    the bounding box, so clustered points crowd a few bins. Counted, not timed: the comparisons
    must stay within PAIRWISE_MAX / 2 per point plus one per point sorted (pairwise over every
    bin made 12.5 million here), and the answer must be the sort's."""
    from toolbox.terrain.gridding import neighbours

    monkeypatch.setattr(neighbours, "NUMPY_MAX_POINTS", -1)  # the compiled path at any size
    rng = np.random.default_rng(3)
    spread = rng.uniform(0, 1000, (3000, 2))
    cluster = rng.uniform(0, 1.0, (5000, 2))  # 5000 points in about one bin
    n = 8000
    bound = n * neighbours.PAIRWISE_MAX // 2 + n
    for xy, expected in ((np.vstack([spread, cluster]), False),
                         (np.vstack([spread, cluster, cluster[1234:1235]]), True),  # in the crowd
                         (np.vstack([spread, cluster, spread[7:8]]), True)):  # in a sparse bin
        bins = neighbours.PointBins.build(xy)
        assert np.diff(bins.offsets).max() > 1000  # the crowd is there
        found, comparisons = bins.duplicate_check()
        assert found is expected
        assert found == (len(np.unique(xy, axis=0)) < len(xy))  # independent: numpy's unique
        assert comparisons <= bound, comparisons


def test_line_rows_in_messages_are_input_features(tmp_path):
    """LINES with a NaN Z on the 2nd vertex of feature 3, after a null feature and a 2-part
    line: the message names feature 3 (it named a vertex of the exploded layer)."""
    xy = np.array([[0, 0], [100, 0], [0, 100], [100, 100], [50, 50]], dtype=float) + [X0, Y0]
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], np.full(5, 300.0)),
                     crs="EPSG:3003").to_file(tmp_path / "pts.gpkg")
    two = shapely.MultiLineString([[(X0 + 10, Y0 + 10, 300), (X0 + 20, Y0 + 10, 300)],
                                   [(X0 + 30, Y0 + 10, 300), (X0 + 40, Y0 + 10, 300)]])
    bad = shapely.LineString([(X0 + 10, Y0 + 80, 300), (X0 + 20, Y0 + 80, np.nan)])
    gpd.GeoDataFrame({"n": [1, 2, 3]}, geometry=[None, two, bad], crs="EPSG:3003").to_file(
        tmp_path / "lines.gpkg")
    out = tmp_path / "dem.tif"
    with pytest.raises(InputDataError, match=r"^LINES: 1 feature\(s\) \(row 3, counting from 1\) "
                                             r"have NaN/inf coordinates or Z$"):
        toolbox.run("dem:tin_linear", {"INPUT": tmp_path / "pts.gpkg",
                                       "LINES": tmp_path / "lines.gpkg", "CELL_SIZE": 5,
                                       "OUTPUT": out})
    assert not out.exists()
