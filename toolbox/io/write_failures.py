"""Failed writes decided by type and by the state of the disk, never by message text.

A writer wraps the library calls that write a file in :func:`writing`: an I/O failure of the
library there (an ``OSError``, a GDAL/rasterio error, a pyogrio data-source error, an SQLite
error) becomes one :class:`~toolbox.errors.OutputWriteError` carrying the cause as an errno:
the exception's own errno when it has one (``ENOSPC``, ``EFBIG``, ``EDQUOT``, ``EROFS``,
``EACCES``...), GDAL's error class (``CPLE_FileIO`` -> ``EIO``, ``CPLE_NoWriteAccess`` ->
``EACCES``), else what the disk shows (:func:`disk_errno`: full, at the process's file-size
limit, read-only), else ``EIO``. The runner then names the output parameter and its final path.

>>> with writing("/tmp/x.tif"):  # doctest: +SKIP
...     dataset.write(block)
"""

from __future__ import annotations

import errno
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from toolbox.errors import OutputWriteError, ToolboxError

# errno values of an OSError that mean "this write failed" (not "this input is unreadable")
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS,
                          errno.ENAMETOOLONG, errno.EACCES, errno.EPERM, errno.EIO})
# GDAL's CPLErrorNum of a failed write (as logged or raised by rasterio) -> errno
GDAL_WRITE_ERRNOS = {3: errno.EIO, 5: errno.EACCES}  # CPLE_FileIO, CPLE_NoWriteAccess
MIN_FREE_BYTES = 64 * 1024  # below this a filesystem counts as full


def _chain(exc: BaseException) -> list[BaseException]:
    out, seen = [], set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        out.append(exc)
        exc = exc.__cause__ or exc.__context__
    return out


def typed_errno(exc: BaseException) -> int | None:
    """The errno of a failed write when ``exc`` (or its cause) says so by its type: an
    ``OSError`` with a write errno, or rasterio's ``CPLE_FileIOError`` /
    ``CPLE_NoWriteAccessError``; else None."""
    for item in _chain(exc):
        code = getattr(item, "errno", None) if isinstance(item, OSError) else None
        if code in WRITE_ERRNOS:
            return code
        if type(item).__module__.startswith("rasterio"):
            from rasterio._err import CPLE_FileIOError, CPLE_NoWriteAccessError

            if isinstance(item, CPLE_NoWriteAccessError):
                return errno.EACCES
            if isinstance(item, CPLE_FileIOError):
                return errno.EIO
    return None


def is_io_error(exc: BaseException) -> bool:
    """``exc`` is of a class a library raises when reading or writing a file fails (not a
    programming error such as ``TypeError``)."""
    import sqlite3

    if isinstance(exc, (OSError, sqlite3.Error)):
        return True
    module = type(exc).__module__ or ""
    if module.startswith("rasterio"):
        from rasterio._err import CPLE_BaseError
        from rasterio.errors import RasterioError

        return isinstance(exc, (CPLE_BaseError, RasterioError))
    if module.startswith("pyogrio"):
        from pyogrio.errors import CRSError, DataLayerError, DataSourceError, FieldError, GeometryError

        return isinstance(exc, (DataSourceError, DataLayerError)) and not isinstance(
            exc, (CRSError, FieldError, GeometryError))
    if module == "lazrs":  # LAZ (de)compression: "IoError: Failed to call write", no cause kept
        return type(exc).__name__ == "LazrsError"
    return False


def disk_errno(path: str | Path) -> int | None:
    """What the disk of ``path`` (a file being written, or its folder) shows: ``ENOSPC`` when
    its filesystem has (almost) no free space, ``EFBIG`` when the file reached the process's
    file-size limit (``RLIMIT_FSIZE``), ``EROFS`` on a read-only filesystem; else None."""
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    try:
        st = os.statvfs(folder)
    except OSError:
        return None
    if st.f_flag & os.ST_RDONLY:
        return errno.EROFS
    if st.f_bavail * st.f_frsize < MIN_FREE_BYTES:
        return errno.ENOSPC
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    except (ImportError, OSError, ValueError):  # pragma: no cover - not POSIX
        return None
    if limit != resource.RLIM_INFINITY:
        files = [path] if path.is_file() else [p for p in folder.iterdir() if p.is_file()]
        if any(p.stat().st_size + MIN_FREE_BYTES >= limit for p in files):
            return errno.EFBIG
    return None


def first_line(exc: BaseException) -> str:
    text = str(getattr(exc, "strerror", None) or exc).strip()
    return " ".join(text.splitlines()[0].split()) if text else type(exc).__name__


def as_write_error(exc: BaseException, path: str | Path) -> OutputWriteError:
    """``exc``, raised while writing ``path``, as an :class:`OutputWriteError` with its errno."""
    code = typed_errno(exc)
    if code in (None, errno.EIO):  # a generic I/O error: the disk may tell why
        code = disk_errno(path) or errno.EIO
    error = OutputWriteError(f"cannot write '{path}': {first_line(exc)}", code, str(path))
    error.strerror = first_line(exc)  # the library's words, for the runner's message
    return error


@contextmanager
def writing(path: str | Path) -> Iterator[None]:
    """Inside the block, an I/O failure of a library (see :func:`is_io_error`) is a failed
    write of ``path``: it leaves as :class:`OutputWriteError`. Toolbox errors and programming
    errors pass unchanged."""
    try:
        yield
    except ToolboxError:
        raise
    except Exception as exc:
        if not is_io_error(exc):
            raise
        raise as_write_error(exc, path) from exc
