"""The project quality report: figures and tables drawn only from the JSON run reports the
algorithms write (and the residual files those reports name).

Sections, each present when its run reports are: interior orientation (residual vectors at the
fiducial marks, per photo), rectification (residual vectors of control, check and rejected
points; check-point RMSE against the orthophoto accuracy rule, S002 §2.6.6: RMS <= 0.3 or
0.5 mm x the scale denominator), DEM cross-validation (RMSE per method, error histograms, a map
of the best method's errors), topology (error and fix counts).
"""

from __future__ import annotations

import base64
import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class Section:
    """One part of the report: a title, rows of (label, value) and matplotlib figures."""

    key: str
    title: str
    rows: list[tuple[str, str]] = field(default_factory=list)
    figures: list[Any] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def load_reports(folder: str | Path) -> dict[str, list[tuple[str, dict]]]:
    """Run reports of a folder by algorithm id: ``{id: [(step name, report), ...]}``."""
    out: dict[str, list[tuple[str, dict]]] = {}
    for path in sorted(Path(folder).glob("*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and "algorithm" in data and "outputs" in data:
            out.setdefault(data["algorithm"], []).append((path.stem, data))
    return out


def _stats(report: dict) -> dict:
    return report.get("outputs", {}).get("STATISTICS") or {}


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _fmt(value: float, unit: str = "", digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}{(' ' + unit) if unit else ''}"


# -- sections ------------------------------------------------------------------------------------
def interior_section(runs: list[tuple[str, dict]]) -> Section:
    import csv

    plt = _plt()
    sec = Section("interior", "Interior orientation")
    for name, report in runs:
        stats = _stats(report)
        sec.rows += [(f"{name}: photos", str(stats.get("photos"))),
                     (f"{name}: max residual", _fmt(stats.get("max_residual_mm"), "mm", 4)),
                     (f"{name}: max sigma0", _fmt(stats.get("max_sigma0_mm"), "mm", 4))]
        csv_path = report["outputs"].get("RESIDUALS")
        if not csv_path or not Path(csv_path).exists():
            sec.notes.append(f"{name}: no residual table, no vector plot")
            continue
        by_photo: dict[str, list[dict]] = {}
        with open(csv_path, newline="", encoding="utf-8") as f:
            for row in csv.DictReader(f):
                by_photo.setdefault(row["photo"], []).append(row)
        photos = sorted(by_photo)
        cols = min(3, len(photos))
        nrows = int(np.ceil(len(photos) / cols))
        fig, axes = plt.subplots(nrows, cols, figsize=(3.3 * cols, 3.3 * nrows),
                                 squeeze=False)
        res_max = max(float(r["res_mm"]) for rows in by_photo.values() for r in rows) or 1.0
        for ax, photo in zip(axes.ravel(), photos):
            rows = by_photo[photo]
            x = np.array([float(r["x_mm"]) for r in rows])
            y = np.array([float(r["y_mm"]) for r in rows])
            dx = np.array([float(r["res_x_mm"]) for r in rows])
            dy = np.array([float(r["res_y_mm"]) for r in rows])
            span = max(np.ptp(x), np.ptp(y), 1.0)
            k = 0.15 * span / res_max  # the largest residual drawn 15% of the frame
            ax.quiver(x, y, dx * k, dy * k, angles="xy", scale_units="xy", scale=1,
                      color="#c0392b", width=0.012)
            ax.plot(x, y, "k+", ms=6)
            ax.set_title(f"{photo}: max {np.hypot(dx, dy).max() * 1000:.1f} µm", fontsize=8)
            ax.set_aspect("equal")
            ax.set_xlim(x.min() - 0.25 * span, x.max() + 0.25 * span)
            ax.set_ylim(y.min() - 0.25 * span, y.max() + 0.25 * span)
            ax.tick_params(labelsize=6)
        for ax in axes.ravel()[len(photos):]:
            ax.set_visible(False)
        fig.suptitle(f"Residual vectors at the fiducial marks (x{k:.0f}; photo coordinates, "
                     "mm)", fontsize=9)
        fig.tight_layout()
        sec.figures.append(fig)
    return sec


def rectification_section(runs: list[tuple[str, dict]], ortho_scale: float,
                          rule_mm: float) -> Section:
    plt = _plt()
    sec = Section("rectification", "Rectification and orthophoto accuracy")
    tolerance = rule_mm / 1000.0 * ortho_scale
    for name, report in runs:
        stats = _stats(report)
        check = stats.get("check") or {}
        rmse_check = check.get("rmse")
        sec.rows += [(f"{name}: model", str(stats.get("model"))),
                     (f"{name}: control / check points",
                      f"{stats.get('used_points')} / {stats.get('check_points')}"),
                     (f"{name}: rejected", ", ".join(stats.get("rejected_points") or [])
                      or "none"),
                     (f"{name}: RMSE control x / y", f"{_fmt(stats.get('rmse_x'), 'm')} / "
                                                    f"{_fmt(stats.get('rmse_y'), 'm')}"),
                     (f"{name}: RMSE check points", _fmt(rmse_check, "m"))]
        if rmse_check is not None:
            verdict = "meets" if rmse_check <= tolerance else "FAILS"
            sec.rows.append((f"{name}: accuracy rule",
                             f"{verdict} RMS <= {rule_mm} mm x {ortho_scale:g} = "
                             f"{tolerance:.2f} m (S002 §2.6.6)"))
        points = stats.get("points") or []
        if not points:
            continue
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4.2),
                                     gridspec_kw={"width_ratios": [1.4, 1]})
        colours = {"control": "#2471a3", "check": "#1e8449", "rejected": "#c0392b"}
        good = [p for p in points if p["role"] != "rejected"]
        res_max = max((p["residual_ground_norm"] for p in good), default=1.0) or 1.0
        xy = np.array([p["ground"] for p in points], dtype="float64")
        span = max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), 1.0)
        k = 0.12 * span / res_max
        origin = xy.mean(axis=0)
        for role, colour in colours.items():
            sel = [p for p in points if p["role"] == role]
            if not sel:
                continue
            g = np.array([p["ground"] for p in sel]) - origin
            r = np.array([p["residual_ground"] for p in sel])
            if role == "rejected":  # gross errors: direction only, not to scale
                r = r / np.hypot(r[:, 0], r[:, 1])[:, None] * res_max
            ax.quiver(g[:, 0], g[:, 1], r[:, 0] * k, r[:, 1] * k, angles="xy",
                      scale_units="xy", scale=1, color=colour, width=0.006, label=role)
            ax.plot(g[:, 0], g[:, 1], "o", color=colour, ms=3)
            for p, (gx, gy) in zip(sel, g):
                ax.annotate(p["id"], (gx, gy), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_aspect("equal")
        ax.legend(fontsize=7, loc="best")
        ax.set_title(f"{name}: ground residuals (x{k:.0f}; rejected not to scale)", fontsize=8)
        ax.set_xlabel(f"E - {origin[0]:.0f} (m)", fontsize=7)
        ax.set_ylabel(f"N - {origin[1]:.0f} (m)", fontsize=7)
        ax.tick_params(labelsize=6)
        ids = [p["id"] for p in good]
        norms = [p["residual_ground_norm"] for p in good]
        bx.bar(ids, norms, color=[colours[p["role"]] for p in good])
        bx.axhline(tolerance, color="#c0392b", ls="--", lw=1,
                   label=f"rule {rule_mm} mm x {ortho_scale:g} = {tolerance:.2f} m")
        if rmse_check is not None:
            bx.axhline(rmse_check, color="#1e8449", ls=":", lw=1,
                       label=f"check RMSE {rmse_check:.3f} m")
        bx.set_ylabel("residual (m)", fontsize=7)
        bx.tick_params(labelsize=6)
        bx.legend(fontsize=6)
        bx.set_title("residual per point", fontsize=8)
        fig.tight_layout()
        sec.figures.append(fig)
    return sec


def dem_section(runs: list[tuple[str, dict]]) -> Section:
    plt = _plt()
    sec = Section("dem", "DEM cross-validation (leave one out: predicted - observed)")
    for name, report in runs:
        methods = _stats(report).get("methods") or {}
        if not methods:
            continue
        for method, m in methods.items():
            sec.rows.append((f"{name}: {method}", f"RMSE {_fmt(m.get('rmse'), 'm')}, mean "
                             f"{_fmt(m.get('mean_error'), 'm')}, max |e| "
                             f"{_fmt(m.get('max_abs_error'), 'm')}, {m.get('predicted')} pts"))
        best = _stats(report).get("best") or min(methods, key=lambda k: methods[k]["rmse"])
        sec.rows.append((f"{name}: best", str(best)))
        fig, ax = plt.subplots(figsize=(6, 2.8))
        names = list(methods)
        ax.bar(names, [methods[k]["rmse"] for k in names],
               color=["#1e8449" if k == best else "#7f8c8d" for k in names])
        ax.set_ylabel("RMSE (m)", fontsize=7)
        ax.set_title(f"{name}: RMSE by method", fontsize=8)
        ax.tick_params(labelsize=7)
        fig.tight_layout()
        sec.figures.append(fig)
        path = report["outputs"].get("RESIDUALS")
        if not path or not Path(path).exists():
            sec.notes.append(f"{name}: no residual points, no histogram or map")
            continue
        import geopandas as gpd

        pts = gpd.read_file(path)
        cols = [f"{k}_err" for k in names if f"{k}_err" in pts.columns]
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.0))
        errors = [pts[c].dropna().to_numpy() for c in cols]
        lim = max((np.percentile(np.abs(e), 99.5) for e in errors if e.size), default=1.0)
        bins = np.linspace(-lim, lim, 41)
        for c, e in zip(cols, errors):
            axes[0].hist(e, bins=bins, histtype="step", lw=1.2 if c == f"{best}_err" else 0.7,
                         label=c[:-4])
        axes[0].set_xlabel("error (m)", fontsize=7)
        axes[0].set_ylabel("points", fontsize=7)
        axes[0].legend(fontsize=6)
        axes[0].set_title("error histograms", fontsize=8)
        e = pts[f"{best}_err"]
        ok = e.notna().to_numpy()
        x, y = pts.geometry.x.to_numpy()[ok], pts.geometry.y.to_numpy()[ok]
        sc = axes[1].scatter(x - x.min(), y - y.min(), c=e[ok], s=3, cmap="RdBu_r",
                             vmin=-lim, vmax=lim)
        fig.colorbar(sc, ax=axes[1], label="error (m)")
        axes[1].set_aspect("equal")
        axes[1].set_title(f"{best}: errors on the ground (from E {x.min():.0f}, "
                          f"N {y.min():.0f})", fontsize=8)
        for a in axes:
            a.tick_params(labelsize=6)
        fig.tight_layout()
        sec.figures.append(fig)
    return sec


def _numeric_leaves(stats: dict, prefix: str = "") -> dict[str, float]:
    out = {}
    for key, value in stats.items():
        if key in ("tolerances", "tolerance_sources", "crs"):
            continue
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_numeric_leaves(value, name + "."))
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            out[name] = float(value)
    return out


def topology_section(runs: list[tuple[str, dict]]) -> Section:
    plt = _plt()
    sec = Section("topology", "Topology")
    for name, report in runs:
        counts = {k: v for k, v in _numeric_leaves(_stats(report)).items()
                  if not k.startswith("input.") and not k.endswith("_length")}
        if not counts:
            continue
        errors = counts.get("output.errors")
        sec.rows.append((f"{name}: errors left", "n/a" if errors is None else f"{errors:.0f}"))
        sec.rows.append((f"{name}: fixed automatically", _fmt(counts.get("output.fixable"),
                                                              digits=0)))
        shown = {k: v for k, v in counts.items() if v > 0}
        fig, ax = plt.subplots(figsize=(7, 0.25 * len(shown) + 1.2))
        keys = list(shown)[::-1]
        ax.barh(keys, [shown[k] for k in keys], color=["#c0392b" if k == "output.errors"
                                                       else "#5d6d7e" for k in keys])
        ax.set_xlabel("count", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.set_title(f"{name}: what the topology check found and fixed", fontsize=8)
        fig.tight_layout()
        sec.figures.append(fig)
    return sec


def build_sections(reports: dict[str, list[tuple[str, dict]]], ortho_scale: float,
                   rule_mm: float) -> list[Section]:
    sections = []
    if reports.get("orientation:interior"):
        sections.append(interior_section(reports["orientation:interior"]))
    if reports.get("rectify:estimate"):
        sections.append(rectification_section(reports["rectify:estimate"], ortho_scale,
                                              rule_mm))
    if reports.get("dem:cross_validate"):
        sections.append(dem_section(reports["dem:cross_validate"]))
    if reports.get("topology:check"):
        sections.append(topology_section(reports["topology:check"]))
    return [s for s in sections if s.rows or s.figures]


# -- writers -------------------------------------------------------------------------------------
def _overview(reports: dict[str, list[tuple[str, dict]]]) -> list[tuple[str, str]]:
    rows = []
    for alg, runs in sorted(reports.items()):
        for name, report in runs:
            warnings = len(report.get("warnings") or [])
            rows.append((name, f"{alg}, {report.get('elapsed_s', 0):.1f} s"
                         + (f", {warnings} warning(s)" if warnings else "")))
    return rows


def write_pdf(path: str | Path, title: str, overview, sections: list[Section]) -> None:
    from matplotlib.backends.backend_pdf import PdfPages

    plt = _plt()
    with PdfPages(path, metadata={"Title": title, "Creator": "photogrammetry-toolbox"}) as pdf:
        for heading, rows, notes in [("Runs", overview, [])] + \
                [(s.title, s.rows, s.notes) for s in sections]:
            fig = plt.figure(figsize=(8.27, 11.69))
            fig.text(0.08, 0.95, title if heading == "Runs" else heading, fontsize=14,
                     fontweight="bold")
            y = 0.91
            if heading == "Runs":
                fig.text(0.08, y, "Runs in this report", fontsize=10)
                y -= 0.03
            for label, value in rows:
                fig.text(0.08, y, label, fontsize=7)
                fig.text(0.45, y, value[:95], fontsize=7)
                y -= 0.018
                if y < 0.05:
                    break
            for note in notes:
                fig.text(0.08, y, note, fontsize=7, style="italic")
                y -= 0.018
            pdf.savefig(fig)
            plt.close(fig)
            for s in sections:
                if s.title == heading:
                    for f in s.figures:
                        pdf.savefig(f)


def write_html(path: str | Path, title: str, overview, sections: list[Section]) -> None:
    from html import escape

    def table(rows):
        return "<table>" + "".join(f"<tr><th>{escape(a)}</th><td>{escape(b)}</td></tr>"
                                   for a, b in rows) + "</table>"

    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{escape(title)}"
             "</title><style>body{font-family:sans-serif;max-width:1000px;margin:auto}"
             "th{text-align:left;padding-right:1em;font-weight:normal;color:#555}"
             "img{max-width:100%}</style></head><body>",
             f"<h1>{escape(title)}</h1><h2>Runs</h2>", table(overview)]
    for s in sections:
        parts.append(f"<h2 id='{s.key}'>{escape(s.title)}</h2>{table(s.rows)}")
        parts += [f"<p><em>{escape(n)}</em></p>" for n in s.notes]
        for f in s.figures:
            buf = io.BytesIO()
            f.savefig(buf, format="png", dpi=110)
            data = base64.b64encode(buf.getvalue()).decode("ascii")
            parts.append(f"<figure class='{s.key}'><img src='data:image/png;base64,{data}'>"
                         "</figure>")
    parts.append("</body></html>")
    Path(path).write_text("\n".join(parts), encoding="utf-8")


def write_report(folder: str | Path, output: str | Path, title: str, ortho_scale: float,
                 rule_mm: float) -> dict:
    """Build the report from the run reports in ``folder``; PDF or HTML by ``output``'s
    extension. Returns what it contains."""
    plt = _plt()
    reports = load_reports(folder)
    sections = build_sections(reports, ortho_scale, rule_mm)
    overview = _overview(reports)
    try:
        if str(output).lower().endswith(".html"):
            write_html(output, title, overview, sections)
        else:
            write_pdf(output, title, overview, sections)
    finally:
        for s in sections:
            for f in s.figures:
                plt.close(f)
    return {"runs": len(overview), "sections": [s.key for s in sections],
            "figures": {s.key: len(s.figures) for s in sections}}
