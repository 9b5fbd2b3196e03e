"""Realistic auxiliary and restitution files for the attribution tests, with every defect of
issue 14 (see :func:`make_files` for the truth)."""

from __future__ import annotations

E0, N0 = 1688500.0, 4799700.0

CODES = """\
# file dei codici: Z-Map columns with an Italian header, Latin-1
codice;descrizione;tipologia;colore
FAB01002;muro perimetrale di fabbricato civile;poligono;12
STR02001;limite di strada;polilinea;3
QUO01001;punto quotato;punto;5
VEG01001;area a verde;poligono;1
ALB01001;albero isolato;punto;1
TOP01001;toponimo di località;testo;8
MAR01001;marciapiede;polilinea;2
FER01001;binario;polilinea;44
"""

COLOURS = """\
INDICE %ROSSO %VERDE %BLU
1 20 80 0
2 10 65 65
3 100 0 0
5 0 0 100
8 0 0 0
12 30 30 30
"""

PARAMETERS = """\
tolleranza di riattacco planimetrico = 0.20
tolleranza di riattacco altimetrico  = 0.10
numero di cifre decimali             = 3
traslazione delle coordinate         = 1688000 4799000
tolleranza di chiusura               = 0.50
passo di spline                      = 2.0
"""


def _xyz(x, y, z):
    """Stored coordinates: map minus the translation 1688000 4799000."""
    return f"{E0 + x - 1688000:.3f} {N0 + y - 4799000:.3f} {z:.2f}"


#: (header, vertices) of the ASCII export, in order (entity numbers 1..13)
ENTITIES = [
    ("CODE FAB01002 12 1", [(0, 0, 330), (20, 0, 330), (20, 10, 330), (0, 10, 330), (0, 0, 330)]),
    ("CODE FAB01002", [(30, 0, 331), (40, 0, 331), (40, 8, 331), (30, 8, 331), (30, 0.3, 331)]),
    ("CODE FAB01002 12 1", [(50, 0, 332), (60, 0, 332), (60, 8, 332), (50, 8, 332),
                            (50, 1.2, 332)]),                                 # 3 unclosed 1.2
    ("CODE STR02001 3 1", [(0, 20, 320.0), (30, 20.5, 320.2), (60, 20, 320.4)]),
    ("CODE STR02001 3 1", [(5, 25, 320.0)]),                                  # 5 one vertex
    ("CODE QUO01001 5 3", [(10, 15, 321.25)]),
    ("CODE QUO01001 5 3", [(12, 15, 321.0), (13, 15, 321.0)]),                # 7 mismatch
    ("CODE XYZ99999 0 1", [(1, 30, 320), (2, 30, 320)]),                      # 8 unknown code
    ("CODE VEG01001 1 1", [(70, 0, 321), (80, 10, 321), (80, 0, 321), (70, 10, 321),
                           (70, 0, 321)]),                                    # 9 bow-tie
    ("CODE VEG01001 1 1", [(70, 20, 321), (75, 20, 321), (80, 20, 321), (70, 20, 321)]),  # 10
    ("CODE MAR01001 2 1", []),                                                # 11 no vertices
    ("CODE FER01001", [(0, 40, 319), (60, 40, 319.6)]),                       # 12 colour 44
    ("code str02001", [(0, 50, 318), (10, 50, 318)]),                         # 13 lower case
]


def make_files(tmp_path):
    """Code, colour, parameter files and an ASCII export. Truth: entities 1, 2 (closed, gap
    0.3), 4, 6, 12 resolve; 3 unclosed_polygon; 5 degenerate (one vertex); 7 type_mismatch;
    8 unknown_code; 9 invalid_polygon (bow-tie); 10 degenerate (zero area); 11 no_vertices;
    13 unknown_code (codes are case-sensitive: 'str02001')."""
    codes = tmp_path / "codici.txt"
    codes.write_bytes(CODES.encode("latin-1"))
    colours = tmp_path / "colori.txt"
    colours.write_text(COLOURS)
    params = tmp_path / "parametri.txt"
    params.write_text(PARAMETERS)
    lines = ["# esportazione ASCII - modello 7", ""]
    for header, pts in ENTITIES:
        lines.append(header + "   # entity")
        lines += [_xyz(*p) for p in pts]
        lines.append("END")
    export = tmp_path / "modello_7.txt"
    export.write_text("\n".join(lines) + "\n")
    return {"codes": codes, "colours": colours, "params": params, "export": export,
            "folder": tmp_path}
