"""Parameters shared by ``topology:build_areas`` and ``topology:check`` (declared once)."""

from __future__ import annotations

from typing import Any

from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs, crs_label
from toolbox.io.vector import read_vector
from toolbox.parameters import Field, File, Number, VectorLayer


def linework_parameters() -> list:
    """INPUT, CODE_FIELD, LABELS, LABEL_CODE_FIELD, CODES, PARAMETERS and the tolerances."""
    return [
        VectorLayer("INPUT", "restitution lines with a code field (polygons are used by their "
                    "rings)", geometry_types=["line", "polygon"]),
        Field("CODE_FIELD", "field with the line code (default: a field named code or codice)",
              parent="INPUT", optional=True),
        VectorLayer("LABELS", "label points: a code and attributes (e.g. quota) for the area "
                    "they fall in", geometry_types=["point"], optional=True),
        Field("LABEL_CODE_FIELD", "field with the area code of the label points (default: a "
              "field named code or codice)", parent="LABELS", optional=True),
        File("CODES", "code file ('file dei codici'): which codes are area codes (type polygon) "
             "and which area code a closed line of a line code gives (its area column); only "
             "area codes can conflict. Without it a closed line's code only fills an area no "
             "label codes", optional=True),
        File("PARAMETERS", "parameter file ('file dei parametri': tolleranza di riattacco, "
             "tolleranza di chiusura, ...); explicit tolerances override it", optional=True),
        Number("SNAP_TOLERANCE", "snap (riattacco) distance for line ends, CRS units "
               "[default: parameter file, else 0.2]", min_value=0, optional=True),
        Number("CLOSURE_TOLERANCE", "largest gap closed between the two ends of a polyline "
               "[default: parameter file, else 0.5]", min_value=0, optional=True),
        Number("MIN_DANGLE_LENGTH", "shorter dangles and overshoots are removed, longer ones "
               "reported [default: parameter file, else 1.0]", min_value=0, optional=True),
        Number("MIN_AREA", "smaller areas are slivers, merged into a neighbour, square CRS units "
               "[default: parameter file, else 1.0]", min_value=0, optional=True),
        Number("PRECISION", "coordinate grid of the result, CRS units [default: 10^-decimals "
               "of the parameter file, else 0.001]", min_value=0, min_exclusive=True,
               optional=True),
    ]


def read_linework(params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
    """Read INPUT and LABELS; pick code fields; check CRSs. Returns what the kernel needs."""
    import numpy as np

    from toolbox.topology.layers import default_code_field, label_inputs

    lines = read_vector(params["INPUT"], name="INPUT")
    if len(lines) == 0:
        raise InputDataError(f"INPUT {params['INPUT']} has no features")
    code_field = params.get("CODE_FIELD") or default_code_field(
        [c for c in lines.columns if c != lines.geometry.name])
    if code_field is None:
        feedback.push_warning("INPUT has no code field (CODE_FIELD not given, no field named "
                              "code/codice): arcs carry no original codes")
        codes = np.full(len(lines), None, dtype=object)
    else:
        codes = lines[code_field].to_numpy(dtype=object)
    out: dict[str, Any] = {"line_geoms": np.asarray(lines.geometry.values, dtype=object),
                           "line_codes": codes, "code_field": code_field,
                           "label_geoms": None, "label_codes": None, "label_attributes": None,
                           "label_dtypes": {}, "label_code_field": None}
    crs_of = {"INPUT": lines.crs}
    if params.get("LABELS") is not None:
        labels = read_vector(params["LABELS"], name="LABELS")
        label_field = params.get("LABEL_CODE_FIELD") or default_code_field(
            [c for c in labels.columns if c != labels.geometry.name])
        if label_field is None:
            feedback.push_warning("LABELS has no code field (LABEL_CODE_FIELD not given, no field "
                                  "named code/codice): areas get attributes but no code")
        geoms, label_codes, attrs, dtypes = label_inputs(labels, label_field)
        out.update(label_geoms=geoms, label_codes=label_codes, label_attributes=attrs,
                   label_dtypes=dtypes, label_code_field=label_field)
        crs_of["LABELS"] = labels.crs
    if params.get("PARAMETERS") is not None:  # the file's coordinate translation, applied
        from toolbox.io.parameter_file import read_parameter_file

        file = read_parameter_file(params["PARAMETERS"], "PARAMETERS")
        if file.offset != (0.0, 0.0):
            out["line_geoms"] = file.translate(out["line_geoms"])
            if out["label_geoms"] is not None:
                out["label_geoms"] = file.translate(out["label_geoms"])
            feedback.push_info(f"PARAMETERS: coordinate translation {file.offset[0]:.10g} "
                               f"{file.offset[1]:.10g} added to the inputs")
    out["area_codes"] = None
    if params.get("CODES") is not None:
        out["area_codes"] = read_area_codes(params["CODES"], out["label_codes"], feedback)
    crs = common_crs(crs_of)
    if crs is None:
        feedback.push_warning("the inputs have no CRS: the output has none either")
    out["crs"] = crs
    out["crs_label"] = crs_label(crs)
    return out


def read_area_codes(path: Any, label_codes: Any, feedback: Feedback | None = None) -> Any:
    """The area codes of the code file CODES; a warning lists label codes it does not know."""
    from toolbox.io.code_file import read_code_file
    from toolbox.topology.area_codes import AreaCodes
    from toolbox.topology.labels import blank_mask

    codes = AreaCodes.from_table(read_code_file(path, "CODES"))
    if feedback is not None and label_codes is not None and len(label_codes):
        present = [str(c).strip() for c, b in zip(label_codes, blank_mask(label_codes),
                                                  strict=True) if not b]
        unknown = sorted(set(present) - codes.known)
        if unknown:
            feedback.push_warning(f"{len(unknown)} label codes not in CODES, taken as area "
                                  f"codes: {', '.join(unknown[:10])}"
                                  + (" ..." if len(unknown) > 10 else ""))
    return codes
