"""Plane transforms: known matrices recovered, Siena interior orientations reproduced."""

import numpy as np
import pytest
from conftest import siena_interior_cases

from toolbox.errors import InputDataError
from toolbox.transforms.plane import AffineTransform, HomographyTransform, SimilarityTransform

H_TRUE = np.array([[0.9, 0.12, 1500.0], [-0.08, 1.1, -320.0], [2e-5, -1e-5, 1.0]])


def grid_points(n=6, span=4000.0):
    u = np.linspace(0, span, n)
    xx, yy = np.meshgrid(u, u)
    return np.column_stack([xx.ravel(), yy.ravel()])


def apply(h, pts):
    p = np.column_stack([pts, np.ones(len(pts))]) @ h.T
    return p[:, :2] / p[:, 2:]


def test_homography_recovered_exactly_without_noise():
    src = grid_points()
    t = HomographyTransform.estimate(src, apply(H_TRUE, src))
    np.testing.assert_allclose(t.params, H_TRUE, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(t.inverse(t(src)), src, atol=1e-7)
    assert t.fit.redundancy == 2 * len(src) - 8
    assert t.fit.sigma0 < 1e-8


def test_homography_with_noise_sigma0_matches_noise():
    rng = np.random.default_rng(1)
    src = grid_points(12)
    dst = apply(H_TRUE, src) + rng.normal(0, 0.05, (len(src), 2))
    t = HomographyTransform.estimate(src, dst)
    assert 0.04 < t.fit.sigma0 < 0.06
    # redundancy numbers sum to the redundancy
    assert t.fit.redundancy_numbers.sum() == pytest.approx(t.fit.redundancy, rel=1e-9)


def test_similarity_and_affine_special_cases():
    src = grid_points(4, 100.0)
    angle, scale = 0.3, 2.5
    sim = np.array([[scale * np.cos(angle), -scale * np.sin(angle), 10],
                    [scale * np.sin(angle), scale * np.cos(angle), -5], [0, 0, 1]])
    t = SimilarityTransform.estimate(src, apply(sim, src))
    assert t.scale == pytest.approx(scale) and t.rotation == pytest.approx(angle)
    aff = np.array([[1.2, 0.3, 7], [-0.1, 0.8, 3], [0, 0, 1]])
    np.testing.assert_allclose(AffineTransform.estimate(src, apply(aff, src)).params, aff,
                               atol=1e-10)
    # a homography fitted to affine data has g = h = 0
    np.testing.assert_allclose(HomographyTransform.estimate(src, apply(aff, src)).params[2, :2], 0,
                               atol=1e-12)


@pytest.mark.parametrize("cls, n", [(SimilarityTransform, 1), (AffineTransform, 2),
                                    (HomographyTransform, 3)])
def test_too_few_points_refused(cls, n):
    src = grid_points(3)[:n]
    with pytest.raises(InputDataError, match="at least"):
        cls.estimate(src, src)


def test_collinear_points_refused():
    src = np.column_stack([np.arange(6.0), 2 * np.arange(6.0)])
    with pytest.raises(InputDataError, match="collinear"):
        HomographyTransform.estimate(src, src + 1)


def test_three_of_four_collinear_refused():
    src = np.array([[0, 0], [1, 0], [2, 0], [0, 1.0]])
    with pytest.raises(InputDataError, match="homography"):
        HomographyTransform.estimate(src, src * 2)


@pytest.mark.parametrize("key, rows, report", siena_interior_cases(), ids=lambda v: "_".join(v)
                         if isinstance(v, tuple) else "")
def test_siena_interior_orientation_reproduced(key, rows, report):
    """Every printed Pixel->Fiducial matrix, residual and 'Sigma globale' to print rounding."""
    px = np.array([[float(r["col_px"]), float(r["row_px"])] for r in rows])
    mm = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in rows])
    cls = AffineTransform if rows[0]["transformation"] == "AFFINE" else HomographyTransform
    t = cls.estimate(px, mm)
    printed = np.array([float(report[f"p2f_{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)])
    np.testing.assert_allclose(t.params.ravel(), printed, atol=1e-6)
    residuals = np.array([[float(r["res_x_mm"]), float(r["res_y_mm"])] for r in rows])
    np.testing.assert_allclose(t.fit.residuals, residuals, atol=1e-6)
    if cls is AffineTransform:
        assert t.fit.variance == pytest.approx(float(report["sigma_globale"]), abs=1e-6)
    else:
        assert t.fit.redundancy == 0 and np.abs(t.fit.residuals).max() < 1e-9


def test_apply_homography_equals_opencv_and_keeps_the_shape():
    import cv2

    from toolbox.transforms.plane import apply_homography

    rng = np.random.default_rng(8)
    m = np.array([[1.1, 0.05, 3.0], [-0.02, 0.95, -7.0], [2e-4, -1e-4, 1.0]])
    pts = rng.uniform(0, 2000, (50, 2))
    want = cv2.perspectiveTransform(pts[None].astype("float64"), m)[0]
    np.testing.assert_allclose(apply_homography(m, pts), want, rtol=1e-12)
    grid = pts.reshape(5, 10, 2)
    out, w = apply_homography(m, grid, return_w=True)
    assert out.shape == (5, 10, 2) and w.shape == (5, 10)
    np.testing.assert_allclose(w, m[2, 0] * grid[..., 0] + m[2, 1] * grid[..., 1] + 1.0)
