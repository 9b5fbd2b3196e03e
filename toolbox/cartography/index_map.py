"""The small index map of a sheet ("quadro d'unione"): the sheet and its neighbours from a sheet
index layer (``carto:sheet_index``), each with its number, the sheet itself shaded, drawn in
the panel's top right corner beside the north arrow."""

from __future__ import annotations

import numpy as np

BOX_MM = (40.0, 24.0)  # the index map's room: width, height
TOP_GAP_MM = 2.0  # below the panel's top
TEXT_PT = 6.0


def index_neighbourhood(frame, field: str, sheet_polygon) -> tuple[int | None, list[int]]:
    """The row of ``frame`` holding the sheet (the one containing the sheet polygon's
    representative point) and the rows of its neighbours (sharing an edge or a corner)."""
    point = sheet_polygon.representative_point()
    hits = [k for k, g in enumerate(frame.geometry) if g is not None and g.contains(point)]
    if not hits:
        return None, []
    own = frame.geometry.iloc[hits[0]]
    near = own.buffer(max(np.sqrt(own.area), 1.0) * 1e-6)
    around = [k for k, g in enumerate(frame.geometry)
              if k != hits[0] and g is not None and g.intersects(near)]
    return hits[0], around


def index_number(frame, field: str, sheet_polygon) -> str:
    """The sheet's number in the index ("" when the sheet is not in it or has none)."""
    own, _ = index_neighbourhood(frame, field, sheet_polygon)
    if own is None or field not in frame:
        return ""
    number = str(frame[field].iloc[own])
    return "" if number in ("None", "nan") else number


def draw_index_map(renderer, frame, field: str, sheet_polygon) -> dict:
    """Draw the index map on ``renderer`` (a :class:`~toolbox.cartography.sheet.SheetRenderer`)
    and return what it shows: the sheet's number and its neighbours' (empty when the sheet is
    not in the index)."""
    import shapely
    from matplotlib.patches import Polygon

    own, around = index_neighbourhood(frame, field, sheet_polygon)
    if own is None:
        return {"sheet": "", "neighbours": []}
    rows = [own, *around]
    geoms = [frame.geometry.iloc[k] for k in rows]
    xmin, ymin, xmax, ymax = shapely.union_all(geoms).bounds
    page = renderer.page
    width, height = BOX_MM
    right = page.panel_left + page.panel_width
    top = page.band_bottom + page.band_height - TOP_GAP_MM
    k = min(width / (xmax - xmin), height / (ymax - ymin))  # mm per ground unit
    x0 = right - (xmax - xmin) * k
    y0 = top - (ymax - ymin) * k
    fig = renderer.fig
    numbers = []
    for row, geom in zip(rows, geoms, strict=True):
        for part in shapely.get_parts(geom):
            xy = np.asarray(part.exterior.coords)[:, :2]
            mm = np.column_stack([x0 + (xy[:, 0] - xmin) * k, y0 + (xy[:, 1] - ymin) * k])
            fig.patches.append(Polygon(
                np.column_stack([renderer._fx(mm[:, 0]), renderer._fy(mm[:, 1])]),
                closed=True, transform=fig.transFigure, linewidth=0.25 * 72 / 25.4,
                edgecolor="black", facecolor="0.75" if row == own else "none"))
        number = str(frame[field].iloc[row]) if field in frame else str(row + 1)
        numbers.append(number)
        c = geom.representative_point()
        fig.text(renderer._fx(x0 + (c.x - xmin) * k), renderer._fy(y0 + (c.y - ymin) * k),
                 number if number not in ("", "None", "nan") else "-", ha="center",
                 va="center", fontsize=TEXT_PT, fontweight="bold" if row == own else "normal",
                 transform=fig.transFigure, gid="index_map")
    return {"sheet": numbers[0], "neighbours": numbers[1:]}
