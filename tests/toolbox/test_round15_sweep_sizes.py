"""Round 15, sizes and extents at the edges: one-cell-wide DEMs, the outer half cell of a DEM,
empty outputs of algorithms without EXTENT/MASK, a one-row DSM, empty sheet layers."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.raster.writer import write_raster

X0, Y0, CRS = 500_000.0, 4_500_000.0, "EPSG:32632"


def dem(path, z, cell=10.0, nodata=-9999.0):
    z = np.asarray(z, "float32")
    write_raster(path, z, Affine(cell, 0, X0, 0, -cell, Y0), CRS, nodata=nodata)
    return path


def band(path):
    with rasterio.open(path) as ds:
        return ds.read(1)


@pytest.mark.parametrize("shape", [(1, 5), (5, 1)])
def test_slope_of_a_one_cell_wide_plane_is_exact_to_its_ends(tmp_path, shape):
    """A 1 x N (or N x 1) DEM of a plane rising 1 m per 10 m cell: every cell's slope is
    atan(0.1) = 5.71 deg (analytic). The edge extrapolation repeated the edge along both axes
    as soon as one was one cell wide, so the two end cells had half the gradient (2.86 deg),
    and their hillshade and the aspect's magnitude with it."""
    z = (100.0 + np.arange(5.0)).reshape(shape)
    path = dem(tmp_path / "row.tif", z)
    toolbox.run("dem:slope", {"INPUT": path, "OUTPUT": tmp_path / "s.tif"})
    np.testing.assert_allclose(band(tmp_path / "s.tif"), math.degrees(math.atan(0.1)),
                               rtol=1e-6)
    toolbox.run("dem:hillshade", {"INPUT": path, "OUTPUT": tmp_path / "h.tif"})
    assert np.unique(band(tmp_path / "h.tif")).size == 1  # a plane: one grey everywhere


@pytest.mark.skipif(shutil.which("gdaldem") is None, reason="gdaldem not found")
@pytest.mark.parametrize("mode", ["slope", "aspect", "hillshade"])
def test_a_nodata_cell_has_no_slope_as_in_gdaldem(tmp_path, mode):
    """A void (one nodata cell) inside a plane: gdaldem writes nodata at the void and around
    it; the toolbox wrote nodata around it but a slope, aspect and shade at the void itself
    (Horn's weights skip the centre cell)."""
    z = np.add.outer(2.0 * np.arange(7), 3.0 * np.arange(7)) + 100.0
    z[3, 3] = -9999.0
    path = dem(tmp_path / "void.tif", z)
    toolbox.run(f"dem:{mode}", {"INPUT": path, "OUTPUT": tmp_path / "t.tif"})
    subprocess.run(["gdaldem", mode, str(path), str(tmp_path / "g.tif"), "-q"], check=True)
    ours, gdal = band(tmp_path / "t.tif")[1:-1, 1:-1], band(tmp_path / "g.tif")[1:-1, 1:-1]
    nodata = 0 if mode == "hillshade" else -9999.0  # gdaldem leaves its border out
    np.testing.assert_array_equal(ours == nodata, gdal == nodata)
    assert (ours == nodata).sum() == 9
    np.testing.assert_allclose(ours[ours != nodata], gdal[gdal != nodata], atol=1)


def test_an_empty_output_names_what_the_algorithm_has(tmp_path):
    """dem:slope of an all-nodata DEM, dem:aspect of a flat one: the refusal said 'check that
    EXTENT, TEMPLATE, MASK and CELL_SIZE cover the data', none of which these algorithms take
    (gdaldem aspect writes an all-nodata raster for a flat DEM: there is no aspect)."""
    from toolbox.errors import InputDataError

    nodata = dem(tmp_path / "nodata.tif", np.full((6, 6), -9999.0))
    with pytest.raises(InputDataError, match="^INPUT 'nodata.tif' has no valid cell"):
        toolbox.run("dem:slope", {"INPUT": nodata, "OUTPUT": tmp_path / "s.tif"})
    flat = dem(tmp_path / "flat.tif", np.full((6, 6), 250.0))
    with pytest.raises(InputDataError, match="OUTPUT would have no valid cell .*: flat cells have "
                                             "no aspect") as err:
        toolbox.run("dem:aspect", {"INPUT": flat, "OUTPUT": tmp_path / "a.tif"})
    assert "EXTENT" not in str(err.value)
    holes = np.full((6, 6), 250.0)
    holes[::2, ::2] = -9999.0  # every cell next to a nodata cell
    holes = dem(tmp_path / "holes.tif", holes)
    with pytest.raises(InputDataError, match="OUTPUT would have no valid cell .*: cells next to "
                                             "nodata are nodata"):
        toolbox.run("dem:hillshade", {"INPUT": holes, "OUTPUT": tmp_path / "h.tif"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["flat.tif", "holes.tif", "nodata.tif"]
    # a TEMPLATE lends its grid only: an all-nodata one is not blamed
    points = tmp_path / "p.csv"
    points.write_text("x,y,z\n" + "".join(f"{X0 + 600 + x},{Y0 + 600 + y},1\n"
                                          for x, y in ((0, 0), (9, 0), (0, 9))))
    with pytest.raises(InputDataError, match="^OUTPUT would have no valid cell .*: check that "
                                             "EXTENT, TEMPLATE, MASK and CELL_SIZE"):
        toolbox.run("dem:nearest", {"INPUT": points, "CRS": CRS, "TEMPLATE": nodata,
                                    "OUTPUT": tmp_path / "n.tif"})


def test_ground_filter_of_a_strip_one_filter_cell_wide(tmp_path):
    """Points in a strip narrower than FILTER_CELL (a one-row filter grid, as a one-row DSM):
    np.gradient refused the grid ('ground filter: Shape of array too small to calculate a
    numerical gradient', exit 2, no parameter named). Points on a plane are all ground and the
    DTM is that plane (analytic)."""
    rng = np.random.default_rng(0)
    x, y = rng.uniform(0, 100, 200), rng.uniform(0.1, 0.9, 200)
    points = tmp_path / "strip.csv"
    points.write_text("x,y,z\n" + "".join(f"{X0 + a},{Y0 + b},{100 + 0.05 * a}\n"
                                          for a, b in zip(x, y, strict=True)))
    stats = toolbox.run("dem:ground", {"INPUT": points, "CRS": CRS, "FILTER_CELL": 1,
                                       "MAX_WINDOW": 5, "CELL_SIZE": 0.5,
                                       "OUTPUT": tmp_path / "dtm.tif",
                                       "NONGROUND": tmp_path / "ng.tif"})
    with rasterio.open(tmp_path / "dtm.tif") as ds:
        z, t = ds.read(1, masked=True), ds.transform
    cols = np.nonzero(~np.ma.getmaskarray(z))[1]
    assert z.count() > 300
    np.testing.assert_allclose(z.compressed(), 100 + 0.05 * (t.c + (cols + 0.5) * t.a - X0),
                               atol=1e-4)
    assert not (band(tmp_path / "ng.tif") == 1).any(), stats  # no point is an object


def test_profile_in_the_outer_half_cell_of_the_dem(tmp_path):
    """A profile along a DEM's top row, 1 m inside its edge (between the edge and the row's
    cell centres): every station had 'no height' ('stations fall outside the surface', exit
    0), as did the first and last half cell of any line. gdalwarp -r bilinear holds the edge
    value level across that half cell (checked: 100 at x = 0.5..4.5, 119 at 195.5..199.5);
    beyond the raster's cells there is still no height."""
    import geopandas as gpd
    from shapely.geometry import LineString

    path = dem(tmp_path / "dem.tif", np.tile(100.0 + np.arange(20.0), (20, 1)))
    lines = tmp_path / "line.gpkg"
    gpd.GeoDataFrame(geometry=[LineString([(X0 + 1, Y0 - 1), (X0 + 209, Y0 - 1)])],
                     crs=CRS).to_file(lines)
    stats = toolbox.run("carto:profile", {"INPUT": lines, "DEM": path, "STEP": 2,
                                          "OUTPUT": tmp_path / "p.gpkg"})["STATISTICS"]
    pts = gpd.read_file(tmp_path / "p.gpkg", layer="profile_points")
    x = pts.geometry.x.to_numpy() - X0
    on = x <= 200
    np.testing.assert_allclose(pts.z[on], 100.0 + np.clip((x[on] - 5) / 10, 0, 19), atol=1e-9)
    assert pts.z[~on].isna().all() and stats["no_height"] == (~on).sum() == 5


@pytest.mark.parametrize("z, words", [
    ([[1.0, 2.0, 3.0, 4.0]], r"has 4 column\(s\) x 1 row\(s\): contours run between cell "
                             "centres, at least 2 x 2"),
    (np.full((4, 4), -9999.0), "has no valid cell")])
def test_contours_of_a_dem_without_a_square_of_centres_are_refused(tmp_path, z, words):
    """A one-row DEM rising 1 to 4 and an all-nodata DEM: exit 0, an empty layer and the
    warning 'no contour at interval 0.5 ... crosses the surface' (false for the first: the
    levels 1.5 to 3.5 do cross it, gdal_contour draws them in its extra half cell)."""
    from toolbox.errors import ParameterError

    path = dem(tmp_path / "dem.tif", z)
    with pytest.raises(ParameterError, match=f"^INPUT '[^']*dem.tif' {words}"):
        toolbox.run("carto:contours", {"INPUT": path, "INTERVAL": 0.5,
                                       "OUTPUT": tmp_path / "c.gpkg"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif"]


def test_empty_sheet_layers_are_refused_and_an_empty_grid_is_said(tmp_path):
    """A SHEETS layer without features: carto:grid and carto:sheet exited 0 with nothing drawn
    and no word; mosaic:cut said 'no sheet of SHEETS (nan..nan, nan..nan) meets INPUT'. An
    EXTENT smaller than the grid step (500 m at 1:5000; no multiple of 500 between 10 and 60):
    an empty grid without a warning."""
    import geopandas as gpd
    from shapely.geometry import box

    from toolbox.errors import InputDataError, ParameterError

    sheets = tmp_path / "sheets.gpkg"
    gpd.GeoDataFrame({"id": [1]}, geometry=[box(X0, Y0, X0 + 1, Y0 + 1)], crs=CRS).iloc[:0] \
        .to_file(sheets, geometry_type="Polygon")
    for alg, out in (("carto:grid", {"OUTPUT": tmp_path / "g.gpkg"}),
                     ("carto:sheet", {"FOLDER": tmp_path / "s"})):
        with pytest.raises(ParameterError, match="^SHEETS '[^']*sheets.gpkg' has no features"):
            toolbox.run(alg, {"SHEETS": sheets, **out})
    with pytest.raises(InputDataError, match="^SHEETS has no sheet to cut by: its 0 feature"):
        toolbox.run("mosaic:cut", {"INPUT": dem(tmp_path / "d.tif", np.ones((3, 3))),
                                   "SHEETS": sheets, "OUTPUT": tmp_path / "cut"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.tif", "sheets.gpkg"]
    feedback = toolbox.Feedback()
    stats = toolbox.run("carto:grid", {"EXTENT": f"{X0 + 10},{Y0 + 10},{X0 + 60},{Y0 + 60}",
                                       "CRS": CRS, "STYLE": "lines",
                                       "OUTPUT": tmp_path / "g.gpkg"},
                        feedback=feedback)["STATISTICS"]
    assert stats["features"] == 0
    assert any("no grid line (every 500 m, 100 mm at 1:5000) falls inside the EXTENT" in w
               for w in feedback.warnings)


def test_volume_against_a_dem_coarser_than_the_tin_is_flagged(tmp_path):
    """A TIN triangle of 5,000 m² (z = 10 + 0.1 x + 0.2 y: 100,000 m³ above z = 0, by hand)
    against a DEM of one 1000 m cell at 0 whose centre is a TIN node: the midpoint rule counted
    the whole cell, area 1,000,000 m² and volume 10,000,000 m³, exit 0 without a word. The
    numbers are the documented method's; now a warning says the cells are coarse. A DEM of
    2 m cells over the same TIN gives no warning (and a volume within 5 %)."""
    import geopandas as gpd
    from shapely.geometry import Point

    points = tmp_path / "p.gpkg"
    gpd.GeoDataFrame(geometry=[Point(X0, Y0, 10), Point(X0 + 100, Y0, 20),
                               Point(X0, Y0 + 100, 30)], crs=CRS).to_file(points)
    tin = tmp_path / "tin.gpkg"
    toolbox.run("tin:delaunay", {"INPUT": points, "OUTPUT": tin})
    exact = toolbox.run("tin:volume", {"TIN": tin, "REFERENCE_Z": 0})["STATISTICS"]
    assert exact["cut_volume"] == pytest.approx(100_000) and exact["area"] == pytest.approx(5000)
    coarse = tmp_path / "coarse.tif"
    write_raster(coarse, np.zeros((1, 1), "float32"), Affine(1000, 0, X0 - 500, 0, -1000,
                                                             Y0 + 500), CRS, nodata=-9999.0)
    feedback = toolbox.Feedback()
    stats = toolbox.run("tin:volume", {"TIN": tin, "REFERENCE_DEM": coarse},
                        feedback=feedback)["STATISTICS"]
    assert stats["area"] == pytest.approx(1e6)
    assert any("the DEM's cells (1000 x 1000) are coarse for this TIN: the cells whose centre "
               "lies on it cover 1,000,000.00 square units where the TIN covers 5,000.00" in w
               for w in feedback.warnings), feedback.warnings
    fine = tmp_path / "fine.tif"
    write_raster(fine, np.zeros((54, 54), "float32"), Affine(2, 0, X0 - 4, 0, -2, Y0 + 104),
                 CRS, nodata=-9999.0)
    feedback = toolbox.Feedback()
    stats = toolbox.run("tin:volume", {"TIN": tin, "REFERENCE_DEM": fine},
                        feedback=feedback)["STATISTICS"]
    assert not any("coarse" in w for w in feedback.warnings), feedback.warnings
    assert stats["cut_volume"] == pytest.approx(100_000, rel=0.05)


def test_cross_validation_of_all_methods_leaves_out_those_short_of_points(tmp_path):
    """Ten points on a plane with the default METHODS=all: the run was refused ('cross-validation
    of cubic needs at least 11 distinct data points, got 10', exit 2, METHODS not named) though
    five of the six methods could run. Now those run (a plane's points: the plane and TIN
    methods predict them exactly), cubic is left out with a warning; asked for by name it is
    still refused, naming METHODS."""
    from toolbox.errors import InputDataError

    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 100, (10, 2))
    points = tmp_path / "p.csv"
    points.write_text("x,y,z\n" + "".join(f"{X0 + x},{Y0 + y},{50 + 0.1 * x - 0.2 * y}\n"
                                          for x, y in xy))
    feedback = toolbox.Feedback()
    report = toolbox.run("dem:cross_validate", {"INPUT": points, "CRS": CRS, "EXTRAPOLATE": True,
                                                "OUTPUT": tmp_path / "cv.json"},
                         feedback=feedback)["STATISTICS"]
    assert sorted(report["methods"]) == ["idw", "nearest", "plane", "quadratic", "tin_linear"]
    assert report["methods"]["plane"]["rmse"] == pytest.approx(0, abs=1e-9)
    assert any("METHODS all: cubic left out, too few points for their cross-validation (11 "
               "needed, got 10)" in w for w in feedback.warnings)
    with pytest.raises(InputDataError, match="cubic needs at least 11 .*: leave cubic out of "
                                             "METHODS"):
        toolbox.run("dem:cross_validate", {"INPUT": points, "CRS": CRS, "METHODS": "idw,cubic",
                                           "OUTPUT": tmp_path / "cv2.json"})
