"""report:ortho_check on a rendered scene with a known truth: a tilted photo rendered through the
collinearity equations over 200 m of relief (the ortho tests' scene, finer texture), its
orthophoto by ortho:photo, check points taken where chosen photo pixels hit the DEM (so the
operator's image measurement is exact). The orthophoto as written must measure ~0; the same
orthophoto with its georeference moved by a known (dx, dy) must measure that shift; the
quality report must show the measured RMSE with its verdict."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio

import toolbox

sys.path.insert(0, str(Path(__file__).parents[1] / "ortho"))
import ortho_scene as scene  # noqa: E402

CELL = 2.5
PIXELS = [(250, 250), (550, 260), (400, 400), (260, 560), (540, 540), (330, 460)]
SHIFT = (3.2, -1.9)  # m, east and north: where the shifted orthophoto shows everything


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    from toolbox.photogrammetry.surface import DemSurface
    from toolbox.photogrammetry.synthetic import (
        frame_photo,
        hills_dem,
        render_photo,
        wave_texture,
        write_photo,
    )

    folder = tmp_path_factory.mktemp("ortho_check")
    z, transform = hills_dem(scene.BOUNDS, cell=10.0, relief=scene.RELIEF, base=scene.BASE,
                             seed=3)
    texture = wave_texture(seed=11, wavelength=(12.0, 45.0), waves=24)
    photo = frame_photo(scene.CENTRE, scene.ANGLES, width=scene.SIZE, height=scene.SIZE,
                        crs=scene.CRS)
    write_photo(folder / "p1.tif", render_photo(photo, z, transform, texture, dtype="uint8"))
    dem = scene.write_dem(folder / "dem.tif", z, transform)
    project = scene.project_yaml(folder / "project.yaml", "p1.tif")
    # check points: where chosen pixels (centres at +0.5) hit the DEM
    surface = DemSurface.from_transform(np.asarray(z, "float64"), transform)
    px = np.array(PIXELS, float) + 0.5
    hit = photo.monoplot_pixels((px[:, 0], px[:, 1]), surface)
    assert hit.ok.all()
    with open(folder / "check.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "X", "Y", "Z", "role"])
        w.writerow(["c0", 1688000, 4799000, 300, "control"])  # not a check point: left out
        w.writerows([[f"k{i}", *map(float, p)] + ["check"] for i, p in enumerate(hit.xyz)])
    with open(folder / "image.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point_id", "photo", "col_px", "row_px"])
        w.writerows([[f"k{i}", "p1", *p] for i, p in enumerate(px)])
    ortho = folder / "ortho.tif"
    toolbox.run("ortho:photo", {"INPUT": folder / "p1.tif", "PROJECT": project, "DEM": dem,
                                "CELL_SIZE": CELL, "OUTPUT": ortho})
    shifted = folder / "ortho_shifted.tif"
    with rasterio.open(ortho) as src:
        profile = src.profile
        data = src.read()
        profile["transform"] = src.transform * rasterio.Affine.identity()
        t = src.transform
    profile["transform"] = rasterio.Affine(t.a, t.b, t.c + SHIFT[0], t.d, t.e, t.f + SHIFT[1])
    profile.pop("blockxsize", None), profile.pop("blockysize", None), profile.pop("tiled", None)
    with rasterio.open(shifted, "w", **profile) as dst:
        dst.write(data)
    return folder, project, ortho, shifted


def run(case, ortho, out, **extra):
    folder, project = case[0], case[1]
    return toolbox.run("report:ortho_check", {
        "ORTHO": ortho, "PROJECT": project, "CHECK_POINTS": folder / "check.csv",
        "MEASUREMENTS": folder / "image.csv", "OUTPUT": out, **extra})


def test_the_orthophoto_as_written_measures_about_zero(case, tmp_path):
    out = tmp_path / "zero.csv"
    stats = run(case, case[2], out, DEM=case[0] / "dem.tif")["STATISTICS"]
    # the check points were made on the DEM: their Z is the DEM's (bilinear, as rendered)
    assert all(abs(float(r["z_minus_dem_m"])) < 0.01 for r in csv.DictReader(open(out)))
    assert stats["points"] == len(PIXELS) and stats["matched"] == len(PIXELS)  # c0 left out
    assert stats["rmse_planimetric_m"] < 0.15 * CELL  # a sub-cell measurement


def test_the_orientation_only_shapes_the_chip(case, tmp_path):
    """A project 15 m and 2 mrad off (the chip is still centred on the measured target) still
    measures the true orthophoto at about zero: the offsets come from the measurements."""
    wrong = scene.project_yaml(tmp_path / "wrong.yaml", str(case[0] / "p1.tif"),
                               centre=(scene.CENTRE[0] + 15.0, *scene.CENTRE[1:]),
                               angles=(scene.ANGLES[0] + 0.002, *scene.ANGLES[1:]))
    stats = run(case, case[2], tmp_path / "wrong.csv", PROJECT=wrong)["STATISTICS"]
    assert stats["matched"] == len(PIXELS) and stats["rmse_planimetric_m"] < 0.25 * CELL


def test_a_known_shift_is_measured(case, tmp_path):
    out = tmp_path / "shift.csv"
    stats = run(case, case[3], out)["STATISTICS"]
    assert stats["matched"] == len(PIXELS)
    assert stats["mean_x_m"] == pytest.approx(SHIFT[0], abs=0.3)
    assert stats["mean_y_m"] == pytest.approx(SHIFT[1], abs=0.3)
    assert stats["rmse_planimetric_m"] == pytest.approx(np.hypot(*SHIFT), abs=0.3)
    rows = list(csv.DictReader(open(out)))
    assert [r["point_id"] for r in rows] == [f"k{i}" for i in range(len(PIXELS))]
    for r in rows:
        assert r["status"] == "matched" and float(r["score"]) > 0.8
        assert float(r["dx_m"]) == pytest.approx(SHIFT[0], abs=0.4)


def test_a_point_off_the_dem_is_flagged(case, tmp_path):
    folder = case[0]
    rows = list(csv.reader(open(folder / "check.csv")))
    rows[2][3] = str(float(rows[2][3]) + 20.0)  # k0 20 m above the ground
    lifted = tmp_path / "lifted.csv"
    csv.writer(open(lifted, "w", newline="")).writerows(rows)
    from toolbox.feedback import Feedback

    feedback = Feedback()
    toolbox.run("report:ortho_check", {
        "ORTHO": case[2], "PROJECT": case[1], "CHECK_POINTS": lifted,
        "MEASUREMENTS": folder / "image.csv", "DEM": folder / "dem.tif",
        "OUTPUT": tmp_path / "lifted_out.csv"}, feedback=feedback)
    assert any("k0 (+20.0 m)" in w for w in feedback.warnings)


def test_a_shift_beyond_the_search_is_not_counted(case, tmp_path):
    stats = run(case, case[3], tmp_path / "edge.csv", SEARCH=2.0)["STATISTICS"]
    assert stats["matched"] == 0 and stats["rmse_planimetric_m"] is None


def test_quality_report_states_the_measured_accuracy(case, tmp_path):
    import json

    reports = tmp_path / "reports"
    reports.mkdir()
    res = run(case, case[3], tmp_path / "q.csv")
    (reports / "ortho_check.json").write_text(json.dumps({
        "algorithm": "report:ortho_check", "outputs": {"STATISTICS": res["STATISTICS"]}}))
    from toolbox.cartography.quality import Specification, build_sections, load_reports

    spec = Specification(5000.0, 0.3, 5.0, 15.0)  # 1.5 m allowed
    verdicts, sections = build_sections(load_reports(reports), spec)
    ortho = [s for s in sections if s.key == "ortho"]
    assert len(ortho) == 1 and len(ortho[0].figures) == 1  # the offsets plotted
    v = [v for v in verdicts if v.criterion.startswith("planimetric RMSE on check points")]
    assert len(v) == 1 and v[0].status == "FAIL"  # 3.7 m > 1.5 m
    assert v[0].measured.startswith(f"{np.hypot(*SHIFT):.1f}"[:2])


def test_image_measurements_in_mm_give_the_same_offsets(case, tmp_path):
    """x_mm, y_mm (fiducial system) read through the photo's interior orientation."""
    from toolbox.photogrammetry.project import load_project

    folder = case[0]
    photo = load_project(case[1]).photo("p1")
    rows = list(csv.DictReader(open(folder / "image.csv")))
    px = np.array([[float(r["col_px"]), float(r["row_px"])] for r in rows])
    mm = photo.pixel_transform.pixel_to_image(px)
    assert np.allclose(photo.pixel_transform.image_to_pixel(mm), px)
    table = tmp_path / "mm.csv"
    with open(table, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point_id", "photo", "x_mm", "y_mm"])
        w.writerows([[r["point_id"], "p1", *xy] for r, xy in zip(rows, mm)])
    a = run(case, case[3], tmp_path / "a.csv")["STATISTICS"]
    b = run(case, case[3], tmp_path / "b.csv", MEASUREMENTS=table)["STATISTICS"]
    assert b["matched"] == len(PIXELS)
    assert b["rmse_planimetric_m"] == pytest.approx(a["rmse_planimetric_m"], abs=1e-3)


def test_a_photo_not_in_the_project_is_one_line_exit_2(case, tmp_path):
    from conftest import run_cli

    folder = case[0]
    out = tmp_path / "bad_out.csv"
    proc = run_cli("run", "report:ortho_check", "--ORTHO", case[2], "--PROJECT", case[1],
                   "--CHECK_POINTS", folder / "check.csv", "--MEASUREMENTS",
                   folder / "image.csv", "--PHOTO", "p9", "--OUTPUT", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "PHOTO" in lines[0] and "'p9'" in lines[0]
    assert "Traceback" not in proc.stderr and not out.exists()


@pytest.mark.parametrize("which", ["ORTHO", "DEM"])
def test_an_ortho_or_dem_in_another_crs_than_the_project_is_refused(case, tmp_path, which):
    """ORTHO or DEM in UTM while the project (and its check points) is in EPSG:3003: one line
    naming it (an ortho matched no point, a DEM left every height difference blank, in
    silence)."""
    from rasterio.warp import calculate_default_transform, reproject

    source = case[2] if which == "ORTHO" else case[0] / "dem.tif"
    utm = tmp_path / "utm.tif"
    with rasterio.open(source) as src:
        t, w, h = calculate_default_transform(src.crs, "EPSG:32632", src.width, src.height,
                                              *src.bounds)
        profile = {k: v for k, v in src.profile.items()
                   if k not in ("blockxsize", "blockysize", "tiled")}
        with rasterio.open(utm, "w", **(profile | {"crs": "EPSG:32632", "transform": t,
                                                   "width": w, "height": h})) as dst:
            for b in range(1, src.count + 1):
                reproject(rasterio.band(src, b), rasterio.band(dst, b))
    params = {"ORTHO": utm} if which == "ORTHO" else {"DEM": utm}
    with pytest.raises(toolbox.InputDataError, match=f"{which} is in EPSG:32632 but PROJECT is "
                                                     "in EPSG:3003"):
        run(case, params.pop("ORTHO", case[2]), tmp_path / "x.csv", **params)
    assert not (tmp_path / "x.csv").exists()


def test_the_orthophoto_is_read_by_windows(case, tmp_path, monkeypatch):
    """The whole orthophoto was read into memory as float32 (a 40,000 x 40,000-cell RGB
    orthophoto: 19 GB; MemoryError or the OOM killer): only a window around each check point
    is read now, and the measurement is the same as before (about zero)."""
    from rasterio.io import DatasetReader

    read = DatasetReader.read
    cells = []

    def recording(self, *args, **kwargs):
        data = read(self, *args, **kwargs)
        if Path(self.name).name == "ortho.tif":
            cells.append(data.shape[-1] * data.shape[-2])
        return data

    monkeypatch.setattr(DatasetReader, "read", recording)
    stats = run(case, case[2], tmp_path / "windows.csv")["STATISTICS"]
    with rasterio.open(case[2]) as src:
        whole = src.width * src.height
    assert len(cells) == len(PIXELS) and max(cells) < whole / 10, (cells, whole)
    assert stats["matched"] == len(PIXELS) and stats["rmse_planimetric_m"] < 0.15 * CELL
