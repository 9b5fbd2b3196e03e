"""Inputs in two CRSs (round 19, crsmix): each algorithm reprojects correctly or refuses naming
both CRSs, never reads one input's coordinates as if they were in the other's CRS.

Cases: EPSG:3003 (Monte Mario / Italy zone 1) and EPSG:32632 (WGS 84 / UTM 32N) near Siena,
~1,000 km apart in easting; EPSG:23032 (ED50 / UTM 32N), 83 m east and 196 m north of
EPSG:32632 there (pyproj), inside both areas of use, so that no area-of-use check catches it;
compound CRSs with two height datums. Truth: pyproj, pyogrio's reading of the written CRS.
"""

from __future__ import annotations

import csv

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import rasterio
import shapely
from pyproj import CRS, Transformer

import toolbox
from toolbox.errors import InputDataError

UTM, GB, ED50 = "EPSG:32632", "EPSG:3003", "EPSG:23032"
X0, Y0 = 689000.0, 4798000.0  # UTM 32N, Siena


def _written_crs(path, layer=None) -> CRS:
    return CRS.from_user_input(pyogrio.read_info(path, layer=layer)["crs"])


def _sheets(path, crs) -> str:
    frame = gpd.GeoDataFrame({"id": ["a"]}, geometry=[shapely.box(X0, Y0, X0 + 1000, Y0 + 1000)],
                             crs=UTM)
    if crs is None:
        frame = frame.set_crs(None, allow_override=True)
    elif crs != UTM:
        frame = frame.to_crs(crs)
    frame.to_file(path)
    return str(path)


# -- a CRS parameter contradicting the CRS the sheets, extent or area name --------------------
def test_grid_sheets_in_another_crs_than_crs_is_refused(tmp_path):
    """Before: the grid was drawn in SHEETS' EPSG:3003, the CRS parameter (EPSG:32632) ignored
    in silence (exit 0)."""
    sheets = _sheets(tmp_path / "sheets.gpkg", GB)
    with pytest.raises(InputDataError, match="SHEETS is in EPSG:3003 but CRS is in EPSG:32632"):
        toolbox.run("carto:grid", {"SHEETS": sheets, "SCALE": 5000, "CRS": UTM,
                                   "OUTPUT": tmp_path / "grid.gpkg"})
    assert not (tmp_path / "grid.gpkg").exists()
    with pytest.raises(InputDataError, match="EXTENT is in EPSG:3003 but CRS is in EPSG:32632"):
        toolbox.run("carto:grid", {"EXTENT": "1689000,4798000,1690000,4799000 EPSG:3003",
                                   "SCALE": 5000, "CRS": UTM, "OUTPUT": tmp_path / "grid.gpkg"})


def test_grid_sheets_without_crs_take_the_crs_parameter(tmp_path):
    """Before: SHEETS without a CRS gave a grid without a CRS, CRS given or not."""
    sheets = _sheets(tmp_path / "sheets.gpkg", None)
    toolbox.run("carto:grid", {"SHEETS": sheets, "SCALE": 5000, "CRS": UTM,
                               "OUTPUT": tmp_path / "grid.gpkg"})
    for layer in ("grid", "grid_labels"):
        assert _written_crs(tmp_path / "grid.gpkg", layer).equals(CRS(UTM))
    # the same sheets labelled: the same grid (the CRS parameter only labels)
    toolbox.run("carto:grid", {"SHEETS": _sheets(tmp_path / "utm.gpkg", UTM), "SCALE": 5000,
                               "OUTPUT": tmp_path / "grid_utm.gpkg"})
    a = gpd.read_file(tmp_path / "grid.gpkg", layer="grid")
    b = gpd.read_file(tmp_path / "grid_utm.gpkg", layer="grid")
    assert len(a) == len(b) > 0 and a.union_all().equals(b.union_all())


def test_sheet_and_sheet_index_and_design_refuse_a_contradicting_crs(tmp_path):
    """carto:sheet drew SHEETS in EPSG:32632 with CRS EPSG:3003 given; carto:sheet_index and
    orientation:design took EXTENT's (or AREA's) CRS over the CRS parameter: all exit 0."""
    sheets = _sheets(tmp_path / "sheets.gpkg", UTM)
    lines = gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 10, Y0 + 10),
                                                           (X0 + 900, Y0 + 900)])], crs=UTM)
    lines.to_file(tmp_path / "lines.gpkg")
    with pytest.raises(InputDataError, match="SHEETS is in EPSG:32632 but CRS is in EPSG:3003"):
        toolbox.run("carto:sheet", {"SHEETS": sheets, "SCALE": 5000, "CRS": GB,
                                    "LAYERS": [str(tmp_path / "lines.gpkg")],
                                    "OUTPUT": tmp_path / "sheet.pdf"})
    with pytest.raises(InputDataError, match="EXTENT is in EPSG:3003 but CRS is in EPSG:32632"):
        toolbox.run("carto:sheet_index", {"EXTENT": "1687500,4798974,1689112,4800350 EPSG:3003",
                                          "SHEET_50K": 296, "ORIGIN": "11.166667,43.4",
                                          "CRS": UTM, "OUTPUT": tmp_path / "index.gpkg"})
    with pytest.raises(InputDataError, match="AREA is in EPSG:3003 but CRS is in EPSG:32632"):
        toolbox.run("orientation:design", {"AREA": _sheets(tmp_path / "area.gpkg", GB),
                                           "CRS": UTM, "MAP_SCALE": 2000,
                                           "OUTPUT": tmp_path / "design.gpkg"})
    for name in ("sheet.pdf", "index.gpkg", "design.gpkg"):
        assert not (tmp_path / name).exists()


# -- control tables in a GeoPackage: their own CRS against the CRS parameter -------------------
def _control(tmp_path, crs):
    """Six ground points near Siena (EPSG:32632) as a CONTROL GeoPackage in ``crs`` (X/Y
    columns and geometry converted by pyproj, heights kept), and their model coordinates
    (ground / 1000 about a corner, rotated a little) as INPUT."""
    ground = np.array([[X0, Y0, 300.0], [X0 + 800, Y0, 320.0], [X0 + 800, Y0 + 700, 290.0],
                       [X0, Y0 + 700, 310.0], [X0 + 400, Y0 + 350, 340.0],
                       [X0 + 200, Y0 + 500, 305.0]])
    ids = [f"p{k}" for k in range(len(ground))]
    c, s = np.cos(0.1), np.sin(0.1)
    local = (ground - ground[0]) / 1000.0
    model = np.column_stack([c * local[:, 0] - s * local[:, 1], s * local[:, 0]
                             + c * local[:, 1], local[:, 2]])
    with open(tmp_path / "model.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "X", "Y", "Z"])
        w.writerows([pid, *xyz] for pid, xyz in zip(ids, model))
    x, y = Transformer.from_crs(UTM, crs, always_xy=True).transform(ground[:, 0], ground[:, 1])
    path = tmp_path / f"control_{crs.replace(':', '')}.gpkg"
    gpd.GeoDataFrame({"id": ids, "X": x, "Y": y, "Z": ground[:, 2]},
                     geometry=gpd.points_from_xy(x, y), crs=crs).to_file(path)
    return path, tmp_path / "model.csv"


def test_absolute_control_in_another_crs_than_crs_is_refused(tmp_path):
    """Before: CONTROL in ED50 / UTM 32N with CRS EPSG:32632: the adjusted points, in ED50
    numbers, were written labelled EPSG:32632, about 200 m from where they are (exit 0;
    inside both areas of use, so no check caught it)."""
    control, model = _control(tmp_path, ED50)
    e = Transformer.from_crs(UTM, ED50, always_xy=True).transform(X0, Y0)
    assert 150 < np.hypot(e[0] - X0, e[1] - Y0) < 300  # the offset a silent run would make
    with pytest.raises(InputDataError, match="CONTROL is in EPSG:23032 but CRS is in EPSG:32632"):
        toolbox.run("orientation:absolute", {"INPUT": model, "CONTROL": control, "CRS": UTM,
                                             "OUTPUT": tmp_path / "abs.gpkg",
                                             "REPORT": tmp_path / "abs.json"})
    assert not (tmp_path / "abs.gpkg").exists()


def test_absolute_output_takes_the_control_layer_crs(tmp_path):
    """Before: without CRS the points were written with no CRS though CONTROL's layer has one."""
    control, model = _control(tmp_path, UTM)
    toolbox.run("orientation:absolute", {"INPUT": model, "CONTROL": control,
                                         "OUTPUT": tmp_path / "abs.gpkg",
                                         "REPORT": tmp_path / "abs.json"})
    assert _written_crs(tmp_path / "abs.gpkg").equals(CRS(UTM))


def test_models_control_in_another_crs_than_crs_is_refused(tmp_path):
    """orientation:models read CONTROL's X/Y as if in CRS (exit 0) and wrote them so."""
    models = tmp_path / "models.csv"
    control = tmp_path / "control.gpkg"
    # two models of a flat square, control at its corners (model = ground / 1000, shifted)
    ground = {"p1": (0, 0), "p2": (100, 0), "p3": (100, 100), "p4": (0, 100), "p5": (50, 50)}
    with open(models, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["model", "point_id", "x", "y", "z"])
        for m, (dx, dy) in (("m1", (0.0, 0.0)), ("m2", (0.5, 0.2))):
            for pid, (x, y) in ground.items():
                w.writerow([m, pid, x / 1000 + dx, y / 1000 + dy, 0.3])
    x = [X0 + g[0] for g in ground.values()]
    y = [Y0 + g[1] for g in ground.values()]
    gpd.GeoDataFrame({"id": list(ground), "X": x, "Y": y, "Z": [300.0] * 5},
                     geometry=gpd.points_from_xy(x, y), crs=ED50).to_file(control)
    with pytest.raises(InputDataError, match="CONTROL is in EPSG:23032 but CRS is in EPSG:32632"):
        toolbox.run("orientation:models", {"INPUT": models, "CONTROL": control, "CRS": UTM,
                                           "OUTPUT": tmp_path / "m.gpkg",
                                           "REPORT": tmp_path / "m.json"})
    toolbox.run("orientation:models", {"INPUT": models, "CONTROL": control,
                                       "OUTPUT": tmp_path / "m.gpkg",
                                       "REPORT": tmp_path / "m.json"})
    assert _written_crs(tmp_path / "m.gpkg").equals(CRS(ED50))


# -- tin:to_raster: nodes reprojected, heights not converted --------------------------------
@pytest.fixture
def tin_compound(tmp_path):
    """A TIN of the plane z = 300 + 0.02 dx + 0.01 dy in EPSG:32632 + Genoa 1942 heights."""
    rng = np.random.default_rng(3)
    x, y = X0 + rng.uniform(0, 600, 60), Y0 + rng.uniform(0, 600, 60)
    z = 300 + 0.02 * (x - X0) + 0.01 * (y - Y0)
    gpd.GeoDataFrame({"z": z}, geometry=gpd.points_from_xy(x, y, z),
                     crs="EPSG:32632+5214").to_file(tmp_path / "pts.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg", "OUTPUT": tmp_path / "tin.gpkg"})
    return tmp_path / "tin.gpkg"


def test_tin_to_raster_refuses_another_height_datum(tin_compound, tmp_path):
    """Before: CRS EPSG:3003+3855 (EGM2008 heights) reprojected the nodes and wrote the Genoa
    1942 heights labelled EGM2008 (exit 0)."""
    with pytest.raises(InputDataError, match="TIN's heights are Genoa 1942 height .* but CRS's "
                                             "are EGM2008 height"):
        toolbox.run("tin:to_raster", {"TIN": tin_compound, "CELL_SIZE": 10, "CRS": "EPSG:3003+3855",
                                      "OUTPUT": tmp_path / "out.tif"})
    assert not (tmp_path / "out.tif").exists()
    # the same horizontal reprojection without a datum clash: each cell is the plane's height
    # at the cell centre converted back to UTM by pyproj
    toolbox.run("tin:to_raster", {"TIN": tin_compound, "CELL_SIZE": 10, "CRS": "EPSG:3003+5214",
                                  "OUTPUT": tmp_path / "ok.tif"})
    with rasterio.open(tmp_path / "ok.tif") as src:
        a = src.read(1, masked=True)
        rows, cols = np.nonzero(~a.mask)
        xs, ys = rasterio.transform.xy(src.transform, rows, cols)
    ux, uy = Transformer.from_crs(GB, UTM, always_xy=True).transform(np.array(xs), np.array(ys))
    assert len(rows) > 1000
    assert np.abs(a[rows, cols] - (300 + 0.02 * (ux - X0) + 0.01 * (uy - Y0))).max() < 1e-3


# -- messages: a CRS without a code or a name ------------------------------------------------
def test_an_unnamed_crs_is_named_by_its_proj_string(tmp_path):
    """Before: 'DEM is in unknown (unknown), whose easting unit is the US survey foot' and
    'MASK is in EPSG:32632 but INPUT is in unknown': nothing said which CRS."""
    feet = CRS.from_proj4("+proj=utm +zone=32 +datum=WGS84 +units=us-ft +no_defs")
    gpd.GeoDataFrame({"z": [1.0, 2.0, 3.0, 4.0]}, geometry=gpd.points_from_xy(
        [X0, X0 + 900, X0 + 900, X0], [Y0, Y0, Y0 + 900, Y0 + 900]), crs=UTM).to_crs(
        feet).to_file(tmp_path / "feet.gpkg")
    gpd.GeoDataFrame(geometry=[shapely.box(X0, Y0, X0 + 100, Y0 + 100)], crs=UTM).to_file(
        tmp_path / "mask.gpkg")
    with pytest.raises(InputDataError) as info:
        toolbox.run("dem:idw", {"INPUT": tmp_path / "feet.gpkg", "Z_FIELD": "z", "CELL_SIZE": 10,
                                "MASK": tmp_path / "mask.gpkg", "OUTPUT": tmp_path / "x.tif"})
    text = str(info.value)
    assert "unknown" not in text and "+units=us-ft" in text and "EPSG:32632" in text


def test_sheet_layers_in_another_crs_are_named(tmp_path):
    """Before: BASE or LAYERS in EPSG:3003 under sheets in EPSG:32632 were refused as 'no
    input meets the sheets ... are they of the same area and CRS?', no CRS named."""
    sheets = _sheets(tmp_path / "sheets.gpkg", UTM)
    gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 10, Y0 + 10), (X0 + 900, Y0 + 900)])],
                     crs=UTM).to_crs(GB).to_file(tmp_path / "lines.gpkg")
    with pytest.raises(InputDataError, match=r"^LAYERS\[1\] is in EPSG:3003 but SHEETS is in "
                                             "EPSG:32632"):
        toolbox.run("carto:sheet", {"SHEETS": sheets, "SCALE": 5000,
                                    "LAYERS": [str(tmp_path / "lines.gpkg")],
                                    "OUTPUT": tmp_path / "sheet.pdf"})
    assert not (tmp_path / "sheet.pdf").exists()


def test_an_unlabelled_input_far_outside_the_crs_parameter_is_refused(tmp_path):
    """Before: points without a CRS holding UTM 32N numbers, given CRS EPSG:3003, were gridded
    as Monte Mario coordinates 1,000 km west of the zone (exit 0), though the same numbers
    labelled EPSG:3003 are refused as far outside its area of use; the same points given
    CRS EPSG:32632 (their own) still run."""
    pts = tmp_path / "pts.gpkg"
    x = X0 + np.array([0.0, 500, 500, 0, 250])
    y = Y0 + np.array([0.0, 0, 500, 500, 250])
    gpd.GeoDataFrame({"z": [1.0, 2, 3, 4, 5]}, geometry=gpd.points_from_xy(x, y)).to_file(pts)
    lon, lat = Transformer.from_crs(GB, "EPSG:4326", always_xy=True).transform(X0, Y0)
    assert lon < CRS(GB).area_of_use.west - 5  # the truth: far west of EPSG:3003's area
    for algorithm in ("dem:idw", "tin:delaunay"):
        extra = {"CELL_SIZE": 50} if algorithm == "dem:idw" else {}
        out = tmp_path / ("dem.tif" if algorithm == "dem:idw" else "tin.gpkg")
        with pytest.raises(InputDataError, match="^INPUT has no CRS and is taken to be in CRS "
                                                 "EPSG:3003, but coordinates"):
            toolbox.run(algorithm, {"INPUT": pts, "Z_FIELD": "z", "CRS": GB, "OUTPUT": out,
                                    **extra})
        assert not out.exists()
        toolbox.run(algorithm, {"INPUT": pts, "Z_FIELD": "z", "CRS": UTM, "OUTPUT": out, **extra})
        if algorithm == "tin:delaunay":
            assert _written_crs(out, "triangles").equals(CRS(UTM))
        else:
            with rasterio.open(out) as src:
                assert CRS.from_wkt(src.crs.to_wkt()).equals(CRS(UTM))
