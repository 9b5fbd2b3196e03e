"""The typed request for an output grid: cell size, extent, template, size guard.

One set of rules answers it (:meth:`GridRequest.grid`; the grid rules in the notes of
:mod:`toolbox.raster.engine`): ``extent`` is honoured as given, else the data's bounds
snapped outwards to whole cells; a template fixes the lattice and the cell, so ``cell_size``
with a template is an error: one rule for every raster output (the ortho lattice of
:func:`template_lattice` too).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from toolbox.errors import ParameterError
from toolbox.io.grid import GridSpec, cell_slack, max_cells_default, snap_outwards


@dataclass(frozen=True)
class GridRequest:
    """What the caller asks of an output grid.

    ``cell_size``: CRS units (None: the template's, or the caller's default); ``extent``: an
    object with ``.bounds`` (xmin, ymin, xmax, ymax) and ``.crs`` (e.g.
    :class:`toolbox.parameters.Extent`; in another CRS than the grid's, its bounding box there:
    :func:`toolbox.io.crs.extent_bounds_in`), or None for the data's bounds; ``template``: a
    :class:`toolbox.io.raster.RasterInfo` whose lattice the grid takes; ``max_cells``: the size
    guard (None: ``TOOLBOX_MAX_CELLS`` or 1e9).
    """

    cell_size: float | None = None
    extent: Any = None
    template: Any = None
    max_cells: int | None = None

    def check(self, *, cell_required: bool = True) -> None:
        """The checks that need no data: CELL_SIZE xor TEMPLATE, a north-up TEMPLATE, and the
        size guard when EXTENT or TEMPLATE already fixes the grid (ParameterError naming
        CELL_SIZE/TEMPLATE/EXTENT). ``cell_required=False`` for callers with a default cell."""
        cell, template = self.cell_size, self.template
        if template is None and cell is None and cell_required:
            raise ParameterError("CELL_SIZE", "is required unless TEMPLATE is given (a cell size "
                                 "in CRS units, or a raster whose grid to copy)")
        if template is not None and cell is not None:
            raise ParameterError("CELL_SIZE", f"must not be given with TEMPLATE (the template's "
                                 f"cells are used), got {cell:g}")
        if template is not None or (self.extent is not None and cell is not None):
            self.grid(None, None)

    def grid(self, data_bounds: tuple[float, ...] | None, crs: Any, *,
             default_cell_size: float | Callable[[], float] | None = None,
             snap: bool = True, max_cells: int | None = None) -> GridSpec:
        """The output grid for data within ``data_bounds`` (None at check time) in ``crs``
        (None: the template's, if any), by the grid rules of :mod:`toolbox.raster.engine`.

        ``default_cell_size``: the cell when none is asked (a callable is only called then);
        ``snap``: snap data bounds outwards to multiples of the cell (never an extent);
        ``max_cells``: the caller's size guard when the request gives none.
        """
        from affine import Affine

        limit = self.max_cells or max_cells or max_cells_default()
        extent, template = self.extent, self.template
        if extent is not None:  # in the grid's CRS (converted when it names another)
            from toolbox.io.crs import extent_bounds_in

            crs_of_grid = crs if crs is not None or template is None else template.crs
            extent_box = extent_bounds_in(extent, crs_of_grid)
        if template is not None:
            from toolbox.io.raster import north_up_transform

            # a south-up or east-to-west template: the same cells, written north-up
            t = north_up_transform(template.transform, template.width, template.height)
            if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
                raise ParameterError("TEMPLATE", f"must be a raster without rotation, "
                                     f"{template} has transform {tuple(t)[:6]}")
            if self.cell_size is not None:
                raise ParameterError("CELL_SIZE", f"must not be given with TEMPLATE (the "
                                     f"template's cells are used), got {self.cell_size:g}")
            _same_horizontal_crs(template.crs, crs, getattr(template, "bounds", None))
            crs = crs if crs is not None else template.crs
            if extent is None:
                return _guarded(GridSpec(t, template.width, template.height, crs), limit,
                                "TEMPLATE")
            cx, cy = t.a, -t.e
            xmin, ymin, xmax, ymax = extent_box
            eps = cell_slack(min(cx, cy), xmin, ymin, xmax, ymax, t.c, t.f)
            col0 = math.floor((xmin - t.c) / cx + eps)
            col1 = math.ceil((xmax - t.c) / cx - eps)
            row0 = math.floor((t.f - ymax) / cy + eps)
            row1 = math.ceil((t.f - ymin) / cy - eps)
            grid = GridSpec(Affine(cx, 0.0, t.c + col0 * cx, 0.0, -cy, t.f - row0 * cy),
                            max(1, col1 - col0), max(1, row1 - row0), crs)
            return _guarded(grid, limit, "TEMPLATE")
        cell = self.cell_size
        if cell is None:
            cell = default_cell_size() if callable(default_cell_size) else default_cell_size
        if cell is None:
            raise ParameterError("CELL_SIZE", "is required unless TEMPLATE is given")
        cell = float(cell)
        if not cell > 0 or not math.isfinite(cell):
            raise ParameterError("CELL_SIZE", f"must be > 0, got {cell:g}")
        if extent is not None:
            xmin, ymin, xmax, ymax = extent_box
            if not (xmax > xmin and ymax > ymin):
                raise ParameterError("EXTENT", f"must have xmax > xmin and ymax > ymin, got "
                                     f"{xmin:g},{ymin:g},{xmax:g},{ymax:g}")
        elif data_bounds is not None:
            xmin, ymin, xmax, ymax = map(float, data_bounds)
            if snap:
                xmin, ymin, xmax, ymax = snap_outwards((xmin, ymin, xmax, ymax), cell)
        else:
            raise ParameterError("EXTENT", "is needed to size the grid before reading the data")
        eps = cell_slack(cell, xmin, ymin, xmax, ymax)  # the edges' own rounding
        width = _cells(xmax - xmin, cell, eps)
        height = _cells(ymax - ymin, cell, eps)
        return _guarded(GridSpec(Affine(cell, 0.0, xmin, 0.0, -cell, ymax), width, height, crs),
                        limit, "CELL_SIZE")


def _same_horizontal_crs(template_crs: Any, crs: Any, bounds: Any = None) -> None:
    """A TEMPLATE whose horizontal CRS is not the output's (``crs``, the data's): its cells
    would be taken as if in the output's CRS; a ParameterError naming both. Another
    definition of the same CRS (an ESRI WKT: :func:`toolbox.io.crs.one_horizontal_crs` on the
    template's ``bounds``), a height datum on one side only, or a CRS missing on either side,
    passes (the callers check heights)."""
    if template_crs is None or crs is None:
        return
    from toolbox.io.crs import crs_label, one_horizontal_crs

    if not one_horizontal_crs(template_crs, crs, bounds):
        raise ParameterError("TEMPLATE", f"is in {crs_label(template_crs)} but the output is "
                             f"in {crs_label(crs)} (the data's CRS): give a TEMPLATE in "
                             f"{crs_label(crs)} (gdalwarp -t_srs reprojects it)")


def _cells(length: float, cell: float, eps: float) -> int:
    """Whole cells covering ``length`` (a length within ``eps`` cell of a multiple is that one:
    :func:`toolbox.io.grid.cell_slack` of the edges, whose rounding the length carries)."""
    return max(1, int(math.ceil(length / cell - eps)))


def _guarded(grid: GridSpec, limit: int, name: str) -> GridSpec:
    n = grid.width * grid.height
    if n > limit:
        cell = grid.cell_size[0]
        raise ParameterError(name, f"{cell:g} gives a {grid.width} x {grid.height} grid "
                             f"({n:,} cells), over the limit of {limit:,} cells; use a larger "
                             "cell size or a smaller extent (or raise MAX_CELLS / "
                             "TOOLBOX_MAX_CELLS)" if name == "CELL_SIZE" else
                             f"gives a {grid.width} x {grid.height} grid ({n:,} cells), over the "
                             f"limit of {limit:,} cells (MAX_CELLS or TOOLBOX_MAX_CELLS)")
    return grid


def template_lattice(template: Any, cell_size: float | None = None, crs: Any = None,
                     what: str = "the output") -> tuple[float, tuple[float, float]]:
    """(cell, lattice origin (x, y)) of a north-up template raster with square cells.

    ``cell_size`` (CELL_SIZE) must not be given (the template's cell is used: the engine's
    rule, same message); ``crs``: the output's CRS, which a template with a CRS must share
    (:func:`toolbox.io.crs.one_crs` on the template's extent: an ESRI WKT of it shares it).
    """
    from toolbox.io.crs import crs_label, one_crs

    if crs is not None and template.crs is not None and \
            not one_crs(template.crs, crs, getattr(template, "bounds", None)):
        raise ParameterError("TEMPLATE", f"is in {crs_label(template.crs)}, {what} in "
                             f"{crs_label(crs)}")
    from toolbox.io.raster import north_up_transform

    t = north_up_transform(template.transform, template.width, template.height)  # same cells
    if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0 or abs(t.a + t.e) > 1e-9 * t.a:
        raise ParameterError("TEMPLATE", f"must be a raster without rotation with square cells, "
                             f"{template} has transform {tuple(t)[:6]}")
    if cell_size is not None:
        raise ParameterError("CELL_SIZE", f"must not be given with TEMPLATE (the template's "
                             f"cells are used), got {cell_size:g}")
    return float(t.a), (float(t.c), float(t.f))
