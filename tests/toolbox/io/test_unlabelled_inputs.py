"""An input without a CRS is taken to be in the other inputs' CRS. When its extent lies away
from theirs (UTM numbers in an EPSG:3003 job), a warning names it: its breaklines were dropped,
a mask masked nothing, profiles found nothing, in silence. Where it lies with the others, no
warning."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox

pytestmark = pytest.mark.filterwarnings("ignore:'crs' was not provided")

X0, Y0 = 1688000.0, 4799500.0


def points(tmp_path):
    rng = np.random.default_rng(3)
    x, y = X0 + rng.uniform(0, 300, 400), Y0 + rng.uniform(0, 300, 400)
    path = tmp_path / "points.gpkg"
    gpd.GeoDataFrame(geometry=shapely.points(x, y, 100 + 0.1 * (x - X0)),
                     crs="EPSG:3003").to_file(path)
    return path


def lines(tmp_path, name, crs_of_numbers):
    line = gpd.GeoSeries([shapely.LineString([(X0 + 50, Y0 + 50, 105), (X0 + 250, Y0 + 250,
                                                                        125)])],
                         crs="EPSG:3003").to_crs(crs_of_numbers)
    path = tmp_path / f"{name}.gpkg"
    gpd.GeoDataFrame(geometry=list(line)).to_file(path)  # written without a CRS
    return path


def run_warnings(tmp_path, breaklines):
    feedback = toolbox.Feedback()
    toolbox.run("tin:delaunay", {"INPUT": points(tmp_path), "BREAKLINES": breaklines,
                                 "OUTPUT": tmp_path / "tin.gpkg"}, feedback=feedback,
                overwrite=True)
    return [w for w in feedback.warnings if "has no CRS" in w]


def test_an_unlabelled_layer_away_from_the_others_is_named(tmp_path):
    found = run_warnings(tmp_path, lines(tmp_path, "utm_numbers", "EPSG:32632"))
    assert len(found) == 1 and found[0].startswith("BREAKLINES has no CRS and lies away")
    assert "taken to be in EPSG:3003" in found[0]


def test_an_unlabelled_layer_over_the_others_is_quiet(tmp_path):
    assert run_warnings(tmp_path, lines(tmp_path, "same_numbers", "EPSG:3003")) == []
