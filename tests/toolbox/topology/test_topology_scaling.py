"""Topology output helpers at scale: CSR subsets without a per-row loop, the same GeoPackage
layers written through Arrow as feature by feature (issue 31)."""

from __future__ import annotations

import numpy as np

from toolbox.topology.output import subset_csr


def test_subset_csr_known_rows():
    # rows: 0 -> [10, 11], 1 -> [], 2 -> [12, 13, 14], 3 -> [15]
    indptr = np.array([0, 2, 2, 5, 6])
    values = np.array([10, 11, 12, 13, 14, 15])
    ptr, vals = subset_csr(indptr, values, np.array([3, 0, 1, 2]))
    assert ptr.tolist() == [0, 1, 3, 3, 6]
    assert vals.tolist() == [15, 10, 11, 12, 13, 14]
    ptr, vals = subset_csr(indptr, values, np.array([], dtype=np.int64))
    assert ptr.tolist() == [0] and vals.tolist() == []
    ptr, vals = subset_csr(indptr, values, np.array([1]))
    assert ptr.tolist() == [0, 0] and vals.tolist() == []


def _read_all(path, layer):
    import pyogrio
    import shapely

    info = pyogrio.read_info(path, layer=layer)
    frame = pyogrio.read_dataframe(path, layer=layer)
    return (list(info["fields"]), list(info["dtypes"]), info["geometry_type"],
            shapely.to_wkb(frame.geometry.values).tolist(),
            frame.drop(columns="geometry").astype(object).where(frame.notna(), None)
            .values.tolist())


def test_arrow_write_gives_the_feature_by_feature_table(tmp_path):
    """The oracle is GDAL's own feature-by-feature write of the same frames."""
    import geopandas as gpd
    import pandas as pd
    import shapely

    from toolbox.io.vector_write import write_layers

    lines = gpd.GeoDataFrame({
        "id": [1, 2, 3], "codes": ["A;B", "", "C"], "length": [1.5, 2.0, 0.25],
        "n": pd.Series([1, None, 3], dtype="Int64")},
        geometry=[shapely.LineString([(0, 0), (1, 1)]), shapely.LineString([(2, 0), (3, 0)]),
                  shapely.LineString([(5, 5), (6, 7), (8, 8)])], crs="EPSG:3003")
    points = gpd.GeoDataFrame({"id": [1, 2], "detail": ["x", None]},
                              geometry=[shapely.Point(1, 2), None], crs="EPSG:3003")
    # an object column mixing numbers and text has no Arrow type: written feature by feature
    mixed = gpd.GeoDataFrame({"value": pd.Series([1, "a", None], dtype=object)},
                             geometry=[shapely.Point(0, 0)] * 3, crs="EPSG:3003")
    empty = gpd.GeoDataFrame({"id": pd.Series([], dtype="int64")},
                             geometry=gpd.GeoSeries([], crs="EPSG:3003"), crs="EPSG:3003")
    layers = {"lines": lines, "points": points, "mixed": mixed, "empty": empty}
    types = {"lines": "LineString", "points": "Point", "mixed": "Point", "empty": "Polygon"}
    plain = write_layers(tmp_path / "plain.gpkg", layers, geometry_types=types)
    arrow = write_layers(tmp_path / "arrow.gpkg", layers, geometry_types=types, arrow=True)
    for name in layers:
        assert _read_all(arrow, name) == _read_all(plain, name), name


def test_ring_starts_known_rings():
    import shapely

    from toolbox.topology.arcs import _ring_starts

    rings = np.array([
        # free, clockwise, starting at (2, 0): from (0, 0), counter-clockwise
        shapely.LineString([(2, 0), (0, 0), (0, 2), (2, 2), (2, 0)]),
        # attached at (2, 2), counter-clockwise: unchanged
        shapely.LineString([(2, 2), (0, 2), (0, 0), (2, 0), (2, 2)]),
        # attached at (2, 2), clockwise: the same start, counter-clockwise
        shapely.LineString([(2, 2), (2, 0), (0, 0), (0, 2), (2, 2)]),
        # free triangle, counter-clockwise from (1, 1): from its lowest (x, y) vertex (0, 3)
        shapely.LineString([(1, 1), (2, 2), (0, 3), (1, 1)]),
    ], dtype=object)
    out = _ring_starts(rings, 0.001, np.array([True, False, False, True]))
    assert [shapely.get_coordinates(g).tolist() for g in out] == [
        [[0, 0], [2, 0], [2, 2], [0, 2], [0, 0]],
        [[2, 2], [0, 2], [0, 0], [2, 0], [2, 2]],
        [[2, 2], [0, 2], [0, 0], [2, 0], [2, 2]],
        [[0, 3], [1, 1], [2, 2], [0, 3]],
    ]
