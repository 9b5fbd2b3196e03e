"""Kernels of toolbox.matching against independent references (images evaluated analytically
at exactly warped positions, hand-built cases)."""

from __future__ import annotations

import numpy as np
import pytest


def smooth_noise(shape, sigma=2.0, seed=0):
    import cv2

    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.uniform(0, 255, shape).astype(np.float32), (0, 0), sigma)
    return (img - img.mean()) / img.std() * 40 + 128


def waves(seed=0, n=40, shortest=10.0, longest=50.0):
    """An analytic image ``f(x, y)`` (pixels): a sum of plane waves of random direction, phase
    and wavelength, so that a warped copy is evaluated exactly (no interpolation in the
    reference)."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, np.pi, n)
    k = 2 * np.pi / rng.uniform(shortest, longest, n)
    phase = rng.uniform(0, 2 * np.pi, n)

    def f(x, y):
        v = np.zeros_like(x, dtype="float64")
        for a, kk, p in zip(angle, k, phase, strict=True):
            v += np.sin(kk * (np.cos(a) * x + np.sin(a) * y) + p)
        return (128 + 60 * v / np.sqrt(n / 2)).astype(np.float32)

    return f


def render(f, shape, affine=None, shift=(0.0, 0.0), centre=(100.0, 100.0)):
    """Pixel centres (toolbox convention: +0.5) of an image ``other`` with
    ``other(A·(x - c) + c + t) = f(x)``, i.e. ``other(y) = f(A⁻¹·(y - c - t) + c)``."""
    rows, cols = shape
    yy, xx = np.mgrid[0:rows, 0:cols] + 0.5
    inv = np.linalg.inv(np.eye(2) if affine is None else affine)
    u = np.stack([xx - centre[0] - shift[0], yy - centre[1] - shift[1]])
    x = inv[0, 0] * u[0] + inv[0, 1] * u[1] + centre[0]
    y = inv[1, 0] * u[0] + inv[1, 1] * u[1] + centre[1]
    return f(x, y)


def test_ncc_peak_is_subpixel():
    from toolbox.matching.ncc import peak, scores

    f = waves(seed=0)
    image = render(f, (120, 120))
    shifted = render(f, (120, 120), shift=(0.3, -0.4))
    template = image[50:71, 50:71]
    p = peak(scores(shifted[44:77, 44:77], template))
    # the template's top-left (50, 50) moved to (50.3, 49.6): offset 6 in the search window;
    # a parabola's known bias toward the integer (pixel locking) stays below 0.1 px
    assert p.x == pytest.approx(6.3, abs=0.1) and p.y == pytest.approx(5.6, abs=0.1)
    assert p.score > 0.95 and p.runner_up < p.score and not p.on_border


@pytest.mark.parametrize("angle, scale", [(0.0, 1.0), (30.0, 1.1), (180.0, 0.95)])
def test_refine_under_rotation_and_scale(angle, scale):
    from toolbox.matching.refine import refine_pair

    f = waves(seed=1)
    image = render(f, (200, 200))
    th = np.deg2rad(angle)
    a = scale * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    t, c = np.array([3.3, -2.7]), np.array([100.0, 100.0])
    other = render(f, (200, 200), a, t, c)
    p = np.array([90.3, 110.6])
    true = a @ (p - c) + c + t
    r = refine_pair(image, (0, 0), p, other, (0, 0), true + [1.2, -0.8], a, 10, 4, 0.7)
    assert r.ok and np.hypot(*(r.xy - true)) < 0.03


def test_refine_rejects_a_flat_patch():
    from toolbox.matching.refine import refine_pair

    flat = np.full((60, 60), 100.0, np.float32)
    r = refine_pair(flat, (0, 0), np.array([30.0, 30.0]), flat, (0, 0), np.array([30.0, 30.0]),
                    np.eye(2))
    assert not r.ok


def test_tracks_drop_inconsistent_chains():
    from toolbox.matching.tracks import build_tracks

    matches = [(0, 1, np.array([0, 1]), np.array([5, 6])),
               (1, 2, np.array([5, 6]), np.array([9, 7])),
               # feature 1 of photo 0 joins feature 3 of photo 2, whose track already holds
               # feature 0 of photo 0 (via 0-5-9)? no: 3 is new; 0 -> 9 closes the loop
               (0, 2, np.array([0, 2]), np.array([9, 7]))]
    tracks, dropped = build_tracks(matches, 100)
    # 0-5-9 is consistent (closed loop); 1-6-7 and 2-7 put two features of photo 0 together
    assert tracks == [[(0, 0), (1, 5), (2, 9)]]
    assert dropped == 1


def test_thinning_prefers_multi_ray_points_one_per_cell():
    from toolbox.matching.thinning import coverage_3x3, thin

    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 100, (400, 2))
    rays = np.where(rng.uniform(size=400) < 0.2, 3, 2)
    keep = thin([(np.arange(400), xy)], rays, rng.uniform(size=400), target=16)
    assert 12 <= keep.sum() <= 16
    cells = (xy[keep] // 25).astype(int)
    assert len({tuple(c) for c in cells}) == keep.sum()  # one per cell of the 4 x 4 grid
    # each cell kept a 3-ray point whenever it had one
    for cell in {tuple(c) for c in (xy // 25).astype(int)}:
        inside = ((xy // 25).astype(int) == cell).all(axis=1)
        if (rays[inside] == 3).any():
            assert (rays[inside & keep] == 3).all()
    assert coverage_3x3(xy[keep], np.zeros(2), np.full(2, 100.0)) == 9


def test_window_reads_match_the_whole_image_with_a_rotated_geotransform(tmp_path):
    """rasterio's boundless windows go through a VRT that misplaces rotated geotransforms;
    the clipped read with padding must not."""
    import rasterio
    from affine import Affine

    from toolbox.matching.images import ImageSource

    data = (np.arange(300 * 200) % 251).astype(np.uint8).reshape(1, 300, 200)
    path = tmp_path / "rot.tif"
    with rasterio.open(path, "w", driver="GTiff", width=200, height=300, count=1, dtype="uint8",
                       transform=Affine(-5.6, -0.02, 1000.0, -0.02, 5.6, 2000.0)) as dst:
        dst.write(data)
    src = ImageSource.open(path)
    src.WHOLE_LIMIT = 0  # force windowed reads
    w = src.window(-5, 290, 30, 20)
    assert (w[:10, 5:] == data[0, 290:300, 0:25]).all() and not w[10:].any() and not w[:, :5].any()
    level, (sx, sy) = src.level(2.0)
    assert level.shape == (150, 100) and (sx, sy) == (2.0, 2.0)


def test_detection_in_tiles_keeps_each_keypoint_once():
    from toolbox.matching.features import detect

    image = smooth_noise((300, 300), sigma=1.5, seed=3).clip(0, 255).astype(np.uint8)
    tiled = detect(image, tile=128, per_tile=5000)
    whole = detect(image, tile=1024, per_tile=50000)
    # SIFT may give one position several orientations; a seam must not give it twice
    key = {(round(x, 2), round(y, 2), round(a, 1)) for (x, y), a in zip(tiled.xy, tiled.angle,
                                                                       strict=True)}
    assert len(key) == len(tiled) and len(tiled) > 0.8 * len(whole)


def test_border_mask_keeps_features_off_the_fiducial_strip():
    from toolbox.matching.features import border_mask, detect

    image = smooth_noise((300, 400), sigma=1.5, seed=4).clip(0, 255).astype(np.uint8)
    mask = border_mask(300, 400, 40)
    feats = detect(image, mask)
    assert len(feats) > 50
    x, y = feats.xy.T
    assert x.min() >= 40 and y.min() >= 40 and x.max() <= 360 and y.max() <= 260
    assert border_mask(300, 400, 0) is None


@pytest.mark.parametrize("family, area_mm2", [
    ("dot", np.pi * 0.5 ** 2),  # 1 mm disc
    ("cross", 2 * 1.0 * 0.1 - 0.1 ** 2),  # two 1 x 0.1 mm bars, their overlap once
])
def test_built_in_marks_have_their_analytic_area(family, area_mm2):
    from toolbox.matching.marks import draw

    pixel = 0.02
    mark = draw(family, 1.0, 0.1, pixel)
    assert mark.shape[0] == mark.shape[1] and mark.shape[0] % 2 == 1
    assert mark.sum() * pixel ** 2 == pytest.approx(area_mm2, rel=0.01)
    # centred on the central pixel: the centroid is there
    yy, xx = np.mgrid[:mark.shape[0], :mark.shape[1]]
    centre = mark.shape[0] // 2
    assert (xx * mark).sum() / mark.sum() == pytest.approx(centre, abs=1e-6)
    assert (yy * mark).sum() / mark.sum() == pytest.approx(centre, abs=1e-6)


def test_turned_templates_are_numpy_rotations_and_flips():
    from toolbox.matching.fiducial_search import ORIENTATIONS, turned

    t = np.random.default_rng(5).uniform(0, 1, (9, 9)).astype(np.float32)
    # G maps an upright offset (col, row) to the scan's; G = rot 90 (clockwise on screen)
    assert np.allclose(turned(t, ORIENTATIONS["0"]), t, atol=1e-5)
    assert np.allclose(turned(t, ORIENTATIONS["90"]), np.rot90(t, -1), atol=1e-5)
    assert np.allclose(turned(t, ORIENTATIONS["180"]), np.rot90(t, 2), atol=1e-5)
    assert np.allclose(turned(t, ORIENTATIONS["0m"]), t[:, ::-1], atol=1e-5)


def test_planar_scene_wrong_matches_along_the_epipolar_lines_are_dropped():
    """Nadir views of flat ground: a fundamental matrix is degenerate there, and matches that
    are wrong by 40 px ALONG the true epipolar lines satisfy the true F exactly; the homography
    check drops them and keeps the true matches."""
    from toolbox.matching.features import Features
    from toolbox.matching.matching import symmetric_epipolar_distance, verify

    rng = np.random.default_rng(5)
    k = np.array([[1000.0, 0.0, 500.0], [0.0, 1000.0, 400.0], [0.0, 0.0, 1.0]])
    nadir = np.diag([1.0, -1.0, -1.0])  # OpenCV camera looking down
    turn = cv2_rotation(0.03, -0.02, 0.2)

    def camera(rot, centre):
        return k @ np.hstack([rot, -rot @ np.asarray(centre)[:, None]])

    pa, pb = camera(nadir, [0.0, 0.0, 1000.0]), camera(turn @ nadir, [300.0, 60.0, 1010.0])
    ground = np.column_stack([rng.uniform(-200, 500, 400), rng.uniform(-300, 300, 400),
                              np.zeros(400), np.ones(400)])

    def project(p):
        h = ground @ p.T
        return h[:, :2] / h[:, 2:]

    xa, xb = project(pa), project(pb)
    inside = (xa > 0).all(1) & (xa < [1000, 800]).all(1) & (xb > 0).all(1) & \
        (xb < [1000, 800]).all(1)
    xa, xb = xa[inside], xb[inside]
    # the true F (OpenCV frame): [e_b]x P_b P_a^+
    centre_a = np.array([0.0, 0.0, 1000.0, 1.0])
    e = pb @ centre_a
    f_true = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]]) @ pb @ \
        np.linalg.pinv(pa)
    wrong = np.arange(0, len(xa), 15)
    line = np.column_stack([xa[wrong], np.ones(len(wrong))]) @ f_true.T
    along = np.column_stack([line[:, 1], -line[:, 0]]) / np.hypot(line[:, 0], line[:, 1])[:, None]
    xb = xb.copy()
    xb[wrong] += 40.0 * along
    assert np.abs(symmetric_epipolar_distance(f_true, xa[wrong], xb[wrong])).max() < 1e-6
    noise = rng.normal(0, 0.15, xa.shape)
    n = len(xa)
    fa = Features(xa + 0.5 + noise, np.ones(n), np.zeros(n), np.zeros((n, 128), np.float32))
    fb = Features(xb + 0.5, np.ones(n), np.zeros(n), np.zeros((n, 128), np.float32))
    kept = verify(fa, fb, np.arange(n), np.arange(n), 1.0)
    assert not set(kept.ia.tolist()) & set(wrong.tolist())
    assert len(kept) >= 0.95 * (n - len(wrong))


def cv2_rotation(omega: float, phi: float, kappa: float) -> np.ndarray:
    import cv2

    return cv2.Rodrigues(np.array([omega, phi, kappa]))[0]
