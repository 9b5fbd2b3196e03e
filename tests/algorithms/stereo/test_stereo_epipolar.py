"""stereo:epipolar on a synthetic pair rendered through the collinearity equations (tilted
photos, radial distortion): bright Gaussian marks painted on the ground at known points are
measured (intensity centroids) in the two epipolar images: they must lie on the same row within
0.1 px, and their disparity must triangulate back to the ground point."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from scipy import ndimage

import toolbox
from tests.helpers_cli import assert_refused
from toolbox.photogrammetry.synthetic import hills_dem
from toolbox.stereo.epipolar import EpipolarGeometry

sys.path.insert(0, str(Path(__file__).parent))
import stereo_scene as sc  # noqa: E402

SIGMA = 4.0  # m, the marks' Gaussian radius (~2.2 px)
BACKGROUND = 40.0
MARKS = np.array([(sc.X0 + x, sc.Y0 + y) for x in range(260, 800, 100)
                  for y in range(100, 1000, 100)], dtype="float64")


def mark_texture(x, y):
    """Background plus a Gaussian at each mark; the marks lie on a 100 m lattice, so only the
    nearest one counts (the next is 12 sigma away)."""
    mx = sc.X0 + np.clip(np.rint((x - sc.X0 - 260) / 100), 0, 5) * 100 + 260
    my = sc.Y0 + np.clip(np.rint((y - sc.Y0 - 100) / 100), 0, 8) * 100 + 100
    return BACKGROUND + 180.0 * np.exp(-((x - mx) ** 2 + (y - my) ** 2) / (2 * SIGMA ** 2))


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("epipolar")
    z, transform = hills_dem((sc.X0 - 300, sc.Y0 - 100, sc.X0 + 1300, sc.Y0 + 1100), cell=5.0,
                             relief=60.0, base=300.0, seed=4)
    return sc.make_pair(folder, z, transform, mark_texture)


def mark_heights(pair):
    t = pair.transform
    rows = (MARKS[:, 1] - t.f) / t.e - 0.5
    cols = (MARKS[:, 0] - t.c) / t.a - 0.5
    z = ndimage.map_coordinates(pair.surface.astype("float64"), [rows, cols], order=1)
    return np.column_stack([MARKS, z])


def centroid(image, col, row, half=7):
    """Intensity centroid (pixel convention: centres at +0.5) near (col, row)."""
    c0, r0 = int(col), int(row)
    patch = image[r0 - half:r0 + half + 1, c0 - half:c0 + half + 1].astype("float64")
    w = np.clip(patch - BACKGROUND - 2.0, 0, None)
    rr, cc = np.mgrid[r0 - half:r0 + half + 1, c0 - half:c0 + half + 1]
    return (w * (cc + 0.5)).sum() / w.sum(), (w * (rr + 0.5)).sum() / w.sum()


def run_epipolar(pair, out: Path, **extra):
    params = {"PROJECT": str(pair.project), "LEFT": "L", "RIGHT": "R", "TERRAIN_HEIGHT": 320.0,
              "OUTPUT_LEFT": str(out / "left.tif"), "OUTPUT_RIGHT": str(out / "right.tif"),
              "TRANSFORM": str(out / "pair.json"), **extra}
    return toolbox.run("stereo:epipolar", params)


def test_homologous_points_on_one_row_and_back_to_ground(pair, tmp_path):
    res = run_epipolar(pair, tmp_path)
    geometry = EpipolarGeometry.read(tmp_path / "pair.json")
    assert json.loads((tmp_path / "pair.json").read_text())["base_length"] == \
        pytest.approx(np.linalg.norm(np.subtract(sc.CENTRES["R"], sc.CENTRES["L"])))
    with rasterio.open(tmp_path / "left.tif") as left, rasterio.open(tmp_path / "right.tif") as right:
        images = [left.read(1), right.read(1)]
        alpha = left.read(2)
        assert left.crs is None and left.transform == geometry.transform(0)
    truth = mark_heights(pair)
    measured = []
    for xyz in truth:
        where = [geometry.ground_to_pixels(xyz[None], side)[0] for side in (0, 1)]
        measured.append([centroid(images[side], *where[side]) for side in (0, 1)])
    measured = np.array(measured)  # (marks, side, col/row)
    rows_left, rows_right = measured[:, 0, 1], measured[:, 1, 1]
    assert np.abs(rows_left - rows_right).max() < 0.1  # rows are epipolar lines
    disparity = measured[:, 0, 0] - measured[:, 1, 0]
    xyz = geometry.triangulate(measured[:, 0, 0], rows_left, disparity)
    # sigma_Z of a 0.05 px centroid: (Z/B) x GSD x 0.05 ~ 0.15 m
    assert np.abs(xyz[:, 2] - truth[:, 2]).max() < 0.3  # measured: 0.05 m
    assert np.abs(xyz[:, :2] - truth[:, :2]).max() < 0.2  # measured: 0.04 m
    assert alpha.min() == 0 and alpha.max() == 255  # the photo edge is marked
    assert res["STATISTICS"]["overlap"] > 0.5


def test_scheduler_local_is_not_overridden_by_the_environment(pair, tmp_path, monkeypatch):
    """SCHEDULER local runs both images' windows on local threads: a DASK_SCHEDULER_ADDRESS
    naming no cluster (nothing listens on port 9) is not contacted, and the images equal a run
    without the variable (issue 31)."""
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    (tmp_path / "plain").mkdir()
    (tmp_path / "env").mkdir()
    run_epipolar(pair, tmp_path / "plain")
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")
    run_epipolar(pair, tmp_path / "env", SCHEDULER="local")
    for name in ("left.tif", "right.tif"):
        with rasterio.open(tmp_path / "plain" / name) as a, \
                rasterio.open(tmp_path / "env" / name) as b:
            first, second = a.read(), b.read()
        assert first[-1].max() == 255 and (first == second).all(), name  # alpha: not empty


def test_refused_pairs(pair, tmp_path):
    base = ["run", "stereo:epipolar", "--PROJECT", str(pair.project), "--TERRAIN_HEIGHT", "320",
            "--OUTPUT_LEFT", str(tmp_path / "l.tif"), "--OUTPUT_RIGHT", str(tmp_path / "r.tif"),
            "--TRANSFORM", str(tmp_path / "p.json")]
    cases = [(["--LEFT", "L", "--RIGHT", "far", "--RIGHT_IMAGE", str(pair.folder / "R.tif")],
              "overlap by 0.0 %"),
             (["--LEFT", "L", "--RIGHT", "R", "--SIGMA_Z", "0.01"], "too short for SIGMA_Z"),
             (["--LEFT", "L", "--RIGHT", "L"], "RIGHT must differ from LEFT"),
             (["--LEFT", "L", "--RIGHT", "unoriented"], "has no exterior orientation")]
    for args, text in cases:
        line = assert_refused(base + args, text,
                              tuple(tmp_path / n for n in ("l.tif", "r.tif", "p.json")))
        if "SIGMA_Z" in text:  # the stated precision is the normal case's (S002 eq. [37])
            import re

            b, z, sz, sp = map(float, re.search(
                r"B = (\S+) m at Z = (\S+) m .* sigma_Z = (\S+) m with sigma_p = (\S+) um",
                line).groups())
            assert b == pytest.approx(np.linalg.norm(np.subtract(sc.CENTRES["R"],
                                                                 sc.CENTRES["L"])), abs=0.1)
            assert 600 < z < 800  # the cameras ~1000 m, the terrain 320 m
            # (printed to 1 mm)
            assert sz == pytest.approx(z / b * z / sc.C_MM * sp / 1000.0, abs=6e-4)
            assert sz > 0.01
