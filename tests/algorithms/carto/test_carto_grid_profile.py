"""carto:grid (step from the scale, nodes on multiples of the step, labels at the frame) and
carto:profile (heights equal scipy's bilinear interpolation of the DEM, contour crossings,
perpendicular sections)."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely
from scipy.interpolate import RegularGridInterpolator

import toolbox
from toolbox.demo.samples.terrain import CRS, terrain
from toolbox.raster.writer import write_raster

EXTENT = "1687520,4798980,1689110,4800340 [EPSG:3003]"


def test_grid_lines_every_500_m_at_1_5000(tmp_path):
    out = tmp_path / "g.gpkg"
    res = toolbox.run("carto:grid", {"EXTENT": EXTENT, "SCALE": 5000, "STYLE": "lines",
                                     "OUTPUT": out})
    assert res["STATISTICS"]["ground_step"] == 500.0  # 10 cm on paper at 1:5000
    grid = gpd.read_file(out, layer="grid")
    xs = sorted(grid[grid.kind == "x"].value)
    ys = sorted(grid[grid.kind == "y"].value)
    assert xs == [1688000.0, 1688500.0, 1689000.0]
    assert ys == [4799000.0, 4799500.0, 4800000.0]
    for geom, kind, value in zip(grid.geometry, grid.kind, grid.value):
        c = shapely.get_coordinates(geom)
        assert np.all(c[:, 0 if kind == "x" else 1] == value)
        # full lines from frame edge to frame edge
        assert np.ptp(c[:, 1 if kind == "x" else 0]) == (1360 if kind == "x" else 1590)
    labels = gpd.read_file(out, layer="grid_labels")
    assert len(labels) == 2 * (3 + 3)
    bottom = labels[(labels.axis == "x") & (labels.edge == "bottom")]
    assert list(bottom.text) == ["1688000", "1688500", "1689000"]
    assert np.allclose(bottom.geometry.y, 4798980) and grid.crs.to_epsg() == 3003
    left = labels[(labels.axis == "y") & (labels.edge == "left")]
    assert list(left.text) == ["4799000", "4799500", "4800000"]


def test_grid_crosses_at_1_1000_with_sheets(tmp_path):
    sheets = gpd.GeoDataFrame({"sheet_no": ["A", "B"]}, geometry=[
        shapely.box(1688000, 4799000, 1688250, 4799200),
        shapely.box(1688250, 4799000, 1688500, 4799200)], crs=CRS)
    sheets.to_file(tmp_path / "sheets.gpkg")
    out = tmp_path / "g.gpkg"
    toolbox.run("carto:grid", {"SHEETS": tmp_path / "sheets.gpkg", "SHEET_ID": "sheet_no",
                               "SCALE": 1000, "CROSS_SIZE": 10, "OUTPUT": out})
    grid = gpd.read_file(out, layer="grid")
    # 100 m step; sheet A: x 1688000..1688200, y 4799000..4799200 -> 3 x 3 nodes
    assert (grid.sheet == "A").sum() == 9 and (grid.sheet == "B").sum() == 9
    inner = grid[(grid.sheet == "A")].geometry
    centres = {(round(g.centroid.x), round(g.centroid.y)) for g in inner
               if g.length == pytest.approx(20.0)}  # full crosses: 2 arms of 10 m (1 cm)
    assert (1688100, 4799100) in centres


@pytest.fixture(scope="module")
def dem(tmp_path_factory):
    z, transform = terrain()
    path = tmp_path_factory.mktemp("p") / "dem.tif"
    write_raster(path, z, transform, CRS, nodata=-9999.0)
    rows, cols = z.shape
    xc = transform.c + (np.arange(cols) + 0.5) * transform.a
    yc = transform.f + (np.arange(rows) + 0.5) * transform.e
    oracle = RegularGridInterpolator((yc[::-1], xc), z[::-1].astype("float64"))
    return path, lambda x, y: oracle(np.column_stack([y, x]))


def write_line(tmp_path, coords):
    path = tmp_path / "line.gpkg"
    gpd.GeoDataFrame({"name": ["axis"]}, geometry=[shapely.linestrings(coords)],
                     crs=CRS).to_file(path)
    return path


def test_profile_heights_equal_the_dem(dem, tmp_path):
    path, oracle = dem
    line = write_line(tmp_path, [[1687700, 4799000], [1688300, 4799600], [1688900, 4799700]])
    out, plot = tmp_path / "p.gpkg", tmp_path / "p.png"
    toolbox.run("carto:profile", {"INPUT": line, "DEM": path, "STEP": 25.0, "OUTPUT": out,
                                  "PLOT": plot})
    pts = gpd.read_file(out, layer="profile_points")
    length = 600 * np.sqrt(2) + np.hypot(600, 100)
    expected = np.append(np.arange(0, length, 25.0), length)
    np.testing.assert_allclose(pts.chainage, expected, atol=1e-9)
    np.testing.assert_allclose(pts.z, oracle(pts.geometry.x.values, pts.geometry.y.values),
                               atol=1e-9)
    assert plot.read_bytes()[:4] == b"\x89PNG"
    lines = gpd.read_file(out, layer="profile_lines")
    assert len(lines) == 1 and lines["length"].iloc[0] == pytest.approx(length)


def test_sections_are_perpendicular_and_centred(dem, tmp_path):
    path, oracle = dem
    line = write_line(tmp_path, [[1687800, 4799200], [1688800, 4799200]])  # eastward axis
    out = tmp_path / "s.gpkg"
    toolbox.run("carto:profile", {"INPUT": line, "DEM": path, "MODE": "sections",
                                  "SPACING": 250, "HALF_WIDTH": 60, "STEP": 20,
                                  "OUTPUT": out})
    pts = gpd.read_file(out, layer="profile_points")
    assert sorted(set(pts.chainage)) == [0, 250, 500, 750, 1000]
    for ch, group in pts.groupby("chainage"):
        assert np.allclose(group.geometry.x, 1687800 + ch)  # north-south sections
        # offsets -60..60, negative on the left (north) of the eastward axis
        np.testing.assert_allclose(group["distance"], np.arange(-60, 61, 20))
        np.testing.assert_allclose(group.geometry.y, 4799200 - group["distance"])
        np.testing.assert_allclose(group.z, oracle(group.geometry.x.values,
                                                   group.geometry.y.values), atol=1e-9)


def test_profile_at_contour_crossings(dem, tmp_path):
    path, oracle = dem
    contours = tmp_path / "c.gpkg"
    toolbox.run("carto:contours", {"INPUT": path, "INTERVAL": 5.0, "OUTPUT": contours})
    line = write_line(tmp_path, [[1687700, 4799000], [1688300, 4799600]])
    out = tmp_path / "p.gpkg"
    toolbox.run("carto:profile", {"INPUT": line, "CONTOURS": contours, "MODE": "contours",
                                  "OUTPUT": out})
    pts = gpd.read_file(out, layer="profile_points")
    assert len(pts) > 5 and (np.diff(pts.chainage) >= 0).all()
    assert set(pts.z) <= set(np.arange(290.0, 345.0, 5.0))
    # each crossing lies on a contour line of its height, and on the profile line
    lines = gpd.read_file(contours, layer="contours")
    for point, z in zip(pts.geometry, pts.z):
        assert lines[lines.elev == z].distance(point).min() < 1e-6
    axis = shapely.linestrings([[1687700, 4799000], [1688300, 4799600]])
    assert max(axis.distance(p) for p in pts.geometry) < 1e-6
    # and the DEM there is close to it (contour chords vs the bilinear surface: < 0.2 m here)
    assert np.abs(oracle(pts.geometry.x.values, pts.geometry.y.values) - pts.z).max() < 0.2
    assert pts.chainage.iloc[0] > 0 and pts.chainage.iloc[-1] < 600 * np.sqrt(2)  # P1, P2 out


def test_profile_needs_a_surface(tmp_path, dem):
    from toolbox.errors import ParameterError

    line = write_line(tmp_path, [[1687700, 4799000], [1688300, 4799600]])
    with pytest.raises(ParameterError, match="DEM or TIN"):
        toolbox.run("carto:profile", {"INPUT": line, "OUTPUT": tmp_path / "p.gpkg"})


def test_profile_on_a_tin_of_a_plane_is_exact(tmp_path):
    rng = np.random.default_rng(11)
    xy = np.vstack([rng.uniform(0, 200, (200, 2)), [[0, 0], [200, 0], [0, 200], [200, 200]]])
    xy = xy + [1688000.0, 4799000.0]
    z = 250.0 + 0.02 * (xy[:, 0] - 1688000) - 0.03 * (xy[:, 1] - 4799000)
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], z), crs=CRS).to_file(
        tmp_path / "pts.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg", "OUTPUT": tmp_path / "t.gpkg"})
    line = write_line(tmp_path, [[1688010, 4799010], [1688190, 4799150]])
    out = tmp_path / "p.gpkg"
    toolbox.run("carto:profile", {"INPUT": line, "TIN": tmp_path / "t.gpkg", "STEP": 7.0,
                                  "OUTPUT": out})
    pts = gpd.read_file(out, layer="profile_points")
    x, y = pts.geometry.x.values, pts.geometry.y.values
    np.testing.assert_allclose(pts.z, 250 + 0.02 * (x - 1688000) - 0.03 * (y - 4799000),
                               atol=1e-6)
    assert len(pts) == int(np.hypot(180, 140) // 7) + 2


# -- sheets of carto:grid: degenerate, invalid, holed and curved polygons ---------------------
X0, Y0 = 1688000.0, 4799000.0  # at 1:100 the grid step is 10 m: lines on multiples of 10


def sheet_box(x0, y0, x1, y1):
    return shapely.box(X0 + x0, Y0 + y0, X0 + x1, Y0 + y1)


def write_sheets(tmp_path, geoms):
    path = tmp_path / "sheets.gpkg"
    gpd.GeoDataFrame({"sheet_no": [chr(65 + i) for i in range(len(geoms))]}, geometry=geoms,
                     crs=CRS).to_file(path)
    return path


def run_grid(sheets, out, style="lines", feedback=None):
    toolbox.run("carto:grid", {"SHEETS": sheets, "SHEET_ID": "sheet_no", "SCALE": 100,
                               "STYLE": style, "OUTPUT": out}, feedback=feedback)
    return gpd.read_file(out, layer="grid")


@pytest.mark.parametrize("geom, says", [
    (None, "has no geometry"), (shapely.Polygon(), "has an empty geometry"),
    (shapely.Polygon([(X0 + 20, Y0 + 20), (X0 + 80, Y0 + 20), (X0 + 50, Y0 + 20)]),
     "has no area")])
def test_grid_refuses_a_sheet_without_area(tmp_path, geom, says):
    from toolbox.errors import ParameterError

    sheets = write_sheets(tmp_path, [sheet_box(20, 20, 80, 80), geom])
    out = tmp_path / "g.gpkg"
    with pytest.raises(ParameterError, match=rf"^SHEETS feature 2 \(sheet 'B'\) {says}"):
        run_grid(sheets, out)
    assert not out.exists()


def test_grid_refusal_of_a_null_sheet_is_one_line_exit_2(tmp_path):
    from conftest import run_cli

    sheets = write_sheets(tmp_path, [None, sheet_box(20, 20, 80, 80)])
    out = tmp_path / "g.gpkg"
    proc = run_cli("run", "carto:grid", "--SHEETS", sheets, "--SCALE", "100", "--OUTPUT", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "SHEETS feature 1" in lines[0] and "no geometry" in lines[0]
    assert "Traceback" not in proc.stderr and not out.exists()


@pytest.mark.parametrize("style", ["lines", "crosses"])
def test_grid_of_a_holed_sheet_is_multilinestrings_clipped_to_it(tmp_path, style):
    import pyogrio

    sheet = sheet_box(20, 20, 80, 80).difference(sheet_box(40, 40, 60, 60))
    out = tmp_path / "g.gpkg"
    grid = run_grid(write_sheets(tmp_path, [sheet]), out, style)
    assert pyogrio.read_info(out, layer="grid")["geometry_type"] == "MultiLineString"
    assert set(grid.geom_type) == {"MultiLineString"}
    for geom in grid.geometry:  # inside the sheet, off the hole
        assert geom.difference(sheet.buffer(1e-6)).length == 0
    if style == "lines":  # 7 + 7 lines of 60 m; x = 50 and y = 50 cross the 20 m hole
        assert len(grid) == 14 and grid.length.sum() == pytest.approx(14 * 60 - 2 * 20)
        middle = grid[(grid.kind == "x") & (grid.value == X0 + 50)].geometry.iloc[0]
        assert len(middle.geoms) == 2  # one feature: the line's two pieces
    else:  # 7 x 7 nodes; the one at the hole's centre has no cross left
        assert len(grid) == 48


def test_grid_of_a_bowtie_sheet_is_repaired_with_a_warning(tmp_path):
    bowtie = shapely.Polygon([(X0 + 20, Y0 + 20), (X0 + 80, Y0 + 80), (X0 + 80, Y0 + 20),
                              (X0 + 20, Y0 + 80)])
    feedback = toolbox.Feedback()
    grid = run_grid(write_sheets(tmp_path, [bowtie]), tmp_path / "g.gpkg", feedback=feedback)
    assert any("SHEETS feature 1 (sheet 'A') is not a valid polygon" in w and "repaired" in w
               for w in feedback.warnings)
    # two triangles of 900 m² meeting at (50, 50): by hand, x lines 20..40 and 60..80 are
    # 60, 40, 20 m long (x = 50 only touches); y lines 30..70 are 20, 40, 60, 40, 20 m long
    # (y = 20 and 80 only touch the corners)
    assert len(grid) == 6 + 5
    assert grid.length.sum() == pytest.approx(2 * (60 + 40 + 20) + 20 + 40 + 60 + 40 + 20)


def test_grid_of_a_curved_sheet_keeps_only_line_pieces(tmp_path):
    """A CurvePolygon circle (r 30 m): the grid lines at its left and right edges only touch
    it (GEOS gives a point there), the others are its chords."""
    import struct

    import pyogrio

    arc = [(X0 + 20, Y0 + 50), (X0 + 80, Y0 + 50), (X0 + 20, Y0 + 50)]
    ring = struct.pack("<BII", 1, 8, 3) + b"".join(struct.pack("<dd", *p) for p in arc)
    sheets = tmp_path / "circle.gpkg"
    pyogrio.raw.write(sheets, geometry=np.array([struct.pack("<BII", 1, 10, 1) + ring],
                                                dtype=object),
                      field_data=[np.array(["A"])], fields=["sheet_no"],
                      geometry_type="Unknown", crs=CRS)
    grid = run_grid(sheets, tmp_path / "g.gpkg")
    assert set(grid.geom_type) == {"MultiLineString"}
    assert sorted(grid[grid.kind == "x"].value - X0) == [30, 40, 50, 60, 70]
    chords = [2 * np.sqrt(30.0 ** 2 - (v - X0 - 50) ** 2) for v in grid[grid.kind == "x"].value]
    np.testing.assert_allclose(grid[grid.kind == "x"].length, chords, atol=0.1)


# -- carto:profile numbers its profiles by input feature and part -----------------------------
def test_profile_lines_are_numbered_by_feature_and_part(dem, tmp_path):
    path, _ = dem
    parts = [[[1687700, 4799000], [1688000, 4799300]], [[1688100, 4799300], [1688100, 4799700]]]
    single = [[1688300, 4799000], [1688300, 4799500]]
    line = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"name": ["none", "two parts", "one"]}, geometry=[
        None, shapely.multilinestrings(parts), shapely.multilinestrings([single])],
        crs=CRS).to_file(line)
    out, feedback = tmp_path / "p.gpkg", toolbox.Feedback()
    toolbox.run("carto:profile", {"INPUT": line, "DEM": path, "STEP": 50.0, "OUTPUT": out},
                feedback=feedback)
    assert any("1 feature(s) without geometry" in w and "row 1, counting from 1" in w
               for w in feedback.warnings)
    lines = gpd.read_file(out, layer="profile_lines")
    assert list(zip(lines.profile, lines.line, lines.part)) == [("2.1", 2, 1), ("2.2", 2, 2),
                                                               ("3", 3, 1)]
    # each part from its own first vertex, its chainage from 0 to its own length
    for geom, coords in zip(lines.geometry, [*parts, single]):
        assert geom.coords[0][:2] == pytest.approx(coords[0])
        assert geom.coords[-1][:2] == pytest.approx(coords[-1])
    np.testing.assert_allclose(lines["length"], [300 * np.sqrt(2), 400, 500])
    pts = gpd.read_file(out, layer="profile_points")
    assert set(zip(pts.profile, pts.line, pts.part)) == {("2.1", 2, 1), ("2.2", 2, 2),
                                                         ("3", 3, 1)}
    assert (pts.groupby("profile").chainage.min() == 0).all()


def test_profile_of_only_null_lines_is_refused(dem, tmp_path):
    from toolbox.errors import InputDataError

    line = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"name": ["none", "empty"]}, geometry=[None, shapely.LineString()],
                     crs=CRS).to_file(line, geometry_type="LineString")
    out = tmp_path / "p.gpkg"
    with pytest.raises(InputDataError, match="INPUT has no line to profile: its 2 feature"):
        toolbox.run("carto:profile", {"INPUT": line, "DEM": dem[0], "OUTPUT": out})
    assert not out.exists()
