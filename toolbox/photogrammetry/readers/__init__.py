"""Readers of orientation results computed upstream (aerial triangulation).

- :func:`read_exterior_orientations`: exterior orientations from any supported file, with the
  format detected or named: ``native`` CSV, ``pix4d``, ``metashape``, generic ``opk`` text
  (:mod:`.text`) and the Z-Map adjustment log ``zmap_log`` (:mod:`.zmap_log`);
- :mod:`toolbox.photogrammetry.project` reads the native YAML project file (cameras, photos,
  interior and exterior orientations, CRS).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError, ParameterError
from toolbox.io.text import read_text
from toolbox.photogrammetry.readers.text import (
    OrientationTable,
    photo_id,
    read_native_csv,
    read_opk_text,
    sniff_format,
)

FORMATS = ("auto", "native", "pix4d", "metashape", "opk", "zmap_log")

__all__ = ["FORMATS", "OrientationTable", "ZMapRun", "parse_zmap_log", "photo_id",
           "read_exterior_orientations", "read_zmap_log", "read_text"]


def __getattr__(name: str) -> Any:
    """The Z-Map log reader's names, imported on first use (PEP 562): its module compiles 33
    regular expressions, 20 ms at every start of a run that reads no Z-Map log."""
    if name in ("ZMapRun", "parse_zmap_log", "read_zmap_log"):
        from toolbox.photogrammetry.readers import zmap_log

        return getattr(zmap_log, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def read_exterior_orientations(path: str | Path, fmt: str = "auto", angle_unit: str | None = None,
                               crs: Any = None, where: Mapping[str, str] | None = None,
                               run: str | int | None = None, stage: str = "final"
                               ) -> OrientationTable:
    """Exterior orientations from ``path``.

    Parameters
    ----------
    fmt : {"auto", "native", "pix4d", "metashape", "opk", "zmap_log"}
    angle_unit : rad, deg or gon
        Unit of the angles in the file when it does not state it (required for ``opk``; the
        default is degrees for pix4d/metashape, radians for zmap_log, the ``angle_unit`` column
        for native).
    crs : pyproj.CRS, optional
        CRS of the coordinates (the files do not carry one).
    where : mapping, optional
        ``native`` only: keep rows whose columns equal these values.
    run : str or int, optional
        ``zmap_log`` with several logs in one file: the run's name (project file stem, e.g.
        ``Blocco``) or index; default the last.
    stage : {"final", "initial"}
        ``zmap_log``: adjusted (final) or approximate (initial) values.
    """
    if fmt not in FORMATS:
        raise ParameterError("FORMAT", f"must be one of {', '.join(FORMATS)}; got {fmt!r}")
    text = read_text(path)
    source = str(path)
    kind = sniff_format(text) if fmt == "auto" else fmt
    if kind == "zmap_log":
        from toolbox.photogrammetry.readers.zmap_log import parse_zmap_log

        runs = parse_zmap_log(text, source, angle_unit or "rad", crs)
        chosen = _choose_run(runs, run, source)
        orientations = chosen.exterior_orientations(stage)
        if not orientations:
            raise InputDataError(f"{source}: run {chosen.name!r} prints no {stage} values")
        table = OrientationTable(source, "zmap_log", orientations)
        missing = chosen.missing(stage)
        table.notes.append(f"run {chosen.name} ({chosen.date} {chosen.time}), {stage} values, "
                           f"angle unit {chosen.angle_unit}")
        if missing:
            table.notes.append(f"no {stage} values printed for: {', '.join(missing)}")
        return table
    if kind == "native":
        return read_native_csv(text, source, angle_unit, crs, where)
    if where:
        raise ParameterError("WHERE", f"row filters apply to the native CSV only, not to {kind}")
    return read_opk_text(text, source, angle_unit, crs, kind)


def _choose_run(runs: list[Any], run: str | int | None, source: str) -> Any:
    """The ZMapRun named or numbered ``run`` (default the last)."""
    if run is None:
        return runs[-1]
    if isinstance(run, int) or str(run).isdigit():
        index = int(run)
        if not 0 <= index < len(runs):
            raise ParameterError("RUN", f"must be 0..{len(runs) - 1} for {source}, got {run!r}")
        return runs[index]
    for r in runs:
        if r.name == run:
            return r
    raise ParameterError("RUN", f"{run!r} is not a run of {source}; runs: "
                         f"{', '.join(r.name for r in runs)}")
