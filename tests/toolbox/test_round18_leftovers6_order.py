"""Round 18, input order:

- mosaic:build's Voronoi cells took two orthos whose centres are 40 m apart in UTM for one
  centre (np.allclose's relative tolerance at northings ~5e6): one of them got their whole
  overlap, which one by input order, exit 0; now they split on the bisector;
- mosaic:build gave cells on a shared cut edge (and the fallback cells) to a source by input
  order, mosaic:seamlines' seams likewise: the same orthos in another order gave another
  mosaic; now file-name order, byte-identical mosaics;
- orientation:tiepoints depended on the order of the photos; now id order, identical outputs.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import rasterio
import shapely
from rasterio.transform import from_origin

import toolbox
from toolbox.mosaic.partition import voronoi_cells

X0, Y0 = 500000.0, 5000000.0


def test_voronoi_splits_orthos_40_m_apart_in_utm_on_their_bisector():
    a = shapely.box(X0, Y0, X0 + 60, Y0 + 60)
    b = shapely.box(X0, Y0 - 40, X0 + 60, Y0 + 20)
    cells = voronoi_cells([a, b], [(X0 + 30, Y0 + 30), (X0 + 30, Y0 - 10)])
    assert cells[0].equals(shapely.box(X0, Y0 + 10, X0 + 60, Y0 + 60))  # was all of a
    assert cells[1].equals(shapely.box(X0, Y0 - 40, X0 + 60, Y0 + 10))


def _ortho(folder, name, x0, x1, y0, y1, value):
    w, h = x1 - x0, y1 - y0
    with rasterio.open(folder / f"{name}.tif", "w", driver="GTiff", width=w, height=h, count=1,
                       dtype="uint8", nodata=0, crs="EPSG:32633",
                       transform=from_origin(X0 + x0, Y0 + y1, 1, 1)) as dst:
        dst.write(np.full((1, h, w), value, np.uint8))
    return folder / f"{name}.tif"


@pytest.mark.parametrize("blend", ["none", "feather"])
def test_mosaic_is_the_same_whatever_the_input_order(tmp_path, blend):
    # footprint centres (30.5, 30.5), (70.5, 30.5), (70.5, -9.5): the bisectors x = 50.5 and
    # y = 10.5 run through cell centres
    orthos = [_ortho(tmp_path, "a", 0, 61, 0, 61, 100), _ortho(tmp_path, "b", 40, 101, 0, 61, 200),
              _ortho(tmp_path, "c", 40, 101, -40, 21, 50)]
    digests, index = [], []
    for k, order in enumerate(([0, 1, 2], [2, 1, 0], [1, 0, 2])):
        out = tmp_path / f"m{k}.tif"
        toolbox.run("mosaic:build", {"INPUT": [orthos[i] for i in order], "BLEND": blend,
                                     "SOURCE_INDEX": tmp_path / f"i{k}.tif", "OUTPUT": out})
        digests.append(hashlib.sha256(out.read_bytes()).hexdigest())
        with rasterio.open(tmp_path / f"i{k}.tif") as src:  # input numbers -> names
            lut = np.array(["-"] + [src.tags()[f"SOURCE_{n}"][-5] for n in range(1, 4)])
            index.append(lut[src.read(1)])
    assert digests[1] == digests[0] and digests[2] == digests[0]
    np.testing.assert_array_equal(index[1], index[0])
    np.testing.assert_array_equal(index[2], index[0])
    # the tie row y = 10.5 (row 50) between b and c goes to b, the first by name; the column
    # x = 50.5 (column 50) between a and b to a
    assert (index[0][50, 52:] == "b").all() and (index[0][51, 52:] == "c").all()
    assert (index[0][:40, 50] == "a").all() and (index[0][:40, 51] == "b").all()


def test_seamlines_seams_are_the_same_whatever_the_input_order(tmp_path):
    import geopandas as gpd

    orthos = [_ortho(tmp_path, "a", 0, 61, 0, 61, 100), _ortho(tmp_path, "b", 40, 101, 0, 61, 200),
              _ortho(tmp_path, "c", 40, 101, -40, 21, 50)]
    seams = []
    for k, order in enumerate(([0, 1, 2], [2, 1, 0])):
        out = tmp_path / f"s{k}.gpkg"
        toolbox.run("mosaic:seamlines", {"INPUT": [orthos[i] for i in order], "OUTPUT": out})
        frame = gpd.read_file(out, layer="seamlines")
        seams.append({tuple(sorted((a, b))): g for a, b, g in zip(frame["a"], frame["b"],
                                                                   frame.geometry, strict=True)})
    assert seams[0].keys() == seams[1].keys()
    for pair, line in seams[0].items():
        assert line.equals(seams[1][pair]), pair
    assert seams[0][("b", "c")].length == 50.0  # below the tie row, which b keeps


def test_tiepoints_are_the_same_whatever_the_photo_order(tmp_path):
    """orientation:tiepoints matched each pair from its lower-listed photo (Lowe's ratio test
    is one-way) and seeded the tracks by list position: the same block listed in another
    order gave other points (114 against 109 here, 371 against 387 on all six photos)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent / "matching"))
    import block_scene

    from toolbox.photogrammetry.synthetic import hills_dem, render_photo

    z, transform = hills_dem(block_scene.BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=4)
    photos = [p for p in block_scene.true_photos() if p.id in ("s1_1", "s1_2", "s2_1")]
    images = [block_scene.write_photo(tmp_path / f"{p.id}.tif", render_photo(
        p, z, transform, block_scene.texture, dtype="uint8")) for p in photos]
    outputs = []
    for name, order in (("listed", [0, 1, 2]), ("reversed", [2, 1, 0])):
        project = block_scene.project_yaml(tmp_path / f"{name}.yaml", [photos[k] for k in order],
                                           [images[k] for k in order])
        toolbox.run("orientation:tiepoints", {"PROJECT": project, "TERRAIN_HEIGHT": 350.0,
                                              "MAX_FEATURES": 1000, "REFINE": False,
                                              "OUTPUT": tmp_path / f"{name}.csv"})
        outputs.append((tmp_path / f"{name}.csv").read_bytes())
    assert outputs[0].count(b"\n") > 100
    assert outputs[1] == outputs[0]
