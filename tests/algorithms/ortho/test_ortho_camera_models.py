"""ortho:photo through camera models (Brown, fisheye): synthetic photos rendered with OpenCV's
undistortion as the lens (cv2.undistortPoints / cv2.fisheye.undistortPoints, an independent
inverse of the models) and the collinearity equations marched down to a DEM with 200 m of
relief; the ortho must give the texture back at its cell centres (phase correlation per patch,
scikit-image), and must not without the lens."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

import toolbox
from toolbox.cameras import create_intrinsics
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.photo import Photo
from toolbox.photogrammetry.surface import DemSurface
from toolbox.photogrammetry.synthetic import write_photo

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402
from test_ortho_photo import patch_positions, read_with_truth  # noqa: E402

CELL = 2.5
BROWN = {"type": "brown", "im_size": [720, 560], "focal_len": 0.75, "cx": 0.012, "cy": -0.008,
         "k1": -0.21, "k2": 0.09, "k3": -0.012, "p1": 0.0012, "p2": -0.0007}
FISHEYE = {"type": "fisheye", "im_size": [640, 640], "focal_len": 0.66, "cx": -0.01,
           "cy": 0.006, "k1": -0.06, "k2": 0.012, "k3": -0.002, "k4": 0.0002}
OPENCV = {"type": "opencv", "im_size": [720, 560], "focal_len": 0.75, "cx": -0.01, "cy": 0.01,
          "k1": -0.18, "k2": 0.07, "k3": -0.01, "k4": 0.02, "k5": 0.003, "k6": 0.001,
          "p1": 0.001, "p2": -0.0006, "s1": 0.002, "s2": -0.0004, "s3": -0.0012, "s4": 0.0003}
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)


def render(spec: dict, dem, transform, texture) -> np.ndarray:
    """Every pixel centre's ray: OpenCV undistorts it (product pixels - 0.5 = OpenCV's), the
    collinearity equations (c = 1 on normalised coordinates, y up) march it to the DEM."""
    model = create_intrinsics(spec)
    w, h = model.image_size_px
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    px = np.column_stack([cols.ravel(), rows.ravel()]) - 0.5
    if model.kind == "fisheye":
        xn = cv2.fisheye.undistortPoints(px.reshape(-1, 1, 2), model.matrix(),
                                         model.opencv_coefficients(), criteria=CRITERIA)
    else:
        xn = cv2.undistortPoints(px.reshape(-1, 1, 2), model.matrix(),
                                 model.opencv_coefficients(), criteria=CRITERIA)
    xn = xn.reshape(-1, 2) * [1.0, -1.0]
    eo = ExteriorOrientation.from_angles("p1", *scene.CENTRE, *scene.ANGLES, crs=scene.CRS)
    surface = DemSurface.from_transform(np.asarray(dem, dtype="float64"), transform)
    hit = Photo("p1", model, eo).monoplot_image(xn, surface)
    value = np.where(hit.ok, texture(np.where(hit.ok, hit.xyz[:, 0], 0.0),
                                     np.where(hit.ok, hit.xyz[:, 1], 0.0)), 0.0)
    return np.clip(np.rint(value), 0, 255).astype("uint8").reshape(h, w)


def some_patches(valid: np.ndarray) -> np.ndarray:
    """``valid`` on every third patch row and column (a ninth of the patches, spread over
    the whole ortho; phase correlation is the slow part of the check)."""
    from test_ortho_photo import PATCH

    i, j = np.indices(valid.shape) // PATCH
    return valid & (i % 3 == 0) & (j % 3 == 0)


def model_project(path: Path, spec: dict) -> Path:
    doc = {"crs": scene.CRS, "angle_unit": "rad", "cameras": [{"name": "lens", "model": spec}],
           "photos": [{"id": "p1", "camera": "lens", "image": "p1.tif",
                       "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                            [*scene.CENTRE, *scene.ANGLES], strict=True))}]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def terrain(tmp_path_factory):
    folder = tmp_path_factory.mktemp("model_scene")
    z, transform = scene.hills_dem(scene.BOUNDS, cell=10.0, relief=scene.RELIEF,
                                   base=scene.BASE, seed=3)
    texture = scene.wave_texture(seed=7, wavelength=(40.0, 120.0))
    return folder, z, transform, texture, scene.write_dem(folder / "dem.tif", z, transform)


@pytest.mark.parametrize("spec", [BROWN, FISHEYE, OPENCV],
                         ids=["brown", "fisheye", "opencv-thin-prism"])
def test_ortho_through_a_camera_model_recovers_the_texture(terrain, spec, tmp_path):
    folder, z, transform, texture, dem = terrain
    write_photo(tmp_path / "p1.tif", render(spec, z, transform, texture))
    project = model_project(tmp_path / "project.yaml", spec)
    # the fisheye sees more than the DEM: its photo is black beyond the DEM's edge, and the
    # bilinear resampling blends that black into the ortho's outermost cells (heights reach the
    # DEM's outer cell edges): the ortho stops one DEM cell inside them
    b, inset = scene.BOUNDS, transform.a
    area = {"DEM": dem, "CELL_SIZE": CELL,
            "EXTENT": [b[0] + inset, b[1] + inset, b[2] - inset, b[3] - inset]}
    out = toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "PROJECT": project, **area,
                                      "OUTPUT": tmp_path / "ortho.tif"})
    data, truth, _ = read_with_truth(tmp_path / "ortho.tif", texture)
    patches = patch_positions(data[0], some_patches(data[1] == 255), truth)
    assert len(patches) >= 9
    assert patches[:, 0].max() <= 0.1, np.sort(patches[:, 0])[-5:]
    assert patches[:, 1].min() > 0.98
    report = out["STATISTICS"]
    assert report["max_relief_displacement_px"] > 10  # the relief mattered
    # negative control: the same photo through the lens without its distortion is wrong
    flat = {k: v for k, v in spec.items() if not k.startswith(("k", "p", "s"))}
    flat["type"] = "pinhole" if spec["type"] != "fisheye" else "fisheye"
    model_project(tmp_path / "no_lens.yaml", flat)
    toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "PROJECT": tmp_path / "no_lens.yaml",
                                **area, "OUTPUT": tmp_path / "bad.tif"})
    data, truth, _ = read_with_truth(tmp_path / "bad.tif", texture)
    wrong = patch_positions(data[0], some_patches(data[1] == 255), truth)
    assert np.median(wrong[:, 0]) > 0.5


def test_ortho_batch_with_a_model_camera(terrain, tmp_path):
    folder, z, transform, texture, dem = terrain
    write_photo(tmp_path / "p1.tif", render(BROWN, z, transform, texture))
    project = model_project(tmp_path / "project.yaml", BROWN)
    out = toolbox.run("ortho:batch", {"PROJECT": project, "DEM": dem, "CELL_SIZE": CELL,
                                      "FOLDER": str(tmp_path / "orthos"),
                                      "OUTPUT": tmp_path / "batch.json"})
    assert out["STATISTICS"]["done"] == 1
    data, truth, _ = read_with_truth(tmp_path / "orthos" / "p1.tif", texture)
    patches = patch_positions(data[0], some_patches(data[1] == 255), truth)
    assert len(patches) >= 9 and patches[:, 0].max() <= 0.1


def test_camera_yaml_with_a_model_and_bad_models_on_the_command_line(terrain, tmp_path):
    """CAMERA + EXTERIOR with a model camera gives the PROJECT's ortho; a model whose
    distortion folds back inside the image is a one-line error (exit 2) with no output left."""
    import rasterio
    from conftest import run_cli

    folder, z, transform, texture, dem = terrain
    write_photo(tmp_path / "p1.tif", render(BROWN, z, transform, texture))
    (tmp_path / "cam.yaml").write_text(yaml.safe_dump({"name": "lens", "model": BROWN}))
    area = {"DEM": dem, "CELL_SIZE": 10.0, "INPUT": tmp_path / "p1.tif"}
    toolbox.run("ortho:photo", {**area, "CAMERA": tmp_path / "cam.yaml", "CRS": scene.CRS,
                                "EXTERIOR": ",".join(map(str, [*scene.CENTRE, *scene.ANGLES])),
                                "OUTPUT": tmp_path / "a.tif"})
    toolbox.run("ortho:photo", {**area, "PROJECT": model_project(tmp_path / "p.yaml", BROWN),
                                "OUTPUT": tmp_path / "b.tif"})
    with rasterio.open(tmp_path / "a.tif") as a, rasterio.open(tmp_path / "b.tif") as b:
        assert a.bounds == b.bounds and np.array_equal(a.read(), b.read())
    project = model_project(tmp_path / "bad.yaml", dict(BROWN, k1=-0.6))
    result = run_cli("run", "ortho:photo", "--INPUT", tmp_path / "p1.tif", "--PROJECT",
                     project, "--DEM", dem, "--OUTPUT", tmp_path / "bad.tif")
    assert result.returncode == 2, result.stderr
    assert "do not fit the image size" in result.stderr
    assert len(result.stderr.splitlines()) == 1
    assert not (tmp_path / "bad.tif").exists()
