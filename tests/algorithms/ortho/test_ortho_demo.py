"""The demo's orthos of the Siena block: real orientations (2_7139 has the calibrated distortion
table and kappa ~ pi), synthetic radiometry rendered through the collinearity equations."""

from __future__ import annotations

import numpy as np
import rasterio

import toolbox


def test_siena_photo_ortho_recovers_the_texture(tmp_path):
    from skimage.registration import phase_cross_correlation

    from toolbox.demo.samples import ortho, terrain
    from toolbox.raster.writer import write_raster

    z, transform = terrain.terrain()
    write_raster(tmp_path / "dem.tif", z, transform, terrain.CRS, nodata=-9999.0)
    made = ortho.make(tmp_path, {})
    stats = toolbox.run("ortho:photo", {
        "INPUT": tmp_path / "siena_ortho" / "2_7139.tif", "PROJECT": made["siena_ortho_project"],
        "DEM": tmp_path / "dem.tif", "CELL_SIZE": 2.0, "MAP_SCALE": 5000,
        "OUTPUT": tmp_path / "o.tif"})["STATISTICS"]
    assert stats["crs"] == "EPSG:3003" and stats["map_blocks"]["distortion_interpolated"] > 0
    assert stats["expected_accuracy"]["rms_small_scale_m"] == 1.5
    assert 1.6 < stats["photo_gsd_m"] < 1.8  # 0.448 mm x ~1150 m / 303.55 mm
    with rasterio.open(tmp_path / "o.tif") as src:
        data = src.read()
        t = src.transform
    xs = t.c + (np.arange(src.width) + 0.5) * t.a
    ys = t.f + (np.arange(src.height) + 0.5) * t.e
    truth = ortho.texture()(*np.meshgrid(xs, ys))
    valid = data[3] == 255
    h, w = valid.shape
    shifts = []
    for i0 in range(0, h - 64, 64):
        for j0 in range(0, w - 64, 64):
            p = (slice(i0, i0 + 64), slice(j0, j0 + 64))
            if valid[p].all():
                shift, _, _ = phase_cross_correlation(truth[1][p], data[1][p].astype(float),
                                                      upsample_factor=100, normalization=None)
                shifts.append(np.hypot(*shift))
                assert np.corrcoef(truth[1][p].ravel(), data[1][p].ravel())[0, 1] > 0.99
    assert len(shifts) >= 16 and max(shifts) <= 0.1
