"""Typed description of a bundle block (arrays, no files) and of its adjusted result.

Indices are 0-based into the id lists. Ground coordinates are in the block's CRS (metres);
image observations are image mm in the fiducial system (pixels are converted through each photo's
interior orientation before a block is built; :mod:`toolbox.triangulation.inputs`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolbox.triangulation.model import BROWN_NAMES, CALIBRATION_NAMES, KIND_FILM

FIXED, FREE, WEIGHTED = 0, 1, 2
MODE_NAMES = {"fixed": FIXED, "free": FREE, "weighted": WEIGHTED}


@dataclass
class Block:
    """Unknowns, observations and their a priori sigmas.

    photo_ids, photo_camera (n,) camera index of each photo; camera_names;
    calibration (k, 8) start (and, for weighted parameters, observed) values of
    :data:`~toolbox.triangulation.model.CALIBRATION_NAMES` (mm, mm⁻², ...), or for a Brown
    camera (``camera_kind`` KIND_BROWN; its observations and sigmas in pixels) of
    :data:`~toolbox.triangulation.model.BROWN_NAMES` (px, unitless);
    calibration_mode (k, 8) FIXED / FREE / WEIGHTED; calibration_sigma (k, 8);
    point_ids; obs_photo, obs_point (m,), obs_xy, obs_sigma (m, 2) image mm;
    ground_point (g,), ground_xyz (g, 3) surveyed coordinates (NaN: component not known, e.g.
    a Z-only point has NaN X, Y), ground_sigma (g, 3) metres;
    centre_photo (h,), centre_xyz, centre_sigma (h, 3): GNSS antenna positions, observing
    ``C + R·lever_arm`` (lever_arm (3,): antenna offset in the camera frame, metres: x along the
    image x, y along the image y, z away from the ground; zero = GNSS at the projection centre).
    """

    photo_ids: list[str]
    photo_camera: np.ndarray
    camera_names: list[str]
    calibration: np.ndarray
    point_ids: list[str]
    obs_photo: np.ndarray
    obs_point: np.ndarray
    obs_xy: np.ndarray
    obs_sigma: np.ndarray
    calibration_mode: np.ndarray | None = None
    calibration_sigma: np.ndarray | None = None
    ground_point: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    ground_xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    ground_sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    centre_photo: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    centre_xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    centre_sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    lever_arm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    centre_group: np.ndarray | None = None
    centre_time: np.ndarray | None = None
    gnss_shift: bool = False
    gnss_drift: bool = False
    attitude_photo: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    attitude_obs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    attitude_sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    boresight: bool = False
    camera_kind: np.ndarray | None = None  # (k,) KIND_FILM (image mm) or KIND_BROWN (pixels)
    camera_aspect: np.ndarray | None = None  # (k,) fy/fx of a Brown camera (held fixed)
    camera_models: list | None = None  # (k,) the Intrinsics of KIND_MODEL cameras (else None)

    def __post_init__(self) -> None:
        k = len(self.camera_names)
        self.camera_kind = np.zeros(k, dtype=np.int64) if self.camera_kind is None else \
            np.asarray(self.camera_kind, dtype=np.int64).reshape(k)
        self.camera_aspect = np.ones(k) if self.camera_aspect is None else \
            np.asarray(self.camera_aspect, dtype=float).reshape(k)
        self.photo_camera = np.asarray(self.photo_camera, dtype=np.int64)
        self.calibration = np.asarray(self.calibration, dtype=float).reshape(k, 8)
        if self.calibration_mode is None:
            self.calibration_mode = np.zeros((k, 8), dtype=np.int64)
        if self.calibration_sigma is None:
            self.calibration_sigma = np.full((k, 8), np.nan)
        self.calibration_mode = np.asarray(self.calibration_mode, dtype=np.int64).reshape(k, 8)
        self.calibration_sigma = np.asarray(self.calibration_sigma, dtype=float).reshape(k, 8)
        h = len(np.asarray(self.centre_photo).ravel())
        if self.centre_group is None:
            self.centre_group = np.zeros(h, dtype=np.int64)
        if self.centre_time is None:
            self.centre_time = np.zeros(h)
        self.centre_time = np.asarray(self.centre_time, dtype=float).ravel()
        for name in ("obs_photo", "obs_point", "ground_point", "centre_photo", "centre_group",
                     "attitude_photo"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=np.int64).ravel())
        for name in ("obs_xy", "obs_sigma"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float).reshape(-1, 2))
        self.lever_arm = np.asarray(self.lever_arm, dtype=float).reshape(3)
        for name in ("ground_xyz", "ground_sigma", "centre_xyz", "centre_sigma", "attitude_obs",
                     "attitude_sigma"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float).reshape(-1, 3))

    @property
    def n_photos(self) -> int:
        return len(self.photo_ids)

    @property
    def n_points(self) -> int:
        return len(self.point_ids)

    @property
    def n_groups(self) -> int:
        """GNSS strips (groups of shift/drift unknowns)."""
        return int(self.centre_group.max()) + 1 if len(self.centre_group) else 0

    def calibration_label(self, camera: int, parameter: int) -> str:
        names = BROWN_NAMES if self.camera_kind[camera] != KIND_FILM else CALIBRATION_NAMES
        return f"camera {self.camera_names[camera]!r} {names[parameter]}"

    def observation_cameras(self, rows: np.ndarray | None = None
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Camera index, camera kind and aspect of the image observations ``rows`` (all)."""
        ph = self.obs_photo if rows is None else self.obs_photo[rows]
        cam = self.photo_camera[ph]
        return cam, self.camera_kind[cam], self.camera_aspect[cam]

    def model_arguments(self, cam: np.ndarray) -> dict:
        """The ``cameras``/``models`` keywords of
        :func:`~toolbox.triangulation.model.observation_residuals`."""
        return {"cameras": cam, "models": self.camera_models}


@dataclass
class Options:
    """How to adjust: iterations, convergence, robust stage, data snooping."""

    max_iterations: int = 50
    tolerance: float = 1e-10  # relative decrease of the weighted sum of squares
    robust: bool = False  # Huber reweighting before the least squares and the snooping
    huber_k: float = 2.0  # Huber threshold, in standardised residuals
    snooping: bool = True
    critical_w: float = 3.29  # |w| above which an observation is rejected (alpha0 = 0.1 %)
    max_rejections: int = 20
    precision: bool = True  # cofactors and redundancy numbers (dense reduced inverse)


@dataclass
class Rejection:
    """One observation removed by data snooping."""

    kind: str  # "image", "ground", "centre" or "attitude"
    index: int  # into obs_*, ground_*, centre_* or attitude_*
    component: int  # image: 0 x / 1 y; ground/centre: 0 X, 1 Y, 2 Z; attitude: ω, φ, κ
    w: float
    redundancy: float
    residual: float  # computed minus observed, mm (image; px for a Brown camera), m or rad


@dataclass
class Solution:
    """An adjusted block (global coordinates; angles rad; residuals computed minus observed).

    exterior (n, 6); points (P, 3); calibration (k, 8); sigma0 (a posteriori, unitless: 1 when
    the a priori sigmas are right); redundancy (observations - unknowns); residuals of every
    observation used or rejected (image mm, ground m, centre m); w-tests and redundancy numbers
    where computed (NaN otherwise); standard deviations of exterior (n, 6), points (P, 3),
    calibration (k, 8) (NaN for fixed parameters) and the point covariances (P, 3, 3).
    """

    exterior: np.ndarray
    points: np.ndarray
    calibration: np.ndarray
    sigma0: float
    redundancy: int
    iterations: int
    image_residuals: np.ndarray
    ground_residuals: np.ndarray
    centre_residuals: np.ndarray
    obs_active: np.ndarray
    ground_active: np.ndarray
    centre_active: np.ndarray
    image_w: np.ndarray
    image_r: np.ndarray
    ground_w: np.ndarray
    ground_r: np.ndarray
    exterior_std: np.ndarray
    point_std: np.ndarray
    point_cov: np.ndarray
    calibration_std: np.ndarray
    rejections: list[Rejection] = field(default_factory=list)
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    notes: list[str] = field(default_factory=list)
    gnss_shift: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (G, 3) m
    gnss_drift: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (G, 3) m/unit
    boresight: np.ndarray = field(default_factory=lambda: np.zeros(3))  # rad
    gnss_shift_std: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gnss_drift_std: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    boresight_std: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    attitude_residuals: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # rad
    attitude_active: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=bool))
    attitude_w: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # w-tests
