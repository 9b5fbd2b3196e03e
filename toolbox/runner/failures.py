"""Failures of a run told apart by type and by the disk, never by message text: write errors
(full disk, read-only folder) named after their output, read errors named after their input,
GDAL error messages, rasters written incomplete."""

from __future__ import annotations

import errno
import logging
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, OutputWriteError, ToolboxError
from toolbox.io.gdal_errors import COLLECTORS
from toolbox.io.staging import OutputStaging, write_error
from toolbox.io.write_failures import GDAL_WRITE_ERRNOS, disk_errno, first_line, is_io_error, typed_errno
from toolbox.parameters import OutputRaster, RasterLayer, VectorLayer
from toolbox.runner.paths import input_paths

# errno values that can only come from a write (EACCES or EIO may be an input's)
UNAMBIGUOUS_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS,
                            errno.ENAMETOOLONG}


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
    fail (full, read-only, at the file-size limit), or None; of those, the one written last
    (outputs on one full disk: the one being written when it filled)."""
    found = []
    for name, final, staged in staging.items():
        code = disk_errno(staged if staged.exists() else staged.parent)
        if code is not None:
            written = staged.stat().st_mtime_ns if staged.exists() else -1
            found.append((-written, len(found), code, name, final))
    return min(found)[2:] if found else None


def named_write_error(exc: OutputWriteError, staging: OutputStaging) -> OutputWriteError:
    """A writer's :class:`OutputWriteError` (about a staged file) naming the output parameter
    and its final path."""
    where = _output_of(exc.filename, staging)
    if where is None:
        return exc  # not about a staged output (already named by whoever raised it)
    text = exc.strerror or str(exc)
    for _, final, staged in staging.items():  # the library's words name the staged file
        text = text.replace(str(staged), str(final))
    return write_error(OSError(exc.errno or errno.EIO, text), *where)


def as_write_error(exc: Exception, staging: OutputStaging) -> ToolboxError | None:
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


def as_read_error(exc: Exception, gdal_messages: list[str], alg_cls: type[Algorithm],
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
    #: the thread that logged it (GDAL reports an error in the thread of the failing call)
    thread: int | None = None


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
            message.thread = threading.get_ident()
            self.messages.append(message)


@contextmanager
def collect_gdal_errors():
    """Collect the errors GDAL reports through rasterio's logger while the algorithm runs (some
    write failures are only logged)."""
    logger = logging.getLogger("rasterio")
    handler = _ErrorLog()
    previous = logger.level
    logger.addHandler(handler)
    if logger.getEffectiveLevel() > logging.INFO:
        logger.setLevel(logging.INFO)
    COLLECTORS.append(handler.messages)
    try:
        yield handler.messages
    finally:
        COLLECTORS.remove(handler.messages)
        logger.removeHandler(handler)
        logger.setLevel(previous)


def check_gdal_errors(messages: list[str], staging: OutputStaging) -> None:
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


def empty_output_message(alg_cls: type[Algorithm], values: dict[str, Any], name: str) -> str:
    """Why raster output ``name`` has no valid cell, naming only what the algorithm has: a
    raster input with no valid cell, else the grid parameters it takes (EXTENT, TEMPLATE, MASK,
    CELL_SIZE), else its own hint (``Algorithm.empty_output_hint``)."""
    from toolbox.io.raster import has_valid_pixel

    for p in alg_cls.parameters:  # a TEMPLATE gives only its grid: it may be all nodata
        info = values.get(p.name)
        if isinstance(p, RasterLayer) and p.name != "TEMPLATE" and info is not None \
                and not has_valid_pixel(info.path):
            return (f"{p.name} '{info.path.name}' has no valid cell (every cell is nodata): "
                    f"{name} would have none either")
    text = f"{name} would have no valid cell (every cell is nodata)"
    grid = [n for n in ("EXTENT", "TEMPLATE", "MASK", "CELL_SIZE")
            if any(p.name == n for p in alg_cls.parameters)]
    if grid:
        return f"{text}: check that {', '.join(grid[:-1])}{' and ' if grid[1:] else ''}" \
               f"{grid[-1]} cover the data"
    hint = getattr(alg_cls, "empty_output_hint", None)
    return f"{text}: {hint}" if hint else text


def check_raster_outputs(alg_cls: type[Algorithm], values: dict[str, Any],
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
            raise InputDataError(empty_output_message(alg_cls, values, dest.name))
        if problem:
            state = _disk_state(staging)  # a truncated file on a full disk: say so
            raise write_error(OSError(state[0] if state else errno.EIO, problem), dest.name,
                              values[dest.name])
    for name, final, staged in staging.folder_files():  # the rasters an output folder holds
        if staged.suffix.lower() not in (".tif", ".tiff"):
            continue
        from toolbox.io.raster import verify_written_raster

        problem = verify_written_raster(staged, check_empty=False)  # a folder may hold an empty one
        if problem:
            state = _disk_state(staging)
            raise write_error(OSError(state[0] if state else errno.EIO, problem), name, final)

