"""Round 15 sweep of LAS/LAZ inputs: withheld points, CRS from GeoTIFF keys."""

from __future__ import annotations

import numpy as np
import pytest

laspy = pytest.importorskip("laspy")


def _grid_cloud(path, withheld=None, z=None, crs="EPSG:32633"):
    xs, ys = np.meshgrid(500000.0 + 10 * np.arange(5), 4500000.0 + 10 * np.arange(5))
    x, y = xs.ravel(), ys.ravel()
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([500000.0, 4500000.0, 0.0])
    if crs is not None:
        from pyproj import CRS

        header.add_crs(CRS.from_user_input(crs))
    las = laspy.LasData(header)
    las.x, las.y = x, y
    las.z = 100.0 + 0.1 * (x - 500000) if z is None else z
    las.classification = np.full(len(x), 2, np.uint8)
    las.return_number = np.ones(len(x), np.uint8)
    las.number_of_returns = np.ones(len(x), np.uint8)
    if withheld is not None:
        las.withheld = withheld
    las.write(path)
    return x, y, np.asarray(las.z)


def test_withheld_points_are_not_read(tmp_path):
    """LAS spec: a withheld point 'should not be included in processing' (deleted). It was
    gridded like any other (a deleted 9999 m spike in the DEM)."""
    from toolbox.io.pointcloud import PointFilter, open_point_cloud, read_xyz

    withheld = np.zeros(25, bool)
    withheld[[3, 12]] = True
    z = np.full(25, 100.0)
    z[withheld] = 9999.0
    x, y, _ = _grid_cloud(tmp_path / "w.las", withheld, z)
    ref = open_point_cloud(tmp_path / "w.las")
    for flt in (PointFilter(), PointFilter((2,)), PointFilter(None, "last")):
        xyz, report = read_xyz(ref, flt)
        assert len(xyz) == 23 and xyz[:, 2].max() == 100.0
        np.testing.assert_allclose(xyz[:, 0], x[~withheld])
        assert report.as_dict()["points_withheld"] == 2
        assert report.read == 25 and report.kept == 23
