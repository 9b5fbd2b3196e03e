"""Sample TIN inputs over the sample terrain (EPSG:3003): 3D breaklines, a clip boundary with a
hole, and check points, all with heights taken from the sample DEM (so their truth is known).

- ``tin_breaklines``: the two edges of a road (LineStringZ, vertices every 10 m) and a stream
  line that crosses the road without a shared vertex (tin:delaunay splits it there);
- ``tin_boundary``: a concave survey boundary with a hole (a pond), inside the terrain;
- ``tin_check_points``: 200 PointZ check points inside the boundary (heights from the DEM) for
  tin:interpolate.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolbox.demo.samples.terrain import CELL, CRS, XMIN, YMAX, sample_heights, terrain


def _densify(xy: np.ndarray, step: float) -> np.ndarray:
    """Vertices every ``step`` map units along a polyline (its own vertices kept)."""
    out = [xy[:1]]
    for a, b in zip(xy[:-1], xy[1:], strict=True):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        t = np.arange(1, n + 1)[:, None] / n
        out.append(a + t * (b - a))
    return np.vstack(out)


def make(folder: Path, made: dict) -> dict:
    import geopandas as gpd
    import shapely

    from toolbox.io.vector_write import write_layers

    z, transform = terrain()
    rows, cols = z.shape
    x0, y0 = XMIN + 20 * CELL, YMAX - 20 * CELL  # stay inside the DEM's cell centres
    x1, y1 = XMIN + (cols - 20) * CELL, YMAX - (rows - 20) * CELL

    def height(xy: np.ndarray) -> np.ndarray:
        return np.round(sample_heights(z, transform, xy[:, 0], xy[:, 1]), 3)

    axis = np.array([[x0 + 50, y1 + 300], [x0 + 600, y1 + 520], [x1 - 300, y0 - 420],
                     [x1 - 40, y0 - 380]])
    normal = np.array([-(axis[-1, 1] - axis[0, 1]), axis[-1, 0] - axis[0, 0]])
    normal /= np.hypot(*normal)
    stream = np.array([[x0 + 400, y0 - 60], [x0 + 560, y0 - 500], [x0 + 820, y1 + 120],
                       [x0 + 900, y1 + 40]])
    lines, kinds = [], []
    for xy, kind in ((_densify(axis + 4.0 * normal, 10.0), "road edge"),
                     (_densify(axis - 4.0 * normal, 10.0), "road edge"),
                     (_densify(stream, 10.0), "stream")):
        lines.append(shapely.linestrings(xy[:, 0], xy[:, 1], height(xy)))
        kinds.append(kind)
    breaklines = gpd.GeoDataFrame({"kind": kinds}, geometry=lines, crs=CRS)
    outer = [(x0 + 100, y1 + 100), (x1 - 150, y1 + 60), (x1 - 100, y0 - 500),
             (x0 + 900, y0 - 350), (x0 + 700, y0 - 80), (x0 + 60, y0 - 150)]
    pond = [(x0 + 1000, y1 + 250), (x0 + 1150, y1 + 240), (x0 + 1120, y1 + 380),
            (x0 + 990, y1 + 360)]
    area = shapely.Polygon(outer, [pond])
    boundary = gpd.GeoDataFrame({"name": ["survey area"]}, geometry=[area], crs=CRS)
    rng = np.random.default_rng(55)
    xy = np.column_stack([rng.uniform(x0, x1, 1000), rng.uniform(y1, y0, 1000)])
    xy = xy[shapely.contains_xy(area, xy[:, 0], xy[:, 1])][:200]
    checks = gpd.GeoDataFrame({"id": np.arange(1, len(xy) + 1)},
                              geometry=shapely.points(xy[:, 0], xy[:, 1], height(xy)), crs=CRS)
    paths = {}
    for name, frame in (("tin_breaklines", breaklines), ("tin_boundary", boundary),
                        ("tin_check_points", checks)):
        path = folder / f"{name}.gpkg"
        if path.exists():
            path.unlink()
        write_layers(path, {name.removeprefix("tin_"): frame})
        paths[name] = path
    return paths
