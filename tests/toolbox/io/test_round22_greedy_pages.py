"""Page starts of the bulk page writer (toolbox.io.sqlite_pages._greedy_starts) against a plain
item-by-item greedy fill: runs of equal sizes (counted), pages across runs, sizes all over the
place."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from toolbox.io.sqlite_pages import _greedy_starts


def greedy_by_hand(sizes, cap):
    starts, used = [], cap + 1
    for i, size in enumerate(sizes):
        if used + size > cap:
            starts.append(i)
            used = 0
        used += size
    return starts


runs = st.lists(st.tuples(st.integers(1, 700), st.integers(1, 5000)), min_size=1, max_size=6)


@settings(max_examples=150, deadline=None)
@given(runs, st.sampled_from([4088, 1016, 65528]))
def test_runs_of_sizes(pieces, cap):
    sizes = np.concatenate([np.full(count, min(size, cap), np.int64) for size, count in pieces])
    assert _greedy_starts(sizes, cap).tolist() == greedy_by_hand(sizes.tolist(), cap)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(1, 4088), min_size=1, max_size=3000))
def test_sizes_all_over_the_place(sizes):
    sizes = np.array(sizes, np.int64)
    assert _greedy_starts(sizes, 4088).tolist() == greedy_by_hand(sizes.tolist(), 4088)


def test_a_batch_of_triangles_with_a_few_null_neighbours():
    sizes = np.full(65_536, 279, np.int64)
    sizes[::997] = 276  # border triangles: a NULL neighbour, 3 bytes shorter
    sizes[30_000:] += 1  # the rowid's varint a byte longer from here
    assert _greedy_starts(sizes, 4088).tolist() == greedy_by_hand(sizes.tolist(), 4088)
