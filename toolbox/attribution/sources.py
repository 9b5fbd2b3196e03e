"""Reading the restitution inputs (shared by the ``attribution:*`` algorithms)."""

from __future__ import annotations

from typing import Any

from toolbox.errors import InputDataError


def read_sources(inputs: list, crs: Any, feedback: Any, *, coordinates: Any = None,
                 code_field: str | None = None) -> tuple[list, dict]:
    """The entity tables of the restitution files ``inputs`` (one per model; messages call
    them INPUT) and the readers' reports. With ``coordinates`` (COORDINATES) given, the single
    input is the descriptions table of the two-table form. ``code_field``: the code field of
    an OGR layer (None: found by name)."""
    from toolbox.attribution.restitution import read_restitution, read_two_tables

    reports: dict[str, Any] = {}
    if coordinates is not None:
        if len(inputs) != 1:
            raise InputDataError("INPUT: with COORDINATES give exactly one descriptions file, "
                                 f"got {len(inputs)}")
        frame, report = read_two_tables(inputs[0], coordinates, "INPUT",
                                        "COORDINATES", crs)
        if report["bbox_mismatches"]:
            feedback.push_warning(f"INPUT: {len(report['bbox_mismatches'])} records whose "
                                  "bounding box does not hold their vertices (records "
                                  f"{report['bbox_mismatches'][:10]})")
        return [frame], {"two_tables": report}
    frames = []
    for k, source in enumerate(inputs, start=1):
        frame, report = read_restitution(source, code_field, "INPUT", crs)
        skipped = report.get("skipped_dxf_entities")
        if skipped:
            feedback.push_warning(f"INPUT {k}: DXF entities not read: "
                                  + ", ".join(f"{n} {t}" for t, n in sorted(skipped.items())))
        hidden = report.get("hidden_dxf_layers")
        if hidden:
            feedback.push_warning(
                f"INPUT {k}: DXF entities on frozen or switched-off layers left out (not "
                "drawn, not deliverables): " + ", ".join(
                    f"{n} on {layer!r} ({state})" for layer, (n, state) in sorted(hidden.items())))
        frames.append(frame)
        reports[f"input_{k}"] = report
    from toolbox.io.crs import common_crs

    # models of one block share a CRS (merging them in two would join lines kilometres apart)
    common = common_crs({f"INPUT {k}": f.crs for k, f in enumerate(frames, start=1)}, crs)
    frames = [f if f.crs is not None or common is None else f.set_crs(common) for f in frames]
    return frames, reports


def translated(frame, file) -> Any:
    """``frame`` with the parameter file's coordinate translation added (a new frame)."""
    import geopandas as gpd

    return frame.set_geometry(gpd.GeoSeries(list(file.translate(frame.geometry.values)),
                                            crs=frame.crs, index=frame.index))


def check_coordinates(frames: list, algorithm_id: str, translated_by_file: bool) -> None:
    """Refuse entities the algorithm cannot measure in metres: a geographic CRS, or coordinates
    far outside their CRS's area of use (model coordinates labelled with a map CRS: the
    parameter file's coordinate translation is missing)."""
    import numpy as np

    from toolbox.errors import InputDataError
    from toolbox.io.crs import check_input_crs, outside_area_of_use, parse_crs

    for frame in frames:
        if frame.crs is None or not len(frame):
            continue
        crs = parse_crs(frame.crs, "INPUT")
        check_input_crs(algorithm_id, "INPUT", crs)  # geographic: refused
        bounds = tuple(float(b) for b in frame.total_bounds)
        if not np.isfinite(bounds).all():
            continue
        problem, far = outside_area_of_use(crs, bounds)
        if problem and far:
            hint = ("check the coordinate translation of PARAMETERS" if translated_by_file else
                    "if they are model (local) coordinates, give PARAMETERS with the coordinate "
                    "translation ('traslazione delle coordinate') to map coordinates")
            raise InputDataError(f"INPUT: {problem}: {hint}, or label the data with its true "
                                 "CRS")
