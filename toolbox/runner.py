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

import errno
import json
import logging
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import (
    InputDataError,
    OutputExistsError,
    OutputWriteError,
    ParameterError,
    ToolboxError,
)
from toolbox.feedback import Feedback
from toolbox.io.staging import OutputStaging, protected_paths, write_error
from toolbox.io.write_failures import (
    GDAL_WRITE_ERRNOS,
    disk_errno,
    first_line,
    is_io_error,
    typed_errno,
)
from toolbox.parameters import (
    Boolean,
    Folder,
    Number,
    OutputFolder,
    OutputRaster,
    RasterLayer,
    ValidationContext,
    VectorLayer,
)
from toolbox.registry import get

OVERWRITE = "OVERWRITE"
REPORT = "--run-report"
# errno values that can only come from a write (EACCES or EIO may be an input's)
UNAMBIGUOUS_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS,
                            errno.ENAMETOOLONG}


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
        if not p.is_output and alg.projected_crs_only:
            from toolbox.io.crs import check_input_crs

            check_input_crs(alg.id, p.name, ctx.values[p.name], warnings)
    values = {p.name: ctx.values[p.name] for p in alg.parameters}
    check_magnitudes(alg, values)
    _check_band(alg, values)
    _check_outputs_against_inputs(alg, values)
    alg().check(values)
    check_planned_files(alg, values, overwrite)
    return values


TINY, HUGE = 1e-300, 1e150  # below (but not 0) / above: no computation with it is sound


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
    """The one BAND check: BAND exists in the DEM when given, else in the one raster input."""
    band = values.get("BAND")
    given = {p.name: values[p.name] for p in alg_cls.parameters
             if isinstance(p, RasterLayer) and values.get(p.name) is not None}
    rasters = [given["DEM"]] if "DEM" in given else list(given.values())
    if isinstance(band, int) and len(rasters) == 1 and band > rasters[0].count:
        raise ParameterError("BAND", f"must be <= {rasters[0].count} (bands of {rasters[0]}), "
                             f"got {band}")


# -- what the run reads and writes ----------------------------------------------------------------
def _flatten(value: Any):
    if isinstance(value, (list, tuple)):
        for item in value:
            yield from _flatten(item)
    elif value is not None:
        yield value


def input_paths(alg_cls: type[Algorithm], values: dict[str, Any]) -> dict[Path, str]:
    """Every file the inputs name (whatever the parameter type) and their sidecars, resolved ->
    parameter name."""
    out: dict[Path, str] = {}
    for p in alg_cls.parameters:
        if p.is_output:
            continue
        for item in _flatten(values.get(p.name)):
            path = getattr(item, "path", item)
            if not isinstance(path, (str, Path)) or not str(path).strip():
                continue
            try:
                candidate = Path(str(path).split("|", 1)[0]).expanduser()
                if isinstance(p, Folder) and candidate.is_dir():  # an input folder's files
                    for named in (f for f in candidate.iterdir() if f.is_file()):
                        for protected in protected_paths(named):
                            out.setdefault(protected, p.name)
                elif candidate.is_file():
                    for named in [candidate, *_referenced_files(candidate)]:
                        for protected in protected_paths(named):
                            out.setdefault(protected, p.name)
            except (OSError, ValueError):  # a string that is no path (too long, NUL...)
                continue
    return out


def _referenced_files(path: Path) -> list[Path]:
    """Existing files a small YAML/JSON input names (a project's photos and orientation
    files), relative to its folder: they are inputs too."""
    if path.suffix.lower() not in (".yaml", ".yml", ".json") or path.stat().st_size > 1 << 20:
        return []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
        if path.suffix.lower() == ".json":  # (YAML holds JSON, but PyYAML reads it 50x slower)
            import json

            doc = json.loads(text)
        else:
            import yaml

            doc = yaml.safe_load(text)
    except Exception:  # noqa: BLE001 - unreadable: its reader reports it
        return []
    found, stack = [], [doc]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        elif isinstance(item, str) and 0 < len(item) < 1024 and "\n" not in item:
            try:
                target = path.parent / Path(item).expanduser()
                if target.is_file():
                    found.append(target)
            except (OSError, ValueError):
                continue
    return found


def _check_outputs_against_inputs(alg_cls: type[Algorithm], values: dict[str, Any]) -> None:
    inputs = input_paths(alg_cls, values)
    for dest in alg_cls.destinations():
        final = values.get(dest.name)
        if final is None:
            continue
        resolved = Path(final).expanduser().resolve()
        if resolved in inputs:
            raise ParameterError(dest.name, f"'{final}' is the input {inputs[resolved]} (or one "
                                 "of its files); an input is never overwritten: choose another "
                                 "output path")


_GLOB = set("*?[")


def planned_paths(alg_cls: type[Algorithm], values: dict[str, Any]) -> dict[str, list[Path]]:
    """Every file the destinations will write besides their own path (see
    :meth:`Algorithm.planned_files`), as final paths; glob patterns are expanded to the files
    that exist now. Names leaving their folder (``..``, absolute) are refused."""
    plan = alg_cls().planned_files(values) or {}
    out: dict[str, list[Path]] = {}
    for dest in alg_cls.destinations():
        final = values.get(dest.name)
        if final is None:
            continue
        if isinstance(dest, OutputFolder) and dest.name not in plan:
            raise RuntimeError(f"{alg_cls.id} plans no file for its output folder {dest.name}")
        folder = Path(final).expanduser().absolute()
        if not isinstance(dest, OutputFolder):
            folder = folder.parent
        paths: list[Path] = []
        for name in plan.get(dest.name, []):
            relative = Path(str(name))
            if relative.is_absolute() or ".." in relative.parts or not relative.parts:
                raise ParameterError(dest.name, f"would write {str(name)!r}, which is not a file "
                                     f"name inside '{folder}' (check the ids the file names "
                                     "come from)")
            if _GLOB & set(str(name)):
                paths += sorted(folder.glob(str(name)))
            else:
                paths.append(folder / relative)
        out[dest.name] = paths
    return out


def check_planned_files(alg_cls: type[Algorithm], values: dict[str, Any],
                        overwrite: bool) -> None:
    """Each planned file is checked as an output path: not an input (by path, sidecars and the
    files a project names included, or by inode), not another output, not a folder, and not
    existing without ``overwrite``."""
    plan = planned_paths(alg_cls, values)
    if not any(plan.values()):
        return
    inputs = input_paths(alg_cls, values)
    inodes = {}
    for path, name in inputs.items():
        try:
            st = path.stat()
        except OSError:
            continue
        inodes[(st.st_dev, st.st_ino)] = name
    seen = {Path(values[d.name]).expanduser().resolve(): d.name
            for d in alg_cls.destinations() if values.get(d.name) is not None}
    for dest_name, paths in plan.items():
        for path in paths:
            resolved = path.resolve()
            victim = inputs.get(resolved)
            if victim is None and path.exists():
                st = path.stat()
                victim = inodes.get((st.st_dev, st.st_ino))
            if victim is not None:
                raise ParameterError(dest_name, f"would write '{path}', which is the input "
                                     f"{victim} (or one of its files); an input is never "
                                     "overwritten: choose another output folder or name")
            if resolved in seen:
                raise ParameterError(dest_name, f"would write '{path}' twice (also "
                                     f"{seen[resolved]}): choose another output folder")
            seen[resolved] = dest_name
            if path.is_dir():
                raise ParameterError(dest_name, f"would write '{path}', which is a folder")
            if path.exists() and not overwrite:
                raise OutputExistsError(dest_name, f"would replace '{path}', which exists; "
                                        "pass --overwrite (OVERWRITE=True in Python) to "
                                        "replace it")


def _check_report(report: str | Path, alg_cls: type[Algorithm], values: dict[str, Any],
                  overwrite: bool) -> Path:
    path = Path(report).expanduser()
    resolved = path.resolve()
    inputs = input_paths(alg_cls, values)
    if resolved in inputs:
        raise ParameterError(REPORT, f"'{report}' is the input {inputs[resolved]} (or one of its "
                             "files); an input is never overwritten: choose another report path")
    for dest in alg_cls.destinations():
        final = values.get(dest.name)
        if final is not None and Path(final).expanduser().resolve() == resolved:
            raise ParameterError(REPORT, f"'{report}' is also the output {dest.name}")
    for name, paths in planned_paths(alg_cls, values).items():
        if any(p.resolve() == resolved for p in paths):
            raise ParameterError(REPORT, f"'{report}' is also one of the files of {name}")
    if path.is_dir():
        raise ParameterError(REPORT, f"'{report}' is a folder, expected a file path")
    if path.exists() and not overwrite:
        raise OutputExistsError(REPORT, f"'{report}' exists; pass --overwrite to replace it")
    return path


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
    alg_cls = get(algorithm_id)
    started = time.time()
    t0 = time.perf_counter()
    params, overwrite = _pop_overwrite(parameters or {}, overwrite)
    crs_warnings: list[str] = []
    values = validate(alg_cls, params, overwrite, crs_warnings)
    for text in crs_warnings:
        feedback.push_warning(text)
    protected = set(input_paths(alg_cls, values))
    report_path = None if report is None else _check_report(report, alg_cls, values, overwrite)
    staging = OutputStaging()
    try:
        staged = dict(values)
        for dest in alg_cls.destinations():
            if values[dest.name] is not None:
                stage = staging.stage_folder if isinstance(dest, OutputFolder) \
                    else staging.stage
                staged[dest.name] = stage(values[dest.name], dest.name)
        staged_report = None if report_path is None else staging.stage(report_path, REPORT)
        for folder in staging.removed_stale:
            feedback.push_warning(f"removed {folder}: the staging folder of an earlier run that "
                                  "was killed")
        feedback.set_progress(0)
        with _gdal_errors() as gdal_errors:
            try:
                result = alg_cls().process(staged, feedback) or {}
            except OutputWriteError as exc:  # a writer's: name the output, its final path
                raise _named(exc, staging) from None
            except (ToolboxError, KeyboardInterrupt):
                raise
            except Exception as exc:
                converted = _as_write_error(exc, staging) or _as_read_error(
                    exc, gdal_errors, alg_cls, values)
                if converted is None:
                    raise
                raise converted from None
        feedback.check_canceled()
        _check_gdal_errors(gdal_errors, staging)
        _check_raster_outputs(alg_cls, values, staging)
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
        staging.commit(overwrite=overwrite, protected=protected)
    finally:
        staging.rollback()
    return outputs


# -- write-error detection (by type and by the disk, never by message text) ---------------------
def _output_of(filename: str | None, staging: OutputStaging) -> tuple[str, Path] | None:
    """``(parameter name, final path)`` of the staged output ``filename`` lies in."""
    if not filename:
        return None
    path = Path(filename).absolute()
    for name, final, staged in staging.items():
        if path == staged or staged.parent in path.parents:
            return name, final
    return None


def _which_output(staging: OutputStaging) -> tuple[str, Path] | None:
    """The output a failure is about when nothing names it: the only one, or the one being
    written (the staged file modified last)."""
    items = staging.items()
    if len(items) == 1:
        return items[0][0], items[0][1]
    started = [(staged.stat().st_mtime, name, final) for name, final, staged in items
               if staged.exists()]
    if started:
        _, name, final = max(started)
        return name, final
    return (items[0][0], items[0][1]) if items else None


def _disk_state(staging: OutputStaging) -> tuple[int, str, Path] | None:
    """``(errno, parameter name, final path)`` of a staged output whose disk shows why writes
    fail (full, read-only, at the file-size limit), or None."""
    for name, final, staged in staging.items():
        code = disk_errno(staged if staged.exists() else staged.parent)
        if code is not None:
            return code, name, final
    return None


def _named(exc: OutputWriteError, staging: OutputStaging) -> OutputWriteError:
    """A writer's :class:`OutputWriteError` (about a staged file) naming the output parameter
    and its final path."""
    where = _output_of(exc.filename, staging)
    if where is None:
        return exc  # not about a staged output (already named by whoever raised it)
    return write_error(OSError(exc.errno or errno.EIO, exc.strerror or str(exc)), *where)


def _as_write_error(exc: Exception, staging: OutputStaging) -> ToolboxError | None:
    """A one-line :class:`OutputWriteError` when ``exc`` is a failed write of an output, decided
    by type: an ``OSError`` with a write-only errno (ENOSPC, EDQUOT, EFBIG, EROFS, ENAMETOOLONG)
    or about a staged file; GDAL's CPLE_FileIO / CPLE_NoWriteAccess; or any I/O error of a
    library while an output's disk is full, read-only or at the file-size limit."""
    chain = [e for e in (exc, exc.__cause__, exc.__context__) if e is not None]
    os_error = next((e for e in chain if isinstance(e, OSError) and (
        e.errno in UNAMBIGUOUS_WRITE_ERRNOS or _output_of(e.filename, staging)
        or _output_of(e.filename2, staging))), None)
    gdal_code = next((typed_errno(e) for e in chain
                      if not isinstance(e, OSError) and typed_errno(e)), None)
    state = _disk_state(staging) if any(is_io_error(e) for e in chain) else None
    if state is not None:  # the disk tells why, whatever the library said
        code, name, final = state
        if os_error is not None and os_error.errno not in (None, errno.EIO):
            code = os_error.errno
    elif os_error is not None:
        code = os_error.errno or errno.EIO
        name, final = (_output_of(os_error.filename, staging)
                       or _output_of(os_error.filename2, staging)
                       or _which_output(staging) or ("OUTPUT", ""))
    elif gdal_code is not None:
        code = gdal_code
        name, final = _which_output(staging) or ("OUTPUT", "")
    else:
        return None
    return write_error(OSError(code, first_line(os_error or exc)), name, final)


READ_LIBRARIES = ("rasterio", "pyogrio", "fiona", "sqlite3", "PIL", "cv2")


def _as_read_error(exc: Exception, gdal_messages: list[str], alg_cls: type[Algorithm],
                   values: dict[str, Any]) -> ToolboxError | None:
    """An :class:`InputDataError` naming the input when a reading library failed on it (a
    truncated or corrupt GeoTIFF/JPEG whose header opens, a damaged GeoPackage)."""
    module = type(exc).__module__ or ""
    if not module.startswith(READ_LIBRARIES):
        return None
    detail = next((m for m in reversed(gdal_messages) if "failed" in m.lower()),
                  gdal_messages[-1] if gdal_messages else str(exc))
    detail = " ".join(detail.replace("GDAL signalled an error: ", "").split())
    text = " ".join([str(exc), *gdal_messages])
    for path, name in input_paths(alg_cls, values).items():
        if path.name in text:
            return InputDataError(f"{name}: cannot read '{path}': the file is truncated or "
                                  f"corrupt ({detail[:200]})")
    kind = RasterLayer if module.startswith("rasterio") else VectorLayer
    candidates = [p for p in alg_cls.parameters
                  if isinstance(p, kind) and values.get(p.name) is not None]
    if len(candidates) == 1:  # the only input that library reads
        value = values[candidates[0].name]
        return InputDataError(f"{candidates[0].name}: cannot read {value}: the file is truncated "
                              f"or corrupt ({detail[:200]})")
    return InputDataError(f"cannot read an input: it is truncated or corrupt ({detail[:200]})")


class GdalMessage(str):
    """A GDAL error message as logged by rasterio, with its GDAL error class (``err_no``: 3
    CPLE_FileIO, 5 CPLE_NoWriteAccess...; None when unknown)."""

    err_no: int | None = None


class _ErrorLog(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if record.levelno >= logging.ERROR or "signalled an error" in text:
            message = GdalMessage(text)
            args = record.args if isinstance(record.args, tuple) else ()
            message.err_no = args[0] if args and isinstance(args[0], int) else None
            self.messages.append(message)


@contextmanager
def _gdal_errors():
    """Collect the errors GDAL reports through rasterio's logger while the algorithm runs (some
    write failures are only logged)."""
    logger = logging.getLogger("rasterio")
    handler = _ErrorLog()
    previous = logger.level
    logger.addHandler(handler)
    if logger.getEffectiveLevel() > logging.INFO:
        logger.setLevel(logging.INFO)
    try:
        yield handler.messages
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous)


def _check_gdal_errors(messages: list[str], staging: OutputStaging) -> None:
    """A write failure GDAL only logged: by its error class (CPLE_FileIO, CPLE_NoWriteAccess)
    when it names a staged output, or any error while an output's disk is full, read-only or at
    the file-size limit (libtiff's "Write error" has no class of its own)."""
    for text in messages:
        err_no = getattr(text, "err_no", None)
        about = next((item for item in staging.items() if str(item[2].parent) in text), None)
        state = _disk_state(staging)
        if state is not None:
            code, name, final = state
        elif err_no in GDAL_WRITE_ERRNOS and about is not None:
            code, name, final = GDAL_WRITE_ERRNOS[err_no], about[0], about[1]
        else:
            continue
        detail = " ".join(str(text).replace("GDAL signalled an error: ", "").split())
        raise write_error(OSError(code, detail.replace(str(about[2].parent), str(final.parent))
                                  if about else detail), name, final)


def _check_raster_outputs(alg_cls: type[Algorithm], values: dict[str, Any],
                          staging: OutputStaging) -> None:
    """Every raster output is complete (its TIFF blocks lie inside the file) and has at least
    one valid cell."""
    for dest in alg_cls.destinations():
        if not isinstance(dest, OutputRaster) or values.get(dest.name) is None:
            continue
        staged = staging.staged_path(values[dest.name])
        if staged is None or not staged.exists():
            continue
        from toolbox.io.raster import verify_written_raster

        problem = verify_written_raster(staged)
        if problem == "empty":
            raise InputDataError(f"{dest.name} would have no valid cell (every cell is nodata): "
                                 "check that EXTENT, TEMPLATE, MASK and CELL_SIZE cover the data")
        if problem:
            state = _disk_state(staging)  # a truncated file on a full disk: say so
            raise write_error(OSError(state[0] if state else errno.EIO, problem), dest.name,
                              values[dest.name])
    for name, final, staged in staging.folder_files():  # the rasters an output folder holds
        if staged.suffix.lower() not in (".tif", ".tiff"):
            continue
        from toolbox.io.raster import verify_written_raster

        problem = verify_written_raster(staged)
        if problem and problem != "empty":
            state = _disk_state(staging)
            raise write_error(OSError(state[0] if state else errno.EIO, problem), name, final)


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
