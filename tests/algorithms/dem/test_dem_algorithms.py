"""dem:* gridding algorithms through the runner and the CLI: known surfaces, grid alignment,
nodata rules, tiling, breaklines, line vertices, duplicates and bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely
from affine import Affine

import toolbox
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.raster.writer import write_raster

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_799_500.0  # Siena block: large projected coordinates
W, H = 300.0, 200.0
GRID_METHODS = ["dem:nearest", "dem:idw", "dem:plane", "dem:quadratic", "dem:cubic",
                "dem:tin_linear"]


def plane(x, y):
    return 300.0 + 0.05 * (np.asarray(x) - X0) - 0.02 * (np.asarray(y) - Y0)


def quadratic(x, y):
    u, v = np.asarray(x) - X0 - 150.0, np.asarray(y) - Y0 - 100.0
    return 320.0 + 0.04 * u - 0.03 * v + 4e-4 * u * u - 2e-4 * u * v + 3e-4 * v * v


def write_points(path, xy, z, crs=CRS, z_in_geometry=True, layer="points"):
    geom = shapely.points(xy[:, 0], xy[:, 1], z) if z_in_geometry else shapely.points(xy)
    gpd.GeoDataFrame({"h": z}, geometry=geom, crs=crs).to_file(path, layer=layer)
    return path


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dem")
    rng = np.random.default_rng(45)
    xy = np.column_stack([X0 + rng.uniform(0, W, 1500), Y0 + rng.uniform(0, H, 1500)])
    corners = np.array([[X0, Y0], [X0 + W, Y0], [X0 + W, Y0 + H], [X0, Y0 + H]])
    xy = np.vstack([corners, xy])
    return {"folder": folder, "xy": xy,
            "plane": write_points(folder / "plane.gpkg", xy, plane(xy[:, 0], xy[:, 1])),
            "quadratic": write_points(folder / "quadratic.gpkg", xy,
                                      quadratic(xy[:, 0], xy[:, 1])),
            "plane_2d": write_points(folder / "plane_2d.gpkg", xy, plane(xy[:, 0], xy[:, 1]),
                                     z_in_geometry=False)}


def read(path):
    with rasterio.open(path) as src:
        return src.read(1, masked=True), src.transform, src.profile, src.crs


def centres(transform, shape):
    xs = transform.c + (np.arange(shape[1]) + 0.5) * transform.a
    ys = transform.f + (np.arange(shape[0]) + 0.5) * transform.e
    return np.meshgrid(xs, ys)


# -- known surfaces ---------------------------------------------------------------------------
@pytest.mark.parametrize("alg", GRID_METHODS)
def test_every_method_writes_a_georeferenced_float32_dem(alg, data, tmp_path):
    out = toolbox.run(alg, {"INPUT": data["plane"], "CELL_SIZE": 5, "OUTPUT": tmp_path / "d.tif"})
    z, transform, profile, crs = read(out["OUTPUT"])
    assert profile["dtype"] == "float32" and profile["nodata"] == -9999.0
    assert crs.to_epsg() == 3003 and profile["compress"] == "deflate"
    assert profile["tiled"] and profile["blockxsize"] == profile["blockysize"] == 512  # small too
    assert (transform.a, transform.e) == (5.0, -5.0)
    assert transform.c % 5 == 0 and transform.f % 5 == 0  # snapped to the cell size
    assert z.shape == (40, 60) and z.count() > 0.95 * z.size
    gx, gy = centres(transform, z.shape)
    err = np.abs(z - plane(gx, gy))
    stats = out["STATISTICS"]
    assert stats["cells"]["cells_with_value"] == z.count()
    if alg in ("dem:plane", "dem:quadratic", "dem:cubic", "dem:tin_linear"):
        assert err.max() < 1e-3  # a plane is reproduced exactly (float32 rounding)
    else:
        assert 0 < err.max() < 2.0  # nearest / IDW only approximate it
    if alg != "dem:nearest":
        assert stats["method"]["options"]["max_distance"] is None


@pytest.mark.parametrize("alg", ["dem:quadratic", "dem:cubic"])
def test_quadratic_surface_reproduced(alg, data, tmp_path):
    out = toolbox.run(alg, {"INPUT": data["quadratic"], "CELL_SIZE": 4,
                            "OUTPUT": tmp_path / "q.tif"})
    z, transform, _, _ = read(out["OUTPUT"])
    gx, gy = centres(transform, z.shape)
    assert np.abs(z - quadratic(gx, gy)).max() < 2e-3
    assert out["STATISTICS"]["method"]["fallbacks"] == 0


def test_plane_method_does_not_fit_a_quadratic(data, tmp_path):
    out = toolbox.run("dem:plane", {"INPUT": data["quadratic"], "CELL_SIZE": 4,
                                    "OUTPUT": tmp_path / "p.tif"})
    z, transform, _, _ = read(out["OUTPUT"])
    gx, gy = centres(transform, z.shape)
    assert np.abs(z - quadratic(gx, gy)).max() > 0.01


def test_z_field_gives_the_same_dem_as_geometry_z(data, tmp_path):
    a = toolbox.run("dem:idw", {"INPUT": data["plane"], "CELL_SIZE": 5, "OUTPUT": tmp_path / "a.tif"})
    b = toolbox.run("dem:idw", {"INPUT": data["plane_2d"], "Z_FIELD": "h", "CELL_SIZE": 5,
                                "OUTPUT": tmp_path / "b.tif"})
    assert np.array_equal(read(a["OUTPUT"])[0].filled(), read(b["OUTPUT"])[0].filled())


# -- grid alignment, nodata rules ------------------------------------------------------------
def test_output_takes_the_template_grid(data, tmp_path):
    t = Affine(2.5, 0, X0 + 13.3, 0, -2.5, Y0 + 181.7)  # off the 2.5 m lattice of 0
    template = write_raster(tmp_path / "template.tif", np.zeros((60, 90), "float32"), t, CRS)
    out = toolbox.run("dem:idw", {"INPUT": data["plane"], "TEMPLATE": template,
                                  "OUTPUT": tmp_path / "t.tif"})
    z, transform, _, _ = read(out["OUTPUT"])
    assert transform == t and z.shape == (60, 90)
    cut = toolbox.run("dem:idw", {"INPUT": data["plane"], "TEMPLATE": template,
                                  "EXTENT": f"{X0 + 50},{Y0 + 50},{X0 + 100},{Y0 + 90}",
                                  "OUTPUT": tmp_path / "c.tif"})
    zc, tc, _, _ = read(cut["OUTPUT"])
    # the cut grid lies on the template's lattice and covers the extent
    assert (tc.a, tc.e) == (2.5, -2.5)
    assert abs((tc.c - t.c) / 2.5 - round((tc.c - t.c) / 2.5)) < 1e-6
    assert abs((tc.f - t.f) / 2.5 - round((tc.f - t.f) / 2.5)) < 1e-6
    assert tc.c <= X0 + 50 < tc.c + 2.5 and tc.f - 2.5 < Y0 + 90 <= tc.f
    # same cells, same values as in the full template run
    col, row = int(round((tc.c - t.c) / 2.5)), int(round((t.f - tc.f) / 2.5))
    assert np.array_equal(zc, z[row:row + zc.shape[0], col:col + zc.shape[1]])


def test_extent_is_honoured_as_given(data, tmp_path):
    # the origin stays at the extent's xmin/ymax; the far edges round up to whole cells
    out = toolbox.run("dem:nearest", {"INPUT": data["plane"], "CELL_SIZE": 10,
                                      "EXTENT": f"{X0 + 3},{Y0 + 7},{X0 + 95},{Y0 + 61}",
                                      "OUTPUT": tmp_path / "e.tif"})
    z, t, _, _ = read(out["OUTPUT"])
    assert (t.c, t.f) == (X0 + 3, Y0 + 61) and z.shape == (6, 10)


def test_cells_outside_the_convex_hull_are_nodata(tmp_path):
    # points in the triangle (0,0) (100,0) (0,100): the north-east half of the box is outside
    rng = np.random.default_rng(5)
    uv = rng.uniform(0, 100, (3000, 2))
    uv = uv[uv.sum(axis=1) <= 100]
    uv = np.vstack([uv, [[0, 0], [100, 0], [0, 100]]])
    xy = uv + [X0, Y0]
    pts = write_points(tmp_path / "tri.gpkg", xy, plane(xy[:, 0], xy[:, 1]))
    for alg in ("dem:idw", "dem:quadratic", "dem:tin_linear"):
        out = toolbox.run(alg, {"INPUT": pts, "CELL_SIZE": 2, "OUTPUT": tmp_path / f"{alg[4:]}.tif"})
        z, t, _, _ = read(out["OUTPUT"])
        gx, gy = centres(t, z.shape)
        u, v = gx - X0, gy - Y0
        inside = (u >= 0) & (v >= 0) & (u + v <= 100)
        assert (~z.mask == inside).all(), alg
    out = toolbox.run("dem:idw", {"INPUT": pts, "CELL_SIZE": 2, "EXTRAPOLATE": True,
                                  "OUTPUT": tmp_path / "extra.tif"})
    assert read(out["OUTPUT"])[0].count() == 50 * 50


def test_mask_polygon_and_max_distance(data, tmp_path):
    mask = gpd.GeoDataFrame(geometry=[shapely.box(X0 + 100, Y0 + 50, X0 + 200, Y0 + 150)],
                            crs=CRS)
    mask.to_file(tmp_path / "mask.gpkg")
    out = toolbox.run("dem:idw", {"INPUT": data["plane"], "CELL_SIZE": 5,
                                  "MASK": tmp_path / "mask.gpkg", "OUTPUT": tmp_path / "m.tif"})
    z, t, _, _ = read(out["OUTPUT"])
    gx, gy = centres(t, z.shape)
    inside = (gx > X0 + 100) & (gx < X0 + 200) & (gy > Y0 + 50) & (gy < Y0 + 150)
    assert (~z.mask == inside).all()
    # two far-apart clusters: cells between them are farther than 10 m from any point
    xy = np.array([[X0 + dx, Y0 + dy] for dx in (0, 5, 10) for dy in (0, 5, 10)]
                  + [[X0 + 90 + dx, Y0 + 90 + dy] for dx in (0, 5, 10) for dy in (0, 5, 10)])
    pts = write_points(tmp_path / "clusters.gpkg", xy, plane(xy[:, 0], xy[:, 1]))
    out = toolbox.run("dem:idw", {"INPUT": pts, "CELL_SIZE": 2, "EXTRAPOLATE": True,
                                  "MAX_DISTANCE": 10, "OUTPUT": tmp_path / "md.tif"})
    z, t, _, _ = read(out["OUTPUT"])
    gx, gy = centres(t, z.shape)
    d = np.min(np.hypot(gx[..., None] - xy[:, 0], gy[..., None] - xy[:, 1]), axis=-1)
    assert (~z.mask == (d <= 10)).all()


@pytest.mark.parametrize("alg,extra", [("dem:idw", {}), ("dem:quadratic", {}),
                                       ("dem:tin_linear", {}),
                                       ("dem:tin_linear", {"MAX_DISTANCE": 4}),
                                       ("dem:nearest", {"MAX_DISTANCE": 4}),
                                       ("dem:idw", {"SECTORS": 4, "RADIUS": 15}),
                                       ("dem:cubic", {"RADIUS": 8, "MIN_NEIGHBOURS": 4})])
def test_tiles_with_halo_give_the_untiled_result(alg, extra, data, tmp_path):
    """Small tiles (each with only the points of its halo) == one tile with every point."""
    common = {"INPUT": data["quadratic"], "CELL_SIZE": 3, "OVERVIEWS": False, **extra}
    a = toolbox.run(alg, common | {"TILE_SIZE": 16, "OUTPUT": tmp_path / "a.tif"})
    b = toolbox.run(alg, common | {"TILE_SIZE": 512, "OUTPUT": tmp_path / "b.tif"})
    za, zb = read(a["OUTPUT"])[0], read(b["OUTPUT"])[0]
    assert a["STATISTICS"]["cells"]["tiles"] == 7 * 5 and b["STATISTICS"]["cells"]["tiles"] == 1
    assert np.array_equal(za.filled(), zb.filled())


def test_cog_output_with_overviews(data, tmp_path):
    from toolbox.raster.writer import cog_problems

    out = toolbox.run("dem:nearest", {"INPUT": data["plane"], "CELL_SIZE": 0.4, "COG": True,
                                      "OUTPUT": tmp_path / "c.tif"})
    with rasterio.open(out["OUTPUT"]) as src:
        assert src.shape == (500, 750) and src.overviews(1) == [2]
        assert src.tags(ns="IMAGE_STRUCTURE")["PREDICTOR"] == "3"
    assert cog_problems(out["OUTPUT"]) == []


# -- lines, breaklines ----------------------------------------------------------------------
def test_contour_vertices_as_points(tmp_path):
    """LINES with an elevation field (contours of z = 300 + 0.5 u): every vertex is a point."""
    lines = [shapely.LineString([(X0 + u, Y0 + v) for v in np.linspace(0, 100, 21)])
             for u in range(0, 101, 10)]
    frame = gpd.GeoDataFrame({"elev": [300 + 0.5 * u for u in range(0, 101, 10)]},
                             geometry=lines, crs=CRS)
    frame.to_file(tmp_path / "contours.gpkg")
    for alg in ("dem:tin_linear", "dem:plane"):
        out = toolbox.run(alg, {"LINES": tmp_path / "contours.gpkg", "LINES_Z_FIELD": "elev",
                                "CELL_SIZE": 2.5, "OUTPUT": tmp_path / f"{alg[4:]}.tif"})
        z, t, _, _ = read(out["OUTPUT"])
        gx, _ = centres(t, z.shape)
        assert z.count() == 40 * 40 and np.abs(z - (300 + 0.5 * (gx - X0))).max() < 1e-3
        assert out["STATISTICS"]["inputs"] == {"lines_vertices": 11 * 21}


def test_breaklines_keep_a_ridge(tmp_path):
    """A roof z = 100 - 0.5 |x - 50|: random points miss the ridge; the TIN is exact only when
    the ridge is a breakline (no triangle may cross it)."""
    rng = np.random.default_rng(8)
    uv = np.vstack([rng.uniform(0, 100, (400, 2)), [[0, 0], [100, 0], [100, 100], [0, 100]]])
    uv = uv[np.abs(uv[:, 0] - 50) > 0.5]
    xy = uv + [X0, Y0]
    roof = 100 - 0.5 * np.abs(uv[:, 0] - 50)
    pts = write_points(tmp_path / "roof.gpkg", xy, roof)
    ridge = gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 50, Y0 + v, 100.0)
                                                           for v in (0, 25, 50, 75, 100)])],
                             crs=CRS)
    ridge.to_file(tmp_path / "ridge.gpkg")
    without = toolbox.run("dem:tin_linear", {"INPUT": pts, "CELL_SIZE": 1,
                                             "OUTPUT": tmp_path / "a.tif"})
    with_bl = toolbox.run("dem:tin_linear", {"INPUT": pts, "BREAKLINES": tmp_path / "ridge.gpkg",
                                             "CELL_SIZE": 1, "OUTPUT": tmp_path / "b.tif"})
    for out, exact in ((without, False), (with_bl, True)):
        z, t, _, _ = read(out["OUTPUT"])
        gx, _ = centres(t, z.shape)
        err = np.abs(z - (100 - 0.5 * np.abs(gx - X0 - 50)))
        assert z.count() == 100 * 100
        assert (err.max() < 1e-3) == exact
    assert with_bl["STATISTICS"]["breakline_segments"] == 4


# -- duplicates and bad input -------------------------------------------------------------------
def test_duplicate_xy_rule_is_applied_and_reported(tmp_path):
    xy = np.array([[X0, Y0], [X0 + 10, Y0], [X0, Y0 + 10], [X0 + 10, Y0 + 10], [X0 + 10, Y0 + 10]])
    z = np.array([1.0, 2.0, 3.0, 4.0, 8.0])
    pts = write_points(tmp_path / "dup.gpkg", xy, z)
    feedback = Feedback()
    one_cell = {"CELL_SIZE": 20, "EXTENT": f"{X0},{Y0},{X0 + 20},{Y0 + 20}"}  # centre X0+10, Y0+10
    out = toolbox.run("dem:nearest", {"INPUT": pts, **one_cell, "OUTPUT": tmp_path / "d.tif"},
                      feedback=feedback)
    dup = out["STATISTICS"]["duplicates"]
    assert dup == {"duplicate_groups": 1, "duplicates_removed": 1, "max_z_spread": 4.0,
                   "rule": "mean"}
    assert any("rule 'mean'" in w for w in feedback.warnings)
    z_out = read(out["OUTPUT"])[0]
    assert z_out[0, 0] == 6.0  # the cell centre (X0+10, Y0+10) sits on the merged point
    out = toolbox.run("dem:nearest", {"INPUT": pts, **one_cell, "DUPLICATES": "max",
                                      "OUTPUT": tmp_path / "m.tif"})
    assert read(out["OUTPUT"])[0][0, 0] == 8.0
    with pytest.raises(InputDataError, match="different Z"):
        toolbox.run("dem:idw", {"INPUT": pts, "CELL_SIZE": 10, "DUPLICATES": "error",
                                "OUTPUT": tmp_path / "e.tif"})
    assert not (tmp_path / "e.tif").exists()
    # a tolerance merges points closer than it in plan; breakline ends follow the merge
    near = write_points(tmp_path / "near.gpkg", xy[:4] + [[0, 0], [0.03, 0], [0, 0], [0, 0]],
                        z[:4])
    line = gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 10.01, Y0, 2.0),
                                                          (X0, Y0 + 10, 3.0)])], crs=CRS)
    line.to_file(tmp_path / "bl.gpkg")
    out = toolbox.run("dem:tin_linear", {"INPUT": near, "BREAKLINES": tmp_path / "bl.gpkg",
                                         "DUPLICATE_TOLERANCE": 0.05, "CELL_SIZE": 1,
                                         "OUTPUT": tmp_path / "t.tif"})
    stats = out["STATISTICS"]
    assert stats["duplicates"]["duplicate_groups"] == 2 and stats["points_used"] == 4
    assert stats["breakline_segments"] == 1


def test_bad_parameters_name_the_parameter(data, tmp_path):
    out = tmp_path / "x.tif"
    cases = [
        ({"CELL_SIZE": 5}, "INPUT is required"),
        ({"INPUT": data["plane"], "CELL_SIZE": 0}, "CELL_SIZE must be > 0, got 0"),
        ({"INPUT": data["plane"], "CELL_SIZE": -2}, "CELL_SIZE must be > 0, got -2"),
        ({"INPUT": data["plane"]}, "CELL_SIZE is required"),
        ({"INPUT": data["plane"], "CELL_SIZE": 5, "TILE_SIZE": 100}, "TILE_SIZE must be a multiple"),
        ({"INPUT": data["plane"], "CELL_SIZE": 5, "SECTORS": 4}, "RADIUS is required"),
        ({"INPUT": data["plane"], "CELL_SIZE": 5, "NEIGHBOURS": 4, "MIN_NEIGHBOURS": 6},
         "MIN_NEIGHBOURS must be <= NEIGHBOURS"),
        ({"INPUT": data["plane"], "CELL_SIZE": 5, "POWER": 0}, "POWER must be > 0"),
    ]
    for params, message in cases:
        with pytest.raises(ParameterError, match=message):
            toolbox.run("dem:idw", params | {"OUTPUT": out})
    with pytest.raises(ParameterError, match="NEIGHBOURS must be >= 10, got 8"):
        toolbox.run("dem:cubic", {"INPUT": data["plane"], "CELL_SIZE": 5, "NEIGHBOURS": 8,
                                  "OUTPUT": out})
    with pytest.raises(ParameterError, match="CELL_SIZE must not be given with TEMPLATE"):
        tpl = write_raster(tmp_path / "t.tif", np.zeros((4, 4), "float32"),
                           Affine(1, 0, X0, 0, -1, Y0), CRS)
        toolbox.run("dem:idw", {"INPUT": data["plane"], "CELL_SIZE": 5, "TEMPLATE": tpl,
                                "OUTPUT": out})
    assert not out.exists()


def test_size_guard_refuses_before_any_work(data, tmp_path, monkeypatch):
    from toolbox.runner import validate

    big = f"{X0},{Y0},{X0 + 100000},{Y0 + 100000}"
    # with an extent the guard runs at validation, before the data are read
    with pytest.raises(ParameterError, match=r"CELL_SIZE 0.1 gives a 1000000 x 1000000 grid"):
        validate("dem:idw", {"INPUT": data["plane"], "CELL_SIZE": 0.1, "EXTENT": big,
                             "OUTPUT": tmp_path / "g.tif"})
    with pytest.raises(ParameterError, match="over the limit of 1,000 cells"):
        toolbox.run("dem:quadratic", {"INPUT": data["plane"], "CELL_SIZE": 5, "MAX_CELLS": 1000,
                                      "OUTPUT": tmp_path / "g.tif"})
    monkeypatch.setenv("TOOLBOX_MAX_CELLS", "500")
    with pytest.raises(ParameterError, match="over the limit of 500 cells"):
        toolbox.run("dem:nearest", {"INPUT": data["plane"], "CELL_SIZE": 5,
                                    "OUTPUT": tmp_path / "g.tif"})
    assert not (tmp_path / "g.tif").exists()


def test_bad_input_data(tmp_path):
    xy = np.array([[X0, Y0], [X0 + 10, Y0], [X0, Y0 + 10], [X0 + 10, Y0 + 10], [X0 + 5, Y0 + 3]])
    few = write_points(tmp_path / "few.gpkg", xy, np.arange(5.0))
    with pytest.raises(InputDataError, match="dem:cubic needs at least 10 distinct data points, "
                                             "got 5"):
        toolbox.run("dem:cubic", {"INPUT": few, "CELL_SIZE": 1, "OUTPUT": tmp_path / "a.tif"})
    nan = write_points(tmp_path / "nan.gpkg", xy, np.array([1.0, np.nan, 2, 3, 4]),
                       z_in_geometry=False)
    with pytest.raises(InputDataError, match="NaN/inf"):
        toolbox.run("dem:idw", {"INPUT": nan, "Z_FIELD": "h", "CELL_SIZE": 1,
                                "OUTPUT": tmp_path / "b.tif"})
    empty = gpd.GeoDataFrame({"h": []}, geometry=gpd.GeoSeries([], crs=CRS))
    empty.to_file(tmp_path / "empty.gpkg", layer="points")
    with pytest.raises(InputDataError, match="no features"):
        toolbox.run("dem:idw", {"INPUT": tmp_path / "empty.gpkg", "CELL_SIZE": 1,
                                "OUTPUT": tmp_path / "c.tif"})
    flat = write_points(tmp_path / "no_z.gpkg", xy, np.arange(5.0), z_in_geometry=False)
    with pytest.raises(InputDataError, match="no Z"):
        toolbox.run("dem:idw", {"INPUT": flat, "CELL_SIZE": 1, "OUTPUT": tmp_path / "d.tif"})
    line = write_points(tmp_path / "line.gpkg", np.column_stack([X0 + np.arange(5.0),
                                                                 Y0 + np.arange(5.0)]),
                        np.arange(5.0))
    with pytest.raises(InputDataError, match="collinear"):
        toolbox.run("dem:idw", {"INPUT": line, "CELL_SIZE": 1, "OUTPUT": tmp_path / "e.tif"})
    other = write_points(tmp_path / "utm.gpkg", xy, np.arange(5.0), crs="EPSG:32632")
    with pytest.raises(InputDataError, match="EPSG:32632.*EPSG:3003|EPSG:3003.*EPSG:32632"):
        toolbox.run("dem:idw", {"INPUT": few, "BREAKLINES": None, "LINES": _lines(tmp_path),
                                "CELL_SIZE": 1, "CRS": "EPSG:32632", "OUTPUT": tmp_path / "f.tif"})
    with pytest.raises(InputDataError, match="reproject"):
        toolbox.run("dem:idw", {"INPUT": other, "LINES": _lines(tmp_path), "CELL_SIZE": 1,
                                "OUTPUT": tmp_path / "g.tif"})
    assert not list(tmp_path.glob("*.tif"))


def _lines(tmp_path):
    path = tmp_path / "lines.gpkg"
    if not path.exists():
        gpd.GeoDataFrame(geometry=[shapely.LineString([(X0, Y0, 1), (X0 + 9, Y0 + 4, 2)])],
                         crs=CRS).to_file(path)
    return path


# -- quality report, CLI --------------------------------------------------------------------
def test_quality_report_is_written(data, tmp_path):
    out = toolbox.run("dem:quadratic", {"INPUT": data["plane"], "CELL_SIZE": 10,
                                        "OUTPUT": tmp_path / "q.tif",
                                        "QUALITY": tmp_path / "q.json"})
    report = json.loads((tmp_path / "q.json").read_text())
    cv = report["methods"]["quadratic"]
    assert cv["points"] == 1504 and cv["rmse"] < 1e-9 and cv["hull_vertices_not_predicted"] == 4
    assert cv["predicted"] == 1500 and out["STATISTICS"]["cross_validation"]["rmse"] == cv["rmse"]


def test_cli_runs_and_reports_errors(data, tmp_path):
    ok = subprocess.run([sys.executable, "-m", "toolbox.cli", "-q", "run", "dem:idw",
                         "--INPUT", str(data["plane"]), "--CELL_SIZE", "10", "--scheduler",
                         "local", "--OUTPUT", str(tmp_path / "cli.tif")],
                        capture_output=True, text=True, timeout=300)
    assert ok.returncode == 0, ok.stderr
    outputs = json.loads(ok.stdout)
    assert outputs["STATISTICS"]["cells"]["executor"].startswith("local threads")
    bad = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "dem:idw", "--INPUT",
                          str(data["plane"]), "--CELL_SIZE", "-1", "--OUTPUT",
                          str(tmp_path / "bad.tif")], capture_output=True, text=True,
                         timeout=300)
    assert bad.returncode == 2 and "CELL_SIZE must be > 0, got '-1'" in bad.stderr
