"""Photo file variants read as one pixel grid by every photo reader (the matchers'
ImageSource, the fiducial ScanReader, the warps): a paletted photo as its colours, never an
internal overview for a reduced level, a 4-bit grey photo over its full range, a grey + alpha
scan by its grey band, and a warning (grid kept as stored) for an EXIF Orientation.

References are independent: GDAL's own ``gdal_translate -expand rgb``, numpy block means of the
stored pixels, and rasterio's plain read of the stored grid."""

from __future__ import annotations

import shutil
import subprocess
import warnings

import numpy as np
import rasterio

from toolbox.matching.fiducial_search import ScanReader
from toolbox.matching.images import ImageSource

W, H = 96, 64  # not square: a turned read would change the shape


def texture(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.random((H, W)) * 255).astype(np.uint8)


def write(path, data, **extra):
    data = data if data.ndim == 3 else data[None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                           count=data.shape[0], dtype=data.dtype, **extra) as dst:
            dst.write(data)
    return path


def read(path) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path) as src:
            return src.read()


def test_paletted_photo_is_read_as_its_colours(tmp_path):
    grey = texture()
    perm = np.random.default_rng(5).permutation(256)  # colour code perm[g] shows grey g
    codes = perm[grey].astype(np.uint8)
    path = write(tmp_path / "pal.tif", codes)
    with rasterio.open(path, "r+") as dst:
        dst.write_colormap(1, {int(perm[g]): (g, g, g, 255) for g in range(256)})
    subprocess.run(["gdal_translate", "-q", "-expand", "rgb", str(path),
                    str(tmp_path / "rgb.tif")], check=True)
    reference = read(tmp_path / "rgb.tif").astype(np.float32).mean(axis=0)
    assert np.array_equal(reference, grey)  # GDAL's expansion: the grey levels
    source = ImageSource.open(path)
    assert np.array_equal(source.window(0, 0, W, H), reference)
    assert np.array_equal(source.level(1.0)[0], reference)
    window, origin = ScanReader(path).window(0, 0, W, H)
    assert origin == (0, 0) and np.array_equal(window, reference)


def test_reduced_level_never_reads_an_internal_overview(tmp_path):
    grey = texture(1)
    plain = write(tmp_path / "plain.tif", grey)
    shutil.copy(plain, tmp_path / "ovr.tif")
    subprocess.run(["gdaladdo", "-q", "-r", "nearest", str(tmp_path / "ovr.tif"), "2", "4"],
                   check=True)
    # the reference: 4 x 4 block means of the stored full-resolution pixels
    blocks = grey.reshape(H // 4, 4, W // 4, 4).astype(np.float64).mean(axis=(1, 3))
    level, factors = ImageSource.open(tmp_path / "ovr.tif").level(4.0)
    assert factors == (4.0, 4.0)
    assert np.abs(level.astype(np.float64) - blocks).max() <= 1.0


def test_four_bit_grey_photo_spans_the_grey_range(tmp_path):
    codes = (np.random.default_rng(2).random((H, W)) * 16).astype(np.uint8)
    path = write(tmp_path / "nb4.tif", codes, nbits=4)
    assert read(path).max() == 15
    source = ImageSource.open(path)
    assert np.array_equal(source.window(0, 0, W, H), codes * 17)  # 15 -> 255


def test_grey_and_alpha_scan_is_read_by_its_grey_band(tmp_path):
    grey = texture(3)
    alpha = np.full_like(grey, 255)
    alpha[:, : W // 3] = 0
    path = write(tmp_path / "la.tif", np.stack([grey, alpha]))
    window, _ = ScanReader(path).window(0, 0, W, H)
    assert np.array_equal(window, grey)
    assert np.array_equal(ImageSource.open(path).window(0, 0, W, H), grey)


def test_exif_orientation_warns_and_keeps_the_stored_grid(tmp_path, caplog):
    from PIL import Image

    from toolbox.raster.warp import open_photo

    grey = texture(4)
    image = Image.fromarray(grey)
    exif = image.getexif()
    exif[0x0112] = 6  # "rotate 90 CW to view"
    image.save(tmp_path / "turned.jpg", exif=exif, quality=100)
    image.save(tmp_path / "plain.jpg", quality=100)
    stored = read(tmp_path / "turned.jpg")[0]  # GDAL: the grid as stored
    assert stored.shape == (H, W)
    def warned(opening):  # on the "toolbox" logger: the run's feedback keeps it
        caplog.clear()
        with caplog.at_level("WARNING", logger="toolbox"):
            result = opening()
        assert [r.getMessage() for r in caplog.records if "EXIF Orientation 6" in
                r.getMessage()], caplog.text
        return result

    source = warned(lambda: ImageSource.open(tmp_path / "turned.jpg"))
    assert (source.width, source.height) == (W, H)
    assert np.array_equal(source.window(0, 0, W, H), stored)
    reader = warned(lambda: ScanReader(tmp_path / "turned.jpg"))
    assert np.array_equal(reader.window(0, 0, W, H)[0], stored)
    _, src = warned(lambda: open_photo(tmp_path / "turned.jpg"))
    src.close()
    caplog.clear()
    with caplog.at_level("WARNING", logger="toolbox"), warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # no orientation tag: no warning
        ImageSource.open(tmp_path / "plain.jpg")
        ScanReader(tmp_path / "plain.jpg")
    assert "EXIF" not in caplog.text


def test_paletted_reference_ortho_is_sampled_as_its_colours(tmp_path):
    from rasterio.transform import from_origin

    from toolbox.matching.ortho_match import OrthoReference

    grey = texture(6)
    perm = np.random.default_rng(7).permutation(256)
    georef = {"crs": "EPSG:3003", "transform": from_origin(1688000.0, 4799000.0, 2.0, 2.0)}
    path = write(tmp_path / "pal_ortho.tif", perm[grey].astype(np.uint8), **georef)
    with rasterio.open(path, "r+") as dst:
        dst.write_colormap(1, {int(perm[g]): (g, g, g, 255) for g in range(256)})
    subprocess.run(["gdal_translate", "-q", "-expand", "rgb", str(path),
                    str(tmp_path / "rgb_ortho.tif")], check=True)
    rows, cols = np.mgrid[2:H - 2:7, 2:W - 2:5]
    x = 1688000.0 + (cols + 0.5) * 2.0  # cell centres: no interpolation
    y = 4799000.0 - (rows + 0.5) * 2.0
    reference = OrthoReference.open(tmp_path / "rgb_ortho.tif").sample(x, y)
    assert np.array_equal(reference, grey[rows, cols].astype(np.float32))
    assert np.array_equal(OrthoReference.open(path).sample(x, y), reference)
