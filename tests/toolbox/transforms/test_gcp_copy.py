"""The GCP copy of rectify:image (MODE=gcps) written window by window by the RasterWriter:
several tiles, partial ones at the east and south edges, give the source's pixels exactly
(rasterio's read as oracle), in a tiled, compressed GeoTIFF georeferenced by its points only."""

from __future__ import annotations

import numpy as np
import rasterio

from toolbox.feedback import Feedback
from toolbox.io.crs import parse_crs
from toolbox.transforms.rectification import write_gcp_geotiff


def test_copy_in_many_windows_equals_the_source(tmp_path):
    data = np.random.default_rng(3).integers(0, 255, (3, 150, 230), dtype=np.uint8)
    source = tmp_path / "photo.tif"
    with rasterio.open(source, "w", driver="GTiff", width=230, height=150, count=3,
                       dtype="uint8") as dst:
        dst.write(data)
    gcps = [("a", 10.5, 20.5, 1688000.0, 4799000.0, 50.0),
            ("b", 200.5, 140.5, 1688100.0, 4798900.0, 60.0)]
    out = tmp_path / "gcps.tif"
    write_gcp_geotiff(source, out, gcps, parse_crs("EPSG:3003"), Feedback(), chunk=64)
    with rasterio.open(out) as ds:
        np.testing.assert_array_equal(ds.read(), data)  # 4 x 3 windows, the last ones partial
        assert ds.profile["tiled"] and ds.block_shapes == [(512, 512)] * 3
        assert ds.compression.name == "deflate"
        assert ds.tags(ns="IMAGE_STRUCTURE").get("PREDICTOR") == "2"
        assert [c.name for c in ds.colorinterp] == ["red", "green", "blue"]
        assert ds.transform.is_identity and ds.crs is None  # the GCPs alone georeference it
        assert ds.overviews(1) == []
        points, crs = ds.gcps
        assert crs.to_epsg() == 3003
        # (GeoTIFF tie points keep no ids: GDAL numbers them on reading)
        assert [(p.col, p.row, p.x, p.y, p.z) for p in points] == [g[1:] for g in gcps]


def test_a_failed_copy_leaves_no_file(tmp_path):
    source = tmp_path / "photo.tif"
    with rasterio.open(source, "w", driver="GTiff", width=40, height=30, count=1,
                       dtype="uint8") as dst:
        dst.write(np.ones((1, 30, 40), np.uint8))

    class Cancel(Feedback):
        def iterate(self, items, *args, **kwargs):
            yield items[0]
            raise KeyboardInterrupt

    out = tmp_path / "gcps.tif"
    gcps = [("a", 1.5, 1.5, 0.0, 0.0, 0.0)]
    try:
        write_gcp_geotiff(source, out, gcps, parse_crs("EPSG:3003"), Cancel(), chunk=16)
    except KeyboardInterrupt:
        pass
    assert not out.exists()
