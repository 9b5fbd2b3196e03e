"""Error tree of the toolbox.

Every error a user can cause is a :class:`ToolboxError`; the CLI prints its message on one line and
exits with code 2, without a traceback. Classes also inherit the matching builtin (as rasterio's
``CRSError(ValueError)``) so callers can catch either.
"""

from __future__ import annotations


class ToolboxError(Exception):
    """Base class of every error caused by input, parameters or environment (not by a bug)."""


class ParameterError(ToolboxError, ValueError):
    """A parameter value is missing, of the wrong type, out of range or inconsistent.

    The message names the parameter, the value given and what was expected.
    """

    def __init__(self, name: str, message: str):
        self.name = name
        super().__init__(f"{name} {message}" if name else message)


class InputDataError(ToolboxError, ValueError):
    """An input dataset is readable but its content cannot be processed (no Z, too few points...)."""


class AlgorithmNotFoundError(ToolboxError, KeyError):
    """No algorithm is registered under the requested id."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class OutputExistsError(ParameterError):
    """An output exists and the user did not ask to overwrite it."""


class CanceledError(ToolboxError):
    """The run was canceled through its feedback object; no output was written."""


class ConvergenceError(ToolboxError, ArithmeticError):
    """An iterative solution did not converge (least squares, ray/DEM intersection...)."""


class PipelineError(ToolboxError):
    """A batch pipeline file is malformed or a step reference cannot be resolved."""


class OutputWriteError(ToolboxError, OSError):
    """An output could not be written (no space left, read-only folder, name too long...).

    Nothing was committed: the previous file, if any, is untouched. ``errno`` is the cause
    (``errno.ENOSPC``...) when known and ``filename`` the file being written: a writer raises it
    with the staged path, the runner names the output parameter and its final path.
    """

    def __init__(self, message: str, errno: int | None = None, filename: str | None = None):
        Exception.__init__(self, message)
        self.errno, self.filename = errno, filename

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""



class ServiceError(ToolboxError):
    """A service the run depends on failed (a Dask scheduler that does not answer or is lost
    mid-run): not the user's input, not a bug in the toolbox. The CLI prints one line and exits
    with code 3 (:attr:`exit_code`); nothing was written."""

    exit_code = 3
