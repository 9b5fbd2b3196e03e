"""dem:match on a stereo pair rendered through the collinearity equations (tilted photos, radial
distortion) over a textured hilly surface with a building and trees: completeness on textured
ground, median error against the rendered surface, the roof and the tree crowns present, and no
value outside the stereo coverage."""

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


#: trees: crowns 16 m wide and 12 m high (half ellipsoids) in two rows across the coverage
TREES = np.array([(sc.X0 + 380.0 + 60.0 * i, sc.Y0 + y) for i in range(5) for y in (320.0, 680.0)])
CROWN, TREE_HEIGHT = 8.0, 12.0


def trees(x, y):
    d2 = (x[..., None] - TREES[:, 0]) ** 2 + (y[..., None] - TREES[:, 1]) ** 2
    return TREE_HEIGHT * np.sqrt(np.clip(1.0 - d2 / CROWN ** 2, 0.0, None)).max(axis=-1)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("match")
    z, transform = hills_dem((sc.X0 - 300, sc.Y0 - 100, sc.X0 + 1300, sc.Y0 + 1100), cell=2.0,
                             relief=40.0, base=300.0, seed=5)
    rows, cols = np.indices(z.shape)
    x, y = transform.c + (cols + 0.5) * 2.0, transform.f - (rows + 0.5) * 2.0
    x0, y0, x1, y1, h = BUILDING
    roof = (x > x0) & (x < x1) & (y > y0) & (y < y1)
    z = z + np.where(roof, h, 0.0).astype("float32") + trees(x, y).astype("float32")
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
    d_tree = np.sqrt(((x[..., None] - TREES[:, 0]) ** 2
                      + (y[..., None] - TREES[:, 1]) ** 2).min(axis=-1))
    open_ground = covered & ~near_building & (d_tree > 16)
    valid = ~dsm.mask
    completeness = valid[open_ground].mean()
    error = np.abs(dsm.data - truth)[open_ground & valid]
    assert completeness >= 0.90, completeness
    assert np.median(error) <= 0.5 * GSD * H_OVER_B, (np.median(error), 0.5 * GSD * H_OVER_B)
    assert not valid[outside].any()  # nothing outside the stereo coverage
    roof = (x > x0 + 8) & (x < x1 - 8) & (y > y0 + 8) & (y < y1 - 8) & valid
    assert roof.sum() > 0.8 * ((x1 - x0 - 16) * (y1 - y0 - 16)) / CELL ** 2
    assert np.median(np.abs(dsm.data - truth)[roof]) < 1.5  # the roof is there, 15 m up
    # the trees are there: their crowns (11-12 m up within 3 m of the top) stand out, lowered
    # by the matching at this GSD (1.8 m: a crown is 9 px wide, 4 px of parallax; the 5 px
    # window and SGBM's smoothness penalty flatten it): measured 6.2 m up
    crowns = (d_tree < 3.0) & valid
    assert crowns.sum() >= len(TREES) and valid[d_tree < 3.0].mean() >= 0.9
    assert np.median((dsm.data - (truth - trees(x, y)))[crowns]) > 0.4 * TREE_HEIGHT
    assert set(np.unique(count[valid])) == {1} and (count[~valid] == 0).all()
    las = laspy.read(tmp_path / "points.laz")
    assert len(las.points) == res["STATISTICS"]["points_written"] > 0.8 * valid.sum()
    assert las.header.parse_crs().to_epsg() == 3003
    # colour from the photo: each point's RGB (16 bit) is the left photo's value where the
    # point projects (collinearity, the photo read here), to resampling and matching noise
    rgb = np.column_stack([np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)])
    assert rgb.std() > 1000 and (rgb % 257 == 0).all()
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])[::50]
    with rasterio.open(scene.folder / "L.tif") as ds:
        photo = ds.read().astype(float)
    px = np.floor(scene.photos["L"].ground_to_pixel(xyz)).astype(int)
    inside = ((px >= 0) & (px < sc.SIZE)).all(axis=1)
    seen = photo.mean(axis=0)[px[inside, 1], px[inside, 0]]
    assert np.median(np.abs(rgb[::50][inside].mean(axis=1) / 257 - seen)) < 8.0


def test_match_bad_input_exit_2(scene, tmp_path):
    base = ["run", "dem:match", "--PROJECT", str(scene.project), "--CELL_SIZE", "4",
            "--OUTPUT", str(tmp_path / "d.tif"), "--COUNT", str(tmp_path / "c.tif"),
            "--SPREAD", str(tmp_path / "s.tif"), "--POINTS", str(tmp_path / "p.laz")]
    cases = [(["--PHOTOS", "L,far", "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370"],
              "no suitable stereo pair"),
             (["--PHOTOS", "L,R", "--MIN_HEIGHT", "-2000", "--MAX_HEIGHT", "900"],
              "more than MAX_DISPARITIES"),
             (["--PHOTOS", "L,R", "--MIN_HEIGHT", "380", "--MAX_HEIGHT", "370"],
              "MAX_HEIGHT must be above MIN_HEIGHT"),
             # ranges that miss the terrain (300-355 m, roofs and crowns to 370 m): a coarse
             # match over a wider range finds it outside (without the check: a DSM of garbage)
             (["--PHOTOS", "L,R", "--MIN_HEIGHT", "400", "--MAX_HEIGHT", "470"],
              "100 % of the terrain outside MIN_HEIGHT 400 .. MAX_HEIGHT 470"),
             (["--PHOTOS", "L,R", "--MIN_HEIGHT", "200", "--MAX_HEIGHT", "290"],
              "100 % of the terrain outside MIN_HEIGHT 200 .. MAX_HEIGHT 290"),
             (["--PHOTOS", "L,unoriented", "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370"],
              "has no exterior orientation")]
    for args, text in cases:
        assert_refused(base + args, text,
                       tuple(tmp_path / n for n in ("d.tif", "c.tif", "s.tif", "p.laz")))


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


def test_a_pair_beyond_max_disparities_is_skipped_not_the_run(scene, tmp_path):
    """One pair needing more than MAX_DISPARITIES stopped the whole run (exit 2) while other
    unusable pairs are skipped: L-R spans 64 disparities (base 420 m), L-M and R-M 32 (half the
    base), so MAX_DISPARITIES 48 skips L-R with a warning and fuses the two others. With NODATA
    0 the SPREAD keeps its own nodata (-1): a spread of 0 is a value, not a hole."""
    import json

    from tests.helpers_cli import cli

    out = tmp_path / "stats.json"
    code, stdout, err = cli(
        "run", "dem:match", "--PROJECT", str(scene.project), "--PHOTOS", "L,R,M",
        "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370", "--CELL_SIZE", "4",
        "--MAX_DISPARITIES", "48", "--NODATA", "0", "--OUTPUT", str(tmp_path / "d.tif"),
        "--COUNT", str(tmp_path / "c.tif"), "--SPREAD", str(tmp_path / "s.tif"),
        "--run-report", str(out))
    assert code == 0, err
    assert ("pair skipped: L-R: MIN_HEIGHT 280 .. MAX_HEIGHT 370 spans 64 disparities, more "
            "than MAX_DISPARITIES 48") in err
    stats = json.loads(out.read_text())["outputs"]["STATISTICS"]
    assert sorted(p["pair"] for p in stats["pairs"]) == ["L-M", "R-M"]
    assert all(p["num_disparities"] <= 48 for p in stats["pairs"])
    assert any(line.startswith("L-R: ") for line in stats["skipped"])
    with rasterio.open(tmp_path / "d.tif") as ds:
        dsm = ds.read(1, masked=True)
    with rasterio.open(tmp_path / "s.tif") as ds:
        assert ds.nodata == -1.0
        spread = ds.read(1, masked=True)
    assert np.array_equal(spread.mask, dsm.mask) and (spread.data[~spread.mask] >= 0).all()
    # every pair beyond it: refused, naming MAX_DISPARITIES
    assert_refused(["run", "dem:match", "--PROJECT", str(scene.project), "--PHOTOS", "L,R,M",
                    "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370", "--CELL_SIZE", "4",
                    "--MAX_DISPARITIES", "16", "--OUTPUT", str(tmp_path / "e.tif"),
                    "--COUNT", str(tmp_path / "f.tif"), "--SPREAD", str(tmp_path / "g.tif")],
                   "no stereo pair fits MAX_DISPARITIES 16", (tmp_path / "e.tif",))
