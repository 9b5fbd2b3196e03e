"""Vertices gathered once per batch of triangles (toolbox.terrain.tin.topology.triangle_corners)
and whole-vertex WKB copies (toolbox.terrain.tin.store): checked against shapely's decoding and
areas, and numpy's fancy indexing."""

from __future__ import annotations

import numpy as np
import shapely

from toolbox.terrain.tin.store import wkb_records
from toolbox.terrain.tin.topology import triangle_areas, triangle_corners


def cloud(n=500, seed=4):
    rng = np.random.default_rng(seed)
    xyz = np.c_[rng.uniform(0, 100, (n, 2)) + [1_688_000.0, 4_799_500.0], rng.normal(300, 5, n)]
    return xyz, rng.integers(0, n, (900, 3))


def test_wkb_of_gathered_corners_decodes_to_the_nodes_coordinates():
    """The writer's path: corners gathered once (triangle_corners, np.take), then WKB."""
    xyz, nodes = cloud()
    wide = np.zeros((len(xyz), 5))
    wide[:, 1:4] = xyz
    strided = wide[:, 1:4]  # not contiguous
    corners = triangle_corners(strided, nodes)
    rings = shapely.from_wkb([r.tobytes() for r in wkb_records(1003, corners, True)])
    got = shapely.get_coordinates(rings, include_z=True).reshape(-1, 4, 3)
    np.testing.assert_array_equal(got[:, :3], xyz[nodes])
    np.testing.assert_array_equal(got[:, 3], xyz[nodes[:, 0]])
    ends = np.take(xyz, nodes[:, :2], axis=0)
    lines = shapely.from_wkb([r.tobytes() for r in wkb_records(1002, ends)])
    np.testing.assert_array_equal(
        shapely.get_coordinates(lines, include_z=True).reshape(-1, 2, 3), xyz[nodes[:, :2]])


def test_triangle_corners_and_areas_match_fancy_indexing_and_shapely():
    xyz, tri = cloud()
    np.testing.assert_array_equal(triangle_corners(xyz, tri), xyz[tri])
    flat, space = triangle_areas(xyz, tri)
    polygons = shapely.polygons(xyz[tri][:, :, :2] - xyz[:, :2].min(axis=0))
    np.testing.assert_allclose(flat, shapely.area(polygons), rtol=1e-9, atol=1e-9)
    p = xyz[tri]  # Heron-free 3D area: half the cross product's length, by hand
    u, w = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    cross = np.stack([u[:, 1] * w[:, 2] - u[:, 2] * w[:, 1], u[:, 2] * w[:, 0] - u[:, 0] * w[:, 2],
                      u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]], axis=1)
    np.testing.assert_allclose(space, np.sqrt((cross ** 2).sum(axis=1)) / 2, rtol=1e-12)


def test_bulk_edges_layer_lets_its_edge_table_go_before_the_rtree(tmp_path, monkeypatch):
    """10 M points peaked while the edges' R-tree was packed with the 30 M-edge table alive:
    in bulk, no edge table of the TIN is referenced any more then (gc's view)."""
    import gc

    from toolbox.io import gpkg_bulk
    from toolbox.io.crs import parse_crs
    from toolbox.terrain.tin import store
    from toolbox.terrain.tin.build import build_tin
    from toolbox.terrain.tin.topology import EdgeTable

    xyz, _ = cloud(2000)
    model = build_tin(xyz)
    alive = {}
    packed = gpkg_bulk.packed_rtree_stored

    def spy(ids, boxes32, page_size=4096):
        gc.collect()
        alive[len(ids)] = sum(isinstance(o, EdgeTable) for o in gc.get_objects())
        return packed(ids, boxes32, page_size)

    monkeypatch.setattr(gpkg_bulk, "packed_rtree_stored", spy)
    counts = store.write_tin(tmp_path / "t.gpkg", model, parse_crs("EPSG:3003"))
    assert set(alive) == {counts["triangles"], counts["nodes"], counts["edges"]}
    assert alive[counts["edges"]] == 0


def test_the_model_keeps_the_triangulations_int32_arrays_and_writes_the_same_tin(tmp_path):
    """Round twenty-three: build_tin no longer widens CDT's triangles and neighbours to int64
    (96 MB of new memory at 1 M points; the 10 M run's peak 3.82 -> 3.23 GB). The GeoPackage
    written from the int32 model has the rows of the same model in int64."""
    import dataclasses
    import sqlite3

    from toolbox.io.crs import parse_crs
    from toolbox.terrain.tin import store
    from toolbox.terrain.tin.build import build_tin

    xyz, _ = cloud(3000)
    model = build_tin(xyz)
    assert model.triangles.dtype == np.int32 and model.neighbors.dtype == np.int32
    wide = dataclasses.replace(model, triangles=model.triangles.astype(np.int64),
                               neighbors=model.neighbors.astype(np.int64))
    crs = parse_crs("EPSG:3003")
    store.write_tin(tmp_path / "narrow.gpkg", model, crs)
    store.write_tin(tmp_path / "wide.gpkg", wide, crs)
    for layer in ("triangles", "nodes", "edges"):
        rows = []
        for name in ("narrow", "wide"):
            with sqlite3.connect(tmp_path / f"{name}.gpkg") as db:
                rows.append(db.execute(f'SELECT * FROM "{layer}" ORDER BY fid').fetchall())
        assert len(rows[0]) > 1000 and rows[0] == rows[1], layer
