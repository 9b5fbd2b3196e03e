"""Round 16, datums: the datum transformation of a reprojection is named, with its accuracy,
and warned about when it is of unknown accuracy (a ballpark, ignoring the datum shift), coarser
than the output's cell, or when a better one needs a PROJ grid not installed here.

Monte Mario (EPSG:3003, Gauss-Boaga) -> RDN2008 / UTM 32N (EPSG:6707): without the IGM grid
``35160622_47161840_R40_F00.gsb`` PROJ applies a 7-parameter Helmert through ETRS89 (4 m)
instead of "Monte Mario to RDN2008 (5)" (0.1 m); an ortho of 2.5 m cells or a 1 m DEM was
written in silence with positions up to 4 m off. Truth: pyproj's TransformerGroup (its
operations, accuracies and missing grids), independent of the toolbox."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pyproj.transformer import TransformerGroup

import toolbox
from toolbox.feedback import Feedback
from toolbox.io.crs import transformation_check


def group(source, target):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return TransformerGroup(source, target, always_xy=True)


def missing_grids(source, target):
    return {g.short_name for op in group(source, target).unavailable_operations
            for g in op.grids if not g.available}


needs_missing_grid = pytest.mark.skipif(
    not missing_grids("EPSG:3003", "EPSG:6707"),
    reason="the IGM Monte Mario -> RDN2008 grid is installed here: PROJ uses it")


@needs_missing_grid
def test_monte_mario_to_rdn2008_without_grid_is_warned():
    """The accuracy reported is the best *available* one PROJ lists (4 m, a Helmert), the
    warning names the missing grid and the 0.1 m operation that needs it."""
    available = [t.accuracy for t in group("EPSG:3003", "EPSG:6707").transformers
                 if t.accuracy is not None and t.accuracy >= 0]
    bounds = (1500000.0, 5000000.0, 1500200.0, 5000200.0)
    record, text = transformation_check("EPSG:3003", "EPSG:6707", bounds, 0.2, "DEM")
    assert record["accuracy_m"] >= min(available, default=4.0)
    assert record["accuracy_m"] == pytest.approx(4.0)
    assert record["better_operation"]["accuracy_m"] == pytest.approx(0.1)
    grids = missing_grids("EPSG:3003", "EPSG:6707")
    assert set(record["better_operation"]["missing_grids"]) <= grids
    assert text is not None and "coarser than the output cell (0.2 m)" in text
    assert all(g in text for g in record["better_operation"]["missing_grids"])


def test_no_warning_without_datum_change_or_when_accurate_enough():
    assert transformation_check("EPSG:3003", "EPSG:3003") == (None, None)
    assert transformation_check(None, "EPSG:3003") == (None, None)
    record, text = transformation_check("EPSG:3003", "EPSG:3004",
                                        (1500000.0, 5000000.0, 1500100.0, 5000100.0), 0.1)
    assert text is None and record["accuracy_m"] == 0.0  # Gauss-Boaga zones: same datum
    # ETRS89 -> WGS 84 (1 m): fine for a 5 m cell (no better operation needs a grid)
    record, text = transformation_check("EPSG:25832", "EPSG:32632",
                                        (500000.0, 5000000.0, 500100.0, 5000100.0), 5.0)
    assert text is None and record["accuracy_m"] == pytest.approx(1.0)


def test_ballpark_transformation_is_warned():
    """A CRS on a datum PROJ knows no shift for (a Bessel Transverse Mercator without
    towgs84): PROJ's only operation is a ballpark one, which ignores the datum shift."""
    bessel = "+proj=tmerc +lat_0=0 +lon_0=9 +k=0.9996 +x_0=1500000 +ellps=bessel +units=m"
    descriptions = [t.description for t in group(bessel, "EPSG:25832").transformers]
    assert descriptions and all("allpark" in d for d in descriptions)
    record, text = transformation_check(bessel, "EPSG:25832",
                                        (1500000.0, 5000000.0, 1500100.0, 5000100.0), 10.0)
    assert record["accuracy_m"] is None
    assert text is not None and "accuracy is unknown" in text


@needs_missing_grid
def test_ortho_in_another_crs_reports_its_transformation():
    """An ortho of a photo oriented in EPSG:3003 written in EPSG:6707 at 2.5 m cells on a DEM
    of 10 m cells in EPSG:3003 (what ortho:photo/ortho:batch do per photo,
    :func:`toolbox.ortho.run.transformations`): warned (the Helmert's 4 m is coarser than the
    cell; the grid is missing) and the report records which operation moved the cells."""
    from types import SimpleNamespace as NS

    from affine import Affine

    from toolbox.ortho.run import transformations

    photo = NS(id="p1", require_exterior=lambda: NS(crs="EPSG:3003"))
    dem = NS(crs="EPSG:3003", transform=Affine(10.0, 0, 1686600.0, 0, -10.0, 4800800.0))
    grid = NS(crs="EPSG:6707", cell_size=(2.5, 2.5),
              bounds=(688000.0, 4798000.0, 688500.0, 4798500.0))
    feedback = Feedback()
    found = transformations(photo, dem, grid, NS(transformer=object()), feedback)
    assert [(f["from"], f["to"]) for f in found] == [("EPSG:6707", "EPSG:3003")] * 2
    assert found[0]["accuracy_m"] == pytest.approx(4.0)
    cells = [w for w in feedback.warnings if w.startswith("the ortho's cells")]
    assert len(cells) == 1 and "coarser than the output cell (2.5 m)" in cells[0]
    assert "35160622_47161840_R40_F00.gsb" in cells[0]
    dem_warning = [w for w in feedback.warnings if w.startswith("the DEM's positions")]
    assert len(dem_warning) == 1 and "coarser" not in dem_warning[0]  # 4 m < the DEM's 10 m
    # same CRSs: nothing made, nothing said
    grid.crs, feedback = "EPSG:3003", Feedback()
    assert transformations(photo, dem, grid, NS(transformer=None), feedback) == []
    assert not feedback.warnings


@needs_missing_grid
def test_tin_to_raster_in_another_crs_names_its_transformation(tmp_path):
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(1)
    x, y = 1500000 + rng.uniform(0, 100, 30), 5000000 + rng.uniform(0, 100, 30)
    gpd.GeoDataFrame(geometry=[shapely.Point(a, b, 100.0) for a, b in zip(x, y, strict=True)],
                     crs=3003).to_file(tmp_path / "pts.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg", "OUTPUT": tmp_path / "t.gpkg"})
    feedback = Feedback()
    toolbox.run("tin:to_raster", {"TIN": tmp_path / "t.gpkg", "CRS": "EPSG:6707",
                                  "CELL_SIZE": 1.0, "OUTPUT": tmp_path / "d.tif"},
                feedback=feedback)
    assert any("accuracy (4 m) is coarser than the output cell (1 m)" in w
               for w in feedback.warnings)


# -- angle units: an angle beyond a full turn is not in the unit it is read in -----------------
def test_gon_csv_read_as_degrees_is_refused(tmp_path):
    """An Orthority CSV of gon angles without a unit (kappa 385 gon): read as degrees (the
    CSV's default) kappa became 25 deg instead of 346.5 deg (385 x 0.9), exit 0. Now refused
    naming ANGLE_UNIT and gon; with ANGLE_UNIT gon the hand conversion comes out."""
    import math

    from toolbox.errors import ParameterError
    from toolbox.exchange.csvtable import read_csv

    path = tmp_path / "eo.csv"
    path.write_text("filename,x,y,z,omega,phi,kappa\n"
                    "p1.tif,1500000,5000000,1500,0.12,-0.34,385.0\n")
    with pytest.raises(ParameterError, match=r"^ANGLE_UNIT is deg.*385.*in gon\?"):
        read_csv(path, crs="EPSG:3003")
    with pytest.raises(ParameterError, match=r"^ANGLE_UNIT is rad.*in gon\?"):
        read_csv(path, crs="EPSG:3003", angle_unit="rad")
    photo = next(iter(read_csv(path, crs="EPSG:3003", angle_unit="gon").photos.values()))
    assert [math.degrees(a) for a in photo.opk] == pytest.approx([0.108, -0.306, 346.5])


def test_degrees_read_as_radians_are_refused_by_every_reader():
    """ExteriorOrientation.from_angles (the project, native CSV, OPK text and Z-Map readers):
    kappa 178 deg given as rad was taken as 178 rad (= 358.5 deg after wrapping)."""
    from toolbox.errors import ParameterError
    from toolbox.photogrammetry.exterior import ExteriorOrientation

    with pytest.raises(ParameterError, match=r"^ANGLE_UNIT is rad.*photo p1.*178.*in deg\?"):
        ExteriorOrientation.from_angles("p1", 0, 0, 1000, 0.5, -1.2, 178.0, unit="rad")
    eo = ExteriorOrientation.from_angles("p1", 0, 0, 1000, 0.5, -1.2, 178.0, unit="deg")
    assert eo.kappa == pytest.approx(178.0 * np.pi / 180.0)
    eo = ExteriorOrientation.from_angles("p1", 0, 0, 1000, 0.0, 0.0, -399.9, unit="gon")
    assert eo.kappa == pytest.approx(-399.9 * np.pi / 200.0)


# -- heights: one side states its datum, the other none ------------------------------------------
def _tiny_dem(path, crs):
    import rasterio
    from affine import Affine

    with rasterio.open(path, "w", driver="GTiff", width=4, height=4, count=1, dtype="float32",
                       crs=crs, transform=Affine(10.0, 0, 1688000.0, 0, -10.0, 4799200.0)) as d:
        d.write(np.full((1, 4, 4), 300.0, dtype="float32"))
    return path


def _egm96_n(lon, lat):
    """Independent: pyproj with the EGM96 grid, N = h - H; None when the grid is missing."""
    from pyproj import Transformer

    from toolbox.ortho.vertical import use_system_grids

    use_system_grids()
    t = Transformer.from_crs("EPSG:4979", "EPSG:4326+5773", always_xy=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            h = t.transform(lon, lat, 0.0, errcheck=True)[2]
        except Exception:  # noqa: BLE001
            return None
    return None if "allpark" in t.get_last_used_operation().description else -h


def test_ellipsoidal_photos_on_a_dem_without_datum_are_warned(tmp_path):
    """Photos' heights stated ellipsoidal (GNSS, HEIGHTS ellipsoidal, an RPC camera), the DEM
    (EPSG:3003, an Italian DTM: orthometric) states none: its heights were taken as ellipsoidal
    with an *info* line only; an error of the geoid undulation (~48 m here). Now a warning,
    with N from EGM96 when its grid is installed."""
    from pyproj import Transformer

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.vertical import dem_in_photo_datum

    info = open_raster_info(_tiny_dem(tmp_path / "dem.tif", "EPSG:3003"), "DEM")
    feedback = Feedback()
    with dem_in_photo_datum(info, 1, "ellipsoidal", None, feedback) as (dem, band, note):
        assert dem is info and not note.converted
    assert any(w.startswith("heights used as they are: the photos' are ellipsoidal")
               for w in feedback.warnings)
    lon, lat = Transformer.from_crs("EPSG:3003", "EPSG:4326", always_xy=True).transform(
        1688020.0, 4799180.0)
    n = _egm96_n(lon, lat)
    if n is not None:
        assert note.as_dict()["geoid_separation_m"] == pytest.approx(n, abs=0.01)
        assert f"{n:.1f} m here (EGM96)" in feedback.warnings[-1]
    # neither side states a datum: nothing to compare, information only
    feedback = Feedback()
    with dem_in_photo_datum(info, 1, None, "EPSG:3003", feedback) as (_, _, note):
        pass
    assert not feedback.warnings and "no height datum stated" in note.text


@needs_missing_grid
def test_gcp_list_in_another_crs_warns_a_transformation_coarser_than_control(tmp_path):
    """An ODM gcp_list in EPSG:3003 converted to EPSG:6707: the control points were moved by
    the 4 m Helmert with a note naming only the two CRSs. Now warned (4 m against a control
    point's 0.1 m; the grid named) and the summary's notes name the operation."""
    (tmp_path / "gcp_list.txt").write_text("EPSG:3003\n1500000.0 5000000.0 100.0 512 384 p1.jpg A\n"
                                           "1500100.0 5000050.0 101.0 900 300 p1.jpg B\n")
    feedback = Feedback()
    out = toolbox.run("orientation:convert", {
        "INPUT": str(tmp_path / "gcp_list.txt"), "FORMAT": "gcp", "CRS": "EPSG:6707",
        "OUTPUT": tmp_path / "m.csv"}, feedback=feedback)
    assert any("coarser than a control point's tolerance (0.1 m)" in w
               and "35160622_47161840_R40_F00.gsb" in w for w in feedback.warnings)
    assert any(n.startswith("transformation: ") and "accuracy 4.0 m" in n
               for n in out["SUMMARY"]["notes"])


def test_rpc_ortho_in_monte_mario_warns_the_helmert_to_wgs84():
    """An RPC (satellite) ortho in EPSG:3003 at 0.5 m cells: every cell goes to the RPCs' WGS 84
    longitude/latitude by a Monte Mario -> WGS 84 Helmert (PROJ lists none better than 4 m
    available: TransformerGroup's truth); said nowhere before, now warned and recorded."""
    from types import SimpleNamespace as NS

    from toolbox.ortho.rpc import _transformations

    best = min(t.accuracy for t in group("EPSG:3003", "EPSG:4326").transformers
               if t.accuracy is not None and t.accuracy >= 0)
    grid = NS(crs="EPSG:3003", cell_size=(0.5, 0.5),
              bounds=(1688000.0, 4799000.0, 1688500.0, 4799500.0))
    feedback = Feedback()
    found = _transformations(None, grid, NS(transformer=None), feedback)
    assert len(found) == 1 and found[0]["to"] == "EPSG:4326"
    assert found[0]["accuracy_m"] >= best > 0.5
    assert any(w.startswith("the RPC ortho's cells") and "coarser than the output cell (0.5 m)"
               in w for w in feedback.warnings)


@needs_missing_grid
def test_sheet_second_grid_coarser_than_the_map_tolerance_is_warned():
    """carto:sheet of a Gauss-Boaga (EPSG:3003) sheet at 1:5000 with RDN2008 ticks (GRID_CRS
    EPSG:6707, as Italian CTR sheets carry): the ticks are placed by the 4 m Helmert, coarser
    than the map's 0.5 mm x 5000 = 2.5 m tolerance; at 1:25000 (0.3 mm: 7.5 m) only the missing grid is
    said."""
    from types import SimpleNamespace as NS

    import shapely
    from pyproj import CRS

    from toolbox.cartography.sheet_job import _second_grid_accuracy
    from toolbox.photogrammetry.accuracy import planimetric_tolerance_m

    assert planimetric_tolerance_m(5000) == pytest.approx(2.5)
    sheets = [("1", shapely.box(1688000.0, 4799000.0, 1689000.0, 4799800.0))]
    feedback = Feedback()
    _second_grid_accuracy(CRS("EPSG:3003"), NS(grid_crs=CRS("EPSG:6707"), scale=5000.0),
                          sheets, feedback)
    assert len(feedback.warnings) == 1 and feedback.warnings[0].startswith(
        "the second grid (GRID_CRS)")
    assert "coarser than the map's planimetric tolerance at 1:5000 (2.5 m)" in \
        feedback.warnings[0]
    feedback = Feedback()
    _second_grid_accuracy(CRS("EPSG:3003"), NS(grid_crs=CRS("EPSG:6707"), scale=25000.0),
                          sheets, feedback)
    assert len(feedback.warnings) == 1 and "coarser" not in feedback.warnings[0]
    assert "35160622_47161840_R40_F00.gsb" in feedback.warnings[0]


def test_ctr_sheet_index_in_gauss_boaga_warns_its_ed50_transformation(tmp_path):
    """carto:sheet_index in EPSG:3003: the element edges (ED50 meridians and parallels) were
    placed by PROJ's Monte Mario <-> ED50 operation, a chain of Helmerts through WGS 84 (10 m:
    pyproj's own choice, get_last_used_operation), said nowhere. Now warned against the 1:5000
    tolerance (2.5 m), naming the missing IGM grid, and recorded in STATISTICS."""
    from pyproj import Transformer

    origin = (11 + 10 / 60, 43 + 24 / 60)
    truth = Transformer.from_crs("EPSG:4230", "EPSG:3003", always_xy=True)
    truth.transform(origin[0] + 1 / 6, origin[1] - 0.1)
    used = truth.get_last_used_operation()
    feedback = Feedback()
    out = toolbox.run("carto:sheet_index", {
        "EXTENT": "1663000,4802000,1663040,4802040 [EPSG:3003]", "SHEET_50K": 296,
        "ORIGIN": f"{origin[0]!r},{origin[1]!r}", "NEIGHBOURS": False,
        "OUTPUT": tmp_path / "index.gpkg"}, feedback=feedback)
    record = out["STATISTICS"]["transformation"]
    assert (record["from"], record["to"]) == ("EPSG:4230", "EPSG:3003")
    assert (record["operation"], record["accuracy_m"]) == (used.description, used.accuracy)
    if used.accuracy > 2.5:
        assert any(w.startswith("the sheet edges (ED50)") and "1:5000 (2.5 m)" in w
                   for w in feedback.warnings)
    assert set(record.get("better_operation", {}).get("missing_grids", [])) <= \
        missing_grids("EPSG:4230", "EPSG:3003")


def test_lla_csv_ellipsoidal_altitudes_into_a_2d_crs_are_warned(tmp_path):
    """An Orthority CSV of latitude/longitude/altitude (WGS84 ellipsoidal metres, its documented
    meaning) converted into EPSG:6707 (no height datum): the altitudes went through unchanged,
    written into a project that states no datum, in silence (exit 0); an ortho on an
    orthometric DEM would then take them as orthometric. Now a warning naming HEIGHTS."""
    from pyproj import Transformer

    path = tmp_path / "lla.csv"
    path.write_text("filename,latitude,longitude,altitude,omega,phi,kappa\n"
                    "p1.jpg,43.32,11.33,420.5,0.5,-0.3,12.0\n")
    feedback = Feedback()
    out = toolbox.run("orientation:convert", {"INPUT": str(path), "CRS": "EPSG:6707",
                                              "FORMAT_OUT": "csv",
                                              "OUTPUT": tmp_path / "o.csv"}, feedback=feedback)
    assert any("WGS84 ellipsoidal" in w and "HEIGHTS ellipsoidal" in w for w in feedback.warnings)
    assert out["SUMMARY"]
    # the altitude itself is kept (ellipsoidal, as pyproj's WGS 84 3D -> 2D grid gives it)
    z = Transformer.from_crs("EPSG:4979", "EPSG:6707", always_xy=True).transform(11.33, 43.32,
                                                                                  420.5)[2]
    row = (tmp_path / "o.csv").read_text().splitlines()[1].split(",")
    assert float(row[3]) == pytest.approx(z, abs=1e-3)


@pytest.fixture(scope="module")
def bundle_sample(tmp_path_factory):
    from toolbox.demo.samples.bundle_block import make

    return make(tmp_path_factory.mktemp("datums_bundle"), {})


@pytest.mark.parametrize(("code", "refused"), [("+5214", None), ("", "reproject it")])
def test_bundle_control_with_a_height_datum_is_not_told_to_reproject(bundle_sample, tmp_path,
                                                                      code, refused):
    """CONTROL labelled PROJECT's CRS + Genova 1942 heights (EPSG:3003+5214, a .prj as an
    Italian survey states it) was refused 'reproject it to PROJECT's CRS first' although its
    horizontal CRS is PROJECT's (pyproj: the compound's first part equals EPSG:3003). Now taken
    with a warning that only one side states a height datum; another horizontal CRS
    (EPSG:3004) is still refused."""
    import shutil

    from pyproj import CRS

    from toolbox.errors import ToolboxError
    from toolbox.photogrammetry.project import load_project

    epsg = CRS.from_user_input(load_project(bundle_sample["bundle_project"]).crs).to_epsg()
    control = tmp_path / "control.csv"
    shutil.copy(bundle_sample["bundle_control"], control)
    label = CRS.from_user_input(f"EPSG:{epsg}{code}" if code else f"EPSG:{epsg + 1}")
    assert code == "" or label.sub_crs_list[0].equals(CRS.from_epsg(epsg))
    control.with_suffix(".prj").write_text(label.to_wkt())
    params = {"PROJECT": bundle_sample["bundle_project"],
              "INPUT": bundle_sample["bundle_measurements"], "CONTROL": control,
              "SIGMA_PX": 0.3, "OUTPUT": tmp_path / "a.yaml"}
    feedback = Feedback()
    if refused:
        with pytest.raises(ToolboxError, match=refused):
            toolbox.run("orientation:bundle", params, feedback=feedback)
        return
    out = toolbox.run("orientation:bundle", params, feedback=feedback)
    assert 0.8 < out["STATISTICS"]["sigma0"] < 1.2
    assert any(w.startswith("CONTROL heights are Genoa 1942 height") and "taken as the same"
               in w for w in feedback.warnings)


def test_opensfm_reconstruction_to_monte_mario_names_its_helmert(tmp_path):
    """An ODM reconstruction (reference_lla in Tuscany) converted to EPSG:3003: its WGS 84
    positions went to Monte Mario by a 4 m Helmert, the notes saying only 'through pyproj'.
    Now the notes name the operation and its accuracy (pyproj's own choice as truth)."""
    import json

    from pyproj import Transformer

    from toolbox.exchange.opensfm import read_reconstruction

    lat, lon = 43.32, 11.33
    doc = {"cameras": {"c": {"projection_type": "perspective", "width": 400, "height": 300,
                             "focal": 0.8, "k1": 0.0, "k2": 0.0}},
           "shots": {"IMG_0.JPG": {"rotation": [3.14159, 0.0, 0.0],
                                   "translation": [0.0, 0.0, 100.0], "camera": "c"}},
           "reference_lla": {"latitude": lat, "longitude": lon, "altitude": 300.0}}
    (tmp_path / "reconstruction.json").write_text(json.dumps([doc]))
    oset = read_reconstruction(tmp_path / "reconstruction.json", "EPSG:3003")
    truth = Transformer.from_crs("EPSG:4326", "EPSG:3003", always_xy=True)
    truth.transform(lon, lat)
    used = truth.get_last_used_operation()
    assert any(n == f"WGS 84 -> EPSG:3003: {used.description}, accuracy {used.accuracy} m"
               for n in oset.notes), oset.notes


def test_transformation_check_of_infinite_bounds_is_no_crash():
    """A gcp_list with an 'inf' coordinate (the readers' fuzz test): OverflowError while
    rounding the centre; now the operation is judged without a place."""
    record, _ = transformation_check("EPSG:3003", "EPSG:6707",
                                     (float("inf"), 5000000.0, float("inf"), 5000100.0), 0.2)
    assert record["from"] == "EPSG:3003"


def test_inputs_differing_only_by_a_stated_height_datum_are_one_crs(tmp_path):
    """tin:delaunay of points labelled EPSG:3003+5214 (Genova 1942 heights) with breaklines
    labelled EPSG:3003: refused 'reproject the inputs to one CRS first' (exit 2, misleading:
    pyproj says the horizontal CRSs are equal). Now one CRS, with a warning; two different
    height datums and two horizontal CRSs are still refused, saying which."""
    from pyproj import CRS

    from toolbox.errors import InputDataError
    from toolbox.io.crs import common_crs

    compound = CRS("EPSG:3003+5214")
    assert compound.sub_crs_list[0].equals(CRS("EPSG:3003"))
    assert common_crs({"INPUT": compound, "BREAKLINES": CRS("EPSG:3003")}) is compound
    with pytest.raises(InputDataError, match="BREAKLINES's heights are .*Genoa 1942.* but "
                                             "INPUT's are .*EGM2008"):
        common_crs({"INPUT": CRS("EPSG:3003+3855"), "BREAKLINES": compound})
    with pytest.raises(InputDataError, match="reproject the inputs"):
        common_crs({"INPUT": compound, "BREAKLINES": CRS("EPSG:3004")})
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(2)
    x, y = 1688000 + rng.uniform(0, 100, 30), 4799000 + rng.uniform(0, 100, 30)
    gpd.GeoDataFrame(geometry=[shapely.Point(a, b, 100.0) for a, b in zip(x, y, strict=True)],
                     crs=compound).to_file(tmp_path / "pts.gpkg")
    gpd.GeoDataFrame(geometry=[shapely.LineString([(1688010, 4799010, 101.0),
                                                   (1688090, 4799090, 102.0)])],
                     crs="EPSG:3003").to_file(tmp_path / "bl.gpkg")
    feedback = Feedback()
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg", "BREAKLINES": tmp_path / "bl.gpkg",
                                 "OUTPUT": tmp_path / "tin.gpkg"}, feedback=feedback)
    assert (tmp_path / "tin.gpkg").exists()


@needs_missing_grid
def test_mosaic_layers_in_another_crs_name_their_transformation(tmp_path, caplog):
    """mosaic:build's CUTLINES / NADIR_POINTS in EPSG:3003 for orthos in EPSG:6707 were moved
    by the 4 m Helmert in silence; now the "toolbox" logger warns (the console and the run
    report show it), naming the missing IGM grid."""
    import logging

    import geopandas as gpd
    import shapely
    from pyproj import CRS

    from toolbox.mosaic.block import read_in_crs

    gpd.GeoDataFrame({"name": ["a"]}, geometry=[shapely.box(1688000, 4799000, 1688100,
                                                            4799100)],
                     crs="EPSG:3003").to_file(tmp_path / "cut.gpkg")
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        frame = read_in_crs(str(tmp_path / "cut.gpkg"), CRS("EPSG:6707"), "CUTLINES")
    assert CRS(frame.crs).equals(CRS("EPSG:6707"))
    assert any(r.getMessage().startswith("CUTLINES transformed from EPSG:3003 to EPSG:6707")
               and "35160622_47161840_R40_F00.gsb" in r.getMessage() for r in caplog.records)
