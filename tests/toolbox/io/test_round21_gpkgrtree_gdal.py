"""A GeoPackage whose spatial index holds a packed R-tree (toolbox.io.sqlite_rtree) in place of
the one GDAL built: GDAL (pyogrio's, and the system's ``ogrinfo``) filters by bbox through it and
finds the features shapely's STRtree finds, and the same as with GDAL's own index."""

from __future__ import annotations

import re
import shutil
import sqlite3
import subprocess
from contextlib import closing

import numpy as np
import pytest

from toolbox.io.sqlite_rtree import insert_rtree_rows, packed_rtree

OGRINFO = shutil.which("ogrinfo") or "/usr/bin/ogrinfo"
X0, Y0 = 1_688_000.0, 4_799_500.0


def _triangles(tmp_path):
    import geopandas as gpd
    import pyogrio
    import shapely
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(5)
    pts = rng.random((1500, 2)) * [900.0, 700.0]
    tri = Delaunay(pts).simplices
    xy = pts[tri] + [X0, Y0]
    geoms = shapely.polygons(np.concatenate([xy, xy[:, :1]], axis=1))
    path = tmp_path / "tin.gpkg"
    frame = gpd.GeoDataFrame({"k": np.arange(len(geoms))}, geometry=geoms, crs="EPSG:3003")
    pyogrio.write_dataframe(frame, path, layer="tri", driver="GPKG",
                            layer_options={"SPATIAL_INDEX": "YES"})
    return path


def _bbox_fids(path, bbox) -> list[int]:
    import pyogrio

    frame = pyogrio.read_dataframe(path, layer="tri", bbox=bbox, fid_as_index=True)
    return sorted(frame.index.tolist())


def _ogrinfo_fids(path, bbox) -> list[int]:
    out = subprocess.run([OGRINFO, "-ro", "-q", "-spat", *(repr(float(v)) for v in bbox), str(path), "tri"],
                         capture_output=True, text=True, check=True).stdout
    return sorted(int(f) for f in re.findall(r"OGRFeature\(tri\):(\d+)", out))


def _windows(rng, count):
    for _ in range(count):
        w, h = rng.uniform(5.0, 150.0, 2)
        x, y = X0 + rng.uniform(-20, 900), Y0 + rng.uniform(-20, 700)
        yield (x, y, x + w, y + h)


def test_gdal_filters_through_a_packed_index_as_through_its_own(tmp_path):
    import pyogrio
    import shapely

    path = _triangles(tmp_path)
    frame = pyogrio.read_dataframe(path, layer="tri", fid_as_index=True)
    fids = frame.index.to_numpy(np.int64)
    geoms = frame.geometry.values
    tree = shapely.STRtree(geoms)
    windows = list(_windows(np.random.default_rng(8), 25))
    gdal_own = [_bbox_fids(path, w) for w in windows]

    with closing(sqlite3.connect(path)) as db:
        (geom_column,) = db.execute("SELECT column_name FROM gpkg_geometry_columns WHERE "
                                    "table_name = 'tri'").fetchone()
        name = f"rtree_tri_{geom_column}"
        page_size = db.execute("PRAGMA page_size").fetchone()[0]
        gdal_nodes = db.execute(f"SELECT count(*) FROM {name}_node").fetchone()[0]
        bounds = shapely.bounds(geoms)  # minx, miny, maxx, maxy
        rows = packed_rtree(fids, bounds[:, 0], bounds[:, 2], bounds[:, 1], bounds[:, 3],
                            page_size=page_size)
        with db:
            insert_rtree_rows(db, name, rows, replace=True)
        assert db.execute("SELECT rtreecheck(?)", (name,)).fetchone()[0] == "ok"
        ours = db.execute(f"SELECT nodeno, data FROM {name}_node ORDER BY nodeno").fetchall()
    # the index is ours now (fewer, fuller nodes than GDAL's insert-built tree)
    assert len(ours) == len(rows.node_numbers) < gdal_nodes
    assert [bytes(b) for _, b in ours] == [b.tobytes() for b in rows.node_blobs]

    for w, own in zip(windows, gdal_own):
        expected = sorted(fids[tree.query(shapely.box(*w), predicate="intersects")].tolist())
        assert expected, w
        assert _bbox_fids(path, w) == expected == own, w
    for w in windows[:4]:
        expected = sorted(fids[tree.query(shapely.box(*w), predicate="intersects")].tolist())
        assert _ogrinfo_fids(path, w) == expected, w


@pytest.mark.skipif(not shutil.which(OGRINFO), reason="no ogrinfo on this machine")
def test_ogrinfo_validates_the_packed_index(tmp_path):
    """GDAL's own checks of a GeoPackage (``ogrinfo`` reads the rtree's extent and counts)."""
    import pyogrio
    import shapely

    path = _triangles(tmp_path)
    frame = pyogrio.read_dataframe(path, layer="tri", fid_as_index=True)
    bounds = shapely.bounds(frame.geometry.values)
    with closing(sqlite3.connect(path)) as db, db:
        (geom_column,) = db.execute("SELECT column_name FROM gpkg_geometry_columns").fetchone()
        insert_rtree_rows(db, f"rtree_tri_{geom_column}",
                          packed_rtree(frame.index.to_numpy(np.int64), bounds[:, 0],
                                       bounds[:, 2], bounds[:, 1], bounds[:, 3]),
                          replace=True)
    out = subprocess.run([OGRINFO, "-ro", "-so", "-al", str(path)], capture_output=True,
                         text=True, check=True)
    assert f"Feature Count: {len(frame)}" in out.stdout
    assert "ERROR" not in out.stderr
    sql = subprocess.run([OGRINFO, "-ro", "-q", str(path), "-sql",
                          f"SELECT count(*) AS n FROM rtree_tri_{geom_column}"],
                         capture_output=True, text=True, check=True).stdout
    assert re.search(rf"n \(Integer\) = {len(frame)}\b", sql), sql
