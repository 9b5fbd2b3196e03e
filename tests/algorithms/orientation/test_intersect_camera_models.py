"""orientation:intersect with camera models (drone photos: a Brown camera and a fisheye): the
measured pixels are made by OpenCV (cv2.projectPoints / cv2.fisheye.projectPoints, the
independent oracle) from known ground points and the product's exterior convention (world ->
OpenCV camera = diag(1, -1, -1)·Rᵀ, R = Rx·Ry·Rz from scipy); the intersection recovers the
points to 0.1 mm, with pixel residuals ~0. Image-mm measurements of a model camera and pixels
past a fisheye's field are one-line errors."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest
import rasterio
import yaml
from scipy.spatial.transform import Rotation

import toolbox

W, H = 1368, 912
BROWN = {"type": "brown", "im_size": [W, H], "focal_len": 0.6664614123723713,
         "cx": -0.0015460447606643697, "cy": 0.004751874732641298,
         "k1": -0.2640629100413887, "k2": 0.10188934223670705, "p1": 0.0007345906274317972,
         "p2": 0.0002595206713083041, "k3": -0.02581956399353581}
FISHEYE = {"type": "fisheye", "im_size": [1200, 1000], "focal_len": 0.3, "cx": 0.005,
           "cy": -0.01, "k1": -0.03, "k2": 0.004, "k3": -0.0008, "k4": 0.0001}
POSES = {"a": ("brown", (500000.0, 4000000.0, 120.0), (2.0, -1.5, 10.0)),
         "b": ("brown", (500045.0, 4000002.0, 121.0), (-1.0, 2.0, 12.0)),
         "c": ("fisheye", (500020.0, 3999990.0, 118.0), (0.5, 0.5, 95.0))}


def opencv_pixels(spec, centre, angles_deg, ground):
    """Product pixels (OpenCV's + 0.5) of ground points through OpenCV's own model."""
    w, h = spec["im_size"]
    s = max(w, h)
    f = spec["focal_len"] * s
    k = np.array([[f, 0, w / 2 + spec["cx"] * s - 0.5], [0, f, h / 2 + spec["cy"] * s - 0.5],
                  [0, 0, 1]])
    r = Rotation.from_euler("XYZ", angles_deg, degrees=True).as_matrix()
    world_to_cv = np.diag([1.0, -1.0, -1.0]) @ r.T
    rvec, _ = cv2.Rodrigues(world_to_cv)
    tvec = -world_to_cv @ np.asarray(centre)
    if spec["type"] == "fisheye":
        d = np.array([spec[f"k{i}"] for i in range(1, 5)])
        px, _ = cv2.fisheye.projectPoints(ground.reshape(-1, 1, 3), rvec, tvec, k, d)
    else:
        d = np.array([spec["k1"], spec["k2"], spec["p1"], spec["p2"], spec["k3"]])
        px, _ = cv2.projectPoints(ground, rvec, tvec, k, d)
    return px.reshape(-1, 2) + 0.5


@pytest.fixture
def block(tmp_path):
    rng = np.random.default_rng(11)
    ground = np.column_stack([rng.uniform(499990, 500050, 12), rng.uniform(3999975, 4000015, 12),
                              rng.uniform(0, 15, 12)])
    rows = ["point_id,photo,col_px,row_px"]
    for pid, (cam, centre, angles) in POSES.items():
        spec = BROWN if cam == "brown" else FISHEYE
        px = opencv_pixels(spec, centre, angles, ground)
        w, h = spec["im_size"]
        for k, (c, r) in enumerate(px):
            if 0 < c < w and 0 < r < h:
                rows.append(f"p{k},{pid},{c:.9f},{r:.9f}")
    (tmp_path / "pixels.csv").write_text("\n".join(rows) + "\n")
    doc = {"crs": "EPSG:32632", "angle_unit": "deg",
           "cameras": [{"name": "brown", "model": BROWN}, {"name": "fisheye", "model": FISHEYE}],
           "photos": [{"id": pid, "camera": cam,
                       "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                            [*centre, *angles], strict=True))}
                      for pid, (cam, centre, angles) in POSES.items()]}
    (tmp_path / "project.yaml").write_text(yaml.safe_dump(doc))
    return tmp_path, ground


def test_intersection_through_brown_and_fisheye_recovers_the_points(block):
    import geopandas

    folder, ground = block
    stats = toolbox.run("orientation:intersect", {
        "PROJECT": folder / "project.yaml", "INPUT": folder / "pixels.csv",
        "OUTPUT": folder / "points.gpkg"})["STATISTICS"]
    assert stats["status"]["ok"] >= 10 and stats["max_residual_px"] < 1e-4
    points = geopandas.read_file(folder / "points.gpkg", layer="points")
    ok = points[points["status"] == "ok"]
    for _, row in ok.iterrows():
        truth = ground[int(row["point_id"][1:])]
        assert np.allclose([row["x"], row["y"], row["z"]], truth, atol=1e-4), row["point_id"]
    assert (ok["n_photos"] == 3).any()  # some points seen by the fisheye too


def test_model_camera_bad_measurements_are_one_line(block):
    folder, _ = block
    (folder / "mm.csv").write_text("point_id,photo,x_mm,y_mm\np0,a,1.0,2.0\np0,b,1.5,2.0\n")
    (folder / "far.csv").write_text("point_id,photo,col_px,row_px\np0,a,600,400\n"
                                    "p0,c,1.0,1.0\n")
    for name, message in (("mm.csv", "measure it in pixels"), ("far.csv", "have no ray")):
        out = folder / f"{name}.gpkg"
        run = subprocess.run([sys.executable, "-m", "toolbox", "run", "orientation:intersect",
                              "--PROJECT", str(folder / "project.yaml"), "--INPUT",
                              str(folder / name), "--OUTPUT", str(out)],
                             capture_output=True, text=True)
        assert run.returncode == 2, run.stderr
        assert run.stderr.count("\n") == 1 and message in run.stderr, run.stderr
        assert not out.exists()


def test_resection_of_a_brown_camera_photo(block):
    """orientation:resection of the Brown photo 'a' from its OpenCV-projected control points:
    the pose comes back to 0.1 mm and 1e-7 rad, residuals in pixels ~0."""
    folder, ground = block
    (folder / "control.csv").write_text("id,X,Y,Z\n" + "".join(
        f"p{k},{x:.6f},{y:.6f},{z:.6f}\n" for k, (x, y, z) in enumerate(ground)))
    stats = toolbox.run("orientation:resection", {
        "PROJECT": folder / "project.yaml", "INPUT": folder / "pixels.csv",
        "CONTROL": folder / "control.csv", "OUTPUT": folder / "resected.yaml",
        "REPORT": folder / "resection.json"})["STATISTICS"]
    assert stats["photos"] == 3
    doc = yaml.safe_load((folder / "resected.yaml").read_text())
    a = next(p for p in doc["photos"] if p["id"] == "a")["exterior"]
    _, centre, angles = POSES["a"]
    unit = doc.get("angle_unit", "rad")
    got = np.array([a["omega"], a["phi"], a["kappa"]], dtype=float)
    got = np.radians(got) if unit == "deg" else got
    assert np.allclose([a["X0"], a["Y0"], a["Z0"]], centre, atol=1e-4)
    assert np.allclose(got, np.radians(angles), atol=1e-7)
    import json

    report = json.loads((folder / "resection.json").read_text())["photos"]["a"]
    assert report["sigma0_um"] is None and report["sigma0_px"] < 1e-4
    assert max(p["res_px"] for p in report["points"]) < 1e-4


def test_orientation_check_of_camera_model_photos(block):
    """orientation:check on Brown and fisheye photos: residuals in pixels ~0 (no µm: no film
    plane), the known points intersected back onto themselves."""
    folder, ground = block
    (folder / "control.csv").write_text("id,X,Y,Z,role\n" + "".join(
        f"p{k},{x:.6f},{y:.6f},{z:.6f},{'check' if k % 2 else 'control'}\n"
        for k, (x, y, z) in enumerate(ground)))
    stats = toolbox.run("orientation:check", {
        "PROJECT": folder / "project.yaml", "INPUT": folder / "pixels.csv",
        "CONTROL": folder / "control.csv", "REPORT": folder / "check.json",
        "OUTPUT": folder / "check.gpkg"})["STATISTICS"]
    assert stats["observations"] > 20 and stats["flagged"] == 0 and stats["rmse_um"] is None
    assert stats["check_rmse_xy_m"] < 1e-4 and stats["check_rmse_z_m"] < 1e-4
    import json

    report = json.loads((folder / "check.json").read_text())
    assert max(o["res_px"] for o in report["observations"]) < 1e-4
    assert all(p["rmse_px"] < 1e-4 for p in report["photos"].values())


def test_bundle_of_camera_model_photos(block):
    """orientation:bundle of the Brown and fisheye photos (interiors fixed) from half the points
    as control: the poses come back, the other half (check points) land on themselves; a
    self-calibration asked of a model camera is a one-line error."""
    import json

    folder, ground = block
    (folder / "control.csv").write_text("id,X,Y,Z,role\n" + "".join(
        f"p{k},{x:.6f},{y:.6f},{z:.6f},{'check' if k % 2 else 'control'}\n"
        for k, (x, y, z) in enumerate(ground)))
    bare = yaml.safe_load((folder / "project.yaml").read_text())
    for photo in bare["photos"]:
        del photo["exterior"]  # start values computed (START auto), not the truth
    (folder / "bare.yaml").write_text(yaml.safe_dump(bare))
    toolbox.run("orientation:bundle", {
        "PROJECT": folder / "bare.yaml", "INPUT": folder / "pixels.csv",
        "CONTROL": folder / "control.csv", "SIGMA_PX": 0.5, "OUTPUT": folder / "bundle.yaml",
        "REPORT": folder / "bundle.json"})
    doc = yaml.safe_load((folder / "bundle.yaml").read_text())
    assert {c["name"]: c["model"] for c in doc["cameras"]} == {"brown": BROWN,
                                                                "fisheye": FISHEYE}
    unit = doc.get("angle_unit", "rad")
    for photo in doc["photos"]:
        _, centre, angles = POSES[photo["id"]]
        e = photo["exterior"]
        got = np.array([e["omega"], e["phi"], e["kappa"]], dtype=float)
        got = np.radians(got) if unit == "deg" else got
        assert np.allclose([e["X0"], e["Y0"], e["Z0"]], centre, atol=1e-3), photo["id"]
        assert np.allclose(got, np.radians(angles), atol=1e-6), photo["id"]
    report = json.loads((folder / "bundle.json").read_text())
    summary = report["summary"]
    assert summary["rms_image_residual_um"] is None and summary["rms_image_residual_px"] < 1e-3
    assert max(abs(v) for v in summary["check_rmse_m"].values()) < 1e-3
    run = subprocess.run([sys.executable, "-m", "toolbox", "run", "orientation:bundle",
                          "--PROJECT", str(folder / "project.yaml"), "--INPUT",
                          str(folder / "pixels.csv"), "--CONTROL", str(folder / "control.csv"),
                          "--SELF_CALIBRATION", "c", "--OUTPUT", str(folder / "b2.yaml")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and run.stderr.count("\n") == 1
    assert "interior is held fixed" in run.stderr and not (folder / "b2.yaml").exists()


def test_monoplot_of_camera_model_photos_on_a_dem(block):
    """orientation:monoplot of OpenCV-projected pixels of the Brown photos on a sloping DEM (a
    plane: bilinear interpolation is exact on it): the ground points back. (This fisheye sees
    past 90 degrees at its corners: it has no footprint to window a DEM with, refused.)"""
    import geopandas

    from toolbox.raster.writer import write_raster

    folder, _ = block
    rng = np.random.default_rng(5)
    xy = np.column_stack([rng.uniform(500000, 500040, 15), rng.uniform(3999985, 4000010, 15)])
    plane = lambda x, y: 5.0 + 0.1 * (x - 499900.0) - 0.05 * (y - 3999900.0)  # noqa: E731
    ground = np.column_stack([xy, plane(xy[:, 0], xy[:, 1])])
    cols, rows = np.meshgrid(np.arange(400) + 0.5, np.arange(400) + 0.5)
    transform = rasterio.Affine(1.0, 0.0, 499900.0, 0.0, -1.0, 4000100.0)
    gx, gy = transform * (cols, rows)
    write_raster(folder / "plane.tif", plane(gx, gy).astype("float64"), transform, "EPSG:32632")
    lines = ["point_id,photo,col_px,row_px"]
    for pid in ("a", "b"):
        cam, centre, angles = POSES[pid]
        px = opencv_pixels(BROWN if cam == "brown" else FISHEYE, centre, angles, ground)
        lines += [f"m{k},{pid},{c:.9f},{r:.9f}" for k, (c, r) in enumerate(px)]
    (folder / "mono.csv").write_text("\n".join(lines) + "\n")
    toolbox.run("orientation:monoplot", {"PROJECT": folder / "project.yaml",
                                         "INPUT": folder / "mono.csv",
                                         "DEM": folder / "plane.tif",
                                         "OUTPUT": folder / "mono.gpkg"})
    points = geopandas.read_file(folder / "mono.gpkg", layer="points")
    assert len(points) == 30 and (points["status"] == "ok").all()
    for _, row in points.iterrows():
        truth = ground[int(row["point_id"][1:])]
        got = np.array([row.geometry.x, row.geometry.y, row.geometry.z])
        assert np.allclose(got, truth, atol=1e-3), (row["point_id"], row["photo"], got - truth)


def test_relative_orientation_of_two_brown_photos(block):
    """orientation:relative of the two Brown photos: the model is the ground up to a similarity
    (fitted independently: scale from the spreads, rotation by scipy's Kabsch), y-parallaxes
    in pixels ~0."""
    import csv

    folder, ground = block
    stats = toolbox.run("orientation:relative", {
        "PROJECT": folder / "project.yaml", "INPUT": folder / "pixels.csv", "PHOTO1": "a",
        "PHOTO2": "b", "OUTPUT": folder / "model.csv"})["STATISTICS"]
    assert stats["sigma0_px"] < 1e-5 and "sigma0_um" not in stats
    with (folder / "model.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) >= 8 and max(abs(float(r["py_px"])) for r in rows) < 1e-5
    model = np.array([[float(r[k]) for k in "XYZ"] for r in rows])
    truth = ground[[int(r["point_id"][1:]) for r in rows]]
    m, t = model - model.mean(axis=0), truth - truth.mean(axis=0)
    scale = np.sqrt((t ** 2).sum() / (m ** 2).sum())
    rotation, _ = Rotation.align_vectors(t, scale * m)
    residual = rotation.apply(scale * m) - t
    assert np.abs(residual).max() < 1e-4  # metres, over a 60 m block


def test_control_layer_in_another_crs_than_the_project_is_refused(block):
    """A CONTROL GeoPackage layer labelled in another CRS than the project: its X/Y/Z columns
    are read as they are, so it is refused naming CONTROL and both CRSs (it gave a misleading
    'behind the projection centre' refusal, and report:ortho_check 'none found'); the same
    table labelled in the project's CRS runs."""
    import geopandas as gpd
    import shapely

    folder, ground = block  # the project is in EPSG:32632
    frame = gpd.GeoDataFrame({"id": [f"p{k}" for k in range(len(ground))],
                              "X": ground[:, 0], "Y": ground[:, 1], "Z": ground[:, 2]},
                             geometry=shapely.points(ground[:, :2]))
    for crs in ("EPSG:32632", "EPSG:3003"):
        frame.set_crs(crs).to_file(folder / f"control_{crs[5:]}.gpkg")
    params = {"PROJECT": folder / "project.yaml", "INPUT": folder / "pixels.csv",
              "REPORT": folder / "c.json", "OUTPUT": folder / "c.gpkg"}
    toolbox.run("orientation:check", params | {"CONTROL": folder / "control_32632.gpkg"},
                overwrite=True)
    with pytest.raises(toolbox.InputDataError, match="CONTROL: .* is a layer in EPSG:3003 but "
                                                     "the project is in EPSG:32632"):
        toolbox.run("orientation:check", params | {"CONTROL": folder / "control_3003.gpkg"},
                    overwrite=True)
