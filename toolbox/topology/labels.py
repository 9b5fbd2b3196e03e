"""Label points give areas their code and attributes (thesis S002 §2.2.2: a spot height plotted
inside an area becomes the area's height attribute; §2.4: "codifica logica" of areas).

A label point strictly inside an area labels it. A point with an empty code contributes its
attributes only (e.g. a spot height that is not an area code), and so does a point whose code the
code file declares a point code. When the labels of one area give different area codes,
or different non-null values of one attribute, the area is *conflicting*: it takes the values of
its first label (input order) and is reported. A point on a boundary or outside the linework
labels nothing and is reported.

A closed coded outline codes the area it bounds too (the thesis' building plotted closed with the
building code, §2.2.2), when its code is an area code or names one in the code file
(:mod:`toolbox.topology.area_codes`): the face takes it when no label gives a code. Only area
codes can disagree: a label code that is neither one of an outline's area codes nor the outline's
own code, or two outlines with no area code in common, make the face conflicting (the label's
code is kept).
Without a code file an outline's code fills an uncoded face and never conflicts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import shapely

from toolbox.topology.area_codes import AreaCodes


def is_blank(value: Any) -> bool:
    """None, NaN and empty/whitespace text count as "no value"."""
    if value is None:
        return True
    if isinstance(value, str):
        return not value.strip()
    try:
        return bool(pd.isna(value))
    except (TypeError, ValueError):
        return False


def blank_mask(values: np.ndarray) -> np.ndarray:
    """Vectorised :func:`is_blank` over an object array."""
    arr = np.asarray(values, dtype=object)
    mask = np.asarray(pd.isna(arr), dtype=bool).reshape(-1)
    text = np.fromiter((isinstance(v, str) for v in arr), dtype=bool, count=len(arr))
    if text.any():
        mask[text] = np.char.strip(arr[text].astype(str)) == ""
    return mask


@dataclass
class LabelAssignment:
    """Result of :func:`assign_labels`.

    Attributes
    ----------
    label_face : (L,) face index of each label, -1 outside every face.
    face_code : (F,) object array, the area code (None when unlabelled).
    face_attributes : dict name -> (F,) object array of attribute values (None when missing).
    face_labels : (F,) int array, number of labels inside each face.
    face_first_label : (F,) int array, first label (input order) in each face, -1 when none.
    conflicts : dict face -> text describing the disagreement.
    """

    label_face: np.ndarray
    face_code: np.ndarray
    face_attributes: dict[str, np.ndarray]
    face_labels: np.ndarray
    face_first_label: np.ndarray
    conflicts: dict[int, str] = field(default_factory=dict)


def _show(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


#: the codes one closed outline offers the face it bounds: (line code, area codes it may give)
Outline = tuple[str, tuple[str, ...]]


def outline_codes(faces: np.ndarray, outlines: np.ndarray, codes: np.ndarray,
                  precision: float, area_codes: AreaCodes | None = None) -> list[list[Outline]]:
    """The closed outlines that bound each face and the area codes they give it: an outline
    bounds a face when the face's exterior ring lies within ``2 * precision`` of it everywhere
    (Hausdorff distance), so vertices added by noding do not matter. Blank codes are ignored, and
    with ``area_codes`` so are codes that give no area code (a kerb closed around a block).

    Parameters
    ----------
    faces : (F,) Polygons. outlines : (K,) closed LineStrings (same coordinates).
    codes : (K,) their codes. precision : the coordinate grid.
    area_codes : the code file's area codes; None: an outline's code is its face's code.
    """
    found: list[list[Outline]] = [[] for _ in range(len(faces))]
    codes = np.asarray(codes, dtype=object)
    keep = ~blank_mask(codes) if len(codes) else np.zeros(0, bool)
    outlines, codes = np.asarray(outlines, dtype=object)[keep], codes[keep]
    if area_codes is not None and len(codes):
        gives = np.fromiter((bool(area_codes.of_outline(str(c).strip())) for c in codes),
                            dtype=bool, count=len(codes))
        outlines, codes = outlines[gives], codes[gives]
    if not len(faces) or not len(outlines):
        return found
    rings = shapely.get_exterior_ring(faces)
    oi, fi = shapely.STRtree(rings).query(outlines, predicate="dwithin", distance=2 * precision)
    for o, f in zip(oi.tolist(), fi.tolist(), strict=True):
        if shapely.hausdorff_distance(rings[f], outlines[o]) <= 2 * precision:
            code = str(codes[o]).strip()
            areas = (code,) if area_codes is None else area_codes.of_outline(code)
            if all(code != c for c, _ in found[f]):
                found[f].append((code, areas))
    return found


def _outline_text(code: str, areas: tuple[str, ...]) -> str:
    return code if areas == (code,) else f"{code} (area {' or '.join(areas)})"


def _outline_conflicts(outline: list[Outline], label_code: Any) -> tuple[str | None, str | None]:
    """(code for the face, problem text or None) from its outlines and its label code (None)."""
    if label_code is not None:
        label = str(label_code).strip()
        wrong = [o for o in outline if label not in o[1] and label != o[0]]
        if not wrong:
            return None, None
        lines = ", ".join(_outline_text(*o) for o in wrong)
        return None, (f"closed line {lines} and label code {label_code} disagree: the label's "
                      "code is used")
    common = [c for c in outline[0][1] if all(c in areas for _, areas in outline[1:])]
    if common:
        return common[0], None
    lines = ", ".join(_outline_text(*o) for o in outline)
    return outline[0][1][0], (f"closed lines {lines} give different area codes: "
                              f"{outline[0][1][0]} (the first line's) is used")


def assign_labels(faces: np.ndarray, points: np.ndarray, codes: np.ndarray,
                  attributes: dict[str, np.ndarray] | None = None,
                  face_outline_codes: list[list[Outline]] | None = None,
                  area_codes: AreaCodes | None = None) -> LabelAssignment:
    """Give each face the code and attributes of the label points inside it, else the area code
    of its closed coded outline.

    Parameters
    ----------
    faces : (F,) Polygons.
    points : (L,) Points (same coordinates as ``faces``).
    codes : (L,) codes (text; blank = attributes only).
    attributes : dict name -> (L,) values, optional.
    face_outline_codes : per face, the closed outlines bounding it (see :func:`outline_codes`),
        optional.
    area_codes : the code file's area codes: label codes it declares point codes give
        attributes only, and outlines are checked against the labels. None: every label code is
        an area code, outlines only fill faces without one.
    """
    attributes = attributes or {}
    codes = np.asarray(codes, dtype=object)
    if area_codes is not None and len(codes):
        blank = blank_mask(codes)
        not_area = np.fromiter((not b and not area_codes.is_area_label(str(c).strip())
                                for c, b in zip(codes, blank, strict=True)),
                               dtype=bool, count=len(codes))
        codes = np.where(not_area, None, codes)
    nf, nl = len(faces), len(points)
    label_face = np.full(nl, -1, dtype=np.int64)
    if nf and nl:
        li, fi = shapely.STRtree(faces).query(points, predicate="within")
        label_face[li] = fi
    face_code = np.full(nf, None, dtype=object)
    face_attrs = {name: np.full(nf, None, dtype=object) for name in attributes}
    counts = np.bincount(label_face[label_face >= 0], minlength=nf)
    first = np.full(nf, -1, dtype=np.int64)
    conflicts: dict[int, str] = {}
    inside = np.flatnonzero(label_face >= 0)
    order = inside[np.lexsort((inside, label_face[inside]))]
    bounds = np.searchsorted(label_face[order], np.arange(nf + 1))
    codes = np.asarray(codes, dtype=object)
    code_blank = blank_mask(codes)
    attr_blank = {name: blank_mask(values) for name, values in attributes.items()}
    # one label: its values (the common case, vectorised)
    single = np.flatnonzero(counts == 1)
    lab = order[bounds[single]]
    first[single] = lab
    ok = ~code_blank[lab]
    face_code[single[ok]] = codes[lab[ok]]
    for name, values in attributes.items():
        ok = ~attr_blank[name][lab]
        face_attrs[name][single[ok]] = np.asarray(values, dtype=object)[lab[ok]]
    # several labels: first non-blank value, conflicts reported
    for f in np.flatnonzero(counts > 1):
        members = order[bounds[f]:bounds[f + 1]]
        first[f] = members[0]
        problems = []
        found = [codes[i] for i in members if not code_blank[i]]
        if found:
            face_code[f] = found[0]
            distinct = list(dict.fromkeys(str(c) for c in found))
            if len(distinct) > 1:
                problems.append(f"{len(found)} labels give area codes {', '.join(distinct)}: "
                                f"{distinct[0]} (the first label's) is used")
        for name, values in attributes.items():
            present = [values[i] for i in members if not attr_blank[name][i]]
            if present:
                face_attrs[name][f] = present[0]
                distinct = list(dict.fromkeys(_show(v) for v in present))
                if len(distinct) > 1:
                    problems.append(f"{len(present)} labels give {name} {', '.join(distinct)}: "
                                    f"{distinct[0]} (the first label's) is used")
        if problems:
            conflicts[int(f)] = "; ".join(problems)
    for f, outline in enumerate(face_outline_codes or []):
        if not outline:
            continue
        if area_codes is None:  # no code file: fill only, never a conflict
            if face_code[f] is None:
                face_code[f] = outline[0][0]
            continue
        code, problem = _outline_conflicts(outline, face_code[f])
        if face_code[f] is None:
            face_code[f] = code
        if problem:
            conflicts[f] = "; ".join([conflicts[f], problem] if f in conflicts else [problem])
    return LabelAssignment(label_face, face_code, face_attrs, counts, first, conflicts)
