"""dem:match on a stereo pair rendered through the collinearity equations (tilted photos, radial
distortion) over a textured hilly surface with a building: completeness on textured ground,
median error against the rendered surface, the roof present, and no value outside the stereo
coverage."""

from __future__ import annotations

import sys
from pathlib import Path

import laspy
import numpy as np
import pytest
import rasterio
from scipy import ndimage

import toolbox
from tests.helpers_cli import assert_refused
from toolbox.photogrammetry.synthetic import hills_dem, wave_texture

sys.path.insert(0, str(Path(__file__).parents[1] / "stereo"))
import stereo_scene as sc  # noqa: E402

BUILDING = (sc.X0 + 450.0, sc.Y0 + 450.0, sc.X0 + 530.0, sc.Y0 + 520.0, 15.0)
CELL = 4.0
GSD = 230.0 / sc.SIZE * 705.0 / sc.C_MM  # m: pixel (mm) x distance (m) / c (mm)
H_OVER_B = 705.0 / 420.0


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("match")
    z, transform = hills_dem((sc.X0 - 300, sc.Y0 - 100, sc.X0 + 1300, sc.Y0 + 1100), cell=2.0,
                             relief=40.0, base=300.0, seed=5)
    rows, cols = np.indices(z.shape)
    x, y = transform.c + (cols + 0.5) * 2.0, transform.f - (rows + 0.5) * 2.0
    x0, y0, x1, y1, h = BUILDING
    roof = (x > x0) & (x < x1) & (y > y0) & (y < y1)
    z = z + np.where(roof, h, 0.0).astype("float32")
    texture = wave_texture(seed=2, wavelength=(8.0, 40.0), waves=40)
    return sc.make_pair(folder, z, transform, texture, names=("L", "R", "M"))


def surface_at(pair, x, y):
    t = pair.transform
    return ndimage.map_coordinates(pair.surface.astype("float64"),
                                   [(y - t.f) / t.e - 0.5, (x - t.c) / t.a - 0.5], order=1)


def run_match(pair, out: Path, **extra):
    params = {"PROJECT": str(pair.project), "PHOTOS": "L,R", "MIN_HEIGHT": 280.0,
              "MAX_HEIGHT": 370.0, "CELL_SIZE": CELL, "OUTPUT": str(out / "dsm.tif"),
              "COUNT": str(out / "count.tif"), "SPREAD": str(out / "spread.tif"), **extra}
    return toolbox.run("dem:match", params)


def test_dsm_of_a_rendered_pair(scene, tmp_path):
    res = run_match(scene, tmp_path, POINTS=str(tmp_path / "points.laz"))
    with rasterio.open(tmp_path / "dsm.tif") as ds:
        dsm = ds.read(1, masked=True)
        t = ds.transform
        assert ds.crs.to_epsg() == 3003
    with rasterio.open(tmp_path / "count.tif") as ds:
        count = ds.read(1)
    rows, cols = np.indices(dsm.shape)
    x, y = t.c + (cols + 0.5) * t.a, t.f + (rows + 0.5) * t.e
    truth = surface_at(scene, x.ravel(), y.ravel()).reshape(x.shape)
    # stereo coverage: the cell's surface point inside both photos (margin in pixels)
    ground = np.column_stack([x.ravel(), y.ravel(), truth.ravel()])

    def inside(margin):
        ok = np.ones(len(ground), bool)
        for name in ("L", "R"):
            px = scene.photos[name].ground_to_pixel(ground)
            ok &= (px >= margin).all(axis=1) & (px <= sc.SIZE - margin).all(axis=1)
        return ok.reshape(x.shape)

    covered, outside = inside(8), ~inside(-3)
    x0, y0, x1, y1, _ = BUILDING
    near_building = (x > x0 - 25) & (x < x1 + 25) & (y > y0 - 25) & (y < y1 + 25)
    open_ground = covered & ~near_building
    valid = ~dsm.mask
    completeness = valid[open_ground].mean()
    error = np.abs(dsm.data - truth)[open_ground & valid]
    assert completeness >= 0.90, completeness
    assert np.median(error) <= 0.5 * GSD * H_OVER_B, (np.median(error), 0.5 * GSD * H_OVER_B)
    assert not valid[outside].any()  # nothing outside the stereo coverage
    roof = (x > x0 + 8) & (x < x1 - 8) & (y > y0 + 8) & (y < y1 - 8) & valid
    assert roof.sum() > 0.8 * ((x1 - x0 - 16) * (y1 - y0 - 16)) / CELL ** 2
    assert np.median(np.abs(dsm.data - truth)[roof]) < 1.5  # the roof is there, 15 m up
    assert set(np.unique(count[valid])) == {1} and (count[~valid] == 0).all()
    las = laspy.read(tmp_path / "points.laz")
    assert len(las.points) == res["STATISTICS"]["points_written"] > 0.8 * valid.sum()
    assert las.header.parse_crs().to_epsg() == 3003


def test_match_bad_input_exit_2(scene, tmp_path):
    base = ["run", "dem:match", "--PROJECT", str(scene.project), "--CELL_SIZE", "4",
            "--OUTPUT", str(tmp_path / "d.tif"), "--COUNT", str(tmp_path / "c.tif"),
            "--SPREAD", str(tmp_path / "s.tif")]
    cases = [(["--PHOTOS", "L,far", "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370"],
              "no suitable stereo pair"),
             (["--PHOTOS", "L,R", "--MIN_HEIGHT", "-2000", "--MAX_HEIGHT", "900"],
              "more than MAX_DISPARITIES"),
             (["--PHOTOS", "L,R", "--MIN_HEIGHT", "380", "--MAX_HEIGHT", "370"],
              "MAX_HEIGHT must be above MIN_HEIGHT"),
             (["--PHOTOS", "L,unoriented", "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370"],
              "has no exterior orientation")]
    for args, text in cases:
        assert_refused(base + args, text, tuple(tmp_path / n for n in ("d.tif", "c.tif", "s.tif")))


def test_three_photos_three_pairs_fused(scene, tmp_path):
    res = run_match(scene, tmp_path, PHOTOS="L,R,M")
    assert sorted(p["pair"] for p in res["STATISTICS"]["pairs"]) == ["L-M", "L-R", "R-M"]
    with rasterio.open(tmp_path / "dsm.tif") as ds:
        dsm = ds.read(1, masked=True)
        t = ds.transform
    with rasterio.open(tmp_path / "count.tif") as ds:
        count = ds.read(1)
    with rasterio.open(tmp_path / "spread.tif") as ds:
        spread = ds.read(1, masked=True)
    rows, cols = np.indices(dsm.shape)
    x, y = t.c + (cols + 0.5) * t.a, t.f + (rows + 0.5) * t.e
    truth = surface_at(scene, x.ravel(), y.ravel()).reshape(x.shape)
    x0, y0, x1, y1, _ = BUILDING
    open_ground = ~dsm.mask & ~((x > x0 - 25) & (x < x1 + 25) & (y > y0 - 25) & (y < y1 + 25))
    assert (count[~dsm.mask] >= 1).all() and (count == 3).sum() > 0.3 * (~dsm.mask).sum()
    assert np.array_equal(spread.mask, dsm.mask)
    three = open_ground & (count == 3)
    assert np.median(np.abs(dsm.data - truth)[three]) <= 0.5 * GSD * H_OVER_B
    assert np.median(spread.data[three]) < 2.0  # the pairs agree within their noise
