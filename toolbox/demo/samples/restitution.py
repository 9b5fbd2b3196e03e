"""Sample restitution for the attribution demo: two adjacent stereo models over the Siena block.

A 100 m x 60 m sheet at E 1688300-1688400, N 4799600-4799660 (EPSG:3003), east of the topology
sheet, plotted in two models split at E 1688350 with a 10 m overlap. The ASCII exports store
coordinates relative to the false origin E 1688000, N 4799000, as the parameter file's
"traslazione delle coordinate" says. The code file (Z-Map's columns with a header, Latin-1, a
"località" description) and the colour file are in the thesis' formats. A DXF of the same sheet
carries blocks (trees) and texts (place names).

Defects, each once (local metres from E 1688300, N 4799600; listed in :data:`DEFECTS`):

- building C plotted in both models (duplicate, removed by the merge);
- road edge 1 crosses the model edge with a 0.07 m gap, 0.02 m in height (joined);
- road edge 2 meets in plan but differs by 0.6 m in height (not joined, reported);
- an unknown code (``XYZ99999``); a road edge with one vertex; a hedge area unclosed by 1.2 m;
  building D unclosed by 0.3 m (closed); a spot height plotted as a two-vertex line;
- buildings A, B (sharing a wall) and E plotted a few centimetres out of square.
"""

from __future__ import annotations

from pathlib import Path

from toolbox.demo.samples.parameter_file import parameter_file_text

CRS = "EPSG:3003"
E0, N0 = 1688300.0, 4799600.0
FALSE_ORIGIN = (1688000.0, 4799000.0)

CODE_FILE_TEXT = """\
# file dei codici - carta tecnica 1:500, foglio Siena est
# spessore (mm), tipo linea, simbolo, campitura: the map sheet's symbology; codice consegna: the
# code of the delivered file (illustrative names; the marciapiede is delivered as a road edge)
codice;descrizione;tipologia;colore;spessore;tipo linea;simbolo;campitura;codice consegna
FAB01002;muro perimetrale di fabbricato civile;poligono;12;0.25;continua;;45/1.0;EDIFICIO
STR02001;limite di strada;polilinea;3;0.18;continua;;;BORDO_STRADA
QUO01001;punto quotato;punto;5;0.13;;dot 0.7;;PUNTO_QUOTATO
VEG01001;area a verde;poligono;1;0.13;tratteggiata;;solid;AREA_VERDE
CUR01001;curva di livello direttrice;polilinea;7;0.25;;;;CURVA_DIRETTRICE
ALB01001;albero isolato;punto;1;0.13;;tree 2.0;;ALBERO
TOP01001;toponimo (località);testo;8;;;;;TOPONIMO
MAR01001;marciapiede;polilinea;2;0.18;continua;;;BORDO_STRADA
"""

COLOUR_FILE_TEXT = """\
INDICE\t%ROSSO\t%VERDE\t%BLU
1\t20\t80\t0
2\t10\t65\t65
3\t100\t0\t0
5\t0\t0\t100
7\t60\t40\t20
8\t0\t0\t0
12\t30\t30\t30
"""

PARAMETER_FILE_TEXT = parameter_file_text(
    ["File dei parametri - restituzione foglio Siena est (EPSG:3003)"],
    ("0.50", "0.20", "0.10", "m", "3", "1688000 4799000", "0.10", "0.20", "3.0", "2.0", "0.50",
     "0.30"))


def _contour(z: float) -> list[tuple[float, float, float]]:
    """A gently curving contour across the sheet, plotted in stream mode every ~0.5 m."""
    import math

    pts = []
    for k in range(0, 111):
        x = k * 0.45
        pts.append((x, 55.0 + 2.5 * math.sin(x / 8.0), z))
    return pts


#: model number -> list of (code, colour or None, source, local vertices (x, y, z))
MODELS: dict[int, list[tuple[str, str | None, str, list[tuple[float, float, float]]]]] = {
    12: [
        ("FAB01002", None, "1", [(10, 10, 331.2), (30.06, 10.03, 331.2), (30.02, 25.05, 331.2),
                                 (9.97, 24.98, 331.2), (10, 10, 331.2)]),          # building A
        ("FAB01002", None, "1", [(30.06, 10.03, 329.4), (42, 10, 329.4), (42.04, 25.02, 329.4),
                                 (30.02, 25.05, 329.4), (30.06, 10.03, 329.4)]),  # building B
        ("STR02001", None, "1", [(0, 40, 320.0), (25, 40.02, 320.1), (50.05, 40, 320.2)]),
        ("STR02001", None, "1", [(0, 50, 320.3), (50, 50.01, 320.3)]),
        ("QUO01001", None, "1", [(20, 45, 320.55)]),                               # spot height
        ("FAB01002", None, "1", [(46, 10, 327.0), (54, 10, 327.0), (54, 18, 327.0),
                                 (46, 18, 327.0), (46, 10, 327.0)]),               # building C
        ("XYZ99999", None, "1", [(5, 30, 321.0), (8, 30, 321.0)]),                 # unknown code
        ("STR02001", None, "1", [(12, 35, 320.0)]),                                # one vertex
        ("VEG01001", None, "1", [(2, 2, 321), (8, 2, 321), (8, 7, 321), (2, 7, 321),
                                 (2, 3.2, 321)]),                                  # unclosed 1.2
        ("QUO01001", None, "1", [(35, 45, 320.6), (36, 45, 320.6)]),               # type mismatch
        ("CUR01001", "7", "1", _contour(325.0)[:112]),
    ],
    13: [
        ("STR02001", None, "1", [(50.1, 40.05, 320.22), (100, 40, 320.5)]),        # joins
        ("STR02001", None, "1", [(50.08, 50, 320.9), (100, 50, 321.0)]),           # dz 0.6
        ("FAB01002", None, "1", [(46.02, 10.01, 327.02), (54.01, 10, 327.0),
                                 (54, 18.02, 327.0), (46, 18, 327.0),
                                 (46.02, 10.01, 327.02)]),                         # C again
        ("FAB01002", None, "1", [(60, 10, 330.0), (79.95, 10.08, 330.0), (80.03, 30.04, 330.0),
                                 (59.96, 29.97, 330.0), (60, 10, 330.0)]),         # building E
        ("FAB01002", None, "1", [(85, 5, 328.0), (95, 5, 328.0), (95, 15, 328.0),
                                 (85, 15, 328.0), (85, 5.3, 328.0)]),              # D, 0.3 gap
        ("QUO01001", None, "1", [(75, 45, 320.9)]),
    ],
}

DEFECTS = {"duplicates_removed": 1, "joins": 1, "joins_refused_height": 1,
           "unresolved": {"unknown_code": 1, "degenerate": 1, "unclosed_polygon": 1,
                          "type_mismatch": 1}, "polygons_closed": 1}


def ascii_export(entities, offset=FALSE_ORIGIN, model: int | None = None) -> str:
    """The ASCII restitution export of ``entities`` (stored relative to ``offset``)."""
    lines = [f"# esportazione ASCII della restituzione - modello {model}",
             "# CODE <codice> [colore] [provenienza] / E N Z / END"]
    for code, colour, source, pts in entities:
        head = f"CODE {code}"
        if colour or source:
            head += f" {colour or 0} {source}"
        lines.append(head)
        for x, y, z in pts:
            lines.append(f"{E0 + x - offset[0]:.3f} {N0 + y - offset[1]:.3f} {z:.3f}")
        lines.append("END")
    return "\n".join(lines) + "\n"


def write_dxf(path: Path) -> None:
    """A DXF of the sheet in map coordinates: layers are codes; a closed LWPOLYLINE building,
    a 3D POLYLINE road edge, a POINT spot height, two INSERTs of the tree block ALBERO and a
    TEXT place name."""
    import ezdxf

    doc = ezdxf.new("R2010")
    for code, colour in (("FAB01002", 8), ("STR02001", 1), ("QUO01001", 5), ("ALB01001", 3),
                         ("TOP01001", 7)):
        doc.layers.add(code, color=colour)
    tree = doc.blocks.new("ALBERO")
    tree.add_circle((0, 0), 1.0)
    msp = doc.modelspace()
    msp.add_lwpolyline([(E0 + 60, N0 + 10), (E0 + 80, N0 + 10), (E0 + 80, N0 + 30),
                        (E0 + 60, N0 + 30)], close=True,
                       dxfattribs={"layer": "FAB01002", "elevation": 330.0})
    msp.add_polyline3d([(E0, N0 + 40, 320.0), (E0 + 50, N0 + 40, 320.2),
                        (E0 + 100, N0 + 40, 320.5)], dxfattribs={"layer": "STR02001"})
    msp.add_point((E0 + 20, N0 + 45, 320.55), dxfattribs={"layer": "QUO01001"})
    msp.add_blockref("ALBERO", (E0 + 5, N0 + 20, 321.0),
                     dxfattribs={"layer": "ALB01001", "rotation": 30.0, "xscale": 1.5,
                                 "yscale": 1.5})
    msp.add_blockref("ALBERO", (E0 + 5, N0 + 28, 321.0), dxfattribs={"layer": "ALB01001"})
    msp.add_text("Località Pian dei Mantellini", height=2.0, rotation=0.0,
                 dxfattribs={"layer": "TOP01001", "insert": (E0 + 30, N0 + 47, 320.0)})
    doc.saveas(path)


def make(folder: Path, made: dict) -> dict:
    paths = {"restitution_codes": folder / "siena_codici.txt",
             "restitution_colours": folder / "siena_colori.txt",
             "restitution_parameters": folder / "siena_parametri_restituzione.txt",
             "restitution_model_12": folder / "siena_modello_12.txt",
             "restitution_model_13": folder / "siena_modello_13.txt",
             "restitution_dxf": folder / "siena_restituzione.dxf"}
    # the code file in Latin-1, as Windows plotting software writes it
    paths["restitution_codes"].write_bytes(CODE_FILE_TEXT.encode("latin-1"))
    paths["restitution_colours"].write_text(COLOUR_FILE_TEXT, encoding="utf-8")
    paths["restitution_parameters"].write_text(PARAMETER_FILE_TEXT, encoding="utf-8")
    for model in (12, 13):
        paths[f"restitution_model_{model}"].write_text(ascii_export(MODELS[model], model=model),
                                           encoding="utf-8")
    write_dxf(paths["restitution_dxf"])
    return paths
