"""toolbox.io.sqlite_pages: records and table B-trees written straight into a closed SQLite file,
checked against SQLite itself (``PRAGMA integrity_check``, and the same rows inserted into a twin
table with ``executemany``, values and ``typeof`` compared)."""

from __future__ import annotations

import hashlib
import math
import sqlite3

import numpy as np
import pytest

from toolbox.io.sqlite_pages import BtreeAppender, UnsupportedDatabase, encode_records

COLS = "fid INTEGER PRIMARY KEY, a INTEGER, b REAL, c TEXT, d BLOB, e"
SELECT = ("SELECT fid, a, typeof(a), b, typeof(b), c, typeof(c), d, typeof(d), e, typeof(e) "
          "FROM {} ORDER BY fid")


def make_db(path, page_size=4096, tables=("t", "twin"), cols=COLS, pragmas=()):
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA page_size={page_size}")
    for p in pragmas:
        con.execute(p)
    for t in tables:
        con.execute(f"CREATE TABLE {t}({cols})")
    con.commit()
    con.close()


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def integrity(path):
    con = sqlite3.connect(path)
    try:
        return [r[0] for r in con.execute("PRAGMA integrity_check")]
    finally:
        con.close()


def depth(path, table):
    con = sqlite3.connect(path)
    try:
        paths = [r[0] for r in con.execute("SELECT path FROM dbstat WHERE name = ?", (table,))]
    finally:
        con.close()
    return max(p.count("/") for p in paths)


def assert_same_as_twin(con, path, select="*"):
    """Commit the twin's rows, compare ``SELECT select`` of ``t`` (filled by the appender) with
    the ``twin`` (filled by SQLite), close, and check the file's integrity."""
    con.commit()
    q = f"SELECT {select} FROM {{}} ORDER BY fid"
    assert con.execute(q.format("t")).fetchall() == con.execute(q.format("twin")).fetchall()
    con.close()
    assert integrity(path) == ["ok"]


def mixed_rows(n, seed=0):
    """Columns for COLS with every kind of value, and the same rows as Python tuples."""
    rng = np.random.default_rng(seed)
    a = rng.integers(-(2**62), 2**62, n)
    a[: min(n, 6)] = [0, -1, 2**63 - 1, -(2**63), 127, -129][: min(n, 6)]
    am = rng.random(n) < 0.2
    b = rng.normal(size=n) * 1e3
    specials = [math.nan, math.inf, -math.inf, -0.0, 0.0, 1.5]
    b[: min(n, 6)] = specials[: min(n, 6)]
    bm = rng.random(n) < 0.1
    words = ["", "x", "été", "日本語テキスト", "a" * 300, "\u0000z", "plain"]
    c = np.array([words[i % len(words)] for i in rng.integers(0, 1000, n)], object)
    cm = rng.random(n) < 0.1
    d = np.array([bytes(rng.integers(0, 256, k).astype(np.uint8)) for k in
                  rng.integers(0, 40, n)], object)
    d[::5] = b""
    e = rng.random(n) < 0.5
    em = rng.random(n) < 0.1
    cols = [None, ("int", a, am), ("real", b, bm), ("text", c, cm), ("blob", d, None),
            ("bool", e, em)]
    rows = [(None if am[i] else int(a[i]), None if bm[i] else float(b[i]),
             None if cm[i] else c[i], d[i], None if em[i] else bool(e[i])) for i in range(n)]
    return cols, rows


def slice_cols(cols, sl):
    out = []
    for spec in cols:
        if spec is None:
            out.append(None)
        else:
            kind, v, m = spec
            out.append((kind, v[sl], None if m is None else m[sl]))
    return out


def batched(rowids, cols, sizes):
    """(rowids, flat, offsets) batches of the given sizes (cycled) over all rows."""
    out = []
    i = 0
    k = 0
    while i < len(rowids):
        s = sizes[k % len(sizes)]
        sl = slice(i, i + s)
        part = rowids[sl]
        out.append((part, *encode_records(slice_cols(cols, sl), len(part))))
        i += s
        k += 1
    return out


def fill_and_twin(path, rowids, cols, rows, sizes=(1000,), table="t", twin="twin"):
    with BtreeAppender(path) as app:
        assert app.fill(table, batched(rowids, cols, sizes)) == len(rowids)
    con = sqlite3.connect(path)
    con.executemany(f"INSERT INTO {twin} VALUES (?,?,?,?,?,?)",
                    [(int(r), *row) for r, row in zip(rowids, rows)])
    con.commit()
    got = con.execute(SELECT.format(table)).fetchall()
    want = con.execute(SELECT.format(twin)).fetchall()
    con.close()
    return got, want


def test_every_kind_of_value_reads_back_as_sqlite_stores_it(tmp_path):
    path = tmp_path / "a.db"
    make_db(path)
    cols, rows = mixed_rows(500)
    rowids = np.arange(1, 501)
    got, want = fill_and_twin(path, rowids, cols, rows, sizes=(37, 200, 1))
    assert integrity(path) == ["ok"]
    assert got == want
    assert got[3][3] == 0.0 and math.copysign(1, got[3][3]) == -1  # -0.0 kept
    assert got[0][3] is None  # NaN reads as NULL, as SQLite stores it


@pytest.mark.parametrize("page_size, n, levels", [
    (4096, 10, 1), (4096, 150, 2), (512, 3000, 3), (512, 60000, 4), (1024, 3000, 3),
    (65536, 2000, 2)])
def test_tree_depths(tmp_path, page_size, n, levels):
    path = tmp_path / "d.db"
    make_db(path, page_size)
    cols, rows = mixed_rows(n, seed=n)
    cols[3] = ("text", np.array([s[:20] for s in cols[3][1]], object), cols[3][2])
    rows = [(r[0], r[1], None if r[2] is None else r[2][:20], r[3], r[4]) for r in rows]
    got, want = fill_and_twin(path, np.arange(5, 5 + n) * 3, cols, rows, sizes=(n // 3 + 1,))
    assert integrity(path) == ["ok"]
    assert depth(path, "t") == levels
    assert got == want


def test_rowids_across_varint_lengths_gaps_and_one_row_batches(tmp_path):
    path = tmp_path / "r.db"
    make_db(path, 1024)
    rowids = np.unique(np.concatenate([
        [-(2**63), -(2**40), -5, 0, 2, 3], np.arange(120, 135), np.arange(16380, 16390),
        np.arange(2**21 - 5, 2**21 + 5), np.arange(2**28 - 3, 2**28 + 3), [2**35],
        np.arange(2**40, 2**40 + 200), np.arange(2**56 - 2, 2**56 + 2), [2**63 - 1]]))
    n = rowids.size
    cols, rows = mixed_rows(n, seed=3)
    got, want = fill_and_twin(path, rowids, cols, rows, sizes=(1, 1, 7, 1, 64, 3))
    assert integrity(path) == ["ok"]
    assert got == want
    assert [r[0] for r in got] == rowids.tolist()


def test_several_tables_beside_data_and_freelist_then_normal_sql(tmp_path):
    path = tmp_path / "m.db"
    make_db(path, 1024, tables=("t", "twin", "t2", "twin2", "old"))
    con = sqlite3.connect(path)
    con.execute("CREATE INDEX old_a ON old(a)")
    con.executemany("INSERT INTO old VALUES (?,?,?,?,?,?)",
                    [(None, i, i * 0.5, f"r{i}", b"x" * (i % 50), i) for i in range(6000)])
    con.commit()
    con.execute("DELETE FROM old WHERE fid % 3 != 0")
    con.commit()
    assert con.execute("PRAGMA freelist_count").fetchone()[0] > 0
    con.close()
    cols, rows = mixed_rows(3000, seed=7)
    cols2, rows2 = mixed_rows(800, seed=8)
    r1 = np.arange(10, 3010) * 2
    r2 = np.arange(1, 801) + 2**33
    with BtreeAppender(path) as app:
        app.fill("t", batched(r1, cols, (700,)))
        app.fill("T2", batched(r2, cols2, (333,)))  # names as SQLite matches them
    assert integrity(path) == ["ok"]
    con = sqlite3.connect(path)
    con.executemany("INSERT INTO twin VALUES (?,?,?,?,?,?)",
                    [(int(r), *row) for r, row in zip(r1, rows)])
    con.executemany("INSERT INTO twin2 VALUES (?,?,?,?,?,?)",
                    [(int(r), *row) for r, row in zip(r2, rows2)])
    con.commit()
    for t, tw in (("t", "twin"), ("t2", "twin2")):
        assert con.execute(SELECT.format(t)).fetchall() == con.execute(SELECT.format(tw)
                                                                        ).fetchall()
    # untouched: fid = a + 1, the rows of fid 3, 6, ... kept
    assert con.execute("SELECT count(*), sum(a) FROM old").fetchone() == (
        2000, sum(range(2, 6000, 3)))
    # the filled tables take ordinary writes afterwards
    con.executemany("INSERT INTO t(a, c) VALUES (?, ?)", [(i, "new") for i in range(4000)])
    con.execute("UPDATE t SET c = 'upd', d = zeroblob(100) WHERE fid % 7 = 0")
    con.execute("DELETE FROM t WHERE fid % 5 = 0")
    con.execute("DELETE FROM t2 WHERE fid > ?", (2**33 + 400,))
    con.commit()
    con.execute("VACUUM")
    con.close()
    assert integrity(path) == ["ok"]
    con = sqlite3.connect(path)
    assert con.execute("SELECT count(*) FROM t2").fetchone()[0] == 400
    assert con.execute("SELECT count(*) FROM t WHERE c = 'new'").fetchone()[0] == len(
        [f for f in range(6019, 6019 + 4000) if f % 5 and f % 7])  # after the largest, 6018
    con.close()


def test_empty_batches_leave_the_table_empty(tmp_path):
    path = tmp_path / "e.db"
    make_db(path)
    with BtreeAppender(path) as app:
        assert app.fill("t", []) == 0
        assert app.fill("twin", [(np.zeros(0, np.int64), *encode_records([None, None], 0))]) == 0
    assert integrity(path) == ["ok"]
    con = sqlite3.connect(path)
    assert con.execute("SELECT count(*) FROM t").fetchone() == (0,)
    con.close()


def test_fixed_size_blobs_and_uniform_rows(tmp_path):
    path = tmp_path / "f.db"
    make_db(path, 4096, cols="fid INTEGER PRIMARY KEY, a INTEGER, b REAL, g BLOB",
            tables=("t", "twin"))
    n = 20000
    rng = np.random.default_rng(5)
    a = rng.integers(0, 70000, n)
    b = rng.normal(size=n)
    g = rng.integers(0, 256, (n, 149)).astype(np.uint8)
    rowids = np.arange(1, n + 1)
    cols = [None, ("int", a, None), ("real", b, None), ("blob", g, None)]
    flat, offsets = encode_records(cols, n)
    assert np.all(np.diff(offsets) == offsets[1])  # one layout: fixed-size records
    with BtreeAppender(path) as app:
        app.fill("t", [(rowids[:5000], *encode_records(slice_cols(cols, slice(0, 5000)), 5000)),
                       (rowids[5000:], *encode_records(slice_cols(cols, slice(5000, n)),
                                                       n - 5000))])
    con = sqlite3.connect(path)
    con.executemany("INSERT INTO twin VALUES (?,?,?,?)",
                    [(i + 1, int(a[i]), float(b[i]), g[i].tobytes()) for i in range(n)])
    assert_same_as_twin(con, path, "fid, a, typeof(a), b, g")


def test_an_exception_in_the_block_restores_the_file(tmp_path):
    path = tmp_path / "x.db"
    make_db(path, 1024)
    before = digest(path)
    cols, _rows = mixed_rows(3000)
    with pytest.raises(RuntimeError), BtreeAppender(path) as app:
        app.fill("t", batched(np.arange(1, 3001), cols, (500,)))
        app.fill("twin", batched(np.arange(1, 11), slice_cols(cols, slice(0, 10)), (5,)))
        raise RuntimeError("caller failed")
    assert digest(path) == before


# -- refusals: each raises UnsupportedDatabase and leaves the file byte-identical ---------------


def _refused(path, table="t", batches=None, match=None):
    before = digest(path)
    if batches is None:
        cols, _rows = mixed_rows(50)
        batches = batched(np.arange(1, 51), cols, (20,))
    with pytest.raises(UnsupportedDatabase, match=match), BtreeAppender(path) as app:
        app.fill(table, batches)
    assert digest(path) == before


def test_refuses_wal_mode(tmp_path):
    path = tmp_path / "w.db"
    make_db(path, pragmas=("PRAGMA journal_mode=WAL",))
    _refused(path, match="WAL")


def test_refuses_auto_vacuum(tmp_path):
    for mode in ("FULL", "INCREMENTAL"):
        path = tmp_path / f"v{mode}.db"
        make_db(path, pragmas=(f"PRAGMA auto_vacuum={mode}",))
        _refused(path, match="auto_vacuum")


def test_refuses_utf16(tmp_path):
    path = tmp_path / "u.db"
    make_db(path, pragmas=("PRAGMA encoding='UTF-16le'",))
    _refused(path, match="encoding")


def test_refuses_a_non_empty_table(tmp_path):
    path = tmp_path / "n.db"
    make_db(path)
    con = sqlite3.connect(path)
    con.execute("INSERT INTO t(a) VALUES (1)")
    con.commit()
    con.close()
    _refused(path, match="not an empty")


def test_refuses_decreasing_rowids_after_pages_were_written(tmp_path):
    path = tmp_path / "o.db"
    make_db(path, 1024)
    cols, _rows = mixed_rows(2000)
    good = batched(np.arange(1000, 3000), cols, (900,))
    bad = batched(np.array([5, 6]), slice_cols(cols, slice(0, 2)), (2,))
    _refused(path, batches=good + bad, match="increasing")
    within = batched(np.array([1, 3, 2]), slice_cols(cols, slice(0, 3)), (3,))
    _refused(path, batches=within, match="increasing")
    equal = batched(np.array([1, 1]), slice_cols(cols, slice(0, 2)), (2,))
    _refused(path, batches=equal, match="increasing")


def test_refuses_a_journal_beside_it(tmp_path):
    path = tmp_path / "j.db"
    make_db(path)
    (tmp_path / "j.db-journal").write_bytes(b"")
    _refused(path, match="-journal")


def test_refuses_a_table_with_an_index(tmp_path):
    for ddl in ("CREATE INDEX t_a ON t(a)", "CREATE UNIQUE INDEX t_c ON t(c)"):
        path = tmp_path / f"i{len(ddl)}.db"
        make_db(path)
        con = sqlite3.connect(path)
        con.execute(ddl)
        con.commit()
        con.close()
        _refused(path, match="index")
    path = tmp_path / "uniq.db"
    make_db(path, cols="fid INTEGER PRIMARY KEY, a INTEGER UNIQUE, b, c, d, e")
    _refused(path, match="index")  # its sqlite_autoindex


def test_refuses_records_that_need_overflow_pages(tmp_path):
    path = tmp_path / "big.db"
    make_db(path, 512, cols="fid INTEGER PRIMARY KEY, d BLOB")
    ok = [None, ("blob", np.zeros((2, 470), np.uint8), None)]  # 4 + 470 bytes <= 512 - 35
    with BtreeAppender(path) as app:
        app.fill("t", [(np.array([1, 2]), *encode_records(ok, 2))])
    assert integrity(path) == ["ok"]
    big = [None, ("blob", np.zeros((1, 475), np.uint8), None)]  # 4 + 475 bytes > 512 - 35
    _refused(path, table="twin", batches=[(np.array([1]), *encode_records(big, 1))],
             match="overflow")


def test_refuses_what_is_not_a_table_or_not_sqlite(tmp_path):
    path = tmp_path / "s.db"
    make_db(path, cols="fid INTEGER PRIMARY KEY, a")
    con = sqlite3.connect(path)
    con.execute("CREATE VIEW v AS SELECT * FROM t")
    con.execute("CREATE TABLE wr(k TEXT PRIMARY KEY, a) WITHOUT ROWID")
    con.commit()
    con.close()
    for name, why in (("missing", "not a table"), ("v", "not a table"),
                      ("wr", "not an empty rowid table")):
        _refused(path, table=name, match=why)
    other = tmp_path / "plain.txt"
    other.write_bytes(b"not a database" * 100)
    with pytest.raises(UnsupportedDatabase, match="not an SQLite"):
        BtreeAppender(other)


def test_wrong_column_count_is_refused_before_writing(tmp_path):
    path = tmp_path / "c.db"
    make_db(path)
    before = digest(path)
    rec = encode_records([None, ("int", np.array([1]), None)], 1)
    with pytest.raises(ValueError, match="2 columns"), BtreeAppender(path) as app:
        app.fill("t", [(np.array([1]), *rec)])
    assert digest(path) == before


def test_fixed_width_columns_with_nulls(tmp_path):
    """The TIN layout: NULL-able integers, reals, a NULL-able 149-byte blob (a 2-byte serial
    type, so a NULL also shortens the record header) and 0/1 columns (serial types 8/9)."""
    path = tmp_path / "n.db"
    cols_sql = ("fid INTEGER PRIMARY KEY, a INTEGER, b INTEGER, c REAL, g BLOB, f INTEGER, "
                "h INTEGER")
    make_db(path, 4096, cols=cols_sql)
    n = 5000
    rng = np.random.default_rng(11)
    a = rng.integers(-(2**31), 2**31, n)
    am = rng.random(n) < 0.1
    b = rng.integers(0, 2, n)
    bm = rng.random(n) < 0.3
    c = rng.normal(size=n)
    g = rng.integers(0, 256, (n, 149)).astype(np.uint8)
    gm = rng.random(n) < 0.2
    f = rng.random(n) < 0.5
    h = np.full(n, 7)
    hm = np.ones(n, bool)  # an all-NULL column
    cols = [None, ("int", a, am), ("int", b, bm), ("real", c, None), ("blob", g, gm),
            ("bool", f, None), ("int", h, hm)]
    rowids = np.arange(1, n + 1) * 5
    with BtreeAppender(path) as app:
        app.fill("t", batched(rowids, cols, (1700, 3)))
    con = sqlite3.connect(path)
    con.executemany("INSERT INTO twin VALUES (?,?,?,?,?,?,?)", [
        (int(rowids[i]), None if am[i] else int(a[i]), None if bm[i] else int(b[i]),
         float(c[i]), None if gm[i] else g[i].tobytes(), bool(f[i]), None) for i in range(n)])
    assert_same_as_twin(con, path, "fid, a, typeof(a), b, typeof(b), c, g, typeof(g), f, "
                        "typeof(f), h, typeof(h)")


def test_the_lock_byte_page_past_one_gib_stays_unused(tmp_path):
    """SQLite never uses the page holding byte 2**30 (its lock bytes); a file grown past 1 GiB
    skips it. The file is made to end just before it without writing a GiB: pages 4..16380 of
    65536 bytes are a (sparse) freelist written by hand."""
    import struct

    path = tmp_path / "big.db"
    make_db(path, 65536, cols="fid INTEGER PRIMARY KEY, a INTEGER, g BLOB")
    ps = 65536
    lock = 2**30 // ps + 1  # 16385
    end = lock - 5
    with open(path, "r+b") as f:
        head = bytearray(f.read(100))
        used = struct.unpack(">I", head[28:32])[0]
        trunk = used + 1
        leaves = list(range(trunk + 1, end + 1))
        f.seek((trunk - 1) * ps)
        f.write(struct.pack(f">II{len(leaves)}I", 0, len(leaves), *leaves))
        f.truncate(end * ps)
        counter = struct.unpack(">I", head[24:28])[0] + 1
        head[24:28] = head[92:96] = struct.pack(">I", counter)
        head[28:32] = struct.pack(">I", end)
        head[32:40] = struct.pack(">II", trunk, end - used)
        f.seek(0)
        f.write(head)
    assert integrity(path) == ["ok"]  # the hand-made freelist is valid
    n = 400  # 16 rows a page: 25 leaves, pages end + 1 .. end + 26 with the lock page skipped
    rng = np.random.default_rng(2)
    g = rng.integers(0, 256, (n, 4000)).astype(np.uint8)
    cols = [None, ("int", np.arange(n), None), ("blob", g, None)]
    with BtreeAppender(path) as app:
        app.fill("t", batched(np.arange(1, n + 1), cols, (150,)))
    assert integrity(path) == ["ok"]
    con = sqlite3.connect(path)
    pages = [r[0] for r in con.execute("SELECT pageno FROM dbstat WHERE name = 't'")]
    rows = con.execute("SELECT fid, a, g FROM t ORDER BY fid").fetchall()
    con.close()
    assert lock not in pages and max(pages) > lock
    assert rows == [(i + 1, i, g[i].tobytes()) for i in range(n)]


def test_a_caught_refusal_still_undoes_every_fill_and_close_says_so(tmp_path):
    path = tmp_path / "c.db"
    make_db(path, 1024)
    before = digest(path)
    cols, _rows = mixed_rows(300)
    app = BtreeAppender(path)
    app.fill("t", batched(np.arange(1, 301), cols, (100,)))
    with pytest.raises(UnsupportedDatabase, match="not a table"):
        app.fill("missing", [])
    assert digest(path) == before
    with pytest.raises(UnsupportedDatabase, match="restored"):
        app.fill("twin", [])
    with pytest.raises(UnsupportedDatabase, match="restored"):
        app.close()
    assert digest(path) == before


def test_an_appender_never_closed_is_undone(tmp_path):
    path = tmp_path / "d.db"
    make_db(path, 1024)
    before = digest(path)
    cols, _rows = mixed_rows(300)
    app = BtreeAppender(path)
    app.fill("t", batched(np.arange(1, 301), cols, (100,)))
    assert digest(path) != before
    del app
    assert digest(path) == before


@pytest.mark.parametrize("columns, match", [
    ([("int", np.array([2**64 - 1], np.uint64), None)], "more than an SQLite integer"),
    ([("int", np.array([1.5]), None)], "expected integers"),
    ([("int", np.array([1, 2]), None)], r"shape \(2,\), expected \(1,\)"),
    ([("real", np.array([1.0]), np.array([True, False]))], "mask has shape"),
    ([("date", np.array([1]), None)], "expected one of int, real, bool, text, blob"),
    ([(1, 2)], "expected None or"),
    ([], "at least one column"),
])
def test_bad_columns_name_the_column(columns, match):
    with pytest.raises(ValueError, match=match):
        encode_records(columns, 1)


def test_a_wide_table_whose_record_header_needs_two_bytes(tmp_path):
    path = tmp_path / "w.db"
    k = 150  # 150 one-byte serial types: a 152-byte header, its size a 2-byte varint
    make_db(path, 4096, cols="fid INTEGER PRIMARY KEY, " + ", ".join(f"c{i}" for i in range(k)))
    n = 300
    rng = np.random.default_rng(4)
    vals = rng.integers(-100, 100, (k, n))
    masks = rng.random((k, n)) < 0.1
    cols = [None] + [("int", vals[i], masks[i]) for i in range(k)]
    with BtreeAppender(path) as app:
        app.fill("t", batched(np.arange(1, n + 1), cols, (77,)))
    con = sqlite3.connect(path)
    con.executemany(f"INSERT INTO twin VALUES ({', '.join('?' * (k + 1))})", [
        (j + 1, *[None if masks[i, j] else int(vals[i, j]) for i in range(k)]) for j in range(n)])
    assert_same_as_twin(con, path)


def test_the_table_named_by_its_root_page(tmp_path):
    path = tmp_path / "p.db"
    make_db(path)
    con = sqlite3.connect(path)
    root = con.execute("SELECT rootpage FROM sqlite_schema WHERE name = 'twin'").fetchone()[0]
    con.close()
    cols, rows = mixed_rows(40)
    with BtreeAppender(path) as app:
        app.fill(root, batched(np.arange(1, 41), cols, (40,)))
    con = sqlite3.connect(path)
    assert con.execute("SELECT count(*) FROM twin").fetchone() == (40,)
    assert con.execute("SELECT count(*) FROM t").fetchone() == (0,)
    con.close()
    _refused(path, table=1, match="not the root page of a table")  # sqlite_schema's own page
