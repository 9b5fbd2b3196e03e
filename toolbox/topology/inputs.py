"""The inputs of ``topology:build_areas`` and ``topology:check``: lines, labels, codes."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs, crs_label
from toolbox.io.vector import read_vector, single_points


@dataclass(frozen=True)
class LineworkSources:
    """The inputs of area building and its checks.

    ``lines``: restitution lines (a vector layer) with a code field ``code_field`` (None: a
    field named code/codice); ``labels``: label points with ``label_code_field``; ``codes``:
    the code file (which codes are area codes); ``parameters``: the parameter file, whose
    coordinate translation is added to lines and labels.
    """

    lines: Any
    code_field: str | None = None
    labels: Any = None
    label_code_field: str | None = None
    codes: Path | None = None
    parameters: Path | None = None


def read_linework(sources: LineworkSources, feedback: Feedback) -> dict[str, Any]:
    """Read the lines and labels; pick code fields; check CRSs. Returns what the kernel
    needs."""
    import numpy as np

    from toolbox.topology.layers import default_code_field, label_inputs

    lines = read_vector(sources.lines, name="INPUT")
    if len(lines) == 0:
        raise InputDataError(f"INPUT {sources.lines} has no features")
    code_field = sources.code_field or default_code_field(
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
    if sources.labels is not None:
        labels = read_vector(sources.labels, name="LABELS")
        label_field = sources.label_code_field or default_code_field(
            [c for c in labels.columns if c != labels.geometry.name])
        if label_field is None:
            feedback.push_warning("LABELS has no code field (LABEL_CODE_FIELD not given, no field "
                                  "named code/codice): areas get attributes but no code")
        labels[labels.geometry.name] = single_points(labels.geometry.values, "LABELS")
        geoms, label_codes, attrs, dtypes = label_inputs(labels, label_field)
        out.update(label_geoms=geoms, label_codes=label_codes, label_attributes=attrs,
                   label_dtypes=dtypes, label_code_field=label_field)
        crs_of["LABELS"] = labels.crs
    if sources.parameters is not None:  # the file's coordinate translation, applied
        from toolbox.io.parameter_file import read_parameter_file

        file = read_parameter_file(sources.parameters, "PARAMETERS")
        if file.offset != (0.0, 0.0):
            out["line_geoms"] = file.translate(out["line_geoms"])
            if out["label_geoms"] is not None:
                out["label_geoms"] = file.translate(out["label_geoms"])
            feedback.push_info(f"PARAMETERS: coordinate translation {file.offset[0]:.10g} "
                               f"{file.offset[1]:.10g} added to the inputs")
    out["area_codes"] = None
    if sources.codes is not None:
        out["area_codes"] = read_area_codes(sources.codes, out["label_codes"], feedback)
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
