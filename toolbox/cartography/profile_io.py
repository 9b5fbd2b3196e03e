"""Profiles and sections from files: polylines, a DEM or a TIN or contour lines; GeoPackage
layers and a plot."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.cartography.profile import (
    bilinear,
    contour_crossings,
    points_at,
    sample_stations,
    section_axes,
)


@dataclass
class Profile:
    """One sampled line: ``name`` (line id, or line/section), stations along it (``distance``,
    from its start), points ``xy`` and heights ``z``; ``chainage`` is the position along the
    axis (the distance itself for profiles, the section's station for sections)."""

    name: str
    line: int
    section: int | None
    chainage: float
    distance: np.ndarray
    xy: np.ndarray
    z: np.ndarray


class Surface:
    """Heights at map points from a DEM (bilinear between cell centres) or a TIN (planes)."""

    def __init__(self, dem=None, band: int = 1, tin=None):
        if dem is not None:
            import rasterio

            from toolbox.cartography.contour_io import GridFrame

            with rasterio.open(dem.path) as src:  # profiles need the whole DEM band in memory
                self.z = src.read(band, masked=True).astype("float64").filled(np.nan)
                self.frame = GridFrame.of(src.transform)
            self.tin = None
        else:
            from toolbox.terrain.tin.store import read_tin

            self.tin = read_tin(tin)[:2]

    def heights(self, xy: np.ndarray) -> np.ndarray:
        if self.tin is not None:
            from toolbox.terrain.tin.kernels import interpolate_tin

            return interpolate_tin(self.tin[0], self.tin[1], xy[:, 0], xy[:, 1])
        f = self.frame
        return bilinear(self.z, f.x0, f.y0, f.dx, f.dy, xy)


def line_parts(frame) -> list[np.ndarray]:
    """Vertices (x, y) of each line of a layer (multi-lines split into their parts)."""
    import shapely

    return [shapely.get_coordinates(p) for g in frame.geometry.values
            for p in shapely.get_parts(g) if not p.is_empty]


def sample_profiles(lines: list[np.ndarray], mode: str, step: float, surface: Surface | None,
                    contours=None, spacing: float = 0.0, half_width: float = 0.0
                    ) -> list[Profile]:
    """Profiles of every line (``mode`` step / contours) or sections along every line as an
    axis (``mode`` sections)."""
    out = []
    for i, xy in enumerate(lines, start=1):
        if mode == "contours":
            geoms, levels = contours
            ch, pts, hs = contour_crossings(xy, geoms, levels)
            out.append(Profile(f"{i}", i, None, 0.0, ch, pts, hs))
        elif mode == "step":
            ch = sample_stations(xy, step)
            pts = points_at(xy, ch)
            out.append(Profile(f"{i}", i, None, 0.0, ch, pts, surface.heights(pts)))
        else:
            for k, (station, ends) in enumerate(section_axes(xy, spacing, half_width), 1):
                d = sample_stations(ends, step)
                pts = points_at(ends, d)
                out.append(Profile(f"{i}/{k}", i, k, station, d - half_width, pts,
                                   surface.heights(pts)))
    return out


def profile_frames(profiles: list[Profile], crs):
    """(points, lines) GeoDataFrames: PointZ stations with ``line``, ``section``, ``chainage``,
    ``distance`` (offset across the axis for sections, negative on the left), ``z``; and one
    LineString Z per profile with its length and height range."""
    import geopandas as gpd
    import shapely

    rows, lines = [], []
    for p in profiles:
        good = np.isfinite(p.z)
        for d, (x, y), z in zip(p.distance, p.xy, p.z):
            rows.append({"profile": p.name, "line": p.line, "section": p.section,
                         "chainage": p.chainage if p.section else float(d),
                         "distance": float(d), "z": float(z) if np.isfinite(z) else None,
                         "geometry": shapely.points(x, y, z if np.isfinite(z) else np.nan)})
        if good.sum() >= 2:
            xyz = np.column_stack([p.xy[good], p.z[good]])
            lines.append({"profile": p.name, "line": p.line, "section": p.section,
                          "chainage": p.chainage, "length": float(np.ptp(p.distance[good])),
                          "z_min": float(p.z[good].min()), "z_max": float(p.z[good].max()),
                          "geometry": shapely.linestrings(xyz)})
    cols = ["profile", "line", "section", "chainage", "distance", "z", "geometry"]
    points = gpd.GeoDataFrame(rows or None, columns=cols, geometry="geometry", crs=crs)
    lcols = ["profile", "line", "section", "chainage", "length", "z_min", "z_max", "geometry"]
    line_frame = gpd.GeoDataFrame(lines or None, columns=lcols, geometry="geometry", crs=crs)
    return points, line_frame


def plot_profiles(profiles: list[Profile], path: str | Path, title: str = "",
                  max_panels: int = 12) -> None:
    """Plot profiles (height against distance) to PNG or SVG: one panel per line, or small
    multiples for sections (the first ``max_panels``)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    shown = profiles[:max_panels]
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
