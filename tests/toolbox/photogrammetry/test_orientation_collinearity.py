"""Collinearity kernels: the brief's formulas, ground -> image -> ground round trips to 1e-9 m on a
plane and on a DEM, monoplotting on steep terrain, and rays that miss (flagged, never NaN)."""

import math

import numpy as np
import pytest
from affine import Affine

from toolbox.errors import ConvergenceError, InputDataError
from toolbox.photogrammetry import collinearity as col
from toolbox.photogrammetry.camera import Camera, RadialDistortion
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.fiducials import InteriorOrientation
from toolbox.photogrammetry.photo import Photo
from toolbox.photogrammetry.rotation import rotation_matrix
from toolbox.photogrammetry.surface import DemSurface

X0, Y0 = 1688000.0, 4799500.0  # Siena-sized coordinates
C = 303.55


def brief_ground_to_image(xyz, centre, r, c, pp=(0.0, 0.0)):
    """Brief section 4, first form, written out independently of the kernels."""
    dx, dy, dz = (xyz - centre).T
    den = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
    xi = pp[0] - c * (r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz) / den
    eta = pp[1] - c * (r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz) / den
    return np.column_stack([xi, eta])


def brief_image_to_ground(xy, z, centre, r, c, pp=(0.0, 0.0)):
    """Brief section 4, second form."""
    a, b = xy[:, 0] - pp[0], xy[:, 1] - pp[1]
    den = r[2, 0] * a + r[2, 1] * b - r[2, 2] * c
    x = centre[0] + (z - centre[2]) * (r[0, 0] * a + r[0, 1] * b - r[0, 2] * c) / den
    y = centre[1] + (z - centre[2]) * (r[1, 0] * a + r[1, 1] * b - r[1, 2] * c) / den
    return np.column_stack([x, y])


def random_ground(rng, n, half=400.0):
    return np.column_stack([rng.uniform(X0 - half, X0 + half, n),
                            rng.uniform(Y0 - half, Y0 + half, n), rng.uniform(280, 345, n)])


def make_photo(omega=0.02, phi=-0.015, kappa=0.05, distortion=True, homography=False,
               pp=(0.011, -0.007), z0=1460.0):
    dist = RadialDistortion.from_polynomial(-4e-8, 3e-13) if distortion else None
    cam = Camera("test", C, pp, image_size_px=(16644, 16644), pixel_size_mm=0.014,
                 frame_size_mm=(230.0, 230.0), distortion=dist)
    p2f = np.array([[0.014, 0.000025, -117.44], [0.000025, -0.014001, 114.69], [0, 0, 1.0]])
    if homography:
        p2f[2, :2] = [2e-9, -1e-9]
    eo = ExteriorOrientation.from_angles("p", X0 + 12.0, Y0 - 7.0, z0, omega, phi, kappa)
    return Photo("p", cam, eo, InteriorOrientation(p2f, "homography" if homography else "affine"))


def test_kernels_match_the_brief_formulas():
    rng = np.random.default_rng(1)
    centre = np.array([X0, Y0, 1460.0])
    r = rotation_matrix(0.1, -0.2, 2.5)
    xyz = random_ground(rng, 1000)
    xy = col.ground_to_image(xyz, centre, r, C, (0.02, -0.01))
    np.testing.assert_allclose(xy, brief_ground_to_image(xyz, centre, r, C, (0.02, -0.01)),
                               rtol=0, atol=1e-11)
    ground = col.image_to_ground(xy, xyz[:, 2], centre, r, C, (0.02, -0.01))
    np.testing.assert_allclose(ground[:, :2], brief_image_to_ground(xy, xyz[:, 2], centre, r, C,
                                                                    (0.02, -0.01)), atol=1e-8)
    np.testing.assert_array_equal(ground[:, 2], xyz[:, 2])


def test_nadir_photo_is_a_similarity_with_scale_z_over_c():
    """Brief section 6: omega = phi = 0 gives X = X0 + (Z0/c)(cos k x - sin k y) on Z = 0."""
    k = 0.7
    centre = np.array([0.0, 0.0, 1500.0])
    xy = np.array([[10.0, 20.0], [-50.0, 3.0]])
    g = col.image_to_ground(xy, 0.0, centre, rotation_matrix(0, 0, k), 150.0)
    m = 1500.0 / 150.0
    np.testing.assert_allclose(g[:, 0], m * (math.cos(k) * xy[:, 0] - math.sin(k) * xy[:, 1]))
    np.testing.assert_allclose(g[:, 1], m * (math.sin(k) * xy[:, 0] + math.cos(k) * xy[:, 1]))


@pytest.mark.parametrize("homography", [False, True])
@pytest.mark.parametrize("angles", [(0.02, -0.015, 0.05), (0.25, 0.3, 3.1), (-0.2, 0.1, -1.7)])
def test_round_trip_flat_terrain_to_1e9_m(angles, homography):
    rng = np.random.default_rng(7)
    photo = make_photo(*angles, homography=homography)
    xyz = random_ground(rng, 20000, half=250.0)
    px = photo.ground_to_pixel(xyz)
    back = photo.pixel_to_ground(px, xyz[:, 2])
    assert np.abs(back - xyz).max() < 1e-9
    mm = photo.ground_to_image(xyz)
    assert np.abs(photo.image_to_ground(mm, xyz[:, 2]) - xyz).max() < 1e-9


def test_tuple_inputs_keep_their_shape():
    photo = make_photo()
    xs, ys = np.meshgrid(np.linspace(X0 - 100, X0 + 100, 7), np.linspace(Y0 - 80, Y0 + 80, 5))
    zs = np.full_like(xs, 310.0)
    px = photo.ground_to_pixel((xs, ys, zs))
    assert px.shape == (5, 7, 2)
    flat = photo.ground_to_pixel(np.column_stack([xs.ravel(), ys.ravel(), zs.ravel()]))
    np.testing.assert_array_equal(px.reshape(-1, 2), flat)


def analytic_dem(cell=4.0, half=700.0, amplitude=25.0):
    n = int(2 * half / cell) + 1
    xc = X0 - half + cell * np.arange(n)
    yc = Y0 + half - cell * np.arange(n)
    gx, gy = np.meshgrid(xc - X0, yc - Y0)
    z = 310 + amplitude * np.sin(gx / 150.0) * np.cos(gy / 210.0) + 0.01 * gx
    transform = Affine(cell, 0, X0 - half - cell / 2, 0, -cell, Y0 + half + cell / 2)
    return DemSurface.from_transform(z, transform)


def test_round_trip_on_a_dem_to_1e9_m():
    rng = np.random.default_rng(11)
    dem = analytic_dem()
    photo = make_photo(0.03, -0.02, 0.6)
    xy = np.column_stack([rng.uniform(X0 - 300, X0 + 300, 5000), rng.uniform(Y0 - 300, Y0 + 300,
                                                                            5000)])
    xyz = np.column_stack([xy, dem.height(xy[:, 0], xy[:, 1])])
    px = photo.ground_to_pixel(xyz)
    result = photo.monoplot_pixels(px, dem).raise_on_failure()
    assert np.abs(result.xyz - xyz).max() < 1e-9
    fixed = photo.monoplot_pixels(px, dem, method="fixed_point", tolerance=1e-12)
    assert fixed.ok.all() and np.abs(fixed.xyz - xyz).max() < 1e-8


def test_steep_terrain_march_converges_where_fixed_point_fails():
    """A ramp facing the camera, seen about 24 degrees off nadir (tan = 0.45): at 60 degrees
    (slope 1.73, 1.73 * 0.45 < 1) both methods converge; at 75 degrees (3.73 * 0.45 > 1) the
    fixed-point iteration oscillates away and reports it, the march still converges. (Started
    from the DEM's mean, 235 m, the fixed point cycles between the plateaus even at 60 degrees.)"""
    cell = 1.0
    xs = np.arange(-400.0, 400.0 + cell, cell)
    gx, gy = np.meshgrid(xs, xs[::-1])
    photo = make_photo(0.0, 0.0, 0.0, distortion=False, pp=(0.0, 0.0), z0=1000.0)
    for degrees, fixed_ok in ((60, True), (75, False)):
        slope = math.tan(math.radians(degrees))
        z = 300.0 - np.clip(slope * (gx + 300.0), -80.0, 80.0)  # rises westward, faces east
        dem = DemSurface.from_transform(z, Affine(cell, 0, X0 - 400.5, 0, -cell, Y0 + 400.5))
        pts = np.column_stack([X0 - 300.0 + np.linspace(-15, 15, 6), np.linspace(Y0 - 40, Y0 + 30,
                                                                                  6)])
        truth = np.column_stack([pts, dem.height(pts[:, 0], pts[:, 1])])
        tan_off_nadir = np.abs(truth[:, 0] - photo.exterior.x0) / (1000.0 - truth[:, 2])
        assert np.all((0.38 < tan_off_nadir) & (tan_off_nadir < 0.52))
        px = photo.ground_to_pixel(truth)
        march = photo.monoplot_pixels(px, dem).raise_on_failure()
        assert np.abs(march.xyz - truth).max() < 1e-9
        # contraction factor ~0.84 at 60 degrees: rounding keeps a ~2e-9 m limit cycle, hence 1e-7
        fixed = photo.monoplot_pixels(px, dem, method="fixed_point", max_iterations=500,
                                      tolerance=1e-7, z_start=300.0)
        if fixed_ok:
            assert fixed.ok.all() and np.abs(fixed.xyz - truth).max() < 1e-6
        else:
            assert (fixed.status == col.NOT_CONVERGED).all() and np.isnan(fixed.xyz).all()
            with pytest.raises(ConvergenceError, match="not_converged"):
                fixed.raise_on_failure()


def test_rays_missing_the_dem_are_flagged_not_nan():
    dem = analytic_dem(half=150.0)
    photo = make_photo()
    hole = dem.z.copy()
    hole[30:40, 30:40] = np.nan
    holed = DemSurface(hole, dem.x0, dem.y0, dem.cell_x, dem.cell_y)
    inside = np.array([[X0 + 12.0, Y0 - 7.0]])
    nodata_xy = np.array([[dem.x0 + 35 * dem.cell_x, dem.y0 - 35 * dem.cell_y]])
    far = np.array([[X0 + 600.0, Y0]])
    targets = np.vstack([inside, nodata_xy, far])
    xyz = np.column_stack([targets, np.full(3, 310.0)])
    px = photo.ground_to_pixel(xyz)
    result = photo.monoplot_pixels(px, holed)
    assert result.status.tolist() == [col.OK, col.NODATA, col.OUTSIDE]
    assert result.counts() == {"ok": 1, "outside_dem": 1, "dem_nodata": 1}
    assert np.isfinite(result.xyz[0]).all() and np.isnan(result.xyz[1:]).all()
    with pytest.raises(InputDataError, match="2 of 3 rays did not meet the DEM"):
        result.raise_on_failure()


def test_rays_above_the_horizon_and_points_behind_the_camera():
    photo = make_photo(phi=1.3, distortion=False)  # strongly tilted: part of the frame sees sky
    xy = np.array([[0.0, 0.0], [-110.0, 0.0], [110.0, 0.0]])
    with pytest.raises(InputDataError, match="do not meet the height plane"):
        photo.image_to_ground(xy, 300.0)
    g = photo.image_to_ground(xy, 300.0, invalid="nan")
    assert np.isnan(g[:, 0]).sum() >= 1
    result = photo.monoplot_image(xy, analytic_dem())
    assert col.RAY_UPWARD in result.status
    above = np.array([[X0, Y0, 5000.0]])
    with pytest.raises(InputDataError, match="behind the plane of the projection centre"):
        make_photo().ground_to_pixel(above)
    assert np.isnan(make_photo().ground_to_pixel(above, behind="nan")).all()


def test_bad_arguments_refused():
    photo = make_photo()
    with pytest.raises(InputDataError, match=r"\(N, 3\)"):
        photo.ground_to_image(np.zeros((4, 2)))
    with pytest.raises(Exception, match="METHOD must be one of march, fixed_point"):
        photo.monoplot_image(np.zeros((1, 2)), analytic_dem(), method="newton")
    no_io = Photo("q", Camera("bare", 150.0), photo.exterior)
    with pytest.raises(InputDataError, match="no interior orientation"):
        no_io.ground_to_pixel(np.array([[X0, Y0, 300.0]]))
    with pytest.raises(InputDataError, match="no exterior orientation"):
        Photo("r", Camera("bare", 150.0)).ground_to_image(np.array([[X0, Y0, 300.0]]))


def test_agrees_with_opencv_project_points():
    """The field's pinhole model: OpenCV looks down +z with y down, ours down -z with y up, so
    R_cv = diag(1, -1, -1)·Rᵀ and t = -R_cv·C; with K = diag(c, c, 1), (u, v) = (ξ, -η)."""
    import cv2

    rng = np.random.default_rng(5)
    centre = np.array([X0, Y0, 1460.0])
    r = rotation_matrix(0.12, -0.08, 2.2)
    xyz = random_ground(rng, 2000)
    r_cv = np.diag([1.0, -1.0, -1.0]) @ r.T
    rvec, _ = cv2.Rodrigues(r_cv)
    uv, _ = cv2.projectPoints(xyz, rvec, -r_cv @ centre, np.diag([C, C, 1.0]), None)
    uv = uv.reshape(-1, 2)
    ours = col.ground_to_image(xyz, centre, r, C)
    np.testing.assert_allclose(ours, np.column_stack([uv[:, 0], -uv[:, 1]]), atol=1e-8)


@pytest.mark.parametrize("distortion", [
    RadialDistortion.from_table([10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 148],
                                [0.0, 0.1, -0.1, -0.3, -0.5, -0.9, -1.0, -1.1, -0.3, 0.2, 1.2, 1.3,
                                 0.5, -0.4, -1.4], "um"),  # the Siena table (l.2257-2285)
    RadialDistortion.from_table([3.3, 41.0, 41.5, 99.0, 160.0], [20.0, -35.0, 12.0, 40.0, -5.0],
                                "um"),  # uneven nodes
    RadialDistortion.from_polynomial(-4e-8, 3e-13),
])
def test_compiled_distortion_equals_the_camera_model(distortion):
    """The kernels' table lookup (bin index + scan) and Newton inversion against numpy's
    np.interp / fixed point in camera.py."""
    rng = np.random.default_rng(2)
    cam = Camera("d", C, (0.01, -0.02), distortion=distortion)
    centre, r = np.array([X0, Y0, 1460.0]), rotation_matrix(0.05, -0.04, 1.0)
    xyz = random_ground(rng, 5000, half=420.0)
    kernel = col.ground_to_image(xyz, centre, r, C, cam.principal_point_mm, distortion)
    ideal = brief_ground_to_image(xyz, centre, r, C)
    np.testing.assert_allclose(kernel, cam.camera_to_image(ideal), atol=1e-12)
    back = col.image_to_ground(kernel, xyz[:, 2], centre, r, C, cam.principal_point_mm, distortion)
    assert np.abs(back - xyz).max() < 1e-9
