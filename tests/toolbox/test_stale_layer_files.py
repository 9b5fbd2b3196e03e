"""An output in a one-layer-per-file format (Shapefile, FlatGeobuf, GeoParquet, GeoJSON) keeps
its declared layers in ``<stem>_<layer><ext>`` beside it. A run that leaves a layer out (a TIN
without EDGES) removes the earlier run's file of that layer with ``--overwrite``: it sat beside
the new triangles as if it were their edges (another TIN's, exit 0)."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from toolbox.errors import OutputExistsError

CRS = "EPSG:3003"


def _points(tmp_path, seed):
    rng = np.random.default_rng(seed)
    n = 60
    geoms = shapely.points(1688000 + 100 * rng.random(n), 4799500 + 100 * rng.random(n),
                           300 + rng.random(n))
    path = tmp_path / f"p{seed}.gpkg"
    gpd.GeoDataFrame(geometry=geoms, crs=CRS).to_file(path)
    return path


@pytest.mark.parametrize("ext", [".shp", ".fgb"])
def test_a_layer_left_out_removes_the_earlier_runs_file_of_it(tmp_path, ext):
    out = tmp_path / f"tin{ext}"
    toolbox.run("tin:delaunay", {"INPUT": _points(tmp_path, 1), "OUTPUT": out})
    edges = tmp_path / f"tin_edges{ext}"
    assert edges.exists()
    with pytest.raises(OutputExistsError):
        toolbox.run("tin:delaunay", {"INPUT": _points(tmp_path, 2), "OUTPUT": out,
                                     "EDGES": False})
    assert edges.exists()  # refused: nothing changed
    toolbox.run("tin:delaunay", {"INPUT": _points(tmp_path, 2), "OUTPUT": out, "EDGES": False},
                overwrite=True)
    assert not edges.exists()
    leftovers = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("tin_edges"))
    assert leftovers == []
    nodes = gpd.read_file(tmp_path / f"tin_nodes{ext}")
    assert len(nodes) == 60  # the new run's layers are in place


def test_a_layer_file_that_is_an_input_is_left_alone(tmp_path):
    """The earlier run's edges read by this run (as its BREAKLINES) are an input: not removed,
    though this run leaves its edges out."""
    out = tmp_path / "tin.shp"
    toolbox.run("tin:delaunay", {"INPUT": _points(tmp_path, 1), "OUTPUT": out})
    edges = tmp_path / "tin_edges.shp"
    before = edges.read_bytes()
    toolbox.run("tin:delaunay", {"INPUT": _points(tmp_path, 1), "BREAKLINES": str(edges),
                                 "OUTPUT": out, "EDGES": False}, overwrite=True)
    assert edges.read_bytes() == before
