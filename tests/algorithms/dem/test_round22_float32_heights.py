"""A height beyond what a float32 DEM cell holds (|Z| > 3.4e38) is refused before gridding
(exit 2, one line naming the parameter and the value), instead of written as inf with numpy's
overflow warnings (dem gridding, in memory and streamed)."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox.io.pointcloud as pointcloud
from tests.helpers_cli import cli, one_error

X0, Y0 = 1_688_000.0, 4_799_500.0


def points(path, z):
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 100, (len(z), 2)) + [X0, Y0]
    gpd.GeoDataFrame(geometry=shapely.points(np.c_[xy, z]), crs="EPSG:3003").to_file(path)
    return path


@pytest.mark.parametrize("method", ["dem:idw", "dem:nearest", "dem:tin_linear"])
def test_a_height_beyond_float32_is_refused(tmp_path, method):
    z = np.full(200, 250.0)
    z[17] = -1e200
    src = points(tmp_path / "p.gpkg", z)
    out = tmp_path / "dem.tif"
    code, _, err = cli("run", method, "--INPUT", src, "--OUTPUT", out, "--CELL_SIZE", 5)
    assert code == 2
    line = one_error(err)
    assert "INPUT" in line and "-1e+200" in line and "float32" in line, line
    assert not out.exists()


def test_heights_at_the_float32_limit_are_gridded(tmp_path):
    z = np.full(200, 250.0)
    z[17] = 3.0e38  # fits a float32 cell
    src = points(tmp_path / "p.gpkg", z)
    code, _, err = cli("run", "dem:nearest", "--INPUT", src, "--OUTPUT", tmp_path / "dem.tif",
                       "--CELL_SIZE", 5)
    assert code == 0, err


def test_a_streamed_cloud_is_refused_too(tmp_path, monkeypatch):
    from toolbox.io.pointcloud import write_point_cloud

    rng = np.random.default_rng(4)
    n = 3000
    xyz = np.c_[np.round(X0 + rng.uniform(0, 200, n), 3), np.round(Y0 + rng.uniform(0, 150, n), 3),
                np.full(n, 250.0)]
    cloud = tmp_path / "c.las"
    write_point_cloud(cloud, xyz, "EPSG:3003")
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    real = pointcloud.iter_xyz

    def with_one_huge_height(*args, **kwargs):  # LAS stores scaled int32: no 1e200 on file
        for k, chunk in enumerate(real(*args, **kwargs)):
            if k == 1:
                chunk = chunk.copy()
                chunk[5, 2] = 1e200
            yield chunk

    monkeypatch.setattr(pointcloud, "iter_xyz", with_one_huge_height)
    out = tmp_path / "dem.tif"
    code, _, err = cli("run", "dem:idw", "--INPUT", cloud, "--OUTPUT", out, "--CELL_SIZE", 2)
    assert code == 2
    line = one_error(err)
    assert "INPUT" in line and "1e+200" in line, line
    assert not out.exists()


def test_the_ground_filter_refuses_it_too(tmp_path):
    """dem:ground read its points with its own call: the point at -1e200 was filtered out as
    non-ground with numpy's 'overflow encountered in cast' and exit 0 (round twenty-three)."""
    z = np.full(400, 250.0)
    z[17] = -1e200
    src = points(tmp_path / "p.gpkg", z)
    out = tmp_path / "dtm.tif"
    code, _, err = cli("run", "dem:ground", "--INPUT", src, "--OUTPUT", out, "--NONGROUND",
                       tmp_path / "ng.tif", "--CELL_SIZE", 5, "--MAX_WINDOW", 10)
    assert code == 2
    line = one_error(err)
    assert "INPUT" in line and "-1e+200" in line and "float32" in line, line
    assert not out.exists() and not (tmp_path / "ng.tif").exists()
