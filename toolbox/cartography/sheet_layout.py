"""The page of a map sheet: paper sizes, margins and panel in millimetres, what a sheet shows
(:class:`SheetSpec`) and where the map frame and the side panel go on the paper (:func:`layout_page`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MM_PER_INCH = 25.4
PT_PER_MM = 72.0 / MM_PER_INCH
MARGIN = 10.0  # mm, paper edge to the map frame's labels
LABEL_BAND = 6.0  # mm outside the frame for grid labels
PANEL = 78.0  # mm, width of the side panel (legend, scale bar, north arrow, title block)
GAP = 6.0  # mm between the frame labels and the panel
ISO_SHEETS = {"A4": (210.0, 297.0), "A3": (297.0, 420.0), "A2": (420.0, 594.0),
              "A1": (594.0, 841.0), "A0": (841.0, 1189.0)}
PANEL_MIN_HEIGHT = 170.0  # mm the panel needs
PANEL_MAX = 120.0  # mm, the panel's width where the paper leaves room


@dataclass
class SheetSpec:
    """What a sheet shows and says: its ground bounds, scale and title-block text."""

    bounds: tuple[float, float, float, float]
    scale: float
    title: str
    sheet_id: str = ""
    crs_label: str = ""
    date: str = ""
    sources: list[str] = field(default_factory=list)
    paper: str = "auto"  # an ISO_SHEETS name or "auto"
    credits: str = ""
    datum: str = ""
    contour_interval: float | None = None  # m, stated in the title block and the legend
    producer: str = ""
    second_crs: str = ""  # the CRS ticked outside the frame (GRID_CRS), stated in the block
    index_number: str = ""  # the sheet's number in the sheet index (INDEX), when not its id


@dataclass
class PageLayout:
    """Paper and map-frame geometry, millimetres."""

    paper: str
    width: float
    height: float
    frame: tuple[float, float, float, float]  # left, bottom, width, height
    panel_width: float = 78.0
    band_bottom: float = 0.0  # the map and the panel share this band of the page
    band_height: float = 0.0

    @property
    def panel_left(self) -> float:
        return self.frame[0] + self.frame[2] + LABEL_BAND + GAP


def layout_page(spec: SheetSpec) -> PageLayout:
    """The smallest ISO sheet (portrait or landscape) holding the map frame at scale plus the
    side panel; a custom size when even A0 is too small, or the named ``spec.paper``."""
    xmin, ymin, xmax, ymax = spec.bounds
    map_w = (xmax - xmin) / spec.scale * 1000.0
    map_h = (ymax - ymin) / spec.scale * 1000.0
    need_w = 2 * MARGIN + 2 * LABEL_BAND + map_w + GAP + PANEL
    need_h = 2 * MARGIN + 2 * LABEL_BAND + max(map_h, PANEL_MIN_HEIGHT)
    names = [spec.paper] if spec.paper in ISO_SHEETS else list(ISO_SHEETS)
    choice = None
    for name in names:
        short, long_ = ISO_SHEETS[name]
        for w, h in ((long_, short), (short, long_)):
            if w >= need_w and h >= need_h:
                choice = (name, w, h)
                break
        if choice:
            break
    if choice is None:
        if spec.paper in ISO_SHEETS:
            raise ValueError(f"the map ({map_w:.0f} x {map_h:.0f} mm at 1:{spec.scale:g}) does "
                             f"not fit on {spec.paper}")
        choice = ("custom", float(np.ceil(need_w)), float(np.ceil(need_h)))
    name, w, h = choice
    panel = min(PANEL_MAX, PANEL + max(0.0, w - need_w) / 2.0)  # free width: half to the panel
    content_w = need_w - PANEL + panel
    left = max(0.0, (w - content_w) / 2.0) + MARGIN + LABEL_BAND
    band = max(map_h, PANEL_MIN_HEIGHT)
    band_bottom = (h - band) / 2.0
    bottom = band_bottom + (band - map_h) / 2.0  # a small map sits mid-height, not in a corner
    return PageLayout(name, w, h, (left, bottom, map_w, map_h), panel, band_bottom, band)


def nice_length(max_ground: float) -> float:
    """The largest 1, 2 or 5 x 10^k not above ``max_ground`` (scale-bar length)."""
    k = 10 ** np.floor(np.log10(max_ground))
    for m in (5, 2, 1):
        if m * k <= max_ground:
            return float(m * k)
    return float(k)
