"""Round 16, algorithms chained on real data (Orthority's NGI frames): what one algorithm writes,
the next reads as written.

- the PointZ GeoPackages the toolbox writes (tie points, intersected points) serve as CONTROL:
  their coordinates are in the geometry, which the table reader did not look at;
- dem:match's per-pair sigma_z_m is the normal case's for half a pixel of the epipolar images
  it matched (it took a film-measurement 5 um whatever the pixel: 0.22 m on 153 um pixels);
- orientation:convert finds the images in any input's folder (only the first was searched: a
  camera file listed first left every photo without its image) or in IMAGES.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import toolbox

NGI_CRS = "+proj=tmerc +lon_0=25 +datum=WGS84 +units=m"


def point_layer(path: Path, rows, z: bool = True, extra: dict | None = None) -> Path:
    import geopandas as gpd
    import shapely

    geometry = [shapely.Point(x, y, h) if z else shapely.Point(x, y) for _, x, y, h in rows]
    frame = gpd.GeoDataFrame({"point_id": [r[0] for r in rows], **(extra or {})},
                             geometry=geometry, crs="EPSG:32633")
    frame.to_file(path, driver="GPKG", layer="tie_points")
    return path


ROWS = [("A", 500010.25, 4000020.5, 101.75), ("B", 500110.0, 4000030.125, 99.5),
        ("C", 500060.5, 4000120.0, 120.25)]


def test_control_from_a_pointz_geopackage_takes_the_geometry(tmp_path):
    from toolbox.triangulation.inputs import read_control

    control = read_control(point_layer(tmp_path / "p.gpkg", ROWS))
    assert control.ids == ["A", "B", "C"]
    np.testing.assert_array_equal(control.xyz, [r[1:] for r in ROWS])


def test_control_from_2d_points_is_planimetric_and_attributes_win(tmp_path):
    from toolbox.triangulation.inputs import read_control

    flat = read_control(point_layer(tmp_path / "p2.gpkg", ROWS, z=False))
    np.testing.assert_array_equal(flat.xyz[:, :2], [r[1:3] for r in ROWS])
    assert np.isnan(flat.xyz[:, 2]).all()  # no Z: planimetric points, as a blank Z column
    # a height attribute is the point's Z, not the geometry's (here 2D)
    height = read_control(point_layer(tmp_path / "p3.gpkg", ROWS, z=False,
                                      extra={"height": [1.0, 2.0, 3.0]}))
    np.testing.assert_array_equal(height.xyz[:, 2], [1.0, 2.0, 3.0])


def ngi_orientations(data: Path) -> dict[str, np.ndarray]:
    out = {}
    for line in (data / "ngi" / "camera_pos_ori.txt").read_text().splitlines():
        if line.strip():
            name, *values = line.split()
            out[name] = np.array([float(v) for v in values])
    return out


def test_match_sigma_z_is_for_half_an_epipolar_pixel(orthority_data, tmp_path):
    data = orthority_data
    project = tmp_path / "ngi.yaml"
    toolbox.run("orientation:convert", {
        "INPUT": f"{data / 'ngi' / 'camera_pos_ori.txt'},{data / 'io' / 'ngi_int_param.yaml'}",
        "CRS": NGI_CRS, "ANGLE_UNIT": "deg", "OUTPUT": project})
    low, high = 100.0, 1000.0
    out = toolbox.run("dem:match", {
        "PROJECT": project, "MIN_HEIGHT": low, "MAX_HEIGHT": high, "CELL_SIZE": 24.0,
        "OUTPUT": tmp_path / "dsm.tif", "COUNT": tmp_path / "n.tif",
        "SPREAD": tmp_path / "s.tif"})
    eo = ngi_orientations(data)
    pairs = out["STATISTICS"]["pairs"]
    assert pairs
    for pair in pairs:
        left, right = (eo[name] for name in pair["pair"].split("-"))
        base = float(np.linalg.norm(left[:3] - right[:3]))
        distance = (left[2] + right[2]) / 2 - (low + high) / 2
        # normal case: sigma_Z = (Z/B)·(Z/c)·sigma_p, sigma_p half the matched pixel, c 120 mm
        truth = distance / base * distance / 120.0 * 0.5 * pair["pixel_mm"]
        assert pair["sigma_z_m"] == pytest.approx(truth, rel=1e-9)
        assert pair["sigma_z_m"] > 2.0  # a 6 m pixel on the ground: metres, not 0.22 m


def test_convert_finds_images_in_any_input_folder_or_images(orthority_data, tmp_path):
    data = orthority_data
    names = sorted(p.stem for p in (data / "ngi").glob("3324c_*.tif"))
    first = tmp_path / "camera_first.yaml"
    out = toolbox.run("orientation:convert", {
        "INPUT": f"{data / 'io' / 'ngi_int_param.yaml'},{data / 'ngi' / 'camera_pos_ori.txt'}",
        "CRS": NGI_CRS, "ANGLE_UNIT": "deg", "OUTPUT": first})
    doc = yaml.safe_load(first.read_text())
    assert {p["id"]: Path(p["image"]).name for p in doc["photos"]} == \
        {n: f"{n}.tif" for n in names}
    assert json.dumps(out["SUMMARY"]).count("image paths") == 1
    # the Orthority io/ files: images in another folder, given as IMAGES
    given = tmp_path / "images_given.yaml"
    toolbox.run("orientation:convert", {
        "INPUT": f"{data / 'io' / 'ngi_int_param.yaml'},{data / 'io' / 'ngi_xyz_opk.csv'}",
        "IMAGES": str(data / "ngi"), "OUTPUT": given})
    doc = yaml.safe_load(given.read_text())
    assert [Path(p["image"]).resolve() for p in doc["photos"]] == \
        [(data / "ngi" / f"{p['id']}.tif").resolve() for p in doc["photos"]]


def test_convert_images_refusals(orthority_data, tmp_path):
    from tests.helpers_cli import assert_refused

    data = orthority_data
    inputs = f"{data / 'io' / 'ngi_int_param.yaml'},{data / 'io' / 'ngi_xyz_opk.csv'}"
    base = ["run", "orientation:convert", "--INPUT", inputs]
    line = assert_refused([*base, "--IMAGES", str(data / "io"), "--OUTPUT",
                           str(tmp_path / "a.yaml")], "IMAGES", (tmp_path / "a.yaml",))
    assert "no image file" in line
    assert_refused([*base, "--IMAGES", str(data / "ngi"), "--FORMAT_OUT", "csv", "--OUTPUT",
                    str(tmp_path / "a.csv")], "FORMAT_OUT project only", (tmp_path / "a.csv",))


X0, Y0 = 1688000.0, 4799000.0


def nadir_project(tmp_path: Path, crs: str = "EPSG:3003") -> Path:
    """One nadir photo, c = 150 mm, 900 m above the plane Z = 100."""
    path = tmp_path / "nadir.yaml"
    path.write_text("\n".join([
        "version: 1", f"crs: '{crs}'", "angle_unit: rad", "cameras:",
        "  - {name: cam, principal_distance_mm: 150.0, frame_size_mm: [230.0, 230.0],",
        "     image_size_px: [11500, 11500], pixel_size_mm: 0.02}", "photos:",
        f"  - {{id: n1, camera: cam, exterior: {{X0: {X0}, Y0: {Y0}, Z0: 1000.0, omega: 0.0, "
        "phi: 0.0, kappa: 0.0}}"]) + "\n")
    return path


def flat_dem(tmp_path: Path, crs: str) -> Path:
    from affine import Affine
    from pyproj import CRS
    from rasterio.crs import CRS as RasterioCRS

    from toolbox.raster.writer import write_raster

    path = tmp_path / f"dem_{crs.replace(':', '_').replace('+', '_')}.tif"
    write_raster(path, np.full((300, 400), 100.0, dtype="float32"),
                 Affine(10.0, 0, X0 - 1500.0, 0, -10.0, Y0 + 1500.0),
                 RasterioCRS.from_wkt(CRS(crs).to_wkt()), nodata=-9999.0)
    return path


def test_dem_published_with_its_vertical_datum_is_in_the_project_crs(tmp_path):
    """A DEM tagged 'projected + EGM2008 height' (as NGI's) is in the converted project's
    projected CRS: monoplot, footprints and precision refused it ('reproject the inputs to one
    CRS first'), ortho:batch took it. Truth: a ray at (20, -20) mm from 900 m meets Z = 100 at
    120 m east and south of the nadir point."""
    import geopandas as gpd

    from tests.helpers_cli import assert_refused

    project = nadir_project(tmp_path)
    table = tmp_path / "pts.csv"
    table.write_text("point_id,photo,x_mm,y_mm\ne,n1,20,-20\n")
    dem = flat_dem(tmp_path, "EPSG:3003+3855")
    out = toolbox.run("orientation:monoplot", {"PROJECT": project, "INPUT": table, "DEM": dem,
                                               "OUTPUT": tmp_path / "m.gpkg"})
    point = gpd.read_file(out["OUTPUT"], layer="points").geometry[0]
    assert (point.x, point.y, point.z) == pytest.approx((X0 + 120.0, Y0 - 120.0, 100.0))
    out = toolbox.run("orientation:footprints", {"PROJECT": project, "DEM": dem,
                                                 "OUTPUT": tmp_path / "f.gpkg"})
    area = gpd.read_file(out["OUTPUT"], layer="footprints")["area_m2"][0]
    assert area == pytest.approx((230.0 * 6.0) ** 2, rel=1e-9)  # photo scale 900/0.15
    # both state a height datum and they differ: refused, naming the DEM and both datums
    other = nadir_project(tmp_path, "EPSG:3003+5773")
    line = assert_refused(["run", "orientation:monoplot", "--PROJECT", str(other), "--INPUT",
                           str(table), "--DEM", str(dem), "--OUTPUT", str(tmp_path / "x.gpkg")],
                          "DEM heights are EGM2008", (tmp_path / "x.gpkg",))
    assert "EGM96" in line
    # another horizontal CRS is still refused
    assert_refused(["run", "orientation:monoplot", "--PROJECT", str(project), "--INPUT",
                    str(table), "--DEM", str(flat_dem(tmp_path, "EPSG:32632+3855")),
                    "--OUTPUT", str(tmp_path / "y.gpkg")], "reproject", (tmp_path / "y.gpkg",))


def test_ortho_check_takes_the_published_ngi_dem(orthority_data, tmp_path):
    """report:ortho_check on an NGI ortho with NGI's own DEM (compound CRS) and the project
    converted from Orthority's files (projected CRS only): refused before; now the check
    points, monoplotted on that DEM from pixels of the photo, are found where they are."""
    import csv

    import geopandas as gpd

    data = orthority_data
    project = tmp_path / "ngi.yaml"
    toolbox.run("orientation:convert", {
        "INPUT": f"{data / 'ngi' / 'camera_pos_ori.txt'},{data / 'io' / 'ngi_int_param.yaml'}",
        "CRS": NGI_CRS, "ANGLE_UNIT": "deg", "OUTPUT": project})
    dem = data / "ngi" / "dem.tif"
    photo = "3324c_2015_1004_05_0182_RGB"
    ortho = toolbox.run("ortho:photo", {"INPUT": data / "ngi" / f"{photo}.tif",
                                        "PROJECT": project, "PHOTO": photo, "DEM": dem,
                                        "CELL_SIZE": 10.0, "OUTPUT": tmp_path / "o.tif"})
    pixels = [(160.5, 300.5), (480.5, 300.5), (320.5, 576.5), (160.5, 850.5), (480.5, 850.5)]
    measurements = tmp_path / "m.csv"
    with open(measurements, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point_id", "photo", "col_px", "row_px"])
        w.writerows([f"P{k}", photo, c, r] for k, (c, r) in enumerate(pixels))
    mono = toolbox.run("orientation:monoplot", {"PROJECT": project, "INPUT": measurements,
                                                "DEM": dem, "OUTPUT": tmp_path / "p.gpkg"})
    points = gpd.read_file(mono["OUTPUT"], layer="points")
    check = tmp_path / "check.csv"
    check.write_text("id,X,Y,Z\n" + "".join(f"{i},{g.x!r},{g.y!r},{g.z!r}\n" for i, g in
                                             zip(points["point_id"], points.geometry,
                                                 strict=True)))
    out = toolbox.run("report:ortho_check", {"ORTHO": ortho["OUTPUT"], "PROJECT": project,
                                             "CHECK_POINTS": check, "MEASUREMENTS": measurements,
                                             "DEM": dem, "OUTPUT": tmp_path / "c.csv"})
    stats = out["STATISTICS"]
    assert stats["matched"] == len(pixels)
    assert stats["largest_m"] < 1.0  # truth 0 (same DEM and orientation); was 12.4 m


def test_gnss_and_imu_from_an_orientation_csv(tmp_path):
    """The orientation CSV orientation:convert writes (and Orthority's: ``filename,x,y,z,
    omega,phi,kappa``) as the bundle's GNSS and IMU: refused before ('no photo column'); now
    read, a file name ``id.tif`` standing for photo ``id``."""
    import types

    from toolbox.triangulation.inputs import _require_photos, read_attitudes, read_centres

    project = nadir_project(tmp_path)
    out = tmp_path / "eo.csv"
    toolbox.run("orientation:convert", {"INPUT": str(project), "FORMAT_OUT": "csv",
                                        "ANGLE_UNIT_OUT": "deg", "OUTPUT": out})
    assert out.read_text().splitlines()[0].startswith("filename,x,y,z,omega,phi,kappa")
    centres = read_centres(out)
    assert centres.photos == ["n1"]
    np.testing.assert_allclose(centres.xyz, [[X0, Y0, 1000.0]])
    attitudes = read_attitudes(out, "deg")
    np.testing.assert_allclose(attitudes.angles, [[0.0, 0.0, 0.0]], atol=1e-12)
    orthority = tmp_path / "orthority.csv"
    orthority.write_text(f"filename,x,y,z,omega,phi,kappa\nn1.tif,{X0},{Y0},1000,1.5,-2,90\n")
    np.testing.assert_allclose(read_attitudes(orthority, "deg").angles,
                               [np.radians([1.5, -2.0, 90.0])])
    fake = types.SimpleNamespace(photos={"n1": None, "n2.tif": None})
    assert _require_photos(["n1.tif", "n1", "n2.tif"], fake, "GNSS") == ["n1", "n1", "n2.tif"]
    with pytest.raises(Exception, match="GNSS names photo.*'n3.tif'"):
        _require_photos(["n3.tif"], fake, "GNSS")


def test_file_parameter_given_a_layer_reference_says_so(tmp_path):
    """CONTROL given 'bundle.gpkg|layername=points' (the bundle's own POINTS layer) was refused
    as 'file ... does not exist' though the file exists: the refusal names the real cause."""
    from tests.helpers_cli import assert_refused

    gpkg = point_layer(tmp_path / "p.gpkg", ROWS)
    (tmp_path / "m.csv").write_text("point_id,photo,x_mm,y_mm\nA,n1,0,0\n")
    line = assert_refused(["run", "orientation:check", "--PROJECT",
                           str(nadir_project(tmp_path)), "--INPUT", str(tmp_path / "m.csv"),
                           "--CONTROL", f"{gpkg}|layername=tie_points", "--REPORT",
                           str(tmp_path / "r.json")], "CONTROL takes a file, not a layer")
    assert "ogr2ogr out.gpkg p.gpkg tie_points" in line


def test_match_without_a_pair_names_the_rule_to_relax(orthority_data, tmp_path):
    """ODM's four 30-degree oblique views: no pair within MAX_ANGLE 30; the refusal said only
    'optical axes 43.2 deg apart', not which parameter allows it."""
    from tests.helpers_cli import assert_refused

    project = tmp_path / "odm.yaml"
    toolbox.run("orientation:convert", {
        "INPUT": str(orthority_data / "odm" / "opensfm" / "reconstruction.json"),
        "OUTPUT": project})
    line = assert_refused(["run", "dem:match", "--PROJECT", str(project), "--MIN_HEIGHT", "50",
                           "--MAX_HEIGHT", "140", "--CELL_SIZE", "0.5", "--OUTPUT",
                           str(tmp_path / "d.tif"), "--COUNT", str(tmp_path / "c.tif"),
                           "--SPREAD", str(tmp_path / "s.tif")], "no suitable stereo pair")
    assert "deg apart (MAX_ANGLE 30)" in line


def test_mosaic_takes_the_folder_of_ortho_batch(tmp_path):
    """ortho:batch writes its orthos into FOLDER; mosaic:seamlines / mosaic:build took only
    the files one by one (a folder was 'not recognized as a raster'). Now the folder stands for
    its GeoTIFFs, by name, hidden files and other files left: same cut polygons as the list."""
    import geopandas as gpd
    from affine import Affine

    from toolbox.raster.writer import write_raster

    folder = tmp_path / "orthos"
    folder.mkdir()
    rng = np.random.default_rng(1)
    for k, x0 in enumerate((500000.0, 500060.0)):
        write_raster(folder / f"p{k}.tif", rng.integers(1, 255, (1, 50, 100), dtype=np.uint8),
                     Affine(1.0, 0, x0, 0, -1.0, 4000050.0), "EPSG:32633")
    (folder / "orthos.json").write_text("[]")
    write_raster(folder / ".staged.tif", np.zeros((1, 5, 5), np.uint8),
                 Affine(1.0, 0, 0, 0, -1.0, 0), "EPSG:32633")
    runs = {}
    for name, value in (("folder", str(folder)),
                        ("list", [str(folder / "p0.tif"), str(folder / "p1.tif")])):
        out = toolbox.run("mosaic:seamlines", {"INPUT": value, "METHOD": "voronoi",
                                               "CENTRES": "footprint",
                                               "OUTPUT": tmp_path / f"{name}.gpkg"})
        runs[name] = gpd.read_file(out["OUTPUT"], layer="cut_polygons")
    assert runs["folder"]["source"].tolist() == ["p0", "p1"]
    assert runs["folder"].geometry.geom_equals(runs["list"].geometry).all()
    (tmp_path / "empty").mkdir()
    with pytest.raises(Exception, match="holds no GeoTIFF"):
        toolbox.run("mosaic:seamlines", {"INPUT": str(tmp_path / "empty"),
                                         "OUTPUT": tmp_path / "x.gpkg"})
