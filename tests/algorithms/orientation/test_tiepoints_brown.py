"""orientation:tiepoints on a rendered 3 x 2 block taken through a Brown camera model (strong
radial and tangential distortion: tens of pixels at the corners).

Rendering and truth go through OpenCV, not the toolbox's camera code: every pixel centre is
undistorted by ``cv2.undistortPoints`` and its ray marched to the DEM (as the ortho tests'
camera-model renderer does); each tie point is intersected from its observations undistorted by
OpenCV with the TRUE orientations and projected back with ``cv2.projectPoints``.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

import toolbox

sys.path.insert(0, str(Path(__file__).parents[2] / "toolbox" / "matching"))
import block_scene  # noqa: E402

BROWN = {"type": "brown", "im_size": [640, 480], "focal_len": 0.75, "cx": 0.012, "cy": -0.008,
         "k1": -0.21, "k2": 0.09, "k3": -0.012, "p1": 0.0012, "p2": -0.0007}
BASE, GAP = 800.0, 700.0  # m: footprints of about 1870 x 1400 m: ~57 % forward, 50 % side
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)


def orientations() -> dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]:
    rng = np.random.default_rng(21)
    out = {}
    for s in range(2):
        for i in range(3):
            x = block_scene.X0 + (i if s == 0 else 2 - i) * BASE
            kappa = (0.0 if s == 0 else np.pi) + rng.uniform(-0.03, 0.03)
            out[f"b{s + 1}_{i + 1}"] = ((x, block_scene.Y0 + s * GAP, block_scene.HEIGHT),
                                        (rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02),
                                         kappa))
    return out


def undistort(model, px: np.ndarray) -> np.ndarray:
    """Toolbox pixels (centres at +0.5) -> normalised camera coordinates, y up (OpenCV)."""
    xn = cv2.undistortPoints((px - 0.5).reshape(-1, 1, 2), model.matrix(),
                             model.opencv_coefficients(), criteria=CRITERIA)
    return xn.reshape(-1, 2) * [1.0, -1.0]


@pytest.fixture(scope="module")
def brown_block(tmp_path_factory):
    from toolbox.cameras import create_intrinsics
    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.photo import Photo
    from toolbox.photogrammetry.surface import DemSurface
    from toolbox.photogrammetry.synthetic import hills_dem, write_photo

    folder = tmp_path_factory.mktemp("brown_block")
    model = create_intrinsics(BROWN)
    z, transform = hills_dem(block_scene.BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=4)
    surface = DemSurface.from_transform(z.astype("float64"), transform)
    w, h = model.image_size_px
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    xn = undistort(model, np.column_stack([cols.ravel(), rows.ravel()]))
    truth = {}
    for pid, (centre, angles) in orientations().items():
        eo = ExteriorOrientation.from_angles(pid, *centre, *angles, crs=block_scene.CRS)
        hit = Photo(pid, model, eo).monoplot_image(xn, surface)
        assert hit.ok.all()
        value = block_scene.texture(hit.xyz[:, 0], hit.xyz[:, 1])
        write_photo(folder / f"{pid}.tif",
                    np.clip(np.rint(value), 0, 255).astype("uint8").reshape(h, w))
        truth[pid] = eo
    doc = {"crs": block_scene.CRS, "angle_unit": "rad",
           "cameras": [{"name": "lens", "model": BROWN}],
           "photos": [{"id": pid, "camera": "lens", "image": f"{pid}.tif",
                       "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                            [*c, *a], strict=True))}
                      for pid, (c, a) in orientations().items()]}
    (folder / "block.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return folder, model, truth


def test_brown_block_tie_points_match_the_truth(brown_block, tmp_path):
    from toolbox.photogrammetry.forward_intersection import intersect

    folder, model, truth = brown_block
    out = toolbox.run("orientation:tiepoints", {
        "PROJECT": folder / "block.yaml", "TERRAIN_HEIGHT": 350.0, "TARGET": 32,
        "OUTPUT": tmp_path / "tie.csv", "PAIRS": tmp_path / "pairs.csv"})
    stats = out["STATISTICS"]
    assert stats["untied_photos"] == [] and stats["pairs_tied"] == stats["pairs_candidate"]
    with open(tmp_path / "pairs.csv", newline="") as f:
        pairs = list(csv.DictReader(f))
    assert len(pairs) >= 11 and all(int(p["kept"]) >= 10 for p in pairs)
    with open(tmp_path / "tie.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    ids = list(dict.fromkeys(r["point_id"] for r in rows))
    index = {pid: k for k, pid in enumerate(ids)}
    point = np.array([index[r["point_id"]] for r in rows])
    obs = np.array([[float(r["col_px"]), float(r["row_px"])] for r in rows])
    normal = np.vstack([undistort(model, o[None]) for o in obs])
    eos = [truth[r["photo"]] for r in rows]
    res = intersect(point, normal, np.array([e.centre for e in eos]),
                    np.array([e.rotation for e in eos]), np.ones(len(rows)), len(ids))
    assert len(ids) > 120 and res.ok.all()
    back = np.zeros_like(obs)
    for m, e in enumerate(eos):
        v = e.rotation.T @ (res.xyz[point[m]] - e.centre)  # camera frame, looking along -z
        cam = np.array([[v[0] / -v[2], -v[1] / -v[2], 1.0]])  # OpenCV's frame: y down, z ahead
        px, _ = cv2.projectPoints(cam, np.zeros(3), np.zeros(3), model.matrix(),
                                  model.opencv_coefficients())
        back[m] = px.ravel() + 0.5
    err = np.hypot(*(back - obs).T)
    assert np.mean(err <= 0.5) >= 0.99, np.percentile(err, [50, 99, 100])
    # the corners, where the distortion is largest, are measured too
    r = np.hypot(*(obs - [320.0, 240.0]).T)
    assert (r > 250).sum() >= 20
