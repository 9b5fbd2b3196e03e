"""RPC cameras against GDAL's RPC transformer (rasterio), on a real QuickBird image (Orthority's
test data) and on a synthetic RPC written as GDAL's sidecars; the film camera behind the camera
protocol; a project YAML camera with ``model:``."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer

from toolbox.cameras import CameraModel, FilmFrame, FrameCamera, RpcCamera, create_camera, read_rpc
from toolbox.errors import InputDataError
from toolbox.photogrammetry.camera import RadialDistortion
from toolbox.photogrammetry.project import load_project
from toolbox.photogrammetry.synthetic import frame_photo

sys.path.insert(0, str(Path(__file__).parent))
from test_camera_models import ODM_BROWN  # noqa: E402


def gdal_pixels(rpcs, lon, lat, h):
    """GDAL's forward RPC transform (exact: no iteration), product pixel convention (GDAL's
    pixel/line put the top-left pixel's corner at 0, as the product does)."""
    rows, cols = RPCTransformer(rpcs).rowcol(lon, lat, h, op=lambda v: v)
    return np.column_stack([cols, rows])


def test_quickbird_rpc_equals_gdal_both_ways(orthority_data):
    path = orthority_data / "rpc" / "qb2_basic1b.tif"
    camera = read_rpc(path)
    assert isinstance(camera, CameraModel) and camera.image_size == (850, 1450)
    with rasterio.open(path) as src:
        rpcs = src.rpcs
    rng = np.random.default_rng(1)
    lon, lat = rng.uniform(24.34, 24.44, 200), rng.uniform(-33.72, -33.64, 200)
    h = rng.uniform(300, 1100, 200)
    ours = camera.project(np.column_stack([lon, lat, h]))
    np.testing.assert_allclose(ours, gdal_pixels(rpcs, lon, lat, h), atol=1e-6)
    # pixel -> ground at a height, checked through GDAL's forward transform
    px = np.column_stack([rng.uniform(0, 850, 200), rng.uniform(0, 1450, 200)])
    ground = camera.pixel_to_ground(px, h)
    assert np.isfinite(ground).all()
    back = gdal_pixels(rpcs, ground[:, 0], ground[:, 1], h)
    assert np.abs(back - px).max() < 1e-3
    # in a projected CRS (UTM 34S) the same pixels
    utm = RpcCamera(camera.rpc, camera.image_size, "EPSG:32734")
    ground_utm = utm.pixel_to_ground(px, h)
    np.testing.assert_allclose(utm.project(ground_utm), px, atol=1e-3)
    rays = utm.unproject(px[:5])
    assert (rays[:, 2] < -0.9).all()  # lines of sight of a near-nadir satellite, downwards


def synthetic_rpc() -> RPC:
    num_s, num_l = np.zeros(20), np.zeros(20)
    num_s[[1, 2, 3, 4, 7]] = [1.0, 0.05, 0.02, 0.01, -0.003]  # L, P, H, LP, L²
    num_l[[1, 2, 3, 6, 8]] = [-0.04, -1.0, 0.03, 0.005, 0.002]  # L, P, H, PH, P²
    den = np.zeros(20)
    den[[0, 1, 2]] = [1.0, 0.001, -0.002]
    return RPC(height_off=500.0, height_scale=400.0, lat_off=45.0, lat_scale=0.05,
               line_den_coeff=den.tolist(), line_num_coeff=num_l.tolist(), line_off=500.0,
               line_scale=520.0, long_off=11.0, long_scale=0.07, samp_den_coeff=den.tolist(),
               samp_num_coeff=num_s.tolist(), samp_off=600.0, samp_scale=620.0)


@pytest.mark.parametrize("sidecar", ["RPCTXT", "RPB"])
def test_synthetic_rpc_read_from_a_gdal_sidecar_equals_gdal(tmp_path, sidecar):
    rpcs = synthetic_rpc()
    path = tmp_path / "scene.tif"
    with rasterio.open(path, "w", driver="GTiff", width=1200, height=1000, count=1,
                       dtype="uint8", rpcs=rpcs, PROFILE="BASELINE", **{sidecar: "YES"}) as dst:
        dst.write(np.zeros((1, 1000, 1200), dtype="uint8"))
    assert any(p.name != "scene.tif" for p in tmp_path.iterdir())  # the sidecar GDAL wrote
    camera = create_camera({"type": "rpc", "path": str(path)})
    assert camera.image_size == (1200, 1000)
    rng = np.random.default_rng(2)
    lon, lat = rng.uniform(10.95, 11.05, 100), rng.uniform(44.96, 45.04, 100)
    h = rng.uniform(100, 900, 100)
    with rasterio.open(path) as src:
        gdal_rpcs = src.rpcs
    np.testing.assert_allclose(camera.project(np.column_stack([lon, lat, h])),
                               gdal_pixels(gdal_rpcs, lon, lat, h), atol=1e-6)
    # the same camera from Orthority's RPC schema
    spec = {"type": "rpc", "im_size": [1200, 1000], "rpc": rpcs.to_dict()}
    again = create_camera(spec)
    np.testing.assert_allclose(again.project(np.column_stack([lon, lat, h])),
                               camera.project(np.column_stack([lon, lat, h])), atol=1e-9)


def test_rpc_errors_are_one_line(tmp_path):
    plain = tmp_path / "plain.tif"
    with rasterio.open(plain, "w", driver="GTiff", width=4, height=4, count=1,
                       dtype="uint8") as dst:
        dst.write(np.zeros((1, 4, 4), dtype="uint8"))
    with pytest.raises(InputDataError, match="has no RPCs"):
        read_rpc(plain)
    with pytest.raises(InputDataError, match="RPCs lack line_num_coeff"):
        create_camera({"type": "rpc", "im_size": [4, 4],
                       "rpc": {k: v for k, v in synthetic_rpc().to_dict().items()
                               if k != "line_num_coeff"}})


def test_film_camera_behind_the_protocol_is_the_photo_model():
    table = RadialDistortion.from_table([20.0, 60.0, 100.0, 150.0], [2.0, -3.0, 4.0, -6.0])
    photo = frame_photo((1000.0, 2000.0, 1500.0), (0.02, -0.01, 0.5), width=900, height=700,
                        distortion=table)
    camera = photo.sensor()
    assert isinstance(camera, FilmFrame) and isinstance(camera, CameraModel)
    rng = np.random.default_rng(4)
    px = np.column_stack([rng.uniform(0, 900, 300), rng.uniform(0, 700, 300)])
    z = rng.uniform(100, 300, 300)
    ground = camera.pixel_to_ground(px, z)
    np.testing.assert_allclose(ground, photo.pixel_to_ground(px, z), atol=1e-6)
    np.testing.assert_allclose(camera.project(ground), px, atol=1e-6)
    rays = camera.unproject(px)
    toward = ground - photo.exterior.centre
    np.testing.assert_allclose(rays, toward / np.linalg.norm(toward, axis=1)[:, None], atol=1e-9)


def model_project(tmp_path, model: dict, **photo) -> object:
    doc = {"crs": "EPSG:32651", "angle_unit": "deg",
           "cameras": [{"name": "drone", "model": model}],
           "photos": [{"id": "a", "camera": "drone", "image": "a.tif",
                       "exterior": {"X0": 292700.0, "Y0": 2731000.0, "Z0": 200.0, "omega": 2.0,
                                    "phi": -1.0, "kappa": 30.0}, **photo}]}
    path = tmp_path / "project.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_project_camera_with_a_model(tmp_path):
    project = load_project(model_project(tmp_path, ODM_BROWN))
    photo = project.photo("a")
    camera = photo.sensor()
    assert isinstance(camera, FrameCamera) and isinstance(camera, CameraModel)
    direct = create_camera(ODM_BROWN, photo.exterior)
    ground = np.array([[292710.0, 2731010.0, 20.0], [292650.0, 2730980.0, 5.0]])
    np.testing.assert_allclose(camera.project(ground), direct.project(ground))
    # the photo's own pixel methods go through the model
    px = camera.project(ground)
    np.testing.assert_allclose(photo.ground_to_pixel(ground), px)
    np.testing.assert_allclose(photo.pixel_to_ground(px, ground[:, 2]), ground, atol=1e-6)
    # written back as it was read
    again = project.as_dict()["cameras"][0]
    assert again == {"name": "drone", "model": ODM_BROWN}


def test_project_model_errors(tmp_path):
    with pytest.raises(InputDataError, match="no 'interior'"):
        load_project(model_project(tmp_path, ODM_BROWN,
                                   interior={"pixel_to_fiducial": np.eye(3).tolist()}))
    path = tmp_path / "p2.yaml"
    path.write_text(yaml.safe_dump({"cameras": [{"name": "x", "model": ODM_BROWN,
                                                 "principal_distance_mm": 10.0}]}))
    with pytest.raises(InputDataError, match="either 'model' or the film camera's fields"):
        load_project(path)
    bad = dict(ODM_BROWN, type="equirectangular")
    with pytest.raises(InputDataError, match="type must be one of"):
        load_project(model_project(tmp_path, bad))


def test_film_only_steps_stop_with_a_one_line_error_on_a_model_camera(tmp_path):
    """A step written for film cameras (fiducials, principal distance in mm) asked to work on
    a model camera: a one-line InputDataError, never an internal error; the camera still
    pickles (Dask workers)."""
    import pickle

    photo = load_project(model_project(tmp_path, ODM_BROWN)).photo("a")
    with pytest.raises(InputDataError, match="is a brown model without c: this step handles"):
        _ = photo.camera.c
    with pytest.raises(InputDataError, match="film cameras only"):
        photo.require_pixel_transform()
    again = pickle.loads(pickle.dumps(photo))
    np.testing.assert_allclose(again.sensor().project(np.array([[292700.0, 2731010.0, 0.0]])),
                               photo.sensor().project(np.array([[292700.0, 2731010.0, 0.0]])))


def test_a_fisheye_seeing_past_90_degrees_has_no_footprint_outline():
    from test_camera_models import FISHEYE

    from toolbox.cameras import create_intrinsics
    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.photo import Photo

    eo = ExteriorOrientation.from_angles("f", 0.0, 0.0, 100.0, 0.0, 0.0, 0.0)
    photo = Photo("f", create_intrinsics(FISHEYE), eo)
    with pytest.raises(InputDataError, match="90 degrees or more off the optical axis"):
        photo.frame_outline_mm(4)
    narrow = Photo("f", create_intrinsics(dict(FISHEYE, focal_len=0.8)), eo)
    assert np.isfinite(narrow.frame_outline_mm(4)).all()
