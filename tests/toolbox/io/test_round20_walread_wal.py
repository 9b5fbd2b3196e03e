"""A GeoPackage whose -wal GDAL cannot read (no -shm can be created beside it: a read-only
folder) is refused, not read without the log's rows.

GDAL (since 3.5, OSGeo/gdal#6407) then reopens the file with ``IMMUTABLE=YES`` and only warns:
the rows committed to the -wal are silently missing. SQLite itself refuses such a file
("unable to open database file"). The tests run as root, for whom no folder is read-only, so the
-shm that cannot be created is a symbolic link into a folder that does not exist: the same
failure of SQLite's, the same fallback of GDAL's (checked by hand as an unprivileged user in a
folder without write permission: the same warning, 10 rows of 15).
"""

from __future__ import annotations

import hashlib
import shutil
import sqlite3
import warnings
from pathlib import Path

import numpy as np
import pytest

from tests.helpers_cli import cli, one_error
from toolbox.errors import ParameterError
from toolbox.io.vector import open_layer


def _points(n, seed):
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, 300, (2, n)) + [[1_687_000.0], [4_798_500.0]]
    return gpd.GeoDataFrame({"z": rng.uniform(300, 400, n)},
                            geometry=shapely.points(x, y, rng.uniform(300, 400, n)),
                            crs="EPSG:3003")


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _copied_with_wal(work: Path, path: Path, write) -> None:
    """``write(connection)`` commits to ``work``'s -wal only (no checkpoint); the database file
    and its -wal are then copied to ``path`` (a writer's files copied while it had them open)."""
    writer = sqlite3.connect(work)
    try:
        writer.execute("PRAGMA journal_mode=WAL")
        writer.execute("PRAGMA wal_autocheckpoint=0")
        write(writer)
        writer.commit()
        path.parent.mkdir()
        shutil.copy(work, path)
        shutil.copy(f"{work}-wal", f"{path}-wal")
    finally:
        writer.close()


@pytest.fixture
def wal_left_behind(tmp_path) -> Path:
    """10 points in the database file, 5 more committed to its -wal only (a writer's files
    copied while it had them open), and a -shm SQLite cannot create."""
    work = tmp_path / "writer" / "wal.gpkg"
    work.parent.mkdir()
    _points(10, 31).to_file(work, layer="pts", SPATIAL_INDEX="NO")
    extra = _points(5, 7)
    rows = [(float(z), b"GP\x00\x01" + (3003).to_bytes(4, "little") + g.wkb)
            for z, g in zip(extra["z"], extra.geometry, strict=True)]
    path = tmp_path / "input" / "wal.gpkg"
    _copied_with_wal(work, path,
                     lambda db: db.executemany("INSERT INTO pts (z, geom) VALUES (?, ?)", rows))
    # the reference (SQLite): 10 points in the database file alone (immutable: the -wal left
    # out), 15 with its -wal (read from a copy, to leave the input as it is)
    def count(uri):
        con = sqlite3.connect(uri, uri=True)
        try:
            return con.execute("SELECT count(*) FROM pts").fetchone()[0]
        finally:
            con.close()

    assert count(f"file:{path}?mode=ro&immutable=1") == 10
    check = tmp_path / "check" / "wal.gpkg"
    check.parent.mkdir()
    shutil.copy(path, check)
    shutil.copy(f"{path}-wal", f"{check}-wal")
    assert count(f"file:{check}?mode=ro") == 15
    Path(f"{path}-shm").symlink_to(tmp_path / "no such folder" / "wal.gpkg-shm")
    # SQLite itself cannot open it
    with pytest.raises(sqlite3.OperationalError, match="unable to open"):
        sqlite3.connect(f"file:{path}?mode=ro", uri=True).execute("SELECT 1 FROM pts")
    return path


@pytest.mark.parametrize("args", [["vector:info"],
                                  ["dem:idw", "--CELL_SIZE", "20", "--Z_FIELD", "z"]])
def test_the_cli_refuses_a_wal_it_cannot_read(wal_left_behind, tmp_path, args):
    path = wal_left_behind
    before = _digest(path), _digest(Path(f"{path}-wal"))
    extra = ["--OUTPUT", tmp_path / "idw.tif"] if args[0] == "dem:idw" else []
    code, out, err = cli("run", *args, "--INPUT", path, *extra)
    assert code == 2, (out, err)
    line = one_error(err)
    assert line.startswith(f"toolbox: error: INPUT '{path}': its write-ahead log "
                           "'wal.gpkg-wal' (")
    assert "last committed edits would be missing" in line
    assert (_digest(path), _digest(Path(f"{path}-wal"))) == before
    assert not (tmp_path / "idw.tif").exists()


def test_open_layer_names_the_parameter(wal_left_behind):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ParameterError, match=r"^POINTS '.*wal\.gpkg': its write-ahead"):
            open_layer(str(wal_left_behind), "POINTS")


def test_a_raster_geopackage_too(tmp_path):
    """A raster GeoPackage (rasterio's GDAL): a tile rewritten in the -wal only."""
    import rasterio
    from rasterio.transform import from_origin

    from toolbox.io.raster import open_raster_info

    work = tmp_path / "writer" / "dem.gpkg"
    work.parent.mkdir()
    with rasterio.open(work, "w", driver="GPKG", width=512, height=512, count=1, dtype="uint8",
                       crs="EPSG:3003", transform=from_origin(1_687_000, 4_799_000, 1, 1)) as ds:
        ds.write(np.arange(512 * 512, dtype=np.uint32).reshape(1, 512, 512).astype(np.uint8))
    def delete_a_tile(db):
        table = db.execute("SELECT table_name FROM gpkg_contents").fetchone()[0]
        db.execute(f'DELETE FROM "{table}" WHERE tile_column = 0 AND tile_row = 0')

    path = tmp_path / "input" / "dem.gpkg"
    _copied_with_wal(work, path, delete_a_tile)
    Path(f"{path}-shm").symlink_to(tmp_path / "no such folder" / "dem.gpkg-shm")
    before = _digest(path), _digest(Path(f"{path}-wal"))
    with pytest.raises(ParameterError, match=r"^DEM '.*dem\.gpkg': its write-ahead log "
                                             r"'dem\.gpkg-wal' \(\d+ bytes\)"):
        open_raster_info(path, "DEM", "dem")
    assert (_digest(path), _digest(Path(f"{path}-wal"))) == before
