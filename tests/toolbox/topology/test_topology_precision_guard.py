"""A PRECISION finer than the coordinates can hold is refused before any work (the sweep found
a 1e-45 grid crashing GEOS's snap rounding)."""

import shapely

from toolbox.errors import ParameterError
from toolbox.ui.topology import check_precision


def test_precision_finer_than_the_coordinates_is_refused():
    lines = shapely.linestrings([[(1688000.0, 4799500.0), (1688010.0, 4799510.0)]])
    try:
        check_precision(1.4e-45, lines)
    except ParameterError as exc:
        assert "PRECISION" in str(exc) and "\n" not in str(exc)
    else:
        raise AssertionError("a 1e-45 grid was accepted")
    check_precision(0.001, lines)  # a millimetre grid at Siena's coordinates is fine
    check_precision(0.0, lines)  # 0: no grid
