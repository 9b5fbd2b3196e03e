"""The TIN GeoPackage: WKB encoding, writing and reading back, with and without pyarrow."""

from __future__ import annotations

import sys

import numpy as np
import pyogrio
import pytest
import shapely
from pyproj import CRS

from toolbox.io.vector import open_layer
from toolbox.terrain.tin.build import build_tin
from toolbox.terrain.tin.store import points_from_wkb, read_tin, wkb_records, write_tin

ORIGIN = np.array([1_688_000.0, 4_799_500.0, 300.0])


@pytest.fixture(scope="module")
def model():
    rng = np.random.default_rng(41)
    pts = ORIGIN + np.column_stack([rng.uniform(0, 60, (150, 2)), rng.normal(0, 2, 150)])
    line = ORIGIN + np.array([[5.0, 5.0, 1.0], [55.0, 50.0, 2.0]])
    return build_tin(pts, line, np.array([0, 0]))


def test_wkb_records_decode_with_shapely():
    coords = np.arange(18, dtype=float).reshape(2, 3, 3)
    polys = shapely.from_wkb([r.tobytes() for r in wkb_records(1003, coords, ring=True)])
    np.testing.assert_array_equal(shapely.get_coordinates(polys[1], include_z=True)[:3], coords[1])
    lines = shapely.from_wkb([r.tobytes() for r in wkb_records(1002, coords[:, :2])])
    assert shapely.get_num_coordinates(lines).tolist() == [2, 2]
    points = wkb_records(1001, coords[:, :1])
    np.testing.assert_array_equal(points_from_wkb(points), coords[:, 0])
    as_objects = np.array([r.tobytes() for r in points], dtype=object)
    np.testing.assert_array_equal(points_from_wkb(as_objects), coords[:, 0])


@pytest.mark.parametrize("arrow", [True, False], ids=["pyarrow", "no-pyarrow"])
def test_write_and_read_back(model, tmp_path, monkeypatch, arrow):
    if not arrow:
        monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow -> ImportError
    path = tmp_path / "tin.gpkg"
    counts = write_tin(path, model, CRS.from_epsg(3003))
    assert counts["triangles"] == len(model.triangles)
    info = pyogrio.read_info(path, layer="edges")
    assert info["features"] == counts["edges"] and info["geometry_type"] == "LineString Z"
    xyz, triangles, crs = read_tin(open_layer(path))
    np.testing.assert_array_equal(xyz, model.xyz)
    np.testing.assert_array_equal(triangles, model.triangles)
    assert crs.to_epsg() == 3003
    frame = pyogrio.read_dataframe(path, layer="triangles")
    assert frame.nbr1.isna().any()  # border triangles have NULL neighbours
    assert int(frame.nbr1.max()) <= len(frame)


def test_edges_layer_can_be_skipped(model, tmp_path):
    path = tmp_path / "lean.gpkg"
    write_tin(path, model, None, spatial_index=False, edges_layer=False)
    assert [row[0] for row in pyogrio.list_layers(path)] == ["triangles", "nodes"]


@pytest.mark.parametrize("suffix", [".gpkg", ".parquet"])
def test_batches_stream_the_same_layers(model, tmp_path, monkeypatch, suffix):
    """Written in batches of 7 features (many batches, a short last one), every layer equals the
    one-batch write, and its geometries are the model's nodes (read back by GDAL/shapely)."""
    import geopandas as gpd

    from toolbox.io.vector_write import layer_paths
    from toolbox.terrain.tin import store

    frames = {}
    for batch in (7, 1 << 16):
        monkeypatch.setattr(store, "BATCH", batch)
        path = tmp_path / f"tin{batch}{suffix}"
        write_tin(path, model, CRS.from_epsg(3003))
        targets = layer_paths(path, ["triangles", "nodes", "edges"])
        frames[batch] = {name: gpd.read_parquet(target) if suffix == ".parquet" else
                         gpd.read_file(target, layer=name) for name, target in targets.items()}
    for name in ("triangles", "nodes", "edges"):
        small, big = frames[7][name], frames[1 << 16][name]
        assert len(small) == len(big) > 7
        assert small.drop(columns="geometry").equals(big.drop(columns="geometry")), name
        assert small.geometry.geom_equals_exact(big.geometry, 0).all()
    tri = frames[7]["triangles"]
    corners = shapely.get_coordinates(tri.geometry.values, include_z=True).reshape(-1, 4, 3)
    ids = tri[["node1", "node2", "node3"]].to_numpy() - 1
    np.testing.assert_array_equal(corners[:, :3], model.xyz[ids])
    np.testing.assert_array_equal(tri.id, np.arange(1, len(tri) + 1))
    # measures computed batch by batch: the plan area is GEOS's area of each written polygon
    np.testing.assert_allclose(tri.area_2d, shapely.area(tri.geometry.values), rtol=1e-9)
    edges = frames[7]["edges"]
    np.testing.assert_allclose(edges.length_2d, shapely.length(edges.geometry.values), rtol=1e-12)
    nodes = frames[7]["nodes"]
    np.testing.assert_array_equal(shapely.get_coordinates(nodes.geometry.values, include_z=True),
                                  model.xyz)
