"""Round 21, tinbulk: a TIN GeoPackage written in bulk (SQLite pages built with numpy,
toolbox.io.gpkg_bulk) holds what GDAL's own writer puts in it: the same rows, values and types
in every layer, the same R-tree entries (SQLite's float32 rounding), the same metadata; SQLite's
integrity checks, GDAL's validate_gpkg.py and GDAL's spatial filter accept it; GDAL and SQLite
keep editing it afterwards."""

from __future__ import annotations

import sqlite3
import subprocess
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
LAYERS = ("triangles", "nodes", "edges")


def _model(n: int = 3000, seed: int = 0):
    """Random points on a tilted plane at Siena's coordinates, two crossing breaklines (a
    crossing node, breakline edges) and duplicates (merged nodes): every field kind, NULLs on
    the border (neighbours, right triangles)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 500, (n, 2)) + [X0, Y0]
    xy[:20] = xy[20:40]  # 20 duplicates
    z = 300 + 0.05 * (xy[:, 0] - X0) + rng.normal(0, 1, n)
    lines = np.array([[X0 + 50, Y0 + 50, 310.0], [X0 + 450, Y0 + 400, 330.0],
                      [X0 + 50, Y0 + 450, 305.0], [X0 + 450, Y0 + 60, 320.0]])
    return build_tin(np.c_[xy, z], lines, np.array([0, 0, 1, 1]))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The same model written in bulk (``write_tin``) and by GDAL (the oracle)."""
    folder = tmp_path_factory.mktemp("tinbulk")
    model, crs = _model(), parse_crs("EPSG:3003")
    bulk, gdal = folder / "bulk.gpkg", folder / "gdal.gpkg"
    counts = store.write_tin(bulk, model, crs)
    store._write_tin(gdal, model, crs, True, None, True, bulk=False)
    return bulk, gdal, counts, model


def _rows(path: Path, sql: str) -> list[tuple]:
    with sqlite3.connect(path) as db:
        return db.execute(sql).fetchall()


@pytest.mark.parametrize("layer", LAYERS)
def test_rows_values_and_types_equal_gdals(written, layer):
    bulk, gdal, counts, _ = written
    columns = [row[1] for row in _rows(gdal, f'PRAGMA table_info("{layer}")')]
    assert columns == [row[1] for row in _rows(bulk, f'PRAGMA table_info("{layer}")')]
    selected = ", ".join(f'"{c}", typeof("{c}")' for c in columns)
    sql = f'SELECT {selected} FROM "{layer}" ORDER BY fid'
    expected = _rows(gdal, sql)
    assert len(expected) == counts[layer] > 100
    assert _rows(bulk, sql) == expected  # geometry blobs byte for byte, NULLs, Booleans, text


@pytest.mark.parametrize("layer", LAYERS)
def test_rtree_entries_equal_gdals(written, layer):
    bulk, gdal, _, _ = written
    sql = f'SELECT id, minx, maxx, miny, maxy FROM "rtree_{layer}_geom" ORDER BY id'
    expected = _rows(gdal, sql)
    assert len(expected) > 100
    assert _rows(bulk, sql) == expected  # SQLite's own outward float32 rounding


def test_metadata_equal_gdals(written):
    bulk, gdal, _, _ = written
    for sql in ("SELECT table_name, data_type, identifier, description, min_x, min_y, max_x, "
                "max_y, srs_id FROM gpkg_contents ORDER BY table_name",
                "SELECT * FROM gpkg_ogr_contents ORDER BY table_name",
                "SELECT * FROM sqlite_sequence ORDER BY name",
                "SELECT * FROM gpkg_geometry_columns ORDER BY table_name",
                "SELECT * FROM gpkg_extensions ORDER BY table_name, extension_name",
                "SELECT * FROM gpkg_spatial_ref_sys ORDER BY srs_id",
                "SELECT type, name, tbl_name, sql FROM sqlite_master ORDER BY name",
                "PRAGMA application_id", "PRAGMA user_version", "PRAGMA page_size",
                "PRAGMA journal_mode"):
        assert _rows(bulk, sql) == _rows(gdal, sql), sql
    last_change = _rows(bulk, "SELECT last_change FROM gpkg_contents")
    assert all(len(v) == 24 and v.endswith("Z") for (v,) in last_change)


def test_sqlite_gpkg_and_gdal_checks_pass(written):
    bulk, *_ = written
    assert _rows(bulk, "PRAGMA integrity_check") == [("ok",)]
    for layer in LAYERS:
        assert _rows(bulk, f"SELECT rtreecheck('rtree_{layer}_geom')") == [("ok",)]
    assert gpkg_problems(bulk) == []
    assert gdal_validator_problems(bulk) == ""


def test_gdal_spatial_filter_finds_what_shapely_finds(written):
    bulk, _, _, model = written
    geoms = pyogrio.read_dataframe(bulk, layer="triangles").geometry.values
    tree = shapely.STRtree(geoms)
    rng = np.random.default_rng(3)
    for _ in range(5):
        x, y = X0 + rng.uniform(0, 450), Y0 + rng.uniform(0, 450)
        box = (x, y, x + 40, y + 25)
        found = pyogrio.read_dataframe(bulk, layer="triangles", bbox=box, columns=["id"])
        expected = tree.query(shapely.box(*box), predicate="intersects")
        assert sorted(found["id"]) == sorted(expected + 1)
        assert len(expected) > 5
    if Path("/usr/bin/ogrinfo").exists():  # Debian's GDAL 3.6 reads it, with the index
        text = subprocess.run(["/usr/bin/ogrinfo", "-so", "-spat", *map(str, box), str(bulk),
                               "triangles"], capture_output=True, text=True, check=True).stdout
        # its count with a filter is the R-tree's: envelopes that meet the box
        assert f"Feature Count: {len(tree.query(shapely.box(*box)))}" in text


def test_gdal_and_sqlite_keep_editing_it(tmp_path):
    model = _model(800, seed=5)
    path = tmp_path / "t.gpkg"
    store.write_tin(path, model, parse_crs("EPSG:3003"))
    extra = pyogrio.read_dataframe(path, layer="edges", max_features=30)
    pyogrio.write_dataframe(extra, path, layer="edges", append=True)  # GDAL's triggers fill the R-tree
    with sqlite3.connect(path) as db:
        n = db.execute("SELECT count(*) FROM edges").fetchone()[0]
        db.execute("DELETE FROM rtree_edges_geom WHERE id <= 40")  # the rtree module edits it
        db.execute("DELETE FROM nodes WHERE fid > 700")
    assert pyogrio.read_info(path, layer="edges")["features"] == n
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]
    for layer in LAYERS:
        assert _rows(path, f"SELECT rtreecheck('rtree_{layer}_geom')") == [("ok",)]
    rtree_ids = {i for (i,) in _rows(path, "SELECT id FROM rtree_edges_geom")}
    assert rtree_ids == set(range(41, n + 1))  # the 30 GDAL added are indexed


def test_without_spatial_index_and_without_edges(tmp_path):
    model = _model(500, seed=2)
    path = tmp_path / "t.gpkg"
    store.write_tin(path, model, None, spatial_index=False, edges_layer=False)
    assert [name for name, _ in pyogrio.list_layers(path)] == ["triangles", "nodes"]
    assert _rows(path, "SELECT count(*) FROM sqlite_master WHERE name LIKE 'rtree%'") == [(0,)]
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]
    frame = pyogrio.read_dataframe(path, layer="nodes")
    np.testing.assert_array_equal(shapely.get_coordinates(frame.geometry.values, include_z=True),
                                  model.xyz)


def test_gdal_writes_what_the_bulk_writer_refuses(tmp_path, monkeypatch):
    """A refusal after the first layer: the half-written file is removed and GDAL writes all."""
    from toolbox.io import gpkg_bulk

    calls = []
    original = gpkg_bulk.write_layer_bulk

    def refuse_second(path, layer, *args, **kwargs):
        calls.append(layer.name)
        if len(calls) == 2:
            raise gpkg_bulk.BulkUnsupported("a test's refusal")
        return original(path, layer, *args, **kwargs)

    monkeypatch.setattr(gpkg_bulk, "write_layer_bulk", refuse_second)
    model = _model(400, seed=4)
    path = tmp_path / "t.gpkg"
    counts = store.write_tin(path, model, parse_crs("EPSG:3003"))
    assert calls == ["triangles", "nodes"]
    assert {name: pyogrio.read_info(path, layer=name)["features"] for name in LAYERS} == counts
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]


def test_packed_rtree_by_chunks_of_nodes_is_the_same_tree(monkeypatch):
    """The levels are filled a chunk of nodes at a time (bounded memory for 30 M boxes): chunks
    of 3 nodes give the arrays of one chunk (whose tree the SQLite-oracle tests check)."""
    from toolbox.io import sqlite_rtree

    rng = np.random.default_rng(8)
    x, y = rng.uniform(X0, X0 + 900, 20_000), rng.uniform(Y0, Y0 + 400, 20_000)
    boxes = np.column_stack([sqlite_rtree.rtree_round_down(x), sqlite_rtree.rtree_round_up(x + 2),
                             sqlite_rtree.rtree_round_down(y), sqlite_rtree.rtree_round_up(y + 1)])
    ids = np.arange(5, 20_005, dtype=np.int64)
    whole = sqlite_rtree.packed_rtree_stored(ids, boxes)
    monkeypatch.setattr(sqlite_rtree, "_CHUNK_NODES", 3)
    chunked = sqlite_rtree.packed_rtree_stored(ids, boxes)
    assert whole.depth == 2
    for name in ("node_numbers", "node_blobs", "rowids", "rowid_nodes", "parent_nodes",
                 "parents"):
        np.testing.assert_array_equal(getattr(chunked, name), getattr(whole, name))
    # and the float64 entry point rounds to the same stored boxes: the same tree
    same = sqlite_rtree.packed_rtree(ids, x, x + 2, y, y + 1)
    np.testing.assert_array_equal(same.node_blobs, whole.node_blobs)


def test_a_refusal_on_the_encoding_thread_falls_back_to_gdal(tmp_path, monkeypatch):
    """The batches are encoded on threads of their own (gpkg_bulk.ahead_map): a refusal raised
    there (here: the edges' geometries) reaches the writer, the appender puts the file back, and
    GDAL writes the whole TIN."""
    from toolbox.io import gpkg_bulk

    original = gpkg_bulk.geometry_blobs

    def refuse_lines(wkb, srs_id, stored=None):
        if int(wkb[0, 1:5].view("<u4")[0]) == 1002:  # LineString Z: the edges
            raise gpkg_bulk.BulkUnsupported("a test's refusal")
        return original(wkb, srs_id, stored)

    monkeypatch.setattr(gpkg_bulk, "geometry_blobs", refuse_lines)
    model = _model(400, seed=6)
    path = tmp_path / "t.gpkg"
    counts = store.write_tin(path, model, parse_crs("EPSG:3003"))
    assert {name: pyogrio.read_info(path, layer=name)["features"] for name in LAYERS} == counts
    assert _rows(path, "PRAGMA integrity_check") == [("ok",)]
    assert _rows(path, "SELECT rtreecheck('rtree_edges_geom')") == [("ok",)]


def test_ahead_map_keeps_order_raises_the_error_and_stops():
    import threading
    import time

    from toolbox.io.gpkg_bulk import ahead_map

    def slow_square(k):  # later calls may finish first: the order is the arguments'
        time.sleep(0.002 * (k % 3))
        return k * k

    assert list(ahead_map(slow_square, ((k,) for k in range(50)))) == [k * k for k in range(50)]

    def failing(k):
        if k == 3:
            raise ValueError("boom")
        return k

    items = ahead_map(failing, ((k,) for k in range(10)))
    assert [next(items) for _ in range(3)] == [0, 1, 2]
    with pytest.raises(ValueError, match="boom"):
        next(items)
    made = []

    def endless():
        while True:
            made.append(1)
            yield (len(made),)

    items = ahead_map(lambda k: k, endless(), workers=2, depth=3)
    assert next(items) == 1
    items.close()  # the consumer stops early: the threads end too, nothing more is made
    assert not any(t.name.startswith("gpkg-bulk-encode") and t.is_alive()
                   for t in threading.enumerate())
    assert len(made) <= 4
