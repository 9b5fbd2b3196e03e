"""The demo's Siena block from its photos alone (toolbox/demo/pipeline/65_block.yaml): DSM by
dense matching -> DTM and heights by the ground filter -> true orthos on the DSM -> least-cost
seamlines with the heights -> mosaic. Known truth: the landscape's building footprints (the
photos were rendered with them standing 7-16 m, toolbox/demo/samples/landscape.py).

The seams routed with the matched DSM's heights must run through buildings much less than the
seams of the same orthos routed without them (the images alone) and than the Voronoi seams.
"""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import rasterio
import shapely

import toolbox

BLOCK = ("1_7150", "1_7151", "1_7152", "2_7138", "2_7139", "2_7140")


def _inside_buildings(gpkg) -> tuple[float, float]:
    """(seam length, seam length more than 1 m inside a building footprint), metres."""
    from toolbox.demo.samples.landscape import landscape_vectors

    houses = shapely.union_all(landscape_vectors()["buildings"]).buffer(-1.0)
    seams = shapely.union_all(gpd.read_file(gpkg, layer="seamlines").geometry.values)
    return seams.length, seams.intersection(houses).length


def test_block_chain_seams_go_round_buildings(demo_run, tmp_path):
    out, _ = demo_run
    orthos = [str(out / "ortho" / "siena_block" / f"{pid}.tif") for pid in BLOCK]
    # the chain ran without any external surface: orthos on the matched DSM, true orthos
    report = __import__("json").loads((out / "reports" / "siena_block_orthos.json").read_text())
    assert report["parameters"]["DEM"] == str(out / "surface" / "siena_dsm.tif")
    assert report["parameters"]["OCCLUSION"] is True
    # the heights stand up on the buildings and not elsewhere
    from toolbox.demo.samples.landscape import landscape_vectors

    houses = shapely.union_all(landscape_vectors()["buildings"])
    with rasterio.open(out / "surface" / "siena_heights.tif") as ds:
        heights = ds.read(1, masked=True)
        t = ds.transform
    rows, cols = np.indices(heights.shape)
    x, y = t.c + (cols + 0.5) * t.a, t.f + (rows + 0.5) * t.e
    ok = ~heights.mask
    inner = ok & shapely.contains_xy(houses.buffer(-2.0), x, y)
    far = ok & ~shapely.contains_xy(houses.buffer(6.0), x, y)
    assert inner.sum() > 300 and far.sum() > 20_000
    assert np.median(heights.data[inner]) > 3.0
    assert np.mean(heights.data[far] > 3.0) < 0.02

    length, inside = _inside_buildings(out / "mosaic" / "siena_block_seamlines.gpkg")
    assert length > 2000  # the block's seams, all of them
    with_dsm = inside / length
    others = {}
    for name, extra in (("images only", {}), ("voronoi", {"METHOD": "voronoi"})):
        path = tmp_path / f"{name.replace(' ', '_')}.gpkg"
        toolbox.run("mosaic:seamlines", {"INPUT": orthos, "METHOD": "least_cost",
                                         "OUTPUT": str(path), **extra})
        total, through = _inside_buildings(path)
        others[name] = through / total
    assert with_dsm < 0.06, (with_dsm, others)  # 4.2 % measured (10.7 % images only)
    assert with_dsm < 0.5 * min(others.values()), (with_dsm, others)
    # and the mosaic was built on those seams from the six true orthos
    with rasterio.open(out / "mosaic" / "siena_block_source.tif") as ds:
        index = ds.read(1)
    assert set(np.unique(index)) - {0, ds.nodata} == set(range(1, 7))
