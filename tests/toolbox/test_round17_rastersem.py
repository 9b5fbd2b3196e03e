"""Round 17, raster metadata semantics: what GDAL's metadata of a raster says, honoured or refused.

- a DEM whose band unit says feet (GDAL's unit type "ft", "US survey foot") was read as metres in
  silence: dem:slope of a 45 degree plane stored in feet gave 73.05 degrees, ortho:photo and
  tin:volume took its heights for metres; now refused (exit 2) with the gdal_calc.py command that
  converts them (or Z_FACTOR where the algorithm has one);
- a complex DEM (a SAR product) was read as heights with a numpy warning (imaginary parts
  dropped, exit 0); now refused (exit 2) with the gdal_translate command that writes the real part;
- a photo (read in pixels) carrying georeferencing of its own (a world file, lon/lat corners) was
  refused by ortho:photo as "in the geographic CRS EPSG:4326 ...: reproject it" (exit 2: warping
  the photo would spoil its orientation) or warned about as "taken to be in" the project's CRS;
  photos are now left out of the CRS checks;
- mosaic:cut of a raster without nodata or alpha band (every value valid) tagged its sheets
  nodata 0: the valid zeros (sea level in an int16 DEM, black in a photo) became no data in
  silence (gdal_translate -projwin keeps them); now NaN nodata for floats, else an alpha band;
  mosaic:build of such orthos likewise wrote nodata 0 (black pixels lost); now the same rule;
- an alpha band of another type than Byte or UInt16 (an Int16 DEM + alpha) is no mask to GDAL:
  RasterWriter now also writes it as the internal mask (cells outside were valid data);
- the raster engine took band 1's nodata for every band: dem:slope BAND=2 of a VRT whose bands
  have nodata of their own read band 2's nodata cells (-32768) as heights (slopes of 89.97
  degrees beside them, exit 0; gdaldem -b 2: 45 everywhere); each band's own nodata now;
- a south-up DEM given to ortho:photo, monoplot, precision or control was refused as "the DEM
  must be north-up" without the file or the command; now as footprints does (DEM, gdalwarp);
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import toolbox
from toolbox.errors import ParameterError


def plane_dem(path: Path, unit: str | None = None, factor: float = 1.0, crs: str = "EPSG:32632",
              dtype: str = "float32", nodata: float | None = -9999.0,
              origin: tuple[float, float] = (500000, 5000200)) -> Path:
    """A 20 x 20 DEM of 10 m cells (metres) rising 45 degrees to the east, its heights stored
    divided by ``factor`` (metres per stored unit) with band unit ``unit``."""
    import rasterio
    from rasterio.transform import from_origin

    z = np.tile((np.arange(20) + 0.5) * 10.0, (20, 1)) / factor
    profile = {"driver": "GTiff", "width": 20, "height": 20, "count": 1, "dtype": dtype,
               "crs": crs, "transform": from_origin(*origin, 10, 10), "nodata": nodata}
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(z.astype(dtype), 1)
        if unit is not None:
            dst.units = (unit,)
    return path


def centre_value(path: Path) -> float:
    import rasterio

    with rasterio.open(path) as src:
        return float(src.read(1)[10, 10])


@pytest.mark.parametrize(("unit", "factor"), [("ft", 0.3048), ("US survey foot", 1200 / 3937)])
def test_slope_of_a_dem_in_feet_is_refused_with_the_conversion(tmp_path, unit, factor):
    dem = plane_dem(tmp_path / "ft.tif", unit, factor)
    with pytest.raises(ParameterError, match=rf"^INPUT .*'{unit}'.*metre.*gdal_calc.py .*"
                                             rf"A\*{factor:.4f}.*Z_FACTOR"):
        toolbox.run("dem:slope", {"INPUT": dem, "OUTPUT": tmp_path / "s.tif"})
    out = toolbox.run("dem:slope", {"INPUT": dem, "Z_FACTOR": factor,
                                    "OUTPUT": tmp_path / "z.tif"})  # the conversion given
    assert centre_value(out["OUTPUT"]) == pytest.approx(45.0, abs=1e-3)


def test_slope_of_a_dem_in_metres_or_unlabelled_runs(tmp_path):
    for unit in (None, "m", "metre"):
        dem = plane_dem(tmp_path / f"{unit}.tif", unit)
        out = toolbox.run("dem:slope", {"INPUT": dem, "OUTPUT": tmp_path / f"s_{unit}.tif"})
        assert centre_value(out["OUTPUT"]) == pytest.approx(45.0, abs=1e-3)


def test_heights_in_metres_on_a_crs_in_feet_are_refused_where_units_must_agree(tmp_path):
    # EPSG:2229 (NAD83 California zone 5, US feet): a slope mixes x, y in feet with heights in m
    dem = plane_dem(tmp_path / "m.tif", "m", crs="EPSG:2229", origin=(6500000, 1900000))
    with pytest.raises(ParameterError, match=r"^INPUT .*'m'.*US survey foot.*A\*3\.28083"):
        toolbox.run("dem:slope", {"INPUT": dem, "OUTPUT": tmp_path / "s.tif"})


def test_feet_of_a_crs_in_us_feet_pass(tmp_path):
    # heights labelled "ft" (international) on a CRS in US survey feet: 2 ppm apart, no refusal
    dem = plane_dem(tmp_path / "ft.tif", "ft", crs="EPSG:2229", origin=(6500000, 1900000))
    out = toolbox.run("dem:slope", {"INPUT": dem, "OUTPUT": tmp_path / "s.tif"})
    assert centre_value(out["OUTPUT"]) == pytest.approx(45.0, abs=1e-3)


def test_contours_keep_heights_in_their_own_unit(tmp_path):
    dem = plane_dem(tmp_path / "ft.tif", "ft", 0.3048)
    toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 50,
                                   "OUTPUT": tmp_path / "c.gpkg"})  # levels in feet: fine


def test_require_height_unit_for_an_algorithm_in_metres(tmp_path):
    from toolbox.io.raster import open_raster_info, require_height_unit

    info = open_raster_info(plane_dem(tmp_path / "ft.tif", "ft", 0.3048), "DEM", "heights")
    assert info.units == ("ft",)
    with pytest.raises(ParameterError, match=r"^DEM .*'ft'.*ortho:photo reads heights in "
                                             r"metres.*A\*0\.3048"):
        require_height_unit(info, "DEM", 1, "ortho:photo", "metre")
    require_height_unit(info, "DEM", 1, "carto:contours", "horizontal")


def test_complex_dem_is_refused(tmp_path):
    dem = plane_dem(tmp_path / "c.tif", dtype="complex64", nodata=None)
    with pytest.raises(ParameterError, match=r"^INPUT .*complex numbers \(complex64\).*"
                                             r"gdal_translate -ot Float32 -b 1"):
        toolbox.run("dem:slope", {"INPUT": dem, "OUTPUT": tmp_path / "s.tif"})
    assert not (tmp_path / "s.tif").exists()


def test_a_photo_is_not_held_to_the_crs_rules(tmp_path):
    import rasterio
    from rasterio.transform import from_bounds

    from toolbox.io.raster import open_raster_info
    from toolbox.registry import get
    from toolbox.runner import check_parameter_crs

    path = tmp_path / "photo.tif"
    with rasterio.open(path, "w", driver="GTiff", width=8, height=8, count=1, dtype="uint8",
                       crs="EPSG:4326", transform=from_bounds(11.3, 43.31, 11.32, 43.33, 8, 8)
                       ) as dst:
        dst.write(np.zeros((8, 8), "uint8"), 1)
    alg = get("ortho:photo")
    photo = next(p for p in alg.parameters if p.name == "INPUT")
    dem = next(p for p in alg.parameters if p.name == "DEM")
    info = open_raster_info(path, "INPUT", "photo")
    warnings: list[str] = []
    check_parameter_crs(alg, photo, info, warnings)  # read in pixels: its CRS is not used
    assert warnings == []
    with pytest.raises(ParameterError, match=r"^DEM is in the geographic CRS"):
        check_parameter_crs(alg, dem, open_raster_info(path, "DEM", "heights"), warnings)


@pytest.mark.parametrize(("dtype", "count"), [("int16", 1), ("uint8", 3), ("float32", 1)])
def test_cut_keeps_the_valid_zeros_of_a_raster_without_nodata(tmp_path, dtype, count):
    import rasterio
    from rasterio.transform import from_origin

    values = np.arange(400).reshape(20, 20) % 200  # zeros at (0, 0) and (10, 0): valid
    src = tmp_path / "src.tif"
    with rasterio.open(src, "w", driver="GTiff", width=20, height=20, count=count, dtype=dtype,
                       crs="EPSG:32632", transform=from_origin(500000, 5000200, 10, 10)) as dst:
        dst.write(np.stack([values] * count).astype(dtype))
    out = toolbox.run("mosaic:cut", {"INPUT": src, "SCALE": 1000, "SHEET_WIDTH": 10,
                                     "SHEET_HEIGHT": 10, "ORIGIN_X": 500000,
                                     "ORIGIN_Y": 5000000, "OUTPUT": tmp_path / "out"})
    sheet = Path(out["OUTPUT"]) / "0_1.tif"  # the north-west sheet: cells (0..9, 0..9)
    with rasterio.open(sheet) as cut:
        assert cut.transform.c == 500000 and cut.transform.f == 5000200
        assert (cut.dataset_mask() > 0).all()  # every cell valid, the zero at (0, 0) too
        np.testing.assert_array_equal(cut.read(list(range(1, count + 1))),
                                      np.stack([values[:10, :10]] * count).astype(dtype))


@pytest.mark.parametrize(("dtype", "count"), [("uint8", 3), ("float32", 1)])
def test_mosaic_keeps_the_valid_zeros_of_orthos_without_nodata(tmp_path, dtype, count):
    import rasterio
    from rasterio.transform import from_origin

    inputs = []
    for k in range(2):  # two adjacent 20 x 20 orthos, every value valid, zeros included
        values = (np.arange(400).reshape(20, 20) * (k + 1)) % 200
        path = tmp_path / f"o{k}.tif"
        with rasterio.open(path, "w", driver="GTiff", width=20, height=20, count=count,
                           dtype=dtype, crs="EPSG:32632",
                           transform=from_origin(500000 + 200 * k, 5000200, 10, 10)) as dst:
            dst.write(np.stack([values] * count).astype(dtype))
        inputs.append(path)
    out = toolbox.run("mosaic:build", {"INPUT": inputs, "BLEND": "none", "COG": False,
                                       "OUTPUT": tmp_path / "m.tif"})
    with rasterio.open(out["OUTPUT"]) as mosaic:
        assert (mosaic.width, mosaic.height) == (40, 20)
        assert (mosaic.dataset_mask() > 0).all()  # the zeros (0, 0), (10, 0)... are valid
        assert (mosaic.read_masks(1) > 0).all()
        np.testing.assert_array_equal(mosaic.read(1)[:, :20], np.arange(400).reshape(20, 20)
                                      % 200)


def test_int16_alpha_is_also_written_as_the_mask(tmp_path):
    import rasterio
    from rasterio.transform import from_origin

    from toolbox.io.grid import GridSpec
    from toolbox.raster.writer import RasterWriter

    grid = GridSpec(from_origin(500000, 5000200, 10, 10), 8, 8, "EPSG:32632")
    data = np.zeros((2, 8, 8), "int16")
    data[1, :, :4] = 32767  # west half opaque (values 0: valid heights), east half outside
    with RasterWriter(tmp_path / "a.tif", grid, 2, "int16", alpha=True) as dst:
        dst.write(rasterio.windows.Window(0, 0, 8, 8), data)
    with rasterio.open(tmp_path / "a.tif") as src:  # GDAL's mask, as QGIS and gdalwarp read it
        np.testing.assert_array_equal(src.read_masks(1) > 0, data[1] > 0)


def test_mosaic_of_int16_orthos_without_nodata_masks_the_gap(tmp_path):
    import rasterio
    from rasterio.transform import from_origin

    inputs = []
    for k in range(2):  # 20 x 20 cells each, apart: the mosaic's 50 x 30 grid has a gap
        path = tmp_path / f"o{k}.tif"
        with rasterio.open(path, "w", driver="GTiff", width=20, height=20, count=1,
                           dtype="int16", crs="EPSG:32632",
                           transform=from_origin(500000 + 300 * k, 5000200 - 100 * k, 10, 10)
                           ) as dst:
            dst.write(((np.arange(400).reshape(20, 20) * (k + 1)) % 200).astype("int16"), 1)
        inputs.append(path)
    out = toolbox.run("mosaic:build", {"INPUT": inputs, "BLEND": "none",
                                       "OUTPUT": tmp_path / "m.tif"})
    with rasterio.open(out["OUTPUT"]) as mosaic:
        mask = mosaic.read_masks(1) > 0
        assert (mosaic.width, mosaic.height) == (50, 30)
        assert mask.sum() == 800 and mask[0, 0] and mosaic.read(1)[0, 0] == 0


def two_band_vrt(tmp_path: Path) -> Path:
    """A VRT of two 45 degree planes, band 1 with nodata -9999, band 2 with nodata -32768 (a
    2 x 2 hole each, in different places)."""
    import rasterio
    from rasterio.transform import from_origin

    z = np.tile((np.arange(20) + 0.5) * 10.0, (20, 1)).astype("float32")
    bands = ""
    for k, (nodata, hole) in enumerate(((-9999, 2), (-32768, 10)), start=1):
        values = z.copy()
        values[hole:hole + 2, hole:hole + 2] = nodata
        with rasterio.open(tmp_path / f"b{k}.tif", "w", driver="GTiff", width=20, height=20,
                           count=1, dtype="float32", crs="EPSG:32632", nodata=nodata,
                           transform=from_origin(500000, 5000200, 10, 10)) as dst:
            dst.write(values, 1)
        bands += (f'<VRTRasterBand dataType="Float32" band="{k}"><NoDataValue>{nodata}'
                  f'</NoDataValue><SimpleSource><SourceFilename relativeToVRT="1">b{k}.tif'
                  "</SourceFilename><SourceBand>1</SourceBand></SimpleSource>"
                  "</VRTRasterBand>")
    with rasterio.open(tmp_path / "b1.tif") as src:
        srs = src.crs.to_wkt()
    path = tmp_path / "two.vrt"
    path.write_text(f'<VRTDataset rasterXSize="20" rasterYSize="20"><SRS>{srs}</SRS>'
                    "<GeoTransform>500000, 10, 0, 5000200, 0, -10</GeoTransform>"
                    f"{bands}</VRTDataset>")
    return path


def test_each_band_reads_with_its_own_nodata(tmp_path):
    import rasterio

    vrt = two_band_vrt(tmp_path)
    with rasterio.open(vrt) as src:
        assert src.nodatavals == (-9999.0, -32768.0)
    out = toolbox.run("dem:slope", {"INPUT": vrt, "BAND": 2, "OUTPUT": tmp_path / "s.tif"})
    with rasterio.open(out["OUTPUT"]) as slope:
        values = slope.read(1, masked=True)
    assert values.count() > 0 and values.min() == pytest.approx(45.0, abs=1e-3)
    assert values.max() == pytest.approx(45.0, abs=1e-3)  # gdaldem slope -b 2: 45 everywhere
    assert values.mask[10:12, 10:12].all()  # band 2's hole


def test_read_onto_warps_each_band_with_its_own_nodata(tmp_path):
    import math

    import rasterio
    from rasterio.transform import from_origin

    from toolbox.raster.reproject import read_onto

    with rasterio.open(two_band_vrt(tmp_path)) as src:  # onto a grid shifted by half a cell
        out = read_onto(src, from_origin(500005, 5000195, 10, 10), 19, 19, indexes=[1, 2],
                        resampling="nearest", dtype="float64")
    assert not (out <= -9999).any()  # no nodata value taken for a height
    assert math.isnan(out[0, 2, 2]) and math.isnan(out[1, 10, 10])


def test_a_south_up_dem_is_refused_with_the_gdalwarp_command(tmp_path):
    import rasterio
    from rasterio import Affine

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler
    from toolbox.photogrammetry.surface import read_dem_window

    path = tmp_path / "south_up.tif"
    with rasterio.open(path, "w", driver="GTiff", width=4, height=4, count=1, dtype="float32",
                       crs="EPSG:32632", transform=Affine(10, 0, 500000, 0, 10, 5000000)) as dst:
        dst.write(np.ones((4, 4), "float32"), 1)
    info = open_raster_info(path, "DEM", "heights")
    for read in (read_dem_window, DemSampler):
        with pytest.raises(ParameterError, match=r"^DEM '.*south_up.tif' is stored south-up.*"
                                                 r"gdalwarp '.*south_up.tif' north_up.tif"):
            read(info)
