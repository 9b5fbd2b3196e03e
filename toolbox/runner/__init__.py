"""Runner: validate parameters -> execute -> check and move outputs into place -> JSON report.

Promises kept here, for every algorithm: an input is never overwritten (every path the run
writes, report and sidecars included, is compared with every input after resolving symlinks and
``..``, whatever ``overwrite`` says); a failed, canceled or interrupted run leaves nothing (no
staged file, no output folder it created); a write error (full disk, read-only folder) is one
:class:`~toolbox.errors.OutputWriteError`; a raster output without a single valid cell is an
error, not an all-nodata file.

>>> import toolbox
>>> toolbox.run("dem:hillshade", {"INPUT": "dem.tif", "OUTPUT": "hs.tif"})  # doctest: +SKIP
{'OUTPUT': '/abs/path/hs.tif'}
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import OutputWriteError, ParameterError, ToolboxError
from toolbox.feedback import Feedback, logged_warnings
from toolbox.io.source_date import source_date, source_date_for_gdal
from toolbox.io.staging import OutputStaging, write_error
from toolbox.parameters import (
    Boolean,
    Number,
    OutputFolder,
    OutputVector,
    RasterLayer,
    ValidationContext,
)
from toolbox.registry import get
from toolbox.runner.failures import (
    as_read_error,
    as_write_error,
    check_gdal_errors,
    check_raster_outputs,
    collect_gdal_errors,
    named_write_error,
)
from toolbox.runner.paths import (  # noqa: F401 - input_paths, planned_paths: public here too
    REPORT,
    check_inputs_unchanged,
    check_outputs_against_inputs,
    check_planned_files,
    check_report,
    declared_layer_files,
    input_paths,
    input_stamps,
    planned_paths,
)

OVERWRITE = "OVERWRITE"


def _pop_overwrite(parameters: dict[str, Any], overwrite: bool) -> tuple[dict[str, Any], bool]:
    params = dict(parameters)
    if OVERWRITE in params:
        overwrite = Boolean(OVERWRITE).validate(params.pop(OVERWRITE), ValidationContext())
    return params, overwrite


def validate(algorithm: type[Algorithm] | str, parameters: dict[str, Any],
             overwrite: bool = False, warnings: list[str] | None = None) -> dict[str, Any]:
    """Validate ``parameters`` for an algorithm; return the normalised values.

    Unknown names, missing required values and bad values raise :class:`ParameterError`; so do
    outputs that would replace an input and, for algorithms working in metres, geographic CRSs.
    Coordinates a little outside their CRS's area of use add a message to ``warnings``.
    Nothing is written.
    """
    return _validate(algorithm, parameters, overwrite, warnings)[0]


def _validate(algorithm: type[Algorithm] | str, parameters: dict[str, Any],
              overwrite: bool = False, warnings: list[str] | None = None
              ) -> tuple[dict[str, Any], dict[Path, str]]:
    """:func:`validate`'s values and the run's :func:`input_paths`, worked out once (a
    project's or a VRT's files, every sidecar: a few stat calls per input file) for the checks
    here and the run's protection of its inputs."""
    alg = get(algorithm) if isinstance(algorithm, str) else algorithm
    params, overwrite = _pop_overwrite(parameters, overwrite)
    if not isinstance(params, dict):
        raise ParameterError("", f"parameters must be a mapping of NAME: value, got {params!r}")
    params = alg.rename_deprecated(params)
    known = {p.name for p in alg.parameters}
    unknown = sorted(set(params) - known, key=str)
    if unknown:
        raise ParameterError(str(unknown[0]), f"is not a parameter of {alg.id}; its parameters "
                             f"are: {', '.join(p.name for p in alg.parameters)}")
    ctx = ValidationContext(overwrite=overwrite)
    # inputs first (so outputs can be checked against every input path), in declaration order
    ordered = [p for p in alg.parameters if not p.is_output] + alg.destinations()
    for p in ordered:
        try:
            ctx.values[p.name] = p.resolve(params.get(p.name), ctx)
        except OSError as exc:  # a path the system refuses (name too long, a file as folder...)
            raise ParameterError(p.name, f"cannot use {params.get(p.name)!r}: "
                                 f"{exc.strerror or exc}") from None
        check_parameter_crs(alg, p, ctx.values[p.name], warnings)
    values = {p.name: ctx.values[p.name] for p in alg.parameters}
    inputs = {p.name: values[p.name] for p in alg.parameters
              if not p.is_output and values[p.name] is not None and not read_in_pixels(p)}
    if len(inputs) > 1:  # toolbox.io.crs loads pyproj: not for a one-input run
        from toolbox.io.crs import check_unlabelled_in_area, warn_unlabelled_elsewhere

        warn_unlabelled_elsewhere(inputs, warnings)
        if alg.projected_crs_only and alg.crs_labels_inputs and hasattr(values.get("CRS"),
                                                                        "area_of_use"):
            check_unlabelled_in_area(inputs, values["CRS"], warnings)
    check_magnitudes(alg, values)
    _check_band(alg, values)
    input_files = input_paths(alg, values)
    check_outputs_against_inputs(alg, values, input_files)
    alg().check(values)
    check_planned_files(alg, values, overwrite, input_files)
    return values, input_files


TINY, HUGE = 1e-300, 1e150  # below (but not 0) / above: no computation with it is sound


def check_parameter_crs(alg: type[Algorithm], p: Any, value: Any,
                        warnings: list[str] | None = None) -> None:
    """The CRS rules of ``alg`` for the value of its input ``p``
    (:func:`toolbox.io.crs.check_input_crs` with the algorithm's length units); outputs and the
    algorithms that take any CRS pass, as do photos (read in pixels: their georeferencing, a
    world file say, is not used)."""
    if not p.is_output and alg.projected_crs_only and not read_in_pixels(p):
        from toolbox.io.crs import check_input_crs

        check_input_crs(alg.id, p.name, value, warnings, alg.length_units)


def read_in_pixels(p: Any) -> bool:
    """Whether the input ``p`` is a photo (a raster read in pixel coordinates)."""
    return getattr(p, "role", None) == "photo" or getattr(getattr(p, "_item", None), "role",
                                                         None) == "photo"


def check_magnitudes(alg_cls: type[Algorithm], values: dict[str, Any]) -> None:
    """Refuse numbers no computation survives: subnormal ones (``1e-320``: a division by it
    overflows) and ones whose square overflows (``1e308``)."""
    for p in alg_cls.parameters:
        value = values.get(p.name)
        if not isinstance(p, Number) or not isinstance(value, (int, float)) or value == 0:
            continue
        if abs(value) < TINY:
            raise ParameterError(p.name, f"is too small to compute with, got {value:g}; use 0 "
                                 f"or a value of at least {TINY:g}")
        if abs(value) > HUGE:
            raise ParameterError(p.name, f"is too large to compute with, got {value:g} (at most "
                                 f"{HUGE:g})")


def _check_band(alg_cls: type[Algorithm], values: dict[str, Any]) -> None:
    """The one BAND check: BAND exists in the DEM when given, else in the one raster input;
    the band read of each heights raster (BAND's, else band 1) holds heights, not colours,
    in the unit the algorithm reads them in (its band unit, unless Z_FACTOR converts them)."""
    band = values.get("BAND")
    given = {p.name: values[p.name] for p in alg_cls.parameters
             if isinstance(p, RasterLayer) and values.get(p.name) is not None}
    rasters = [given["DEM"]] if "DEM" in given else list(given.values())
    banded = rasters[0] if isinstance(band, int) and len(rasters) == 1 else None
    if banded is not None and band > banded.count:
        raise ParameterError("BAND", f"must be <= {banded.count} (bands of {banded}), got {band}")
    for p in alg_cls.parameters:
        if isinstance(p, RasterLayer) and p.role == "heights" and p.name in given:
            from toolbox.io.raster import require_height_band, require_height_unit

            info = given[p.name]
            require_height_band(info, p.name, *((band, "BAND") if info is banded else (1,)))
            z_factor = values.get("Z_FACTOR")
            if z_factor is None or z_factor == 1:  # a Z_FACTOR given converts the heights
                require_height_unit(info, p.name, band if info is banded else 1, alg_cls.id,
                                    alg_cls.length_units,
                                    "Z_FACTOR" if "Z_FACTOR" in values else None)


# -- what the run reads and writes ----------------------------------------------------------------


# -- run ------------------------------------------------------------------------------------------
def run(algorithm_id: str, parameters: dict[str, Any] | None = None,
        feedback: Feedback | None = None, overwrite: bool = False,
        report: str | Path | None = None) -> dict[str, Any]:
    """Run an algorithm and return its outputs (``{name: value}``; files as absolute paths).

    Parameters
    ----------
    algorithm_id : str
        ``group:name``, e.g. ``"dem:idw"``.
    parameters : dict
        Parameter values by UPPERCASE name (Python objects or text as on the command line).
        ``OVERWRITE: True`` may be given here instead of ``overwrite``.
    feedback : Feedback, optional
        Progress, messages and cancellation. A silent one is used by default.
    overwrite : bool
        Replace existing outputs (otherwise an existing output is an error). Inputs are never
        replaced.
    report : path, optional
        Write a JSON run report (parameters, versions, timings, outputs, warnings) there.

    Raises
    ------
    ToolboxError
        For every problem the user can fix (bad parameters, unreadable inputs, a full disk...).
        No output is left behind when a run fails or is canceled.
    """
    feedback = (feedback or Feedback()).step(0, 100)  # run-local messages and timings
    with logged_warnings(feedback):  # the report's warnings are the console's
        return _run(algorithm_id, parameters, feedback, overwrite, report)


def _run(algorithm_id: str, parameters: dict[str, Any] | None, feedback: Feedback,
         overwrite: bool, report: str | Path | None) -> dict[str, Any]:
    alg_cls = get(algorithm_id)
    started = time.time()
    t0 = time.perf_counter()
    params, overwrite = _pop_overwrite(parameters or {}, overwrite)
    crs_warnings: list[str] = []
    values, inputs = _validate(alg_cls, params, overwrite, crs_warnings)
    source_date()  # a malformed SOURCE_DATE_EPOCH: refused before anything is written
    for text in crs_warnings:
        feedback.push_warning(text)
    protected = set(inputs)
    stamps = input_stamps(inputs)  # an input written meanwhile: refused before the commit
    report_path = None if report is None else check_report(report, alg_cls, values, overwrite,
                                                            inputs)
    staging = OutputStaging(record=True)
    try:
        staged = dict(values)
        for dest in alg_cls.destinations():
            if values[dest.name] is None:
                continue
            if isinstance(dest, OutputFolder):
                staged[dest.name] = staging.stage_folder(values[dest.name], dest.name)
            else:
                staged[dest.name] = staging.stage(values[dest.name], dest.name,
                                                  declared_layer_files(dest, values[dest.name]))
        staged_report = None if report_path is None else staging.stage(report_path, REPORT)
        report_leftovers(staging, feedback)
        feedback.set_progress(0)
        with collect_gdal_errors() as gdal_errors, source_date_for_gdal():
            try:
                result = alg_cls().process(staged, feedback) or {}
            except OutputWriteError as exc:  # a writer's: name the output, its final path
                raise named_write_error(exc, staging) from None
            except (ToolboxError, KeyboardInterrupt):
                raise
            except Exception as exc:
                converted = as_write_error(exc, staging) or as_read_error(
                    exc, gdal_errors, alg_cls, values)
                if converted is None:
                    raise
                raise converted from None
        feedback.check_canceled()
        check_gdal_errors(gdal_errors, staging)
        check_raster_outputs(alg_cls, values, staging)
        write_declared_styles(alg_cls, values, staged)
        written = {final for _, final, staged_file in staging.items() if staged_file.exists()}
        outputs = _final_outputs(alg_cls, values, result, written)
        feedback.set_progress(100)
        if staged_report is not None:
            from toolbox.report import build_report, to_jsonable

            doc = build_report(alg_cls, values, to_jsonable(outputs), feedback, started,
                               time.perf_counter() - t0)
            try:
                staged_report.write_text(json.dumps(doc, indent=2) + "\n")
            except OSError as exc:
                raise write_error(exc, REPORT, report_path) from None
        feedback.check_canceled()  # again: a signal a library swallowed meanwhile stops it too
        check_inputs_unchanged(inputs, stamps)
        staging.commit(overwrite=overwrite, protected=protected)
    finally:
        staging.rollback()
    return outputs


def report_leftovers(staging: OutputStaging, feedback: Feedback) -> None:
    """One info line for the staging folders of killed runs the staging removed (with the space
    freed), a warning for each old one of another machine it left alone."""
    removed = staging.removed_stale
    if removed:
        names = ", ".join(str(p) for p in removed[:3]) + (", ..." if len(removed) > 3 else "")
        feedback.push_info(f"removed {len(removed)} staging folder{'s' * (len(removed) > 1)} of "
                           f"earlier runs that were killed ({_size(staging.freed)} freed):"
                           f" {names}")
    for folder, age in staging.foreign_staging:
        feedback.push_warning(f"left {folder} alone: the staging folder of a run on another "
                              f"machine or container (or of this one before a restart), "
                              f"{age / 86400:.0f} days old; remove it if no run writes there")


def _size(n: int) -> str:
    return next(f"{n / f:.1f} {unit}" for f, unit in ((1e9, "GB"), (1e6, "MB"), (1e3, "kB"),
                                                      (1, "bytes")) if n >= f or f == 1)


def write_declared_styles(alg_cls: type[Algorithm], values: dict[str, Any],
                          staged: dict[str, Any]) -> None:
    """Embed the default style of every layer an :class:`OutputVector` declares styled
    (``Layer(style=...)``, :mod:`toolbox.styles.layers`) in its staged GeoPackage; a one-layer
    format has no style table: the style goes beside each layer file as ``<stem>.qml``/``.sld``
    (staged with it, committed with it). Imports nothing unless a layer declares a style."""
    for dest in alg_cls.destinations():
        if not isinstance(dest, OutputVector):
            continue
        pairs = [(layer.name, layer.style) for layer in dest.layers if layer.style]
        path = staged.get(dest.name)
        if not pairs or path is None or not Path(path).is_file():
            continue
        import sqlite3

        from toolbox.io.vector import vector_driver
        from toolbox.styles.layers import write_declared_style_files
        from toolbox.styles.layers import write_declared_styles as write_styles

        try:
            if vector_driver(path) == "GPKG":
                write_styles(path, pairs)
            else:
                write_declared_style_files(path, [(layer.name, layer.style, layer.geometry_type)
                                                  for layer in dest.layers])
        except (OSError, sqlite3.Error) as exc:  # a full disk, a read-only folder
            raise write_error(exc, dest.name, values[dest.name]) from None


# -- write-error detection (by type and by the disk, never by message text) ---------------------


def _final_outputs(alg_cls: type[Algorithm], values: dict[str, Any], result: dict[str, Any],
                   written: set[Path]) -> dict[str, Any]:
    outputs: dict[str, Any] = {}
    for dest in alg_cls.destinations():
        final = values[dest.name]
        if final is None:
            continue
        final_abs = Path(final).expanduser().absolute()
        if final_abs in written:
            outputs[dest.name] = str(final_abs)
        elif dest.name in result:
            raise RuntimeError(f"{alg_cls.id} reported {dest.name} but did not write it")
    declared = {o.name for o in alg_cls.outputs}
    destinations = {d.name for d in alg_cls.destinations()}
    for key, value in result.items():
        if key in declared:
            outputs[key] = value
        elif key not in destinations:
            raise RuntimeError(f"{alg_cls.id} returned undeclared output {key!r}")
    return outputs
