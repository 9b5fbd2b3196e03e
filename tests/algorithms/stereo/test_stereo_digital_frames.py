"""Digital frames with an interior model (Orthority's pinhole DMC of the NGI test data): the
frame camera the stereo steps use projects exactly as the model camera; dem:match on the real
NGI frames gives a DSM that agrees with NGI's own 24 m DEM; a distorted (Brown) model is
resampled through its lens; fisheye models are refused."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.errors import InputDataError
from toolbox.stereo.frames import as_frame_photo

PHOTO = "3324c_2015_1004_05_0182_RGB"


@pytest.fixture(scope="module")
def ngi(orthority_data):
    from toolbox.photogrammetry.tables import load_project_parameter

    return orthority_data, load_project_parameter(orthority_data / "io" / "ngi_ext_param.geojson")


def test_frame_camera_projects_as_the_model(ngi):
    _, project = ngi
    photo = project.photo(PHOTO)
    frame = as_frame_photo(photo)
    assert frame.camera.principal_distance_mm == pytest.approx(120.0)  # the DMC's focal_len
    c = photo.exterior.centre
    rng = np.random.default_rng(1)
    ground = np.column_stack([c[0] + rng.uniform(-1500, 1500, 200),
                              c[1] + rng.uniform(-2500, 2500, 200), rng.uniform(200, 700, 200)])
    np.testing.assert_allclose(frame.ground_to_pixel(ground), photo.ground_to_pixel(ground),
                               atol=1e-6)


BROWN = {"type": "brown", "im_size": [720, 560], "focal_len": 0.75, "cx": 0.012, "cy": -0.008,
         "k1": -0.21, "k2": 0.09, "k3": -0.012, "p1": 0.0012, "p2": -0.0007}


def _brown_pair():
    """Two nadir-ish photos 300 m apart at 1000 m over flat ground at 300 m, Brown lens."""
    from toolbox.cameras import create_intrinsics
    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.photo import Photo

    model = create_intrinsics(BROWN, name="brown")
    x0, y0 = 1_688_000.0, 4_799_500.0
    left = Photo("L", model, ExteriorOrientation.from_angles(
        "L", x0, y0, 1300.0, 0.4, -0.3, 1.0, crs="EPSG:3003"))
    right = Photo("R", model, ExteriorOrientation.from_angles(
        "R", x0 + 300.0, y0 + 10.0, 1290.0, -0.5, 0.2, -0.8, crs="EPSG:3003"))
    return left, right


def test_a_distorted_model_is_resampled_through_its_lens():
    """The normalised images' pixels are fetched through the Brown lens: for ground points seen
    by both photos, the map from their normalised position (distortion-free frame geometry)
    lands on the pixel OpenCV's projectPoints gives with the Brown coefficients (an independent
    lens model), and the two normalised rows agree (epipolar)."""
    import cv2

    from toolbox.stereo.epipolar import EpipolarMap, epipolar_geometry

    left, right = _brown_pair()
    frames = (as_frame_photo(left), as_frame_photo(right))
    geometry = epipolar_geometry(*frames)
    rng = np.random.default_rng(5)
    ground = np.column_stack([1_688_150.0 + rng.uniform(-150, 150, 300),
                              4_799_505.0 + rng.uniform(-150, 150, 300),
                              rng.uniform(250, 350, 300)])
    rows = []
    for side, photo in enumerate((left, right)):
        colrow = geometry.ground_to_pixels(ground, side)  # normalised image (col, row)
        rows.append(colrow[:, 1])
        transform = geometry.transform(side)
        xn, yn = transform * (colrow[:, 0], colrow[:, 1])  # normalised mm
        cols, prow = EpipolarMap(geometry, photo, side).pixels(np.asarray(xn), np.asarray(yn))
        eo = photo.exterior
        world_to_cv = np.diag([1.0, -1.0, -1.0]) @ eo.rotation.T  # camera y down, z ahead
        rvec, _ = cv2.Rodrigues(world_to_cv)
        tvec = -world_to_cv @ np.asarray(eo.centre)
        model = photo.camera
        truth, _ = cv2.projectPoints(ground.reshape(-1, 1, 3), rvec, tvec, model.matrix(),
                                     model.opencv_coefficients())
        truth = truth.reshape(-1, 2) + 0.5  # OpenCV's pixel centres at integers
        inside = (truth[:, 0] > 0) & (truth[:, 0] < 720) & (truth[:, 1] > 0) & (truth[:, 1] < 560)
        assert inside.sum() > 200
        err = np.hypot(cols[inside] - truth[inside, 0], prow[inside] - truth[inside, 1])
        assert err.max() < 0.01, err.max()
        # without the lens (the frame equivalent) the same rays miss by pixels
        cols0, rows0 = EpipolarMap(geometry, frames[side], side).pixels(np.asarray(xn),
                                                                        np.asarray(yn))
        assert np.hypot(cols0 - cols, rows0 - prow)[inside].max() > 3.0
    np.testing.assert_allclose(rows[0], rows[1], atol=1e-6)


def test_a_fisheye_model_is_refused(ngi):
    _, project = ngi
    photo = project.photo(PHOTO)
    fisheye = replace(photo.camera, kind="fisheye", coefficients={"k1": 0.01})
    with pytest.raises(InputDataError, match="fisheye model"):
        as_frame_photo(replace(photo, camera=fisheye))


def test_dsm_of_the_real_ngi_frames(ngi, tmp_path):
    """The two pairs of the four NGI frames that overlap enough, at NGI's DEM grid (24 m): the
    matched DSM against that DEM (EGM2008 heights, as the orientations) on the cells both have.
    Measured: 9,890 cells, median difference -0.6 m, median absolute 1.8 m (the DSM has the
    buildings and trees the DEM has not; 10-12 % of the left images matched: small overlaps of
    5.6 m pixels)."""
    from toolbox.photogrammetry.project import Project, save_project

    data, project = ngi
    photos = {k: replace(v, image=data / "ngi" / f"{k}.tif") for k, v in project.photos.items()}
    path = save_project(Project(project.crs, project.cameras, photos), tmp_path / "ngi.yaml")
    dem = data / "ngi" / "dem.tif"
    res = toolbox.run("dem:match", {
        "PROJECT": str(path), "MIN_HEIGHT": 100.0, "MAX_HEIGHT": 850.0, "TEMPLATE": str(dem),
        "OUTPUT": str(tmp_path / "dsm.tif"), "COUNT": str(tmp_path / "c.tif"),
        "SPREAD": str(tmp_path / "s.tif")})
    assert len(res["STATISTICS"]["pairs"]) == 2
    with rasterio.open(tmp_path / "dsm.tif") as a, rasterio.open(Path(dem)) as b:
        dsm, truth = a.read(1, masked=True), b.read(1)
        assert a.transform == b.transform
    diff = (dsm.data - truth)[~dsm.mask]
    assert diff.size > 5000
    assert abs(np.median(diff)) < 2.0
    assert np.median(np.abs(diff)) < 4.0
