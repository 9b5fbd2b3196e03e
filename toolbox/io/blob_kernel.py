"""GeoPackage geometry blobs, their boxes and the R-tree's stored boxes in one compiled pass
(numba; also compiled ahead of time, :mod:`toolbox.aot`): the twin of
:func:`toolbox.io.gpkg_bulk.geometry_blobs`' numpy steps for the bulk writer's encoding threads.

The numpy steps read each coordinate column through a strided, unaligned view of the WKB
records, store the envelope through another and round the R-tree's boxes to float32 in a
third pass (0.28 s of CPU for a 1 M-point TIN's 2 M triangles); here each record is read once.
The numpy steps stay the writer where no compiled module is built, and the oracle (tests: the
same bytes and boxes).
"""

from __future__ import annotations

import numba
import numpy as np

# SQLite's rtreeValueDown / rtreeValueUp factors, as the numpy rounding uses them
from toolbox.io.sqlite_rtree import _RNDAWAY, _RNDTOWARDS


@numba.njit(cache=True, nogil=True, inline="always")
def _stored(value, down):
    """``value`` as SQLite's rtree stores a lower (``down``) or upper bound in float32."""
    f = np.float32(value)
    if (f > value) if down else (f < value):
        away = (value < 0) if down else (value >= 0)
        f = np.float32(value * (_RNDAWAY if away else _RNDTOWARDS))
    return f


@numba.njit(cache=True, nogil=True)
def gpkg_blobs(wkb, head, dims, header, envelope, out, boxes, stored):
    """Fill ``out`` (n, 8 + 8 ``envelope`` + size) with GeoPackage blobs of the ``(n, size)``
    little-endian WKB records ``wkb`` (``head`` bytes before ``dims`` coordinates a point):
    the 8 ``header`` bytes, the envelope ``[minx, maxx, miny, maxy(, minz, maxz)]`` when
    ``envelope`` (its count of doubles: 0, 4 or 6), the WKB. ``boxes`` (n, 4) float64 gets
    ``[minx, maxx, miny, maxy]``, ``stored`` (n, 4) float32 (or (0, 4): none) the same rounded
    outward as SQLite stores them. Returns the count of records with a NaN or infinite
    coordinate (written all the same: the caller refuses the batch)."""
    n, size = wkb.shape
    points = (size - head) // (8 * dims)
    body = 8 + 8 * envelope
    bad = 0
    for i in range(n):
        row = wkb[i]
        blob = out[i]
        for k in range(8):
            blob[k] = header[k]
        copy = blob[body:]
        for k in range(size):  # (a slice of its own: a loop LLVM vectorises)
            copy[k] = row[k]
        coords = row[head:head + 8 * dims * points].view(np.float64)
        extremes = blob[8:body].view(np.float64) if envelope else coords[:0]
        finite = True
        for d in range(dims):
            low = coords[d]
            high = low
            finite &= np.isfinite(low)
            for p in range(1, points):
                v = coords[p * dims + d]
                low = min(low, v)
                high = max(high, v)
                finite &= np.isfinite(v)
            if envelope:
                extremes[2 * d] = low
                extremes[2 * d + 1] = high
            if d < 2:
                boxes[i, 2 * d] = low
                boxes[i, 2 * d + 1] = high
                if stored.shape[0]:
                    stored[i, 2 * d] = _stored(low, True)
                    stored[i, 2 * d + 1] = _stored(high, False)
        if not finite:
            bad += 1
    return bad
