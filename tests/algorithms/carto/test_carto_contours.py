"""carto:contours: vertices exactly on the level of the bilinear DEM surface / the TIN planes
(plane and cone, checked with scipy interpolators), tiles stitched into the untiled lines, no
crossing and no leaving the cell band after smoothing on the real demo DEM, agreement with
gdal_contour, index flags and the embedded style."""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import xml.etree.ElementTree as ET

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely
from affine import Affine
from scipy.interpolate import LinearNDInterpolator, RegularGridInterpolator
from scipy.spatial import Delaunay

import toolbox
from toolbox.cartography.contours import TRACERS, dem_contours, smooth_contours, tin_contours
from toolbox.demo.samples.terrain import CRS, terrain
from toolbox.raster.writer import write_raster

X0, Y0, CELL = 1_688_000.0, 4_800_000.0, 2.0


def write_dem(path, z, cell=CELL):
    write_raster(path, z.astype("float64"), Affine(cell, 0, X0, 0, -cell, Y0), CRS,
                 nodata=-9999.0)
    return path


def centres(rows, cols, cell=CELL):
    xc = X0 + (np.arange(cols) + 0.5) * cell
    yc = Y0 - (np.arange(rows) + 0.5) * cell
    return np.meshgrid(xc, yc)


def bilinear(z, cell=CELL):
    """Independent oracle: scipy's bilinear interpolator through the cell centres."""
    rows, cols = z.shape
    xc = X0 + (np.arange(cols) + 0.5) * cell
    yc = Y0 - (np.arange(rows) + 0.5) * cell
    f = RegularGridInterpolator((yc[::-1], xc), z[::-1], bounds_error=False, fill_value=None)
    return lambda xy: f(np.column_stack([xy[:, 1], xy[:, 0]]))


def read_contours(path):
    return gpd.read_file(path, layer="contours")


def test_plane_contours_are_exact_and_straight(tmp_path):
    x, y = centres(40, 50)
    z = 300.0 + 0.3 * (x - X0) - 0.2 * (y - Y0)
    out = tmp_path / "c.gpkg"
    result = toolbox.run("carto:contours", {"INPUT": write_dem(tmp_path / "p.tif", z),
                                            "INTERVAL": 2.0, "OUTPUT": out})
    frame = read_contours(out)
    levels = np.arange(np.ceil(z.min() / 2) * 2, z.max(), 2.0)
    assert sorted(frame["elev"]) == list(levels)  # one line per level
    assert result["STATISTICS"]["lines"] == len(levels)
    for geom, level in zip(frame.geometry, frame["elev"]):
        xyz = shapely.get_coordinates(geom, include_z=True)
        assert np.all(xyz[:, 2] == level)
        np.testing.assert_allclose(300.0 + 0.3 * (xyz[:, 0] - X0) - 0.2 * (xyz[:, 1] - Y0),
                                   level, atol=1e-6)
        # higher ground on the right: the gradient (0.3, -0.2) points right of the direction
        d = xyz[-1, :2] - xyz[0, :2]
        assert d[0] * -0.2 - d[1] * 0.3 < 0
    assert frame.geometry.iloc[0].has_z


def test_cone_contours_lie_on_the_bilinear_surface(tmp_path):
    x, y = centres(60, 60)
    r = np.hypot(x - (X0 + 60), y - (Y0 - 60))
    z = 400.0 - 0.5 * r
    contours = dem_contours(z, [395.0, 390.0, 385.0, 380.0], X0 + 1, Y0 - 1, CELL, -CELL, tile=17)
    oracle = bilinear(z)
    for c in contours:
        np.testing.assert_allclose(oracle(c.xy), c.level, atol=1e-9)
    rings = [c for c in contours if c.closed]
    assert sorted(c.level for c in contours) == [380.0, 385.0, 390.0, 395.0]  # one ring each
    assert len(rings) == 4
    for c in rings:  # and each near its circle (linear interpolation of r along cell edges)
        radius = np.hypot(c.xy[:, 0] - (X0 + 60), c.xy[:, 1] - (Y0 - 60))
        expected = (400.0 - c.level) / 0.5
        assert np.abs(radius - expected).max() < CELL**2 / (8 * (expected - CELL)) + 1e-9


def test_tin_contours_are_exact_and_chained(tmp_path):
    rng = np.random.default_rng(3)
    xy = rng.uniform(-50, 50, (400, 2))
    xy = np.vstack([xy, [[0, 0]]])
    z = 100.0 - 0.4 * np.hypot(xy[:, 0], xy[:, 1])
    tri = Delaunay(xy)
    xyz = np.column_stack([xy + [X0, Y0], z])
    levels = [95.0, 90.0, 85.0]
    contours = tin_contours(xyz, tri.simplices, levels)
    oracle = LinearNDInterpolator(tri, z)  # scipy's own piecewise-linear surface
    for c in contours:
        np.testing.assert_allclose(oracle(c.xy - [X0, Y0]), c.level, atol=1e-9)
    assert [c.level for c in contours if c.closed] == levels  # whole rings around the apex
    for c in contours:  # higher ground (the apex) on the right of closed rings: clockwise
        if c.closed:
            assert shapely.is_ccw(shapely.linearrings(c.xy)) is np.False_


def test_contours_from_a_tin_geopackage(tmp_path):
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 100, (300, 2)) + [X0, Y0]
    z = 300.0 + 0.1 * (xy[:, 0] - X0) + 0.05 * (xy[:, 1] - Y0)
    points = gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], z), crs=CRS)
    points.to_file(tmp_path / "pts.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg", "OUTPUT": tmp_path / "t.gpkg"})
    out = tmp_path / "c.gpkg"
    toolbox.run("carto:contours", {"TIN": tmp_path / "t.gpkg", "INTERVAL": 1.0, "OUTPUT": out})
    frame = read_contours(out)
    assert len(frame) > 5 and frame.crs.to_epsg() == 3003
    for geom, level in zip(frame.geometry, frame["elev"]):
        c = shapely.get_coordinates(geom)
        np.testing.assert_allclose(300 + 0.1 * (c[:, 0] - X0) + 0.05 * (c[:, 1] - Y0), level,
                                   atol=1e-6)


@pytest.mark.parametrize("tracer", TRACERS)
def test_tiles_stitch_into_the_untiled_lines(tracer):
    z, t = terrain()
    z = z.astype("float64")
    args = (np.arange(290.0, 345.0, 5.0), t.c + 2, t.f - 2, 4.0, -4.0)
    whole = dem_contours(z, *args, tracer=tracer)
    tiled = dem_contours(z, *args, tile=37, tracer=tracer)
    assert len(tiled) == len(whole) > 100
    geoms = {(c.level, shapely.normalize(shapely.linestrings(c.xy)).wkb) for c in whole}
    for c in tiled:  # the same lines: nothing broken at tile edges, nothing doubled
        assert (c.level, shapely.normalize(shapely.linestrings(c.xy)).wkb) in geoms


@pytest.mark.parametrize("tracer", TRACERS)
def test_blocks_trace_only_their_levels_even_at_node_heights(tracer):
    """Each block traces only the levels its heights span; levels exactly at node heights (a
    block's lowest or highest node) must still give every line contourpy gives on the whole
    grid (traced just below the level, as the kernel does)."""
    import contourpy

    rng = np.random.default_rng(7)
    z = rng.integers(0, 6, size=(23, 31)).astype("float64")  # heights on the levels themselves
    levels = np.arange(0.0, 6.0)
    tiled = dem_contours(z, levels, 0.0, 0.0, 1.0, 1.0, tile=4, tracer=tracer)
    gen = contourpy.contour_generator(np.arange(31.0), np.arange(23.0), z)
    for level in levels:
        expected = sum(shapely.length(shapely.linestrings(line)) for line in
                       gen.lines(level - 1024 * np.spacing(max(abs(level), 1e-300))))
        got = sum(shapely.length(shapely.linestrings(c.xy)) for c in tiled if c.level == level)
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-9), level


@pytest.mark.parametrize("tracer", TRACERS)
def test_tiles_stitch_around_nodata_holes(tracer):
    z, t = terrain()
    z = z.astype("float64")
    z[100:160, 70:75] = np.nan  # a hole across the tile edge at column 74
    z[221:223, 30:200] = np.nan  # a strip on the tile edge at row 222
    args = (np.arange(290.0, 345.0, 5.0), t.c + 2, t.f - 2, 4.0, -4.0)
    whole = dem_contours(z, *args, tracer=tracer)
    tiled = dem_contours(z, *args, tile=37, tracer=tracer)
    assert len(tiled) == len(whole)
    geoms = {(c.level, shapely.normalize(shapely.linestrings(c.xy)).wkb) for c in whole}
    assert all((c.level, shapely.normalize(shapely.linestrings(c.xy)).wkb) in geoms
               for c in tiled)


def test_both_tracers_give_the_same_stitched_lines():
    """contourpy (small grids) and the one-pass kernel (large ones): the same lines after
    stitching and mapping, holes and a strip of nodata on a tile edge included (vertices to
    1e-6 m: the two interpolate in a different arithmetic order)."""
    z, t = terrain()
    z = z.astype("float64")
    z[100:160, 70:75] = np.nan
    z[221:223, 30:200] = np.nan
    args = (np.arange(290.0, 345.0, 2.5), t.c + 2, t.f - 2, 4.0, -4.0)

    def lines(tracer):
        out = set()
        for c in dem_contours(z, *args, tile=37, tracer=tracer):
            g = shapely.normalize(shapely.linestrings(c.xy))  # rings from one vertex
            out.add((c.level, tuple(map(tuple, np.round(shapely.get_coordinates(g), 6)))))
        return out

    kernel = lines("kernel")
    assert len(kernel) > 200
    assert lines("contourpy") == kernel


def test_few_levels_trace_without_numba_many_with_the_kernel(tmp_path):
    """The 5 % rule (issue 26): a DEM with few levels is traced by contourpy and its process
    never imports numba (about 0.65 CPU s); many levels on a large grid take the kernel. Both
    runs in fresh processes, with numba's JIT (``TOOLBOX_AOT=0``; the kernel compiled ahead of
    time is tests/toolbox/test_aot.py's); the lines compared on the same DEM."""
    import os
    import sys

    rng = np.random.default_rng(5)
    from scipy.ndimage import gaussian_filter

    z = 300.0 + gaussian_filter(rng.normal(size=(700, 700)), 25) * 4000.0
    dem = write_dem(tmp_path / "d.tif", z)
    code = ("import sys, toolbox; s = toolbox.run('carto:contours', {{'INPUT': {dem!r}, "
            "'INTERVAL': {interval}, 'OUTPUT': {out!r}}})['STATISTICS']; "
            "print(s['tracer'], s['levels'], 'numba' in sys.modules)")
    runs = {}
    for interval in (20.0, 1.0):
        out = str(tmp_path / f"c{interval}.gpkg")
        proc = subprocess.run([sys.executable, "-c", code.format(dem=str(dem), interval=interval,
                                                                  out=out)],
                              capture_output=True, text=True, check=True,
                              env=os.environ | {"TOOLBOX_AOT": "0"})
        runs[interval] = proc.stdout.split()
    few, many = runs[20.0], runs[1.0]
    assert few[0] == "contourpy" and few[2] == "False" and int(few[1]) >= 3, few
    assert many[0] == "kernel" and many[2] == "True" and int(many[1]) > 100, many
    ours = read_contours(tmp_path / "c20.0.gpkg")
    levels = sorted(set(ours["elev"]))
    kernel = dem_contours(z, levels, X0 + 1, Y0 - 1, CELL, -CELL, tile=512, tracer="kernel")
    assert len(ours) == len(kernel)
    assert float(ours.geometry.length.sum()) == pytest.approx(
        sum(float(shapely.length(shapely.linestrings(c.xy))) for c in kernel), rel=1e-12)


def test_a_dem_read_once_gives_the_lines_of_one_read_by_blocks(tmp_path, monkeypatch):
    """A small DEM on local threads is read whole and its blocks traced from memory; a big one
    (or one on a cluster) is read by blocks twice: the same range, levels and lines, bit for
    bit, holes and a block edge strip of nodata included."""
    from toolbox.cartography import contour_io

    z, t = terrain()
    z = z.astype("float64")
    z[100:160, 70:75] = np.nan
    z[221:223, 30:200] = np.nan
    path = tmp_path / "holes.tif"
    write_raster(path, z, t, CRS, nodata=-9999.0)
    reads = []
    trace_block = contour_io.trace_block
    monkeypatch.setattr(contour_io, "trace_block", lambda task: reads.append(task) or
                        trace_block(task))
    once = contour_io.raster_contours(path, 1, 2.5, 0.0, tile_size=37)
    assert not reads  # every block from memory
    monkeypatch.setattr(contour_io, "IN_MEMORY_CELLS", 0)
    blocks = contour_io.raster_contours(path, 1, 2.5, 0.0, tile_size=37)
    assert len(reads) == once.stats["tiles"] > 1
    assert (once.stats["z_min"], once.stats["z_max"]) == (np.nanmin(z), np.nanmax(z))
    assert once.stats == blocks.stats and np.array_equal(once.levels, blocks.levels)
    assert len(once.contours) == len(blocks.contours) > 0
    assert all(a.level == b.level and np.array_equal(a.xy, b.xy)
               for a, b in zip(once.contours, blocks.contours, strict=True))


@pytest.fixture(scope="module")
def demo_dem(tmp_path_factory):
    z, transform = terrain()
    path = tmp_path_factory.mktemp("dem") / "dem.tif"
    write_raster(path, z, transform, CRS, nodata=-9999.0)
    return path, z.astype("float64"), transform


def test_smoothed_contours_never_cross_nor_leave_their_band(demo_dem, tmp_path):
    path, z, t = demo_dem
    out = tmp_path / "smooth.gpkg"
    res = toolbox.run("carto:contours", {"INPUT": path, "INTERVAL": 2.0, "SMOOTHING": 3,
                                         "TILE_SIZE": 100, "OUTPUT": out})
    frame = read_contours(out)
    geoms = frame.geometry.values
    left, right = shapely.STRtree(geoms).query(geoms, predicate="intersects")
    assert (left == right).all(), "two contours touch or cross"
    # the band: every vertex and segment midpoint lies in a grid square whose four corner
    # heights bracket the line's level
    x0, y0 = t.c + 2.0, t.f - 2.0
    for geom, level in zip(geoms, frame["elev"]):
        xy = shapely.get_coordinates(geom)
        pts = np.vstack([xy, 0.5 * (xy[1:] + xy[:-1])])
        col = np.clip(np.floor((pts[:, 0] - x0) / 4.0).astype(int), 0, z.shape[1] - 2)
        row = np.clip(np.floor((y0 - pts[:, 1]) / 4.0).astype(int), 0, z.shape[0] - 2)
        corners = np.stack([z[row, col], z[row + 1, col], z[row, col + 1],
                            z[row + 1, col + 1]])
        assert (corners.min(axis=0) <= level + 1e-9).all()
        assert (corners.max(axis=0) >= level - 1e-9).all()
    # smoothing did something: more vertices than the traced lines
    plain = dem_contours(z, sorted(set(frame["elev"])), x0, y0, 4.0, -4.0)
    assert res["STATISTICS"]["vertices"] > 1.5 * sum(len(c.xy) for c in plain)


def test_smoothing_reverts_lines_that_would_touch():
    # two close parallel zigzags: corner cutting of one would reach the other
    a = np.array([[0.0, 0.0], [1.0, 0.9], [2.0, 0.0], [3.0, 0.9], [4.0, 0.0]])
    b = a + [0.0, 0.35]
    from toolbox.cartography.contours import Contour

    lines, reverted = smooth_contours([Contour(1.0, a), Contour(2.0, b)], 1)
    assert not shapely.intersects(shapely.linestrings(lines[0].xy),
                                  shapely.linestrings(lines[1].xy))
    assert reverted in (0, 2)


def test_index_contours_and_embedded_style(demo_dem, tmp_path):
    out, qml = tmp_path / "c.gpkg", tmp_path / "c.qml"
    toolbox.run("carto:contours", {"INPUT": demo_dem[0], "INTERVAL": 5.0, "INDEX_EVERY": 5,
                                   "OUTPUT": out, "STYLE": qml})
    frame = read_contours(out)
    assert ((frame["elev"] % 25 == 0) == (frame["index"] == 1)).all()
    assert frame["index"].sum() > 0 and (frame["index"] == 0).sum() > 0
    assert pyogrio.read_info(out, layer="contours")["geometry_type"] == "LineString Z"
    with sqlite3.connect(out) as db:
        rows = db.execute("SELECT f_table_name, styleQML, styleSLD, useAsDefault, "
                          "f_geometry_column FROM layer_styles").fetchall()
    assert len(rows) == 1
    name, style, sld, default, geom = rows[0]
    assert name == "contours" and default == 1 and geom == "geom"
    assert qml.read_text() == style
    # QML: rule-based on index, index contours heavier, curved labels (placement 3) of elev
    root = ET.fromstring(style.split("\n", 1)[1])
    rules = {r.get("key"): r for r in root.iter("rule")}
    assert rules["index"].get("filter") == '"index" = 1' and rules["normal"].get("filter") == \
        "ELSE"
    widths = {s.get("name"): float(s.find(".//Option[@name='line_width']").get("value"))
              for s in root.iter("symbol")}
    assert widths[rules["index"].get("symbol")] > widths[rules["normal"].get("symbol")]
    assert root.find("labeling/settings/placement").get("placement") == "3"
    assert "elev" in root.find("labeling/settings/text-style").get("fieldName")
    # SLD: the same two rules, the index one heavier and labelled along the line
    ns = {"sld": "http://www.opengis.net/sld", "ogc": "http://www.opengis.net/ogc"}
    doc = ET.fromstring(sld.split("\n", 1)[1])
    sld_rules = {r.find("sld:Name", ns).text: r for r in doc.iterfind(".//sld:Rule", ns)}
    assert set(sld_rules) == {"index", "normal"}
    width = {k: float(r.find(".//sld:CssParameter[@name='stroke-width']", ns).text)
             for k, r in sld_rules.items()}
    assert width["index"] > width["normal"]
    index_filter = sld_rules["index"].find("ogc:Filter/ogc:PropertyIsEqualTo", ns)
    assert index_filter.find("ogc:PropertyName", ns).text == "index"
    assert sld_rules["index"].find(
        "sld:TextSymbolizer/sld:Label/ogc:PropertyName", ns).text == "elev"
    assert sld_rules["index"].find(".//sld:LinePlacement", ns) is not None
    assert sld_rules["normal"].find("sld:TextSymbolizer", ns) is None


def test_needs_exactly_one_surface(demo_dem, tmp_path):
    from toolbox.errors import ParameterError

    with pytest.raises(ParameterError, match="exactly one"):
        toolbox.run("carto:contours", {"OUTPUT": tmp_path / "c.gpkg"})


@pytest.mark.skipif(shutil.which("gdal_contour") is None,
                    reason="gdal_contour not found: install gdal-bin to compare with GDAL")
def test_agrees_with_gdal_contour(demo_dem, tmp_path):
    path, z, t = demo_dem
    ref = tmp_path / "gdal.gpkg"
    subprocess.run(["gdal_contour", "-q", "-i", "5", "-a", "elev", str(path), str(ref)],
                   check=True)
    out = tmp_path / "ours.gpkg"
    toolbox.run("carto:contours", {"INPUT": path, "INTERVAL": 5.0, "TILE_SIZE": 128,
                                   "OUTPUT": out})
    from toolbox.cartography.compare import contour_agreement

    gdal = gpd.read_file(ref)
    # gdal_contour runs its lines on to the raster edge (half a cell past the outer centres)
    rows, cols = z.shape
    centre_box = (t.c + 2, t.f - 4 * rows + 2, t.c + 4 * cols - 2, t.f - 2)
    agree = contour_agreement(read_contours(out), gdal, tolerance=0.001, clip=centre_box)
    assert agree["ours_matched"] > 0.99 and agree["reference_matched"] > 0.99, agree
    assert set(agree["levels"]) == set(gdal["elev"])
    # the same length as gdal_contour's lines inside the cell-centre box: 0.2 % in all
    ours = read_contours(out)
    assert set(ours["elev"]) == set(gdal["elev"])
    box = shapely.box(*centre_box)
    ref_length = {level: shapely.length(shapely.intersection(
        gdal.geometry.values[np.asarray(gdal["elev"] == level)], box)).sum()
        for level in set(gdal["elev"])}
    our_length = {level: shapely.length(ours.geometry.values[np.asarray(ours["elev"] == level)]
                                        ).sum() for level in ref_length}
    assert sum(our_length.values()) == pytest.approx(sum(ref_length.values()), rel=0.002)


@pytest.mark.parametrize("ext", [".shp", ".fgb"])
def test_a_one_layer_output_gets_its_style_beside_it(tmp_path, ext):
    """A Shapefile or FlatGeobuf has no style table: the contours' style is written beside it
    as <stem>.qml / <stem>.sld (QGIS loads <stem>.qml with the file), the QML the GeoPackage
    embeds; it was not written at all (the layer opened in one plain symbol). An existing
    <stem>.qml needs --overwrite, as the output does."""
    from toolbox.errors import OutputExistsError

    x, y = centres(30, 30)
    dem = write_dem(tmp_path / "p.tif", 300.0 + 0.3 * (x - X0))
    toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 2.0, "OUTPUT": tmp_path / "g.gpkg"})
    with sqlite3.connect(tmp_path / "g.gpkg") as db:
        embedded = db.execute("SELECT styleQML FROM layer_styles").fetchone()[0]
    out = tmp_path / f"c{ext}"
    toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 2.0, "OUTPUT": out})
    assert (tmp_path / "c.qml").read_text(encoding="utf-8") == embedded
    ET.fromstring((tmp_path / "c.sld").read_text(encoding="utf-8"))
    for part in tmp_path.glob("c.*"):  # the output gone, its style left
        if part.suffix not in (".qml", ".sld"):
            part.unlink()
    with pytest.raises(OutputExistsError):
        toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 2.0, "OUTPUT": out})
