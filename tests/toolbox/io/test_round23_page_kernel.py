"""The bulk page writer's compiled pass (toolbox.io.page_kernel) against its numpy twin in
toolbox.io.sqlite_pages: random tables (column kinds, NULLs, rowids of every varint length,
negative ones too, batch sizes, page sizes of 512 to 65536 bytes) give
byte-identical files through numba's JIT, the numpy steps and, where this process has them, the
kernels compiled ahead of time; SQLite's integrity_check passes and the rows read back as
SQLite's own inserts of the same values (test_round21_sqlitepages_random.py's oracle)."""

from __future__ import annotations

import sqlite3
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from tests.toolbox.io.test_round21_sqlitepages_random import DECL, KINDS, column, twin_tables
from toolbox.io import page_kernel, sqlite_pages
from toolbox.io.sqlite_pages import BtreeAppender, encode_records

JIT = (page_kernel.leaf_cells, page_kernel.copy_records)


def write(folder: Path, name: str, kernels, page_size: int, decl: str, batches) -> Path:
    """A fresh database with table ``t`` filled from ``batches`` through ``kernels`` (None: the
    numpy steps)."""
    path = twin_tables(folder / f"{name}.db", page_size, decl)
    saved = sqlite_pages.compiled_page_kernels
    sqlite_pages.compiled_page_kernels = lambda: kernels
    try:
        with BtreeAppender(path) as app:
            app.fill("t", batches)
    finally:
        sqlite_pages.compiled_page_kernels = saved
    return path


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1),
       kinds=st.lists(st.sampled_from(KINDS), min_size=1, max_size=5),
       page_size=st.sampled_from([512, 4096, 65536]),
       n=st.integers(1, 3000),
       width=st.integers(0, 300),
       batch=st.integers(1, 1500),
       gap=st.sampled_from([1, 1000, 2**20, 2**40, 2**48]),
       first=st.integers(-(2**62), 2**60))  # up to 2**60 + 3000 * 2**48 < 2**63: no wrap
def test_the_compiled_pass_writes_the_numpy_bytes(seed, kinds, page_size, n, width, batch, gap,
                                                  first):
    rng = np.random.default_rng(seed)
    steps = rng.integers(1, gap + 1, n) if gap > 1 else np.ones(n, np.int64)
    rowids = first + np.cumsum(steps)
    specs, pys = zip(*[column(k, n, rng, 0.1, width) for k in kinds])
    decl = ", ".join(f"c{i} {DECL[k]}" for i, k in enumerate(kinds))
    batches = []
    for a in range(0, n, batch):
        sl = slice(a, a + batch)
        part = [None] + [(k, v[sl], None if m is None else m[sl]) for k, v, m in specs]
        batches.append((rowids[sl], *encode_records(part, len(rowids[sl]))))
    assume(max(int(np.diff(b[2]).max()) for b in batches) <= page_size - 35)  # no overflow
    writers = {"numpy": None, "jit": JIT}
    compiled = sqlite_pages.compiled_page_kernels()
    if compiled is not None:  # this process loads the ahead-of-time modules (toolbox warmup)
        writers["compiled"] = compiled
    with tempfile.TemporaryDirectory() as tmp:
        files = {name: write(Path(tmp), name, kernels, page_size, decl, batches)
                 for name, kernels in writers.items()}
        reference = files["numpy"].read_bytes()
        for name, path in files.items():
            assert path.read_bytes() == reference, name
        con = sqlite3.connect(files["jit"])
        try:
            assert [r[0] for r in con.execute("PRAGMA integrity_check")] == ["ok"]
            marks = ", ".join("?" * (len(kinds) + 1))
            con.executemany(f"INSERT INTO twin VALUES ({marks})",
                            [(int(r), *vals) for r, vals in zip(rowids, zip(*pys))])
            cols = ", ".join(f"c{i}, typeof(c{i})" for i in range(len(kinds)))
            q = f"SELECT fid, {cols} FROM {{}} ORDER BY fid"
            assert con.execute(q.format("t")).fetchall() == con.execute(q.format("twin")
                                                                        ).fetchall()
        finally:
            con.close()


def test_varint_sizes_match_the_file_format():
    """Every length boundary of SQLite's varint (7 bits a byte, the ninth byte whole) and a
    negative value (9 bytes), written by the kernel and decoded by the numpy writer's reader."""
    values = [0, 1, 127, 128, 2**14 - 1, 2**14, 2**21, 2**28, 2**35, 2**42, 2**49, 2**56 - 1,
              2**56, 2**63 - 1, -1, -(2**63)]
    for value in values:
        buf = np.zeros(16, np.uint8)
        end = page_kernel._put_varint(buf, 0, value)
        decoded, pos = sqlite_pages._read_varint(bytes(buf), 0)
        assert pos == end == page_kernel._varint_size(value), value
        assert decoded == value % 2**64, value


def test_rowids_falling_by_more_than_half_the_int64_range_are_refused(tmp_path):
    """Rowids 2**62 then -2**62 - 1 fall, but their np.diff wraps to a positive number: the
    appender took them and wrote a tree SQLite calls out of order (found by the test above)."""
    decl = "c0 INTEGER"
    rowids = np.array([2**62, -(2**62) - 1], np.int64)
    batch = (rowids, *encode_records([None, ("int", np.array([1, 2]), None)], 2))
    try:
        write(tmp_path, "wrap", None, 4096, decl, [batch])
    except sqlite_pages.UnsupportedDatabase as exc:
        assert "not strictly increasing" in str(exc)
    else:
        raise AssertionError("falling rowids were taken")

