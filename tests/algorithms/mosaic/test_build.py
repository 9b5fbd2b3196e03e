"""mosaic:build: no gaps where any input has data, every cell away from the seam equals its
source cell (none, feather, multiband), feathering weights sum to 1 and ramp linearly across a
seam, block balancing removes a known gain/offset, inputs off the grid are resampled."""

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely

import toolbox
from toolbox.demo.samples.mosaic import make_block, pair_specs, texture
from toolbox.feedback import Feedback
from toolbox.mosaic.blend import feather_weights, multiband_blend


def read_mosaic(path):
    with rasterio.open(path) as src:
        return src.read(), src.transform, [c.name for c in src.colorinterp]


def source_values(ortho, transform, shape):
    """The ortho's own cells on the mosaic grid (the grids are aligned: integer offsets)."""
    with rasterio.open(ortho.path) as src:
        dc = round((transform.c - src.transform.c) / transform.a)
        dr = round((transform.f - src.transform.f) / transform.e)
        data = np.zeros((3, *shape), "uint8")
        valid = np.zeros(shape, bool)
        r0, c0 = max(0, -dr), max(0, -dc)
        r1, c1 = min(shape[0], src.height - dr), min(shape[1], src.width - dc)
        win = ((r0 + dr, r1 + dr), (c0 + dc, c1 + dc))
        data[:, r0:r1, c0:c1] = src.read([1, 2, 3], window=win)
        valid[r0:r1, c0:c1] = src.dataset_mask(window=win) > 0
    return data, valid


def distance_to(line, transform, shape):
    rows, cols = np.indices(shape)
    x, y = transform @ (cols + 0.5, rows + 0.5)
    return shapely.distance(line, shapely.points(x, y))


@pytest.fixture(scope="module")
def mosaics(pair, seams, tmp_path_factory):
    orthos, _ = pair
    folder = tmp_path_factory.mktemp("build")
    out = {}
    for blend, extra in (("none", {}), ("feather", {"FEATHER_WIDTH": 12}),
                         ("multiband", {"LEVELS": 3})):
        out[blend] = toolbox.run("mosaic:build", {
            "INPUT": [str(o.path) for o in orthos], "CUTLINES": str(seams["least_cost"]["OUTPUT"]),
            "BLEND": blend, **extra, "OUTPUT": str(folder / f"{blend}.tif"),
            "SOURCE_INDEX": str(folder / f"{blend}_index.tif"),
            "SEAMLINES": str(folder / f"{blend}_seams.gpkg")})
    return out


@pytest.mark.parametrize("blend,reach", [("none", 0.0), ("feather", 7.0), ("multiband", 34.0)])
def test_mosaic_has_no_gaps_and_equals_its_sources_away_from_the_seam(pair, mosaics, blend, reach):
    orthos, _ = pair
    result = mosaics[blend]
    data, transform, interp = read_mosaic(result["OUTPUT"])
    assert interp == ["red", "green", "blue", "alpha"]  # ortho_b has an alpha band
    shape = data.shape[1:]
    src = [source_values(o, transform, shape) for o in orthos]
    any_valid = src[0][1] | src[1][1]
    assert any_valid.sum() == 400 * 1000 - 10 * 400  # only the corner strip x > 600, y < 10 is empty
    assert np.array_equal(data[3] == 255, any_valid)  # no gap, nothing invented
    with rasterio.open(result["SOURCE_INDEX"]) as s:
        index = s.read(1)
    assert np.array_equal(index > 0, any_valid)
    seam = shapely.union_all(list(gpd.read_file(result["SEAMLINES"]).geometry))
    far = distance_to(seam, transform, shape) > reach + 1.0
    for k, (values, valid) in enumerate(src):
        mine = far & (index == k + 1)
        assert valid[mine].all()
        assert mine.sum() > 100_000
        assert np.array_equal(data[:3][:, mine], values[:, mine])


def test_feathering_weights_sum_to_one_and_ramp_linearly():
    rng = np.random.default_rng(1)
    labels = np.full((60, 80), -1, "int16")
    labels[:, :40] = 0
    labels[:, 40:] = 1
    labels[50:, :] = 2
    valid = np.ones((3, 60, 80), bool)
    valid[:, :, 75:] = rng.random((3, 60, 5)) > 0.5
    labels[:, 75:][~valid[1, :, 75:] & (labels[:, 75:] == 1)] = -1
    w = feather_weights(labels, valid, 10.0)
    total = w.sum(axis=0)
    some = valid.any(axis=0)
    assert np.allclose(total[some], 1.0, atol=1e-6)
    assert np.all(w[~valid] == 0)
    # along row 20 (seam between 0 and 1 at x = 40, between cell centres 39 and 40):
    # the weight of 1 is clip(0.5 + d / 10) with d the signed distance of the centre
    d = np.arange(80) + 0.5 - 40
    expected = np.clip(0.5 + d / 10, 0, 1)
    assert np.allclose(w[1, 20, :70], expected[:70], atol=1e-6)


def test_multiband_blend_of_identical_images_is_the_image():
    rng = np.random.default_rng(2)
    image = rng.uniform(0, 255, (2, 64, 96)).astype("float32")
    labels = np.zeros((64, 96), "int16")
    labels[:, 50:] = 1
    valid = np.ones((2, 64, 96), bool)
    out = multiband_blend([image, image.copy()], valid, labels, levels=4)
    assert np.abs(out - image).max() < 1e-3


def test_balancing_removes_a_known_gain_and_offset(tmp_path):
    gain, offset = 1.12, -9.0
    orthos, _ = make_block(tmp_path, pair_specs(gain, offset), building=(500.0, 200.0, 0.0))
    inputs = [str(o.path) for o in orthos]
    runs = {}
    for balance in (False, True):
        runs[balance] = toolbox.run("mosaic:build", {
            "INPUT": inputs, "BLEND": "none", "BALANCE": balance,
            "OUTPUT": str(tmp_path / f"m{balance}.tif")})
    g, o = np.array(runs[True]["STATISTICS"]["gains"]), np.array(runs[True]["STATISTICS"]["offsets"])
    # corrected images agree: g_a·T + o_a = g_b·(gain·T + offset) + o_b for every band
    assert np.allclose(g[0] / g[1], gain, rtol=3e-3)
    assert np.allclose(o[0], g[1] * offset + o[1], atol=0.3)
    assert np.allclose(g.mean(axis=0), 1.0) and np.allclose(o.mean(axis=0), 0.0, atol=1e-6)
    # the jump across the seam (x = 500 m local) is gone: both sides follow g_a·T + o_a
    for balance, limit in ((False, None), (True, 1.0)):
        data, t, _ = read_mosaic(runs[balance]["OUTPUT"])
        cols = np.arange(440, 560)
        rows = np.arange(20, 380)
        x = t.c + (cols + 0.5) * t.a - orthos[0].bounds[0] + 0.0
        y = t.f + (rows + 0.5) * t.e - orthos[0].bounds[1]
        gx, gy = np.meshgrid(x, y)
        truth = np.clip(np.rint(texture(gx, gy)), 1, 255)
        expected = g[0][:, None, None] * truth + o[0][:, None, None]
        error = np.abs(data[:3][:, rows][:, :, cols] - expected)
        if limit is None:
            assert error[:, :, 60:].mean() > 3  # unbalanced: the right side is off
        else:
            assert error.max() <= limit + 0.51


def test_inputs_on_another_grid_are_resampled_with_a_warning(pair, tmp_path):
    orthos, _ = pair
    coarse = tmp_path / "coarse_b.tif"
    with rasterio.open(orthos[1].path) as src:
        profile = src.profile | {"width": src.width // 2, "height": src.height // 2,
                                 "transform": src.transform @ src.transform.scale(2, 2)}
        data = src.read(out_shape=(src.count, src.height // 2, src.width // 2))
        tags = src.tags()
        with rasterio.open(coarse, "w", **profile) as dst:
            dst.write(data)
            dst.colorinterp = src.colorinterp
            dst.update_tags(**tags)
    feedback = Feedback()
    out = toolbox.run("mosaic:build", {"INPUT": [str(orthos[0].path), str(coarse)],
                                       "BLEND": "none", "OUTPUT": str(tmp_path / "m.tif")},
                      feedback=feedback)
    assert any("resampled" in w for w in feedback.warnings)
    cog = toolbox.run("mosaic:build", {"INPUT": [str(orthos[0].path), str(coarse)],
                                       "BLEND": "none", "COG": True,
                                       "OUTPUT": str(tmp_path / "cog.tif")})
    with rasterio.open(cog["OUTPUT"]) as src:
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        assert src.overviews(1) == [2] and src.block_shapes[0] == (512, 512)
        assert np.array_equal(src.read(), read_mosaic(out["OUTPUT"])[0])
    data, t, _ = read_mosaic(out["OUTPUT"])
    assert t.a == 1.0 and data.shape[1:] == (400, 1000)
    assert (data[3] == 255).sum() == 400 * 1000 - 10 * 400


def test_block_balancing_chains_through_images_that_do_not_overlap():
    # three images in a strip: A-B and B-C overlap, A and C do not; image k = g_k·T + o_k
    from toolbox.mosaic.balance import overlap_stats, solve_gain_offset

    rng = np.random.default_rng(5)
    truth = [(1.0, 0.0), (1.2, -10.0), (0.9, 12.0)]
    stats = []
    for a, b in ((0, 1), (1, 2)):
        t = rng.uniform(30, 200, (2, 40, 40))
        da, db = (truth[k][0] * t + truth[k][1] for k in (a, b))
        stats.append(overlap_stats(a, b, da, db, np.ones((40, 40), bool)))
    g, o = solve_gain_offset(stats, 3, 2)
    # corrected images agree everywhere: g_k·(G_k·T + O_k) + o_k is the same for every k
    corrected = [(g[k] * gk, g[k] * ok + o[k]) for k, (gk, ok) in enumerate(truth)]
    for gain, offset in corrected[1:]:
        assert np.allclose(gain, corrected[0][0], rtol=1e-6)
        assert np.allclose(offset, corrected[0][1], atol=1e-4)
    assert np.allclose(g.mean(axis=0), 1) and np.allclose(o.mean(axis=0), 0, atol=1e-6)
