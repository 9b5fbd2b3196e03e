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

    Nothing was committed: the previous file, if any, is untouched.
    """

    def __init__(self, message: str):
        Exception.__init__(self, message)

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""

