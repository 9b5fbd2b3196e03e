"""SQLite table leaf pages laid out and filled in one compiled pass (numba; also compiled ahead
of time, :mod:`toolbox.aot`): the bulk writer's (:mod:`toolbox.io.sqlite_pages`) hot loop.

The numpy twin in :mod:`toolbox.io.sqlite_pages` does the same in whole-array steps: a cell
layout, the headers, the varint prefixes, then the records copied through window views. That
is several passes over a gigabyte for a 1 M-point TIN, and numpy's fancy-index copies hold the
GIL. Here each page is written once, record by record (1 M-point TIN, whole process: 5.91 ->
5.54 s, medians of 5 interleaved; ``bench/results/tin.md``, round twenty-three). The numpy path
stays the writer where no compiled module is built, and the
oracle: the tests compare both byte for byte, and SQLite reads the pages.

File format: https://www.sqlite.org/fileformat2.html (B-tree pages, varints).
"""

from __future__ import annotations

import numba
import numpy as np

_LEAF_TABLE = 0x0D
_LEAF_HEADER = 8  # bytes of a leaf page's header


@numba.njit(cache=True, nogil=True, inline="always")
def _varint_size(value):
    """Bytes of the SQLite varint of the int64 ``value`` (1..9; a negative one takes 9)."""
    if value < 0:
        return 9
    size = 1
    while size < 9 and value >= (numba.int64(1) << (7 * size)):
        size += 1
    return size


@numba.njit(cache=True, nogil=True, inline="always")
def _put_varint(buf, pos, value):
    """Write the SQLite varint of ``value`` at ``buf[pos]``; returns the position after it."""
    size = _varint_size(value)
    u = numba.uint64(value)
    if size == 9:
        buf[pos + 8] = numba.uint8(u & numba.uint64(0xFF))
        u >>= numba.uint64(8)
        for i in range(8):
            buf[pos + 7 - i] = numba.uint8((u & numba.uint64(0x7F)) | numba.uint64(0x80))
            u >>= numba.uint64(7)
        return pos + 9
    for i in range(size):
        byte = u & numba.uint64(0x7F)
        if i:
            byte |= numba.uint64(0x80)
        buf[pos + size - 1 - i] = numba.uint8(byte)
        u >>= numba.uint64(7)
    return pos + size


@numba.njit(cache=True, nogil=True)
def leaf_cells(buf, page_size, rowids, reclen, starts, ends, slots):
    """Lay out table leaf pages in ``buf`` (pages of ``page_size`` bytes): page ``p``
    (at page slot ``slots[p]`` of the buffer) holds rows ``starts[p]`` to ``ends[p] - 1`` of
    ``rowids`` and record lengths ``reclen``, its cells back to back at the page's end in row
    order, each a varint of the record's length, one of the rowid, then the record. Writes
    each page's header (type 0x0D, cell count, content start; 65536 as 0), cell pointers and
    zeros up to the cells (``buf`` may hold an earlier batch's pages), and every cell's two
    varints; returns ``(ends[-1],)`` int64: where each row's record goes
    (rows ``0`` to ``starts[0] - 1`` are not on these pages: -1)."""
    rec_pos = np.full(ends[-1], -1, np.int64)
    for p in range(starts.shape[0]):
        base = slots[p] * page_size
        total = 0
        for i in range(starts[p], ends[p]):
            total += _varint_size(reclen[i]) + _varint_size(rowids[i]) + reclen[i]
        content = page_size - total
        count = ends[p] - starts[p]
        buf[base:base + _LEAF_HEADER] = 0
        buf[base + _LEAF_HEADER + 2 * count:base + content] = 0  # the free space
        buf[base] = _LEAF_TABLE
        buf[base + 3] = (count >> 8) & 0xFF
        buf[base + 4] = count & 0xFF
        buf[base + 5] = (content >> 8) & 0xFF  # 65536 wraps to 0, as the format says
        buf[base + 6] = content & 0xFF
        offset = content
        pointer = base + _LEAF_HEADER
        for i in range(starts[p], ends[p]):
            buf[pointer] = (offset >> 8) & 0xFF
            buf[pointer + 1] = offset & 0xFF
            pointer += 2
            pos = _put_varint(buf, base + offset, reclen[i])
            pos = _put_varint(buf, pos, rowids[i])
            rec_pos[i] = pos
            offset = pos + reclen[i] - base
    return rec_pos


@numba.njit(cache=True, nogil=True)
def copy_records(buf, rec_pos, flat, rec_start, reclen):
    """``buf[rec_pos[i]:][:reclen[i]] = flat[rec_start[i]:][:reclen[i]]`` for every row ``i``."""
    for i in range(rec_pos.shape[0]):
        dst = buf[rec_pos[i]:rec_pos[i] + reclen[i]]
        src = flat[rec_start[i]:rec_start[i] + reclen[i]]
        for j in range(min(dst.shape[0], src.shape[0])):  # 4-5x numba's slice assignment
            dst[j] = src[j]  # (element-wise, with index checks): LLVM vectorises this loop

