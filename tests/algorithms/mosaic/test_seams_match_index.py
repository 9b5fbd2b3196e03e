"""Seamlines are exactly the boundaries between different sources in the mosaic's source index
(issue 30): the kernel on a hand-made label array, a zero-area sliver gives no seam, and on a
three-ortho least-cost block the seams of mosaic:seamlines and of mosaic:build, rasterised,
match the source-index edges within one cell both ways, with the right method."""

from __future__ import annotations

import geopandas as gpd
import mosaic_scene
import numpy as np
import pytest
import rasterio
import shapely
from affine import Affine
from rasterio.features import rasterize
from scipy import ndimage

import toolbox
from toolbox.demo.samples.mosaic import ORIGIN, make_block
from toolbox.mosaic import index_seams
from toolbox.mosaic.index_seams import label_edges, seam_lines


def test_label_edges_of_a_hand_made_array():
    labels = np.array([[0, 0, 1],
                       [0, 2, 1],
                       [-1, 2, 2]])
    edges = label_edges(labels, Affine(1, 0, 0, 0, -1, 3))
    got = {k: sorted(map(tuple, v.tolist())) for k, v in edges.items()}
    assert got == {(0, 1): [(2, 3, 2, 2)],
                   (0, 2): [(1, 2, 1, 1), (1, 2, 2, 2)],
                   (1, 2): [(2, 1, 3, 1), (2, 2, 2, 1)]}
    lines = {(i, j): line for i, j, line in seam_lines(edges)}
    assert lines[(0, 2)].equals(shapely.MultiLineString([[(1, 1), (1, 2), (2, 2)]]))
    assert lines[(1, 2)].length == 2 and lines[(0, 1)].length == 1


def test_strips_give_the_same_seams(tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    labels = ndimage.zoom(rng.integers(0, 4, (6, 5)), 7, order=0).astype("uint8")  # 42 x 35
    path = tmp_path / "index.tif"
    with rasterio.open(path, "w", driver="GTiff", width=35, height=42, count=1, dtype="uint8",
                       transform=Affine(2, 0, 100, 0, -2, 500)) as dst:
        dst.write(labels, 1)
    whole, _ = index_seams.index_raster_seams(path)
    monkeypatch.setattr(index_seams, "STRIP_ROWS", 16)  # 42 rows in strips of 16, 16 and 10
    assert list(index_seams.strips(42, 35)) == [(0, 16), (16, 16), (32, 10)]
    strips, _ = index_seams.index_raster_seams(path)
    assert [(i, j) for i, j, _ in whole] == [(i, j) for i, j, _ in strips]
    for (_, _, a), (_, _, b) in zip(whole, strips, strict=True):
        assert a.symmetric_difference(b).length < 1e-9 and a.length == pytest.approx(b.length)


def test_a_zero_area_sliver_gives_no_seam(tmp_path_factory):
    from toolbox.mosaic.block import mosaic_grid, open_block
    from toolbox.mosaic.build import MosaicPlan
    from toolbox.mosaic.partition import seamlines

    orthos, _ = mosaic_scene.standard_pair(tmp_path_factory)
    sources, crs = open_block([o.path for o in orthos])
    ox, oy = ORIGIN
    area = shapely.union_all([s.footprint for s in sources])
    left = area.intersection(shapely.box(ox - 10, oy - 10, ox + 500, oy + 410))
    right = area.difference(left)
    sliver = shapely.box(ox + 450, oy + 100, ox + 450 + 1e-7, oy + 300)  # 200 m long, no area
    cells = [left.difference(sliver), shapely.union_all([right, sliver])]
    assert sum(g.length for _, _, g in seamlines(cells)) > 790  # the old rule: a 400 m extra
    grid = mosaic_grid(sources, crs, None, area)
    plan = MosaicPlan(sources, cells, grid, 3, "uint8")
    (i, j, seam), = index_seams.partition_seams(plan)
    assert (i, j) == (0, 1)
    # x = 500 m local down to y = 10 m, where ortho_b's data starts; below it ortho_a fills the
    # cells up to x = 600 m (its data's end), so the seam turns along y = 10 m
    truth = shapely.LineString([(ox + 500, oy + 400), (ox + 500, oy + 10), (ox + 600, oy + 10)])
    assert seam.length == pytest.approx(truth.length)
    assert seam.hausdorff_distance(truth) <= grid.cell_size[0]


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """Three orthos meeting at a junction (2 m cells), a least-cost partition and the mosaic."""
    folder = tmp_path_factory.mktemp("three")
    specs = [{"name": "north_west", "bounds": (0, 0, 300, 300), "nadir": (150, 150)},
             {"name": "east", "bounds": (200, 0, 500, 300), "valid": (200, 0, 500, 290),
              "nadir": (350, 150)},
             {"name": "south", "bounds": (100, -200, 400, 100), "nadir": (250, -50)}]
    orthos, _ = make_block(folder, specs, building=(250.0, 150.0, 15.0), cell=2.0)
    inputs = [str(o.path) for o in orthos]
    seams = toolbox.run("mosaic:seamlines", {"INPUT": inputs, "METHOD": "least_cost",
                                             "OUTPUT": folder / "seams.gpkg"})
    built = toolbox.run("mosaic:build", {"INPUT": inputs, "CUTLINES": folder / "seams.gpkg",
                                         "BLEND": "none", "OUTPUT": folder / "mosaic.tif",
                                         "SOURCE_INDEX": folder / "index.tif",
                                         "SEAMLINES": folder / "mosaic_seams.gpkg"})
    return folder, seams, built


def pair_edges(index: np.ndarray, a: int, b: int) -> np.ndarray:
    """Cells with source ``a`` next to a cell with source ``b`` or the other way (1-based)."""
    out = np.zeros(index.shape, bool)
    for (p, q) in ((a, b), (b, a)):
        h = (index[:, :-1] == p) & (index[:, 1:] == q)
        v = (index[:-1] == p) & (index[1:] == q)
        out[:, :-1] |= h
        out[:, 1:] |= h
        out[:-1] |= v
        out[1:] |= v
    return out


def assert_seams_match_index(index_path, frame, ids):
    """Every source-index edge cell of a pair within one cell of its seam, and vice versa; every
    pair with edges has a seam and no other pair has one."""
    with rasterio.open(index_path) as src:
        index, transform = src.read(1), src.transform
    n = len(ids)
    pairs = {tuple(sorted((ids[a], ids[b]))) for a, b in zip(frame["a"], frame["b"], strict=True)}
    present = {(a, b) for a in range(1, n + 1) for b in range(a + 1, n + 1)
               if pair_edges(index, a, b).any()}
    assert pairs == present
    near = np.ones((3, 3), bool)
    for a, b, geom in zip(frame["a"], frame["b"], frame.geometry, strict=True):
        edge = pair_edges(index, ids[a], ids[b])
        seam = rasterize([geom], out_shape=index.shape, transform=transform,
                         all_touched=True, dtype="uint8") > 0
        assert (edge & ~ndimage.binary_dilation(seam, near)).sum() == 0, (a, b)
        assert (seam & ~ndimage.binary_dilation(edge, near)).sum() == 0, (a, b)
    return pairs


@pytest.mark.parametrize("layer_file", ["seams.gpkg", "mosaic_seams.gpkg"])
def test_seams_are_the_source_index_edges(block, layer_file):
    folder, _, _ = block
    frame = gpd.read_file(folder / layer_file, layer="seamlines")
    pairs = assert_seams_match_index(folder / "index.tif", frame,
                                     {"north_west": 1, "east": 2, "south": 3})
    assert pairs == {(1, 2), (1, 3), (2, 3)}  # every seam of the mosaic, no other


def test_edited_cut_polygons_seam_where_the_mosaic_changes_source(tmp_path_factory, tmp_path):
    """A cut polygon edited past its ortho's data (ortho_a ends at x = 600 m local, its polygon
    at 700 m): the mosaic fills 600-700 m from ortho_b, so the seam is at 600 m, not on the
    polygons' shared boundary at 700 m."""
    from toolbox.mosaic.partition import seamlines

    orthos, _ = mosaic_scene.standard_pair(tmp_path_factory)
    ox, oy = ORIGIN
    a = shapely.box(ox, oy, ox + 700, oy + 400)
    b = shapely.box(ox + 700, oy, ox + 1000, oy + 400)
    gpd.GeoDataFrame({"source": ["ortho_a", "ortho_b"]}, geometry=[a, b],
                     crs="EPSG:3003").to_file(tmp_path / "cut.gpkg")
    toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos],
                                 "CUTLINES": tmp_path / "cut.gpkg", "BLEND": "none",
                                 "OUTPUT": tmp_path / "m.tif", "SOURCE_INDEX": tmp_path / "i.tif",
                                 "SEAMLINES": tmp_path / "s.gpkg"})
    frame = gpd.read_file(tmp_path / "s.gpkg", layer="seamlines")
    assert assert_seams_match_index(tmp_path / "i.tif", frame,
                                    {"ortho_a": 1, "ortho_b": 2}) == {(1, 2)}
    assert frame["method"].tolist() == ["cut polygons"]
    x = shapely.get_coordinates(frame.geometry[0])[:, 0] - ox
    assert set(np.round(x, 6)) <= {600.0, 400.0} and 600.0 in set(np.round(x, 6))
    (_, _, old), = seamlines([a, b])  # the polygons' boundary: 100 m away from the mosaic's seam
    assert old.distance(frame.geometry[0]) == pytest.approx(100.0)


def test_seam_method_follows_the_run(block):
    folder, seams, _ = block
    report = {tuple(sorted((e["a"], e["b"]))): e["method"]
              for e in seams["STATISTICS"]["seams"]}
    assert set(report.values()) == {"least_cost"}
    for name in ("seams.gpkg", "mosaic_seams.gpkg"):
        frame = gpd.read_file(folder / name, layer="seamlines")
        got = {tuple(sorted((a, b))): m
               for a, b, m in zip(frame["a"], frame["b"], frame["method"], strict=True)}
        assert got == report, name
    cut = gpd.read_file(folder / "seams.gpkg", layer="cut_polygons")
    assert sorted(cut["path"]) == ["east.tif", "north_west.tif", "south.tif"]  # beside it
