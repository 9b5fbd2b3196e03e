"""The mosaic's label raster of a window (toolbox.mosaic.build.window_labels): each cell takes
its cut polygon's source where that source has data, else the first source with data, else -1;
checked cell by cell against that rule on random partitions and masks, in both of its ways
(one pass per source for a few sources, one gather for many)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import shapely
from affine import Affine
from rasterio.windows import Window

import toolbox.mosaic.build as build


def rule(labels: np.ndarray, valid: np.ndarray) -> np.ndarray:
    out = np.full(labels.shape, -1, dtype="int16")
    for r in range(labels.shape[0]):
        for c in range(labels.shape[1]):
            k = labels[r, c]
            if k >= 0 and valid[k, r, c]:
                out[r, c] = k
            elif valid[:, r, c].any():
                out[r, c] = int(np.flatnonzero(valid[:, r, c])[0])
    return out


# window_labels makes its passes over strips of rows (kept in the CPU's cache): every strip
# size, a last strip shorter than the others included, gives the rule's labels
@pytest.mark.parametrize("strip_cells", [1, 31, 5 * 31 + 7, 23 * 31, 10**6])
@pytest.mark.parametrize("sources", [1, 2, 3, 7, 9])
@pytest.mark.parametrize("few", [0, 6])
def test_window_labels_follow_the_rule(monkeypatch, sources, few, strip_cells):
    monkeypatch.setattr(build, "FEW_SOURCES", few)
    monkeypatch.setattr(build, "LABEL_STRIP_CELLS", strip_cells)
    rng = np.random.default_rng(sources * 10 + few)
    rows, cols = 23, 31
    # vertical strips as cut polygons (the last strip has no polygon: label -1 there)
    edges = np.linspace(0, cols - 4, sources + 1)
    cells = [shapely.box(edges[k], 0, edges[k + 1], rows) for k in range(sources)]
    grid = SimpleNamespace(window_transform=lambda w: Affine(1, 0, 0, 0, -1, rows))
    plan = SimpleNamespace(cells=cells, grid=grid)
    valid = rng.random((sources, rows, cols)) < 0.6
    if sources > 2:
        valid[1] = False  # a source without data in the window
    out = build.window_labels(plan, Window(0, 0, cols, rows), valid)
    from rasterio.features import rasterize

    labels = rasterize([(c, k) for k, c in enumerate(cells)], out_shape=(rows, cols),
                       transform=grid.window_transform(None), fill=-1, dtype="int16")
    assert (labels == -1).any() and (labels >= 0).any()
    assert out.dtype == np.int16
    np.testing.assert_array_equal(out, rule(labels, valid))
