"""The quality report's model: the specification and its tolerances, verdicts, sections, the
run reports read from a folder and the formatting helpers the sections share (see
:mod:`toolbox.cartography.quality`)."""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: NMAS vertical rule: 90 % within half the contour interval; 1.6449 = the normal 90 % quantile
NMAS_90 = 1.6449

PASS, FAIL, NOT_CHECKED = "pass", "FAIL", "not checked"


@dataclass(frozen=True)
class Specification:
    """The tolerances a delivery is judged by (see the module docstring for the sources)."""

    map_scale: float = 5000.0  # scale denominator of the map and the orthophoto
    ortho_rule_mm: float = 0.3  # S002 §2.6.6: 0.3 (small scales) or 0.5 (large scales) mm
    contour_interval_m: float = 5.0  # S002 l.3278: 5 m at 1:5000
    io_tolerance_um: float = 15.0  # producer's threshold for fiducial residuals

    @property
    def planimetric_m(self) -> float:
        return self.ortho_rule_mm / 1000.0 * self.map_scale

    @property
    def height_rmse_m(self) -> float:
        return self.contour_interval_m / (2.0 * NMAS_90)

    def describe(self) -> str:
        return (f"map scale 1:{self.map_scale:g}; planimetric RMS <= {self.ortho_rule_mm:g} mm x "
                f"{self.map_scale:g} = {_fmt(self.planimetric_m, 'm', 2)} (S002 §2.6.6); height RMSE <= "
                f"{_fmt(self.height_rmse_m, 'm', 2)} (contour interval {self.contour_interval_m:g} m, "
                f"90 % within half of it); fiducial residuals <= {self.io_tolerance_um:g} µm")


@dataclass
class Verdict:
    """One criterion of one product."""

    product: str
    criterion: str
    measured: str
    tolerance: str
    status: str  # PASS, FAIL or NOT_CHECKED
    source: str = ""


@dataclass
class Section:
    """A part of the report: blocks in reading order, each ``("table", header, rows)``,
    ``("text", str)`` or ``("figure", matplotlib figure)``."""

    key: str
    title: str
    blocks: list[tuple] = field(default_factory=list)

    def table(self, header: list[str], rows: list[list[str]]) -> None:
        if rows:
            self.blocks.append(("table", header, rows))

    def text(self, text: str) -> None:
        self.blocks.append(("text", text))

    def figure(self, fig: Any) -> None:
        self.blocks.append(("figure", fig))

    @property
    def figures(self) -> list:
        return [b[1] for b in self.blocks if b[0] == "figure"]


# -- reading the run reports ---------------------------------------------------------------------
def load_reports(folder: str | Path) -> dict[str, list[tuple[str, dict]]]:
    """Run reports of a folder by algorithm id: ``{id: [(step name, report), ...]}``."""
    out: dict[str, list[tuple[str, dict]]] = {}
    for path in sorted(Path(folder).glob("*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and isinstance(data.get("algorithm"), str) \
                and isinstance(data.get("outputs"), dict) \
                and isinstance(data["outputs"].get("STATISTICS") or {}, dict):
            out.setdefault(data["algorithm"], []).append((path.stem, data))
    return out


def _stats(report: dict) -> dict:
    return report.get("outputs", {}).get("STATISTICS") or {}


_PATH = re.compile(r"(?:[A-Za-z]:)?(?:[\\/][^\s\\/'\",;:()]+)+[\\/]([^\s\\/'\",;:()]+)")


def without_paths(text: str) -> str:
    """``text`` with absolute file paths reduced to their file names (no machine paths)."""
    return _PATH.sub(lambda m: m.group(1), str(text))


def _fmt(value: Any, unit: str = "", digits: int = 3) -> str:
    """``value`` with ``digits`` decimals, or more to keep two significant digits (a 2.5 cm
    cell read "0.03 m", an RMSE of 0.4 mm "0.000 m"; 0.03 stays "0.03"); "n/a" for None."""
    if value is None:
        return "n/a"
    v = float(value)
    if math.isfinite(v) and v != 0.0:
        two = 1 - math.floor(math.log10(abs(v)))  # decimals showing two significant digits
        if two > digits:  # one fewer when that is exact (0.03, not 0.030)
            digits = min(12, two - 1 if math.isclose(round(v, two - 1), v, rel_tol=1e-9)
                         else two)
    return f"{v:.{digits}f}{(' ' + unit) if unit else ''}"


def _planimetric(rmse: dict) -> float | None:
    """sqrt(RMSE_x² + RMSE_y²) of a ``{"x", "y", ...}`` report entry, None without both (a
    block whose check points are all height points has ``x``, ``y`` None)."""
    x, y = rmse.get("x"), rmse.get("y")
    return None if x is None or y is None else float(np.hypot(x, y))


def _judge(value: float | None, limit: float) -> str:
    return NOT_CHECKED if value is None else (PASS if value <= limit else FAIL)


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt
