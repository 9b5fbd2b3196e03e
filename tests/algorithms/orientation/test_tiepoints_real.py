"""orientation:tiepoints and orientation:bundle on real photos: Orthority's test data with their
published orientations.

- NGI: four aerial frames (Intergraph DMC, pinhole, f = 120 mm, 92.16 x 165.888 mm sensor,
  640 x 1152 px, two strips flown in opposite directions); camera_pos_ori.txt: X Y Z omega phi
  kappa in degrees (Orthority's omega-phi-kappa, the photogrammetric convention of this toolbox).
- ODM: four drone frames (DJI FC6310, Brown model, 1368 x 912 px, 30-degree oblique views in
  four directions) oriented by OpenSfM (reconstruction.json, read by orientation:convert).

Truth for the tie points: every tie point, intersected with the PUBLISHED orientations, reprojects
within 1.5 px in every photo measuring it (the matcher uses the orientations only to choose the
pairs), and lies on the published DEM/DSM.

Truth for the bundle: the published orientations. The bundle starts from them perturbed and gets
its datum from a few CONTROL points derived from the published orientations (tie points spread
over the block, intersected with the published orientations: no surveyed points come with the
data); it must come back to the published orientations within a ground pixel and a pixel's angle
(1.5 of them for NGI, whose derived control is itself that coarse), and within 3 of its own
standard deviations. A second datum, the published centres as GNSS observations (no control),
is run too (angles from the tie points alone: looser bounds, see its test). The ODM photos are
adjusted through their published Brown camera (pixels, the bundle's forward Brown model); a
third ODM run self-calibrates that camera's f, cx, cy, k1, k2 (weighted to OpenSfM's values)
and must still come back to the published orientations.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import toolbox

NGI_TERRAIN = 430.0  # m, median of the NGI DEM
ODM_TERRAIN = 93.0  # m, median of the ODM DSM


def ngi_project(data, folder):
    ngi = data / "ngi"
    photos = []
    for line in (ngi / "camera_pos_ori.txt").read_text().splitlines():
        if line.strip():
            name, *values = line.split()
            photos.append({"id": name, "camera": "dmc", "image": str(ngi / f"{name}.tif"),
                           "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                                map(float, values), strict=True))})
    doc = {"format": "orientation-project", "version": 1,
           "crs": "+proj=tmerc +lon_0=25 +datum=WGS84 +units=m", "angle_unit": "deg",
           "cameras": [{"name": "dmc", "principal_distance_mm": 120.0,
                        "image_size_px": [640, 1152], "pixel_size_mm": 0.144,
                        "frame_size_mm": [92.16, 165.888]}], "photos": photos}
    path = folder / "ngi.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def odm_project(data, folder):
    path = folder / "odm.yaml"
    toolbox.run("orientation:convert", {
        "INPUT": str(data / "odm" / "opensfm" / "reconstruction.json"), "OUTPUT": path})
    return path


class Case:
    """One real block: its project, the tie-point run, and the measurements intersected with
    the published orientations (an independent least-squares intersection, not the bundle)."""

    def __init__(self, data: Path, folder: Path, name: str):
        from toolbox.matching.matching import normaliser
        from toolbox.photogrammetry.forward_intersection import intersect
        from toolbox.photogrammetry.project import load_project

        self.folder, self.name, self.data = folder, name, data
        self.project = (ngi_project if name == "ngi" else odm_project)(data, folder)
        terrain = NGI_TERRAIN if name == "ngi" else ODM_TERRAIN
        self.out = toolbox.run("orientation:tiepoints", {
            "PROJECT": self.project, "TERRAIN_HEIGHT": terrain, "OUTPUT": folder / "tie.csv",
            "PAIRS": folder / "pairs.csv"})
        with open(folder / "tie.csv", newline="") as f:
            self.rows = list(csv.DictReader(f))
        self.photos = load_project(self.project).photos
        self.ids = list(dict.fromkeys(r["point_id"] for r in self.rows))
        index = {pid: k for k, pid in enumerate(self.ids)}
        self.point = np.array([index[r["point_id"]] for r in self.rows])
        self.obs = np.array([[float(r["col_px"]), float(r["row_px"])] for r in self.rows])
        ph = [self.photos[r["photo"]] for r in self.rows]
        # normalised camera coordinates (c = 1), Brown distortion inverted for the ODM camera
        self.normal = np.vstack([normaliser(p)(o[None]) for p, o in zip(ph, self.obs,
                                                                          strict=True)])
        self.res = intersect(self.point, self.normal, np.array([p.exterior.centre for p in ph]),
                             np.array([p.exterior.rotation for p in ph]), np.ones(len(ph)),
                             len(self.ids))
        self.back = np.vstack([ph[m].ground_to_pixel(self.res.xyz[self.point[m]][None])
                               for m in range(len(self.rows))])


@pytest.fixture(scope="module")
def ngi(orthority_data, tmp_path_factory):
    return Case(orthority_data, tmp_path_factory.mktemp("ngi"), "ngi")


@pytest.fixture(scope="module")
def odm(orthority_data, tmp_path_factory):
    return Case(orthority_data, tmp_path_factory.mktemp("odm"), "odm")


def dem_heights(path: Path, xy: np.ndarray) -> np.ndarray:
    import rasterio

    with rasterio.open(path) as dem:
        return np.array([v[0] for v in dem.sample(xy)], dtype=float)


@pytest.mark.parametrize("name, min_points, min_pairs", [("ngi", 60, 5), ("odm", 60, 5)])
def test_tie_points_agree_with_the_published_orientations(name, min_points, min_pairs,
                                                           request, orthority_data):
    case = request.getfixturevalue(name)
    stats = case.out["STATISTICS"]
    assert stats["untied_photos"] == [] and stats["pairs_tied"] >= min_pairs
    assert len(case.ids) >= min_points
    assert case.res.ok.all()
    error = np.hypot(*(case.back - case.obs).T)
    assert error.max() <= 1.5, np.percentile(error, [50, 99, 100])
    # on the ground the published DEM / DSM shows (independent of matcher and intersection):
    # NGI: 24 m DEM cells, 6 m ground pixels; ODM: a DSM of 0.8 m cells, 0.1 m ground pixels
    dem = orthority_data / ("ngi/dem.tif" if name == "ngi" else "odm/odm_dem/dsm.tif")
    dz = case.res.xyz[:, 2] - dem_heights(dem, case.res.xyz[:, :2])
    assert np.isfinite(dz).mean() > 0.8  # the DSM has holes
    assert np.nanmedian(np.abs(dz)) < (10.0 if name == "ngi" else 1.0), \
        np.nanpercentile(dz, [5, 50, 95])


def spread(xy: np.ndarray, first: int, n: int) -> list[int]:
    """``n`` indices of ``xy`` spread over the block (farthest-point sampling from ``first``)."""
    chosen = [first]
    d = np.hypot(*(xy - xy[first]).T)
    for _ in range(n - 1):
        k = int(np.argmax(d))
        chosen.append(k)
        d = np.minimum(d, np.hypot(*(xy - xy[k]).T))
    return chosen


def bundle_inputs(case: Case, folder: Path, shift_m: float, turn_deg: float, n_control: int
                  ) -> tuple[Path, Path, Path]:
    """(start project, measurements, control) for the bundle. Start: the published exteriors
    perturbed (seeded normal noise: ``shift_m`` per coordinate, ``turn_deg`` per angle)."""
    doc = yaml.safe_load(Path(case.project).read_text())
    rng = np.random.default_rng(7)
    for p in doc["photos"]:
        e = p["exterior"]
        for k in ("X0", "Y0", "Z0"):
            e[k] += float(rng.normal(0.0, shift_m))
        for k in ("omega", "phi", "kappa"):
            e[k] += float(rng.normal(0.0, turn_deg))
    measurements = case.folder / "tie.csv"  # pixels; the ODM camera stays the Brown model
    start = folder / "start.yaml"
    start.write_text(yaml.safe_dump(doc, sort_keys=False))
    rays = np.bincount(case.point)
    chosen = spread(case.res.xyz[:, :2], int(np.argmax(rays)), n_control)
    control = folder / "control.csv"
    with open(control, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["id", "X", "Y", "Z"])
        for k in chosen:
            out.writerow([case.ids[k], *case.res.xyz[k]])
    return start, measurements, control


@pytest.mark.parametrize("name, shift_m, turn_deg, sigma_m, pixels", [
    # NGI: ground pixel ~5.8 m; its control points come from 2-3 rays of 0.5 px (~3 m in plan,
    # ~6 m in height with a base/height of 0.5): they alone carry up to about a pixel, hence
    # 1.5 pixels (measured: 0.9 ground pixel, 0.85 pixel angle at most)
    ("ngi", 20.0, 0.3, 3.0, 1.5),
    # ODM: ground pixel ~0.1 m (measured: 0.6 ground pixel, 0.3 pixel angle at most)
    ("odm", 1.0, 0.3, 0.05, 1.0)])
def test_bundle_on_real_tie_points_reproduces_the_published_orientations(
        name, shift_m, turn_deg, sigma_m, pixels, request, tmp_path):
    case = request.getfixturevalue(name)
    start, measurements, control = bundle_inputs(case, tmp_path, shift_m, turn_deg, 8)
    out = toolbox.run("orientation:bundle", {
        "PROJECT": start, "INPUT": measurements, "CONTROL": control, "START": "project",
        "CONTROL_SIGMA_XY": sigma_m, "CONTROL_SIGMA_Z": sigma_m,
        "OUTPUT": tmp_path / "adjusted.yaml", "REPORT": tmp_path / "report.json"})
    from toolbox.photogrammetry.project import load_project

    adjusted = load_project(tmp_path / "adjusted.yaml").photos
    report = {p["photo"]: p for p in json.loads((tmp_path / "report.json").read_text())["photos"]}
    assert out["STATISTICS"]["photos"] == 4 and out["STATISTICS"]["sigma0"] < 1.0
    lines = []
    for pid, published in case.photos.items():
        a, e = adjusted[pid].exterior, published.exterior
        camera = published.camera
        if published.is_model:
            pixel = 1.0 / camera.focal_px[0]  # one pixel's angle, rad
        else:
            pixel = camera.pixel_size_mm / camera.c
        ground = pixel * (e.centre[2] - (NGI_TERRAIN if name == "ngi" else ODM_TERRAIN))
        d_pos = a.centre - e.centre
        d_ang = np.array([a.omega - e.omega, a.phi - e.phi, a.kappa - e.kappa])
        d_ang = (d_ang + np.pi) % (2 * np.pi) - np.pi
        turn = np.arccos(np.clip((np.trace(a.rotation.T @ e.rotation) - 1) / 2, -1, 1))
        lines.append(f"{pid}: dXYZ {np.round(d_pos, 3)} m, d(omega, phi, kappa) "
                     f"{np.round(np.degrees(d_ang), 4)} deg, rotation {np.degrees(turn):.4f} "
                     f"deg (ground pixel {ground:.2f} m, pixel angle {np.degrees(pixel):.4f})")
        std_pos = np.array([report[pid][k] for k in ("std_X0", "std_Y0", "std_Z0")])
        std_ang = np.array([report[pid][k] for k in ("std_omega", "std_phi", "std_kappa")])
        # within ``pixels`` ground pixels and pixel angles of the published orientation ...
        assert np.linalg.norm(d_pos) < pixels * ground and turn < pixels * pixel, \
            "\n".join(lines)
        # ... and within 3 of the bundle's own standard deviations
        assert (np.abs(d_pos) < 3 * std_pos).all() and (np.abs(d_ang) < 3 * std_ang).all(), \
            "\n".join(lines)
    print("\n".join(lines))


@pytest.mark.parametrize("name", ["ngi", "odm"])
def test_bundle_with_the_published_centres_as_gnss(name, request, tmp_path):
    """The other datum: the published projection centres as GNSS observations (the bundle's
    defaults, 0.10 m / 0.15 m), no control (the derived points only as CHECK points). The centres
    then come back trivially; the angles come from the tie points alone, which on four photos
    with 60-80 points determine them to about 0.05-0.2 degrees (the bundle's own standard
    deviations): measured 0.10-0.17 degrees off the published ones (NGI), 0.11-0.14 (ODM),
    i.e. 1.5-2.5 pixel angles; asserted: within 3 standard deviations and 3 pixel angles."""
    case = request.getfixturevalue(name)
    start, measurements, control = bundle_inputs(case, tmp_path, 20.0 if name == "ngi" else 1.0,
                                                 0.3, 8)
    rows = control.read_text().splitlines()
    checks = tmp_path / "checks.csv"
    checks.write_text("id,X,Y,Z,role\n" + "".join(f"{r},check\n" for r in rows[1:]))
    gnss = tmp_path / "gnss.csv"
    gnss.write_text("photo,X,Y,Z\n" + "".join(
        f"{pid},{p.exterior.centre[0]},{p.exterior.centre[1]},{p.exterior.centre[2]}\n"
        for pid, p in case.photos.items()))
    toolbox.run("orientation:bundle", {
        "PROJECT": start, "INPUT": measurements, "CONTROL": checks, "GNSS": gnss,
        "START": "project", "OUTPUT": tmp_path / "adjusted.yaml",
        "REPORT": tmp_path / "report.json"})
    from toolbox.photogrammetry.project import load_project

    adjusted = load_project(tmp_path / "adjusted.yaml").photos
    report = {p["photo"]: p for p in json.loads((tmp_path / "report.json").read_text())["photos"]}
    for pid, published in case.photos.items():
        a, e = adjusted[pid].exterior, published.exterior
        pixel = 1.0 / published.camera.focal_px[0] if published.is_model else \
            published.camera.pixel_size_mm / published.camera.c
        assert np.linalg.norm(a.centre - e.centre) < 0.5
        d_ang = np.array([a.omega - e.omega, a.phi - e.phi, a.kappa - e.kappa])
        d_ang = (d_ang + np.pi) % (2 * np.pi) - np.pi
        std_ang = np.array([report[pid][k] for k in ("std_omega", "std_phi", "std_kappa")])
        turn = np.arccos(np.clip((np.trace(a.rotation.T @ e.rotation) - 1) / 2, -1, 1))
        assert (np.abs(d_ang) < 3 * std_ang).all(), (pid, np.degrees(d_ang), np.degrees(std_ang))
        assert turn < 3 * pixel, (pid, np.degrees(turn), np.degrees(pixel))



def test_bundle_self_calibrates_the_real_brown_camera(odm, tmp_path):
    """ODM with its Brown camera's f, cx, cy, k1, k2 free, started 1.5 % / 7 px / 0.04 / 0.02 off
    OpenSfM's values: the written project's adjusted Brown camera agrees with OpenSfM's (an
    independent calibration of the same photos) within 3 of the bundle's own standard
    deviations, and the orientations stay within 1.5 ground pixels and pixel angles of the
    published ones."""
    from toolbox.photogrammetry.project import load_project

    start, measurements, control = bundle_inputs(odm, tmp_path, 1.0, 0.3, 8)
    doc = yaml.safe_load(start.read_text())  # a perturbed camera to start from
    model = doc["cameras"][0]["model"]
    model.update(focal_len=model["focal_len"] * 0.985, cx=0.0, cy=0.0, k1=-0.22, k2=0.08)
    start.write_text(yaml.safe_dump(doc, sort_keys=False))
    out = toolbox.run("orientation:bundle", {
        "PROJECT": start, "INPUT": measurements, "CONTROL": control, "START": "project",
        "CONTROL_SIGMA_XY": 0.05, "CONTROL_SIGMA_Z": 0.05,
        "SELF_CALIBRATION": "f, cx, cy, k1, k2",
        "OUTPUT": tmp_path / "adjusted.yaml", "REPORT": tmp_path / "report.json"})
    assert out["STATISTICS"]["sigma0"] < 1.0
    published = next(iter(odm.photos.values())).camera
    adjusted = load_project(tmp_path / "adjusted.yaml")
    cam = next(iter(adjusted.cameras.values()))
    assert cam.kind == "brown"
    (cal,) = json.loads((tmp_path / "report.json").read_text())["cameras"]
    # measured: f 911.17 +- 0.41 px (OpenSfM 911.72), cx 681.82 +- 0.69 (681.89), cy 463.34
    # +- 0.42 (462.50), k1 -0.26397 +- 0.00051 (-0.26406), k2 0.10200 +- 0.00044 (0.10189)
    for name, ours, theirs, bound in (
            ("f", cam.focal_px[0], published.focal_px[0], 1.0),
            ("cx", cam.principal_point_px[0], published.principal_point_px[0], 1.5),
            ("cy", cam.principal_point_px[1], published.principal_point_px[1], 1.5),
            ("k1", cam.coefficients["k1"], published.coefficients["k1"], 0.002),
            ("k2", cam.coefficients["k2"], published.coefficients["k2"], 0.002)):
        assert cal[name]["value"] == pytest.approx(ours, rel=1e-9, abs=1e-12)
        assert abs(ours - theirs) < min(bound, 3 * cal[name]["std"]), (name, ours, theirs)
    pixel = 1.0 / published.focal_px[0]
    for pid, p in odm.photos.items():
        a, e = adjusted.photos[pid].exterior, p.exterior
        ground = pixel * (e.centre[2] - ODM_TERRAIN)
        turn = np.arccos(np.clip((np.trace(a.rotation.T @ e.rotation) - 1) / 2, -1, 1))
        assert np.linalg.norm(a.centre - e.centre) < 1.5 * ground and turn < 1.5 * pixel, pid
    # ortho:batch reads the written project (Brown camera) directly: each ortho lands within a
    # 0.3 m cell of the ortho made with the published orientations and camera
    import rasterio
    from skimage.registration import phase_cross_correlation

    images = {Path(f).stem: f for f in (odm_data(odm) / "images").glob("*.tif")}
    shifts = {}
    for tag, source in (("adjusted", tmp_path / "adjusted.yaml"), ("published", odm.project)):
        doc = yaml.safe_load(Path(source).read_text())
        for p in doc["photos"]:
            p["image"] = str(images[p["id"]])
        path = tmp_path / f"{tag}_images.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        out = toolbox.run("ortho:batch", {
            "PROJECT": path, "DEM": odm_data(odm) / "odm_dem" / "dsm.tif", "CELL_SIZE": 0.3,
            "FOLDER": str(tmp_path / tag), "OUTPUT": tmp_path / f"{tag}.json"})
        assert out["STATISTICS"]["done"] == 4 and out["STATISTICS"]["failed"] == 0
    for ortho in sorted((tmp_path / "adjusted").glob("*.tif")):
        with rasterio.open(ortho) as a, rasterio.open(tmp_path / "published" / ortho.name) as b:
            assert a.transform.a == b.transform.a
            window = rasterio.windows.from_bounds(
                max(a.bounds.left, b.bounds.left), max(a.bounds.bottom, b.bounds.bottom),
                min(a.bounds.right, b.bounds.right), min(a.bounds.top, b.bounds.top),
                a.transform).round_offsets().round_lengths()
            da = a.read(window=window).astype(float)
            db = b.read(window=rasterio.windows.from_bounds(
                *rasterio.windows.bounds(window, a.transform), b.transform)
                .round_offsets().round_lengths()).astype(float)
        h, w = min(da.shape[1], db.shape[1]), min(da.shape[2], db.shape[2])
        ok = (da[3, :h, :w] == 255) & (db[3, :h, :w] == 255)
        ga = np.where(ok, da[:3, :h, :w].mean(axis=0), 0.0)
        gb = np.where(ok, db[:3, :h, :w].mean(axis=0), 0.0)
        shift, _, _ = phase_cross_correlation(ga, gb, upsample_factor=10, normalization=None)
        shifts[ortho.stem] = float(np.hypot(*shift))
        assert np.abs(ga - gb)[ok].mean() > 0.1  # two different orthos (measured: 0.7-1.5)
    # measured: 0.0 cells for all four (below the 0.1-cell upsampling step)
    assert len(shifts) == 4 and max(shifts.values()) < 1.0, shifts


def odm_data(case: Case) -> Path:
    """Orthority's odm/ folder (the fixture's data)."""
    return Path(case.data) / "odm"
