"""toolbox.io.sqlite_pages against SQLite on random tables: random column kinds, NULLs, rowids,
batch sizes and page sizes; the appended table must pass ``PRAGMA integrity_check`` and read
back exactly as the same rows inserted into a twin table with ``executemany``."""

from __future__ import annotations

import sqlite3
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolbox.io.sqlite_pages import BtreeAppender, encode_records

KINDS = ("int", "real", "bool", "text", "blob", "fixed_blob", "small_int", "strided_blob")
DECL = {"int": "INTEGER", "small_int": "INTEGER", "real": "REAL", "bool": "INTEGER",
        "text": "TEXT", "blob": "BLOB", "fixed_blob": "BLOB", "strided_blob": "BLOB"}


def column(kind, n, rng, null_rate, width):
    mask = rng.random(n) < null_rate if null_rate else None
    if kind == "int":
        scale = 2 ** int(rng.integers(1, 64))
        v = rng.integers(-scale, scale, n, dtype=np.int64, endpoint=False)
        py = [int(x) for x in v]
    elif kind == "small_int":
        v = rng.integers(0, 2, n)
        py = [int(x) for x in v]
    elif kind == "real":
        v = rng.normal(size=n) * 10.0 ** rng.integers(-5, 300)
        py = [float(x) for x in v]
    elif kind == "bool":
        v = rng.random(n) < 0.5
        py = [bool(x) for x in v]
    elif kind == "text":
        alphabet = ["a", "é", "€", "𝄞", " ", "Z"]
        v = np.array(["".join(rng.choice(alphabet, int(k))) for k in rng.integers(0, 30, n)],
                     object)
        py = list(v)
    elif kind == "blob":
        v = np.array([bytes(rng.integers(0, 256, int(k)).astype(np.uint8))
                      for k in rng.integers(0, 60, n)], object)
        py = list(v)
    elif kind == "strided_blob":  # (n, width) bytes that are not contiguous within a row
        v = rng.integers(0, 256, (n, 2 * width)).astype(np.uint8)[:, ::2]
        py = [bytes(r) for r in v]
    else:
        v = rng.integers(0, 256, (n, width)).astype(np.uint8)
        py = [bytes(r) for r in v]
    if mask is not None:
        py = [None if m else x for x, m in zip(py, mask)]
    spec = "bool" if kind == "bool" else "int" if kind == "small_int" else (
        "blob" if kind in ("fixed_blob", "strided_blob") else kind)
    return (spec, v, mask), py


def twin_tables(path: Path, page_size: int, decl: str) -> Path:
    """A new database of ``page_size`` with two empty tables ``t`` and ``twin`` of the columns
    ``decl`` after an INTEGER PRIMARY KEY ``fid``."""
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA page_size={page_size}")
    con.execute(f"CREATE TABLE t(fid INTEGER PRIMARY KEY, {decl})")
    con.execute(f"CREATE TABLE twin(fid INTEGER PRIMARY KEY, {decl})")
    con.commit()
    con.close()
    return path


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1),
       kinds=st.lists(st.sampled_from(KINDS), min_size=1, max_size=7),
       page_size=st.sampled_from([512, 1024, 4096, 65536]),
       n=st.integers(0, 400),
       null_rate=st.sampled_from([0.0, 0.0, 0.05, 0.5]),
       width=st.integers(0, 90),
       batch=st.integers(1, 200),
       gap=st.sampled_from([1, 2, 1000, 2**20, 2**40]),
       first=st.integers(-(2**62), 2**62))
def test_random_tables_match_sqlite(seed, kinds, page_size, n, null_rate, width, batch, gap,
                                    first):
    rng = np.random.default_rng(seed)
    steps = rng.integers(1, gap + 1, n) if gap > 1 else np.ones(n, np.int64)
    rowids = first + np.cumsum(steps)
    specs, pys = zip(*[column(k, n, rng, null_rate, width) for k in kinds]) if n else (
        [column(k, 0, rng, 0, width)[0] for k in kinds], [[] for _ in kinds])
    names = [f"c{i}" for i in range(len(kinds))]
    decl = ", ".join(f"{c} {DECL[k]}" for c, k in zip(names, kinds))
    with tempfile.TemporaryDirectory() as tmp:
        path = twin_tables(Path(tmp) / "h.db", page_size, decl)
        batches = []
        for a in range(0, n, batch):
            sl = slice(a, a + batch)
            part = [None] + [(k, v[sl], None if m is None else m[sl]) for k, v, m in specs]
            batches.append((rowids[sl], *encode_records(part, len(rowids[sl]))))
        with BtreeAppender(path) as app:
            assert app.fill("t", batches) == n
        con = sqlite3.connect(path)
        try:
            assert [r[0] for r in con.execute("PRAGMA integrity_check")] == ["ok"]
            marks = ", ".join("?" * (len(kinds) + 1))
            con.executemany(f"INSERT INTO twin VALUES ({marks})",
                            [(int(r), *vals) for r, vals in zip(rowids, zip(*pys))])
            cols = ", ".join(f"{c}, typeof({c})" for c in names)
            q = f"SELECT fid, {cols} FROM {{}} ORDER BY fid"
            assert con.execute(q.format("t")).fetchall() == con.execute(q.format("twin")
                                                                        ).fetchall()
        finally:
            con.close()
