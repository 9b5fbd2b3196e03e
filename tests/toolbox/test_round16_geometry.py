"""Round 16, extreme imaging geometry: a drone flying below the DEM's highest hills, an oblique
photo whose frame holds the horizon, a camera beside the DEM looking over it. Truth: the
collinearity equations by hand (numpy) and the analytic texture the photos were rendered from."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.errors import InputDataError
from toolbox.photogrammetry import kernels, kernels_numpy
from toolbox.photogrammetry.surface import DemSurface, photo_ground_bounds
from toolbox.photogrammetry.synthetic import frame_photo, hills_dem, render_photo, wave_texture, write_photo

CRS = "EPSG:3003"
BOUNDS = (1686600.0, 4797600.0, 1688200.0, 4799200.0)


def _project(path, centre, angles, size):
    import yaml

    camera = {"name": "c", "principal_distance_mm": 153.0, "image_size_px": [size, size],
              "pixel_size_mm": 230.0 / size, "frame_size_mm": [230.0, 230.0]}
    doc = {"format": "orientation-project", "version": 1, "crs": CRS, "angle_unit": "rad",
           "cameras": [camera],
           "photos": [{"id": "p1", "camera": "c", "image": "p1.tif",
                       "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                            [*centre, *angles], strict=True))}]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _scene(folder, centre, angles, size=120):
    from toolbox.raster.writer import write_raster

    z, t = hills_dem(BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=3)
    texture = wave_texture(seed=7, wavelength=(40.0, 120.0))
    photo = frame_photo(centre, angles, width=size, height=size, crs=CRS)
    write_photo(folder / "p1.tif", render_photo(photo, z, t, texture, dtype="uint8"))
    write_raster(folder / "dem.tif", z, t, CRS, nodata=-9999.0)
    return z, t, texture, _project(folder / "project.yaml", centre, angles, size)


def _errors(path, texture, centre=None, within=None):
    """|ortho - texture| on the cells the ortho fills, the filled cells, and (given a centre
    and a distance) the cells within that distance of it."""
    with rasterio.open(path) as src:
        data, t = src.read(), src.transform
    xs = t.c + (np.arange(data.shape[2]) + 0.5) * t.a
    ys = t.f + (np.arange(data.shape[1]) + 0.5) * t.e
    gx, gy = np.meshgrid(xs, ys)
    truth = texture(gx, gy)
    seen = data[-1] > 0
    errors = np.abs(data[0].astype(float) - truth)[seen]
    if centre is None:
        return errors, seen
    return errors, seen, seen & (np.hypot(gx - centre[0], gy - centre[1]) < within)


def test_drone_below_the_highest_hills_gets_its_ortho(tmp_path):
    """A camera 60 m above the valley floor, under hills 100 m higher elsewhere on the DEM:
    the DEM window was cut at the DEM's top height, a plane above the camera, and the run
    refused ("image ray(s) do not meet the height plane", exit 2)."""
    z, t, texture, project = _scene(tmp_path, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    surface = DemSurface.from_transform(z, t)
    row, col = np.unravel_index(np.argmin(z[10:-10, 10:-10]), z[10:-10, 10:-10].shape)
    x = t.c + (col + 10.5) * t.a
    y = t.f + (row + 10.5) * t.e
    z0 = float(surface.height(np.array([x]), np.array([y]))[0]) + 60.0
    assert z0 < z.max() - 50.0
    z, t, texture, project = _scene(tmp_path, (float(x), float(y), z0), (0.02, -0.01, 0.3))
    stats = toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "PROJECT": project,
                                        "DEM": tmp_path / "dem.tif",
                                        "OUTPUT": tmp_path / "o.tif"})["STATISTICS"]
    errors, seen = _errors(tmp_path / "o.tif", texture)
    assert seen.sum() > 1000 and np.median(errors) < 2.0
    # the footprint of a camera 60 m up with a 74 degree field: about 90 m across
    b = stats["bounds"]
    assert 60.0 < b[2] - b[0] < 200.0 and abs(0.5 * (b[0] + b[2]) - x) < 40.0


def test_oblique_photo_with_the_horizon_in_its_frame(tmp_path):
    """Tilted 69 degrees (the frame's top above the horizon): refused ("image ray(s) do not
    meet the height plane in front of the camera", exit 2) even with EXTENT; now orthorectified
    on the part of the DEM it sees, the grid cut to the DEM."""
    centre, angles = (1687400.0, 4797000.0, 1000.0), (1.2, 0.0, 0.0)
    _, _, texture, project = _scene(tmp_path, centre, angles, size=200)
    stats = toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "PROJECT": project,
                                        "DEM": tmp_path / "dem.tif",
                                        "OUTPUT": tmp_path / "o.tif"})["STATISTICS"]
    b = stats["bounds"]
    assert b[0] >= BOUNDS[0] - 20 and b[1] >= BOUNDS[1] - 20
    assert b[2] <= BOUNDS[2] + 20 and b[3] <= BOUNDS[3] + 20
    # the texture back where the photo resolves it (within 1 km: its pixel a few metres on the
    # ground; farther, at grazing angles, a pixel spans more than the texture's wavelengths)
    errors, seen, near = _errors(tmp_path / "o.tif", texture, centre, 1000.0)
    assert seen.sum() > 2000 and near.sum() > 500 and np.median(errors[near[seen]]) < 2.5


def test_photo_ground_bounds_below_the_top_and_over_the_horizon():
    within = (0.0, 0.0, 1000.0, 1000.0)
    nadir = frame_photo((500.0, 500.0, 300.0), (0.0, 0.0, 0.0), width=100, height=100)
    # terrain 200-400 m, camera at 300 m: the slice between 200 m and the camera; half side of
    # the frame's view at 100 m below it = 100 * 115 / 153
    half = 100.0 * 115.0 / 153.0
    assert photo_ground_bounds(nadir, 200.0, 400.0) == pytest.approx(
        (500 - half, 500 - half, 500 + half, 500 + half))
    with pytest.raises(InputDataError, match="never reach"):
        photo_ground_bounds(nadir, 350.0, 400.0)
    oblique = frame_photo((1500.0, -200.0, 300.0), (1.2, 0.0, 0.0), width=100, height=100)
    with pytest.raises(InputDataError, match="horizon"):
        photo_ground_bounds(oblique, 0.0, 100.0)
    b = photo_ground_bounds(oblique, 0.0, 100.0, within)
    # truth: the points of the box (at 0 and 100 m) that project into the frame lie inside b,
    # which leaves out the box's south-west (the photo looks north from south-east of it)
    g = np.meshgrid(np.linspace(0, 1000, 101), np.linspace(0, 1000, 101), [0.0, 100.0])
    ground = np.column_stack([v.ravel() for v in g])
    mm = oblique.ground_to_image(ground, behind="nan")
    seen = ground[(np.abs(mm) <= 115.0).all(axis=1)]
    assert len(seen) > 100
    assert (seen[:, 0] >= b[0] - 1e-6).all() and (seen[:, 1] >= b[1] - 1e-6).all()
    assert b[2] == 1000.0 and b[3] == 1000.0 and b[0] > 100.0 and b[1] > 100.0


def _march(module, photo, surface, pixels):
    from toolbox.photogrammetry.collinearity import _distortion_args

    args = photo._args()
    p2f = photo.require_pixel_transform().pixel_to_fiducial
    dem, gx0, gy0, cx, cy, zmin, zmax = surface.kernel_arguments()
    n = len(pixels)
    out, status, its = np.empty((n, 3)), np.empty(n, np.int8), np.empty(n, np.int32)
    module.monoplot(np.ascontiguousarray(pixels[:, 0]), np.ascontiguousarray(pixels[:, 1]),
                    np.asarray(args["centre"], float), np.asarray(args["rotation"], float),
                    float(args["principal_distance"]), np.asarray(args["principal_point"], float),
                    *_distortion_args(None), np.ascontiguousarray(p2f), dem, gx0, gy0, cx, cy,
                    zmin, zmax, 0, 0.0, 1e-9, 100, out, status, its)
    return out, status


@pytest.mark.parametrize("module", [kernels, kernels_numpy])
def test_monoplot_from_a_camera_beside_the_dem(module):
    """A camera south of the DEM looking north over it: its rays were 'outside_dem' (the march
    started above the camera's own position, off the DEM) though they meet the DEM."""
    z = np.full((50, 50), 100.0)
    z[:3, :] = 130.0  # the north edge a little higher: the DEM's top is above the camera's rays
    surface = DemSurface.from_transform(z, Affine(10.0, 0, 0, 0, -10.0, 500.0))
    photo = frame_photo((250.0, -300.0, 400.0), (0.8, 0.0, 0.0), width=100, height=100)
    pixels = np.array([[50.0, 50.0], [20.0, 45.0], [70.0, 30.0]])
    out, status = _march(module, photo, surface, pixels)
    # truth: the collinearity equations by hand, cut at Z = 100
    args = photo._args()
    rot, c = np.asarray(args["rotation"]), float(args["principal_distance"])
    mm = np.column_stack([pixels, np.ones(3)]) @ photo.require_pixel_transform().pixel_to_fiducial.T
    rays = np.column_stack([mm[:, :2] / mm[:, 2:], np.full(3, -c)]) @ rot.T
    truth = np.array([250.0, -300.0, 400.0]) + ((100.0 - 400.0) / rays[:, 2])[:, None] * rays
    assert (truth[:, 1] > 5.0).all() and (truth[:, 1] < 470.0).all()  # on the flat part
    assert status.tolist() == [0, 0, 0]
    np.testing.assert_allclose(out, truth, atol=1e-6)
    # a ray coming over the DEM's south edge below its surface met the terrain before the DEM:
    # outside it
    z[-3:, :] = 390.0
    wall = DemSurface.from_transform(z, Affine(10.0, 0, 0, 0, -10.0, 500.0))
    out, status = _march(module, photo, wall, pixels[:1])
    assert status.tolist() == [1] and np.isnan(out).all()


def test_cells_above_the_camera_are_checked_for_occlusion():
    """A camera in a valley (Z0 = 100) looking up a slope (its cells up to 205 m): the cells
    above the camera were never tested (always 'seen'), so a ridge between them and the camera
    hid nothing in the true ortho. Truth: the line of sight sampled every 0.5 m against the
    DSM (scipy's bilinear interpolation)."""
    from scipy.interpolate import RegularGridInterpolator

    from toolbox.ortho.visibility import visibility_mask

    xs = np.arange(-95.0, 600.0, 10.0)
    ys = np.arange(95.0, -100.0, -10.0)
    gx, gy = np.meshgrid(xs, ys)
    dsm = 50.0 + np.maximum(0.0, gx - 250.0)
    dsm[(gx > 195) & (gx < 225) & (gy > 0)] = 180.0  # a ridge on the north half only
    surface = DemSurface(dsm, xs[0], ys[0], 10.0, 10.0)
    centre = np.array([0.0, 0.0, 100.0])
    cells_x, cells_y = np.array([405.0]), np.array([55.0, -55.0])
    z = 50.0 + (cells_x - 250.0) * np.ones((2, 1))
    hidden = visibility_mask(cells_x, cells_y, z, centre, surface)
    interp = RegularGridInterpolator((ys[::-1], xs), dsm[::-1])
    truth = []
    for y in cells_y:
        t = np.linspace(0.0, 1.0, 2000)[1:-1]
        line = np.array([405.0, y, 205.0]) + t[:, None] * (centre - (405.0, y, 205.0))
        truth.append(int((interp(line[:, 1::-1]) > line[:, 2] + 0.1).any()))
    assert truth == [1, 0]
    assert hidden[:, 0].tolist() == truth


@pytest.mark.parametrize("module", [kernels, kernels_numpy])
def test_monoplot_rising_rays_meet_the_slope_above_the_camera(module):
    """A camera 30 m above a valley floor looking level and up the slope across it (the plane
    Z = 20 + 0.5·Y): its rising rays were 'ray_not_descending' (no point), though they meet the
    slope; the synthetic photos left those pixels empty. Truth: each ray cut with the plane by
    hand."""
    xs = np.arange(-300.0, 300.0, 10.0)
    ys = np.arange(1000.0, -200.0, -10.0)
    z = np.broadcast_to(20.0 + 0.5 * np.maximum(ys, 0.0)[:, None], (len(ys), len(xs)))
    surface = DemSurface(np.array(z), xs[0], ys[0], 10.0, 10.0)
    # looking north, tilted 70 degrees from the nadir: the upper rows of the frame rise
    photo = frame_photo((0.0, -100.0, 50.0), (np.radians(70.0), 0.0, 0.0), width=100,
                        height=100)
    pixels = np.array([[50.0, 20.0], [50.0, 5.0], [20.0, 10.0], [90.0, 2.0]])
    out, status = _march(module, photo, surface, pixels)
    args = photo._args()
    rot, c = np.asarray(args["rotation"]), float(args["principal_distance"])
    mm = np.column_stack([pixels, np.ones(4)]) @ photo.require_pixel_transform().pixel_to_fiducial.T
    rays = np.column_stack([mm[:, :2] / mm[:, 2:], np.full(4, -c)]) @ rot.T
    assert (rays[:, 2] > 0).all()  # rising
    # (0, -100, 50) + t·ray on Z = 20 + 0.5·Y (Y > 0 there)
    t = (20.0 + 0.5 * -100.0 - 50.0) / (rays[:, 2] - 0.5 * rays[:, 1])
    truth = np.array([0.0, -100.0, 50.0]) + t[:, None] * rays
    assert (t > 0).all() and (truth[:, 1] > 0).all() and (np.abs(truth[:, 0]) < 290).all()
    assert status.tolist() == [0, 0, 0, 0]
    np.testing.assert_allclose(out, truth, atol=1e-6)
    # a ray rising over the highest terrain: the sky
    sky, status = _march(module, frame_photo((0.0, -100.0, 600.0), (np.radians(100.0), 0.0, 0.0),
                                             width=100, height=100), surface, pixels[:1])
    assert status.tolist() == [4] and np.isnan(sky).all()


def test_oblique_photo_up_a_slope_from_a_low_camera(tmp_path):
    """A camera 3 m above a valley floor, its axis 83 degrees off the nadir towards the highest
    hill: the footprint's mean height lies above the camera, and the GSD on that plane was
    refused ('4 image ray(s) do not meet the height plane in front of the camera', exit 2).
    The GSD and reference height of an oblique photo are now taken where its principal ray
    meets the DEM. Truth: the principal ray marched by hand every 0.05 m over scipy's bilinear
    DEM."""
    import math

    from scipy.interpolate import RegularGridInterpolator

    from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

    z, t = hills_dem(BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=3)
    inner = z[10:-10, 10:-10]
    i, j = np.unravel_index(np.argmin(inner), inner.shape)
    top_i, top_j = np.unravel_index(np.argmax(z), z.shape)
    x, y = t.c + (j + 10.5) * t.a, t.f + (i + 10.5) * t.e
    azimuth = math.atan2(t.c + (top_j + 0.5) * t.a - x, t.f + (top_i + 0.5) * t.e - y)
    angles = angles_from_matrix(rotation_matrix(0.0, 0.0, -azimuth)
                                @ rotation_matrix(math.radians(83.0), 0.0, 0.0))
    centre = (float(x), float(y), float(z[i + 10, j + 10]) + 3.0)
    _, _, texture, project = _scene(tmp_path, centre, angles, size=60)
    stats = toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "PROJECT": project,
                                        "DEM": tmp_path / "dem.tif",
                                        "OUTPUT": tmp_path / "o.tif"})["STATISTICS"]
    axis = rotation_matrix(*angles) @ np.array([0.0, 0.0, -1.0])
    xs = t.c + (np.arange(z.shape[1]) + 0.5) * t.a
    ys = t.f + (np.arange(z.shape[0]) + 0.5) * t.e
    dem = RegularGridInterpolator((ys[::-1], xs), z[::-1].astype(float))
    steps = np.arange(1.0, 3000.0, 0.05)
    ray = np.array(centre) + steps[:, None] * axis
    inside = (ray[:, 0] > xs[0]) & (ray[:, 0] < xs[-1]) & (ray[:, 1] > ys[-1]) & \
        (ray[:, 1] < ys[0])
    under = np.flatnonzero(inside & (ray[:, 2] <= dem(np.clip(ray[:, 1::-1], [ys[-1], xs[0]],
                                                              [ys[0], xs[-1]]))))
    assert under.size and stats["reference_height"] == pytest.approx(ray[under[0], 2], abs=0.1)
    assert stats["reference_height"] < centre[2]


def test_angles_near_gimbal_lock_give_the_matrix_back():
    """phi within 1e-12..1e-8 rad of ±90 degrees (a camera looking level along X, its matrix
    from OpenCV's Rodrigues): omega and kappa were each divided out of elements ~cos(phi)
    small, and the angles rebuilt a matrix up to 7e-4 off (2 cm at 30 m). Truth: the matrix."""
    import cv2

    from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

    rng = np.random.default_rng(0)
    worst = 0.0
    for eps in (0.0, 1e-12, 1e-11, 1e-10, 1e-8, 1e-6, 1e-2):
        for sign in (1.0, -1.0):
            for omega, kappa in rng.uniform(-3.0, 3.0, (40, 2)):
                r = rotation_matrix(omega, sign * (np.pi / 2 - eps), kappa)
                r = cv2.Rodrigues(cv2.Rodrigues(r)[0])[0]
                worst = max(worst, np.abs(rotation_matrix(*angles_from_matrix(r)) - r).max())
    assert worst < 1e-10


def test_check_flags_a_known_point_behind_the_photo(tmp_path):
    """orientation:check of an oblique photo with a control point 3 km behind it (a wrong id):
    the whole check was refused, exit 2, '1 ground point(s) lie on or behind the plane of the
    projection centre and have no image (first: index 0)', naming neither point nor photo. The
    point is now flagged without residual, named in a warning; the others are checked. Truth:
    the collinearity equations by hand."""
    from toolbox.photogrammetry.rotation import rotation_matrix

    centre, angles = np.array([1687400.0, 4797000.0, 1000.0]), (0.7, 0.0, 0.0)
    project = _project(tmp_path / "project.yaml", tuple(map(float, centre)), angles, 120)
    rot = rotation_matrix(*angles)
    ground = np.array([[1687400.0, 4798000.0, 300.0], [1687300.0, 4798200.0, 310.0],
                       [1687400.0, 4794000.0, 300.0]])
    d = (ground - centre) @ rot  # camera coordinates Rᵀ·(P - C)
    assert (d[:2, 2] < 0).all() and d[2, 2] > 0  # A, B in front; D behind
    pixel = 230.0 / 120
    cols = -153.0 * d[:, 0] / d[:, 2] / pixel + 60.0
    rows = 60.0 + 153.0 * d[:, 1] / d[:, 2] / pixel
    (tmp_path / "control.csv").write_text("id,X,Y,Z\n" + "".join(
        f"{n},{x},{y},{z}\n" for n, (x, y, z) in zip("ABD", ground, strict=True)))
    (tmp_path / "meas.csv").write_text("point_id,photo,col_px,row_px\n" + "".join(
        f"{n},p1,{c},{r}\n" for n, c, r in zip("AB", cols[:2], rows[:2], strict=True)) + "D,p1,30,40\n")
    feedback = toolbox.Feedback()
    toolbox.run("orientation:check", {"PROJECT": project, "INPUT": tmp_path / "meas.csv",
                                      "CONTROL": tmp_path / "control.csv",
                                      "REPORT": tmp_path / "r.json"}, feedback=feedback)
    import json

    obs = {o["point_id"]: o for o in json.loads((tmp_path / "r.json").read_text())["observations"]}
    assert obs["A"]["res_px"] < 1e-6 and obs["B"]["res_px"] < 1e-6
    assert not obs["A"]["flagged"] and obs["D"]["flagged"]
    assert obs["D"]["res_um"] is None and obs["D"]["res_px"] is None
    assert any("D on p1" in w for w in feedback.warnings)


def test_ortho_check_chip_of_a_point_behind_the_photo_is_none():
    """report:ortho_check's reference chip of a check point behind the photo (a wrong id on an
    oblique photo) raised '... lie on or behind the plane of the projection centre ... (first:
    index 0)' and stopped the whole check; it is now no chip ('outside the photo'), as a chip
    leaving the photo. Truth: the point's camera z by hand (> 0: behind)."""
    from toolbox.cartography.quality_ortho import photo_chip
    from toolbox.photogrammetry.rotation import rotation_matrix

    centre, angles = (1687400.0, 4797000.0, 1000.0), (0.7, 0.0, 0.0)
    photo = frame_photo(centre, angles, width=120, height=120)
    behind = np.array([1687400.0, 4794000.0, 300.0])
    assert ((behind - centre) @ rotation_matrix(*angles))[2] > 0

    def read_window(c0, r0, c1, r1):
        return np.full((max(r1 - r0, 0), max(c1 - c0, 0)), 100.0), (c0, r0)

    assert photo_chip(photo, read_window, behind, np.array([30.0, 40.0]), 1.0, 4) is None
    front = np.array([1687400.0, 4798000.0, 300.0])
    measured = photo.ground_to_pixel(front[None])[0]
    assert photo_chip(photo, read_window, front, measured, 1.0, 4) is not None
