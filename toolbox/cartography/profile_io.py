"""Profiles and sections from files: polylines, a DEM or a TIN or contour lines; GeoPackage
layers and a plot."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.cartography.profile import (
    chainage_of_vertices,
    contour_crossings,
    points_at,
    sample_stations,
    section_axes,
)
from toolbox.io.raster import read_filled
from toolbox.raster.bilinear import bilinear


@dataclass(frozen=True)
class InputLine:
    """Part ``part`` (1-based) of INPUT feature ``line`` (its 1-based row) of ``parts`` parts,
    with its vertices ``xy``."""

    line: int
    part: int
    parts: int
    xy: np.ndarray

    @property
    def name(self) -> str:
        """``3``, or ``3.2`` for part 2 of a multi-part feature."""
        return f"{self.line}" if self.parts == 1 else f"{self.line}.{self.part}"

    @property
    def label(self) -> str:
        """``line 3`` (the feature's row), or ``line 3 part 2``."""
        return f"line {self.line}" + (f" part {self.part}" if self.parts > 1 else "")


@dataclass
class Profile:
    """One sampled line: ``name`` (line id, or line/section), the INPUT feature's 1-based
    ``line`` and ``part``, stations along it (``distance``, from its start), points ``xy`` and
    heights ``z``; ``chainage`` is the position along the axis (the distance itself for
    profiles, the section's station for sections)."""

    name: str
    line: int
    part: int
    section: int | None
    chainage: float
    distance: np.ndarray
    xy: np.ndarray
    z: np.ndarray


class Surface:
    """Heights at map points from a DEM (bilinear between cell centres; only the window around
    the points is read, so DEM size does not matter) or a TIN (planes)."""

    def __init__(self, dem=None, band: int = 1, tin=None):
        self.dem, self.band, self.tin = dem, band, None
        if dem is None:
            from toolbox.terrain.tin.store import read_tin

            self.tin = read_tin(tin)[:2]

    def heights(self, xy: np.ndarray) -> np.ndarray:
        if self.tin is not None:
            from toolbox.terrain.tin.kernels import interpolate_tin

            return interpolate_tin(self.tin[0], self.tin[1], xy[:, 0], xy[:, 1])
        import rasterio
        from rasterio.windows import Window

        from toolbox.cartography.contour_io import GridFrame
        from toolbox.io.raster import dataset_transform

        with rasterio.open(self.dem.path) as src:
            f = GridFrame.of(dataset_transform(src))
            cols = (xy[:, 0] - f.x0) / f.dx
            rows = (xy[:, 1] - f.y0) / f.dy
            c0 = int(np.clip(np.floor(np.nanmin(cols)) - 1, 0, src.width - 1))
            r0 = int(np.clip(np.floor(np.nanmin(rows)) - 1, 0, src.height - 1))
            c1 = int(np.clip(np.ceil(np.nanmax(cols)) + 2, c0 + 1, src.width))
            r1 = int(np.clip(np.ceil(np.nanmax(rows)) + 2, r0 + 1, src.height))
            z = read_filled(src, self.band, Window(c0, r0, c1 - c0, r1 - r0))
        out = bilinear(z, f.x0 + c0 * f.dx, f.y0 + r0 * f.dy, f.dx, f.dy, xy, half_cell=True)
        # points off the raster's cells: NaN (the window was clipped to the raster; its outer
        # half cell, beyond the last centres, takes the edge's values as in GDAL)
        off = (cols < -0.5) | (cols > src.width - 0.5) | (rows < -0.5) | (rows > src.height - 0.5)
        return np.where(off, np.nan, out)


def line_parts(frame, warn=None) -> list[InputLine]:
    """The lines of a layer, numbered by feature (1-based row) and part (multi-lines split);
    features without geometry (null or empty) have no profile: ``warn`` names them, and a
    layer of only those is refused."""
    import shapely

    from toolbox.errors import InputDataError
    from toolbox.io.vector import feature_rows, no_geometry

    missing = no_geometry(frame.geometry.values)
    if missing.all():
        raise InputDataError(f"INPUT has no line to profile: its {len(frame)} feature(s) have "
                             "no geometry (null or empty)")
    if missing.any() and warn is not None:
        warn(f"INPUT: {int(missing.sum())} feature(s) without geometry (null or empty) have no "
             f"profile: {feature_rows(np.flatnonzero(missing))}")
    out = []
    for row, geom in enumerate(frame.geometry.values, start=1):
        parts = [] if missing[row - 1] else shapely.get_parts(geom)
        out += [InputLine(row, k, len(parts), shapely.get_coordinates(p))
                for k, p in enumerate(parts, start=1) if not p.is_empty]
    return out


def guard_profile_size(lines: list[np.ndarray], mode: str, step: float, spacing: float,
                       half_width: float) -> None:
    """Refuse before sampling when the stations (the lines' length / ``step``, or for sections
    their number, length / ``spacing``, times 2·``half_width`` / ``step``) are too many."""
    from toolbox.limits import check_size

    if mode == "contours":
        return
    length = float(sum(chainage_of_vertices(xy)[-1] for xy in lines))
    if mode == "step":
        check_size("vertices", length / step + len(lines), "STEP",
                   f"{step:g} along {length:,.0f} units of lines", "use a larger STEP")
        return
    sections = length / spacing + len(lines)
    check_size("features", sections, "SPACING", f"{spacing:g} along {length:,.0f} units of "
               "lines", "use a larger SPACING", "sections")
    check_size("vertices", sections * (2 * half_width / step + 2), "STEP",
               f"{step:g} across {sections:,.0f} sections {2 * half_width:g} wide",
               "use a larger STEP (or SPACING, or a smaller HALF_WIDTH)")


def sample_profiles(lines: list[InputLine], mode: str, step: float, surface: Surface | None,
                    contours=None, spacing: float = 0.0, half_width: float = 0.0
                    ) -> list[Profile]:
    """Profiles of every line (``mode`` step / contours) or sections along every line as an
    axis (``mode`` sections)."""
    from toolbox.errors import InputDataError

    out = []
    for line in lines:
        xy, ids = line.xy, (line.line, line.part)
        if not chainage_of_vertices(xy)[-1] > 0:
            raise InputDataError(f"INPUT {line.label} has zero length (every vertex at one "
                                 f"point, {len(xy)} vertices): no profile along it; remove or "
                                 "fix it")
        if mode == "contours":
            geoms, levels = contours
            ch, pts, hs = contour_crossings(xy, geoms, levels)
            out.append(Profile(line.name, *ids, None, 0.0, ch, pts, hs))
        elif mode == "step":
            ch = sample_stations(xy, step)
            pts = points_at(xy, ch)
            out.append(Profile(line.name, *ids, None, 0.0, ch, pts, surface.heights(pts)))
        else:
            for k, (station, ends) in enumerate(section_axes(xy, spacing, half_width), 1):
                d = sample_stations(ends, step)
                pts = points_at(ends, d)
                out.append(Profile(f"{line.name}/{k}", *ids, k, station, d - half_width, pts,
                                   surface.heights(pts)))
    return out


def profile_frames(profiles: list[Profile], crs):
    """(points, lines) GeoDataFrames: PointZ stations with ``line``, ``part``, ``section``,
    ``chainage``, ``distance`` (offset across the axis for sections, negative on the left),
    ``z``; and one LineString Z per profile with its length and height range."""
    import geopandas as gpd
    import shapely

    rows, lines = [], []
    for p in profiles:
        good = np.isfinite(p.z)
        for d, (x, y), z in zip(p.distance, p.xy, p.z):
            rows.append({"profile": p.name, "line": p.line, "part": p.part,
                         "section": p.section, "chainage": p.chainage if p.section else float(d),
                         "distance": float(d), "z": float(z) if np.isfinite(z) else None,
                         "geometry": shapely.points(x, y, z if np.isfinite(z) else np.nan)})
        if good.sum() >= 2:
            xyz = np.column_stack([p.xy[good], p.z[good]])
            lines.append({"profile": p.name, "line": p.line, "part": p.part,
                          "section": p.section, "chainage": p.chainage,
                          "length": float(np.ptp(p.distance[good])),
                          "z_min": float(p.z[good].min()), "z_max": float(p.z[good].max()),
                          "geometry": shapely.linestrings(xyz)})
    cols = ["profile", "line", "part", "section", "chainage", "distance", "z", "geometry"]
    points = gpd.GeoDataFrame(rows or None, columns=cols, geometry="geometry", crs=crs)
    lcols = ["profile", "line", "part", "section", "chainage", "length", "z_min", "z_max",
             "geometry"]
    line_frame = gpd.GeoDataFrame(lines or None, columns=lcols, geometry="geometry", crs=crs)
    return points, line_frame


def layer_title(layer: Any) -> str:
    """A layer's name for a title: the file name (and ``layername``), never a machine path."""
    if layer is None:
        return ""
    path, name = getattr(layer, "path", None), getattr(layer, "layer", None)
    if path is None and getattr(layer, "frame", None) is not None:
        return "the input layer"
    text = str(path if path is not None else layer)
    base, _, options = text.partition("|")
    title = Path(base).name
    name = name or next((o.split("=", 1)[1] for o in options.split("|")
                         if o.startswith("layername=")), None)
    return f"{title} ({name})" if name and name != Path(base).stem else title


def plot_profiles(profiles: list[Profile], path: str | Path, title: str = "",
                  max_panels: int = 12) -> int:
    """Plot profiles (height against distance) to PNG or SVG: one panel per line, or small
    multiples for sections (the first ``max_panels``; the title then says how many of how
    many, and that all are in the GeoPackage). Returns the number of panels drawn."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    shown = profiles[:max_panels]
    if len(shown) < len(profiles):
        what = "sections" if any(p.section for p in profiles) else "profiles"
        note = (f"the first {len(shown)} of {len(profiles)} {what} shown; all are in the "
                "GeoPackage")
        title = f"{title}\n({note})" if title else note
    n = max(len(shown), 1)
    cols = 1 if n == 1 else min(3, n)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.5 * cols if cols > 1 else 9, 2.6 * rows),
                             squeeze=False)
    for ax, p in zip(axes.ravel(), shown):
        ax.plot(p.distance, p.z, "-", color="#8c5a28", lw=1.2)
        ax.plot(p.distance, p.z, ".", color="#8c5a28", ms=3)
        ax.set_title(f"profile {p.name}" + (f" at chainage {p.chainage:.1f} m"
                                             if p.section else ""), fontsize=9)
        ax.set_xlabel("offset from axis (m)" if p.section else "chainage (m)", fontsize=8)
        ax.set_ylabel("height (m)", fontsize=8)
        ax.grid(True, lw=0.3)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(shown):]:
        ax.set_visible(False)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return len(shown)
