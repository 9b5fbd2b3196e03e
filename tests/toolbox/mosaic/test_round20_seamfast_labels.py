"""Round 20 (seamfast): window_labels makes its passes over strips of rows (the strip's arrays
stay in the CPU's cache); every strip size, a last strip shorter than the others included,
gives the labels of the rule checked cell by cell in test_window_labels.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import shapely
from affine import Affine
from rasterio.windows import Window

import toolbox.mosaic.build as build
from tests.toolbox.mosaic.test_window_labels import rule


@pytest.mark.parametrize("strip_cells", [1, 31, 5 * 31 + 7, 23 * 31, 10**6])
@pytest.mark.parametrize("sources", [1, 2, 3])
def test_labels_by_strips_follow_the_rule(monkeypatch, strip_cells, sources):
    monkeypatch.setattr(build, "LABEL_STRIP_CELLS", strip_cells)
    rng = np.random.default_rng(strip_cells + sources)
    rows, cols = 23, 31
    edges = np.linspace(0, cols - 4, sources + 1)
    cells = [shapely.box(edges[k], 0, edges[k + 1], rows) for k in range(sources)]
    grid = SimpleNamespace(window_transform=lambda w: Affine(1, 0, 0, 0, -1, rows))
    plan = SimpleNamespace(cells=cells, grid=grid)
    valid = rng.random((sources, rows, cols)) < 0.6
    out = build.window_labels(plan, Window(0, 0, cols, rows), valid)
    from rasterio.features import rasterize

    labels = rasterize([(c, k) for k, c in enumerate(cells)], out_shape=(rows, cols),
                       transform=grid.window_transform(None), fill=-1, dtype="int16")
    assert out.dtype == np.int16 and out.shape == (rows, cols)
    np.testing.assert_array_equal(out, rule(labels, valid))
