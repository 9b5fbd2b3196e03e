"""OpenSfM/ODM reconstruction.json: positions and rotations to a map grid, checked by projecting
ground points with OpenCV (OpenSfM's own camera formula) and with the product's collinearity."""

import json

import cv2
import numpy as np
import pytest
from pyproj import Transformer

from tests.toolbox.exchange import exchange_synthetic as syn
from toolbox.errors import InputDataError
from toolbox.exchange import csvtable, opensfm
from toolbox.exchange.project import project_from_orientations
from toolbox.photogrammetry.rotation import rotation_matrix


def test_topocentric_reconstruction_projects_like_opencv(tmp_path):
    """Ground points projected with cv2.projectPoints in the topocentric frame land on the same
    pixels as through the converted UTM orientation and the product's collinearity (0.2 px:
    the grid's scale factor 1.00013 is not a rotation); ignoring the meridian convergence (0.86
    deg) misses by more than 5 px, so the test can fail."""
    oset = opensfm.read_reconstruction(syn.reconstruction(tmp_path / "r.json"))
    assert oset.crs.to_epsg() == 32651
    assert any("frame topocentric" in n for n in oset.notes)
    project = project_from_orientations(oset)
    ref = Transformer.from_crs(4979, 32651, always_xy=True).transform(syn.LON, syn.LAT, syn.ALT)
    for k in range(3):
        points, cv_pixels = syn.ground_points(k)
        photo = project.photo(f"IMG_{k}")
        ours = photo.ground_to_pixel(syn.topocentric_to_utm(points))
        assert np.abs(ours - (cv_pixels + 0.5)).max() < 0.2
        r_w2c = syn.ATTITUDES[k].T  # naive: topocentric offsets and axes taken as grid ones
        naive = cv2.projectPoints(syn.topocentric_to_utm(points), cv2.Rodrigues(r_w2c)[0],
                                  -r_w2c @ np.add(ref, syn.CENTRES[k]), syn.K,
                                  np.zeros(5))[0].reshape(-1, 2)
        if k:  # the camera at the origin only turns, its offset does not move
            assert np.abs(naive - cv_pixels).max() > 5.0


def test_frames_told_apart_and_forced(tmp_path):
    path = syn.reconstruction(tmp_path / "r.json", gps=False)
    default = opensfm.read_reconstruction(path)
    assert any("documented frame" in n for n in default.notes)
    forced = opensfm.read_reconstruction(path, frame="utm_offset")
    assert np.abs(np.subtract(default.photos["IMG_1"].xyz, forced.photos["IMG_1"].xyz)).max() > 1


def test_bad_reconstructions(tmp_path):
    with pytest.raises(InputDataError, match="no reference_lla"):
        opensfm.read_reconstruction(syn.reconstruction(tmp_path / "a.json", reference=False))
    with pytest.raises(InputDataError, match="projection_type 'spherical'"):
        opensfm.read_reconstruction(syn.reconstruction(tmp_path / "b.json",
                                                       projection_type="spherical"))


def test_odm_reconstruction_matches_orthority_csv(orthority_data):
    """ODM's reconstruction.json (UTM-offset frame, found from the shots' GPS positions) gives
    the positions and angles Orthority ships in odm_xyz_opk.csv for the same photos, to their
    printed precision (mm, 0.001 deg)."""
    oset = opensfm.read_reconstruction(orthority_data / "odm/opensfm/reconstruction.json")
    assert any("frame utm_offset" in n for n in oset.notes)
    table = csvtable.read_csv(orthority_data / "io/odm_xyz_opk.csv", crs="EPSG:32651")
    assert set(table.photos) == set(oset.photos)
    for pid, p in table.photos.items():
        q = oset.photos[pid]
        assert np.abs(np.subtract(p.xyz, q.xyz)).max() <= 0.0006
        assert np.degrees(np.abs(np.subtract(p.opk, q.opk))).max() <= 0.0006


def test_odm_reconstruction_projects_like_opencv(orthority_data):
    """The file's own rvec/tvec through cv2.projectPoints (ground = UTM minus ODM's offset) vs
    the converted orientation through the product's projection (with the Brown distortion when
    the toolbox has camera models, else without on both sides)."""
    from toolbox.exchange.project import model_cameras

    path = orthority_data / "odm/opensfm/reconstruction.json"
    doc = json.loads(path.read_text())[0]
    ref = doc["reference_lla"]
    offset = np.array([*Transformer.from_crs(4326, 32651, always_xy=True).transform(
        ref["longitude"], ref["latitude"]), ref["altitude"]])
    cam = next(iter(doc["cameras"].values()))
    size = max(cam["width"], cam["height"])
    k = np.array([[cam["focal_x"] * size, 0, cam["c_x"] * size + (cam["width"] - 1) / 2],
                  [0, cam["focal_y"] * size, cam["c_y"] * size + (cam["height"] - 1) / 2],
                  [0, 0, 1]])
    distortion = np.array([cam[t] for t in ("k1", "k2", "p1", "p2", "k3")]) \
        if model_cameras() else np.zeros(5)
    project = project_from_orientations(opensfm.read_reconstruction(path))
    for name, shot in doc["shots"].items():
        r_w2c = cv2.Rodrigues(np.array(shot["rotation"]))[0]
        centre = -r_w2c.T @ np.array(shot["translation"])
        g = np.linspace(-0.3, 0.3, 4)
        rays = np.array([[x, y, 1.0] for x in g for y in g]) * 150.0
        ground = centre + (r_w2c.T @ rays.T).T + offset
        cv = cv2.projectPoints(ground - offset, np.array(shot["rotation"]),
                               np.array(shot["translation"]), k, distortion)[0].reshape(-1, 2)
        ours = project.photo(name).ground_to_pixel(ground)
        assert np.abs(ours - (cv + 0.5)).max() < 0.01


def test_rotation_convention_opencv_to_photogrammetric():
    """A nadir OpenCV camera (x east, y south, z down) is omega = phi = kappa = 0: camera y up
    is north and the camera looks down its -z."""
    from toolbox.exchange.model import opk_from_opencv

    assert np.allclose(opk_from_opencv(syn.NADIR), 0.0, atol=1e-12)
    r = rotation_matrix(*opk_from_opencv(syn.ATTITUDES[1]))
    assert np.allclose(r @ [0, 0, -1.0], syn.ATTITUDES[1] @ [0, 0, 1.0])  # viewing direction


def test_odm_leftover_says_utm_offset(tmp_path):
    """Without GPS positions, ODM's reconstruction.topocentric.json beside the file means the
    UTM-offset frame: positions are the UTM offset plus the file's coordinates."""
    path = syn.reconstruction(tmp_path / "reconstruction.json", gps=False)
    (tmp_path / "reconstruction.topocentric.json").write_text("[]")
    oset = opensfm.read_reconstruction(path)
    assert any("frame utm_offset" in n for n in oset.notes)
    origin = Transformer.from_crs(4979, 32651, always_xy=True).transform(syn.LON, syn.LAT, 0.0)
    expected = np.add([origin[0], origin[1], syn.ALT], syn.CENTRES[2])
    assert np.allclose(oset.photos["IMG_2"].xyz, expected, atol=1e-6, rtol=0)
    assert np.allclose(rotation_matrix(*oset.photos["IMG_2"].opk),
                       syn.ATTITUDES[2] @ np.diag([1.0, -1.0, -1.0]), atol=1e-12)


def test_cameras_json_models(tmp_path):
    """OpenSfM camera models to the schema: perspective -> brown (focal, k1, k2),
    fisheye_opencv -> fisheye (k1..k4), principal point offsets kept."""
    (tmp_path / "cameras.json").write_text(json.dumps({
        "v2 a": {"projection_type": "perspective", "width": 4000, "height": 3000, "focal": 0.85,
                 "k1": -0.1, "k2": 0.02},
        "v2 b": {"projection_type": "fisheye_opencv", "width": 2000, "height": 2000,
                 "focal_x": 0.3, "focal_y": 0.31, "c_x": 0.01, "c_y": -0.02, "k1": 0.1,
                 "k2": -0.01, "k3": 0.001, "k4": 0.0001}}))
    cams = opensfm.read_cameras_json(tmp_path / "cameras.json").cameras
    assert cams["a"] == {"type": "brown", "im_size": [4000, 3000], "focal_len": 0.85, "cx": 0.0,
                         "cy": 0.0, "k1": -0.1, "k2": 0.02}
    assert cams["b"]["type"] == "fisheye" and cams["b"]["focal_len"] == [0.3, 0.31]
    assert (cams["b"]["cx"], cams["b"]["k4"]) == (0.01, 0.0001)
