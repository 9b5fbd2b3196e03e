"""The typed request for an output grid: cell size, extent, template, size guard.

One set of rules answers it (:func:`toolbox.raster.engine.grid_from_parameters`, module notes
of :mod:`toolbox.raster.engine`): ``cell_size`` with ``template`` is an error, ``extent`` is
honoured as given, else the data's bounds snapped outwards to whole cells.
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
