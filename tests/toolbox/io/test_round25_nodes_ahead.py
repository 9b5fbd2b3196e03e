"""Round 25: a new TIN GeoPackage whose nodes layer was written while the triangulation ran
(``store.NodesAhead``, given the nodes by ``build_tin``'s ``nodes_ready``) holds what GDAL's own
writer puts in it: the same layers in the same order, rows, values and types, R-tree entries and
metadata; SQLite's and the GeoPackage checks accept it. Nothing is written ahead where the
nodes are not known before the triangulation (breaklines, boundary, concave hull); a refusal of
the writing ahead falls back to GDAL, and nodes that are not the model's are never kept."""

from __future__ import annotations

import sqlite3
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pyogrio
import pytest
import shapely

from tests.toolbox.gpkg_check import gdal_validator_problems, gpkg_problems
from toolbox.io.crs import parse_crs
from toolbox.terrain.tin import store
from toolbox.terrain.tin.build import build_tin

X0, Y0 = 1688000.0, 4799000.0
CRS = parse_crs("EPSG:3003")


def _points(n: int, seed: int, duplicates: int = 0) -> np.ndarray:
    """Random points on a tilted plane at Siena's coordinates; the first ``duplicates`` repeat
    the XY of the next ones with another Z (merged nodes)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 500, (n, 2)) + [X0, Y0]
    xy[:duplicates] = xy[duplicates:2 * duplicates]
    return np.c_[xy, 300 + 0.05 * (xy[:, 0] - X0) + rng.normal(0, 1, n)]


def _write_ahead(path: Path, points: np.ndarray, spatial_index: bool = True,
                 edges_layer: bool = True, **build):
    """tin:delaunay's sequence: the nodes handed to NodesAhead by build_tin, then write_tin."""
    with ThreadPoolExecutor(1) as pool:
        ahead = store.NodesAhead(path, CRS, spatial_index, edges_layer, pool)
        model = build_tin(points, nodes_ready=ahead, **build)
        started = ahead.started
        counts = store.write_tin(path, model, CRS, spatial_index, edges_layer=edges_layer,
                                 ahead=ahead)
    return model, started, counts


def _rows(path: Path, sql: str) -> list[tuple]:
    with sqlite3.connect(path) as db:
        return db.execute(sql).fetchall()


def _layer_rows(path: Path, layer: str) -> list[tuple]:
    columns = [row[1] for row in _rows(path, f'PRAGMA table_info("{layer}")')]
    selected = ", ".join(f'"{c}", typeof("{c}")' for c in columns)
    return _rows(path, f'SELECT {selected} FROM "{layer}" ORDER BY fid')


METADATA = ("SELECT table_name, data_type, identifier, description, min_x, min_y, max_x, "
            "max_y, srs_id FROM gpkg_contents ORDER BY table_name",
            "SELECT * FROM gpkg_ogr_contents ORDER BY table_name",
            "SELECT * FROM sqlite_sequence ORDER BY name",
            "SELECT * FROM gpkg_geometry_columns ORDER BY table_name",
            "SELECT * FROM gpkg_extensions ORDER BY table_name, extension_name",
            "SELECT type, name, tbl_name, sql FROM sqlite_master ORDER BY name")


@pytest.mark.parametrize("duplicates, spatial_index, edges_layer",
                         [(0, True, True), (25, True, True), (0, False, True),
                          (10, True, False), (0, False, False)])
def test_written_ahead_is_what_gdal_writes(tmp_path, duplicates, spatial_index, edges_layer):
    path, gdal = tmp_path / "ahead.gpkg", tmp_path / "gdal.gpkg"
    model, started, counts = _write_ahead(path, _points(2500, duplicates, duplicates),
                                          spatial_index, edges_layer)
    assert started
    store._write_tin(gdal, model, CRS, spatial_index, None, edges_layer, bulk=False)
    layers = ["triangles", "nodes", "edges"][:3 if edges_layer else 2]
    # GDAL lists the layers in the order they were made: the triangles stay the first layer
    assert [name for name, _ in pyogrio.list_layers(path)] == layers
    assert [name for name, _ in pyogrio.list_layers(gdal)] == layers
    for layer in layers:
        expected = _layer_rows(gdal, layer)
        assert len(expected) == counts[layer] > 1000
        assert _layer_rows(path, layer) == expected, layer
        if spatial_index:
            sql = f'SELECT id, minx, maxx, miny, maxy FROM "rtree_{layer}_geom" ORDER BY id'
            assert _rows(path, sql) == _rows(gdal, sql), layer
            assert _rows(path, f"SELECT rtreecheck('rtree_{layer}_geom')") == [("ok",)]
    tables = {name for (name,) in _rows(gdal, "SELECT name FROM sqlite_master")}
    for sql in METADATA:
        if sql.split(" FROM ")[1].split()[0] in tables:  # no gpkg_extensions without an index
            assert _rows(path, sql) == _rows(gdal, sql), sql
    if duplicates:
        merged = [m for (m,) in _rows(path, "SELECT merged FROM nodes")]
        assert merged.count(2) == duplicates and len(merged) == 2500 - duplicates
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]
    assert gpkg_problems(path) == []
    if duplicates == 25:  # GDAL's validate_gpkg.py (Debian's), once: a few seconds
        assert gdal_validator_problems(path) == ""


@pytest.mark.parametrize("build", [
    {"line_xyz": np.array([[X0 + 50, Y0 + 50, 310.0], [X0 + 450, Y0 + 400, 330.0]]),
     "line_index": np.array([0, 0])},
    {"boundary": shapely.box(X0 + 100, Y0 + 100, X0 + 400, Y0 + 400)},
    {"concave": True}])
def test_nothing_is_written_ahead_when_the_nodes_come_later(tmp_path, build):
    """Breaklines (crossings), a boundary (its vertices; points outside dropped) and a concave
    hull (nodes may go) change the nodes: the layers are written after the build, as before."""
    path = tmp_path / "t.gpkg"
    model, started, counts = _write_ahead(path, _points(1500, 7), **build)
    assert not started
    frame = pyogrio.read_dataframe(path, layer="nodes")
    np.testing.assert_array_equal(shapely.get_coordinates(frame.geometry.values, include_z=True),
                                  model.xyz)
    assert [name for name, _ in pyogrio.list_layers(path)] == ["triangles", "nodes", "edges"]
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]


def test_a_refusal_ahead_falls_back_to_gdal(tmp_path, monkeypatch):
    """The bulk writer refuses the nodes on the thread: write_tin gets the refusal, removes the
    half-written file and GDAL writes the whole TIN."""
    from toolbox.io import gpkg_bulk

    original = gpkg_bulk.write_layer_bulk
    calls = []

    def refuse_nodes(path, layer, *args, **kwargs):
        calls.append(layer.name)
        if layer.name == "nodes":
            raise gpkg_bulk.BulkUnsupported("a test's refusal")
        return original(path, layer, *args, **kwargs)

    monkeypatch.setattr(gpkg_bulk, "write_layer_bulk", refuse_nodes)
    path = tmp_path / "t.gpkg"
    model, started, counts = _write_ahead(path, _points(1200, 3))
    assert started and calls == ["nodes"]
    assert {name: pyogrio.read_info(path, layer=name)["features"]
            for name in ("triangles", "nodes", "edges")} == counts
    frame = pyogrio.read_dataframe(path, layer="nodes")
    np.testing.assert_array_equal(shapely.get_coordinates(frame.geometry.values, include_z=True),
                                  model.xyz)
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]


def test_nodes_that_are_not_the_models_are_refused(tmp_path):
    """build_tin's contract (the nodes handed over are the model's) is checked, not trusted."""
    points = _points(800, 4)
    path = tmp_path / "t.gpkg"
    with ThreadPoolExecutor(1) as pool:
        ahead = store.NodesAhead(path, CRS, True, True, pool)
        model = build_tin(points, nodes_ready=ahead)
        other = build_tin(points + [0.0, 0.0, 1.0])
        with pytest.raises(RuntimeError, match="not those written ahead"):
            store.write_tin(path, other, CRS, ahead=ahead)
        with pytest.raises(ValueError, match="another file or other options"):
            store.write_tin(path, model, CRS, spatial_index=False, ahead=ahead)


def test_other_formats_and_existing_files_are_not_written_ahead(tmp_path):
    """GeoParquet and FlatGeobuf are written after the build, as before; so is a GeoPackage that
    exists (a layer added to it is GDAL's work, not the bulk writer's)."""
    import pyarrow.parquet as pq

    points = _points(600, 5)
    model, started, counts = _write_ahead(tmp_path / "t.parquet", points)
    assert not started and pq.read_metadata(tmp_path / "t.parquet").num_rows == counts["triangles"]
    model, started, counts = _write_ahead(tmp_path / "t.fgb", points)
    assert not started and pyogrio.read_info(tmp_path / "t.fgb")["features"] == counts["triangles"]
    existing = tmp_path / "existing.gpkg"
    pyogrio.write_dataframe(pyogrio.read_dataframe(tmp_path / "t_nodes.fgb"), existing,
                            layer="other")
    model, started, counts = _write_ahead(existing, points)
    assert not started
    assert [name for name, _ in pyogrio.list_layers(existing)] == ["other", "triangles", "nodes",
                                                                   "edges"]
