"""The demo sample photo end to end: the blunder named, check points within noise, the rectified
photo matches the sample's ground-truth orthoimage, the relief rule warns (Siena hills)."""

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.demo.samples import photo as sample
from toolbox.feedback import Feedback

pytestmark = pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")


def test_demo_photo_rectified_against_truth(tmp_path):
    made = sample.make(tmp_path, {})
    feedback = Feedback()
    est = toolbox.run("rectify:estimate", {
        "INPUT": made["photo_gcps"], "CRS": "EPSG:3003", "PRINCIPAL_DISTANCE": 303.55,
        "FLYING_HEIGHT": 1140, "OUTPUT": tmp_path / "t.json"}, feedback=feedback)
    stats = est["STATISTICS"]
    assert stats["rejected_points"] == [sample.GROSS_ERROR_ID]
    gsd = stats["ground_size_of_image_unit"]  # ~0.72 m
    assert 0.65 < gsd < 0.8
    # 0.3 px measurement noise: sigma0 and the check points agree with it
    assert 0.15 < stats["sigma0_image"] < 0.45
    assert stats["check"]["count"] == 3 and stats["check"]["rmse"] < 3 * sample.NOISE_PX * gsd
    # Siena relief (35 m among the points) is too much for a 1 mm tolerance at c = 303.55 mm
    assert stats["relief"]["flat_enough"] is False
    assert any("orthorectification" in w for w in feedback.warnings)
    out = toolbox.run("rectify:image", {"INPUT": made["photo"], "TRANSFORM": tmp_path / "t.json",
                                        "CELL_SIZE": 1, "OUTPUT": tmp_path / "r.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        data, t = ds.read(), ds.transform
    x = t.c + (np.arange(data.shape[2]) + 0.5) * t.a
    y = t.f + (np.arange(data.shape[1]) + 0.5) * t.e
    xx, yy = np.meshgrid(x, y)
    _, targets = sample.control_points()
    truth = np.moveaxis(sample.orthoimage(xx, yy, targets), -1, 0).astype(float)
    from scipy.ndimage import binary_erosion

    core = binary_erosion(data[3] > 0, iterations=3)
    assert core.mean() > 0.6
    # the photo (0.72 m pixels, JPEG) is softer than the point-sampled truth, but aligned
    luma, luma_truth = data[:3].mean(axis=0), truth.mean(axis=0)
    assert np.corrcoef(luma[core], luma_truth[core])[0, 1] > 0.94
    for band in range(3):
        corr = np.corrcoef(data[band][core].astype(float), truth[band][core])[0, 1]
        assert corr > 0.9, (band, corr)
    from skimage.registration import phase_cross_correlation

    centre = np.s_[200:700, 200:700]
    assert core[centre].all()
    shift = phase_cross_correlation(luma_truth[centre], luma[centre], upsample_factor=50)[0]
    assert np.abs(shift).max() < 0.1  # output pixels (1 m)
