"""orientation:control with a reference orthophoto: control points measured automatically.

Scene: the demo's landscape (toolbox/demo/samples/landscape.py: town, fields, roads, relief
shading) draped on the demo terrain, photographed by a frame camera rendered through the
collinearity equations (ray marching on the DEM, :func:`render_photo`). The reference
orthophoto is the landscape itself on a 1 m grid, with another radiometry (gain and offset).
The control points are ground points of the rendered surface (photo pixels monoplotted with the
TRUE orientation); the project holds a PERTURBED orientation (centre moved by metres, angles by
tenths of a degree), so the predictions are several pixels off.

Truth: each matched measurement within 0.5 px of the point's pixel through the TRUE orientation;
a control point where the ground changed since the orthophoto (its ortho chip shows another
place's texture) is flagged low_correlation and keeps its prediction. (A control point with
wrong coordinates is NOT caught here: the photo shows the place those coordinates name, and the
matcher finds it; the bundle's data snooping is what catches that.)
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
import yaml

import toolbox

CRS = "EPSG:3003"
SIZE = 400  # px; 230 mm frame -> 0.575 mm pixels
C = 153.0
CENTRE = (1688300.0, 4799660.0, 750.0)  # ~430 m over the ground: ~1.6 m ground pixels
TRUE_ANGLES = (0.01, -0.015, 0.3)  # rad
SHIFT = (4.0, -3.0, 2.0)  # m, approximate - true centre
TURN = (0.004, -0.003, 0.005)  # rad, approximate - true angles (0.2-0.3 degrees)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    import rasterio
    from affine import Affine

    from toolbox.demo.samples.landscape import landscape_texture
    from toolbox.demo.samples.terrain import terrain
    from toolbox.photogrammetry.surface import DemSurface
    from toolbox.photogrammetry.synthetic import frame_photo, render_photo, write_photo

    folder = tmp_path_factory.mktemp("control_ortho")
    z, transform = terrain()
    texture = landscape_texture()
    photo = frame_photo(CENTRE, TRUE_ANGLES, width=SIZE, height=SIZE, principal_distance_mm=C,
                        crs=CRS, photo_id="p1")
    image = render_photo(photo, z, transform, texture, supersample=2, fill=0, dtype="uint8")
    write_photo(folder / "p1.tif", image)
    # control points on the rendered surface: photo pixels monoplotted with the true orientation
    surface = DemSurface.from_transform(np.asarray(z, dtype="float64"), transform)
    pixels = np.array([[90.3, 80.7], [310.6, 95.2], [200.1, 200.9], [85.8, 320.4],
                       [300.2, 310.5], [150.7, 250.3], [250.4, 140.6], [330.2, 220.8]])
    hit = photo.monoplot_pixels(pixels, surface)
    assert hit.ok.all()
    xyz = hit.xyz
    # the orthophoto: the landscape on a 1 m grid over the photo's footprint, other radiometry;
    # around the last point ("changed") the ground has changed since: another place's texture
    x0, y1 = CENTRE[0] - 420.0, CENTRE[1] + 420.0
    n = 840
    gx, gy = np.meshgrid(x0 + np.arange(n) + 0.5, y1 - np.arange(n) - 0.5)
    changed = (np.abs(gx - xyz[-1, 0]) < 40) & (np.abs(gy - xyz[-1, 1]) < 40)
    gx = np.where(changed, gx - 260.0, gx)
    gy = np.where(changed, gy + 190.0, gy)
    ortho = np.clip(0.8 * texture(gx, gy) + 25.0, 0, 255).astype("uint8")
    with rasterio.open(folder / "ortho.tif", "w", driver="GTiff", width=n, height=n, count=3,
                       dtype="uint8", crs=CRS, transform=Affine(1.0, 0, x0, 0, -1.0, y1)) as dst:
        dst.write(ortho)
    with rasterio.open(folder / "dem.tif", "w", driver="GTiff", width=z.shape[1],
                       height=z.shape[0], count=1, dtype="float32", crs=CRS,
                       transform=transform) as dst:
        dst.write(np.asarray(z, dtype="float32")[None])
    ids = [f"g{k}" for k in range(len(xyz) - 1)] + ["changed"]
    control = folder / "control.csv"
    control.write_text("id,X,Y,Z\n" + "".join(f"{i},{x},{y},{h}\n" for i, (x, y, h)
                                              in zip(ids, xyz, strict=True)))
    e = photo.exterior
    doc = {"format": "orientation-project", "version": 1, "crs": CRS, "angle_unit": "rad",
           "cameras": [{"name": "cam", "principal_distance_mm": C, "image_size_px": [SIZE, SIZE],
                        "pixel_size_mm": photo.camera.pixel_size_mm,
                        "frame_size_mm": [230.0, 230.0]}],
           "photos": [{"id": "p1", "camera": "cam", "image": "p1.tif", "exterior": {
               "X0": e.x0 + SHIFT[0], "Y0": e.y0 + SHIFT[1], "Z0": e.z0 + SHIFT[2],
               "omega": e.omega + TURN[0], "phi": e.phi + TURN[1], "kappa": e.kappa + TURN[2]}}]}
    project = folder / "project.yaml"
    project.write_text(yaml.safe_dump(doc, sort_keys=False))
    truth = {i: photo.ground_to_pixel(xyz[k][None])[0] for k, i in enumerate(ids)}
    return {"folder": folder, "project": project, "control": control, "truth": truth}


def test_control_points_matched_on_the_orthophoto_within_half_a_pixel(scene, tmp_path):
    out = toolbox.run("orientation:control", {
        "PROJECT": scene["project"], "CONTROL": scene["control"],
        "ORTHO": scene["folder"] / "ortho.tif", "DEM": scene["folder"] / "dem.tif",
        "OUTPUT": tmp_path / "template.csv",
        "MEASURED": tmp_path / "measured.csv"})
    with open(tmp_path / "template.csv", newline="") as f:
        rows = {r["point_id"]: r for r in csv.DictReader(f)}
    assert set(rows) == set(scene["truth"])
    predicted_error, errors = [], []
    for pid, r in rows.items():
        truth = scene["truth"][pid]
        pred = np.array([float(r["predicted_col_px"]), float(r["predicted_row_px"])])
        got = np.array([float(r["col_px"]), float(r["row_px"])])
        if pid == "changed":
            assert r["status"] == "low_correlation", r  # flagged, not moved
            assert np.allclose(got, pred)
            continue
        assert r["status"] == "matched", r
        assert float(r["score"]) >= 0.7
        predicted_error.append(np.hypot(*(pred - truth)))
        errors.append(np.hypot(*(got - truth)))
    # the approximate orientation puts the predictions several pixels off; matching fixes them
    assert min(predicted_error) > 2.0, predicted_error
    assert max(errors) < 0.5, errors
    assert out["STATISTICS"]["matched"] == 7
    assert sum(out["STATISTICS"]["not_matched"].values()) == 1
    with open(tmp_path / "measured.csv", newline="") as f:
        measured = list(csv.DictReader(f))
    assert {r["point_id"] for r in measured} == {f"g{k}" for k in range(7)}


def test_control_ortho_bad_input(scene, tmp_path):
    """An orthophoto in another CRS, MEASURED without ORTHO: exit 2, one line, nothing left."""
    import rasterio
    from conftest import run_cli

    other = tmp_path / "ortho_utm.tif"
    with rasterio.open(scene["folder"] / "ortho.tif") as src:
        profile = {**src.profile, "crs": "EPSG:32632"}
        with rasterio.open(other, "w", **profile) as dst:
            dst.write(src.read())
    out = tmp_path / "template.csv"
    for extra, name in ((["--ORTHO", other], "ORTHO"),
                        (["--MEASURED", tmp_path / "m.csv"], "MEASURED")):
        res = run_cli("run", "orientation:control", "--PROJECT", scene["project"], "--CONTROL",
                      scene["control"], "--OUTPUT", out, *extra)
        assert res.returncode == 2, res.stderr
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and name in lines[0] and "Traceback" not in res.stderr
        assert not out.exists() and not (tmp_path / "m.csv").exists()
