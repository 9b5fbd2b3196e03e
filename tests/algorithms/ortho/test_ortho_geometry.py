"""ortho kernels and special geometries: the coordinate map against the photo model, the
distortion bound, flat terrain against rectify:image, occlusion of a building, incidence angle,
the coarser projection DEM."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.ortho.dem import DemSampler
from toolbox.ortho.distortion import BLOCK_EXACT, BLOCK_INTERPOLATED
from toolbox.ortho.heights import heights_on_grid
from toolbox.ortho.sensor import CollinearityMap
from toolbox.photogrammetry.camera import RadialDistortion
from toolbox.photogrammetry.synthetic import (
    box_dsm,
    frame_photo,
    hills_dem,
    render_photo,
    wave_texture,
    write_photo,
)

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402

SIENA_TABLE = ([10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0, 110.0, 120.0, 130.0,
                140.0, 148.0],
               [0.0, 0.1, -0.1, -0.3, -0.5, -0.9, -1.0, -1.1, -0.3, 0.2, 1.2, 1.3, 0.5, -0.4, -1.4])


def tile_heights(z, transform, tile: Affine, shape):
    xs = tile.c + (np.arange(shape[1]) + 0.5) * tile.a
    ys = tile.f + (np.arange(shape[0]) + 0.5) * tile.e
    out = np.empty(shape)
    heights_on_grid(z.astype("float64"), transform.c + 0.5 * transform.a,
                    transform.f + 0.5 * transform.e, transform.a, -transform.e, xs, ys, out)
    return xs, ys, out


@pytest.mark.parametrize("distortion, mode, effect_px", [
    (None, 0, 0.0),
    (RadialDistortion.from_table(SIENA_TABLE[0], np.array(SIENA_TABLE[1]) * 5),
     BLOCK_INTERPOLATED, 0.03),
    (RadialDistortion.from_polynomial(-2e-6), BLOCK_EXACT, 1.0),
    # k3 and decentring (its bound reaches far beyond the frame: exact), decentring alone
    (RadialDistortion.from_polynomial(2e-8, 0.0, 1.5e-17, 2e-7, -1.5e-7), BLOCK_EXACT, 0.1),
    (RadialDistortion.from_polynomial(0.0, p1=2e-7, p2=-1.5e-7), BLOCK_INTERPOLATED, 0.03),
])
def test_coordinate_map_matches_the_photo_model_within_the_bound(distortion, mode, effect_px):
    """Against Photo.ground_to_pixel (the orientation core's per-point kernel): every cell
    within the stated 0.05 px, also where the distortion is blended on the coarse grid."""
    photo = frame_photo(scene.CENTRE, scene.ANGLES, width=2000, height=2000, crs=scene.CRS,
                        principal_distance_mm=153.0, distortion=distortion)
    z, transform = hills_dem(scene.BOUNDS, cell=10.0, relief=200.0, base=250.0, seed=3)
    cmap = CollinearityMap(photo, block=16, tolerance_px=0.05)
    tile = Affine(2.0, 0.0, 1687700.0, 0.0, -2.0, 4799900.0)
    xs, ys, zz = tile_heights(z, transform, tile, (300, 400))
    cols, rows = cmap(tile, zz)
    xx, yy = np.meshgrid(xs, ys)
    ref = photo.ground_to_pixel((xx, yy, zz))
    error = np.hypot(cols - ref[..., 0], rows - ref[..., 1])
    assert np.isfinite(error).all()
    assert error.max() <= 0.05
    modes = np.bincount(cmap.last_modes.ravel(), minlength=3)
    assert modes[mode] > 0.9 * cmap.last_modes.size
    if distortion is not None:  # the distortion matters: ignoring it is visibly wrong
        plain = CollinearityMap(frame_photo(scene.CENTRE, scene.ANGLES, width=2000, height=2000),
                                block=16)(tile, zz)
        assert np.hypot(plain[0] - ref[..., 0], plain[1] - ref[..., 1]).max() > effect_px


def hilly_scene(distortion, folder: Path):
    """A photo over a DEM with 200 m of relief and a nodata hole, and an output grid reaching
    off the DEM and off the photo: (photo, grid, DemSampler, CollinearityMap)."""
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.plan import lattice_grid

    photo = frame_photo(scene.CENTRE, scene.ANGLES, width=2000, height=2000, crs=scene.CRS,
                        principal_distance_mm=153.0, distortion=distortion)
    z, transform = hills_dem(scene.BOUNDS, cell=10.0, relief=200.0, base=250.0, seed=3)
    z[40:60, 100:130] = np.nan  # a nodata hole
    info = open_raster_info(scene.write_dem(folder / "d.tif", z.astype("float32"), transform))
    b = scene.BOUNDS
    grid = lattice_grid((b[0] - 300.0, b[1] + 500.0, b[2] - 900.0, b[3] + 200.0), 2.5, scene.CRS)
    return photo, grid, DemSampler(info, grid.crs), CollinearityMap(photo, block=32)


@pytest.mark.parametrize("distortion", [None, RadialDistortion.from_table(*SIENA_TABLE)])
def test_fused_window_kernel_equals_heights_then_map(distortion, tmp_path):
    """OrthoWindows' one-pass kernel (heights + map + statistics, strip by strip) against the
    separate DemSampler.heights + CollinearityMap.project on the same windows of a DEM with
    200 m of relief: the same coordinates bit for bit; the counts, box and largest relief
    displacement of the report against the test's own count of those arrays, also on windows
    partly off the DEM (NaN heights) and off the photo."""
    from toolbox.ortho.kernels import RELIEF_ROWS
    from toolbox.ortho.metrics import relief_displacement
    from toolbox.ortho.windows import OrthoWindows

    photo, grid, sampler, cmap = hilly_scene(distortion, tmp_path)
    job = OrthoWindows(photo, grid, sampler, cmap, 300.0)
    from toolbox.raster.tile import iter_tiles

    windows = [t.window for t in iter_tiles(grid, 300)]
    seen = []
    for window in windows:
        assert job.plan(window) is None  # no resampling given: not planned
        cols, rows, box = job.measured(window)
        fused = job.statistics(window)
        xs, ys = grid.cell_centers(window)
        zz = sampler.heights(xs, ys)
        c2, r2, modes, _ = cmap.project(grid.window_transform(window), zz)
        assert np.array_equal(cols, c2, equal_nan=True)
        assert np.array_equal(rows, r2, equal_nan=True)
        have = np.isfinite(c2)
        inside = have & (c2 >= 0) & (c2 <= 2000) & (r2 >= 0) & (r2 <= 2000)
        assert box == ((float(c2.min()), float(r2.min()), float(c2.max()), float(r2.max()))
                       if have.all() else None)
        assert (fused.cells, fused.outside_dem, fused.outside_photo, fused.hidden) == (
            zz.size, np.isnan(zz).sum(), (have & ~inside).sum(), 0)
        every = slice(None, None, RELIEF_ROWS)
        relief = relief_displacement(xs[None, :], ys[every, None], zz[every], job.centre,
                                     300.0)[inside[every]]
        relief = relief[np.isfinite(relief)]
        assert fused.max_relief_m == pytest.approx(relief.max() if relief.size else 0.0,
                                                   rel=1e-12)
        assert fused.blocks == dict(enumerate(np.bincount(modes.ravel(), minlength=3).tolist()))
        seen.append((fused.outside_dem > 0, fused.outside_photo > 0, box is not None))
    assert np.any(seen, axis=0).all() and not np.all(seen, axis=0).any()  # every case met


def test_points_behind_the_camera_and_nan_heights_have_no_image():
    photo = frame_photo((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), width=100, height=100)
    z = np.array([[50.0, np.nan], [150.0, 50.0]])
    cols, _ = CollinearityMap(photo)(Affine(1.0, 0, -1.0, 0, -1.0, 1.0), z)
    assert np.isfinite(cols[0, 0]) and np.isfinite(cols[1, 1])
    assert np.isnan(cols[0, 1]) and np.isnan(cols[1, 0])


def test_dem_sampler_is_bilinear_between_centres_and_coarsens_on_a_fixed_lattice(tmp_path):
    from toolbox.io.raster import open_raster_info

    rng = np.random.default_rng(1)
    z = rng.uniform(100, 200, (40, 50)).astype("float32")
    transform = Affine(5.0, 0, 1000.0, 0, -5.0, 2000.0)
    dem = scene.write_dem(tmp_path / "d.tif", z, transform)
    info = open_raster_info(dem)
    xs = np.array([1002.5, 1010.0, 1013.75])
    ys = np.array([1997.5, 1990.0])
    got = DemSampler(info).heights(xs, ys)
    from scipy.interpolate import RegularGridInterpolator

    xc = 1002.5 + 5.0 * np.arange(50)
    yc = 1997.5 - 5.0 * np.arange(40)
    ref = RegularGridInterpolator((yc[::-1], xc), z[::-1].astype(float))
    xx, yy = np.meshgrid(xs, ys)
    assert got == pytest.approx(ref(np.column_stack([yy.ravel(), xx.ravel()])).reshape(2, 3),
                                abs=1e-9)
    coarse = DemSampler(info, factor=2).heights(np.array([1005.0]), np.array([1995.0]))
    assert coarse[0, 0] == pytest.approx(z[:2, :2].mean(), abs=1e-4)  # centre of a 2 x 2 block
    outside = DemSampler(info).heights(np.array([900.0]), np.array([1995.0]))
    assert np.isnan(outside[0, 0])


def test_flat_terrain_equals_rectify_image_with_the_equivalent_homography(tmp_path):
    """On a flat DEM the ortho is a plane rectification: rectify:estimate from exact control
    points on the plane + rectify:image on the same grid give the same raster."""
    bounds = (1686800.0, 4797800.0, 1689600.0, 4800600.0)
    z, transform = hills_dem(bounds, cell=20.0, relief=1.0, base=300.0)
    z[:] = 300.0
    photo = frame_photo((1688200.0, 4799200.0, 1300.0), (0.03, -0.02, 0.2), width=500,
                        height=500, crs=scene.CRS)
    texture = wave_texture(seed=2, wavelength=(30.0, 90.0))
    photo_path = write_photo(tmp_path / "flat.tif", render_photo(photo, z, transform, texture,
                                                                 dtype="uint8"))
    dem = scene.write_dem(tmp_path / "flat_dem.tif", z, transform)
    project = tmp_path / "flat.yaml"
    import yaml

    project.write_text(yaml.safe_dump({
        "crs": scene.CRS, "cameras": [{"name": "c", "principal_distance_mm": 153.0,
                                       "image_size_px": [500, 500], "pixel_size_mm": 0.46}],
        "photos": [{"id": "flat", "camera": "c", "exterior": dict(zip(
            ("X0", "Y0", "Z0", "omega", "phi", "kappa"),
            [1688200.0, 4799200.0, 1300.0, 0.03, -0.02, 0.2], strict=True))}]}))
    px = np.array([[c, r] for c in (40.0, 180.0, 320.0, 460.0) for r in (50.0, 250.0, 450.0)])
    ground = photo.pixel_to_ground(px, 300.0)
    gcps = tmp_path / "gcps.csv"
    with open(gcps, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "col", "row", "X", "Y", "role"])
        for k, ((c, r), g) in enumerate(zip(px, ground, strict=True)):
            writer.writerow([f"g{k}", c, r, repr(float(g[0])), repr(float(g[1])), "control"])
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": scene.CRS, "MODEL": "homography",
                                     "ROBUST": "none", "OUTPUT": tmp_path / "t.json"})
    stats = toolbox.run("ortho:photo", {"INPUT": photo_path, "PROJECT": project, "DEM": dem,
                                        "CELL_SIZE": 2.0, "OUTPUT": tmp_path / "ortho.tif"}
                        )["STATISTICS"]
    extent = ",".join(str(v) for v in stats["bounds"])
    toolbox.run("rectify:image", {"INPUT": photo_path, "TRANSFORM": tmp_path / "t.json",
                                  "CELL_SIZE": 2.0, "EXTENT": extent,
                                  "OUTPUT": tmp_path / "rect.tif"})
    with rasterio.open(tmp_path / "ortho.tif") as a, rasterio.open(tmp_path / "rect.tif") as b:
        assert a.transform == b.transform and a.shape == b.shape
        da, db = a.read().astype(int), b.read().astype(int)
    both = (da[1] == 255) & (db[1] == 255)
    assert both.sum() > 0.5 * both.size
    assert (da[1] != db[1]).mean() < 0.005  # the same footprint up to its edge cells
    diff = np.abs(da[0] - db[0])[both]
    assert diff.mean() < 0.3 and np.percentile(diff, 99.9) <= 2
    # and the flat ortho is the texture (a homography is right on flat ground)
    xs = a.transform.c + (np.arange(da.shape[2]) + 0.5) * 2.0
    ys = a.transform.f - (np.arange(da.shape[1]) + 0.5) * 2.0
    truth = texture(*np.meshgrid(xs, ys))
    assert np.abs(da[0] - truth)[both].mean() < 1.5


BUILDING = (1000.0, 2000.0, 1060.0, 2050.0, 40.0)  # xmin, ymin, xmax, ymax, height above ground
GROUND = 300.0
CAMERA = (900.0, 1930.0, 800.0)  # 500 m above the ground, ~150 m south-west of the building


def hidden_truth(xs, ys):
    """Ground cells whose line of sight to the camera passes through the box (slab method)."""
    x0, y0, x1, y1, height = BUILDING
    xx, yy = np.meshgrid(xs, ys)
    p = np.stack([xx, yy, np.full_like(xx, GROUND)], axis=-1)
    d = np.asarray(CAMERA) - p
    lo = np.zeros(xx.shape)
    hi = np.ones(xx.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, (a, b) in enumerate(((x0, x1), (y0, y1), (GROUND, GROUND + height))):
            t1 = (a - p[..., k]) / d[..., k]
            t2 = (b - p[..., k]) / d[..., k]
            lo = np.maximum(lo, np.minimum(t1, t2))
            hi = np.minimum(hi, np.maximum(t1, t2))
    inside = (xx > x0) & (xx < x1) & (yy > y0) & (yy < y1)
    return (lo < hi) & (hi > 1e-9) & ~inside


# the building scene's local metres (x 900-1160, y 1900-2150) are far outside EPSG:3003's area
# of use, which the DEM check now refuses: a local transverse Mercator without one
LOCAL_CRS = "+proj=tmerc +lat_0=0 +lon_0=9 +k=1 +x_0=0 +y_0=0 +ellps=GRS80 +units=m +no_defs"


def building_scene(tmp_path, cell_size=1.0):
    """ortho:photo's parameters for the photo of the building (OUTPUT excluded)."""
    dsm, transform = box_dsm((900.0, 1900.0, 1160.0, 2150.0), 1.0, GROUND, [BUILDING])
    photo = frame_photo(CAMERA, (0.0, 0.0, 0.0), width=480, height=480, crs=LOCAL_CRS,
                        principal_distance_mm=60.0, pixel_size_mm=0.1)
    texture = wave_texture(seed=5, wavelength=(8.0, 30.0))
    image = write_photo(tmp_path / "b.tif", render_photo(photo, dsm, transform, texture,
                                                         dtype="uint8"))
    dem = scene.write_dem(tmp_path / "dsm.tif", dsm, transform, crs=LOCAL_CRS)
    camera = tmp_path / "cam.yaml"
    camera.write_text("name: c\nprincipal_distance_mm: 60.0\npixel_size_mm: 0.1\n")
    return {"INPUT": image, "CAMERA": camera, "CRS": LOCAL_CRS, "DEM": dem,
            "CELL_SIZE": cell_size, "EXTENT": "960,1960,1100,2100",
            "EXTERIOR": ",".join(map(str, [*CAMERA, 0.0, 0.0, 0.0]))}


def test_occlusion_mask_is_the_hidden_ground_of_a_building(tmp_path):
    common = building_scene(tmp_path)
    stats = toolbox.run("ortho:photo", {**common, "OCCLUSION": True,
                                        "OCCLUSION_MASK": tmp_path / "mask.tif",
                                        "INCIDENCE": tmp_path / "inc.tif",
                                        "OUTPUT": tmp_path / "true.tif"})["STATISTICS"]
    toolbox.run("ortho:photo", {**common, "OUTPUT": tmp_path / "plain.tif"})
    with rasterio.open(tmp_path / "mask.tif") as src:
        mask = src.read(1)
        t = src.transform
        # written by the RasterWriter: tiled, compressed, on the ortho's grid
        assert src.profile["tiled"] and src.block_shapes == [(512, 512)]
        assert src.compression.name == "deflate" and src.nodata == 255
        assert src.dtypes == ("uint8",) and src.crs is not None
    xs = t.c + (np.arange(mask.shape[1]) + 0.5) * t.a
    ys = t.f + (np.arange(mask.shape[0]) + 0.5) * t.e
    truth = hidden_truth(xs, ys)
    assert 400 < truth.sum() < 3000
    from scipy.ndimage import distance_transform_edt

    edge = np.where(truth, distance_transform_edt(truth), distance_transform_edt(~truth))
    wrong = (mask == 1) != truth
    assert not (wrong & (edge > 2.0)).any()  # disagreements only at the shadow's rim
    assert abs(int((mask == 1).sum()) - int(truth.sum())) < 0.1 * truth.sum()
    assert stats["hidden_fraction"] == pytest.approx((mask == 1).mean())
    with rasterio.open(tmp_path / "true.tif") as a, rasterio.open(tmp_path / "plain.tif") as b:
        alpha_true, alpha_plain = a.read(2), b.read(2)
    core = truth & (edge > 2.0)
    assert (alpha_true[core] == 0).all()  # left empty in the true ortho ...
    assert (alpha_plain[core] == 255).all()  # ... double-mapped (the roof again) without it
    with rasterio.open(tmp_path / "inc.tif") as src:
        incidence = src.read(1)
        assert src.profile["tiled"] and src.compression.name == "deflate"
        assert src.dtypes == ("float32",) and np.isnan(src.nodata)
        assert src.tags(ns="IMAGE_STRUCTURE").get("PREDICTOR") == "3"
        assert src.transform == t
    # flat ground far from the building: the angle between the ray and the vertical
    j, i = 5, mask.shape[0] - 5
    ray = np.asarray(CAMERA) - np.array([xs[j], ys[i], GROUND])
    expected = np.degrees(np.arccos(ray[2] / np.linalg.norm(ray)))
    assert incidence[i, j] == pytest.approx(expected, abs=0.01)


def test_occlusion_mask_and_angles_have_overviews_of_their_kind(tmp_path):
    """A 560 x 560 mask and angle raster get the ortho's overviews (one level): the mask's by
    nearest (its classes only, each overview cell one of the full-resolution cells it covers),
    the angles' by average (within the range of the four cells)."""
    common = building_scene(tmp_path, cell_size=0.25)
    toolbox.run("ortho:photo", {**common, "OCCLUSION": True, "OCCLUSION_MASK": tmp_path / "m.tif",
                                "INCIDENCE": tmp_path / "i.tif", "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "m.tif") as src:
        assert (src.width, src.height) == (560, 560) and src.overviews(1) == [2]
        assert src.tags(ns="rio_overview")["resampling"] == "nearest"
        mask = src.read(1)
        small = src.read(1, out_shape=(280, 280))  # the overview
    assert set(np.unique(mask)) == {0, 1} and (mask == 1).sum() > 1000
    quads = mask.reshape(280, 2, 280, 2).transpose(0, 2, 1, 3).reshape(280, 280, 4)
    assert (quads == small[..., None]).any(axis=-1).all()
    with rasterio.open(tmp_path / "i.tif") as src:
        assert src.overviews(1) == [2]
        angles = src.read(1)
        small = src.read(1, out_shape=(280, 280))
    quads = angles.reshape(280, 2, 280, 2).transpose(0, 2, 1, 3).reshape(280, 280, 4)
    assert (small >= quads.min(-1) - 1e-4).all() and (small <= quads.max(-1) + 1e-4).all()
    np.testing.assert_allclose(small, quads.mean(-1), atol=1e-3)


def test_dem_in_another_crs_lattice_transform_matches_pyproj(tmp_path):
    """Cell centres go to the DEM's CRS through a pyproj lattice + bilinear interpolation: the
    heights DemSampler gives equal scipy's bilinear interpolation of the DEM at the cell
    centres transformed by pyproj on every cell (within the slope x 0.02 m the lattice may
    move a point)."""
    from pyproj import Transformer
    from scipy.interpolate import RegularGridInterpolator

    from toolbox.io.raster import open_raster_info

    z, transform = hills_dem((2268000.0, 4798000.0, 2272000.0, 4802000.0), 20.0, seed=1)
    info = open_raster_info(scene.write_dem(tmp_path / "d3004.tif", z, transform, "EPSG:3004"))
    sampler = DemSampler(info, "EPSG:3003")
    xs = 1735500.0 + np.arange(150) * 3.0  # (on the DEM: 3003 is about 533 km west of 3004)
    ys = 4799500.0 - np.arange(130) * 3.0
    got = sampler.heights(xs, ys)
    xx, yy = np.meshgrid(xs, ys)
    ex, ey = Transformer.from_crs("EPSG:3003", "EPSG:3004", always_xy=True).transform(xx, yy)
    cx = transform.c + (np.arange(z.shape[1]) + 0.5) * transform.a
    cy = transform.f + (np.arange(z.shape[0]) + 0.5) * transform.e
    bilinear = RegularGridInterpolator((cy[::-1], cx), np.asarray(z, "float64")[::-1],
                                       bounds_error=False, fill_value=np.nan)
    expected = bilinear(np.column_stack([ey.ravel(), ex.ravel()])).reshape(got.shape)
    assert np.isfinite(expected).all() and np.isfinite(got).all()
    both = np.isfinite(got)
    slope = max(np.abs(np.gradient(np.asarray(z, "float64"), 20.0)).max(), 1e-3)
    assert np.abs(got - expected)[both].max() < 0.02 * slope * 1.5 + 1e-6


def test_sky_blocks_skip_free_ground_without_changing_the_mask():
    """Rays that jump over DSM blocks lower than themselves hide exactly the cells a plain
    half-cell march hides (block maxima at +inf disable the jumps)."""
    from toolbox.ortho.visibility import hidden_cells, visibility_mask
    from toolbox.photogrammetry.surface import DemSurface

    z, t = hills_dem((0.0, 0.0, 1000.0, 1000.0), 5.0, relief=200.0, seed=4)
    z[100:106, 80:90] += 60.0  # a tower
    surface = DemSurface.from_transform(z.astype("float64"), t)
    xs = np.arange(50.0, 950.0, 4.0) + 0.5
    ys = np.arange(950.0, 50.0, -4.0) - 0.5
    _, _, heights = tile_heights(z, t, Affine(4.0, 0, 50.0, 0, -4.0, 950.0), (225, 225))
    centre = np.array([450.0, 550.0, 700.0])
    fast = visibility_mask(xs, ys, heights, centre, surface)
    plain = np.zeros(heights.shape, dtype=np.uint8)
    hidden_cells(xs, ys, heights, centre, surface.z, surface.x0, surface.y0, 5.0, 5.0,
                 surface.z_range[1], 0.05, np.full((1000, 1000), np.inf), 8, plain)
    assert plain.sum() > 20 and (fast == plain).all()


@pytest.mark.parametrize("distortion", [
    None, RadialDistortion.from_table(*SIENA_TABLE),
    RadialDistortion.from_polynomial(-2e-6)])  # strong: its blocks are computed exactly
def test_planned_maps_are_the_shifted_maps_blanked_outside_the_photo(distortion, tmp_path):
    """A planned window (OrthoWindows with a resampling) against the unplanned one: the plan's
    source window holds every image point inside the photo with the bilinear margin (the
    bound is conservative, with 200 m of relief and the distortion), its maps are the
    unplanned coordinates minus the plan's shift (to float32 rounding), OUTSIDE exactly on
    the cells outside the photo or without image point (but for cells within rounding of the
    edge), and the statistics are the same."""
    from toolbox.ortho.windows import OrthoWindows
    from toolbox.raster.maps import OUTSIDE
    from toolbox.raster.tile import iter_tiles

    photo, grid, sampler, cmap = hilly_scene(distortion, tmp_path)
    plain = OrthoWindows(photo, grid, sampler, cmap, 300.0)
    planned = OrthoWindows(photo, grid, sampler, cmap, 300.0, resampling="bilinear")
    kinds = set()
    for window in [t.window for t in iter_tiles(grid, 300)]:
        cols, rows, _ = plain.measured(window)
        plan = planned.plan(window)
        assert plan is not None
        mx, my = planned.planned_maps(plan)
        assert planned.statistics(window) == plain.statistics(window)
        inside = (cols >= 0) & (cols <= 2000) & (rows >= 0) & (rows <= 2000)
        edge = np.isfinite(cols) & (np.minimum(np.abs(cols - np.round(cols / 2000) * 2000),
                                               np.abs(rows - np.round(rows / 2000) * 2000))
                                    < 1e-3)
        blank = mx == OUTSIDE
        assert (blank == (my == OUTSIDE)).all() and (blank != inside)[~edge].all()
        if plan.window is None or blank.all():
            assert blank.all()
            kinds.add("empty")
            continue
        kinds.add("all inside" if inside.all() else "partly")
        got_c, got_r = mx[~blank] + plan.shift_col, my[~blank] + plan.shift_row
        assert np.abs(got_c - cols[~blank]).max() < 2e-3
        assert np.abs(got_r - rows[~blank]).max() < 2e-3
        w = plan.window  # every sample and its bilinear neighbours are in the window read
        assert got_c.min() - 0.5 - 1 >= w.col_off - plan.pads[2]
        assert got_r.min() - 0.5 - 1 >= w.row_off - plan.pads[0]
        assert got_c.max() - 0.5 + 1 <= w.col_off + w.width - 1 + plan.pads[3]
        assert got_r.max() - 0.5 + 1 <= w.row_off + w.height - 1 + plan.pads[1]
    assert {"all inside", "partly"} <= kinds


@pytest.mark.parametrize("distortion, blended", [
    # 2.5 x the Siena table: about half the blocks at the bound, the other half blended
    (RadialDistortion.from_table(SIENA_TABLE[0], np.array(SIENA_TABLE[1]) * 2.5), True),
    (RadialDistortion.from_polynomial(-2e-6), False)])  # strong: every block exact
def test_block_modes_from_the_dem_bound_the_map_within_the_tolerance(distortion, blended,
                                                                     tmp_path):
    """The block modes of a window's one-pass map come from its DEM part, not from its cells
    (block_modes_on_dem): never more permissive than the modes from the cells (block_modes on
    the distortion-free map), NaN nodes and blocks off the DEM exact; the final map, blended
    where they allow it, is the photo model's own projection of the same heights within the
    stated 0.05 px (photo.ground_to_pixel, independent of the kernels)."""
    from toolbox.ortho.distortion import block_modes
    from toolbox.ortho.windows import OrthoWindows
    from toolbox.raster.tile import iter_tiles

    photo, grid, sampler, cmap = hilly_scene(distortion, tmp_path)  # blocks of 32, 0.05 px
    plain = CollinearityMap(frame_photo(scene.CENTRE, scene.ANGLES, width=2000, height=2000,
                                        crs=scene.CRS, principal_distance_mm=153.0), block=32)
    job = OrthoWindows(photo, grid, sampler, cmap, 300.0)
    model = cmap.model
    counts = np.zeros(3, dtype=int)
    for window in [t.window for t in iter_tiles(grid, 300)]:
        xs, ys = grid.cell_centers(window)
        part = sampler.part(xs, ys)
        if part is None:
            continue
        transform = grid.window_transform(window)
        cols, rows, modes, _, z = cmap.project_on_dem(transform, xs, ys, part, job.centre, 300.0,
                                                      keep_heights=True)
        free_c, free_r, _, _, _ = plain.project_on_dem(transform, xs, ys, part, job.centre, 300.0)
        from_cells = block_modes(free_c, free_r, 32, model.lipschitz * model.f2p_condition, 0.05)
        assert not ((modes == BLOCK_INTERPOLATED) & (from_cells != BLOCK_INTERPOLATED)).any()
        counts += np.bincount(modes.ravel(), minlength=3)
        ref = photo.ground_to_pixel((np.broadcast_to(xs, z.shape),
                                     np.broadcast_to(ys[:, None], z.shape), z), behind="nan")
        have = np.isfinite(ref[..., 0])
        assert (np.isfinite(cols) == have).all()
        error = np.hypot(cols - ref[..., 0], rows - ref[..., 1])[have]
        assert error.size == 0 or error.max() <= 0.05
    if blended:
        assert counts[BLOCK_INTERPOLATED] > 0.3 * counts.sum() and counts[BLOCK_EXACT] > 0
    else:
        assert counts[BLOCK_INTERPOLATED] == 0
