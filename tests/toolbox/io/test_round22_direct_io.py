"""The bulk page writer's O_DIRECT path (toolbox.io.sqlite_pages): the same bytes as through the
page cache, a fallback when the system refuses it, and zeroed free space in its reused buffer.
SQLite itself is the reference (integrity_check, its own inserts of the same rows)."""

from __future__ import annotations

import errno
import os
import sqlite3
import struct

import numpy as np
import pytest

from tests.toolbox.io.test_round21_sqlitepages_btree import batched, integrity, make_db
from toolbox.io import sqlite_pages
from toolbox.io.sqlite_pages import BtreeAppender

N_ROWS = 30_000  # about 6 MB of records: writes of more than the 1 MB direct threshold


def direct_possible(folder) -> bool:
    if not hasattr(os, "O_DIRECT"):
        return False
    probe = folder / "probe"
    probe.write_bytes(b"")
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_DIRECT))
        return True
    except OSError:
        return False
    finally:
        probe.unlink()


def fill_file(path, sizes=(10_000, 3000)):
    """A database with table ``t`` filled by the appender and ``twin`` by SQLite (same rows);
    True when both read back the same."""
    make_db(path, cols="fid INTEGER PRIMARY KEY, a INTEGER, b REAL, d BLOB")
    rng = np.random.default_rng(3)
    a = rng.integers(-(2**40), 2**40, N_ROWS)
    b = rng.normal(size=N_ROWS) * 1e3
    d = np.array([bytes(rng.integers(0, 256, k).astype(np.uint8))
                  for k in rng.integers(100, 200, N_ROWS)], object)
    cols = [None, ("int", a, None), ("real", b, None), ("blob", d, None)]
    rowids = np.arange(1, N_ROWS + 1, dtype=np.int64) * 3
    with BtreeAppender(path) as app:
        app.fill("t", batched(rowids, cols, sizes))
    con = sqlite3.connect(path)
    con.executemany("INSERT INTO twin VALUES (?,?,?,?)", zip(
        rowids.tolist(), a.tolist(), b.tolist(), d.tolist(), strict=True))
    con.commit()
    q = "SELECT *, typeof(a), typeof(b) FROM {} ORDER BY fid"
    same = con.execute(q.format("t")).fetchall() == con.execute(q.format("twin")).fetchall()
    con.close()
    return same


class OpenSpy:
    """Records the flags of os.open calls; refuses O_DIRECT when ``refuse`` is set."""

    def __init__(self, monkeypatch, refuse=False):
        self.flags, self.refuse, self._open = [], refuse, os.open
        monkeypatch.setattr(sqlite_pages.os, "open", self)

    def __call__(self, path, flags, *args, **kwargs):
        self.flags.append(flags)
        if self.refuse and flags & getattr(os, "O_DIRECT", 0):
            raise OSError(errno.EINVAL, "Invalid argument")
        return self._open(path, flags, *args, **kwargs)

    @property
    def direct_opens(self):
        return sum(bool(f & getattr(os, "O_DIRECT", 0)) for f in self.flags)


def test_direct_and_page_cache_paths_write_the_same_bytes(tmp_path, monkeypatch):
    if not direct_possible(tmp_path):
        pytest.skip("this file system takes no O_DIRECT")
    spy = OpenSpy(monkeypatch)
    assert fill_file(tmp_path / "direct.db")
    assert spy.direct_opens == 1  # the large appends went through one O_DIRECT descriptor
    monkeypatch.undo()
    spy = OpenSpy(monkeypatch, refuse=True)
    assert fill_file(tmp_path / "cached.db")
    assert spy.direct_opens == 1  # tried once, refused, then the page cache
    assert (tmp_path / "direct.db").read_bytes() == (tmp_path / "cached.db").read_bytes()
    assert integrity(tmp_path / "direct.db") == ["ok"]


def test_a_write_refused_half_way_continues_through_the_page_cache(tmp_path, monkeypatch):
    if not direct_possible(tmp_path):
        pytest.skip("this file system takes no O_DIRECT")
    real_pwrite, seen = os.pwrite, []
    apps = []
    real_init = BtreeAppender.__init__

    def init(self, path):
        real_init(self, path)
        apps.append(self)

    def pwrite(fd, data, offset):
        direct = apps and fd == apps[0]._direct
        if direct:
            seen.append(offset)
            if len(seen) == 2:  # the second direct write fails as on a file system that
                raise OSError(errno.EINVAL, "Invalid argument")  # refuses it late
        return real_pwrite(fd, data, offset)

    monkeypatch.setattr(BtreeAppender, "__init__", init)
    monkeypatch.setattr(sqlite_pages.os, "pwrite", pwrite)
    assert fill_file(tmp_path / "late.db")
    assert len(seen) == 2  # no direct write after the refusal (three were due)
    assert integrity(tmp_path / "late.db") == ["ok"]


def test_reused_page_buffer_leaves_free_space_zeroed(tmp_path):
    """Batches of very different record sizes reuse one buffer: every page's free space (between
    the cell pointers and the cell content) must be zeros, not a previous batch's bytes."""
    path = tmp_path / "z.db"
    make_db(path, tables=("t",), cols="fid INTEGER PRIMARY KEY, d BLOB")
    rng = np.random.default_rng(5)
    big = np.array([bytes(rng.integers(1, 256, 3000).astype(np.uint8))] * 600, object)
    small = np.array([b"\x01"] * 600, object)
    batches = [(np.arange(1, 601) + k * 600, *sqlite_pages.encode_records(
        [None, ("blob", d, None)], 600)) for k, d in enumerate([big, small, big, small])]
    with BtreeAppender(path) as app:
        app.fill("t", batches)
    assert integrity(path) == ["ok"]
    data = path.read_bytes()
    con = sqlite3.connect(path)
    leaves = [r[0] for r in con.execute(
        "SELECT pageno FROM dbstat WHERE name = 't' AND pagetype = 'leaf'")]
    con.close()
    assert len(leaves) > 600
    for pgno in leaves:
        page = data[(pgno - 1) * 4096: pgno * 4096]
        assert page[0] == 0x0D
        ncells, content = struct.unpack(">HH", page[3:7])
        free = page[8 + 2 * ncells: content or 65536]
        assert free == bytes(len(free)), pgno


def test_a_failed_write_in_flight_restores_the_file(tmp_path, monkeypatch):
    """New pages are written on a thread of their own while the next are laid out: a disk-full
    error there reaches fill(), and the file is put back byte for byte (no write lands after
    the truncation), the writing thread ended."""
    import hashlib
    import threading

    path = tmp_path / "full.db"
    make_db(path, cols="fid INTEGER PRIMARY KEY, a INTEGER, b REAL, d BLOB")
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    rng = np.random.default_rng(7)
    d = np.array([bytes(rng.integers(0, 256, 150).astype(np.uint8))] * N_ROWS, object)
    cols = [None, ("int", np.arange(N_ROWS), None), ("real", rng.normal(size=N_ROWS), None),
            ("blob", d, None)]
    rowids = np.arange(1, N_ROWS + 1, dtype=np.int64)
    real_pwrite, calls = os.pwrite, []

    def pwrite(fd, data, offset):
        if threading.current_thread().name.startswith("sqlite-pages-write"):
            calls.append(offset)
            if len(calls) == 3:
                raise OSError(errno.ENOSPC, "No space left on device")
        return real_pwrite(fd, data, offset)

    monkeypatch.setattr(sqlite_pages.os, "pwrite", pwrite)
    with pytest.raises(OSError, match="No space left"):
        with BtreeAppender(path) as app:
            app.fill("t", batched(rowids, cols, (2000,)))
    assert len(calls) >= 3
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before
    assert not any(t.name.startswith("sqlite-pages-write") and t.is_alive()
                   for t in threading.enumerate())
    assert integrity(path) == ["ok"]
