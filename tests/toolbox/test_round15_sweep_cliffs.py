"""Round 15 sweep (cliffs): parameter values that made a run take forever or eat all memory
now refused before the work, naming the parameter (toolbox.limits.check_size)."""

from __future__ import annotations

import geopandas as gpd
import pytest
from shapely.geometry import LineString

import toolbox
from toolbox.errors import ParameterError

E0, N0 = 1688000.0, 4799000.0
CRS = "EPSG:3003"


def never(*args, **kwargs):
    raise AssertionError("the heavy step ran before the size guard")


@pytest.fixture
def lines(tmp_path):
    path = tmp_path / "l.gpkg"
    gpd.GeoDataFrame({"id": [1]}, geometry=[LineString([(E0 + 20, N0 + 20),
                                                        (E0 + 320, N0 + 20)])],
                     crs=CRS).to_file(path)
    return path


def test_densify_counts_the_moved_vertices_features(lines, tmp_path, monkeypatch):
    """densify writes a moved_vertices point (about 1 kB of memory) per added vertex: 300 m at
    DISTANCE 0.01 adds 29,999 of them, over a features limit of 1,000 (the vertices limit,
    meant for coordinate arrays, let 1e8 of them through: ~100 GB)."""
    from toolbox.attribution import editing

    monkeypatch.setattr(editing, "densify", never)
    monkeypatch.setenv("TOOLBOX_MAX_FEATURES", "1000")
    with pytest.raises(ParameterError) as info:
        toolbox.run("attribution:sample", {"INPUT": lines, "METHOD": "densify",
                                           "DISTANCE": 0.01, "OUTPUT": tmp_path / "s.gpkg"})
    text = str(info.value)
    assert info.value.name == "DISTANCE" and text.startswith("DISTANCE 0.01 "), text
    assert "30,000 added vertices" in text and "limit of 1,000 features" in text, text
    assert "TOOLBOX_MAX_FEATURES" in text
    # the distance method writes a point per removed input vertex only: not refused
    toolbox.run("attribution:sample", {"INPUT": lines, "METHOD": "distance", "DISTANCE": 0.01,
                                       "OUTPUT": tmp_path / "d.gpkg"})
    # within the limit densify runs and adds the vertices (300 m / 1 m: 299 added)
    monkeypatch.undo()
    monkeypatch.setenv("TOOLBOX_MAX_FEATURES", "1000")
    toolbox.run("attribution:sample", {"INPUT": lines, "METHOD": "densify", "DISTANCE": 1.0,
                                       "OUTPUT": tmp_path / "k.gpkg"})
    assert len(gpd.read_file(tmp_path / "k.gpkg", layer="moved_vertices")) == 299
