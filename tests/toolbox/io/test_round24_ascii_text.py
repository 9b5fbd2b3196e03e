"""Round 24: text columns given as numpy ``str`` arrays are encoded without a Python object a
row when they are ASCII (toolbox.io.sqlite_pages._ascii_col): the records are byte for byte
those of the same strings as Python objects, and SQLite reads the strings back; non-ASCII
text takes the object path, and NULLs (a mask) are NULLs either way."""

from __future__ import annotations

import sqlite3

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from toolbox.io.sqlite_pages import BtreeAppender, _ascii_col, encode_records

ASCII = st.text(st.characters(max_codepoint=127), max_size=12)
ANY = st.text(max_size=12)


def records(values: np.ndarray, mask, with_int: bool):
    cols = [None, ("text", values, mask)] + ([("int", np.arange(len(values)), None)]
                                             if with_int else [])
    return encode_records(cols, len(values))


@settings(max_examples=150, deadline=None)
@given(strings=st.lists(st.one_of(ASCII, ANY), min_size=1, max_size=60),
       nulls=st.lists(st.booleans(), min_size=60, max_size=60), with_int=st.booleans())
def test_numpy_text_gives_the_records_of_python_strings(strings, nulls, with_int):
    as_numpy = np.array(strings)  # numpy drops trailing NULs: compare with what it holds
    as_objects = np.array(as_numpy.tolist(), dtype=object)
    mask = np.array(nulls[:len(strings)]) if nulls[0] else None
    flat, offsets = records(as_numpy, mask, with_int)
    want_flat, want_offsets = records(as_objects, mask, with_int)
    np.testing.assert_array_equal(offsets, want_offsets)
    np.testing.assert_array_equal(flat, want_flat)


def test_only_ascii_takes_the_vectorised_path():
    assert _ascii_col(3, np.array(["point", "", "a\x00b"]), None) is not None
    assert _ascii_col(2, np.array(["punto", "città"]), None) is None
    assert _ascii_col(2, np.array(["a", "b"], dtype=object), None) is None


def test_sqlite_reads_the_strings_back(tmp_path):
    values = np.array(["point", "breakline", "", "crossing", "a\x00b", "boundary"] * 50)
    mask = np.zeros(len(values), bool)
    mask[::7] = True
    path = tmp_path / "t.db"
    with sqlite3.connect(path) as db:
        db.execute("CREATE TABLE t (id INTEGER PRIMARY KEY, s TEXT)")
    flat, offsets = records(values, mask, False)
    with BtreeAppender(path) as pages:
        pages.fill("t", [(np.arange(1, len(values) + 1), flat, offsets)])
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        rows = db.execute("SELECT s FROM t ORDER BY id").fetchall()
    assert [r[0] for r in rows] == [None if m else str(v) for v, m in zip(values, mask,
                                                                          strict=True)]
