"""Kept for compatibility: the parameter file reader is :mod:`toolbox.io.parameter_file`, shared
by every algorithm that takes a ``PARAMETERS`` file."""

from toolbox.io.parameter_file import (  # noqa: F401 - re-exported
    KEYS,
    ParameterFile,
    normalise_name,
    read_parameter_file,
)
