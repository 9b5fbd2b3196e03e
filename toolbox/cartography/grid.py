"""The map grid ("parametratura"): a square mesh with a fixed step on paper (10 cm in the
thesis, so the ground step is 0.10 m x the scale denominator: 500 m at 1:5000), drawn as lines
or as crosses at the nodes, with coordinate labels at the frame. Arrays and shapely geometries
in, out; coordinates in map units (metres), x east, y north.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def ground_step(scale: float, map_step_mm: float = 100.0) -> float:
    """Ground distance of ``map_step_mm`` on paper at 1:``scale`` (metres)."""
    return scale * map_step_mm / 1000.0


def grid_values(lo: float, hi: float, step: float) -> np.ndarray:
    """Multiples of ``step`` in ``[lo, hi]`` (a grid tied to the CRS origin, not the frame); an
    edge on a multiple up to the coordinates' rounding is one (:func:`cell_slack`)."""
    from toolbox.io.grid import cell_slack

    eps = cell_slack(step, lo, hi)
    k0, k1 = np.ceil(lo / step - eps), np.floor(hi / step + eps)
    # k·step may land an ulp beyond the edge it is on: the sheet would clip that line away
    return np.clip(np.arange(k0, k1 + 1) * step, lo, hi)


def format_coordinate(value: float) -> str:
    """A grid coordinate as map sheets print it: whole metres, thousands not separated
    (``1688500``); decimals only when the step needs them."""
    return f"{value:.0f}" if abs(value - round(value)) < 1e-6 else f"{value:.2f}"


@dataclass
class MapGrid:
    """A map grid over ``bounds``: ``lines`` or ``crosses`` (shapely geometries with their kind,
    ``x`` or ``y`` for lines, ``node`` for crosses) and ``labels`` (points with text)."""

    step: float
    geometries: list
    kinds: list[str]
    values: list[float]
    labels: list[dict]


def map_grid(bounds: tuple[float, float, float, float], step: float, style: str = "crosses",
             cross_arm: float | None = None) -> MapGrid:
    """The grid over ``bounds`` (xmin, ymin, xmax, ymax) at ``step`` map units.

    ``style="lines"``: one line per grid x (``kind="x"``, south to north) and per grid y
    (``kind="y"``, west to east), clipped to the bounds. ``style="crosses"``: a cross of arms
    ``cross_arm`` (default step/20) at every node inside the bounds. Labels sit where the grid
    meets the frame: x values at the bottom and top edges, y values at the left and right ones,
    each with ``text``, ``axis``, ``value``, ``edge``.
    """
    import shapely

    xmin, ymin, xmax, ymax = bounds
    xs, ys = grid_values(xmin, xmax, step), grid_values(ymin, ymax, step)
    geoms, kinds, values = [], [], []
    if style == "lines":
        for x in xs:
            geoms.append(shapely.linestrings([[x, ymin], [x, ymax]]))
            kinds.append("x")
            values.append(float(x))
        for y in ys:
            geoms.append(shapely.linestrings([[xmin, y], [xmax, y]]))
            kinds.append("y")
            values.append(float(y))
    elif style == "crosses":
        arm = step / 20.0 if cross_arm is None else cross_arm
        box = shapely.box(*bounds)
        for x in xs:
            for y in ys:
                cross = shapely.multilinestrings([[[x - arm, y], [x + arm, y]],
                                                  [[x, y - arm], [x, y + arm]]])
                geoms.append(shapely.intersection(cross, box))
                kinds.append("node")
                values.append(float("nan"))
    else:
        raise ValueError(f"style must be 'lines' or 'crosses', got {style!r}")
    labels = []
    for x in xs:
        for edge, y in (("bottom", ymin), ("top", ymax)):
            labels.append({"x": float(x), "y": float(y), "text": format_coordinate(x),
                           "axis": "x", "value": float(x), "edge": edge})
    for y in ys:
        for edge, x in (("left", xmin), ("right", xmax)):
            labels.append({"x": float(x), "y": float(y), "text": format_coordinate(y),
                           "axis": "y", "value": float(y), "edge": edge})
    return MapGrid(step, geoms, kinds, values, labels)
