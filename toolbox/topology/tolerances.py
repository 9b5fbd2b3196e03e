"""Tolerances of area building: explicit parameters, else the parameter file, else defaults."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import shapely

from toolbox.errors import ParameterError
from toolbox.io.parameter_file import DEFAULTS, ParameterFile, resolve

# parameter name -> (field of Tolerances, key in the parameter file; its default there)
TOLERANCE_PARAMETERS: dict[str, tuple[str, str]] = {
    "SNAP_TOLERANCE": ("snap", "snap_tolerance"),
    "CLOSURE_TOLERANCE": ("closure", "closure_tolerance"),
    "MIN_DANGLE_LENGTH": ("min_dangle", "min_dangle_length"),
    "MIN_AREA": ("min_area", "min_area"),
    "PRECISION": ("precision", "decimals"),
}

#: parameter-file entries area building uses (the others are named in an information message): the
#: tolerances above, the unit (checked against the CRS) and the coordinate translation (added to
#: the input lines and labels)
TOPOLOGY_FILE_KEYS = frozenset({key for _, key in TOLERANCE_PARAMETERS.values()}
                               | {"coordinate_unit", "coordinate_offset"})


@dataclass(frozen=True)
class Tolerances:
    """Tolerances in CRS units (metres for EPSG:3003).

    Attributes
    ----------
    snap : float
        "Tolleranza di riattacco planimetrico": a line end closer than this to another line's
        end, vertex or segment is moved onto it. 0 disables snapping.
    closure : float
        "Tolleranza di chiusura": a polyline whose two free ends are closer than this is closed.
    min_dangle : float
        Dangles (and overshoots) shorter than this are removed; longer ones are kept and
        reported. 0 keeps every dangle.
    min_area : float
        Areas smaller than this (square CRS units) are slivers, merged into the neighbour sharing
        the longest boundary. 0 keeps every area.
    precision : float
        Coordinate grid of the output (10**-decimals of the parameter file): noding is done by
        snap rounding to this grid, so the result is robust and the same on every run.
    """

    snap: float = DEFAULTS["snap_tolerance"]
    closure: float = DEFAULTS["closure_tolerance"]
    min_dangle: float = DEFAULTS["min_dangle_length"]
    min_area: float = DEFAULTS["min_area"]
    precision: float = 10.0 ** -DEFAULTS["decimals"]

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def resolve_tolerances(explicit: dict[str, float | None],
                       parameter_file: ParameterFile | None = None
                       ) -> tuple[Tolerances, dict[str, str]]:
    """Combine explicit values, the parameter file and the defaults.

    Parameters
    ----------
    explicit : dict
        ``{"SNAP_TOLERANCE": 0.3, "MIN_AREA": None, ...}``; None means "not given".
    parameter_file : ParameterFile, optional

    Returns
    -------
    tolerances : Tolerances
    sources : dict
        Field name -> ``"parameter"``, ``"file"`` or ``"default"`` (for the run report).

    Raises
    ------
    ParameterError
        ``PRECISION`` not > 0, or coarser than a non-zero snap tolerance.
    """
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for name, (attr, file_key) in TOLERANCE_PARAMETERS.items():
        value, sources[attr] = resolve(explicit.get(name), parameter_file, file_key)
        values[attr] = float(value)
    tol = Tolerances(**values)
    if not tol.precision > 0:
        raise ParameterError("PRECISION", f"must be > 0, got {tol.precision:g}")
    if tol.snap > 0 and tol.precision > tol.snap:
        raise ParameterError("PRECISION", f"({tol.precision:g}) must not be coarser than the snap "
                             f"tolerance ({tol.snap:g}); lower PRECISION or raise SNAP_TOLERANCE")
    return tol, sources


#: a snap tolerance above this fraction of the median input line's extent draws a warning
LARGE_SNAP_FRACTION = 0.25


def large_snap_warning(snap: float, lines: np.ndarray) -> str | None:
    """A warning when SNAP_TOLERANCE is large for the features it cleans, else None.

    Snapping is meant for near misses: a gap that is a small part of the features. The size
    compared is the median extent of the input lines (the diagonal of each line's bounding
    box: a building's outline, a kerb, a contour piece), robust to a few long or tiny lines and,
    unlike a segment length, independent of how densely a curve was digitised. Above a quarter of
    it a line end can be moved onto a neighbouring feature, or across a typical feature, by a
    distance comparable to the feature itself: the result is no longer a cleaning of the
    linework (10 m buildings with a 200 m tolerance give thousands of mangled areas).
    """
    if not snap > 0 or not len(lines):
        return None
    b = shapely.bounds(lines)
    extent = float(np.median(np.hypot(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1])))
    if snap <= LARGE_SNAP_FRACTION * extent:
        return None
    return (f"SNAP_TOLERANCE {snap:g} is large for the features: the median input line "
            f"extent (bounding-box diagonal) is {extent:.3g}, and a tolerance above a quarter of "
            f"it ({LARGE_SNAP_FRACTION * extent:.3g}) can move line ends across features and "
            "change their shape; check the areas, or use a near-miss distance")
