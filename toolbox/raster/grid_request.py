"""The typed request for an output grid: cell size, extent, template, size guard.

One set of rules answers it (:func:`toolbox.raster.engine.grid_from_parameters`, module notes
of :mod:`toolbox.raster.engine`): ``extent`` is honoured as given, else the data's bounds
snapped outwards to whole cells; a template fixes the lattice and the cell, so ``cell_size``
with a template is an error: one rule for every raster output (the ortho lattice of
:func:`template_lattice` too).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from toolbox.io.grid import GridSpec


@dataclass(frozen=True)
class GridRequest:
    """What the caller asks of an output grid.

    ``cell_size``: CRS units (None: the template's, or the caller's default); ``extent``: an
    object with ``.bounds`` (xmin, ymin, xmax, ymax) and ``.crs`` (e.g.
    :class:`toolbox.parameters.Extent`), or None for the data's bounds; ``template``: a
    :class:`toolbox.io.raster.RasterInfo` whose lattice the grid takes; ``max_cells``: the size
    guard (None: ``TOOLBOX_MAX_CELLS`` or 1e9).
    """

    cell_size: float | None = None
    extent: Any = None
    template: Any = None
    max_cells: int | None = None

    def _rules(self) -> dict[str, Any]:
        """The request in the engine's rule names (its one implementation reads them)."""
        return {"CELL_SIZE": self.cell_size, "EXTENT": self.extent, "TEMPLATE": self.template,
                "MAX_CELLS": self.max_cells}

    def check(self, *, cell_required: bool = True) -> None:
        """The checks that need no data (ParameterError naming CELL_SIZE/TEMPLATE/EXTENT)."""
        from toolbox.raster.engine import check_grid_parameters

        check_grid_parameters(self._rules(), cell_required=cell_required)

    def grid(self, data_bounds: tuple[float, ...] | None, crs: Any, *,
             default_cell_size: float | Callable[[], float] | None = None,
             snap: bool = True) -> GridSpec:
        """The output grid for data within ``data_bounds`` in ``crs`` (see the module notes)."""
        from toolbox.raster.engine import grid_from_parameters

        return grid_from_parameters(self._rules(), data_bounds, crs,
                                    default_cell_size=default_cell_size, snap=snap)


def template_lattice(template: Any, cell_size: float | None = None, crs: Any = None,
                     what: str = "the output") -> tuple[float, tuple[float, float]]:
    """(cell, lattice origin (x, y)) of a north-up template raster with square cells.

    ``cell_size`` (CELL_SIZE) must not be given (the template's cell is used: the engine's
    rule, same message); ``crs``: the output's CRS, which a template with a CRS must share.
    """
    from toolbox.errors import ParameterError
    from toolbox.io.crs import crs_label, same_crs

    if crs is not None and template.crs is not None and not same_crs(template.crs, crs):
        raise ParameterError("TEMPLATE", f"is in {crs_label(template.crs)}, {what} in "
                             f"{crs_label(crs)}")
    t = template.transform
    if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0 or abs(t.a + t.e) > 1e-9 * t.a:
        raise ParameterError("TEMPLATE", f"must be a north-up raster with square cells, "
                             f"{template} has transform {tuple(t)[:6]}")
    if cell_size is not None:
        raise ParameterError("CELL_SIZE", f"must not be given with TEMPLATE (the template's "
                             f"cells are used), got {cell_size:g}")
    return float(t.a), (float(t.c), float(t.f))
