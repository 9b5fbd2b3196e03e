"""JSON run report: the surveyor's proof of quality (parameters, versions, timings, statistics)."""

from __future__ import annotations

import datetime as dt
import json
import math
import platform
import sys
from pathlib import Path
from typing import Any


def versions() -> dict[str, str]:
    """Versions of the toolbox and of the libraries that decide the numbers (GDAL, PROJ, GEOS)."""
    import numpy as np
    import pyproj
    import rasterio
    import shapely

    from toolbox.version import __version__

    out = {"toolbox": __version__, "python": platform.python_version(),
           "numpy": np.__version__, "gdal": rasterio.__gdal_version__,
           "proj": pyproj.proj_version_str, "geos": shapely.geos_version_string,
           "rasterio": rasterio.__version__, "pyproj": pyproj.__version__,
           "shapely": shapely.__version__}
    try:  # pyogrio's own version module: ``pyogrio.__version__`` would run the package's
        # __init__, which imports pandas and geopandas (about 0.45 s of a small run)
        from toolbox.io.vector import _ogr

        _ogr()
        from pyogrio._version import get_versions

        out["pyogrio"] = get_versions()["version"]
    except ImportError:  # pragma: no cover
        pass
    return out


def to_jsonable(value: Any) -> Any:
    """Convert parameter values and statistics into JSON types (paths, CRSs, numpy, extents)."""
    if value is None or isinstance(value, (bool, str)):
        return value
    # numpy only when loaded (no numpy value exists otherwise): vector:info's GeoPackage
    # summary runs without it
    np = sys.modules.get("numpy")
    if isinstance(value, int) or (np is not None and isinstance(value, np.integer)):
        return int(value)
    if isinstance(value, float) or (np is not None and isinstance(value, np.floating)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, Path):
        return str(value)
    if np is not None and isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set)):
        return [to_jsonable(v) for v in value]
    if hasattr(value, "as_text"):  # layer references
        return value.as_text()
    if hasattr(value, "to_authority"):  # pyproj CRS
        from toolbox.io.crs import crs_label

        return crs_label(value)
    if hasattr(value, "bounds") and hasattr(value, "crs"):  # Extent
        return {"bounds": list(value.bounds), "crs": to_jsonable(value.crs)}
    return str(value)


def parameters_record(alg_cls, params: dict[str, Any]) -> dict[str, Any]:
    """The run's parameter values as JSON, file and folder paths absolute (a relative path
    names nothing once the report leaves the folder it was run from)."""
    from toolbox.io.paths import absolute_paths

    record = to_jsonable(params)
    for p in alg_cls.parameters:
        if p.holds_paths and record.get(p.name) is not None:
            record[p.name] = absolute_paths(record[p.name],
                                            comma_separated=getattr(p, "paths", False))
    return record


def input_crs(alg_cls, params: dict[str, Any]) -> dict[str, Any]:
    """The CRS of every raster and vector input as it was read (``{PARAMETER: label}``, None
    for an input without one): a parameter value does not say it."""
    out: dict[str, Any] = {}
    for p in alg_cls.parameters:
        value = params.get(p.name)
        if p.is_output or value is None:
            continue
        items = value if isinstance(value, list) else [value]
        if not items or not all(hasattr(v, "crs") and hasattr(v, "as_text") for v in items):
            continue
        try:
            labels = [to_jsonable(v.crs) for v in items]
        except Exception:  # noqa: BLE001 - the record never fails a run that worked
            continue
        out[p.name] = labels if isinstance(value, list) else labels[0]
    return out


def build_report(alg_cls, params: dict[str, Any], outputs: dict[str, Any], feedback,
                 started: float, elapsed: float) -> dict[str, Any]:
    return {
        "algorithm": alg_cls.id,
        "display_name": alg_cls.display_name,
        "started": dt.datetime.fromtimestamp(started, dt.UTC).isoformat(),
        "elapsed_s": round(elapsed, 4),
        "parameters": parameters_record(alg_cls, params),
        "input_crs": input_crs(alg_cls, params),
        "outputs": to_jsonable(outputs),
        "timings_s": {k: round(v, 4) for k, v in feedback.timings.items()},
        "warnings": feedback.warnings,
        "messages": [text for level, text in feedback.messages if level == "info"],
        "versions": versions(),
    }


def write_report(path: str | Path, alg_cls, params, outputs, feedback, started, elapsed) -> Path:
    from toolbox.io.staging import atomic_path

    report = build_report(alg_cls, params, outputs, feedback, started, elapsed)
    with atomic_path(path) as staged:
        staged.write_text(json.dumps(report, indent=2) + "\n")
    return Path(path)
