"""Digital frames with an interior model (Orthority's pinhole DMC of the NGI test data): the
frame camera the stereo steps use projects exactly as the model camera; dem:match on the real
NGI frames gives a DSM that agrees with NGI's own 24 m DEM; distortion models are refused."""

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


def test_a_distortion_model_is_refused(ngi):
    _, project = ngi
    photo = project.photo(PHOTO)
    brown = replace(photo.camera, kind="brown", coefficients={"k1": 0.01})
    with pytest.raises(InputDataError, match="brown model with distortion"):
        as_frame_photo(replace(photo, camera=brown))


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
