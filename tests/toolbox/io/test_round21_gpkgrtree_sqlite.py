"""Packed SQLite R-trees (toolbox.io.sqlite_rtree) checked against SQLite itself: its node size,
its float32 rounding on insert (a twin rtree filled through SQL is the oracle for the stored
boxes), ``rtreecheck``, window queries against a numpy brute force on the boxes SQLite stored,
and SQLite maintaining the packed tree afterwards (inserts, deletes, updates)."""

from __future__ import annotations

import dataclasses
import sqlite3

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolbox.io.sqlite_rtree import (
    insert_rtree_rows,
    node_size_for_page,
    packed_rtree,
    rtree_round_down,
    rtree_round_up,
)

_CELL = np.dtype([("id", ">i8"), ("box", ">f4", (4,))])
SIENA_X, SIENA_Y = 1_688_000.0, 4_799_500.0


def _connect(page_size: int = 4096) -> sqlite3.Connection:
    db = sqlite3.connect(":memory:")
    db.execute(f"PRAGMA page_size = {page_size}")
    return db


def _create(db: sqlite3.Connection, name: str) -> None:
    db.execute(f'CREATE VIRTUAL TABLE "{name}" USING rtree(id, minx, maxx, miny, maxy)')


def _sql_rows(ids, boxes):
    return zip(np.asarray(ids).tolist(), *(np.asarray(b, dtype=np.float64).tolist() for b in boxes))


def _twin(ids, boxes, page_size: int = 4096) -> sqlite3.Connection:
    """The same boxes inserted one by one through SQL: SQLite's own tree and stored values."""
    db = _connect(page_size)
    _create(db, "twin")
    db.executemany("INSERT INTO twin VALUES (?, ?, ?, ?, ?)", _sql_rows(ids, boxes))
    db.commit()
    return db


def _packed(ids, boxes, page_size: int = 4096) -> sqlite3.Connection:
    db = _connect(page_size)
    _create(db, "packed")
    insert_rtree_rows(db, "packed", packed_rtree(ids, *boxes, page_size=page_size))
    db.commit()
    return db


def _stored(db: sqlite3.Connection, name: str) -> np.ndarray:
    """id, minx, maxx, miny, maxy as the rtree returns them, by id (a record array: the ids stay
    int64)."""
    rows = db.execute(f'SELECT id, minx, maxx, miny, maxy FROM "{name}" ORDER BY id').fetchall()
    out = np.zeros(len(rows), [("id", np.int64), ("box", np.float64, (4,))])
    if rows:
        out["id"] = [r[0] for r in rows]
        out["box"] = [r[1:] for r in rows]
    return out


def _check(db: sqlite3.Connection, name: str) -> None:
    assert db.execute("SELECT rtreecheck(?)", (name,)).fetchone()[0] == "ok"
    assert db.execute("PRAGMA integrity_check").fetchall() == [("ok",)]


def _query(db, name, w) -> list[int]:
    sql = f'SELECT id FROM "{name}" WHERE maxx >= ? AND minx <= ? AND maxy >= ? AND miny <= ?'
    return sorted(r[0] for r in db.execute(sql, (w[0], w[1], w[2], w[3])))


def _brute(stored: np.ndarray, w) -> list[int]:
    b = stored["box"]
    hit = (b[:, 1] >= w[0]) & (b[:, 0] <= w[1]) & (b[:, 3] >= w[2]) & (b[:, 2] <= w[3])
    return sorted(stored["id"][hit].tolist())


def _windows(stored: np.ndarray, rng, count: int):
    """Random windows over the boxes' extent, some of them exactly on stored coordinates."""
    if not len(stored):
        yield (0.0, 1.0, 0.0, 1.0)
        return
    b = stored["box"]
    lo = b[:, [0, 2]].min(axis=0)
    hi = b[:, [1, 3]].max(axis=0)
    finite = np.isfinite(b).all(axis=1)
    if not finite.all():  # boxes beyond float32 (stored as inf): windows over the finite ones
        lo = b[finite][:, [0, 2]].min(axis=0) if finite.any() else np.zeros(2)
        hi = b[finite][:, [1, 3]].max(axis=0) if finite.any() else np.ones(2)
    with np.errstate(over="ignore"):
        span = np.minimum(np.maximum(hi - lo, 1e-3), 1e300)
    for i in range(count):
        if i % 4 == 0:  # on a box's own corners: the float32 values decide
            r = b[rng.integers(len(b))]
            yield (r[0], r[0], r[2], r[2]) if i % 8 == 0 else (r[1], r[1], r[3], r[3])
            continue
        size = span * rng.uniform(0.001, 0.2)
        x0, y0 = lo - span * 0.05 + rng.random(2) * span * 1.1
        yield (x0, x0 + size[0], y0, y0 + size[1])


def _assert_same_as_sqlite(ids, boxes, page_size=4096, windows=40, seed=0):
    packed = _packed(ids, boxes, page_size)
    _check(packed, "packed")
    stored = _stored(_twin(ids, boxes, page_size), "twin")
    mine = _stored(packed, "packed")
    np.testing.assert_array_equal(mine, stored)  # ids and float32 values, bit for bit
    rng = np.random.default_rng(seed)
    for w in _windows(stored, rng, windows):
        assert _query(packed, "packed", w) == _brute(stored, w), w
    return packed, stored


def _random_boxes(n, seed, x0=0.0, y0=0.0, extent=1000.0, size=5.0):
    rng = np.random.default_rng(seed)
    x = x0 + rng.random(n) * extent
    y = y0 + rng.random(n) * extent
    return [x, x + rng.random(n) * size, y, y + rng.random(n) * size]


@pytest.mark.parametrize("page_size", [512, 1024, 4096, 8192, 65536])
def test_node_size_is_the_one_sqlite_gives_a_new_tree(page_size):
    db = _connect(page_size)
    _create(db, "t")
    sqlite_size = db.execute("SELECT length(data) FROM t_node WHERE nodeno = 1").fetchone()[0]
    assert node_size_for_page(page_size) == sqlite_size
    rows = packed_rtree(np.arange(1, 200), *_random_boxes(199, 1), page_size=page_size)
    assert rows.node_blobs.shape[1] == sqlite_size == rows.node_size


def test_doctests():
    import doctest

    from toolbox.io import sqlite_rtree

    assert doctest.testmod(sqlite_rtree).failed == 0


def test_rounding_is_sqlites_on_adversarial_values():
    rng = np.random.default_rng(7)
    a = (rng.standard_normal(500) * 1e6).astype(np.float32)
    up = np.nextafter(a, np.float32(np.inf))
    halfway = (a.astype(np.float64) + up.astype(np.float64)) / 2  # ties of the float32 cast
    special = np.array([0.0, 1.0, 0.1, 1e-40, 1e-45, 1e-50, 5e-324, 2.0 ** -149, 2.0 ** -150,
                        3 * 2.0 ** -151, 1.17549435e-38, 16777217.0, 16777219.0, 3.4e38,
                        SIENA_X, SIENA_Y, SIENA_X + 0.123, SIENA_Y + 0.3, SIENA_Y + 0.25])
    values = np.concatenate([special, -special, a, halfway, np.nextafter(halfway, np.inf),
                             np.nextafter(halfway, -np.inf),
                             rng.standard_normal(500) * 10.0 ** rng.integers(-40, 38, 500),
                             SIENA_X + rng.random(300) * 1e4, SIENA_Y + rng.random(300) * 1e4])
    db = _twin(np.arange(1, values.size + 1), [values] * 4)
    stored = _stored(db, "twin")
    np.testing.assert_array_equal(rtree_round_down(values).astype(np.float64), stored["box"][:, 0])
    np.testing.assert_array_equal(rtree_round_up(values).astype(np.float64), stored["box"][:, 1])
    # and not the plain "next float32 outwards": SQLite's scaling rounds tiny values to 0 etc.
    f = values.astype(np.float32)
    plain = np.where(f > values, np.nextafter(f, np.float32(-np.inf)), f).astype(np.float64)
    assert (plain != stored["box"][:, 0]).any()


@pytest.mark.parametrize(("n", "depth"), [(0, 0), (1, 0), (51, 0), (52, 1), (2601, 1),
                                          (2602, 2)])
def test_level_boundaries(n, depth):
    ids = np.arange(1, n + 1) * 3 - 1
    boxes = _random_boxes(n, n)
    rows = packed_rtree(ids, *boxes)
    assert rows.depth == depth
    assert rows.node_blobs[0, :2].tolist() == [0, depth]
    assert not rows.node_blobs[1:, :2].any()  # only the root carries the depth, as in SQLite
    m = len(rows.node_numbers)
    assert rows.node_numbers.tolist() == list(range(1, m + 1))
    assert rows.parent_nodes.tolist() == list(range(2, m + 1))
    counts = rows.node_blobs[:, 2].astype(int) * 256 + rows.node_blobs[:, 3]
    leaves = counts[len(counts) - (-(-n // 51) if depth else 1):]
    assert leaves.sum() == n and (n < 52 or leaves.min() >= 26)
    _assert_same_as_sqlite(ids, boxes)


def test_empty_input_is_an_empty_root():
    rows = packed_rtree(np.array([], np.int64), *[np.array([])] * 4)
    assert rows.node_numbers.tolist() == [1] and not rows.node_blobs.any()
    assert rows.rowids.size == rows.parents.size == 0
    db = _connect()
    _create(db, "t")
    empty_root = db.execute("SELECT data FROM t_node").fetchone()[0]
    assert rows.node_blobs[0].tobytes() == empty_root


def test_100k_boxes_in_siena_coordinates_and_unsorted_ids():
    n = 100_000
    ids = np.random.default_rng(3).permutation(n) + 10
    boxes = _random_boxes(n, 3, SIENA_X, SIENA_Y, extent=10_000.0, size=20.0)
    _assert_same_as_sqlite(ids, boxes, windows=30)


@pytest.mark.parametrize("case", ["duplicates", "identical", "points", "siena_points", "huge",
                                  "line"])
def test_degenerate_box_sets(case):
    rng = np.random.default_rng(11)
    n = 3000
    if case == "duplicates":  # every box three times
        b = _random_boxes(n // 3, 11)
        boxes = [np.tile(v, 3) for v in b]
    elif case == "identical":
        boxes = [np.full(n, v) for v in (1.5, 2.5, -3.25, 0.1)]
    elif case == "points":  # zero-width boxes
        x, y = rng.random((2, n)) * 100
        boxes = [x, x, y, y]
    elif case == "siena_points":
        x, y = SIENA_X + rng.random(n) * 300, SIENA_Y + rng.random(n) * 300
        boxes = [x, x, y, y]
    elif case == "huge":  # beyond float32 (SQLite stores +-inf) and near float64's limits
        x = rng.choice([1e300, -1e300, 3.5e38, 1e308, -1.7e308, 1.0, 0.0], n)
        y = rng.random(n) * 1e308
        boxes = [np.minimum(x, 1.0), np.maximum(x, 1.0), y * 0.5, y]
    else:  # all on one horizontal line: no height to tile
        x = rng.random(n) * 100
        boxes = [x, x + 1, np.full(n, 7.0), np.full(n, 7.0)]
    ids = np.arange(1, n + 1)
    _assert_same_as_sqlite(ids, boxes)


def test_small_pages_deep_tree():
    """512-byte pages: 18 cells a node, a deeper tree for the same boxes."""
    n = 7000
    rows = packed_rtree(np.arange(1, n + 1), *_random_boxes(n, 5), page_size=512)
    assert rows.node_size == 448 and rows.depth == 3
    _assert_same_as_sqlite(np.arange(1, n + 1), _random_boxes(n, 5), page_size=512)


def test_sqlite_keeps_maintaining_the_packed_tree():
    n = 20_000
    rng = np.random.default_rng(21)
    ids = np.arange(1, n + 1)
    boxes = _random_boxes(n, 21, SIENA_X, SIENA_Y, extent=3000.0, size=10.0)
    packed = _packed(ids, boxes)
    twin = _twin(ids, boxes)
    new_ids = np.arange(n + 1, n + 5001)
    new = _random_boxes(5000, 22, SIENA_X - 500, SIENA_Y - 500, extent=4000.0, size=30.0)
    gone = rng.choice(np.arange(1, n + 5001), 5000, replace=False)
    moved = rng.choice(np.setdiff1d(np.arange(1, n + 5001), gone), 500, replace=False)
    moved_boxes = _random_boxes(500, 23, SIENA_X, SIENA_Y, extent=3000.0, size=50.0)
    for db, name in ((packed, "packed"), (twin, "twin")):
        db.executemany(f"INSERT INTO {name} VALUES (?, ?, ?, ?, ?)", _sql_rows(new_ids, new))
        db.executemany(f"DELETE FROM {name} WHERE id = ?", [(int(i),) for i in gone])
        db.executemany(f"UPDATE {name} SET minx = ?, maxx = ?, miny = ?, maxy = ? WHERE id = ?",
                       [(*b, i) for i, *b in _sql_rows(moved, moved_boxes)])
        db.commit()
    _check(packed, "packed")
    stored = _stored(twin, "twin")
    assert len(stored) == n
    np.testing.assert_array_equal(_stored(packed, "packed"), stored)
    for w in _windows(stored, rng, 40):
        assert _query(packed, "packed", w) == _brute(stored, w)


def _nodes(db, name):
    nodes = {}
    for k, data in db.execute(f'SELECT nodeno, data FROM "{name}_node"'):
        cells = np.frombuffer(data, _CELL, count=int.from_bytes(data[2:4], "big"), offset=4)
        nodes[k] = (cells["id"].astype(np.int64), cells["box"].astype(np.float64))
    return nodes, int.from_bytes(nodes and db.execute(
        f'SELECT data FROM "{name}_node" WHERE nodeno = 1').fetchone()[0][:2], "big")


def _visits(nodes, depth, w) -> int:
    """Nodes a window query reads: the root, then every child whose box meets the window."""
    count, frontier = 0, [1]
    for level in range(depth, -1, -1):
        below = []
        for k in frontier:
            count += 1
            ids, b = nodes[k]
            hit = (b[:, 1] >= w[0]) & (b[:, 0] <= w[1]) & (b[:, 3] >= w[2]) & (b[:, 2] <= w[3])
            if level:
                below.extend(ids[hit].tolist())
        frontier = below
    return count


def test_queries_visit_no_more_nodes_than_sqlites_own_tree():
    """TIN-like triangles: windows of 0.1 % and 1 % of the area read fewer nodes of the packed
    tree than of the tree SQLite builds by inserting the same boxes (fuller, squarer nodes)."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(31)
    pts = rng.random((12_000, 2)) * [3000.0, 2000.0]
    xy = (pts + [SIENA_X, SIENA_Y])[Delaunay(pts).simplices]
    boxes = [xy[:, :, 0].min(1), xy[:, :, 0].max(1), xy[:, :, 1].min(1), xy[:, :, 1].max(1)]
    ids = np.arange(1, len(xy) + 1)
    packed_db = _packed(ids, boxes)
    twin_db = _twin(ids, boxes)
    packed, twin = _nodes(packed_db, "packed"), _nodes(twin_db, "twin")
    assert len(packed[0]) < len(twin[0])
    for fraction in (0.001, 0.01):
        size = np.sqrt(fraction) * np.array([3000.0, 2000.0])
        ours, sqlites = [], []
        for _ in range(100):
            x0, y0 = [SIENA_X, SIENA_Y] + rng.random(2) * ([3000.0, 2000.0] - size)
            w = (x0, x0 + size[0], y0, y0 + size[1])
            ours.append(_visits(*packed, w))
            sqlites.append(_visits(*twin, w))
        assert np.mean(ours) <= np.mean(sqlites), (fraction, np.mean(ours), np.mean(sqlites))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_random_box_sets(data):
    n = data.draw(st.integers(0, 400))
    page_size = data.draw(st.sampled_from([512, 1024, 4096]))
    coord = st.floats(-1e7, 1e7, allow_nan=False, allow_infinity=False)
    lo = np.array(data.draw(st.lists(st.tuples(coord, coord), min_size=n, max_size=n)),
                  dtype=np.float64).reshape(-1, 2)
    size = st.one_of(st.just(0.0), st.floats(0, 1e3, allow_nan=False))
    wh = np.array(data.draw(st.lists(st.tuples(size, size), min_size=n, max_size=n)),
                  dtype=np.float64).reshape(-1, 2)
    ids = np.array(data.draw(st.lists(st.integers(-2 ** 62, 2 ** 62), min_size=n, max_size=n,
                                      unique=True)), dtype=np.int64)
    boxes = [lo[:, 0], lo[:, 0] + wh[:, 0], lo[:, 1], lo[:, 1] + wh[:, 1]]
    _assert_same_as_sqlite(ids, boxes, page_size=page_size, windows=8, seed=n)


@pytest.mark.parametrize(("change", "message"), [
    ({"minx": [0.0, np.nan]}, "minx: 1 value"),
    ({"maxy": [1.0, np.inf]}, "maxy: 1 value"),
    ({"minx": [0.0, 2.0]}, "minx/maxx: 1 box"),
    ({"miny": [5.0, 0.0]}, "miny/maxy: 1 box"),
    ({"ids": [4, 4]}, "ids has 1 duplicate"),
    ({"ids": [1.0, 2.0]}, "ids has dtype float64"),
    ({"maxx": [1.0]}, "maxx has shape (1,)"),
    ({"page_size": 1000}, "page_size is 1000"),
    ({"page_size": 131072}, "page_size is 131072"),
])
def test_bad_input_is_refused_naming_it(change, message):
    args = {"ids": [1, 2], "minx": [0.0, 0.0], "maxx": [1.0, 1.0], "miny": [0.0, 0.0],
            "maxy": [1.0, 1.0], "page_size": 4096}
    args.update(change)
    before = {k: np.array(v, copy=True) for k, v in args.items()}
    with pytest.raises(ValueError) as err:
        packed_rtree(**args)
    assert message in str(err.value)
    for k, v in before.items():
        np.testing.assert_array_equal(np.asarray(args[k]), v)


def test_insert_refuses_a_full_tree_a_wrong_node_size_and_changes_nothing():
    boxes = _random_boxes(100, 41)
    db = _packed(np.arange(1, 101), boxes)
    before = _stored(db, "packed")
    other = packed_rtree(np.arange(1, 11), *_random_boxes(10, 42))
    with pytest.raises(ValueError, match="holds 100 entries"):
        insert_rtree_rows(db, "packed", other)
    small = packed_rtree(np.arange(1, 11), *_random_boxes(10, 42), page_size=1024)
    with pytest.raises(ValueError, match="960-byte nodes"):
        insert_rtree_rows(db, "packed", small, replace=True)
    with pytest.raises(ValueError, match="not an rtree"):
        insert_rtree_rows(db, "nothing", other)
    # a failure half-way (a rowid twice: the _rowid insert fails after the nodes went in)
    broken = dataclasses.replace(other, rowids=np.ones(10, np.int64))
    with pytest.raises(sqlite3.IntegrityError):
        insert_rtree_rows(db, "packed", broken, replace=True)
    np.testing.assert_array_equal(_stored(db, "packed"), before)
    _check(db, "packed")
    insert_rtree_rows(db, "packed", other, replace=True)
    _check(db, "packed")
    assert len(_stored(db, "packed")) == 10


def test_str_order_with_more_slices_than_16_bits():
    """A very elongated level (70,000 slices of 2 nodes): the (slice, y) keys take 48 bits."""
    from toolbox.io.sqlite_rtree import _pack_order, _quantise

    rng = np.random.default_rng(3)
    n_nodes, q = 140_000, 2
    cx, cy = rng.random(n_nodes * q) * 35_000.0, rng.random(n_nodes * q)
    order = _pack_order(cx, cy, n_nodes, q, 0)
    np.testing.assert_array_equal(np.sort(order), np.arange(order.size))
    qx = _quantise(cx)[order].reshape(70_000, 4)  # slices of 2 nodes of 2 items
    assert (qx.max(axis=1)[:-1] <= qx.min(axis=1)[1:]).all()  # side by side in x
    assert (np.diff(cy[order].reshape(70_000, 4), axis=1) >= 0).all()  # each by y


@pytest.mark.parametrize("case", ["uniform", "ties", "clusters"])
def test_slices_are_exact_x_rank_ranges(case):
    """The counting STR slicing puts exactly the items of x rank bounds[t]..bounds[t+1]-1 in slice
    t (ties in input order), as a stable argsort ranks them, also when the histogram's buckets
    are crowded (ties, clusters)."""
    from toolbox.io.sqlite_rtree import _slice_ids

    rng = np.random.default_rng(len(case))
    n = 50_000
    if case == "uniform":
        qx = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(np.uint32)
    elif case == "ties":
        qx = (rng.integers(0, 50, n) * 1000 + 2 ** 31).astype(np.uint32)
    else:
        qx = np.concatenate([rng.integers(0, 2 ** 16, n // 2),
                             rng.integers(2 ** 31, 2 ** 31 + 2 ** 17, n - n // 2)]).astype(np.uint32)
    for slices in (2, 37, 250):
        bounds = np.linspace(0, n, slices + 1).astype(np.int64)
        rank = np.empty(n, np.int64)
        rank[np.argsort(qx, kind="stable")] = np.arange(n)
        np.testing.assert_array_equal(_slice_ids(qx, bounds),
                                      np.searchsorted(bounds, rank, "right") - 1)
