"""Round 16, files: open files, concurrent runs and file names at the staging/commit layer.

Each test failed before its fix: an input rewritten during a run gave an output mixing both
versions (exit 0); two runs committing the same Shapefile at once left the ``.shp`` of one with
the ``.shx``/``.dbf`` of the other (exit 0, a corrupt file); a valid 233-255-byte output name
was refused as "file name too long" (the staging folder's name was longer than the file's).
"""

from __future__ import annotations

import errno
import fcntl
import os
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

import toolbox
import toolbox.io.staging as staging_mod
from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.io.staging import OutputStaging, final_folder, stale_staging_folders


def _dem(path, slope=1.0, n=64):
    x, y = np.meshgrid(np.arange(n), np.arange(n))
    z = (100 + slope * (0.5 * x + 0.2 * y) + 10 * np.sin(x / 7.0)).astype("float32")
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs="EPSG:32632", transform=from_origin(500000, 5000640, 10, 10),
                       nodata=-9999) as dst:
        dst.write(z, 1)
    return z


# -- 1. an input written by another program during the run: refused, nothing written -----------
def _run_changing_input(tmp_path, change):
    dem = tmp_path / "dem.tif"
    _dem(dem)
    done = []

    def progress(percent, message):
        if percent > 40 and not done:
            done.append(True)
            change(dem)

    params = {"INPUT": str(dem), "OUTPUT": str(tmp_path / "hs.tif"), "TILE_SIZE": 16,
              "OVERVIEWS": False}
    try:
        return toolbox.run("dem:hillshade", params, feedback=Feedback(progress))
    finally:
        assert done  # the change did happen during the run


def _edit_in_place(dem):
    new = dem.with_name("new.tif")
    values = _dem(new, slope=5.0)
    with rasterio.open(dem, "r+") as dst:  # QGIS' raster editing, gdal_fillnodata in place...
        dst.write(values, 1)


def test_input_written_in_place_during_the_run_is_refused(tmp_path):
    with pytest.raises(ParameterError, match=r"^INPUT .*dem\.tif' was written by another "
                       "program while the run read it"):
        _run_changing_input(tmp_path, _edit_in_place)
    assert not (tmp_path / "hs.tif").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif", "new.tif"]  # no staging


def test_input_replaced_during_the_run_is_refused(tmp_path):
    def replace(dem):
        _dem(dem.with_name("new.tif"), slope=5.0)
        os.replace(dem.with_name("new.tif"), dem)

    with pytest.raises(ParameterError, match="^INPUT .* while the run read it"):
        _run_changing_input(tmp_path, replace)
    assert not (tmp_path / "hs.tif").exists()


def test_a_pam_file_gdal_writes_beside_an_input_is_no_change(tmp_path):
    def statistics(dem):  # GDAL writes dem.tif.aux.xml itself (statistics, QGIS' histogram)
        dem.with_name("dem.tif.aux.xml").write_text("<PAMDataset/>\n")
        dem.with_name("dem.tif.ovr").write_bytes(b"")  # and QGIS builds overviews

    out = _run_changing_input(tmp_path, statistics)
    assert os.path.isfile(out["OUTPUT"])


# -- 2. two runs committing the same files at once: one's files, never a mix --------------------
def _stage(folder, letter):
    staging = OutputStaging()
    shp = staging.stage(folder / "c.shp")
    for suffix in (".shp", ".shx", ".dbf"):
        shp.with_suffix(suffix).write_text(letter)
    return staging


def test_concurrent_commits_of_the_same_shapefile_do_not_interleave(tmp_path, monkeypatch):
    for suffix in (".shp", ".shx", ".dbf"):
        (tmp_path / f"c{suffix}").write_text("old")
    a, b = _stage(tmp_path, "A"), _stage(tmp_path, "B")
    a_moving = threading.Event()
    backup = staging_mod._backup

    def slow_backup(target, folder, key):  # a slow share: A's commit takes a while
        if threading.current_thread().name == "A" and key == 1:
            a_moving.set()
            time.sleep(0.5)
        return backup(target, folder, key)

    monkeypatch.setattr(staging_mod, "_backup", slow_backup)
    thread = threading.Thread(target=a.commit, name="A")
    thread.start()
    assert a_moving.wait(5)
    b.commit()  # B waits for A's commit to end, then replaces all of A's files
    thread.join()
    contents = {p.suffix: p.read_text() for p in tmp_path.iterdir() if p.is_file()}
    assert contents == {".shp": "B", ".shx": "B", ".dbf": "B"}
    assert not [p for p in tmp_path.iterdir() if p.is_dir()]


def test_a_commit_held_up_too_long_is_refused_naming_the_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(staging_mod, "COMMIT_WAIT", 0.2)
    staging = _stage(tmp_path, "A")
    fd = os.open(tmp_path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # another run's commit into the folder
        with pytest.raises(ParameterError, match="^OUTPUT another run .* into '.*' for 0 s"):
            staging.commit()
    finally:
        os.close(fd)
        staging.rollback()
    assert [p.name for p in tmp_path.iterdir()] == []


# -- 3. a long but valid output name (its staging folder's name would be longer) ----------------
@pytest.mark.parametrize("stem", ["b" * 246, "é" * 123])  # 250-byte names
def test_output_name_of_250_bytes_is_written(tmp_path, stem):
    _dem(tmp_path / "dem.tif")
    out = tmp_path / f"{stem}.tif"
    result = toolbox.run("dem:hillshade", {"INPUT": str(tmp_path / "dem.tif"),
                                           "OUTPUT": str(out)})
    assert result["OUTPUT"] == str(out) and out.is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["dem.tif", out.name])


def test_long_name_staging_folders_are_found_again(tmp_path):
    final = tmp_path / ("é" * 123 + ".tif")
    staging = OutputStaging()
    staged = staging.stage(final)
    assert len(os.fsencode(staged.parent.name)) <= 255
    assert final_folder(staged) == tmp_path
    dead = staged.parent.name.replace(f".{os.getpid()}-", ".4194305-")  # above pid_max
    os.rename(staged.parent, tmp_path / dead)
    assert [p.name for p in stale_staging_folders(final)] == [dead]
    staging.rollback()


# -- 4. an existing, writable output folder in a read-only folder (a share) ---------------------
def test_folder_output_whose_parent_is_read_only_is_staged_inside_it(tmp_path, monkeypatch):
    _dem(tmp_path / "dem.tif")
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    mkdtemp = tempfile.mkdtemp

    def read_only_parent(*args, dir=None, **kwargs):  # EROFS there, as on a read-only share
        if dir is not None and Path(dir) == tmp_path:
            raise OSError(errno.EROFS, "Read-only file system", str(dir))
        return mkdtemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkdtemp", read_only_parent)
    toolbox.run("mosaic:cut", {"INPUT": str(tmp_path / "dem.tif"), "SCALE": 1000,
                               "SHEET_WIDTH": 30, "SHEET_HEIGHT": 30, "OUTPUT": str(out)})
    names = sorted(p.name for p in out.iterdir())
    assert "notes.txt" in names and "sheets.gpkg" in names
    assert len([n for n in names if n.endswith(".tif")]) >= 4  # 640 m square, 300 m sheets
    assert not [n for n in names if n.startswith(".")]  # no staging folder left in it
