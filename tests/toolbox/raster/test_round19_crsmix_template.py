"""The grid of a TEMPLATE in another horizontal CRS than the output's (round 19, crsmix): refused
naming both, by the one grid request every raster algorithm uses. Before, its cells were taken
as if in the output's CRS: dem:match with a UTM 32N TEMPLATE under a Monte Mario project matched
every pair (minutes) and then wrote nothing ("no valid cell"); with two CRSs of one area
(ED50 and WGS 84 UTM 32N: 200 m apart) the DSM would have been written on the wrong grid."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine
from pyproj import CRS

from toolbox.errors import ParameterError
from toolbox.io.grid import GridSpec
from toolbox.io.raster import open_raster_info
from toolbox.raster.grid_request import GridRequest

X0, Y0 = 689_000.0, 4_798_000.0


def _template(tmp_path, crs):
    path = tmp_path / f"t{abs(hash(crs))}.tif"
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=1, dtype="float32",
                       crs=crs, transform=Affine(5.0, 0, X0, 0, -5.0, Y0)) as dst:
        dst.write(np.zeros((1, 30, 40), "float32"))
    return open_raster_info(path)


def test_a_template_in_another_horizontal_crs_is_refused(tmp_path):
    info = _template(tmp_path, "EPSG:23032")
    with pytest.raises(ParameterError, match=r"^TEMPLATE is in EPSG:23032 but the output is in "
                                             "EPSG:32632"):
        GridRequest(template=info).grid(None, CRS.from_epsg(32632))
    with pytest.raises(ParameterError, match="TEMPLATE is in EPSG:23032"):
        GridRequest(template=info, extent=None).grid((X0, Y0 - 100, X0 + 100, Y0),
                                                     CRS.from_user_input("EPSG:32632+5214"))
    # the same horizontal CRS, a height datum on one side, or no CRS on one side: its grid
    t = Affine(5.0, 0, X0, 0, -5.0, Y0)
    info = _template(tmp_path, "EPSG:32632")
    for crs in (CRS.from_epsg(32632), CRS.from_user_input("EPSG:32632+5214"), None):
        grid = GridRequest(template=info).grid(None, crs)
        assert grid == GridSpec(t, 40, 30, crs if crs is not None else info.crs)
