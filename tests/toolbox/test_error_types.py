"""Errors decided by type, not by message text (issue 24 §5): a write failure whose wording no
list knows is still one line, exit 2, nothing left; typed library errors pick the hints."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers_cli import cli, one_error, register_testing
from toolbox.parameters import OutputFile


def _register(error):
    def process(self, params, feedback):
        params["OUTPUT"].write_bytes(b"II*\0half")
        raise error

    register_testing("typed_write_failure", OutputFile("OUTPUT", extensions=[".tif"]), process,
                     "Writes half of its output, then its library fails.")


@pytest.mark.parametrize("make", [
    lambda: __import__("rasterio._err", fromlist=["x"]).CPLE_FileIOError(
        3, 3, "TIFFWriteDirectorySec: something unexpected happened"),
    lambda: OSError(27, "File too large (reworded by a library)"),  # EFBIG
])
def test_a_write_failure_of_any_wording_is_one_line(tmp_path, make):
    _register(make())
    code, _, err = cli("run", "testing:typed_write_failure", "--OUTPUT", tmp_path / "out.tif")
    line = one_error(err)
    assert code == 2 and "OUTPUT" in line
    assert "nothing was written" in line or "cannot write" in line
    assert list(tmp_path.iterdir()) == []


def test_collinear_and_crossing_errors_are_types():
    from toolbox.terrain.points import CollinearError, check_not_collinear
    from toolbox.terrain.tin.kernels import CrossingSegmentsError, triangulate

    with pytest.raises(CollinearError):
        check_not_collinear(np.c_[np.arange(10.0), 2 * np.arange(10.0)])
    xy = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    with pytest.raises(CrossingSegmentsError):
        triangulate(xy, np.array([[0, 2], [1, 3]]))


def test_writers_turn_library_io_errors_into_write_errors_by_class(tmp_path):
    """Inside io.write_failures.writing(), an I/O error class of a library (whatever its words)
    is an OutputWriteError with an errno; a programming error passes unchanged."""
    import errno

    from pyogrio.errors import DataSourceError
    from rasterio._err import CPLE_AppDefinedError, CPLE_NoWriteAccessError

    from toolbox.errors import OutputWriteError
    from toolbox.io.write_failures import writing

    target = tmp_path / "o.gpkg"
    for exc, code in ((DataSourceError("sqlite3_exec(COMMIT) failed: whatever"), errno.EIO),
                      (CPLE_AppDefinedError(1, 1, "TIFFAppendToStrip: oops"), errno.EIO),
                      (CPLE_NoWriteAccessError(5, 5, "reworded"), errno.EACCES),
                      (OSError(errno.EFBIG, "File too large"), errno.EFBIG)):
        with pytest.raises(OutputWriteError) as info, writing(target):
            raise exc
        assert info.value.errno == code and info.value.filename == str(target)
    with pytest.raises(TypeError), writing(target):
        raise TypeError("a bug stays a bug")


def test_a_writers_error_names_the_output_and_its_final_path(tmp_path):
    """A writer raises about the staged file; the user reads the parameter and the final path."""
    import errno

    from toolbox.errors import OutputWriteError

    def process(self, params, feedback):
        params["REPORT"].write_text("half")
        raise OutputWriteError("cannot write the staged file", errno.EFBIG, str(params["REPORT"]))

    register_testing("staged_writer", OutputFile("REPORT", extensions=[".txt"]), process,
                     "Its writer fails on the staged file.")

    code, _, err = cli("run", "testing:staged_writer", "--REPORT", tmp_path / "r.txt")
    line = one_error(err)
    assert code == 2 and line.startswith(f"toolbox: error: cannot write REPORT '{tmp_path / 'r.txt'}'")
    assert ".part" not in line and list(tmp_path.iterdir()) == []
