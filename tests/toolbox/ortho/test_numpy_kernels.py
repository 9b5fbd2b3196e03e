"""The NumPy path of a camera model's ortho (no numba start-up) against the compiled kernels
and OpenCV: DEM heights, the camera's coordinate map (Brown, full OpenCV, fisheye, pinhole;
cv2.projectPoints / cv2.fisheye.projectPoints as the independent oracle), the footprint's
monoplot march on a DEM, a whole ortho of a rendered photo both ways, and a small ortho run
that never imports numba."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from toolbox.cameras import FrameCamera, create_intrinsics
from toolbox.cameras.kernels import KIND_FISHEYE, KIND_PERSPECTIVE, grid_to_pixels
from toolbox.ortho import grid_numpy, heights
from toolbox.photogrammetry import kernels, kernels_numpy
from toolbox.photogrammetry.exterior import ExteriorOrientation

SIZE = [1200, 900]
MODELS = {
    "pinhole": {"type": "pinhole", "im_size": SIZE, "focal_len": 0.9, "cx": 0.01, "cy": -0.02},
    "brown": {"type": "brown", "im_size": SIZE, "focal_len": 0.8, "cx": 0.012, "cy": -0.008,
              "k1": -0.21, "k2": 0.09, "k3": -0.012, "p1": 0.0012, "p2": -0.0007},
    "opencv": {"type": "opencv", "im_size": SIZE, "focal_len": 0.8, "cx": 0.0, "cy": 0.0,
               "k1": -0.2, "k2": 0.05, "k3": 0.01, "p1": 0.001, "p2": -0.002, "k4": 0.02,
               "k5": -0.01, "k6": 0.003, "s1": 0.001, "s2": -0.0005, "s3": 0.0007,
               "s4": -0.0002},
    "fisheye": {"type": "fisheye", "im_size": SIZE, "focal_len": 0.66, "cx": -0.01,
                "cy": 0.006, "k1": -0.06, "k2": 0.012, "k3": -0.002, "k4": 0.0002},
}
CENTRE = (1000.0, 2000.0, 900.0)


def dem_with_holes(seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    dem = 100.0 + np.cumsum(rng.normal(0, 2.0, (60, 80)), axis=1)
    dem[rng.random(dem.shape) < 0.03] = np.nan
    return dem


def test_heights_numpy_equal_compiled():
    """Bilinear heights on a grid partly outside the DEM, with nodata cells: the same values
    (and NaNs) as numba's kernel, on the grid and at scattered points."""
    dem = dem_with_holes()
    args = (dem, 500.0, 3000.0, 10.0, 12.5)
    xs = np.linspace(470.0, 1330.0, 333)  # beyond both edges
    ys = np.linspace(3030.0, 2230.0, 257)
    ours, oracle = np.empty((257, 333)), np.empty((257, 333))
    grid_numpy.heights_on_grid(*args, xs, ys, ours)
    heights.heights_on_grid(*args, xs, ys, oracle)
    np.testing.assert_array_equal(ours, oracle)
    assert np.isnan(ours).any() and np.isfinite(ours).mean() > 0.5
    x, y = np.meshgrid(xs[::7], ys[::5])
    ours_p, oracle_p = np.empty(x.size), np.empty(x.size)
    grid_numpy.heights_at_points(*args, x.ravel(), y.ravel(), ours_p)
    heights.heights_at_points(*args, x.ravel(), y.ravel(), oracle_p)
    np.testing.assert_array_equal(ours_p, oracle_p)


def camera(name: str) -> FrameCamera:
    eo = ExteriorOrientation.from_angles("p", *CENTRE, 0.05, -0.04, 0.7)
    return FrameCamera(create_intrinsics(MODELS[name]), eo)


def ground_grid(h: int = 150, w: int = 170):
    xs = CENTRE[0] + np.linspace(-1100.0, 1100.0, w)
    ys = CENTRE[1] + np.linspace(900.0, -900.0, h)
    z = 120.0 + 40.0 * np.sin(xs[None, :] / 90.0) * np.cos(ys[:, None] / 70.0)
    z[5, 7] = np.nan
    return np.broadcast_to(xs[None, :], z.shape), np.broadcast_to(ys[:, None], z.shape), z


@pytest.mark.parametrize("name", list(MODELS))
def test_camera_map_numpy_equals_compiled_and_opencv(name):
    """The NumPy map equals numba's kernel to the float32 bit (same cells without image) and
    OpenCV's projectPoints within 0.01 px where the model is valid."""
    cam = camera(name)
    gx, gy, z = ground_grid()
    cols, rows, box = grid_numpy.frame_grid_to_pixels(cam, gx, gy, z)
    m = cam.intrinsics
    fisheye = m.kind == "fisheye"
    k = np.zeros(12)
    k[:4 if fisheye else 12] = m.opencv_coefficients()
    oc, orow, obox = np.empty(z.shape, "float32"), np.empty(z.shape, "float32"), np.empty(5)
    grid_to_pixels(gx, gy, z, np.asarray(cam.centre, float), np.ascontiguousarray(
        cam.exterior.rotation), KIND_FISHEYE if fisheye else KIND_PERSPECTIVE, k,
        np.array(m.focal_px, float), np.array(m.principal_point_px, float),
        min(float(m.valid_radius), 1e300), oc, orow, obox)
    np.testing.assert_array_equal(cols, oc)
    np.testing.assert_array_equal(rows, orow)
    np.testing.assert_array_equal(box, obox)
    ok = np.isfinite(cols)
    assert 0.5 < ok.mean() < 1.0 and not ok[5, 7]
    # OpenCV's frame: the camera frame of FrameCamera.to_camera; pixels - 0.5 (centre at 0.5)
    xyz = np.column_stack([gx[ok], gy[ok], z[ok]])
    cam_xyz = cam.to_camera(xyz).reshape(-1, 1, 3)
    zero = np.zeros(3)
    if fisheye:
        px, _ = cv2.fisheye.projectPoints(cam_xyz, zero, zero, m.matrix(),
                                          m.opencv_coefficients())
    else:
        px, _ = cv2.projectPoints(cam_xyz, zero, zero, m.matrix(), m.opencv_coefficients())
    px = px.reshape(-1, 2) + 0.5
    assert np.abs(cols[ok] - px[:, 0]).max() < 0.01
    assert np.abs(rows[ok] - px[:, 1]).max() < 0.01


def test_camera_map_numpy_general_grid_equals_compiled():
    """Cells that are not a broadcast grid (the ortho in another CRS) take the per-cell sums."""
    cam = camera("brown")
    gx, gy, z = ground_grid(40, 50)
    rng = np.random.default_rng(2)
    gx = gx + rng.normal(0, 3.0, z.shape)
    gy = gy + rng.normal(0, 3.0, z.shape)
    ours = grid_numpy.frame_grid_to_pixels(cam, gx, gy, z)
    oracle = cam.project_grid(gx, gy, z)
    for a, b in zip(ours, oracle, strict=True):
        np.testing.assert_array_equal(a, b)


def ray_model():
    rot = ExteriorOrientation.from_angles("p", *CENTRE, 0.3, -0.25, 0.5).rotation
    u, v = np.meshgrid(np.linspace(-0.9, 0.9, 23), np.linspace(-0.8, 0.8, 19))
    return u.ravel(), v.ravel(), np.asarray(CENTRE), np.ascontiguousarray(rot)


def test_monoplot_numpy_equals_compiled():
    """The footprint's march down the rays to a rough DEM with holes, rays leaving the DEM
    and rays going up (tilted 17 degrees): every status, iteration count and point equal."""
    dem = dem_with_holes(4)
    gx0, gy0, cx, cy = 400.0, 2400.0, 12.0, 12.0
    u, v, centre, rot = ray_model()
    u = np.r_[u, 0.0]
    v = np.r_[v, 50.0]  # nearly along the horizon: no intersection in the DEM's range
    identity = np.eye(3)
    args0 = (0, np.zeros(2), np.zeros(2), np.array([0.0, 0.0, 1.0]), np.zeros(1, np.int64))
    zmin, zmax = float(np.nanmin(dem)), float(np.nanmax(dem))
    results = []
    for module in (kernels_numpy, kernels):
        out, status = np.empty((u.size, 3)), np.empty(u.size, np.int8)
        its = np.empty(u.size, np.int32)
        module.monoplot(u, v, centre, rot, 1.0, np.zeros(2), *args0, identity, dem, gx0, gy0,
                        cx, cy, zmin, zmax, 0, 0.0, 1e-10, 100, out, status, its)
        results.append((out, status, its))
    (out, status, its), (o_out, o_status, o_its) = results
    np.testing.assert_array_equal(status, o_status)
    np.testing.assert_array_equal(its, o_its)
    np.testing.assert_array_equal(out, o_out)
    assert {0, 1}.issubset(set(status.tolist())) and (status == 0).sum() > 100
    for z in (np.array([150.0]), np.linspace(90.0, 160.0, u.size)):
        a, b = np.empty((u.size, 3)), np.empty((u.size, 3))
        na = kernels_numpy.image_to_ground_at_z(u, v, z, centre, rot, 1.0, np.zeros(2), *args0,
                                                identity, a)
        nb = kernels.image_to_ground_at_z(u, v, z, centre, rot, 1.0, np.zeros(2), *args0,
                                          identity, b)
        assert na == nb
        np.testing.assert_array_equal(a, b)


def model_scene(folder: Path, image: np.ndarray | None = None) -> tuple[Path, Path, Path]:
    """The ortho camera-model tests' scene: a hilly DEM (200 m of relief), a Brown photo
    rendered from a texture on it with the collinearity equations and OpenCV's undistortion as
    the lens (or ``image``), its project; returns (dem, photo, project)."""
    sys.path.insert(0, str(Path(__file__).parents[2] / "algorithms" / "ortho"))
    import ortho_scene as scene
    import test_ortho_camera_models as models

    from toolbox.photogrammetry.synthetic import write_photo

    z, transform = scene.hills_dem(scene.BOUNDS, cell=10.0, relief=scene.RELIEF, base=scene.BASE,
                                   seed=3)
    dem = scene.write_dem(folder / "dem.tif", z, transform)
    if image is None:
        texture = scene.wave_texture(seed=7, wavelength=(40.0, 120.0))
        image = models.render(models.BROWN, z, transform, texture)
    photo = write_photo(folder / "p1.tif", image)
    return dem, photo, models.model_project(folder / "project.yaml", models.BROWN)


def test_ortho_numpy_path_equals_compiled_path(tmp_path):
    """A whole ortho of a rendered Brown photo, NumPy path and numba path: the same cells."""
    import rasterio

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.plan import plan_photo
    from toolbox.ortho.run import OrthoOptions, orthorectify
    from toolbox.photogrammetry.project import load_project

    dem_path, photo_path, project_path = model_scene(tmp_path)
    project = load_project(project_path)
    photo = project.photos["p1"]
    dem, image = open_raster_info(dem_path), open_raster_info(photo_path)
    plan = plan_photo(photo, dem, project.crs)
    out = {}
    for compiled in (False, True):
        path = tmp_path / f"ortho_{compiled}.tif"
        orthorectify(photo, image, dem, plan.grid, path, OrthoOptions(compiled=compiled))
        with rasterio.open(path) as src:
            out[compiled] = src.read()
    np.testing.assert_array_equal(out[False], out[True])
    assert (out[False][-1] > 0).mean() > 0.5  # most of the grid holds the photo


def test_small_ortho_never_imports_numba(tmp_path):
    """ortho:photo of a small camera-model ortho in a fresh process: numba is never imported
    (its start-up, about 0.8 s CPU and 120 MB, would be most of such a run)."""
    dem, photo, project = model_scene(tmp_path, np.full((560, 720), 100, dtype="uint8"))
    code = (
        "import sys, json, toolbox\n"
        f"toolbox.run('ortho:photo', {{'INPUT': {str(photo)!r}, 'PROJECT': {str(project)!r}, "
        f"'DEM': {str(dem)!r}, 'CELL_SIZE': 10.0, 'OUTPUT': {str(tmp_path / 'o.tif')!r}}})\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'numba')))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout.strip().splitlines()[-1]) == []
    assert (tmp_path / "o.tif").exists()


def test_plan_footprint_is_the_8_a_side_footprint_and_the_outline_bounds_the_grid(tmp_path):
    """The plan monoplots the dense outline once and keeps every (n / 8)-th point as the report
    footprint: exactly the footprint of 8 points a side monoplotted on its own; the grid's
    extent holds the dense outline (a rendered Brown photo on hills)."""
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.plan import footprint_points_per_side, photo_surface, plan_photo
    from toolbox.photogrammetry.coverage import photo_footprint
    from toolbox.photogrammetry.project import load_project

    dem_path, _, project_path = model_scene(tmp_path)
    project = load_project(project_path)
    photo = project.photos["p1"]
    dem = open_raster_info(dem_path)
    plan = plan_photo(photo, dem, project.crs)
    surface = photo_surface(dem, photo, project.crs, 1)
    plane = float(np.nanmean(surface.z))
    alone = photo_footprint(photo, surface, plane, 8).vertices
    np.testing.assert_array_equal(plan.footprint_xy, alone)
    dense = footprint_points_per_side(photo)
    assert dense % 8 == 0 and dense >= max(photo.camera.image_size_px) / 16
    outline = photo_footprint(photo, surface, plane, dense).vertices
    x0, y0, x1, y1 = plan.extent
    assert (outline[:, 0].min(), outline[:, 1].min(), outline[:, 0].max(),
            outline[:, 1].max()) == (x0, y0, x1, y1)
