"""One CRS, two definitions, for rasters and layers (round 22, crsdef). GDAL labels a raster
with whatever WKT it was given: a DEM written with the ESRI ``.prj`` of EPSG:6707 reads back as
a WKT that ``pyproj.CRS.equals`` tells from EPSG:6707, though no point moves from one to the
other (``gdaltransform``). Before, ortho:photo reprojected such a DEM for nothing (two ortho
cells changed), and a TEMPLATE (ortho:photo, dem:idw, tin:to_raster), a second ortho
(mosaic:build) or a BASE (carto:sheet) so labelled was refused with exit 2. Now one rule
(``toolbox.io.crs.one_crs``): one CRS when the data's extent (centre and corners) moves by at
most 1 mm from one to the other; the outputs are bit-identical to the all-EPSG run, and a true
difference (ED50 / UTM 32N, 212 m away by gdaltransform) is still refused naming both CRSs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rasterio
from helpers_cli import cli, one_error
from rasterio.transform import from_origin

import toolbox
from tests.toolbox.crs_cases import ESRI_6707, write_one_photo_project
from tests.toolbox.crs_cases import write_raster as _raster

X0, Y0 = 680000.0, 4800000.0  # the DEMs' top-left corner; 40 x 40 cells of 100 m
LABELS = {"epsg": "EPSG:6707", "esri": ESRI_6707, "ed50": "EPSG:23032"}
# echo "680000 4796000" | gdaltransform -s_srs EPSG:23032 -t_srs EPSG:6707 -output_xy
# (GDAL 3.6.2): 679917.351431935 4795803.92696407 (the ESRI WKT: 680000 4796000, unmoved)
ED50_SHIFT = math.hypot(679917.351431935 - 680000, 4795803.92696407 - 4796000)  # 212.82 m


def _same_raster(a, b) -> bool:
    with rasterio.open(a) as s, rasterio.open(b) as t:
        return s.transform == t.transform and np.array_equal(s.read(), t.read(), equal_nan=True)


@pytest.fixture(scope="module")
def area(tmp_path_factory):
    """DEMs with relief labelled EPSG:6707, its ESRI WKT and ED50 / UTM 32N; a photo of them
    in an EPSG:6707 project; points and their TIN in EPSG:6707 (a GeoPackage or a shapefile
    written with the ESRI WKT is read back as EPSG:6707: GDAL identifies it there)."""
    import geopandas as gpd

    folder = tmp_path_factory.mktemp("crsdef")
    yy, xx = np.mgrid[0:40, 0:40]
    dem = (250 + 3 * xx + 2 * yy + 10 * np.sin(xx / 3.0)).astype("float32")
    for tag, crs in LABELS.items():
        _raster(folder / f"dem_{tag}.tif", dem, crs, from_origin(X0, Y0, 100, 100), -9999.0)
    n = 200
    image = np.full((1, n, n), 2, "uint8")
    image[:, :, ::7] = 250
    image[:, ::9, :] = 250
    _raster(folder / "p1.tif", image, None, from_origin(0, 0, 1, 1))
    write_one_photo_project(folder, n, (X0 + 2000, Y0 - 2000, 1700.0, 0.01, 0.02, 0.4))
    rng = np.random.default_rng(5)
    x, y = rng.uniform(X0 + 100, X0 + 3900, 200), rng.uniform(Y0 - 3900, Y0 - 100, 200)
    z = 200 + 0.01 * (x - X0) + 5 * np.sin(y / 300)
    gpd.GeoDataFrame(geometry=gpd.points_from_xy(x, y, z), crs="EPSG:6707").to_file(
        folder / "p_epsg.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": folder / "p_epsg.gpkg",
                                 "OUTPUT": folder / "tin_epsg.gpkg"})
    return folder


def test_extent_shift_is_gdaltransforms():
    """The extent's largest move (centre and corners) from one CRS to the other: 0 for the ESRI
    WKT of EPSG:6707 (one CRS); gdaltransform's 212.82 m for ED50 (at the corner 680000, 4796000; the
    difference of 3 mm from the grid distance is the scale factor there, 1.000016)."""
    from toolbox.io.crs import PRJ_TOLERANCE_M, extent_shift, one_crs

    bounds = (X0, Y0 - 4000, X0 + 4000, Y0)
    assert extent_shift(ESRI_6707, "EPSG:6707", bounds)[0] == 0.0
    assert extent_shift(ESRI_6707, "EPSG:6707")[0] == 0.0  # the area of use's corners
    shift, at = extent_shift("EPSG:23032", "EPSG:6707", (X0, Y0 - 4000, X0, Y0 - 4000))
    assert at == (X0, Y0 - 4000) and shift == pytest.approx(ED50_SHIFT, rel=2e-5)
    assert one_crs(ESRI_6707, "EPSG:6707", bounds)
    assert not one_crs("EPSG:23032", "EPSG:6707", bounds)
    assert not one_crs("EPSG:3003", "EPSG:6707", bounds)
    assert not one_crs(ESRI_6707, "EPSG:6707+5214", bounds)  # heights stated on one side
    # WGS 84 / UTM 32N moves by 0.1 mm (gdaltransform -s_srs EPSG:32632 -t_srs EPSG:6707:
    # 682000 4798000 -> 682000.000001408 4797999.99988202), by PROJ's null transformation
    # "RDN2008 to WGS 84 (1)" (1 m): two datums, not two definitions of one CRS
    assert extent_shift("EPSG:32632", "EPSG:6707", bounds)[0] < 2e-4
    assert not one_crs("EPSG:32632", "EPSG:6707", bounds)
    assert not one_crs("+proj=utm +zone=32 +ellps=GRS80 +units=m", "EPSG:6707", bounds)
    assert extent_shift("EPSG:23032", "EPSG:6707", bounds)[0] > 1e5 * PRJ_TOLERANCE_M


def test_ortho_photo_on_an_esri_labelled_dem_is_not_reprojected(area, tmp_path):
    """Before: the DEM was warped onto GDAL's suggested grid in EPSG:6707 (bilinear), its
    heights moved, and 2 ortho cells changed by 1 DN; now the ortho is bit-identical."""
    out = {}
    for tag in ("epsg", "esri"):
        out[tag] = tmp_path / f"o_{tag}.tif"
        toolbox.run("ortho:photo", {"INPUT": area / "p1.tif", "PROJECT": area / "project.yaml",
                                    "PHOTO": "p1", "DEM": area / f"dem_{tag}.tif",
                                    "OUTPUT": out[tag]})
    assert _same_raster(out["epsg"], out["esri"])


def _template_run(algorithm, area, template, out):
    common = ["--TEMPLATE", template, "--OUTPUT", out]
    if algorithm == "ortho:photo":
        return cli("run", algorithm, "--INPUT", area / "p1.tif", "--PROJECT",
                   area / "project.yaml", "--PHOTO", "p1", "--DEM", area / "dem_epsg.tif",
                   *common)
    if algorithm == "dem:idw":
        return cli("run", algorithm, "--INPUT", area / "p_epsg.gpkg", *common)
    return cli("run", algorithm, "--TIN", area / "tin_epsg.gpkg", "--CRS", "EPSG:6707",
               *common)


@pytest.mark.parametrize("algorithm", ["ortho:photo", "dem:idw", "tin:to_raster"])
def test_an_esri_labelled_template_is_the_data_crs(area, tmp_path, algorithm):
    """Before: exit 2, "TEMPLATE is in RDN2008 / UTM zone 32N (N-E), the ortho in EPSG:6707"
    (dem:idw: "... but the output is in EPSG:6707", tin:to_raster: "CRS is EPSG:6707 but
    TEMPLATE is in ..."). Now the same grid as the EPSG-labelled template's, bit-identical;
    an ED50 template is still refused, naming both CRSs."""
    out = {}
    for tag in ("epsg", "esri"):
        out[tag] = tmp_path / f"{tag}.tif"
        code, _, err = _template_run(algorithm, area, area / f"dem_{tag}.tif", out[tag])
        assert code == 0, err
    assert _same_raster(out["epsg"], out["esri"])
    code, _, err = _template_run(algorithm, area, area / "dem_ed50.tif", tmp_path / "ed50.tif")
    line = one_error(err)
    assert code == 2 and "EPSG:23032" in line and "EPSG:6707" in line, line
    assert not (tmp_path / "ed50.tif").exists()


def test_a_tin_to_the_esri_wkt_of_its_crs_is_not_reprojected(area, tmp_path):
    """CRS given as the ESRI WKT of the TIN's EPSG:6707 (a ``.prj``'s text). Before: "TIN
    nodes reprojected from EPSG:6707 to RDN2008 / UTM zone 32N (N-E)" (a transformation that
    moves nothing); now none, the same raster as with CRS EPSG:6707."""
    from toolbox.feedback import Feedback

    out, said = {}, {}
    for tag in ("epsg", "esri"):
        out[tag], feedback = tmp_path / f"{tag}.tif", Feedback()
        toolbox.run("tin:to_raster", {"TIN": area / "tin_epsg.gpkg", "CRS": LABELS[tag],
                                      "CELL_SIZE": 50.0, "OUTPUT": out[tag]}, feedback=feedback)
        said[tag] = [text for kind, text in feedback.messages if kind == "warning"]
    assert not any("reprojected" in text for text in said["esri"]), said["esri"]
    assert _same_raster(out["epsg"], out["esri"])


def test_mosaic_of_orthos_labelled_epsg_and_esri_is_one_crs(tmp_path):
    """Before: exit 2, "INPUT[2] (b_esri) is in RDN2008 / UTM zone 32N (N-E) but INPUT[1] (a) is
    in EPSG:6707". Now built, bit-identical to the all-EPSG mosaic; ED50 still refused."""
    rgb = (np.arange(3 * 40 * 60).reshape(3, 40, 60) % 200 + 20).astype("uint8")
    _raster(tmp_path / "a.tif", rgb, "EPSG:6707", from_origin(X0, Y0, 1, 1), 0)
    out = {}
    for tag, crs in LABELS.items():
        _raster(tmp_path / f"b_{tag}.tif", rgb, crs, from_origin(X0 + 40, Y0, 1, 1), 0)
        out[tag] = tmp_path / f"m_{tag}.tif"
        code, _, err = cli("run", "mosaic:build", "--INPUT", tmp_path / "a.tif", "--INPUT",
                           tmp_path / f"b_{tag}.tif", "--BLEND", "none", "--OUTPUT", out[tag])
        assert code == (2 if tag == "ed50" else 0), err
    assert _same_raster(out["epsg"], out["esri"])
    line = one_error(err)
    assert "INPUT[2] (b_ed50) is in EPSG:23032 but INPUT[1] (a) is in EPSG:6707" in line, line
    assert not out["ed50"].exists()


def test_sheet_with_an_esri_labelled_base(area, tmp_path, monkeypatch):
    """Before: exit 2, "BASE is in RDN2008 / UTM zone 32N (N-E) but EXTENT is in EPSG:6707";
    now drawn. An ED50 BASE is still refused naming both."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    extent = f"{X0},{Y0 - 2000},{X0 + 2000},{Y0} [EPSG:6707]"
    for tag in ("esri", "ed50"):
        code, _, err = cli("run", "carto:sheet", "--EXTENT", extent, "--BASE",
                           area / f"dem_{tag}.tif", "--SCALE", 10000, "--OUTPUT",
                           tmp_path / f"{tag}.pdf")
        assert code == (2 if tag == "ed50" else 0), err
    assert (tmp_path / "esri.pdf").stat().st_size > 0
    line = one_error(err)
    assert "BASE is in EPSG:23032 but EXTENT is in EPSG:6707" in line, line
    assert not (tmp_path / "ed50.pdf").exists()


def test_raster_engine_reads_an_esri_labelled_raster_as_aligned(area, monkeypatch):
    """The engine read a raster on its own lattice in another definition of the grid's CRS
    through GDAL's warper (same values, a reprojection for nothing); now a window read."""
    from rasterio.windows import Window

    from toolbox.io.grid import GridSpec
    from toolbox.raster import engine, reproject

    with rasterio.open(area / "dem_epsg.tif") as src:
        transform, expected = src.transform, src.read()
    grid = GridSpec(transform * transform.translation(3, 2), 30, 30, "EPSG:6707")

    def no_warp(*args, **kwargs):
        raise AssertionError("warped")

    monkeypatch.setattr(reproject, "read_onto", no_warp)
    got = engine.read_window(area / "dem_esri.tif", grid, Window(0, 0, 30, 30))
    assert np.array_equal(got, expected[:, 2:32, 3:33])
