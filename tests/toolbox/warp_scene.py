"""The small photo scene of the photo-warp tests (test_round18_warpnodata,
test_round19_warpnan_edges): a W x H photo whose pixels map to EPSG:3003 ground by an exact
similarity (:data:`GEO`), written as a GeoTIFF, and the homography rectify:estimate recovers from
its corners."""

from __future__ import annotations

import warnings

import numpy as np
import rasterio
from affine import Affine

import toolbox

X0, Y0 = 1688000.0, 4800000.0
W, H = 120, 80
THETA, SCALE = np.radians(20.0), 0.8
GEO = Affine(SCALE * np.cos(THETA), SCALE * np.sin(THETA), X0,
             SCALE * np.sin(THETA), -SCALE * np.cos(THETA), Y0)  # photo pixel -> ground


def write_photo(path, data, nodata=None, georeferenced=False):
    """``data`` (bands, H, W) as a GeoTIFF photo; ``georeferenced`` gives it :data:`GEO` (for
    gdalwarp), else it has no georeferencing (as a photo)."""
    extra = {"transform": GEO, "crs": "EPSG:3003"} if georeferenced else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=W, height=H, count=len(data),
                           dtype=data.dtype.name, nodata=nodata, **extra) as dst:
            dst.write(data)
    return path


def estimate_homography(folder):
    """rectify:estimate's homography from five of the photo's points and their ground
    coordinates by :data:`GEO`: the transform JSON's path in ``folder``."""
    points = [(0, 0), (W, 0), (W, H), (0, H), (W / 2, H / 3)]
    rows = "".join(f"P{k},{c},{r},{(GEO * (c, r))[0]},{(GEO * (c, r))[1]},0,control\n"
                   for k, (c, r) in enumerate(points))
    (folder / "g.csv").write_text("id,col,row,X,Y,Z,role\n" + rows)
    toolbox.run("rectify:estimate", {"INPUT": folder / "g.csv", "CRS": "EPSG:3003",
                                     "MODEL": "homography", "OUTPUT": folder / "t.json"})
    return folder / "t.json"
