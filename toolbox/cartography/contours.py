"""Contour lines ("curve di livello") from a DEM grid or a TIN, arrays in, arrays out.

Conventions: a DEM grid is ``z[row, col]`` with cell values at cell centres; ``x0, y0`` is the
centre of cell (0, 0) and ``dx, dy`` the steps between centres (``dy < 0`` for north-up rasters).
Between centres the surface is bilinear, as for ``gdal_contour``; contours are traced either
by contourpy (one pass per level) or for all levels in one pass by the compiled kernel of
:mod:`toolbox.cartography.contour_kernel` (contourpy's lines, its test oracle), whichever
:func:`choose_tracer` expects to cost less in the whole process. A TIN is nodes ``xyz (N, 3)``
and triangles ``(T, 3)``; each triangle is a plane.

Every contour is an ``(n, 2)`` array of x, y (DEM kernels work in grid coordinates, x = column
and y = row of the cell centres, and :func:`to_map` converts), oriented with higher ground on its right (as
ArcGIS and QGIS label placement assume); closed contours repeat their first vertex.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np


@dataclass
class Contour:
    """One contour line: its elevation and its vertices ``(n, 2)``."""

    level: float
    xy: np.ndarray

    @property
    def closed(self) -> bool:
        return len(self.xy) > 2 and bool(np.array_equal(self.xy[0], self.xy[-1]))


def contour_levels(zmin: float, zmax: float, interval: float, base: float = 0.0) -> np.ndarray:
    """Levels ``base + k·interval`` within ``[zmin, zmax]`` (the thesis: 5 m at 1:5000)."""
    if not interval > 0:
        raise ValueError(f"interval must be > 0, got {interval}")
    if not (np.isfinite(zmin) and np.isfinite(zmax)) or zmax < zmin:
        return np.empty(0)
    k0 = np.ceil((zmin - base) / interval)
    k1 = np.floor((zmax - base) / interval)
    return base + np.arange(k0, k1 + 1) * interval


def index_flags(levels: np.ndarray, interval: float, base: float = 0.0,
                every: int = 5) -> np.ndarray:
    """True for index contours: every ``every``-th level counted from ``base``."""
    k = np.rint((np.asarray(levels, dtype="float64") - base) / interval).astype(np.int64)
    return (k % every) == 0 if every > 0 else np.zeros(len(k), dtype=bool)


# -- DEM grids ------------------------------------------------------------------------------------
#: the tracers of a DEM grid: contourpy (one pass per level) and the compiled one-pass kernel
TRACERS = ("contourpy", "kernel")

#: the cost model of the two tracers in CPU seconds of the whole process, measured on the house
#: bench's 2200 x 2200 DEM at 10 m (21 levels) and round3's 2000 x 2000 DEM at 1 m (57 levels),
#: blocks of 513 x 513 (bench/results/house.md, "Round four (contours)"): contourpy costs about
#: 8 ns per cell and level that a block spans (its heights reach above and below the level); the
#: kernel about 60 ns per cell whatever the levels, plus numba's import and the load of its
#: cached kernels, about 0.65 s in any process that traces with it; or, when the kernel was
#: compiled ahead of time (:mod:`toolbox.aot`), the load of its module, about 0.02 s
CONTOURPY_S_PER_CELL_LEVEL = 8e-9
KERNEL_S_PER_CELL = 60e-9
KERNEL_FIXED_S = 0.65
KERNEL_COMPILED_FIXED_S = 0.02


def choose_tracer(cells: int, spanned: int) -> str:
    """The cheaper tracer (:data:`TRACERS`) of a grid of ``cells`` whose blocks span
    ``spanned`` cells x levels in all (at most cells x levels) by the cost model above:
    ``"contourpy"`` for few levels or small grids (numba is then never imported), else
    ``"kernel"``."""
    from toolbox.aot import compiled_available

    fixed = KERNEL_COMPILED_FIXED_S if compiled_available("contour_lines") else KERNEL_FIXED_S
    kernel = fixed + KERNEL_S_PER_CELL * cells
    return "kernel" if CONTOURPY_S_PER_CELL_LEVEL * spanned > kernel else "contourpy"


def spanned_cells_levels(z: np.ndarray, levels: np.ndarray,
                         windows: Iterable[tuple[int, int, int, int]]) -> int:
    """Sum over the blocks ``windows`` (row, col, height, width) of ``z`` (NaN = no data) of
    their cells times the ``levels`` (ascending) their heights span."""
    total = 0
    for r, c, h, w in windows:
        block = z[r:r + h, c:c + w]
        if np.isnan(block).all():
            continue
        lo, hi = np.searchsorted(levels, [np.nanmin(block), np.nanmax(block)])
        total += block.size * int(hi - lo)
    return total


def contourpy_lines(z: np.ndarray, levels: np.ndarray, x0: float = 0.0, y0: float = 0.0,
                    dx: float = 1.0, dy: float = 1.0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`toolbox.cartography.contour_kernel.grid_lines` traced by contourpy (serial,
    corner mask: the same surface and lines), one pass per level the grid spans.

    Returns ``points (n, 2)`` (x = ``x0 + column·dx``, y = ``y0 + row·dy``: contourpy
    interpolates between the nodes' own coordinates, so a block traced with its place in the
    grid gives the whole grid's vertices, bit for bit), ``offsets`` and each line's index into
    ``levels`` (ascending), higher ground on the right in the (column, row) frame.
    """
    import contourpy

    rows, cols = z.shape
    valid = ~np.isnan(z)
    empty = np.empty((0, 2)), np.zeros(1, dtype=np.int64), np.empty(0, dtype=np.int32)
    if not valid.any():
        return empty
    lo, hi = np.searchsorted(levels, [np.nanmin(z), np.nanmax(z)])  # the levels spanned
    if lo >= hi:
        return empty
    data = z if valid.all() else np.ma.array(z, mask=~valid)
    gen = contourpy.contour_generator(x0 + np.arange(cols) * dx, y0 + np.arange(rows) * dy,
                                      data, name="serial",
                                      corner_mask=True,
                                      line_type=contourpy.LineType.ChunkCombinedOffset)
    parts, offsets, level_of, n = [], [np.zeros(1, dtype=np.int64)], [], 0
    for k in range(lo, hi):
        (points,), (line_offsets,) = gen.lines(float(levels[k]))
        if points is None:
            continue
        # contourpy keeps higher ground on the left: the level's points reversed reverse every
        # line (and their order)
        parts.append(points[::-1])
        offsets.append(n + (len(points) - line_offsets[-2::-1]).astype(np.int64))
        level_of.append(np.full(len(line_offsets) - 1, k, dtype=np.int32))
        n += len(points)
    if not parts:
        return empty
    return np.concatenate(parts), np.concatenate(offsets), np.concatenate(level_of)


def grid_contour_pieces(z: np.ndarray, levels: Iterable[float], x0: float, y0: float,
                        dx: float, dy: float, tracer: str | None = None) -> list[Contour]:
    """Contours of one grid (NaN = no data), oriented higher-on-the-right, traced by
    ``tracer`` (:data:`TRACERS`; default :func:`choose_tracer` for this grid): contourpy
    (:func:`contourpy_lines`) or the one-pass kernel
    (:func:`toolbox.cartography.contour_kernel.grid_lines`), the same lines.

    Lines end where the grid or the data end; :func:`stitch` joins pieces of adjacent tiles.
    """
    z = np.asarray(z, dtype="float64")
    levels = np.sort(np.asarray(list(levels), dtype="float64"))
    if z.shape[0] < 2 or z.shape[1] < 2 or not len(levels):
        return []
    tracer = tracer or choose_tracer(z.size, z.size * len(levels))
    # trace just below the level so a node exactly at it counts as above (as gdal_contour and
    # tin_contours do); the offset (1024 ulps) moves lines by far less than a micron
    below = levels - 1024 * np.spacing(np.abs(levels))
    if tracer == "kernel":  # the nodes' coordinates as contourpy's: the same vertices
        xy, offsets, level_of = kernel_lines(z, below, x0 + np.arange(z.shape[1]) * dx,
                                             y0 + np.arange(z.shape[0]) * dy)
    elif tracer == "contourpy":
        xy, offsets, level_of = contourpy_lines(z, below, x0, y0, dx, dy)
    else:
        raise ValueError(f"tracer must be one of {TRACERS}, got {tracer!r}")
    # both keep higher ground on the right in the (column, row) frame: mirrored when the map
    # frame turns the other way (dx·dy < 0)
    flip = (dx * dy) < 0
    values = levels[level_of].tolist()
    return [Contour(values[i], line[::-1] if flip else line)
            for i, line in _split_lines(xy, offsets)]


def kernel_lines(z: np.ndarray, levels: np.ndarray, xs: np.ndarray, ys: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`toolbox.cartography.contour_kernel.grid_lines` of a grid of at least 2 x 2 nodes
    (at x = ``xs[column]``, y = ``ys[row]``) and one level, by the kernel's ahead-of-time build
    when this machine has one (:mod:`toolbox.aot`: numba is not imported), else by numba's JIT:
    the same arrays."""
    from toolbox.aot import compiled_kernel

    compiled = compiled_kernel("contour_lines")
    if compiled is None:
        from toolbox.cartography.contour_kernel import grid_lines

        return grid_lines(z, levels, xs, ys)
    return compiled(*(np.ascontiguousarray(a, dtype=np.float64) for a in (z, levels, xs, ys)))


def _split_lines(points: np.ndarray, offsets: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """``(i, line)``: the lines of a combined ``(n, 2)`` point array (line ``i`` is
    ``offsets[i]:offsets[i+1]``) without vertices equal to their predecessor, and without
    lines left with fewer than 2 vertices (crossings exactly at a node)."""
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = (points[1:] != points[:-1]).any(axis=1)
    keep[offsets[:-1]] = True  # a line's first vertex follows another line's last
    kept_before = np.concatenate([[0], np.cumsum(keep)])
    new_offsets = kept_before[offsets]
    points = points[keep]
    return [(i, points[a:b]) for i, (a, b) in
            enumerate(zip(new_offsets[:-1].tolist(), new_offsets[1:].tolist(), strict=True))
            if b - a >= 2]


@dataclass
class Piece:
    """A contour piece traced in one tile (tiles are indexed by their first row and column)."""

    level: float
    xy: np.ndarray
    tile: tuple[int, int]


def block_windows(rows: int, cols: int, tile: int) -> list[tuple[int, int, int, int]]:
    """``(row, col, height, width)`` of the ``tile``-sized blocks of a ``rows`` x ``cols`` grid;
    a block shares its last row and column with the next, so every grid square is in one block."""
    return [(r, c, min(tile + 1, rows - r), min(tile + 1, cols - c))
            for r in range(0, max(rows - 1, 1), tile) for c in range(0, max(cols - 1, 1), tile)]


def block_pieces(block: np.ndarray, levels: Iterable[float], row: int, col: int,
                 tracer: str | None = None) -> list[Piece]:
    """The contour pieces of one block whose top-left cell is (``row``, ``col``), in grid
    coordinates (x = column, y = row of the cell centres), traced by ``tracer``
    (:func:`grid_contour_pieces`)."""
    return [Piece(p.level, p.xy, (row, col))
            for p in grid_contour_pieces(block, levels, float(col), float(row), 1.0, 1.0, tracer)]


def trace_tiles(read_block: Callable[[int, int, int, int], np.ndarray], rows: int, cols: int,
                tile: int, levels: Iterable[float], feedback=None,
                tracer: str | None = None) -> tuple[list[Contour], int]:
    """Contours of a ``rows`` x ``cols`` grid traced in ``tile``-sized blocks
    (:func:`block_windows`) by ``tracer`` (default: :func:`choose_tracer` for the whole grid)
    and stitched by :func:`stitch_pieces`, in grid coordinates (:func:`to_map` converts). Grid
    coordinates keep full precision near nodes and make tile edges exact integers.

    ``read_block(row, col, height, width)`` returns a block of the grid (NaN = no data).
    Returns the contours and the number of pieces traced.
    """
    levels = list(levels)
    windows = block_windows(rows, cols, tile)
    tracer = tracer or choose_tracer(rows * cols, rows * cols * len(levels))
    pieces: list[Piece] = []
    for i, (r, c, h, w) in enumerate(windows):
        if feedback is not None:
            feedback.check_canceled()
            feedback.set_progress(80.0 * i / len(windows))
        pieces += block_pieces(read_block(r, c, h, w), levels, r, c, tracer)
    return stitch_pieces(pieces, tile), len(pieces)


def to_map(contours: list[Contour], x0: float, y0: float, dx: float, dy: float) -> list[Contour]:
    """Grid-coordinate contours (higher ground on the right) in map coordinates, still with
    higher ground on the right."""
    scale, origin, flip = np.array([dx, dy]), np.array([x0, y0]), dx * dy < 0
    out = []
    for c in contours:
        xy = c.xy * scale + origin  # x0 + x·dx, y0 + y·dy: the same values as column by column
        out.append(Contour(c.level, xy[::-1] if flip else xy))
    return out


def stitch_pieces(pieces: list[Piece], tile: int) -> list[Contour]:
    """Join pieces traced in adjacent tiles into whole lines, by topology, not by distance.

    On each shared tile edge, the ends of one level's pieces from the two tiles cross the same
    grid edges (one crossing per level and edge), so sorted along the tile edge they pair up one
    to one (an end whose partner is missing, where no data lies across the edge, stays open).
    Paired ends get identical coordinates and the pieces are chained head to tail: no break, no
    duplicated vertex, and near-coincident points elsewhere are never merged.
    """
    tol = 1e-9  # grid units: ends on a tile edge have an exactly integer coordinate
    n = len(pieces)
    if not n:
        return []
    # every piece's two ends, end e = 2 * piece + (0 first vertex, 1 last)
    ends = np.array([(p.xy[0], p.xy[-1]) for p in pieces], dtype="float64").reshape(-1, 2)
    tile_r0, tile_c0 = np.repeat(np.array([p.tile for p in pieces], dtype=np.int64), 2, axis=0).T
    level = np.repeat(np.array([p.level for p in pieces], dtype="float64"), 2)
    ring = np.repeat((ends[0::2] == ends[1::2]).all(axis=1), 2)
    col, row = ends[:, 0], ends[:, 1]
    # an end lies on a grid edge: its coordinate across that edge is an exact integer (a
    # crossing next to a node is off by ~1e-10 along the edge, never across it); "v": a
    # vertical grid line (x = column), taken on a tie
    vertical = np.abs(col - np.round(col)) <= np.abs(row - np.round(row))
    pos_line = np.where(vertical, col, row)
    along = np.where(vertical, row, col)
    start = np.where(vertical, tile_c0, tile_r0)
    other = np.where(vertical, tile_r0, tile_c0)  # the tile along the line
    line = np.round(pos_line)
    side = np.where(line == start + tile, 0, 1)  # 0: the tile before the line
    on_edge = ~ring & (np.abs(pos_line - line) <= tol) & (line % tile == 0) & (line != 0) & \
        ((side == 0) | (line == start))
    # ends on one tile edge and level, those of the tile before it then after it, each along the
    # edge (stable: ties keep the pieces' order)
    e = np.nonzero(on_edge)[0]
    e = e[np.lexsort((along[e], side[e], other[e], line[e], vertical[e], level[e]))]
    group = np.column_stack([level[e], vertical[e], line[e], other[e]])
    starts = np.flatnonzero(np.r_[True, (group[1:] != group[:-1]).any(axis=1), True])
    e_list, side_list, along_list = e.tolist(), side[e].tolist(), along[e].tolist()
    link: dict[tuple[int, int], tuple[int, int]] = {}
    for g0, g1 in zip(starts[:-1].tolist(), starts[1:].tolist(), strict=True):
        split = g0 + side_list[g0:g1].count(0)
        i, j = g0, split  # merge the two sorted runs; an end with no partner (no data across
        while i < split and j < g1:  # the tile edge) stays an end
            pa, pb = along_list[i], along_list[j]
            if abs(pa - pb) <= 1e-7:
                a, b = divmod(e_list[i], 2), divmod(e_list[j], 2)
                link[a], link[b] = b, a
                i, j = i + 1, j + 1
            elif pa < pb:
                i += 1
            else:
                j += 1
    return _chain(pieces, link)


def _chain(pieces: list[Piece], link: dict[tuple[int, int], tuple[int, int]]) -> list[Contour]:
    """Walk linked piece ends into lines (reversing pieces entered by their last vertex)."""
    seen = [False] * len(pieces)
    out: list[Contour] = []

    def walk(i: int, entered_at: int) -> tuple[list[np.ndarray], bool]:
        parts, closed = [], False
        first = i
        while True:
            seen[i] = True
            xy = pieces[i].xy if entered_at == 0 else pieces[i].xy[::-1]
            parts.append(xy if not parts else xy[1:])
            nxt = link.get((i, 1 - entered_at))
            if nxt is None:
                break
            j, end = nxt
            if j == first:
                closed = True
                break
            if seen[j]:
                break
            i, entered_at = j, end
        return parts, closed

    # open lines start at an unlinked first vertex (keeps the orientation), then any other
    # unlinked end; what is left are rings
    for entry in (0, 1):
        for i, p in enumerate(pieces):
            if not seen[i] and (i, entry) not in link:
                parts, _ = walk(i, entry)
                xy = parts[0] if len(parts) == 1 else np.concatenate(parts)  # a lone piece
                out.append(Contour(p.level, xy))
    for i, p in enumerate(pieces):
        if not seen[i]:
            parts, _ = walk(i, 0)
            xy = np.concatenate(parts)
            xy[-1] = xy[0]  # the last piece ends where the first began
            out.append(Contour(p.level, xy))
    return out


def dem_contours(z: np.ndarray, levels: Iterable[float], x0: float, y0: float, dx: float,
                 dy: float, tile: int | None = None, smoothing: int = 0,
                 tracer: str | None = None) -> list[Contour]:
    """Contours of a whole grid in map coordinates, optionally traced in ``tile`` x ``tile``
    blocks and stitched, and smoothed (files go through
    :func:`toolbox.cartography.contour_io.raster_contours`); ``tracer`` as
    :func:`trace_tiles`."""
    rows, cols = z.shape
    contours, _ = trace_tiles(lambda r, c, h, w: z[r:r + h, c:c + w], rows, cols,
                              tile or max(rows, cols), levels, tracer=tracer)
    contours, _ = smooth_contours(contours, smoothing)
    return to_map(contours, x0, y0, dx, dy)


# -- TINs -----------------------------------------------------------------------------------------
def tin_contours(xyz: np.ndarray, triangles: np.ndarray, levels: Iterable[float]) -> list[Contour]:
    """Contours of a TIN: each triangle's plane cut at every level, segments chained.

    A node exactly at a level counts as above it, so a triangle holds at most one segment per
    level. Crossing points are interpolated from the lower node id to the higher one, so the two
    triangles sharing an edge produce bit-identical points and chain exactly.
    """
    import shapely

    xyz = np.asarray(xyz, dtype="float64")
    tri = np.asarray(triangles, dtype=np.int64)
    if not len(tri):
        return []
    tz = xyz[tri, 2]
    zmin, zmax = tz.min(axis=1), tz.max(axis=1)
    out: list[Contour] = []
    for level in levels:
        level = float(level)
        sel = np.nonzero((zmin < level) & (zmax >= level))[0]
        if not len(sel):
            continue
        t = tri[sel]
        above = xyz[t, 2] >= level  # (m, 3)
        points = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            a, b = np.minimum(t[:, i], t[:, j]), np.maximum(t[:, i], t[:, j])
            za, zb = xyz[a, 2], xyz[b, 2]
            crosses = above[:, i] != above[:, j]
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(crosses, (level - za) / (zb - za), np.nan)
            p = xyz[a, :2] + f[:, None] * (xyz[b, :2] - xyz[a, :2])
            points.append((crosses, p))
        # the two crossed edges of each triangle, in edge order
        crossed = np.column_stack([c for c, _ in points])
        pts = np.stack([p for _, p in points], axis=1)  # (m, 3 edges, 2)
        first = np.argmax(crossed, axis=1)
        second = 2 - np.argmax(crossed[:, ::-1], axis=1)
        rows = np.arange(len(sel))
        p, q = pts[rows, first], pts[rows, second]
        # the node on its own side of the level: above when the other two are below
        n_above = above.sum(axis=1)
        lone = np.where(n_above == 1, np.argmax(above, axis=1), np.argmin(above, axis=1))
        lone_xy = xyz[t[rows, lone], :2]
        d, e = q - p, lone_xy - p
        side = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]  # > 0: lone node on the left
        lone_is_above = n_above == 1
        # higher ground on the right: an above lone node must be right (side < 0)
        swap = np.where(lone_is_above, side > 0, side < 0)
        p2 = np.where(swap[:, None], q, p)
        q2 = np.where(swap[:, None], p, q)
        segs = shapely.linestrings(np.stack([p2, q2], axis=1))
        merged = shapely.line_merge(shapely.multilinestrings(segs), directed=True)
        for part in shapely.get_parts(merged):
            out.append(Contour(level, shapely.get_coordinates(part)))
    return out


# -- smoothing ------------------------------------------------------------------------------------
def _chaikin(xy: np.ndarray, closed: bool) -> np.ndarray:
    """One round of Chaikin corner cutting (points at 1/4 and 3/4 of every segment); open lines
    keep their end points."""
    a, b = xy[:-1], xy[1:]
    q = 0.75 * a + 0.25 * b
    r = 0.25 * a + 0.75 * b
    inner = np.empty((2 * len(a), 2))
    inner[0::2], inner[1::2] = q, r
    if closed:
        return np.vstack([inner, inner[:1]])
    return np.vstack([xy[:1], inner[1:-1], xy[-1:]])


def _cells_of(xy: np.ndarray) -> np.ndarray:
    """(k, 2) integer (col, row) of the grid square (between four centres) holding each point
    given in grid coordinates."""
    return np.floor(xy).astype(np.int64)


def _cell_keys(cells: np.ndarray) -> np.ndarray:
    return cells[:, 0] * (1 << 32) + cells[:, 1]


def smooth_in_band(contour: Contour, iterations: int) -> np.ndarray:
    """Chaikin-smoothed vertices of a DEM contour (grid coordinates) within its cell band.

    The band is the set of grid cells (squares between four centres) the unsmoothed contour
    crosses: the level lies between those cells' corner heights. A smoothing round is kept only
    when every new vertex lies in a band cell and consecutive vertices lie in the same or
    edge-adjacent band cells (two such cells form a rectangle, so the segment between them stays
    inside the band too); otherwise the last valid round is returned.
    """
    xy = contour.xy
    mid = 0.5 * (xy[:-1] + xy[1:])
    band = np.unique(_cell_keys(_cells_of(mid)))
    current = xy
    for _ in range(iterations):
        candidate = _chaikin(current, contour.closed)
        cells = _cells_of(candidate)
        inner = cells if contour.closed else cells[1:-1]
        if not np.isin(_cell_keys(inner), band, assume_unique=False).all():
            break
        step = np.abs(np.diff(cells[1:-1] if not contour.closed else cells, axis=0)).sum(axis=1)
        if (step > 1).any():
            break
        current = candidate
    return current


def smooth_contours(contours: list[Contour], iterations: int) -> tuple[list[Contour], int]:
    """Smooth DEM contours (grid coordinates) within their cell bands, then undo the smoothing
    of any two lines that touch or cross each other, until none do. Returns the lines and how
    many were reverted."""
    if iterations <= 0 or not contours:
        return contours, 0
    import shapely

    smooth = [Contour(c.level, smooth_in_band(c, iterations)) for c in contours]
    reverted: set[int] = set()
    while True:
        geoms = np.array([shapely.linestrings(c.xy) for c in smooth]) if len(smooth) > 1 else None
        if geoms is None:
            break
        tree = shapely.STRtree(geoms)
        left, right = tree.query(geoms, predicate="intersects")
        bad = {int(i) for i, j in zip(left, right) if i != j} - reverted
        if not bad:
            break
        for i in bad:
            smooth[i] = contours[i]
        reverted |= bad
    return smooth, len(reverted)
