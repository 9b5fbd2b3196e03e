"""Ortho defects of #25: ortho:photo keeps a 1-4 band photo's bands, in order, with one alpha
band, the last (a 4-band photo used to come out with band 2 tagged alpha as well, and a 2-band
one as red/green; three byte bands are written as RGB, as before); the default extent follows
the footprint densely on the DEM."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.enums import ColorInterp

import toolbox

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402


@pytest.fixture(scope="module")
def grey(tmp_path_factory):
    return scene.make_scene(tmp_path_factory.mktemp("bands_scene"))


@pytest.mark.parametrize("bands, photometric", [(1, "MINISBLACK"), (2, "MINISBLACK"),
                                                (4, "MINISBLACK"), (3, "RGB")])
def test_bands_kept_in_order_with_the_last_band_alpha(grey, tmp_path, bands, photometric):
    with rasterio.open(grey.photo_path) as src:
        a = src.read(1).astype(np.int32)
        profile = src.profile
    # band k is a known affine function of band 1, so the order can be checked after resampling
    stack = np.stack([a if k % 2 == 0 else 255 - a for k in range(bands)]).astype("uint8")
    profile.update(count=bands, photometric=photometric)
    photo = tmp_path / "p1.tif"
    with rasterio.open(photo, "w", **profile) as dst:
        dst.write(stack)
    toolbox.run("ortho:photo", {"INPUT": photo, "PROJECT": grey.project_path, "DEM": grey.dem_path,
                                "CELL_SIZE": 10.0, "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "o.tif") as src:
        out = src.read().astype(np.int32)
        interp = list(src.colorinterp)
    assert out.shape[0] == bands + 1
    assert interp[-1] == ColorInterp.alpha and ColorInterp.alpha not in interp[:-1]
    if photometric == "RGB":
        assert interp[:3] == [ColorInterp.red, ColorInterp.green, ColorInterp.blue]
    else:
        assert ColorInterp.red not in interp
    valid = out[-1] == 255
    assert valid.mean() > 0.3
    for k in range(1, bands):
        expected = out[0] if k % 2 == 0 else 255 - out[0]
        assert np.abs(out[k][valid] - expected[valid]).max() <= 1


@pytest.mark.parametrize("dtype", ["float32", "int16"])
def test_photo_types_without_a_gdal_alpha_get_nodata(grey, tmp_path, dtype):
    """GDAL reads an alpha band as the mask only in Byte and UInt16 rasters: a Float32 or Int16
    photo's ortho marks the outside with nodata (NaN; the type's minimum), so GDAL's mask (what
    mosaic:build, gdalwarp and QGIS read) is exactly the valid cells of the Byte photo's ortho,
    and the values are the Byte ortho's."""
    with rasterio.open(grey.photo_path) as src:
        profile, data = src.profile, src.read()
    profile.update(dtype=dtype, nodata=None)
    photo = tmp_path / "p1.tif"
    with rasterio.open(photo, "w", **profile) as dst:
        dst.write(data.astype(dtype))
    run = {"PROJECT": grey.project_path, "DEM": grey.dem_path, "CELL_SIZE": 10.0}
    toolbox.run("ortho:photo", {"INPUT": grey.photo_path, **run, "OUTPUT": tmp_path / "b.tif"})
    toolbox.run("ortho:photo", {"INPUT": photo, **run, "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "b.tif") as ref, rasterio.open(tmp_path / "o.tif") as out:
        assert ref.count == 2 and out.count == 1 and out.dtypes[0] == dtype
        expected_valid = ref.dataset_mask() > 0
        valid = out.dataset_mask() > 0
        assert 0.3 < valid.mean() < 0.95
        assert np.array_equal(valid, expected_valid)
        values = out.read(1).astype(float)
        assert np.abs(values[valid] - ref.read(1)[valid]).max() <= 1
        if dtype == "float32":
            assert np.isnan(out.nodata) and np.isnan(values[~valid]).all()
        else:
            assert out.nodata == -32768 and (values[~valid] == -32768).all()


def test_default_extent_reaches_into_a_valley_between_outline_samples(tmp_path):
    """A 300 m deep trench crosses the photo's east edge between two of the 8 outline points a
    side the footprint used to have: the edge's rays reach its floor 226 m further east
    (analytic: X0 + (Z0 - 0)·115/153). The default grid must include it."""
    from affine import Affine

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.plan import plan_photo
    from toolbox.photogrammetry.coverage import photo_footprint
    from toolbox.photogrammetry.synthetic import frame_photo

    x0, y0, z0 = 1688200.0, 4799200.0, 1700.0
    cell = 10.0
    xs = 1686400.0 + (np.arange(360) + 0.5) * cell
    ys = 4801000.0 - (np.arange(360) + 0.5) * cell
    z = np.full((360, 360), 300.0)
    trench = (ys[:, None] > y0 + 80) & (ys[:, None] < y0 + 190) & (xs[None, :] > x0 + 800)
    z[np.broadcast_to(trench, z.shape)] = 0.0
    dem = scene.write_dem(tmp_path / "trench.tif", z, Affine(cell, 0, 1686400.0, 0, -cell,
                                                             4801000.0))
    photo = frame_photo((x0, y0, z0), (0.0, 0.0, 0.0), width=800, height=800, crs=scene.CRS)
    plan = plan_photo(photo, open_raster_info(dem, "DEM"), scene.CRS, cell=5.0)
    floor_edge = x0 + z0 * 115.0 / 153.0
    assert plan.grid.bounds[2] >= floor_edge - 5.0, (plan.grid.bounds[2] - x0)
    sparse = photo_footprint(photo, plan.surface, 300.0, 8)  # the old outline misses it
    assert sparse.polygon.bounds[2] < x0 + 1100.0


def ortho_on(grey, dem, out):
    """The scene's photo orthorectified on ``dem`` at 10 m: its bands."""
    toolbox.run("ortho:photo", {"INPUT": grey.photo_path, "PROJECT": grey.project_path,
                                "DEM": dem, "CELL_SIZE": 10.0, "OUTPUT": out})
    with rasterio.open(out) as src:
        return src.read()


def test_dem_with_a_vertical_crs_stays_on_the_direct_path(grey, tmp_path):
    """A DEM in EPSG:3003 + EGM2008 height (compound) is the project's horizontal CRS: read
    directly (no reprojection of the cells), the same ortho as with the plain DEM."""
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler

    with rasterio.open(grey.dem_path) as src:
        z = src.read(1)
    dem = scene.write_dem(tmp_path / "dem_egm.tif", z, grey.transform, crs="EPSG:3003+3855")
    info = open_raster_info(dem, "DEM")
    assert info.crs.is_compound
    assert DemSampler(info, scene.CRS).transformer is None
    runs = {}
    for name, path in (("plain", grey.dem_path), ("compound", dem)):
        runs[name] = ortho_on(grey, path, tmp_path / f"{name}.tif")
    assert np.array_equal(runs["plain"], runs["compound"])


def test_integer_dem_with_nodata_in_another_crs_gives_the_float_dems_ortho(grey, tmp_path):
    """An Int16 DEM with a nodata hole, in UTM while the project is in EPSG:3003, is reprojected
    with its nodata as no height: the ortho of the same heights stored as Float32 with NaN
    (it took -32768 as a height: "rays do not meet the height plane", or a wrong ortho)."""
    from rasterio.enums import Resampling
    from rasterio.warp import calculate_default_transform, reproject

    with rasterio.open(grey.dem_path) as src:
        metres = np.rint(src.read(1)).astype("int16")
        profile = src.profile
    metres[30:36, 40:46] = -32768  # a hole under the photo's footprint
    runs = {}
    for dtype, nodata in (("int16", -32768), ("float32", float("nan"))):
        local = tmp_path / f"dem_{dtype}_3003.tif"
        with rasterio.open(local, "w", **(profile | {"dtype": dtype, "nodata": nodata})) as dst:
            dst.write(np.where(metres == -32768, nodata, metres).astype(dtype), 1)
        utm = tmp_path / f"dem_{dtype}_utm.tif"
        with rasterio.open(local) as src:  # gdalwarp -t_srs EPSG:32632 -tr 10 10 -r near
            t, w, h = calculate_default_transform(src.crs, "EPSG:32632", src.width,
                                                  src.height, *src.bounds, resolution=10.0)
            with rasterio.open(utm, "w", **(src.profile | {"crs": "EPSG:32632", "transform": t,
                                                           "width": w, "height": h})) as dst:
                reproject(rasterio.band(src, 1), rasterio.band(dst, 1),
                          resampling=Resampling.nearest)
        runs[dtype] = ortho_on(grey, utm, tmp_path / f"{dtype}.tif")
    assert np.array_equal(runs["int16"], runs["float32"])
    assert (runs["int16"][-1] > 0).mean() > 0.3  # an ortho, not an empty raster
