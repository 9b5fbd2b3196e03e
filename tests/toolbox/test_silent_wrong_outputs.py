"""Silent wrong outputs of issue 24 §4, now refused or corrected with a warning: geographic or
wrong CRSs where an algorithm works in metres, model coordinates labelled with a map CRS, orthos
without a CRS, hull vertices predicted by dem:cross_validate without EXTRAPOLATE."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import yaml
from shapely.geometry import LineString, Point

import toolbox
from toolbox.errors import InputDataError, ParameterError

sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "attribution"))
sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
import ortho_scene as scene  # noqa: E402
from restitution_files import make_files  # noqa: E402

E0, N0 = 1688000.0, 4799000.0


def test_attribution_apply_refuses_degrees_and_unplaced_model_coordinates(tmp_path):
    files = make_files(tmp_path)
    lonlat = tmp_path / "ll.gpkg"
    gpd.GeoDataFrame({"code": ["STR02001"]}, geometry=[LineString([(11.3, 43.3, 0),
                                                                    (11.31, 43.31, 0)])],
                     crs="EPSG:4326").to_file(lonlat)
    with pytest.raises(ParameterError, match="INPUT is in the geographic CRS EPSG:4326"):
        toolbox.run("attribution:apply", {"INPUT": lonlat, "CODES": files["codes"],
                                          "OUTPUT": tmp_path / "a.gpkg"})
    # the ASCII export holds model coordinates (x = 500 m): without PARAMETERS' translation
    # they are no EPSG:3003 coordinates
    with pytest.raises(InputDataError, match="coordinate translation"):
        toolbox.run("attribution:apply", {"INPUT": files["export"], "CODES": files["codes"],
                                          "CRS": "EPSG:3003", "OUTPUT": tmp_path / "a.gpkg"})
    assert not (tmp_path / "a.gpkg").exists()
    out = toolbox.run("attribution:apply", {"INPUT": files["export"], "CODES": files["codes"],
                                            "PARAMETERS": files["params"], "CRS": "EPSG:3003",
                                            "OUTPUT": tmp_path / "a.gpkg"})
    assert out["STATISTICS"]["resolved"] == 5


def test_absolute_orientation_crs_is_a_crs(tmp_path):
    model = np.array([[0, 0, 0], [10, 0, 1], [0, 10, 2], [10, 10, 0], [5, 5, 3.0]])
    ground = model * 2 + [E0, N0, 300.0]
    (tmp_path / "m.csv").write_text("id,X,Y,Z\n" + "".join(
        f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(model)))
    (tmp_path / "c.csv").write_text("id,X,Y,Z\n" + "".join(
        f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(ground)))
    base = {"INPUT": tmp_path / "m.csv", "CONTROL": tmp_path / "c.csv",
            "OUTPUT": tmp_path / "a.gpkg", "REPORT": tmp_path / "a.json"}
    with pytest.raises(ParameterError, match="^CRS .*'abc'"):
        toolbox.run("orientation:absolute", base | {"CRS": "abc"})
    with pytest.raises(ParameterError, match="^CRS is in the geographic CRS EPSG:4326"):
        toolbox.run("orientation:absolute", base | {"CRS": "EPSG:4326"})
    toolbox.run("orientation:absolute", base | {"CRS": "EPSG:3003"})
    assert gpd.read_file(tmp_path / "a.gpkg").crs.to_epsg() == 3003


def _rectify_refused(tmp_path, crs: str, image_to_ground: list, message: str) -> None:
    """rectify:image of tmp_path/photo.tif by an affine TRANSFORM in ``crs`` is refused with a
    ParameterError matching ``message``, and writes nothing."""
    doc = {"format": "toolbox.rectify.transform", "version": 1, "model": "affine",
           "image_units": "pixels", "crs": crs, "image_to_ground": image_to_ground}
    (tmp_path / "t.json").write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match=message):
        toolbox.run("rectify:image", {"INPUT": tmp_path / "photo.tif",
                                      "TRANSFORM": tmp_path / "t.json",
                                      "OUTPUT": tmp_path / "r.tif"})
    assert not (tmp_path / "r.tif").exists()


def test_rectify_refuses_a_transform_in_degrees(tmp_path):
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    write_raster(tmp_path / "photo.tif", np.ones((20, 20), "uint8"), from_origin(0, 20, 1, 1),
                 None)
    _rectify_refused(tmp_path, "EPSG:4326", [[1e-4, 0, 11.3], [0, -1e-4, 43.3], [0, 0, 1]],
                     "^TRANSFORM is in the geographic CRS EPSG:4326")


def test_orthos_of_a_project_without_crs_take_the_dem_crs(tmp_path):
    sc = scene.make_scene(tmp_path)
    doc = yaml.safe_load(sc.project_path.read_text())
    del doc["crs"]
    project = tmp_path / "nocrs.yaml"
    project.write_text(yaml.safe_dump(doc))
    feedback = toolbox.Feedback()
    toolbox.run("ortho:photo", {"INPUT": sc.photo_path, "PROJECT": project, "DEM": sc.dem_path,
                                "CELL_SIZE": 20, "OUTPUT": tmp_path / "o.tif"},
                feedback=feedback)
    with rasterio.open(tmp_path / "o.tif") as src:
        assert src.crs.to_epsg() == 3003  # the DEM's (scene.CRS)
    assert any("DEM's, EPSG:3003" in w for w in feedback.warnings)
    feedback = toolbox.Feedback()
    toolbox.run("ortho:batch", {"PROJECT": project, "DEM": sc.dem_path, "CELL_SIZE": 20,
                                "FOLDER": tmp_path / "block", "OUTPUT": tmp_path / "b.json"},
                feedback=feedback)
    with rasterio.open(tmp_path / "block" / "p1.tif") as src:
        assert src.crs.to_epsg() == 3003
    assert any("DEM's, EPSG:3003" in w for w in feedback.warnings)


def test_cross_validation_of_collinear_points_leaves_the_ends_out(tmp_path):
    """Points on one straight line: the hull is a segment, its two ends lie outside the hull of
    the others (they were predicted, i.e. extrapolated, before); with EXTRAPOLATE they are."""
    x = np.linspace(0.0, 1000.0, 30)
    z = 100.0 + 0.05 * x
    gpd.GeoDataFrame({"z": z}, geometry=[Point(E0 + a, N0, c) for a, c in zip(x, z, strict=True)],
                     crs="EPSG:3003").to_file(tmp_path / "p.gpkg")
    for extrapolate, expected in ((False, [False, True, False]), (True, [True, True, True])):
        out = toolbox.run("dem:cross_validate", {
            "INPUT": tmp_path / "p.gpkg", "METHODS": "nearest,idw", "EXTRAPOLATE": extrapolate,
            "OUTPUT": tmp_path / "cv.json", "RESIDUALS": tmp_path / "cv.gpkg"}, overwrite=True)
        residuals = gpd.read_file(tmp_path / "cv.gpkg")
        for method in ("nearest", "idw"):
            assert list(np.isfinite(residuals[f"{method}_z"].to_numpy()[[0, 1, -1]])) == expected
        if not extrapolate:
            assert out["STATISTICS"]["methods"]["idw"]["hull_vertices_not_predicted"] == 2


def test_sheets_20_km_from_the_data_are_refused(tmp_path):
    """carto:sheet and mosaic:cut on data of another area wrote empty results with exit 0."""
    import shapely
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    write_raster(tmp_path / "dem.tif", np.full((40, 50), 300.0, "float32"),
                 from_origin(E0, N0 + 400, 10, 10), "EPSG:3003", nodata=-9999.0)
    far = (E0 + 20000, N0, E0 + 21000, N0 + 1000)
    gpd.GeoDataFrame({"id": ["a"]}, geometry=[shapely.box(*far)], crs="EPSG:3003"
                     ).to_file(tmp_path / "sheets.gpkg")
    with pytest.raises(InputDataError, match="no input .* meets the sheets"):
        toolbox.run("carto:sheet", {"EXTENT": ",".join(map(str, far)) + " [EPSG:3003]",
                                    "BASE": tmp_path / "dem.tif",
                                    "OUTPUT": tmp_path / "s.pdf"})
    with pytest.raises(InputDataError, match="no sheet of SHEETS .* meets INPUT"):
        toolbox.run("mosaic:cut", {"INPUT": tmp_path / "dem.tif",
                                   "SHEETS": tmp_path / "sheets.gpkg",
                                   "OUTPUT": tmp_path / "cut"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif", "sheets.gpkg"]


def test_a_dem_far_outside_its_crs_area_is_refused(tmp_path):
    """A GeoTIFF's CRS read back as WKT has no area of use: it is taken from the matching EPSG
    code, so dem:slope refuses local coordinates labelled EPSG:3003 as the DEM methods do."""
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    z = np.random.default_rng(0).uniform(100, 200, (20, 20)).astype("float32")
    write_raster(tmp_path / "local.tif", z, from_origin(300, 500, 10, 10), "EPSG:3003",
                 nodata=-9999.0)
    for algorithm in ("dem:slope", "dem:aspect"):
        with pytest.raises(InputDataError, match="outside the area of use of EPSG:3003"):
            toolbox.run(algorithm, {"INPUT": tmp_path / "local.tif",
                                    "OUTPUT": tmp_path / "o.tif"})
    write_raster(tmp_path / "map.tif", z, from_origin(E0, N0, 10, 10), "EPSG:3003",
                 nodata=-9999.0)
    toolbox.run("dem:slope", {"INPUT": tmp_path / "map.tif", "OUTPUT": tmp_path / "o.tif"})


@pytest.mark.parametrize("pixels, nodata", [(np.zeros((20, 20), "uint8"), 0),
                                            (np.full((20, 20), np.nan, "float32"), None)])
def test_rectify_refuses_a_photo_without_a_valid_pixel(tmp_path, pixels, nodata):
    """All nodata gave a transparent output, all NaN an opaque one of NaN cells."""
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    write_raster(tmp_path / "photo.tif", pixels, from_origin(0, 20, 1, 1), None, nodata=nodata)
    _rectify_refused(tmp_path, "EPSG:3003", [[1, 0, E0], [0, -1, N0 + 20], [0, 0, 1]],
                     "^INPUT .* has no valid pixel")


def test_resection_refuses_control_points_far_outside_the_project_crs(tmp_path):
    """Control coordinates in a local system with a project in EPSG:3003 were accepted."""
    from toolbox.demo.samples import siena

    made = siena.make(tmp_path, {})
    ground = Path(made["siena_control_ground"])
    lines = ground.read_text().splitlines()
    local = [lines[0]]
    for line in lines[1:]:
        pid, x, y, *rest = line.split(",")
        local.append(",".join([pid, f"{float(x) - 1687000:.3f}", f"{float(y) - 4799000:.3f}",
                               *rest]))
    (tmp_path / "local.csv").write_text("\n".join(local) + "\n")
    with pytest.raises(InputDataError, match="^CONTROL: coordinates .* outside the area of use"):
        toolbox.run("orientation:resection", {
            "PROJECT": made["siena_project"], "INPUT": made["siena_control_image_points"],
            "CONTROL": tmp_path / "local.csv", "OUTPUT": tmp_path / "r.yaml"})
    assert not (tmp_path / "r.yaml").exists()
