"""A landscape to photograph: the ground of the demo's Siena block as a map, so that the demo's
photos, orthos and mosaic show things a person recognises and a matcher can match.

Vectors (seeded, deterministic, EPSG:3003) over the sample terrain of :mod:`.terrain`: a town
of street blocks with terracotta row houses around courtyards (its core at the restitution
sheet of :mod:`.restitution`, whose buildings and roads are drawn as plotted), country roads
winding out of it, fields split into parcels (wheat, ploughed soil, grass, vineyards in rows,
olive groves) and woods. They are coloured, rasterised at 1 m, shaded with the DEM's hillshade,
given a fine band-limited grain (:func:`~toolbox.photogrammetry.synthetic.wave_texture`, 4-12 m)
and smoothed at 1.5 m, so a photo rendered from it at the demo's ~1.7 m pixels is free of
aliasing (the ortho tests compare the orthos with this texture to 0.1 px).

Writes ``siena_landscape.gpkg`` (coded layers for the map sheet and for overlaying the orthos,
see :func:`make`); :func:`landscape_texture` is the callable the photos are rendered from.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

CRS = "EPSG:3003"
CELL = 1.0  # m, the texture raster
SEED = 20091104
TOWN_CENTRE = (1688330.0, 4799650.0)  # the restitution sheet is the town's core
TOWN_RADIUS = 330.0
STREET_WIDTH = 8.0
BLOCK = 70.0  # street spacing, m
ROOFS = ((178, 84, 52), (190, 98, 60), (160, 72, 48), (200, 112, 72), (170, 90, 64))
CROPS = {  # name: (colour, stripe amplitude, stripe period m)
    "wheat": ((214, 188, 110), 10, 3.0),
    "ploughed": ((142, 104, 72), 22, 4.0),
    "grass": ((112, 150, 72), 6, 9.0),
    "vineyard": ((120, 126, 70), 34, 5.0),
    "olives": ((150, 140, 100), 28, 7.0),
    "wood": ((52, 86, 44), 12, 11.0),
}


def _extent() -> tuple[float, float, float, float]:
    from toolbox.demo.samples.terrain import terrain

    z, t = terrain()
    return t.c, t.f + z.shape[0] * t.e, t.c + z.shape[1] * t.a, t.f


@functools.cache
def landscape_vectors() -> dict:
    """``{"buildings": [...], "roads": [...], "parcels": [(polygon, crop), ...]}`` (shapely,
    projected)."""
    import shapely
    from shapely import affinity

    from toolbox.demo.samples.restitution import E0, MODELS, N0

    rng = np.random.default_rng(SEED)
    xmin, ymin, xmax, ymax = _extent()
    area = shapely.box(xmin, ymin, xmax, ymax)
    cx, cy = TOWN_CENTRE
    town = shapely.Point(cx, cy).buffer(TOWN_RADIUS, 64)
    town = affinity.scale(town, 1.25, 0.85).intersection(area)
    # the street grid, turned 12 degrees, and roads winding out of town
    angle = 12.0
    streets = []
    for k in np.arange(-8, 9):
        for line in (shapely.LineString([(cx - 700, cy + k * BLOCK), (cx + 700, cy + k * BLOCK)]),
                     shapely.LineString([(cx + k * BLOCK, cy - 700), (cx + k * BLOCK, cy + 700)])):
            streets.append(affinity.rotate(line, angle, origin=(cx, cy)))
    grid = shapely.union_all(streets).intersection(town)
    roads = [grid.buffer(STREET_WIDTH / 2, cap_style="flat")]
    for direction in (15.0, 110.0, 200.0, 290.0):
        t = np.linspace(0, 1200, 80)
        a = np.radians(direction) + 0.25 * np.sin(t / 210.0 + direction)
        xs = cx + np.cumsum(np.cos(a)) * 15.0
        ys = cy + np.cumsum(np.sin(a)) * 15.0
        roads.append(shapely.LineString(np.column_stack([xs, ys])).buffer(3.5))
    plotted_roads = [shapely.LineString([(E0 + x, N0 + y) for x, y, _ in v]).buffer(3.0)
                     for code, _, _, v in MODELS[12] + MODELS[13] if code == "STR02001"
                     and len(v) > 1]
    road_area = shapely.union_all(roads + plotted_roads).intersection(area)
    # town blocks: row houses around a courtyard, cut into units
    buildings = []
    plotted = [shapely.Polygon([(E0 + x, N0 + y) for x, y, _ in v])
               for code, _, _, v in MODELS[12] + MODELS[13] if code == "FAB01002"]
    sheet = shapely.box(E0 - 10, N0 - 10, E0 + 110, N0 + 70)
    blocks = shapely.get_parts(shapely.difference(town, road_area.buffer(1.0)))
    for block in blocks:
        if block.area < 400 or block.intersects(sheet):
            continue
        ring = block.buffer(-1.5).difference(block.buffer(-11.0))
        if ring.is_empty:
            continue
        minx, miny, maxx, maxy = block.bounds
        cuts = []
        for _ in range(int(block.length / 30.0)):
            p = shapely.Point(rng.uniform(minx, maxx), rng.uniform(miny, maxy))
            line = affinity.rotate(shapely.LineString([(p.x - 40, p.y), (p.x + 40, p.y)]),
                                   angle + rng.choice([0.0, 90.0]), origin=p)
            cuts.append(line.buffer(0.4))
        units = ring.difference(shapely.union_all(cuts)) if cuts else ring
        buildings += [u for u in shapely.get_parts(units) if u.area > 40]
    buildings += plotted
    # the countryside: parcels around seeds, each with a crop
    country = area.difference(town).difference(road_area)
    seeds = shapely.multipoints(np.column_stack([rng.uniform(xmin, xmax, 70),
                                                 rng.uniform(ymin, ymax, 70)]))
    parcels = []
    names = list(CROPS)
    for cell in shapely.get_parts(shapely.voronoi_polygons(seeds, extend_to=area)):
        piece = cell.intersection(country).buffer(-2.0)  # field margins
        for part in shapely.get_parts(piece):
            if part.area > 500:
                parcels.append((part, names[int(rng.integers(len(names)))],
                                float(rng.uniform(0, 180))))
    return {"buildings": buildings, "roads": shapely.get_parts(road_area).tolist(),
            "parcels": parcels, "town": town}


@functools.cache
def _landscape_raster() -> tuple[np.ndarray, tuple[float, float]]:
    """(3, rows, cols) float32 colours at 1 m and the raster's (xmin, ymax)."""
    import rasterio.features
    from affine import Affine
    from scipy import ndimage

    from toolbox.demo.samples.terrain import terrain
    from toolbox.photogrammetry.synthetic import wave_texture

    v = landscape_vectors()
    xmin, ymin, xmax, ymax = _extent()
    cols, rows = round((xmax - xmin) / CELL), round((ymax - ymin) / CELL)
    transform = Affine(CELL, 0, xmin, 0, -CELL, ymax)
    xs = xmin + (np.arange(cols) + 0.5) * CELL
    ys = ymax - (np.arange(rows) + 0.5) * CELL
    gx, gy = np.meshgrid(xs, ys)
    rgb = np.empty((3, rows, cols), dtype="float32")
    rgb[:] = np.array([128, 120, 96], dtype="float32")[:, None, None]  # bare ground
    def labels(shapes) -> np.ndarray:
        """1 + the index of the shape covering each cell (the last one drawn wins), 0 = none."""
        return rasterio.features.rasterize(((g, k + 1) for k, g in enumerate(shapes)),
                                           (rows, cols), transform=transform, dtype="int32")

    town = labels([v["town"]]) > 0
    rgb[:, town] = np.array([150, 142, 128], dtype="float32")[:, None]  # yards, squares
    parcel = labels([p for p, _, _ in v["parcels"]])
    inside = parcel > 0
    which = parcel[inside] - 1
    crops = [CROPS[c] for _, c, _ in v["parcels"]]
    colour = np.array([c[0] for c in crops], dtype="float32")[which]
    amplitude = np.array([c[1] for c in crops], dtype="float32")[which]
    period = np.array([c[2] for c in crops], dtype="float32")[which]
    heading = np.radians([h for _, _, h in v["parcels"]])[which]
    shade = 1.0 + 0.08 * np.sin(which * 1.7)
    along = gx[inside] * np.cos(heading) + gy[inside] * np.sin(heading)
    stripes = amplitude * np.sin(2 * np.pi * along / period)
    for b in range(3):
        rgb[b, inside] = colour[:, b] * shade + stripes * (0.6 if b == 2 else 1.0)
    roads = labels(v["roads"]) > 0
    rgb[:, roads] = np.array([96, 96, 98], dtype="float32")[:, None]
    house = labels(v["buildings"])
    roofed = house > 0
    roofs = np.array(ROOFS, dtype="float32")[(house[roofed] - 1) % len(ROOFS)]
    rgb[:, roofed] = roofs.T
    # relief shading from the sample DEM, resampled to 1 m
    z, zt = terrain()
    dzdy, dzdx = np.gradient(z.astype("float64"), zt.a)
    slope = np.arctan(np.hypot(dzdx, dzdy))
    aspect = np.arctan2(-dzdx, dzdy)
    az, alt = np.radians(315.0), np.radians(45.0)
    shade = np.sin(alt) * np.cos(slope) + np.cos(alt) * np.sin(slope) * np.cos(az - aspect)
    zoom = (rows / z.shape[0], cols / z.shape[1])
    shade = ndimage.zoom(shade, zoom, order=1)[:rows, :cols]
    grain = wave_texture(seed=SEED, wavelength=(4.0, 12.0), amplitude=1.0, mean=0.0)(gx, gy)
    factor = (0.55 + 0.6 * shade) * (1.0 + 0.12 * grain)
    rgb *= factor.astype("float32")
    rgb = ndimage.gaussian_filter(rgb, sigma=(0, 1.5 / CELL, 1.5 / CELL))
    return np.clip(rgb, 12, 243), (xmin, ymax)


BUILDING_HEIGHTS = (7.0, 16.0)  # m, eaves of two to five storeys, drawn per building (seeded)
SURFACE_CELL = 1.0  # m, the surface the block's photos are rendered on


def building_heights() -> np.ndarray:
    """Height (m) of each building of :func:`landscape_vectors` above its highest ground."""
    n = len(landscape_vectors()["buildings"])
    return np.random.default_rng(SEED + 2).uniform(*BUILDING_HEIGHTS, n)


@functools.cache
def landscape_surface() -> tuple[np.ndarray, object]:
    """The surface the block's photos see (a DSM): the sample terrain, bilinear at 1 m, with
    every building a flat roof at its highest ground + :func:`building_heights` (vertical
    walls). (rows, cols) float64 and its transform (the terrain's extent)."""
    import rasterio.features
    from affine import Affine
    from scipy import ndimage

    from toolbox.demo.samples.terrain import terrain

    z, t = terrain()
    k = round(abs(t.a) / SURFACE_CELL)
    rows, cols = z.shape[0] * k, z.shape[1] * k
    transform = Affine(SURFACE_CELL, 0, t.c, 0, -SURFACE_CELL, t.f)
    # centres of the fine cells in the coarse grid's index space (cell centres at i + 0.5)
    fine = (np.arange(rows) + 0.5) / k - 0.5, (np.arange(cols) + 0.5) / k - 0.5
    rr, cc = np.meshgrid(*fine, indexing="ij")
    ground = ndimage.map_coordinates(z.astype("float64"), [rr, cc], order=1, mode="nearest")
    houses = landscape_vectors()["buildings"]
    label = rasterio.features.rasterize(((g, i + 1) for i, g in enumerate(houses)),
                                        (rows, cols), transform=transform, dtype="int32")
    base = ndimage.maximum(ground, label, index=np.arange(1, len(houses) + 1))
    roof = np.asarray(base, dtype="float64") + building_heights()
    inside = label > 0
    surface = ground.copy()
    surface[inside] = roof[label[inside] - 1]
    return surface, transform


def landscape_texture():
    """The texture callable ``(X, Y) -> (3,) + X.shape`` (bilinear in the 1 m raster)."""
    from scipy import ndimage

    rgb, (xmin, ymax) = _landscape_raster()

    def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        cols = (np.asarray(x, dtype="float64") - xmin) / CELL - 0.5
        rows = (ymax - np.asarray(y, dtype="float64")) / CELL - 0.5
        return np.stack([ndimage.map_coordinates(band, [rows, cols], order=1, mode="nearest")
                         for band in rgb])

    return texture


def make(folder: Path, made: dict) -> dict:
    """``siena_landscape.gpkg``: the landscape's vectors coded with the demo's code file (the
    restitution's ``siena_codici.txt``): buildings FAB01002, road edges STR02001, grass and
    woods VEG01001, spot heights QUO01001 (PointZ on the DEM at street crossings), and every
    parcel with its crop."""
    import geopandas as gpd
    import shapely

    from toolbox.demo.samples.terrain import sample_heights, terrain
    from toolbox.io.vector_write import write_layers

    v = landscape_vectors()
    edges = [line for road in v["roads"] for line in shapely.get_parts(road.boundary)]
    green = [p for p, crop, _ in v["parcels"] if crop in ("grass", "wood")]
    # spot heights: the street crossings' centres inside town, a few hundred metres apart
    rng = np.random.default_rng(SEED + 1)
    xmin, ymin, xmax, ymax = _extent()
    candidates = np.column_stack([rng.uniform(xmin + 50, xmax - 50, 400),
                                  rng.uniform(ymin + 50, ymax - 50, 400)])
    keep: list[np.ndarray] = []
    for xy in candidates:
        if all(np.hypot(*(xy - k)) > 160.0 for k in keep):
            keep.append(xy)
    spots = np.array(keep)
    z, transform = terrain()
    heights = np.round(sample_heights(z, transform, spots[:, 0], spots[:, 1]), 1)
    path = Path(folder) / "siena_landscape.gpkg"
    if path.exists():
        path.unlink()
    write_layers(path, {
        "buildings": gpd.GeoDataFrame({"code": ["FAB01002"] * len(v["buildings"])},
                                      geometry=v["buildings"], crs=CRS),
        "road_edges": gpd.GeoDataFrame({"code": ["STR02001"] * len(edges)}, geometry=edges,
                                       crs=CRS),
        "green": gpd.GeoDataFrame({"code": ["VEG01001"] * len(green)}, geometry=green, crs=CRS),
        "spot_heights": gpd.GeoDataFrame(
            {"code": ["QUO01001"] * len(spots), "quota": heights},
            geometry=shapely.points(spots[:, 0], spots[:, 1], heights), crs=CRS),
        "parcels": gpd.GeoDataFrame({"crop": [c for _, c, _ in v["parcels"]]},
                                    geometry=[p for p, _, _ in v["parcels"]], crs=CRS)})
    return {"landscape": path}
