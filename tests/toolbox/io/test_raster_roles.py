"""Raster inputs by role (RasterLayer ``role``): a map or heights raster without a geotransform
(GCPs only, RPCs only, or nothing: GDAL gives the identity) is refused as "has no
georeferencing" with the gdalwarp command, before any north-up check (carto:contours wrote
contours in pixel coordinates, carto:sheet drew no BASE, footprints and dem:ground called it
"south-up", carto:profile "stations outside the surface"); a photo is read in pixels and stays
accepted. A heights band holding colours (a colour table, a photo's Red/Green/Blue band) is
refused naming the band (slopes and contours of colour indices came out, exit 0)."""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely
from affine import Affine
from rasterio.control import GroundControlPoint
from rasterio.enums import ColorInterp
from rasterio.rpc import RPC

import toolbox
from toolbox.parameters import RasterLayer, ValidationContext

X0, Y0, W, H = 1688000.0, 4800000.0, 60, 50
NORTH_UP = Affine(2, 0, X0, 0, -2, Y0)


def heights() -> np.ndarray:
    r, c = np.indices((H, W))
    return (100 + 0.5 * c + 0.3 * r).astype("float32")


def write(path, data, georef="transform", **extra):
    """A raster of ``data`` (bands, rows, cols) georeferenced by ``georef``: "transform", "gcps"
    (four corners, as gdal_translate -gcp writes them), "rpcs" or "none"."""
    profile = {"driver": "GTiff", "width": data.shape[2], "height": data.shape[1],
               "count": data.shape[0], "dtype": data.dtype.name} | extra
    if georef == "transform":
        profile |= {"crs": "EPSG:3003", "transform": NORTH_UP}
    elif georef == "gcps":
        corners = [(0, 0), (W, 0), (0, H), (W, H)]
        profile["gcps"] = [GroundControlPoint(row=r, col=c, x=X0 + 2 * c, y=Y0 - 2 * r)
                           for c, r in corners]
        profile["crs"] = "EPSG:3003"
    elif georef == "rpcs":
        profile["rpcs"] = RPC(height_off=100, height_scale=100, lat_off=43.3, lat_scale=0.01,
                              line_den_coeff=[1] + [0] * 19, line_num_coeff=[0, 0, -1] + [0] * 17,
                              line_off=H / 2, line_scale=H / 2, long_off=11.3, long_scale=0.01,
                              samp_den_coeff=[1] + [0] * 19, samp_num_coeff=[0, 1] + [0] * 18,
                              samp_off=W / 2, samp_scale=W / 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as dst:
            dst.write(data)
    with warnings.catch_warnings():  # what GDAL reads back: the identity for every non-transform
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path) as src:
            assert src.transform.is_identity == (georef != "transform")
    return path


def line(tmp_path):
    path = tmp_path / "line.gpkg"
    gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 10, Y0 - 10), (X0 + 90, Y0 - 80)])],
                     crs="EPSG:3003").to_file(path)
    return path


def points(tmp_path):
    path = tmp_path / "points.gpkg"
    xy = [(X0 + 10, Y0 - 10), (X0 + 100, Y0 - 20), (X0 + 50, Y0 - 90), (X0 + 20, Y0 - 60)]
    gpd.GeoDataFrame({"z": [1.0, 2.0, 3.0, 4.0]}, crs="EPSG:3003",
                     geometry=[shapely.Point(x, y, z) for (x, y), z in zip(xy, range(4))]
                     ).to_file(path)
    return path


def runs(tmp_path, raster):
    """(algorithm, parameters, the raster's parameter, output) for every kind of raster input."""
    return [
        ("dem:slope", {"INPUT": raster}, "INPUT", tmp_path / "slope.tif"),
        ("carto:contours", {"INPUT": raster, "INTERVAL": 5.0}, "INPUT", tmp_path / "c.gpkg"),
        ("carto:profile", {"INPUT": line(tmp_path), "DEM": raster}, "DEM", tmp_path / "p.gpkg"),
        ("dem:ground", {"DSM": raster, "NONGROUND": tmp_path / "ng.tif"}, "DSM",
         tmp_path / "g.tif"),
        ("dem:idw", {"INPUT": points(tmp_path), "TEMPLATE": raster}, "TEMPLATE",
         tmp_path / "idw.tif"),
        ("carto:sheet", {"EXTENT": f"{X0},{Y0 - 100},{X0 + 120},{Y0} [EPSG:3003]",
                         "SCALE": 2000, "BASE": raster}, "BASE", tmp_path / "s.pdf"),
        ("mosaic:build", {"INPUT": [raster]}, "INPUT", tmp_path / "m.tif"),
        ("mosaic:cut", {"INPUT": raster, "SCALE": 1000, "SHEET_WIDTH": 50, "SHEET_HEIGHT": 50},
         "INPUT", tmp_path / "cut"),
    ]


@pytest.mark.parametrize("georef, how", [
    ("gcps", r"only 4 ground control points\): warp it first: gdalwarp '.*' warped\.tif"),
    ("rpcs", r"only RPCs\): warp it first: gdalwarp -rpc"),
    ("none", r": its cells have no map position")])
def test_a_raster_without_geotransform_is_refused_where_map_coordinates_are_needed(
        tmp_path, georef, how):
    raster = write(tmp_path / f"{georef}.tif", heights()[None], georef)
    for algorithm, params, name, output in runs(tmp_path, raster):
        with pytest.raises(toolbox.ParameterError,
                           match=f"^{name} '{re.escape(str(raster))}' has no georeferencing"
                                 f"( \\(|){how}"):
            toolbox.run(algorithm, params | {"OUTPUT": output})
        assert not output.exists(), algorithm


def test_footprints_say_no_georeferencing_not_south_up(tmp_path):
    sys.path.insert(0, str(Path(__file__).parents[2] / "algorithms" / "ortho"))
    import ortho_scene

    scene = ortho_scene.make_scene(tmp_path)
    dem = write(tmp_path / "gcps.tif", heights()[None], "gcps")
    with pytest.raises(toolbox.ParameterError, match="DEM .* has no georeferencing") as err:
        toolbox.run("orientation:footprints", {"PROJECT": scene.project_path, "DEM": dem,
                                               "OUTPUT": tmp_path / "fp.gpkg"})
    assert "south-up" not in str(err.value) and not (tmp_path / "fp.gpkg").exists()


@pytest.mark.parametrize("georef", ["gcps", "rpcs", "none"])
def test_a_photo_without_geotransform_is_still_accepted(tmp_path, georef):
    photo = write(tmp_path / "photo.tif", np.zeros((3, H, W), "uint8"), georef,
                  photometric="RGB")
    info = RasterLayer("INPUT", role="photo").validate(photo, ValidationContext())
    assert info.width == W and not info.georeferenced


def test_the_cli_refuses_in_one_line_with_exit_2(tmp_path):
    raster = write(tmp_path / "gcps.tif", heights()[None], "gcps")
    run = subprocess.run([sys.executable, "-m", "toolbox", "run", "carto:contours", "--INPUT",
                          str(raster), "--INTERVAL", "5", "--OUTPUT", str(tmp_path / "c.gpkg")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "has no georeferencing" in lines[0] and "gdalwarp" in lines[0]
    assert not (tmp_path / "c.gpkg").exists()


def paletted_dem(path):
    data = np.clip(heights() - 100, 0, 255).astype("uint8")[None]
    write(path, data, photometric="palette")
    with rasterio.open(path, "r+") as dst:
        dst.write_colormap(1, {k: (k, 255 - k, 0, 255) for k in range(256)})
    with rasterio.open(path) as src:  # what GDAL reads: a paletted band
        assert src.colorinterp == (ColorInterp.palette,)
    return path


def rgb_photo(path):
    data = np.stack([np.clip(heights() - 100 + 20 * k, 0, 255) for k in range(3)]).astype("uint8")
    write(path, data, photometric="RGB")
    with rasterio.open(path) as src:
        assert src.colorinterp == (ColorInterp.red, ColorInterp.green, ColorInterp.blue)
    return path


@pytest.mark.parametrize("algorithm, extra, name", [
    ("dem:slope", {}, "INPUT"), ("carto:contours", {"INTERVAL": 5.0}, "INPUT")])
def test_a_paletted_band_is_refused_as_heights(tmp_path, algorithm, extra, name):
    dem = paletted_dem(tmp_path / "pal.tif")
    out = tmp_path / ("o.gpkg" if algorithm == "carto:contours" else "o.tif")
    with pytest.raises(toolbox.ParameterError,
                       match=f"^{name} '{re.escape(str(dem))}' band 1 \\(chosen by BAND\\) has "
                             r"a colour table \(palette\): its values are colour codes, not "
                             "heights"):
        toolbox.run(algorithm, {"INPUT": dem, "OUTPUT": out} | extra)
    assert not out.exists()


def test_a_photo_colour_band_is_refused_as_heights(tmp_path):
    photo = rgb_photo(tmp_path / "rgb.tif")
    with pytest.raises(toolbox.ParameterError,
                       match=f"^DSM '{re.escape(str(photo))}' band 1 has colour interpretation "
                             "Red: a photo's colour channel, not heights"):
        toolbox.run("dem:ground", {"DSM": photo, "OUTPUT": tmp_path / "g.tif",
                                   "NONGROUND": tmp_path / "ng.tif"})
    with pytest.raises(toolbox.ParameterError,
                       match=f"^INPUT '{re.escape(str(photo))}' band 2 \\(chosen by BAND\\) "
                             "has colour interpretation Green"):
        toolbox.run("dem:slope", {"INPUT": photo, "BAND": 2, "OUTPUT": tmp_path / "s.tif"})
    assert not any(tmp_path.glob("[gns]*.tif"))


def test_a_grey_band_of_a_multiband_dem_is_heights(tmp_path):
    dem = write(tmp_path / "three.tif", np.stack([heights()] * 3))  # Gray, Undefined, Undefined
    toolbox.run("dem:slope", {"INPUT": dem, "BAND": 2, "OUTPUT": tmp_path / "s.tif"})
    with rasterio.open(tmp_path / "s.tif") as src:
        slope = src.read(1)[1:-1, 1:-1]
    np.testing.assert_allclose(slope, np.degrees(np.arctan(np.hypot(0.5, 0.3) / 2)), atol=1e-3)
