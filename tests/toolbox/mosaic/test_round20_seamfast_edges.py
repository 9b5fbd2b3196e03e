"""Round 20 (seamfast): label_edges finds the cells where two labels meet from one full-size
comparison (_label_changes), then drops the few next to "no data". The reference is a plain
Python loop over every pair of neighbouring cells (label_edges itself is checked against the
mosaic's source index in tests/algorithms/mosaic/test_seams_match_index.py)."""

from __future__ import annotations

import numpy as np
import pytest


def _brute_changes(first: np.ndarray, second: np.ndarray) -> list[tuple[int, int, int, int]]:
    rows, cols = first.shape
    return [(r, c, int(first[r, c]), int(second[r, c])) for r in range(rows) for c in range(cols)
            if first[r, c] != second[r, c] and first[r, c] >= 0 and second[r, c] >= 0]


@pytest.mark.parametrize("shape", [(40, 57), (1, 9), (9, 1), (1, 1), (0, 4), (6, 0)])
@pytest.mark.parametrize("nodata", [0.0, 0.2, 0.9])
def test_label_changes_are_the_neighbours_that_differ(shape, nodata):
    from toolbox.mosaic.index_seams import _label_changes

    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    labels = rng.integers(0, 3, shape).astype("int16")
    labels[rng.random(shape) < nodata] = -1
    for first, second in ((labels[:, :-1], labels[:, 1:]), (labels[:-1], labels[1:])):
        r, c, la, lb = _label_changes(first, second)
        got = list(zip(r.tolist(), c.tolist(), la.tolist(), lb.tolist(), strict=True))
        assert got == _brute_changes(first, second)

