"""The sheet index of an Italian regional technical map (CTR): 1:10000 sections and 1:5000
elements of an IGM 1:50000 sheet, numbered as the CTRs are (docs/map_sheet.md, "Sheet index").

An IGM 1:50000 sheet ("Carta d'Italia", serie 50, sheets 001-652) spans 20' of longitude by
12' of latitude on ED50 (Hayford ellipsoid, European datum 1950). It is cut 4 x 4 into
sections at 1:10000 (5' x 3'), numbered 01-16 by rows from the north-west (01-04 the northern
row, west to east); each section is cut 2 x 2 into elements at 1:5000 (2'30" x 1'30"),
numbered 1-4 clockwise from the north-east (1 NE, 2 SE, 3 SW, 4 NW). A CTR number has six
digits: the 1:50000 sheet (3), the section (2) and the element (1; 0 for a whole section):
``296061`` is element 1 (NE) of section 06 of sheet 296, ``296060`` that section.

Sheet edges are meridians and parallels of ED50: in a projected CRS they are drawn as
densified polygons (one vertex every 15"), so neighbouring sheets share their edges exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ED50 = "EPSG:4230"
SHEET_DEG = (20 / 60, 12 / 60)  # 1:50000 sheet, degrees of longitude, latitude
SECTION_DEG = (5 / 60, 3 / 60)
ELEMENT_DEG = (2.5 / 60, 1.5 / 60)
#: element number by (row from the north, column from the west) inside its section
ELEMENT_NUMBER = {(0, 1): 1, (1, 1): 2, (1, 0): 3, (0, 0): 4}
DENSIFY_DEG = 0.25 / 60


@dataclass(frozen=True)
class IndexRequest:
    """Sheets of 1:``scale`` (5000: elements, 10000: sections) covering ``bounds`` (xmin,
    ymin, xmax, ymax in ``crs``), numbered inside IGM 1:50000 sheet ``sheet_50k`` whose
    north-west corner is ``origin`` (ED50 longitude, latitude in degrees, east of Greenwich);
    with ``neighbours`` one more ring of sheets around them."""

    bounds: tuple[float, float, float, float]
    crs: object
    sheet_50k: int
    scale: int = 5000
    origin: tuple[float, float] = (0.0, 0.0)
    neighbours: bool = True


@dataclass(frozen=True)
class IndexSheet:
    """One sheet of the index: its CTR ``number`` (empty outside the 1:50000 sheet), its
    ``section`` (1-16) and ``element`` (1-4, 0 for a section), and its ED50 edges."""

    number: str
    section: int
    element: int
    west: float
    south: float
    east: float
    north: float


def ctr_number(sheet_50k: int, row: int, col: int, scale: int) -> tuple[str, int, int]:
    """(number, section, element) of the cell at ``row`` (from the north) and ``col`` (from
    the west) of the 1:50000 sheet's grid of 1:``scale`` cells (4 x 4 sections or 8 x 8
    elements); ("", 0, 0) outside the sheet."""
    cells = 4 if scale == 10000 else 8
    if not (0 <= row < cells and 0 <= col < cells):
        return "", 0, 0
    if scale == 10000:
        section, element = 4 * row + col + 1, 0
    else:
        section = 4 * (row // 2) + col // 2 + 1
        element = ELEMENT_NUMBER[(row % 2, col % 2)]
    return f"{sheet_50k:03d}{section:02d}{element}", section, element


def index_sheets(request: IndexRequest) -> list[tuple[IndexSheet, object]]:
    """The sheets covering ``request.bounds`` (and their neighbours) as (sheet, polygon in
    ``request.crs``), north to south, west to east."""
    import shapely
    from pyproj import Transformer

    to_ed50 = Transformer.from_crs(request.crs, ED50, always_xy=True)
    from_ed50 = Transformer.from_crs(ED50, request.crs, always_xy=True)
    xmin, ymin, xmax, ymax = request.bounds
    xs = np.r_[np.linspace(xmin, xmax, 9), np.full(9, xmax), np.linspace(xmax, xmin, 9),
               np.full(9, xmin)]
    ys = np.r_[np.full(9, ymin), np.linspace(ymin, ymax, 9), np.full(9, ymax),
               np.linspace(ymax, ymin, 9)]
    lon, lat = to_ed50.transform(xs, ys)
    origin = request.origin
    w, h = ELEMENT_DEG if request.scale == 5000 else SECTION_DEG
    ring = 1 if request.neighbours else 0
    c0 = int(np.floor((np.min(lon) - origin[0]) / w + 1e-9)) - ring
    c1 = int(np.floor((np.max(lon) - origin[0]) / w - 1e-9)) + ring
    r0 = int(np.floor((origin[1] - np.max(lat)) / h + 1e-9)) - ring
    r1 = int(np.floor((origin[1] - np.min(lat)) / h - 1e-9)) + ring
    out = []
    for row in range(r0, r1 + 1):
        for col in range(c0, c1 + 1):
            west, north = origin[0] + col * w, origin[1] - row * h
            east, south = west + w, north - h
            number, section, element = ctr_number(request.sheet_50k, row, col, request.scale)
            out.append((IndexSheet(number, section, element, west, south, east, north),
                        shapely.Polygon(_edges(from_ed50, west, south, east, north))))
    return out


def _edges(transformer, west: float, south: float, east: float, north: float) -> np.ndarray:
    """The sheet's outline (meridians and parallels, densified) in the target CRS."""
    nx = max(int(np.ceil((east - west) / DENSIFY_DEG)), 1)
    ny = max(int(np.ceil((north - south) / DENSIFY_DEG)), 1)
    lon = np.r_[np.linspace(west, east, nx, endpoint=False), np.full(ny, east),
                np.linspace(east, west, nx, endpoint=False), np.full(ny, west)]
    lat = np.r_[np.full(nx, south), np.linspace(south, north, ny, endpoint=False),
                np.full(nx, north), np.linspace(north, south, ny, endpoint=False)]
    x, y = transformer.transform(lon, lat)
    return np.column_stack([x, y])
