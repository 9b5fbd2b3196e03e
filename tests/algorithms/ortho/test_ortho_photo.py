"""ortho:photo on synthetic photos with a known truth.

The photos are rendered by ray marching from the camera down to the DEM
(:func:`toolbox.photogrammetry.synthetic.render_photo`), the orthos are compared with the texture
itself at the output cell centres, and positions are measured with scikit-image's phase
correlation (an independent oracle). The terrain has 200 m of relief, so the relief displacement
corrected reaches ~35 photo pixels: a flat plane or a DEM 40 m too high must fail the checks.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.errors import InputDataError, ParameterError

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402

CELL = 2.5
PATCH = 64


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    return scene.make_scene(tmp_path_factory.mktemp("ortho_scene"))


def run_ortho(sc, out: Path, dem=None, **extra):
    params = {"INPUT": sc.photo_path, "PROJECT": sc.project_path, "DEM": dem or sc.dem_path,
              "CELL_SIZE": CELL, "OUTPUT": out, **extra}
    return toolbox.run("ortho:photo", params, overwrite=True)


def read_with_truth(path: Path, texture):
    with rasterio.open(path) as src:
        data = src.read()
        t = src.transform
    xs = t.c + (np.arange(data.shape[2]) + 0.5) * t.a
    ys = t.f + (np.arange(data.shape[1]) + 0.5) * t.e
    xx, yy = np.meshgrid(xs, ys)
    return data, texture(xx, yy), t


def patch_positions(ortho: np.ndarray, valid: np.ndarray, truth: np.ndarray):
    """Phase-correlation shift (px) and normalised correlation of every fully valid patch."""
    from skimage.registration import phase_cross_correlation

    results = []
    h, w = ortho.shape
    for i0 in range(0, h - PATCH, PATCH):
        for j0 in range(0, w - PATCH, PATCH):
            p = (slice(i0, i0 + PATCH), slice(j0, j0 + PATCH))
            if not valid[p].all():
                continue
            shift, _, _ = phase_cross_correlation(truth[p], ortho[p].astype("float64"),
                                                  upsample_factor=100, normalization=None)
            ncc = np.corrcoef(truth[p].ravel(), ortho[p].ravel())[0, 1]
            results.append((float(np.hypot(*shift)), float(ncc)))
    return np.array(results)


def test_texture_recovered_on_every_patch(block, tmp_path):
    out = run_ortho(block, tmp_path / "ortho.tif", REPORT=tmp_path / "r.json")
    data, truth, t = read_with_truth(tmp_path / "ortho.tif", block.texture)
    assert data.shape[0] == 2 and t.a == CELL  # grey + alpha
    valid = data[1] == 255
    patches = patch_positions(data[0], valid, truth)
    assert len(patches) >= 80
    assert patches[:, 0].max() <= 0.1, patches[:, 0].max()
    assert patches[:, 1].min() > 0.99
    # the grid sits on the lattice of the cell; the report states what was corrected
    assert t.c % CELL == 0 and t.f % CELL == 0
    report = json.loads((tmp_path / "r.json").read_text())["photos"][0]
    assert report == json.loads(json.dumps(out["STATISTICS"]))
    assert 25 < report["max_relief_displacement_px"] < 60
    assert report["map_blocks"]["projective_exact"] > 0
    assert report["outside_dem_fraction"] == 0.0
    assert report["photo_gsd_m"] == pytest.approx(2.5, abs=0.1)


def test_scheduler_local_is_not_overridden_by_the_environment(block, tmp_path, monkeypatch):
    """SCHEDULER local runs the ortho's windows on local threads: a DASK_SCHEDULER_ADDRESS
    naming no cluster (nothing listens on port 9) is not contacted, and the ortho equals a run
    without the variable (issue 31)."""
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    run_ortho(block, tmp_path / "plain.tif", CELL_SIZE=10.0, OVERVIEWS=False)
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")
    run_ortho(block, tmp_path / "env.tif", CELL_SIZE=10.0, OVERVIEWS=False, SCHEDULER="local")
    with rasterio.open(tmp_path / "plain.tif") as a, rasterio.open(tmp_path / "env.tif") as b:
        first, second = a.read(), b.read()
    assert first[-1].max() == 255 and (first == second).all()  # alpha: the photo is there


def test_flat_plane_instead_of_dem_is_wrong(block, tmp_path):
    """Rectifying on a plane at the mean height (what a homography does) leaves the relief
    displacement: most patches are off by more than a pixel."""
    flat = block.dem * 0 + float(block.dem.mean())
    dem = scene.write_dem(tmp_path / "flat.tif", flat, block.transform)
    run_ortho(block, tmp_path / "flat_ortho.tif", dem=dem)
    data, truth, _ = read_with_truth(tmp_path / "flat_ortho.tif", block.texture)
    patches = patch_positions(data[0], data[1] == 255, truth)
    assert np.median(patches[:, 0]) > 1.0
    assert (patches[:, 0] <= 0.1).mean() < 0.1


def test_dem_40m_too_high_fails_the_position_check(block, tmp_path):
    dem = scene.write_dem(tmp_path / "high.tif", block.dem + 40.0, block.transform)
    run_ortho(block, tmp_path / "high_ortho.tif", dem=dem)
    data, truth, _ = read_with_truth(tmp_path / "high_ortho.tif", block.texture)
    patches = patch_positions(data[0], data[1] == 255, truth)
    assert patches[:, 0].max() > 2.0
    assert (patches[:, 0] > 0.1).mean() > 0.8


def test_dem_in_another_crs_gives_the_same_ortho(block, tmp_path):
    """The DEM reprojected to Monte Mario zone 2 (same datum): heights are taken in the DEM's
    own grid after transforming the cell centres with pyproj."""
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    with rasterio.open(block.dem_path) as src:
        transform, w, h = calculate_default_transform(src.crs, "EPSG:3004", src.width,
                                                      src.height, *src.bounds)
        z = np.full((h, w), -9999.0, dtype="float32")
        reproject(rasterio.band(src, 1), z, dst_transform=transform, dst_crs="EPSG:3004",
                  resampling=Resampling.cubic, dst_nodata=-9999.0)
    dem = scene.write_dem(tmp_path / "dem_3004.tif", np.where(z == -9999.0, np.nan, z)
                          .astype("float32"), transform, "EPSG:3004")
    out = run_ortho(block, tmp_path / "o3004.tif", dem=dem)
    assert out["STATISTICS"]["crs"] == "EPSG:3003"
    data, truth, _ = read_with_truth(tmp_path / "o3004.tif", block.texture)
    patches = patch_positions(data[0], data[1] == 255, truth)
    assert len(patches) >= 40
    assert np.median(patches[:, 0]) <= 0.1
    assert patches[:, 1].min() > 0.99


def test_dem_not_covering_leaves_cells_empty_and_counted(block, tmp_path):
    half = block.dem[:, : block.dem.shape[1] // 2]
    dem = scene.write_dem(tmp_path / "half.tif", half, block.transform)
    feedback = toolbox.Feedback()
    params = {"INPUT": block.photo_path, "PROJECT": block.project_path, "DEM": dem,
              "CELL_SIZE": CELL, "OUTPUT": tmp_path / "half_ortho.tif",
              "EXTENT": "1687200,4798200,1689200,4800200"}
    stats = toolbox.run("ortho:photo", params, feedback=feedback)["STATISTICS"]
    assert 0.3 < stats["outside_dem_fraction"] < 0.7
    assert any("no DEM height" in w for w in feedback.warnings)
    data, truth, t = read_with_truth(tmp_path / "half_ortho.tif", block.texture)
    xs = t.c + (np.arange(data.shape[2]) + 0.5) * t.a
    # beyond the DEM's outer cell edge (its outer half cell holds the edge heights, as gdalwarp)
    east = xs > block.transform.c + half.shape[1] * block.transform.a
    assert (data[1][:, east] == 0).all()  # never invented
    assert (data[1][:, ~east] == 255).any(axis=0).all()  # up to that edge


@pytest.mark.parametrize("change, message", [
    ({"angles": (3.0, 0.0, 0.0)}, "looks away"),
    ({"centre": (1688200.0, 4799200.0, 200.0)}, "not above the terrain"),
])
def test_impossible_geometry_is_refused(block, tmp_path, change, message):
    project = scene.project_yaml(tmp_path / "bad.yaml", str(block.photo_path),
                                 change.get("centre", scene.CENTRE),
                                 change.get("angles", scene.ANGLES))
    with pytest.raises(InputDataError, match=message):
        toolbox.run("ortho:photo", {"INPUT": block.photo_path, "PROJECT": project,
                                    "DEM": block.dem_path, "OUTPUT": tmp_path / "bad.tif"})
    assert not (tmp_path / "bad.tif").exists()


def test_photo_size_must_match_the_camera(block, tmp_path):
    from toolbox.photogrammetry.synthetic import write_photo

    small = write_photo(tmp_path / "p1.tif", np.zeros((400, 400), dtype="uint8"))
    with pytest.raises(InputDataError, match="400 x 400 px but the camera"):
        toolbox.run("ortho:photo", {"INPUT": small, "PROJECT": block.project_path, "PHOTO": "p1",
                                    "DEM": block.dem_path, "OUTPUT": tmp_path / "o.tif"})
    assert not (tmp_path / "o.tif").exists()


def test_degrees_dem_without_crs_is_refused(block, tmp_path):
    from affine import Affine

    from toolbox.raster.writer import write_raster

    dem = tmp_path / "deg.tif"
    write_raster(dem, block.dem, Affine(0.0001, 0, 11.3, 0, -0.0001, 43.33), None,
                 nodata=-9999.0)
    with pytest.raises(InputDataError, match="geographic degrees"):
        run_ortho(block, tmp_path / "o.tif", dem=dem)


def test_camera_and_exterior_with_tens_of_degrees_warn(block, tmp_path):
    """A vertical photo with omega = 20 (taken as degrees) gets a unit warning; CAMERA +
    EXTERIOR is the same photo as the project's when the angles are right."""
    camera = tmp_path / "camera.yaml"
    camera.write_text("name: synthetic\nprincipal_distance_mm: 153.0\npixel_size_mm: 0.2875\n")
    exterior = ",".join(str(float(v)) for v in [*scene.CENTRE, *np.degrees(scene.ANGLES)])
    feedback = toolbox.Feedback()
    stats = toolbox.run("ortho:photo", {"INPUT": block.photo_path, "CAMERA": camera,
                                        "EXTERIOR": exterior, "ANGLE_UNIT": "deg",
                                        "CRS": "EPSG:3003", "DEM": block.dem_path,
                                        "CELL_SIZE": 5.0, "OUTPUT": tmp_path / "c.tif"},
                        feedback=feedback)["STATISTICS"]
    assert not feedback.warnings and stats["cell_size"] == 5.0
    # the same pixel -> image transform given as orientation:interior's matrix
    s = 230.0 / scene.SIZE
    p2i = f"{s} 0 {-s * scene.SIZE / 2} 0 {-s} {s * scene.SIZE / 2}"
    toolbox.run("ortho:photo", {"INPUT": block.photo_path, "CAMERA": camera,
                                "EXTERIOR": exterior, "ANGLE_UNIT": "deg", "PIXEL_TO_IMAGE": p2i,
                                "CRS": "EPSG:3003", "DEM": block.dem_path, "CELL_SIZE": 5.0,
                                "OUTPUT": tmp_path / "c2.tif"})
    with rasterio.open(tmp_path / "c.tif") as a, rasterio.open(tmp_path / "c2.tif") as b:
        assert np.abs(a.read().astype(int) - b.read().astype(int)).max() <= 1
    # 20 rad (degrees' numbers) as the same rotation within a turn: beyond a full turn an
    # angle is refused (round 16, datums), 20 - 6 pi = 1.150 rad is not
    turn = 20.0 - 6 * np.pi
    tilted = ",".join(map(repr, [*scene.CENTRE, turn, 1.0, turn]))
    feedback = toolbox.Feedback()
    # so tilted the frame sees the horizon: an oblique ortho, its grid cut to the DEM, and the
    # warning that the angles look read in the wrong unit
    stats = toolbox.run("ortho:photo", {"INPUT": block.photo_path, "CAMERA": camera,
                                        "EXTERIOR": tilted, "ANGLE_UNIT": "rad",
                                        "CRS": "EPSG:3003", "DEM": block.dem_path,
                                        "OUTPUT": tmp_path / "t.tif"},
                        feedback=feedback)["STATISTICS"]
    assert any("wrong unit" in w for w in feedback.warnings)
    bounds, dem = stats["bounds"], scene.BOUNDS
    assert bounds[0] >= dem[0] - 50 and bounds[2] <= dem[2] + 50
    assert bounds[1] >= dem[1] - 50 and bounds[3] <= dem[3] + 50


def test_parameter_errors_name_the_parameter(block, tmp_path):
    with pytest.raises(ParameterError, match="PROJECT"):
        toolbox.run("ortho:photo", {"INPUT": block.photo_path, "DEM": block.dem_path,
                                    "OUTPUT": tmp_path / "o.tif"})
    with pytest.raises(ParameterError, match="OCCLUSION_MASK"):
        run_ortho(block, tmp_path / "o.tif", OCCLUSION_MASK=tmp_path / "m.tif")


@pytest.mark.parametrize("terms", [
    {"k1": -2e-7},
    {"k1": -1e-7, "k3": -1e-16, "p1": 1e-5, "p2": -8e-6},
])
def test_radial_distortion_is_applied_in_the_right_direction(block, tmp_path, terms):
    """A photo taken through a lens with k1 = -2e-7 mm^-2 (2.8 px at the corners), or with k3
    and decentring p1, p2 too (about as much): the ortho with the camera's distortion (read
    from the project YAML) recovers the texture, the one without is off. The photo is
    rendered by monoplotting (pixel -> ray: the closed-form correction, OpenCV's
    projectPoints in tests/toolbox/cameras/test_film_lens_distortion.py); the ortho maps
    ground -> pixel (the iterative inverse)."""
    from toolbox.photogrammetry.camera import RadialDistortion
    from toolbox.photogrammetry.synthetic import frame_photo, render_photo, write_photo

    distortion = RadialDistortion.from_polynomial(**terms)
    photo = frame_photo(scene.CENTRE, scene.ANGLES, width=scene.SIZE, height=scene.SIZE,
                        crs=scene.CRS, distortion=distortion)
    image = render_photo(photo, block.dem, block.transform, block.texture, dtype="uint8")
    path = write_photo(tmp_path / "p1.tif", image)
    with_lens = scene.project_yaml(tmp_path / "lens.yaml", "p1.tif",
                                   distortion={"polynomial": terms})
    without = scene.project_yaml(tmp_path / "nolens.yaml", "p1.tif")
    shifts = {}
    for name, project in (("lens", with_lens), ("none", without)):
        out = tmp_path / f"{name}.tif"
        stats = toolbox.run("ortho:photo", {"INPUT": path, "PROJECT": project,
                                            "DEM": block.dem_path, "CELL_SIZE": 5.0,
                                            "OUTPUT": out})["STATISTICS"]
        data, truth, _ = read_with_truth(out, block.texture)
        shifts[name] = patch_positions(data[0], data[1] == 255, truth)[:, 0]
        if name == "lens":
            assert stats["map_blocks"]["projective_exact"] == 0
    assert shifts["lens"].max() <= 0.1
    assert shifts["none"].max() > 0.3


def test_quadratic_resampling_recovers_the_texture(block, tmp_path):
    run_ortho(block, tmp_path / "q.tif", RESAMPLING="quadratic", CELL_SIZE=5.0,
              EXTENT="1687400,4798400,1689000,4800000")
    data, truth, _ = read_with_truth(tmp_path / "q.tif", block.texture)
    patches = patch_positions(data[0], data[1] == 255, truth)
    assert len(patches) >= 9
    assert patches[:, 0].max() <= 0.1 and patches[:, 1].min() > 0.99


def test_cog_output_and_nodata_outside(block, tmp_path):
    out = tmp_path / "cog.tif"
    run_ortho(block, out, CELL_SIZE=4.0, COG=True, OUTSIDE="nodata", NODATA=0)
    with rasterio.open(out) as src:
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        assert src.count == 1 and src.nodata == 0 and src.overviews(1)
        data = src.read(1)
    assert (data == 0).any() and (data > 0).mean() > 0.5
    assert not list(tmp_path.glob(".*"))  # the intermediate GeoTIFF is gone


def test_cli_refuses_a_camera_looking_away_in_one_line(block, tmp_path):
    from conftest import run_cli

    project = scene.project_yaml(tmp_path / "up.yaml", str(block.photo_path),
                                 angles=(3.1, 0.0, 0.0))
    result = run_cli("run", "ortho:photo", "--INPUT", block.photo_path, "--PROJECT", project,
                     "--DEM", block.dem_path, "--OUTPUT", tmp_path / "up.tif")
    assert result.returncode == 2
    assert "looks away from the ground" in result.stderr and len(result.stderr.splitlines()) == 1
    assert not (tmp_path / "up.tif").exists()


def test_ortho_in_another_crs_recovers_the_texture(block, tmp_path):
    """CRS = Monte Mario zone 2 with a zone-1 orientation: the truth at each cell comes from
    pyproj's exact transform of its centre back to zone 1."""
    from pyproj import Transformer

    out = tmp_path / "z2.tif"
    stats = run_ortho(block, out, CRS="EPSG:3004", CELL_SIZE=5.0)["STATISTICS"]
    assert stats["crs"] == "EPSG:3004"
    with rasterio.open(out) as src:
        data = src.read()
        t = src.transform
        assert src.crs.to_epsg() == 3004
    xs = t.c + (np.arange(data.shape[2]) + 0.5) * t.a
    ys = t.f + (np.arange(data.shape[1]) + 0.5) * t.e
    xx, yy = np.meshgrid(xs, ys)
    x1, y1 = Transformer.from_crs("EPSG:3004", "EPSG:3003", always_xy=True).transform(xx, yy)
    truth = block.texture(x1, y1)
    patches = patch_positions(data[0], data[1] == 255, truth)
    assert len(patches) >= 9
    assert patches[:, 0].max() <= 0.1 and patches[:, 1].min() > 0.99
    with pytest.raises(ParameterError, match="OCCLUSION"):
        run_ortho(block, tmp_path / "z2occ.tif", CRS="EPSG:3004", OCCLUSION=True)


@pytest.mark.parametrize("bands, extra", [(1, {}), (1, {"OUTSIDE": "nodata", "NODATA": 7}),
                                          (1, {"RESAMPLING": "cubic", "MAP_BLOCK": 64}),
                                          (3, {})])
def test_planned_windows_give_the_ortho_of_the_generic_path(block, tmp_path, monkeypatch, bands,
                                                            extra):
    """The planned path (the source window decided from a bound of the window's image, the
    OpenCV maps written by the kernel with the cells outside the photo blanked, OpenCV's border
    value as the fill) against the generic one (the map, then the warp's own source window,
    shift, inside test and fill), forced by switching the plans off: the same pixels to 1 grey
    level (the two maps differ by float32 rounding), the same footprint but for cells within
    rounding of the photo's edge, the same report. Grey + alpha takes the warp's band by band
    path, grey with nodata and RGB + alpha its pixel-interleaved one."""
    from toolbox.ortho.windows import OrthoWindows

    sc = block if bands == 1 else scene.make_scene(tmp_path, bands=bands)

    planned = []
    real_plan = OrthoWindows.plan

    def spy(self, *args):
        plan = real_plan(self, *args)
        planned.append(plan is not None)
        return plan

    monkeypatch.setattr(OrthoWindows, "plan", spy)
    fast = run_ortho(sc, tmp_path / "planned.tif", **extra)
    assert planned and all(planned)
    monkeypatch.setattr(OrthoWindows, "plan", lambda self, *args: None)
    slow = run_ortho(sc, tmp_path / "generic.tif", **extra)
    with rasterio.open(tmp_path / "planned.tif") as a, rasterio.open(tmp_path / "generic.tif") as b:
        pa, pb = a.read(), b.read()
        ma, mb = a.dataset_mask(), b.dataset_mask()
    assert pa.shape == pb.shape
    footprint = ma != mb
    assert 0 < (mb > 0).mean() < 1 and footprint.mean() < 1e-3
    both = (ma > 0) & (mb > 0)
    assert np.abs(pa.astype(int) - pb.astype(int))[:, both].max() <= 1
    assert (pa[:, ~(ma > 0) & ~(mb > 0)] == pb[:, ~(ma > 0) & ~(mb > 0)]).all()  # the fill
    ra, rb = fast["STATISTICS"], slow["STATISTICS"]
    for key in ("outside_photo_fraction", "outside_dem_fraction", "max_relief_displacement_m"):
        assert ra[key] == pytest.approx(rb[key], rel=1e-4, abs=1e-6), key


def test_incidence_angles_do_not_change_the_ortho(block, tmp_path):
    """Asking for INCIDENCE takes the windows off the planned path (their angles need the
    heights of a haloed window): the ortho is the planned one to 1 grey level and within
    rounding of the photo's edge, the report's counts the same, and the angles cover exactly
    the cells with a DEM height."""
    plain = run_ortho(block, tmp_path / "plain.tif")
    angled = run_ortho(block, tmp_path / "angled.tif", INCIDENCE=tmp_path / "inc.tif")
    with rasterio.open(tmp_path / "plain.tif") as a, rasterio.open(tmp_path / "angled.tif") as b:
        pa, pb, ma, mb = a.read(), b.read(), a.dataset_mask(), b.dataset_mask()
    with rasterio.open(tmp_path / "inc.tif") as src:
        angles = src.read(1)
    assert (ma != mb).mean() < 1e-3 and 0 < (ma > 0).mean() < 1
    both = (ma > 0) & (mb > 0)
    assert np.abs(pa.astype(int) - pb.astype(int))[:, both].max() <= 1
    ra, rb = plain["STATISTICS"], angled["STATISTICS"]
    for key in ("outside_photo_fraction", "outside_dem_fraction", "max_relief_displacement_m"):
        assert ra[key] == pytest.approx(rb[key], rel=1e-4, abs=1e-6), key
    assert np.isfinite(angles).mean() == pytest.approx(1 - ra["outside_dem_fraction"], abs=1e-9)
    assert 0 <= np.nanmin(angles) and np.nanmax(angles) < 90


def test_project_and_photo_name_the_image_without_input(block, tmp_path):
    """INPUT was required even when PROJECT and PHOTO name the photo, whose image the project
    records: without INPUT the project's image is taken (the same ortho as with it); refused
    in one line naming INPUT when neither gives an image."""
    with_input = run_ortho(block, tmp_path / "a.tif")
    params = {"PROJECT": block.project_path, "PHOTO": "p1", "DEM": block.dem_path,
              "CELL_SIZE": CELL, "OUTPUT": tmp_path / "b.tif"}
    toolbox.run("ortho:photo", params)
    with rasterio.open(with_input["OUTPUT"]) as a, rasterio.open(tmp_path / "b.tif") as b:
        assert a.transform == b.transform and np.array_equal(a.read(), b.read())
    for missing in ("PHOTO", "PROJECT"):
        with pytest.raises(ParameterError, match="INPUT is required .*PROJECT and PHOTO"):
            toolbox.run("ortho:photo", {**{k: v for k, v in params.items() if k != missing},
                                        "OUTPUT": tmp_path / "c.tif"})
