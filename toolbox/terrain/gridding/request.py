"""Typed requests of a DEM gridding run (what ``dem:<method>`` asks, without the UI's names).

A :class:`GriddingRequest` is the data to read (:class:`PointSources`), the output grid
(:class:`~toolbox.raster.grid_request.GridRequest`), the method's options
(:class:`MethodOptions`), which cells get a value (:class:`CellOptions`) and how the tiles run
and are written (:class:`Execution`). Defaults are the algorithms' defaults.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.raster.grid_request import GridRequest

DEFAULT_NODATA = -9999.0
DEFAULT_TILE = 512
TERMS = (1, 3, 6, 10)  # coefficients of the polynomial of order 0, 1, 2, 3
ORDER_NAMES = ("mean", "plane", "quadratic", "cubic")
DEFAULT_MIN_RCOND = 1e-3


@dataclass(frozen=True)
class PointSources:
    """The data points of a run.

    ``points``: mass points, a vector layer (:func:`toolbox.io.vector.open_layer`) or a point
    cloud (:func:`toolbox.io.pointcloud.open_point_cloud`); ``lines``: lines whose vertices are
    data points; ``breaklines``: lines whose edges are kept as triangle edges by tin_linear.
    ``*_z_field``: the height field (None: the geometry's Z). ``classes`` / ``returns``: point
    cloud filters (e.g. ``"2"``, ``"last"``). ``duplicates``: the rule for points sharing one XY
    position (mean, first, min, max, error) within ``duplicate_tolerance`` (CRS units).
    ``crs``: the data's CRS (None: the inputs').
    """

    points: Any = None
    z_field: str | None = None
    lines: Any = None
    lines_z_field: str | None = None
    breaklines: Any = None
    breaklines_z_field: str | None = None
    classes: str | None = None
    returns: str = "all"
    duplicates: str = "mean"
    duplicate_tolerance: float = 0.0
    crs: Any = None

    def layers(self) -> dict[str, Any]:
        """The inputs given, by role (``points``, ``lines``, ``breaklines``)."""
        return {name: getattr(self, name) for name in ("points", "lines", "breaklines")
                if getattr(self, name) is not None}


@dataclass(frozen=True)
class MethodOptions:
    """Options of the methods (each method takes the ones it uses).

    ``neighbours``: k nearest points (None: the method's default); ``radius``: search radius
    (CRS units, None: no limit); ``min_neighbours``: fewer found -> nodata; ``power``: IDW
    exponent p of 1/d^p; ``sectors``: IDW angular sectors (1 = none); ``min_rcond``: polynomial
    conditioning threshold; ``max_distance``: cells (points) whose nearest data point is farther
    stay nodata (not predicted); None: no limit.
    """

    neighbours: int | None = None
    radius: float | None = None
    min_neighbours: int = 1
    power: float = 2.0
    sectors: int = 1
    min_rcond: float = DEFAULT_MIN_RCOND
    max_distance: float | None = None


@dataclass(frozen=True)
class CellOptions:
    """Which cells get a value: ``mask`` (polygon layer: cells whose centre is outside stay
    nodata), ``extrapolate`` (also cells outside the data's convex hull), ``nodata``."""

    nodata: float = DEFAULT_NODATA
    mask: Any = None
    extrapolate: bool = False


@dataclass(frozen=True)
class Execution:
    """Tiles and writing: ``tile_size`` cells (a multiple of 16, also the GeoTIFF block),
    ``scheduler`` (a Dask address, 'local' or None: DASK_SCHEDULER_ADDRESS or local threads),
    ``workers`` (local threads), ``overviews``, ``cog``."""

    tile_size: int = DEFAULT_TILE
    scheduler: str | None = None
    workers: int | None = None
    overviews: bool = True
    cog: bool = False


@dataclass(frozen=True)
class GriddingRequest:
    """One run: ``output`` the DEM GeoTIFF, ``quality`` an optional JSON leave-one-out report."""

    sources: PointSources
    output: Path
    grid: GridRequest = field(default_factory=GridRequest)
    method: MethodOptions = field(default_factory=MethodOptions)
    cells: CellOptions = field(default_factory=CellOptions)
    execution: Execution = field(default_factory=Execution)
    quality: Path | None = None
