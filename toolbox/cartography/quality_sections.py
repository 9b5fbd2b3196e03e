"""The sections of the quality report, one per kind of run (interior orientation, orientation,
rectification, orthophotos, DEM cross-validation, mosaic, topology, warnings, runs), each drawn
from the JSON run reports only (see :mod:`toolbox.cartography.quality`)."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from toolbox.cartography.quality_model import (
    FAIL,
    NOT_CHECKED,
    PASS,
    Section,
    Specification,
    Verdict,
    _fmt,
    _judge,
    _planimetric,
    _plt,
    _stats,
    without_paths,
)


# -- sections ------------------------------------------------------------------------------------
def interior_section(runs, spec: Specification, verdicts: list[Verdict]) -> Section:
    plt = _plt()
    sec = Section("interior", "Interior orientation")
    sec.text("Each scanned photo is tied to its camera's calibrated fiducial marks by a plane "
             "transformation; the residuals at the marks measure the scan and the measurement.")
    for _name, report in runs:
        stats = _stats(report)
        worst_um = None if stats.get("max_residual_mm") is None else \
            1000.0 * stats["max_residual_mm"]
        sigma_um = None if stats.get("max_sigma0_mm") is None else \
            1000.0 * stats["max_sigma0_mm"]  # None: no redundancy (not 0.0, a perfect fit)
        verdicts.append(Verdict("Interior orientation", "largest fiducial residual",
                                _fmt(worst_um, "µm", 1), f"<= {spec.io_tolerance_um:g} µm",
                                _judge(worst_um, spec.io_tolerance_um),
                                "producer's threshold"))
        csv_path = report["outputs"].get("RESIDUALS")
        if not csv_path or not Path(csv_path).exists():
            sec.table(["Photos", "Largest residual", "Largest sigma0"],
                      [[str(stats.get("photos")), _fmt(worst_um, "µm", 1),
                        _fmt(sigma_um, "µm", 1)]])
            sec.text("No residual table was written, so no vector plot.")
            continue
        by_photo: dict[str, list[dict]] = {}
        with open(csv_path, newline="", encoding="utf-8") as f:
            for row in csv.DictReader(f):
                by_photo.setdefault(row["photo"], []).append(row)
        rows = []
        for photo, marks in sorted(by_photo.items()):
            res = np.array([float(r["res_mm"]) for r in marks]) * 1000.0
            rows.append([photo, marks[0].get("transformation", ""), str(len(marks)),
                         f"{np.sqrt(np.mean(res ** 2)):.1f} µm", f"{res.max():.1f} µm",
                         PASS if res.max() <= spec.io_tolerance_um else FAIL])
        sec.table(["Photo", "Transformation", "Marks", "RMS residual", "Largest", "Verdict"],
                  rows)
        photos = sorted(by_photo)
        cols = min(3, len(photos))
        nrows = int(np.ceil(len(photos) / cols))
        fig, axes = plt.subplots(nrows, cols, figsize=(2.4 * cols, 2.4 * nrows), squeeze=False)
        res_max = max(float(r["res_mm"]) for rows_ in by_photo.values() for r in rows_) or 1.0
        k = 1.0
        for ax, photo in zip(axes.ravel(), photos):
            marks = by_photo[photo]
            x = np.array([float(r["x_mm"]) for r in marks])
            y = np.array([float(r["y_mm"]) for r in marks])
            dx = np.array([float(r["res_x_mm"]) for r in marks])
            dy = np.array([float(r["res_y_mm"]) for r in marks])
            span = max(np.ptp(x), np.ptp(y), 1.0)
            k = 0.15 * span / res_max  # the largest residual drawn 15 % of the frame
            ax.quiver(x, y, dx * k, dy * k, angles="xy", scale_units="xy", scale=1,
                      color="#c0392b", width=0.012)
            ax.plot(x, y, "k+", ms=6)
            ax.set_title(f"{photo}: largest {np.hypot(dx, dy).max() * 1000:.1f} µm", fontsize=8)
            ax.set_aspect("equal")
            ax.set_xlim(x.min() - 0.25 * span, x.max() + 0.25 * span)
            ax.set_ylim(y.min() - 0.25 * span, y.max() + 0.25 * span)
            ax.tick_params(labelsize=6)
        for ax in axes.ravel()[len(photos):]:
            ax.set_visible(False)
        fig.suptitle(f"Residual vectors at the fiducial marks, enlarged {k:.0f} times "
                     "(photo coordinates, mm)", fontsize=8)
        fig.tight_layout()
        sec.figure(fig)
    return sec


_NOT_RESECTED = re.compile(r"photo (\S+): (\d+) control point")


def orientation_section(reports, spec: Specification, verdicts: list[Verdict]) -> Section | None:
    sec = Section("orientation", "Orientation of the photos")
    for name, report in reports.get("orientation:resection", []):
        stats = _stats(report)
        sigma = stats.get("sigma0_um") or {}
        missing = [m.group(1) for w in report.get("warnings") or [] for m in
                   [_NOT_RESECTED.search(w)] if m]
        sec.text(f"Space resection ({name}): {len(sigma)} photo(s) oriented from control "
                 "points." + (f" Not oriented (fewer than 4 control points): "
                              f"{', '.join(missing)}." if missing else ""))
        in_px = stats.get("sigma0_px") or {}  # camera models: pixels, no µm
        sec.table(["Photo", "sigma0 a posteriori"],
                  [[p, _fmt(s, "µm", 1) if s is not None or p not in in_px else
                    _fmt(in_px[p], "px", 2)] for p, s in sorted(sigma.items())])
        verdicts.append(Verdict("Orientation", "photos oriented",
                                f"{len(sigma)} of {len(sigma) + len(missing)}",
                                "all photos", FAIL if missing else PASS, "completeness"))
    for name, report in reports.get("orientation:absolute", []):
        stats = _stats(report)
        check = stats.get("check_rmse_xyz")
        rows = [["Control points", str(stats.get("control_points"))],
                ["Model scale", f"1:{stats['scale']:.0f}" if stats.get("scale") else "n/a"]]
        if check:
            xy = float(np.hypot(check[0], check[1]))
            rows += [["Check points RMSE, planimetric", _fmt(xy, "m")],
                     ["Check points RMSE, height", _fmt(check[2], "m")]]
            verdicts.append(Verdict("Absolute orientation", "check points, planimetric RMSE",
                                    _fmt(xy, "m"), f"<= {_fmt(spec.planimetric_m, 'm', 2)}",
                                    _judge(xy, spec.planimetric_m), "S002 §2.6.6"))
        sec.text(f"Absolute orientation of the stereo model ({name}).")
        sec.table(["Quantity", "Value"], rows)
    for name, report in reports.get("orientation:bundle", []):
        stats = _stats(report)
        control, check = stats.get("control_rmse_m") or {}, stats.get("check_rmse_m") or {}
        sec.text(f"Aerial triangulation ({name}): one bundle adjustment of {stats.get('photos')} "
                 f"photos and {stats.get('points')} tie points; sigma0 a posteriori "
                 f"{_fmt(stats.get('sigma0'), digits=2)} (1 when the a priori sigmas are right), "
                 f"redundancy {stats.get('redundancy')}, {stats.get('rejected')} observations "
                 f"rejected as gross errors, {stats.get('flagged')} flagged.")
        sec.table(["Quantity", "Control points", "Check points"], [
            ["RMSE, planimetric", _fmt(_planimetric(control), "m"), _fmt(_planimetric(check), "m")],
            ["RMSE, height", _fmt(control.get("z"), "m"), _fmt(check.get("z"), "m")]])
        for label, value, limit in (("planimetric", _planimetric(check), spec.planimetric_m),
                                    ("height", check.get("z"), spec.height_rmse_m)):
            verdicts.append(Verdict("Aerial triangulation", f"check points, {label} RMSE",
                                    _fmt(value, "m"), f"<= {_fmt(limit, 'm', 2)}", _judge(value, limit),
                                    "S002 §2.6.6" if label == "planimetric" else "NMAS"))
    for name, report in reports.get("orientation:check", []):
        stats = _stats(report)
        sec.text(f"Orientation check ({name}): control and check points projected into every "
                 "photo that sees them; the image residuals and the ground misclosure of the "
                 "intersected points.")
        sec.table(["Quantity", "Control points", "Check points"], [
            ["Points intersected", str(stats.get("control_points", 0)),
             str(stats.get("check_points", 0))],
            ["RMSE, planimetric", _fmt(stats.get("control_rmse_xy_m"), "m"),
             _fmt(stats.get("check_rmse_xy_m"), "m")],
            ["RMSE, height", _fmt(stats.get("control_rmse_z_m"), "m"),
             _fmt(stats.get("check_rmse_z_m"), "m")]])
        sec.table(["Image observations", "RMS residual", "Flagged (over the threshold)"],
                  [[str(stats.get("observations")), _fmt(stats.get("rmse_um"), "µm", 1),
                    f"{stats.get('flagged')} (> {stats.get('threshold_px')} px)"]])
        for label, key, limit in (("planimetric", "check_rmse_xy_m", spec.planimetric_m),
                                  ("height", "check_rmse_z_m", spec.height_rmse_m)):
            verdicts.append(Verdict("Orientation", f"check points, {label} RMSE",
                                    _fmt(stats.get(key), "m"), f"<= {_fmt(limit, 'm', 2)}",
                                    _judge(stats.get(key), limit),
                                    "S002 §2.6.6" if label == "planimetric" else "NMAS"))
    return sec if sec.blocks else None


def rectification_section(runs, spec: Specification, verdicts: list[Verdict]) -> Section:
    plt = _plt()
    sec = Section("rectification", "Rectification accuracy")
    tolerance = spec.planimetric_m
    for _name, report in runs:
        stats = _stats(report)
        check = stats.get("check") or {}
        rmse_check = check.get("rmse")
        sec.table(["Quantity", "Value"], [
            ["Model", str(stats.get("model"))],
            ["Control points used / check points",
             f"{stats.get('used_points')} / {stats.get('check_points')}"],
            ["Rejected as gross errors", ", ".join(stats.get("rejected_points") or []) or "none"],
            ["Control RMSE east / north", f"{_fmt(stats.get('rmse_x'), 'm')} / "
                                          f"{_fmt(stats.get('rmse_y'), 'm')}"],
            ["Check points RMSE", _fmt(rmse_check, "m")]])
        verdicts.append(Verdict("Rectified photo", "check points RMSE", _fmt(rmse_check, "m"),
                                f"<= {_fmt(tolerance, 'm', 2)}", _judge(rmse_check, tolerance),
                                "S002 §2.6.6"))
        points = stats.get("points") or []
        if not points:
            continue
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.8),
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
        ax.set_title(f"Ground residuals, enlarged {k:.0f} times (rejected: direction only)",
                     fontsize=8)
        ax.set_xlabel(f"east - {origin[0]:.0f} (m)", fontsize=7)
        ax.set_ylabel(f"north - {origin[1]:.0f} (m)", fontsize=7)
        ax.tick_params(labelsize=6)
        bx.bar([p["id"] for p in good], [p["residual_ground_norm"] for p in good],
               color=[colours[p["role"]] for p in good])
        bx.axhline(tolerance, color="#c0392b", ls="--", lw=1,
                   label=f"tolerance {_fmt(tolerance, 'm', 2)}")
        if rmse_check is not None:
            bx.axhline(rmse_check, color="#1e8449", ls=":", lw=1,
                       label=f"check RMSE {rmse_check:.3f} m")
        bx.set_ylabel("residual (m)", fontsize=7)
        bx.tick_params(labelsize=6)
        bx.legend(fontsize=6)
        bx.set_title("Residual per point", fontsize=8)
        fig.tight_layout()
        sec.figure(fig)
    return sec


def ortho_section(reports, spec: Specification, verdicts: list[Verdict]) -> Section | None:
    sec = Section("ortho", "Orthophotos")
    rows = []
    failed = []
    for _name, report in reports.get("ortho:photo", []):
        s = _stats(report)
        rows.append([str(s.get("photo")), _fmt(s.get("cell_size"), "m", 2),
                     _fmt(s.get("photo_gsd_m"), "m", 2),
                     _fmt(s.get("max_relief_displacement_m"), "m", 1),
                     f"{100 * (s.get('outside_photo_fraction') or 0):.0f} %"])
    for name, report in reports.get("ortho:batch", []):
        s = _stats(report)
        failed += [f"{name}: {s.get('failed')} of {s.get('photos')} photos failed"] \
            if s.get("failed") else []
        rows.append([f"{name} (block)", _fmt(s.get("cell_size"), "m", 2), "", "",
                     f"{s.get('done')} of {s.get('photos')} photos written"])
    checks = reports.get("report:ortho_check", [])
    if not rows and not checks:
        return None
    sec.text("Orthophotos on the DEM. Their accuracy combines the orientation's and the DEM's: "
             f"the rule is a planimetric RMS <= {_fmt(spec.planimetric_m, 'm', 2)} on check points "
             "measured on the orthophoto.")
    sec.table(["Photo", "Cell", "Photo GSD", "Largest relief shift", "Outside the photo"], rows)
    if rows:
        verdicts.append(Verdict("Orthophotos", "all photos orthorectified",
                                "; ".join(failed) or "all written", "no failure",
                                FAIL if failed else PASS, "completeness"))
    if not checks:
        verdicts.append(Verdict("Orthophotos", "planimetric RMSE on check points",
                                "not measured", f"<= {_fmt(spec.planimetric_m, 'm', 2)}", NOT_CHECKED,
                                "S002 §2.6.6"))
    ortho_check_rows(sec, checks, spec, verdicts)
    return sec


def ortho_check_rows(sec: Section, checks, spec: Specification, verdicts: list[Verdict]
                     ) -> None:
    """The check points measured on each orthophoto (report:ortho_check runs): method, RMSE,
    a verdict per orthophoto."""
    if not checks:
        return
    sec.text("Check points measured on the orthophoto: around each point a chip of the photo, "
             "centred on the target as the operator measured it there, is found on the "
             "orthophoto by normalised cross-correlation; the offset is where the orthophoto "
             "shows the target minus where it was surveyed.")
    table = []
    for _name, report in checks:
        s = _stats(report)
        rms = s.get("rmse_planimetric_m")
        table.append([without_paths(s.get("ortho", _name)), f"{s.get('matched')} of "
                      f"{s.get('points')}", _fmt(s.get("rmse_x_m"), "m", 2),
                      _fmt(s.get("rmse_y_m"), "m", 2), _fmt(rms, "m", 2),
                      _fmt(s.get("largest_m"), "m", 2) if s.get("largest_m") is not None
                      else "n/a"])
        verdicts.append(Verdict("Orthophotos", "planimetric RMSE on check points (measured "
                                f"on {without_paths(s.get('ortho', _name))})",
                                f"{_fmt(rms, 'm', 2)} ({s.get('matched')} point"
                                f"{'' if s.get('matched') == 1 else 's'})"
                                if rms is not None else "no point found",
                                f"<= {_fmt(spec.planimetric_m, 'm', 2)}", _judge(rms,
                                                                         spec.planimetric_m),
                                "S002 §2.6.6"))
    sec.table(["Orthophoto", "Points found", "RMSE east", "RMSE north", "RMSE planimetric",
               "Largest"], table)
    for name, report in checks:
        offsets = _stats(report).get("offsets") or []
        if offsets:
            sec.figure(_offsets_figure(offsets, without_paths(_stats(report).get("ortho", name)),
                                       spec.planimetric_m))


def _offsets_figure(offsets: list[dict], ortho: str, tolerance: float):
    """Offset vectors at the check points (enlarged) and their lengths against the tolerance."""
    plt = _plt()
    xy = np.array([[o["x"], o["y"]] for o in offsets], dtype="float64")
    d = np.array([[o["dx"], o["dy"]] for o in offsets], dtype="float64")
    length = np.hypot(d[:, 0], d[:, 1])
    origin = xy.mean(axis=0)
    span = max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), 1.0)
    k = 0.12 * span / max(float(length.max()), 1e-9)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.6), gridspec_kw={"width_ratios": [1.4, 1]})
    g = xy - origin
    ax.quiver(g[:, 0], g[:, 1], d[:, 0] * k, d[:, 1] * k, angles="xy", scale_units="xy",
              scale=1, color="#1e8449", width=0.006)
    ax.plot(g[:, 0], g[:, 1], "o", color="#1e8449", ms=3)
    for o, (gx, gy) in zip(offsets, g, strict=True):
        ax.annotate(str(o["id"]), (gx, gy), fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax.set_aspect("equal")
    ax.margins(0.15)
    ax.set_title(f"{ortho}: where the orthophoto shows each check point, enlarged {k:.0f} "
                 "times", fontsize=8)
    ax.set_xlabel(f"east - {origin[0]:.0f} (m)", fontsize=7)
    ax.set_ylabel(f"north - {origin[1]:.0f} (m)", fontsize=7)
    ax.tick_params(labelsize=6)
    bx.bar([str(o["id"]) for o in offsets], length, color="#1e8449")
    bx.axhline(tolerance, color="#c0392b", ls="--", lw=1, label=f"tolerance {_fmt(tolerance, 'm', 2)}")
    bx.set_ylabel("offset (m)", fontsize=7)
    bx.tick_params(labelsize=6)
    bx.tick_params(axis="x", rotation=90)
    bx.legend(fontsize=6)
    bx.set_title("Offset per check point", fontsize=8)
    fig.tight_layout()
    return fig


def height_unit(crs_text: str | None) -> tuple[float | None, str]:
    """Metres per height unit of a run's CRS (its label as the run report gives it) and how it
    is known: the vertical axis's unit; without one, metres when x and y are in metres (the
    toolbox's convention), unknown (None) when they are not (feet x, y say nothing of heights)."""
    if not crs_text or crs_text == "none":
        return 1.0, "metres assumed (no CRS)"
    try:
        from pyproj import CRS

        axes = CRS.from_user_input(crs_text).axis_info
    except Exception:  # noqa: BLE001 - a CRS named only: no unit to read
        return 1.0, "metres assumed"
    up = [a for a in axes if a.direction == "up"]
    if up:
        return up[0].unit_conversion_factor, f"heights in {up[0].unit_name} ({crs_text})"
    horizontal = [a for a in axes if a.direction in ("east", "north")]
    if all(abs(a.unit_conversion_factor - 1.0) < 1e-12 for a in horizontal):
        return 1.0, "metres assumed"
    unit = horizontal[0].unit_name if horizontal else "unknown"
    return None, (f"{crs_text} has x, y in {unit} and no vertical axis: the heights' unit is "
                  "unknown")


# duplicate-ok: every section opens alike (plots, title, what the method measures)
def dem_section(runs, spec: Specification, verdicts: list[Verdict]) -> Section:
    plt = _plt()
    sec = Section("dem", "DEM cross-validation")
    sec.text("Leave one out: each height point is predicted from the others; error = predicted "
             "- observed.")
    for _name, report in runs:
        methods = _stats(report).get("methods") or {}
        if not methods:
            continue
        rated = [k for k in methods if methods[k].get("rmse") is not None]
        best = _stats(report).get("best") or min(rated, default=None,
                                                 key=lambda k: methods[k]["rmse"])
        factor, how = height_unit(_stats(report).get("crs"))  # the errors are in CRS heights
        known = factor is not None  # in metres and judged; else as stored, not judged
        scale, unit = (factor, "m") if known else (1.0, "height units")

        def shown(value, scale=scale):
            return None if value is None else float(value) * scale

        if factor != 1.0:
            sec.text(f"Errors converted to metres: {how}." if known else
                     f"Errors in the run's height units, not converted: {how}.")
        sec.table(["Method", "RMSE", "Mean error", "Largest |error|", "Points predicted"],
                  [[k + (" (best)" if k == best else ""), _fmt(shown(v.get("rmse")), unit),
                    _fmt(shown(v.get("mean_error")), unit),
                    _fmt(shown(v.get("max_abs_error")), unit),
                    str(v.get("predicted"))] for k, v in methods.items()])
        if best is None:  # every point a hull vertex (or out of reach): nothing predicted
            verdicts.append(Verdict("DEM", "height RMSE of the best method",
                                    "no point predicted", f"<= {_fmt(spec.height_rmse_m, 'm', 2)}",
                                    NOT_CHECKED, "NMAS, contour interval"))
            sec.text("No method predicted any point (each was a convex-hull vertex or out of "
                     "reach): no RMSE.")
            continue
        best_rmse = shown(methods[best].get("rmse"))
        rmse = best_rmse if known else None
        verdicts.append(Verdict("DEM", f"height RMSE of the best method ({best})",
                                _fmt(rmse, "m") if known else f"{_fmt(best_rmse)} ({how})",
                                f"<= {_fmt(spec.height_rmse_m, 'm', 2)}",
                                _judge(rmse, spec.height_rmse_m), "NMAS, contour interval"))
        fig, ax = plt.subplots(figsize=(6, 2.4))
        names = rated
        ax.bar(names, [methods[k]["rmse"] * scale for k in names],
               color=["#1e8449" if k == best else "#7f8c8d" for k in names])
        if known:
            ax.axhline(spec.height_rmse_m, color="#c0392b", ls="--", lw=1,
                       label=f"tolerance {_fmt(spec.height_rmse_m, 'm', 2)}")
        ax.set_ylabel(f"RMSE ({unit})", fontsize=7)
        ax.set_title("RMSE by method", fontsize=8)
        if known:
            ax.legend(fontsize=6)
        ax.tick_params(labelsize=7)
        fig.tight_layout()
        sec.figure(fig)
        path = report["outputs"].get("RESIDUALS")
        if not path or not Path(path).exists():
            sec.text("No residual points were written, so no histogram or map.")
            continue
        import geopandas as gpd

        pts = _residual_points(gpd, Path(path), list(methods))
        cols = [f"{k}_err" for k in methods if f"{k}_err" in pts.columns]
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
        errors = [pts[c].dropna().to_numpy() * scale for c in cols]
        lim = max((np.percentile(np.abs(e), 99.5) for e in errors if e.size), default=1.0)
        bins = np.linspace(-lim, lim, 41)
        for c, e in zip(cols, errors):
            axes[0].hist(e, bins=bins, histtype="step", lw=1.2 if c == f"{best}_err" else 0.7,
                         label=c[:-4])
        axes[0].set_xlabel(f"error ({unit})", fontsize=7)
        axes[0].set_ylabel("points", fontsize=7)
        axes[0].legend(fontsize=6)
        axes[0].set_title("Error histograms by method", fontsize=8)
        e = pts[f"{best}_err"] * scale
        ok = e.notna().to_numpy()
        x, y = pts.geometry.x.to_numpy()[ok], pts.geometry.y.to_numpy()[ok]
        scatter = axes[1].scatter(x - x.min(), y - y.min(), c=e[ok], s=3, cmap="RdBu_r",
                                  vmin=-lim, vmax=lim)
        fig.colorbar(scatter, ax=axes[1], label=f"error ({unit})")
        axes[1].set_aspect("equal")
        axes[1].set_title(f"{best}: errors on the ground (from E {x.min():.0f}, "
                          f"N {y.min():.0f})", fontsize=8)
        for a in axes:
            a.tick_params(labelsize=6)
        fig.tight_layout()
        sec.figure(fig)
    return sec


def _residual_points(gpd, path: Path, methods: list[str]):
    """The dem:cross_validate residual points of ``path``, with the names the run wrote
    (``z``, then ``<method>_z`` and ``<method>_err`` per method, in order): a Shapefile holds
    them cut to 10 characters (``tin_linear_err`` -> ``tin_line_1``), so the report failed
    ('run report incomplete (no 'tin_linear_err')') and left the cut methods out of the
    histogram."""
    pts = gpd.read_file(path)
    if path.suffix.lower() == ".shp":
        from toolbox.io.vector_write import shapefile_renames

        names = ["z"] + [f"{k}{end}" for k in methods for end in ("_z", "_err")]
        renames = shapefile_renames(path, names)
        pts = pts.rename(columns={new: old for old, new in renames.items()})
    return pts


def mosaic_section(reports, verdicts: list[Verdict]) -> Section | None:
    sec = Section("mosaic", "Mosaic and seamlines")
    for name, report in reports.get("mosaic:seamlines", []):
        s = _stats(report)
        sec.text(f"Seamlines ({name}): method {s.get('method')}, {s.get('orthos')} orthophotos.")
        sec.table(["Orthophoto", "Area it supplies"],
                  [[k, _fmt(v / 1e4, "ha", 2)] for k, v in (s.get("cut_areas") or {}).items()])
        sec.table(["Seam between", "Method", "Vertices", "Pieces"],
                  [[f"{r['a']} / {r['b']}", str(r.get("method")), str(r.get("vertices")),
                    str(r.get("pieces"))] for r in s.get("seams") or []])
        gap, overlap = s.get("partition_gap_area"), s.get("max_overlap_area")
        if gap is not None and overlap is not None:
            worst = max(gap, overlap)
            verdicts.append(Verdict("Mosaic", "gaps and overlaps between the orthophotos' parts",
                                    f"{worst:.3g} m²", "<= 1 m²", _judge(worst, 1.0),
                                    "a partition of the area"))
    for name, report in reports.get("mosaic:build", []):
        s = _stats(report)
        cells = s.get("cells_per_source") or {}
        sec.text(f"Mosaic ({name}): {s.get('width')} x {s.get('height')} cells of "
                 f"{s.get('cell_size')} m, blend {s.get('blend')}, {s.get('empty_cells')} cells "
                 "without data.")
        sec.table(["Orthophoto", "Cells it supplies"], [[k, f"{v:,}"] for k, v in cells.items()])
    return sec if sec.blocks else None


#: plain words for the topology check's counters
TOPOLOGY_LABELS = {
    "snap.ends_to_node": "line ends snapped to a node",
    "snap.ends_to_vertex": "line ends snapped to a vertex",
    "snap.ends_to_segment": "line ends snapped onto a line",
    "snap.collapsed_lines": "lines collapsed by snapping",
    "close.closed": "rings closed",
    "node.edges": "edges after noding",
    "node.crossings_noded": "crossings split into nodes",
    "node.self_intersections_noded": "self-intersections split",
    "duplicates.exact_duplicate_lines": "duplicate lines removed",
    "duplicates.overlapping_pieces": "overlapping pieces removed",
    "dangles.overshoots_trimmed": "overshoots trimmed",
    "dangles.dangles_removed": "dangling lines removed",
    "dangles.dangles_kept": "dangling lines kept (errors)",
    "dangles.unclosed_lines": "lines left open (errors)",
    "polygonize.faces": "areas formed",
    "slivers.merged": "sliver areas merged",
    "slivers.dropped": "sliver areas dropped",
    "labels.labels": "area labels",
    "labels.labelled_areas": "labelled areas",
    "labels.unlabelled_areas": "areas without a label",
    "labels.conflicting_areas": "areas with conflicting labels",
    "labels.labels_outside": "labels outside every area",
    "output.errors": "errors left",
    "output.fixable": "fixed automatically",
}


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


def topology_section(runs, verdicts: list[Verdict]) -> Section:
    plt = _plt()
    sec = Section("topology", "Topology of the linework")
    for name, report in runs:
        counts = {k: v for k, v in _numeric_leaves(_stats(report)).items()
                  if not k.startswith("input.") and not k.endswith("_length")}
        if not counts:
            continue
        errors = counts.get("output.errors")
        verdicts.append(Verdict("Topology", "errors left in the linework",
                                "n/a" if errors is None else f"{errors:.0f}", "0",
                                _judge(errors, 0.0), "a clean area topology"))
        label = {k: TOPOLOGY_LABELS.get(k, k.split(".")[-1].replace("_", " ")) for k in counts}
        shown = {k: v for k, v in counts.items() if v > 0}
        sec.table(["What the check found or did", "Count"],
                  [[label[k], f"{v:.0f}"] for k, v in shown.items()])
        fig, ax = plt.subplots(figsize=(7, 0.2 * len(shown) + 1.0))
        keys = list(shown)[::-1]
        ax.barh([label[k] for k in keys], [shown[k] for k in keys],
                color=["#c0392b" if k == "output.errors" else "#5d6d7e" for k in keys])
        ax.set_xlabel("count", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.set_title(f"{name}: what the topology check found and fixed", fontsize=8)
        fig.tight_layout()
        sec.figure(fig)
    return sec


def warnings_section(reports) -> Section:
    sec = Section("warnings", "Every warning of every run")
    rows = [[name, without_paths(w)] for _, runs in sorted(reports.items()) for name, report in
            runs for w in report.get("warnings") or []]
    if rows:
        sec.table(["Run", "Warning"], rows)
    else:
        sec.text("No run gave a warning.")
    return sec


def runs_section(reports) -> Section:
    sec = Section("runs", "Runs in this report")
    sec.table(["Run", "Algorithm", "Time", "Warnings"],
              [[name, f"{report.get('display_name') or alg} ({alg})",
                f"{report.get('elapsed_s', 0):.1f} s", str(len(report.get("warnings") or []))]
               for alg, runs in sorted(reports.items()) for name, report in runs])
    return sec
