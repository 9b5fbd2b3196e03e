"""rectify:image and the windowed warp kernel: the rectified raster matches the ideal one
(correlation, sub-pixel blob positions), the pixel convention holds exactly (nearest), the fast
and generic paths agree, bands/types/masks, bounded windows, oblique photos, GCP output."""

import json
import math

import numpy as np
import pytest
import rasterio
import rectify_scene as scene
from affine import Affine
from rasterio.windows import Window

import toolbox
from toolbox.errors import CanceledError, InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.io.grid import GridSpec
from toolbox.raster.homography import HomographyMap
from toolbox.raster.resample import inside_mask
from toolbox.raster.warp import warp_to_geotiff
from toolbox.transforms.rectification import default_cell_size, footprint, parse_pixel_to_image

pytestmark = pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")

G2P = scene.ground_to_pixel()
P2G = np.linalg.inv(G2P) / np.linalg.inv(G2P)[2, 2]


def transform_json(path, matrix=P2G, units="pixels", crs="EPSG:3003", points=()):
    """A transform file as rectify:estimate writes it (matrix: image -> ground)."""
    from pyproj import CRS

    doc = {"format": "toolbox.rectify.transform", "version": 1, "model": "homography",
           "image_units": units, "image_to_ground": np.asarray(matrix).tolist(),
           "crs": None if crs is None else CRS.from_user_input(crs).to_wkt(),
           "points": list(points)}
    path.write_text(json.dumps(doc))
    return path


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    """Float photo, its exact transform estimated from noise-free GCPs (through the algorithm)."""
    folder = tmp_path_factory.mktemp("rectify_scene")
    return folder, *scene.photo_and_transform(folder, "float32")


def gdal_valid(path) -> np.ndarray:
    """The cells GDAL takes as valid (its dataset mask: alpha band or nodata)."""
    with rasterio.open(path) as ds:
        return ds.dataset_mask() > 0


def cell_centres(path):
    with rasterio.open(path) as ds:
        t, w, h = ds.transform, ds.width, ds.height
        data = ds.read()
    x = t.c + (np.arange(w) + 0.5) * t.a
    y = t.f + (np.arange(h) + 0.5) * t.e
    xx, yy = np.meshgrid(x, y)
    return data, xx, yy, t


def blob_offsets(values, xx, yy, transform):
    """Centroid of each blob (output minus the blob-free texture) minus its true position, in
    output pixels (col, row)."""
    residual = values - scene.texture(xx, yy, with_blobs=False)
    cell = transform.a
    out = []
    for bx, by in scene.blobs():
        jc = (bx - transform.c) / cell - 0.5
        ic = (transform.f - by) / -transform.e - 0.5
        half = int(np.ceil(5 * scene.BLOB_SIGMA / cell))
        j0, i0 = int(round(jc)) - half, int(round(ic)) - half
        patch = residual[i0:i0 + 2 * half + 1, j0:j0 + 2 * half + 1]
        jj, ii = np.meshgrid(np.arange(j0, j0 + patch.shape[1]), np.arange(i0, i0 + patch.shape[0]))
        weight = patch.sum()
        out.append(((jj * patch).sum() / weight - jc, (ii * patch).sum() / weight - ic))
    return np.array(out)


@pytest.mark.parametrize("resampling, min_corr, max_shift", [
    ("bilinear", 0.999, 0.1), ("cubic", 0.9995, 0.05), ("lanczos", 0.9995, 0.05)])
def test_rectified_matches_ideal(scene_files, tmp_path, resampling, min_corr, max_shift):
    folder, photo, transform = scene_files
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                        "CELL_SIZE": 0.25, "RESAMPLING": resampling,
                                        "OUTPUT": tmp_path / "r.tif"})
    data, xx, yy, t = cell_centres(out["OUTPUT"])
    assert data.shape[0] == 1  # a float photo: no alpha band (GDAL masks only Byte/UInt16 alpha)
    ideal = scene.texture(xx, yy)
    inside = gdal_valid(out["OUTPUT"])
    assert np.array_equal(inside, np.isfinite(data[0]))  # NaN outside, GDAL's mask agrees
    assert inside.mean() > 0.4
    # compare away from the footprint edge (interpolation needs neighbours there)
    from scipy.ndimage import binary_erosion

    core = binary_erosion(inside, iterations=8)
    corr = np.corrcoef(data[0][core], ideal[core])[0, 1]
    assert corr > min_corr
    assert np.abs(data[0][core] - ideal[core]).mean() < 2.0  # of a 250..1250 range
    # sub-pixel position: every blob where it belongs, to max_shift *source* pixels (~0.55 m);
    # an off-by-half-pixel source convention would move them by 0.5
    gsd = default_cell_size(P2G, scene.WIDTH, scene.HEIGHT)
    offsets = blob_offsets(data[0], xx, yy, t) * 0.25 / gsd
    assert np.abs(offsets).max() < max_shift
    stats = out["STATISTICS"]
    assert stats["cell_size"] == 0.25 and stats["crs"] == "EPSG:3003"
    with rasterio.open(out["OUTPUT"]) as ds:
        assert ds.crs.to_epsg() == 3003 and np.isnan(ds.nodata)
        assert ds.overviews(1) and ds.block_shapes[0] == (512, 512)


def test_nearest_follows_the_pixel_convention_exactly(scene_files, tmp_path):
    """Each output cell takes the photo pixel containing the source point of its centre, with
    pixel (i, j) covering [j, j+1) x [i, i+1) (centres at +0.5)."""
    folder, photo, transform = scene_files
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                        "CELL_SIZE": 0.3, "RESAMPLING": "nearest",
                                        "OUTPUT": tmp_path / "n.tif"})
    data, xx, yy, _ = cell_centres(out["OUTPUT"])
    src = scene.apply(G2P, np.column_stack([xx.ravel(), yy.ravel()]))
    col, row = src[:, 0].reshape(xx.shape), src[:, 1].reshape(xx.shape)
    inside = (col >= 0) & (col <= scene.WIDTH) & (row >= 0) & (row <= scene.HEIGHT)
    # cells whose centre maps within 1e-3 px of a pixel edge could go either way
    frac_c, frac_r = col % 1, row % 1
    clear = inside & (np.minimum(frac_c, 1 - frac_c) > 1e-3) & (np.minimum(frac_r, 1 - frac_r) > 1e-3)
    clear &= (col < scene.WIDTH - 1e-3) & (row < scene.HEIGHT - 1e-3)
    with rasterio.open(photo) as ds:
        image = ds.read(1)
    expected = image[np.floor(row[clear]).astype(int), np.floor(col[clear]).astype(int)]
    np.testing.assert_array_equal(data[0][clear], expected)
    # the valid cells (GDAL's mask of the NaN nodata) are exactly the "centre maps into the
    # photo" rule
    ambiguous = inside ^ clear
    assert np.array_equal(gdal_valid(out["OUTPUT"])[~ambiguous], inside[~ambiguous])


def test_fast_and_generic_paths_agree(tmp_path):
    photo = scene.write_photo(tmp_path / "p.tif", scene.photo(3, "uint8"))
    grid = GridSpec.from_bounds(tuple(footprint(P2G, scene.WIDTH, scene.HEIGHT).min(axis=0))
                                + tuple(footprint(P2G, scene.WIDTH, scene.HEIGHT).max(axis=0)),
                                0.4, "EPSG:3003")
    cmap = HomographyMap(G2P, grid.transform, front=tuple(scene.blobs()[0]))
    results = []
    for fast in (True, False):
        path = tmp_path / f"o{fast}.tif"
        warp_to_geotiff(photo, cmap, grid, path, "cubic", chunk=256, overviews=False, fast=fast)
        with rasterio.open(path) as ds:
            results.append(ds.read().astype(int))
    fast_out, generic = results
    assert np.array_equal(fast_out[3], generic[3])  # identical footprint
    diff = np.abs(fast_out[:3] - generic[:3])
    assert diff.max() <= 1 and (diff > 0).mean() < 0.01


def test_inside_intervals_equal_the_coordinate_test():
    t = Affine(0.37, 0, 1687950.0, 0, -0.37, 4799720.0)
    cmap = HomographyMap(G2P, t, front=tuple(scene.blobs()[0]))
    for window in (Window(0, 0, 700, 650), Window(123, 77, 301, 259), Window(560, 450, 90, 80),
                   Window(0, 500, 200, 150)):
        cols, rows = cmap(window)
        by_coordinates = inside_mask(cols, rows, scene.WIDTH, scene.HEIGHT)
        by_intervals = cmap.inside(window, scene.WIDTH, scene.HEIGHT)
        assert (by_coordinates != by_intervals).sum() <= 2  # float32 ties at the very edge
        assert by_intervals.any()


def test_window_splitting_and_small_chunks_give_the_same_raster(tmp_path):
    photo = scene.write_photo(tmp_path / "p.tif", scene.photo(1, "uint16"))
    grid = GridSpec.from_bounds((1687990.0, 4799520.0, 1688150.0, 4799680.0), 0.5, "EPSG:3003")
    cmap = HomographyMap(G2P, grid.transform, front=tuple(scene.blobs()[0]))
    warp_to_geotiff(photo, cmap, grid, tmp_path / "a.tif", overviews=False)
    stats = warp_to_geotiff(photo, cmap, grid, tmp_path / "b.tif", chunk=128,
                            max_source_pixels=2000, overviews=False)
    assert stats.split_windows > 0 and stats.windows > 4
    with rasterio.open(tmp_path / "a.tif") as a, rasterio.open(tmp_path / "b.tif") as b:
        one, other = a.read().astype(int), b.read().astype(int)
    assert np.array_equal(one[1], other[1])  # the same footprint
    # OpenCV rounds each window's coordinates to 1/32 pixel: at most 1 unit apart, rarely
    assert np.abs(one[0] - other[0]).max() <= 1 and (one[0] != other[0]).mean() < 0.02
    # a bounded window never read more than the limit
    assert stats.source_pixels_read < stats.windows * 2000


@pytest.mark.parametrize("bands, dtype, suffix", [(3, "uint16", ".png"), (1, "uint8", ".tif"),
                                                  (5, "float32", ".tif"), (3, "uint8", ".jpg")])
def test_bands_types_and_formats(tmp_path, bands, dtype, suffix, scene_files):
    _, _, transform = scene_files
    data = scene.photo(bands, dtype)
    photo = scene.write_photo(tmp_path / f"p{suffix}", data)
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                        "CELL_SIZE": 1.0, "OUTSIDE": "nodata",
                                        "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert ds.count == bands and ds.dtypes[0] == dtype
        arr = ds.read()
        nodata = ds.nodata
    expected_nodata = 0 if dtype != "float32" else None
    if expected_nodata is None:
        assert np.isnan(nodata) and np.isnan(arr[0]).any()
    else:
        assert nodata == 0
    # band k is band 0 + 50·k in the photo (scaled for uint8): the offsets survive the warp
    valid = np.isfinite(arr[0].astype(float)) & (arr[0] != 0)
    if bands > 1:
        step = 50.0 / (4.0 if dtype == "uint8" else 1.0)
        diff = arr[1].astype(float)[valid] - arr[0].astype(float)[valid]
        tol = 4.0 if suffix == ".jpg" else 1.0
        assert np.abs(np.median(diff) - step) <= tol


def test_source_nodata_and_alpha_are_honoured(tmp_path, scene_files):
    _, _, transform = scene_files
    data = scene.photo(1, "uint8")
    data[0, 100:140, 150:250] = 0  # a hole (nodata) in the photo
    photo = scene.write_photo(tmp_path / "hole.tif", data, nodata=0)
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                        "CELL_SIZE": 0.5, "OUTPUT": tmp_path / "o.tif"})
    data_out, xx, yy, _ = cell_centres(out["OUTPUT"])
    src = scene.apply(G2P, np.column_stack([xx.ravel(), yy.ravel()]))
    col, row = src[:, 0].reshape(xx.shape), src[:, 1].reshape(xx.shape)
    in_hole = (col > 151) & (col < 249) & (row > 101) & (row < 139)
    assert in_hole.sum() > 100 and np.all(data_out[1][in_hole] == 0)
    well_inside = (col > 5) & (col < 395) & (row > 5) & (row < 95)
    assert np.all(data_out[1][well_inside] == 255)
    # RGBA photo: the output alpha is the photo's alpha, resampled
    rgba = np.concatenate([scene.photo(3, "uint8"), np.full((1, scene.HEIGHT, scene.WIDTH), 255,
                                                            np.uint8)])
    rgba[3, :, :200] = 0
    photo = scene.write_photo(tmp_path / "rgba.png", rgba)
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                        "CELL_SIZE": 0.5, "RESAMPLING": "nearest",
                                        "OUTPUT": tmp_path / "rgba.tif"})
    data_out, _, _, _ = cell_centres(out["OUTPUT"])
    assert data_out.shape[0] == 4
    left = (col > 2) & (col < 198) & (row > 2) & (row < 298)
    right = (col > 202) & (col < 398) & (row > 2) & (row < 298)
    assert np.all(data_out[3][left] == 0) and np.all(data_out[3][right] == 255)


def test_image_mm_transform_with_interior_orientation(tmp_path, scene_files):
    """A transform in image mm plus the pixel -> mm matrix gives the pixel transform's raster."""
    folder, photo, transform = scene_files
    p2mm = np.array([[scene.PIXEL_MM, 0, -scene.WIDTH / 2 * scene.PIXEL_MM],
                     [0, -scene.PIXEL_MM, scene.HEIGHT / 2 * scene.PIXEL_MM], [0, 0, 1]])
    mm_to_ground = P2G @ np.linalg.inv(p2mm)
    mm_json = transform_json(tmp_path / "mm.json", mm_to_ground, "mm")
    text = " ".join(repr(float(v)) for v in p2mm[:2].ravel())
    a = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": mm_json, "PIXEL_TO_IMAGE": text,
                                      "CELL_SIZE": 0.5, "OUTPUT": tmp_path / "mm.tif"})
    b = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform_json(
        tmp_path / "px.json"), "CELL_SIZE": 0.5, "OUTPUT": tmp_path / "px.tif"})
    with rasterio.open(a["OUTPUT"]) as ra, rasterio.open(b["OUTPUT"]) as rb:
        assert ra.transform == rb.transform
        assert np.allclose(ra.read(), rb.read(), atol=1e-2, equal_nan=True)
    with pytest.raises(ParameterError, match="PIXEL_TO_IMAGE is required"):
        toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": mm_json,
                                      "OUTPUT": tmp_path / "x.tif"})
    with pytest.raises(ParameterError, match="PIXEL_TO_IMAGE does not apply"):
        toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                      "PIXEL_TO_IMAGE": text, "OUTPUT": tmp_path / "x.tif"})
    with pytest.raises(ParameterError, match="PIXEL_TO_IMAGE must be 6 or 8 numbers"):
        parse_pixel_to_image("1 2 3")


def test_default_cell_size_and_footprint():
    # ground size of a photo pixel at the centre: 0.1 mm at 1:5000, stretched by the tilt
    size = default_cell_size(P2G, scene.WIDTH, scene.HEIGHT)
    assert 0.5 < size < 0.6
    corners = footprint(P2G, scene.WIDTH, scene.HEIGHT)
    np.testing.assert_allclose(scene.apply(G2P, corners),
                               [[0, 0], [400, 0], [400, 300], [0, 300]], atol=1e-6)


def test_oblique_photo_with_the_horizon(tmp_path):
    """ω = 1.45 rad: the horizon is in the photo. The default extent is refused; with EXTENT
    the ground beyond the vanishing line (behind the camera) stays transparent."""
    tilts = (1.45, 0.0, 0.0)
    g2p = scene.ground_to_pixel(tilts)
    p2g = np.linalg.inv(g2p)
    photo = scene.write_photo(tmp_path / "p.tif", scene.photo(1, "uint8", tilts))
    tj = transform_json(tmp_path / "t.json", p2g / p2g[2, 2])
    with pytest.raises(InputDataError, match="vanishing line crosses the photo"):
        toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tj,
                                      "OUTPUT": tmp_path / "x.tif"})
    x0, y0 = scene.ORIGIN
    feedback = Feedback()
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tj, "CELL_SIZE": 20,
                                        "EXTENT": f"{x0 - 3000},{y0 - 3000},{x0 + 3000},{y0 + 9000}",
                                        "OUTPUT": tmp_path / "o.tif"}, feedback=feedback)
    assert any("vanishing line" in w for w in feedback.warnings)
    data, xx, yy, _ = cell_centres(out["OUTPUT"])
    p = np.column_stack([xx.ravel(), yy.ravel(), np.ones(xx.size)]) @ g2p.T
    w = p[:, 2].reshape(xx.shape) * np.sign(
        (g2p @ [x0, y0 + 800, 1])[2])  # a ground point in view has w > 0
    behind = w < 0
    assert behind.any() and np.all(data[1][behind] == 0)
    assert (data[1] > 0).sum() > 100  # the ground in view is rectified
    col = p[:, 0].reshape(xx.shape) / p[:, 2].reshape(xx.shape)
    assert np.all((data[1] > 0) <= ~behind)
    assert np.isfinite(col).all()


def test_gcp_mode_embeds_control_points(tmp_path, scene_files):
    folder, photo, _ = scene_files
    ids, image, ground, roles = scene.gcp_table(10, checks=("G03",))
    gcps = scene.write_gcp_csv(tmp_path / "g.csv", ids, image, ground, roles)
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003",
                                     "OUTPUT": tmp_path / "t.json"})
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "t.json",
                                        "MODE": "gcps", "OUTPUT": tmp_path / "g.tif"})
    assert out["STATISTICS"]["gcps"] == 9 and "G03" not in out["STATISTICS"]["gcp_ids"]
    with rasterio.open(out["OUTPUT"]) as ds, rasterio.open(photo) as src:
        points, crs = ds.gcps
        assert crs.to_epsg() == 3003 and len(points) == 9
        first = points[0]
        assert (first.col, first.row) == pytest.approx(tuple(image[0]))
        assert (first.x, first.y) == pytest.approx(tuple(ground[0]))
        assert np.array_equal(ds.read(), src.read())
        assert "RECTIFY_PIXEL_TO_GROUND" in ds.tags()
    with pytest.raises(ParameterError, match="CELL_SIZE does not apply with MODE=gcps"):
        toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "t.json",
                                      "MODE": "gcps", "CELL_SIZE": 1,
                                      "OUTPUT": tmp_path / "h.tif"})


def test_cancel_leaves_no_output(tmp_path, scene_files):
    _, photo, transform = scene_files
    feedback = Feedback(lambda pct, msg: feedback.cancel() if pct > 5 else None)
    with pytest.raises(CanceledError):
        toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 0.1,
                                      "OUTPUT": tmp_path / "c.tif"}, feedback=feedback)
    assert not (tmp_path / "c.tif").exists()


def test_extent_in_another_crs_is_converted(tmp_path, scene_files, caplog):
    """An EXTENT in another CRS than the transform's is taken as its bounding box in the
    transform's CRS (pyproj's transform_bounds, the conversion of QGIS and gdalwarp -te_srs),
    with a warning naming it; it was refused."""
    from pyproj import Transformer

    _, photo, transform = scene_files
    first = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                          "CELL_SIZE": 0.5, "OUTPUT": tmp_path / "a.tif"})
    with rasterio.open(first["OUTPUT"]) as src:
        b = src.bounds
    inner = (b.left + 2, b.bottom + 2, b.right - 2, b.top - 2)
    utm = Transformer.from_crs("EPSG:3003", "EPSG:32632", always_xy=True).transform_bounds(*inner)
    truth = Transformer.from_crs("EPSG:32632", "EPSG:3003", always_xy=True).transform_bounds(
        *utm, densify_pts=21)
    toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 0.5,
                                  "EXTENT": ",".join(f"{v:.3f}" for v in utm) + " [EPSG:32632]",
                                  "OUTPUT": tmp_path / "x.tif"})
    with rasterio.open(tmp_path / "x.tif") as src:
        assert src.crs.to_epsg() == 3003
        assert src.transform.c == pytest.approx(truth[0], abs=1e-2)
        assert src.transform.f == pytest.approx(truth[3], abs=1e-2)
        assert src.width == math.ceil((truth[2] - truth[0]) / 0.5)  # whole cells, outwards
    assert any("EXTENT is in EPSG:32632: taken as its bounding box in EPSG:3003" in r.message
               for r in caplog.records)


def test_cli_run(tmp_path, scene_files):
    from conftest import run_cli

    _, photo, transform = scene_files
    proc = run_cli("run", "rectify:image", "--INPUT", photo, "--TRANSFORM", transform,
                   "--CELL_SIZE", "1", "--RESAMPLING", "cubic", "--OUTPUT", tmp_path / "cli.tif")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["STATISTICS"]["resampling"] == "cubic"
    proc = run_cli("run", "rectify:image", "--INPUT", photo, "--TRANSFORM", transform,
                   "--RESAMPLING", "spline", "--OUTPUT", tmp_path / "cli2.tif")
    assert proc.returncode == 2
    assert "RESAMPLING must be one of nearest, bilinear, cubic, lanczos" in proc.stderr


def test_facade_in_a_local_object_system(tmp_path):
    """A facade: ground = metres on the wall (0..40 x 0..25), no CRS; the output GeoTIFF has
    the facade grid and no CRS."""
    facade_to_pixel = np.array([[9.0, 1.2, 20.0], [0.4, -8.5, 260.0], [0.004, 0.0015, 1.0]])
    p2f = np.linalg.inv(facade_to_pixel)
    p2f /= p2f[2, 2]
    rng = np.random.default_rng(2)
    wall = np.column_stack([rng.uniform(1, 39, 8), rng.uniform(1, 24, 8)])
    image = scene.apply(facade_to_pixel, wall)
    gcps = scene.write_gcp_csv(tmp_path / "facade.csv", [f"F{i}" for i in range(8)], image, wall,
                               ["control"] * 8)
    est = toolbox.run("rectify:estimate", {"INPUT": gcps, "OUTPUT": tmp_path / "f.json"})
    assert est["STATISTICS"]["crs"] == "none" and est["STATISTICS"]["sigma0"] < 1e-6
    photo = scene.write_photo(tmp_path / "wall.png", scene.photo(1, "uint8"))
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "f.json",
                                        "CELL_SIZE": 0.05, "EXTENT": "0,0,40,25",
                                        "OUTPUT": tmp_path / "f.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert ds.crs is None and ds.bounds == (0.0, 0.0, 40.0, 25.0)
        assert (ds.width, ds.height) == (800, 500)
        assert (ds.read(2) > 0).mean() > 0.5
    assert out["STATISTICS"]["crs"] == "none"


def test_extent_is_honoured_and_cog_is_valid(tmp_path, scene_files):
    """An EXTENT off the cell lattice keeps its origin (xmin/ymax); COG=true writes a valid
    Cloud Optimized GeoTIFF (the float band with NaN nodata, with overviews)."""
    from toolbox.raster.writer import cog_problems

    _, photo, transform = scene_files
    x0, y0 = 1688000.3, 4799520.7
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 0.2,
                                        "EXTENT": f"{x0},{y0},{x0 + 150.1},{y0 + 110}",
                                        "COG": True, "OUTPUT": tmp_path / "cog.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert (ds.transform.c, ds.transform.f) == (x0, y0 + 110)
        assert (ds.width, ds.height) == (751, 550)  # 150.1 m -> 751 cells: the east edge rounds up
        assert ds.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG" and ds.overviews(1) == [2]
        assert ds.count == 1 and np.isnan(ds.nodata) and ds.dataset_mask().any()
    assert cog_problems(out["OUTPUT"]) == []
