"""Synthetic blocks with a known truth for the triangulation tests (imported by name: a second
``conftest`` module would shadow tests/conftest.py's helpers) (collinearity through the
toolbox's camera chain, Gaussian noise of known sigma)."""

from dataclasses import dataclass

import numpy as np

from toolbox.triangulation.approximations import by_resection
from toolbox.triangulation.inputs import BlockRequest, Control, Measurements, build_block
from toolbox.triangulation.synthetic import SyntheticBlockSpec, corner_control, make_block


@dataclass
class Case:
    synthetic: object
    block: object
    info: dict
    exterior0: np.ndarray
    points0: np.ndarray
    truth_exterior: np.ndarray
    truth_points: np.ndarray
    control: Control


def build_case(spec: SyntheticBlockSpec, n_control: int = 6, checks=(), project=None,
               xy=None, **request) -> Case:
    sb = make_block(spec)
    chosen = corner_control(sb, n_control + len(checks))
    ids = [sb.point_ids[i] for i in chosen]
    roles = ["check" if k >= n_control else "control" for k in range(len(chosen))]
    control = Control(ids, sb.points[chosen], roles)
    ms = Measurements(sb.obs_point, sb.obs_photo, sb.xy if xy is None else xy, sb.kind,
                      np.full(len(sb.xy), np.nan))
    options = {"sigma_mm": sb.sigma, "sigma_px": sb.sigma, "control_sigma_xy": 0.01,
               "control_sigma_z": 0.01} | request
    block, info = build_block(BlockRequest(project or sb.project, ms, control, **options))
    ext0, pts0, _ = by_resection(block)
    photos = [sb.project.photos[p] for p in block.photo_ids]
    truth_ext = np.array([[*p.exterior.centre, p.exterior.omega, p.exterior.phi, p.exterior.kappa]
                          for p in photos])
    index = {p: k for k, p in enumerate(sb.point_ids)}
    truth_pts = sb.points[[index[p] for p in block.point_ids]]
    return Case(sb, block, info, ext0, pts0, truth_ext, truth_pts, control)


def angle_diff(a, b):
    return (np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi
