"""The GCP copy of rectify:image (MODE=gcps) written window by window: several tiles, partial
ones at the east and south edges, give the source's pixels exactly (rasterio's read as oracle)."""

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
        points, crs = ds.gcps
        assert crs.to_epsg() == 3003
        # (GeoTIFF tie points keep no ids: GDAL numbers them on reading)
        assert [(p.col, p.row, p.x, p.y, p.z) for p in points] == [g[1:] for g in gcps]
