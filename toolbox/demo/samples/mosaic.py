"""Synthetic orthophotos with known truth, for the mosaic tests, bench and demo.

Every ortho samples one ground texture (smooth, 3 bands, values 20-235, never 0) on a 1 m grid;
a flat-roofed "building" appears with its roof displaced radially from each ortho's nadir point
(relief displacement ``Δ = k·(P − N)``, ``k = h/H``); between its base and the roof each ortho
sees a different facade (its own colour, with window stripes).
The nadir point is written in the tags ``NADIR_X``/``NADIR_Y``. Odd orthos mark missing data with
nodata 0, even ones with an alpha band.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

ORIGIN = (1688000.0, 4799000.0)  # Siena-like projected coordinates (EPSG:3003)
CRS = "EPSG:3003"
ROOF = (245.0, 240.0, 228.0)
WALLS = ((60.0, 52.0, 48.0), (150.0, 128.0, 110.0), (95.0, 110.0, 125.0))  # per ortho, cycled


def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ground texture ``(3, rows, cols)`` at local coordinates ``x``, ``y`` (m), 20-235."""
    base = (50 * np.sin(x / 23.0) * np.cos(y / 17.0) + 30 * np.sin((x + y) / 41.0)
            + 15 * np.sin(x / 3.1 + y / 5.3))
    return np.stack([128 + base, 120 + 0.8 * base, 110 + 0.6 * base]).clip(20, 235)


@dataclass
class SyntheticOrtho:
    path: Path
    nadir: tuple[float, float]  # projected coordinates
    bounds: tuple[float, float, float, float]  # valid data, projected
    roof: object  # shapely polygon of the displaced roof, projected


def make_block(folder: Path, specs: list[dict], building=(500.0, 200.0, 20.0),
               displacement: float = 0.1, cell: float = 1.0) -> tuple[list[SyntheticOrtho], object]:
    """Write one ortho per spec ``{"name", "bounds": (x0, y0, x1, y1) local m, "nadir": (x, y)
    local m, optional "gain", "offset", "valid": (x0, y0, x1, y1)}``; returns the orthos and the
    building's ground footprint (projected). ``building`` = (x, y, half side), local m."""
    import rasterio
    import shapely
    from affine import Affine
    from rasterio.enums import ColorInterp

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    ox, oy = ORIGIN
    bx, by, hs = building
    footprint = shapely.box(bx - hs, by - hs, bx + hs, by + hs)
    out = []
    for k, spec in enumerate(specs):
        x0, y0, x1, y1 = spec["bounds"]
        nx, ny = spec["nadir"]
        cols, rows = round((x1 - x0) / cell), round((y1 - y0) / cell)
        xs = x0 + (np.arange(cols) + 0.5) * cell
        ys = y1 - (np.arange(rows) + 0.5) * cell
        gx, gy = np.meshgrid(xs, ys)
        image = texture(gx, gy)
        dx, dy = displacement * (bx - nx), displacement * (by - ny)
        roof = shapely.affinity.translate(footprint, dx, dy)
        in_base = shapely.contains_xy(footprint, gx, gy)
        in_roof = shapely.contains_xy(roof, gx, gy)
        stripes = 1.0 + 0.25 * (np.floor(gx / 3.0) % 2)
        for b in range(3):
            image[b][in_base] = (WALLS[k % len(WALLS)][b] * stripes)[in_base]
            image[b][in_roof] = ROOF[b]
        image = spec.get("gain", 1.0) * image + spec.get("offset", 0.0)
        data = np.clip(np.rint(image), 1, 255).astype("uint8")
        vx0, vy0, vx1, vy1 = spec.get("valid", spec["bounds"])
        valid = (gx >= vx0) & (gx <= vx1) & (gy >= vy0) & (gy <= vy1)
        transform = Affine(cell, 0, ox + x0, 0, -cell, oy + y1)
        path = folder / f"{spec['name']}.tif"
        alpha = k % 2 == 1
        profile = {"driver": "GTiff", "width": cols, "height": rows, "count": 4 if alpha else 3,
                   "dtype": "uint8", "crs": CRS, "transform": transform, "tiled": True,
                   "blockxsize": 256, "blockysize": 256, "compress": "deflate",
                   "nodata": None if alpha else 0}
        with rasterio.open(path, "w", **profile) as dst:
            data[:, ~valid] = 0
            if alpha:
                dst.write(np.concatenate([data, (valid * 255).astype("uint8")[None]]))
                dst.colorinterp = [ColorInterp.red, ColorInterp.green, ColorInterp.blue,
                                   ColorInterp.alpha]
            else:
                dst.write(data)
            dst.update_tags(NADIR_X=f"{ox + nx:.3f}", NADIR_Y=f"{oy + ny:.3f}")
        out.append(SyntheticOrtho(path, (ox + nx, oy + ny),
                                  (ox + vx0, oy + vy0, ox + vx1, oy + vy1),
                                  shapely.affinity.translate(roof, ox, oy)))
    return out, shapely.affinity.translate(footprint, ox, oy)


def pair_specs(gain: float = 1.0, offset: float = 0.0) -> list[dict]:
    """Two orthos side by side, overlapping over x 400-600 m; nadir points 500 m apart, so the
    Voronoi seam is the line x = 500 m, through the building."""
    return [
        {"name": "ortho_a", "bounds": (0, 0, 620, 400), "valid": (0, 0, 600, 400),
         "nadir": (250, 200)},
        {"name": "ortho_b", "bounds": (400, 0, 1000, 400), "valid": (400, 10, 1000, 400),
         "nadir": (750, 200), "gain": gain, "offset": offset},
    ]


def make(folder: Path, made: dict) -> dict:
    """Demo orthos: three 300 x 260 m orthos (1 m cells) in a row with 100 m overlaps."""
    specs = [{"name": f"mosaic_ortho_{k + 1}", "bounds": (200 * k, 0, 200 * k + 300, 260),
              "nadir": (200 * k + 150, 130), "gain": (1.0, 1.08, 0.95)[k],
              "offset": (0.0, -6.0, 5.0)[k]} for k in range(3)]
    orthos, _ = make_block(Path(folder) / "mosaic", specs, building=(250.0, 130.0, 12.0))
    return {f"mosaic_ortho_{k + 1}": o.path for k, o in enumerate(orthos)}
