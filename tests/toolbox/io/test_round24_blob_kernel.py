"""Round 24: GeoPackage geometry blobs in one compiled pass (toolbox.io.blob_kernel) against the
numpy steps of gpkg_bulk.geometry_blobs (themselves checked against GDAL's writer in
test_round21_tinbulk.py and SQLite's rtree rounding in test_round21_gpkgrtree_sqlite.py):
points, line strings and polygons, 2-D and 3-D, coordinates of every size (beyond float32's
range too) give the same blobs, boxes and stored boxes through numba's JIT and, where built, the
compiled module; a NaN or infinite coordinate anywhere is refused both ways."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from toolbox.aot import compiled_kernel
from toolbox.io import blob_kernel, gpkg_bulk

#: (WKB type code, points a record, bytes before the coordinates)
SHAPES = {"point": (1, 1, 5), "line": (2, 2, 9), "polygon": (3, 4, 13)}
COORDS = st.sampled_from([1e-3, 1.0, 1e3, 1.7e6, 4.8e6, 1e30, 1e39, 1e300])


def wkb_records(shape: str, dims: int, coords: np.ndarray) -> np.ndarray:
    """Little-endian ISO WKB records of one shape (a polygon: one ring of ``points``)."""
    code, points, head = SHAPES[shape]
    n = len(coords)
    out = np.zeros((n, head + 8 * dims * points), np.uint8)
    out[:, 0] = 1
    out[:, 1:5] = np.frombuffer(np.uint32(code + (1000 if dims == 3 else 0)).tobytes(),
                                np.uint8)
    if shape == "line":
        out[:, 5:9] = np.frombuffer(np.uint32(points).tobytes(), np.uint8)
    if shape == "polygon":
        out[:, 5:9] = np.frombuffer(np.uint32(1).tobytes(), np.uint8)
        out[:, 9:13] = np.frombuffer(np.uint32(points).tobytes(), np.uint8)
    out[:, head:] = coords.reshape(n, -1).view(np.uint8)
    return out


def run(kernel, wkb: np.ndarray, monkeypatch):
    stored = np.full((len(wkb), 4), -7.0, np.float32)
    with monkeypatch.context() as m:
        m.setattr(gpkg_bulk, "compiled_kernel", lambda name: kernel)
        blobs, boxes = gpkg_bulk.geometry_blobs(wkb, 3003, stored)
    return blobs, boxes, stored


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), shape=st.sampled_from(sorted(SHAPES)),
       dims=st.sampled_from([2, 3]), n=st.integers(1, 300), scale=COORDS,
       signed=st.booleans())
def test_the_compiled_pass_gives_the_numpy_blobs_and_boxes(seed, shape, dims, n, scale, signed):
    rng = np.random.default_rng(seed)
    points = SHAPES[shape][1]
    coords = rng.uniform(-scale if signed else 0.0, scale, (n, points, dims))
    if shape == "polygon":
        coords[:, -1] = coords[:, 0]  # a closed ring
    wkb = wkb_records(shape, dims, coords)
    with pytest.MonkeyPatch.context() as m:
        want = run(None, wkb, m)
        got = run(blob_kernel.gpkg_blobs, wkb, m)
        built = compiled_kernel("gpkg_blobs")
        compiled = run(built, wkb, m) if built is not None else want
    for mine, theirs, other in zip(got, want, compiled, strict=True):
        np.testing.assert_array_equal(mine, theirs)
        np.testing.assert_array_equal(other, theirs)
    assert got[1][:, 0].tolist() == coords[:, :, 0].min(axis=1).tolist()  # the boxes' minx


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("at", [(0, 0, 0), (2, 3, 1), (4, 1, 2)])
def test_a_nan_or_infinity_anywhere_is_refused_both_ways(bad, at, monkeypatch):
    coords = np.random.default_rng(1).uniform(0, 100, (5, 4, 3))
    coords[:, -1] = coords[:, 0]
    coords[at] = bad
    wkb = wkb_records("polygon", 3, coords)
    for kernel in (None, blob_kernel.gpkg_blobs, compiled_kernel("gpkg_blobs")):
        with pytest.raises(gpkg_bulk.BulkUnsupported, match="NaN or infinite"):
            run(kernel, wkb, monkeypatch)
