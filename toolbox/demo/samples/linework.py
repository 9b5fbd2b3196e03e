"""Sample restitution sheet for area topology (EPSG:3003, inside the Siena block area).

A 100 m x 60 m sheet at E 1688200-1688300, N 4799600-4799660, plotted as coded lines the way the
thesis describes (S002 §2.2.2): a road between an outer road edge and a block edge, two buildings,
garden walls splitting the block's pavement, a traffic island. Building B2 sits on the road edge
and is plotted closed with the building code; the block edge is an open polyline attached to B2's
corners, so every wall B2 shares with the pavement or the road is plotted once (the thesis' edge
2-5).

Each typical defect appears once (local coordinates, metres from E 1688200, N 4799600):

===================================  ========================================================
defect                               where
===================================  ========================================================
near-miss end onto a node            block edge starts at (59.90, 10.05), B2's corner (60, 10)
undershoot onto a vertex             block edge ends at (80.12, 10), B2's corner (80, 10)
undershoot onto a segment            wall 8 starts at (30, 19.85), 0.15 m below B1
polyline not closed (0.30 m)         building B1 ends at (20, 20.30)
crossing without node + overshoot    wall 7 crosses the block edge at (30, 50), 0.40 m past
corner overshoot (both lines)        outer road edges cross at (100, 60), 0.30 m past each
exact duplicate                      building B2 plotted twice (second one reversed)
overlapping duplicate                pavement edge (40, 50)-(70, 50) on the block edge
sliver (0.80 m2)                     pavement edge 10 bulges 0.04 m off the block edge
short dangle (0.60 m)                stub on B2's north wall at (70, 30)
dangle kept (5 m)                    wall from B1 at (20, 30) to (15, 30)
self-intersection + overshoot        traffic island ends 0.60 m past its own start (40, 3)
unclosed line (1.50 m gap)           hedge in the road, ends at (45, 53) and (45, 54.5)
unlabelled area                      garden west of wall 8 (600 m2)
conflicting labels                   two codes on the traffic island
label outside every area             label at (105, 30)
===================================  ========================================================

With snap 0.2 m, closure 0.5 m, minimum dangle 1 m and minimum area 1 m² (the sample parameter
file) the true areas are: road 2760 m² (code STR01001, spot height 321.00 from an uncoded point),
traffic island 40 m², B1 400 m², B2 400 m² (FAB01002), pavement east 1800 m² (MAR01001) and
garden west 600 m² (unlabelled): 6000 m² in all. ``tests/algorithms/topology`` checks exactly
these values.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolbox.demo.parameter_files import parameter_file_text

CRS = "EPSG:3003"
E0, N0 = 1688200.0, 4799600.0

#: (code, z, local vertices) of each plotted line, in plotting order (feature numbers 1..14)
LINES: list[tuple[str, float, list[tuple[float, float]]]] = [
    ("STR02001", 320.0, [(0, 0), (100, 0), (100, 60.3)]),                     # 1 outer road edge
    ("STR02001", 320.0, [(100.3, 60), (0, 60), (0, 0)]),                      # 2 outer road edge
    ("STR02001", 320.5, [(59.9, 10.05), (10, 10), (10, 50), (90, 50), (90, 10),
                         (80.12, 10)]),                                       # 3 block edge
    ("FAB01002", 331.2, [(20, 20), (40, 20), (40, 40), (20, 40), (20, 20.3)]),  # 4 building B1
    ("FAB01002", 328.7, [(60, 10), (80, 10), (80, 30), (60, 30), (60, 10)]),  # 5 building B2
    ("FAB01002", 328.7, [(60, 10), (60, 30), (80, 30), (80, 10), (60, 10)]),  # 6 B2 again
    ("MUR01001", 321.0, [(30, 40), (30, 50.4)]),                              # 7 garden wall
    ("MUR01001", 321.0, [(30, 19.85), (30, 10)]),                             # 8 garden wall
    ("MAR01001", 320.6, [(40, 50), (70, 50)]),                                # 9 pavement edge
    ("MAR01001", 320.6, [(90, 50), (89.96, 30), (90, 10)]),                   # 10 pavement edge
    ("MUR01001", 321.0, [(70, 30), (70, 30.6)]),                              # 11 wall stub
    ("MUR01001", 321.0, [(20, 30), (15, 30)]),                                # 12 garden wall
    ("STR03001", 320.1, [(40, 3), (50, 3), (50, 7), (40, 7), (40, 2.4)]),     # 13 traffic island
    ("VER02001", 320.2, [(45, 53), (55, 53), (55, 57), (45, 57), (45, 54.5)]),  # 14 hedge
]

#: (code, quota, local point) of each label point (feature numbers 1..8); blank code = spot
#: height only
LABELS: list[tuple[str | None, float | None, tuple[float, float]]] = [
    ("STR01001", None, (5, 30)),      # 1 road
    ("FAB01002", 331.20, (30, 30)),   # 2 building B1
    ("FAB01002", 328.70, (70, 20)),   # 3 building B2
    ("MAR01001", 322.40, (50, 45)),   # 4 pavement east
    ("VER01001", None, (42, 5)),      # 5 traffic island: flower bed ...
    ("STR03001", None, (48, 5)),      # 6 ... or traffic island? (conflict)
    (None, 321.00, (95, 30)),         # 7 spot height in the road
    ("FAB01002", 330.00, (105, 30)),  # 8 outside the sheet
]

#: thematic zones for the overlay demo: (zone, local rectangle xmin, ymin, xmax, ymax)
ZONES: list[tuple[str, tuple[float, float, float, float]]] = [
    ("centro storico", (-5, -5, 50, 65)),
    ("zona di completamento", (50, -5, 105, 65)),
]

#: the sample parameter file ("file dei parametri", S002 §2.2.1), in the format of
#: toolbox.io.parameter_file
PARAMETER_FILE_TEXT = parameter_file_text(
    ["File dei parametri - foglio di esempio (Siena, EPSG:3003)",
     "formato: nome = valore; '#' commento; valori in metri"],
    ("0.50", "0.20", "0.10", "m", "3", "0 0", "0.05", "0.10", "1.0", "0.50", "0.50", "0.30"),
    {"lunghezza minima dei pendenti": "1.00", "area minima": "1.00"},
    "estensioni del toolbox per la generazione delle aree")


def sheet_lines():
    """The coded lines (3D, Z = plotted height) as a GeoDataFrame in EPSG:3003."""
    import geopandas as gpd
    import shapely

    geoms = [shapely.LineString([(E0 + x, N0 + y, z) for x, y in pts]) for _, z, pts in LINES]
    return gpd.GeoDataFrame({"code": [c for c, _, _ in LINES]}, geometry=geoms, crs=CRS)


def sheet_labels():
    """The label points (code, quota) as a GeoDataFrame in EPSG:3003."""
    import geopandas as gpd
    import shapely

    return gpd.GeoDataFrame(
        {"code": [c for c, _, _ in LABELS],
         "quota": np.array([np.nan if q is None else q for _, q, _ in LABELS])},
        geometry=[shapely.Point(E0 + x, N0 + y) for _, _, (x, y) in LABELS], crs=CRS)


def sheet_zones():
    """Two thematic zones (polygons) covering the sheet, for ``topology:overlay``."""
    import geopandas as gpd
    import shapely

    return gpd.GeoDataFrame(
        {"zone": [z for z, _ in ZONES]},
        geometry=[shapely.box(E0 + a, N0 + b, E0 + c, N0 + d) for _, (a, b, c, d) in ZONES],
        crs=CRS)


def make(folder: Path, made: dict) -> dict:
    from toolbox.io.vector_write import write_layers

    paths = {"linework": folder / "siena_linework.gpkg", "linework_labels": folder /
             "siena_labels.gpkg", "linework_zones": folder / "siena_zones.gpkg"}
    for path in paths.values():
        if path.exists():
            path.unlink()
    write_layers(paths["linework"], {"lines": sheet_lines()})
    write_layers(paths["linework_labels"], {"labels": sheet_labels()})
    write_layers(paths["linework_zones"], {"zones": sheet_zones()})
    parameters = folder / "siena_parametri.txt"
    parameters.write_text(PARAMETER_FILE_TEXT, encoding="utf-8")
    return paths | {"linework_parameters": parameters}
