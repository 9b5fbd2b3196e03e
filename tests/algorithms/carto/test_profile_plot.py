"""carto:profile's plot says what it leaves out and names its input without a machine path
(issue 30)."""

from __future__ import annotations

import geopandas as gpd
import matplotlib
import numpy as np
import pytest
import shapely
from affine import Affine

import toolbox
from toolbox.cartography.profile_io import layer_title
from toolbox.raster.writer import write_raster

CRS = "EPSG:3003"


@pytest.fixture()
def inputs(tmp_path):
    z = np.add.outer(np.arange(100.0), np.arange(120.0)).astype("float32")  # a plane
    dem = tmp_path / "dem.tif"
    write_raster(dem, z, Affine(10, 0, 1687700, 0, -10, 4799700), CRS, nodata=-9999.0)
    line = tmp_path / "axis.gpkg"
    gpd.GeoDataFrame({"name": ["axis"]}, geometry=[shapely.LineString(
        [(1687800, 4799200), (1688800, 4799200)])], crs=CRS).to_file(line)
    return dem, line


def test_sections_plot_says_how_many_it_shows(inputs, tmp_path, monkeypatch):
    dem, line = inputs
    monkeypatch.setitem(matplotlib.rcParams, "svg.fonttype", "none")  # text stays text
    plot = tmp_path / "sections.svg"
    feedback = toolbox.Feedback()
    res = toolbox.run("carto:profile", {"INPUT": line, "DEM": dem, "MODE": "sections",
                                        "SPACING": 40, "HALF_WIDTH": 50, "STEP": 10,
                                        "OUTPUT": tmp_path / "s.gpkg", "PLOT": plot},
                      feedback=feedback)
    stats = res["STATISTICS"]
    assert (stats["profiles"], stats["plotted"]) == (26, 12)  # sections at 0, 40, ..., 1000 m
    svg = plot.read_text()
    assert "the first 12 of 26 sections shown; all are in the GeoPackage" in svg
    assert "sections along axis.gpkg" in svg and str(tmp_path) not in svg
    assert any("first 12 of 26" in t for lvl, t in feedback.messages if lvl == "info")


def test_layer_title_never_a_path():
    assert layer_title("/home/me/job/lines.gpkg|layername=axes") == "lines.gpkg (axes)"
    assert layer_title("/home/me/job/axis.gpkg|layername=axis") == "axis.gpkg"
    assert layer_title("C:/data/lines.shp") == "lines.shp"
