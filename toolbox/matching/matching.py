"""Matching two photos' features: nearest neighbours with Lowe's ratio test, then geometric
verification by a fundamental matrix estimated with OpenCV's USAC/MAGSAC++
(``cv2.findFundamentalMat(..., cv2.USAC_MAGSAC)``), and, when both photos are oriented, the
distance of each match from its epipolar line computed from the orientations.

Distances are in pixels of the coordinates given (the callers pass full-resolution pixels).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from toolbox.matching.features import Features, binary

Normaliser = Callable[[np.ndarray], np.ndarray]


@dataclass
class EpipolarModel:
    """The two-view geometry estimated for a pair: a fundamental matrix on pixels (``kind``
    "F", OpenCV pixel frame) or an essential matrix on normalised camera coordinates (``kind``
    "E": ``to_a``/``to_b`` map pixels to ``(x̄/c, ȳ/c)``, ``angle`` is one pixel's angle)."""

    matrix: np.ndarray
    kind: str
    to_a: Normaliser | None = None
    to_b: Normaliser | None = None
    angle: float = 1.0

    def residual(self, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
        """Symmetric distance (px) of matched pixels ``xa``, ``xb`` (N, 2) from the epipolar
        lines of the model."""
        if self.kind == "F":
            return symmetric_epipolar_distance(self.matrix, xa - 0.5, xb - 0.5)
        return symmetric_epipolar_distance(self.matrix, self.to_a(xa), self.to_b(xb)) / self.angle


@dataclass
class PairMatches:
    """Matches of photo a with photo b: indices into each photo's features, and per match the
    symmetric distance to the epipolar lines of the estimated model (px). ``candidates`` counts
    the matches that passed the ratio test (before the geometric check)."""

    ia: np.ndarray
    ib: np.ndarray
    f_residual: np.ndarray
    candidates: int
    model: EpipolarModel | None = None

    def __len__(self) -> int:
        return len(self.ia)


def ratio_matches(a: Features, b: Features, ratio: float = 0.8, detector: str = "sift"
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(ia, ib)`` of the matches whose nearest neighbour in b is closer than ``ratio``
    times the second nearest, and that are mutual (a's best in b has b's best in a)."""
    import cv2

    if len(a) < 2 or len(b) < 2:
        return np.zeros(0, int), np.zeros(0, int)
    def make():
        if binary(detector):
            return cv2.BFMatcher(cv2.NORM_HAMMING)
        # kd-trees (FLANN): several times faster than brute force on SIFT's 128 floats
        return cv2.FlannBasedMatcher({"algorithm": 1, "trees": 4}, {"checks": 64})

    # FLANN's randomised kd-trees draw from OpenCV's RNG (one per thread, in whatever state
    # earlier calls left it): seeded, a pair's matches are the same on any thread or worker
    cv2.setRNGSeed(0)
    matcher = make()
    knn = matcher.knnMatch(a.descriptors, b.descriptors, k=2)
    ia, ib = [], []
    for pair in knn:
        if len(pair) == 2 and pair[0].distance < ratio * pair[1].distance:
            ia.append(pair[0].queryIdx)
            ib.append(pair[0].trainIdx)
    if not ia:
        return np.zeros(0, int), np.zeros(0, int)
    ia, ib = np.array(ia), np.array(ib)
    back = make().knnMatch(b.descriptors[ib], a.descriptors, k=1)
    mutual = np.array([m[0].trainIdx if m else -1 for m in back]) == ia  # every ib unique
    return ia[mutual], ib[mutual]


def symmetric_epipolar_distance(f: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Mean of the distances of ``xb`` from ``F·xa`` and of ``xa`` from ``Fᵀ·xb`` (px)."""
    ha = np.column_stack([xa, np.ones(len(xa))])
    hb = np.column_stack([xb, np.ones(len(xb))])
    la = ha @ f.T  # lines in b
    lb = hb @ f  # lines in a
    num = np.abs(np.sum(hb * la, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        return 0.5 * (num / np.hypot(la[:, 0], la[:, 1]) + num / np.hypot(lb[:, 0], lb[:, 1]))


def verify(a: Features, b: Features, ia: np.ndarray, ib: np.ndarray, threshold_px: float,
           confidence: float = 0.9999, min_matches: int = 12,
           cameras: tuple[Normaliser, Normaliser, float] | None = None) -> PairMatches:
    """Keep the matches consistent with one two-view geometry (USAC/MAGSAC++, inlier threshold
    ``threshold_px``); none when fewer than ``min_matches`` candidates or inliers.

    Without ``cameras`` a fundamental matrix is fitted on the pixels. With ``cameras`` =
    ``(to_a, to_b, pixel angle)`` (pixels -> normalised camera coordinates of each photo) an
    essential matrix is fitted instead: 5 degrees of freedom instead of 7, and the five-point
    solver does not degenerate on the nearly flat scenes of aerial photos, where a fundamental
    matrix can absorb wrong matches.
    """
    import cv2

    empty = PairMatches(np.zeros(0, int), np.zeros(0, int), np.zeros(0), len(ia))
    if len(ia) < max(8, min_matches):
        return empty
    xa = a.xy[ia].astype("float64")
    xb = b.xy[ib].astype("float64")
    try:
        if cameras is None:
            # OpenCV's pixel centres are at integers: F lives in OpenCV's frame
            m, inliers = cv2.findFundamentalMat(xa - 0.5, xb - 0.5, cv2.USAC_MAGSAC,
                                                threshold_px, confidence, 10000)
            model = None if m is None else EpipolarModel(m, "F")
        else:
            to_a, to_b, angle = cameras
            na, nb = to_a(xa), to_b(xb)
            # a model camera's pixel that does not invert (past its lens field) is no match
            fin = np.isfinite(na).all(axis=1) & np.isfinite(nb).all(axis=1)
            if fin.sum() < max(8, min_matches):
                return empty
            ia, ib, xa, xb = ia[fin], ib[fin], xa[fin], xb[fin]
            m, inliers = cv2.findEssentialMat(na[fin], nb[fin], np.eye(3), cv2.USAC_MAGSAC,
                                              confidence, threshold_px * angle)
            model = None if m is None else EpipolarModel(m[:3], "E", to_a, to_b, angle)
    except cv2.error:
        return empty
    if model is None or inliers is None or model.matrix.shape != (3, 3):
        return empty
    keep = inliers.ravel().astype(bool)
    if model.kind == "F" and keep.sum() >= min_matches:
        keep &= _planar_check(xa, xb, keep, threshold_px, confidence)
    if keep.sum() < min_matches:
        return empty
    return PairMatches(ia[keep], ib[keep], model.residual(xa[keep], xb[keep]), len(ia), model)


#: share of a fundamental matrix's inliers that one homography explains, from which the scene
#: counts as planar (flat ground seen by nadir photos)
PLANAR_SHARE = 0.9


def _planar_check(xa: np.ndarray, xb: np.ndarray, keep: np.ndarray, threshold_px: float,
                  confidence: float) -> np.ndarray:
    """Mask of the matches to keep after a homography check of a fundamental matrix's inliers.

    On a planar scene (flat ground, nadir photos) the fundamental matrix is degenerate: a
    one-parameter family fits the true matches, and a wrong match anywhere along its (ill-
    defined) epipolar line passes. When one homography explains ``PLANAR_SHARE`` of the
    inliers (USAC/MAGSAC, threshold 3 x ``threshold_px``: lens distortion and small relief
    stay in), the homography decides instead; otherwise every inlier is kept."""
    import cv2

    idx = np.flatnonzero(keep)
    try:
        h, on = cv2.findHomography(xa[idx] - 0.5, xb[idx] - 0.5, cv2.USAC_MAGSAC,
                                   3.0 * threshold_px, maxIters=10000, confidence=confidence)
    except cv2.error:
        return np.ones(len(keep), bool)
    if h is None or on is None or on.sum() < PLANAR_SHARE * len(idx):
        return np.ones(len(keep), bool)
    out = np.ones(len(keep), bool)
    out[idx[~on.ravel().astype(bool)]] = False
    return out


def has_camera(photo) -> bool:
    """True when pixels of ``photo`` can be turned into rays: an interior model camera (Brown,
    OpenCV...) or a film/digital camera with a pixel transform."""
    return photo is not None and (photo.is_model or photo.pixel_transform is not None)


def normaliser(photo) -> Normaliser:
    """Pixels -> normalised camera coordinates ``(x̄/c, ȳ/c)`` (x right, y up; the ray is
    ``(x̄/c, ȳ/c, -1)``) of a photo with a camera: an interior model (its distortion inverted;
    NaN where a pixel does not invert) or a film camera with a pixel transform (interior
    orientation or pixel size)."""
    if photo.is_model:
        return photo.camera.pixel_to_normalised
    transform = photo.require_pixel_transform()
    camera = photo.camera

    def to_normal(xy: np.ndarray) -> np.ndarray:
        return camera.image_to_camera(transform.pixel_to_image(xy)) / camera.c

    return to_normal


def ground_rays(photo, xy_px: np.ndarray) -> np.ndarray:
    """Unit ray directions in the ground frame, ``R·(x̄/c, ȳ/c, -1)``, of pixels ``(col, row)``
    of an oriented photo (interior orientation, principal point and distortion applied)."""
    xy = normaliser(photo)(np.asarray(xy_px, dtype="float64").reshape(-1, 2))
    v = np.column_stack([xy, -np.ones(len(xy))])
    d = v @ photo.require_exterior().rotation.T
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def pixel_angle(photo) -> float:
    """Approximate angle subtended by one pixel at the principal point (radians)."""
    if photo.is_model:
        fx, fy = photo.camera.focal_px
        return float(1.0 / np.sqrt(fx * fy))
    p2f = photo.require_pixel_transform().pixel_to_fiducial
    size = np.sqrt(abs(np.linalg.det(p2f[:2, :2])))
    return float(size / photo.camera.c)


def orientation_epipolar_distance(photo_a, photo_b, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Distance (px, mean of both photos) of each match from the epipolar plane that the two
    orientations define: the angle between a ray and the plane through the base and the other
    ray, over the angle of one pixel."""
    da = ground_rays(photo_a, xa)
    db = ground_rays(photo_b, xb)
    base = photo_b.require_exterior().centre - photo_a.require_exterior().centre
    na = np.cross(base, da)
    nb = np.cross(base, db)
    na /= np.linalg.norm(na, axis=1, keepdims=True)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    sin_b = np.abs(np.sum(na * db, axis=1))
    sin_a = np.abs(np.sum(nb * da, axis=1))
    return 0.5 * (np.arcsin(np.clip(sin_b, 0, 1)) / pixel_angle(photo_b)
                  + np.arcsin(np.clip(sin_a, 0, 1)) / pixel_angle(photo_a))
