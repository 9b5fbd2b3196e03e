"""report:ortho_check of an ortho made from a paletted photo (the same grey levels stored as
shuffled colour codes with a grey colour table): ortho:photo warps the photo's colours, so the
check must take its photo chips from the colours too and find the check points as with the
plain photo (same statuses, shifts within 0.01 m), not compare colour codes with grey levels
("no match")."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import rasterio
import yaml

import toolbox

sys.path.insert(0, str(Path(__file__).parents[2] / "algorithms" / "ortho"))
import ortho_scene as scene  # noqa: E402

PIXELS = [(200.5, 200.5), (600.5, 200.5), (400.5, 400.5), (200.5, 600.5), (600.5, 600.5)]


def check(sc, folder: Path, image: Path, ortho: Path) -> list[dict[str, str]]:
    doc = yaml.safe_load(sc.project_path.read_text())
    doc["photos"][0]["image"] = str(image)
    project = folder / f"{image.stem}.yaml"
    project.write_text(yaml.safe_dump(doc))
    measurements = folder / "m.csv"
    with open(measurements, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point_id", "photo", "col_px", "row_px"])
        w.writerows([f"P{k}", "p1", c, r] for k, (c, r) in enumerate(PIXELS))
    # check points on the ground under those pixels (the photo's own orientation and DEM)
    photo = scene.frame_photo(scene.CENTRE, scene.ANGLES, width=scene.SIZE, height=scene.SIZE,
                              crs=scene.CRS)
    from toolbox.photogrammetry.surface import DemSurface

    hit = photo.monoplot_pixels(np.array(PIXELS), DemSurface.from_transform(
        np.asarray(sc.dem, dtype="float64"), sc.transform))
    assert hit.ok.all()
    points = folder / "check.csv"
    points.write_text("id,X,Y,Z\n" + "".join(f"P{k},{float(x)!r},{float(y)!r},{float(z)!r}\n"
                                             for k, (x, y, z) in enumerate(hit.xyz)))
    out = folder / f"c_{image.stem}.csv"
    toolbox.run("report:ortho_check", {"ORTHO": ortho, "PROJECT": project, "CHECK_POINTS": points,
                                       "MEASUREMENTS": measurements, "DEM": sc.dem_path,
                                       "OUTPUT": out})
    with open(out, newline="") as f:
        return list(csv.DictReader(f))


def test_ortho_check_of_a_paletted_photo_matches_the_plain_photos(tmp_path):
    sc = scene.make_scene(tmp_path)
    with rasterio.open(sc.photo_path) as src:
        grey, profile = src.read(1), src.profile
    perm = np.random.default_rng(5).permutation(256)  # colour code perm[g] shows grey g
    paletted = tmp_path / "pal.tif"
    with rasterio.open(paletted, "w", **profile) as dst:
        dst.write(perm[grey].astype(np.uint8), 1)
        dst.write_colormap(1, {int(perm[g]): (g, g, g, 255) for g in range(256)})
    # the ortho of the paletted photo: its colours (grey), as the plain photo's
    ortho = toolbox.run("ortho:photo", {"INPUT": paletted, "PROJECT": sc.project_path,
                                        "DEM": sc.dem_path, "CELL_SIZE": 5.0, "PHOTO": "p1",
                                        "OUTPUT": tmp_path / "ortho.tif"})["OUTPUT"]
    plain = check(sc, tmp_path, sc.photo_path, ortho)
    assert [r["status"] for r in plain] == ["matched"] * len(PIXELS)
    got = check(sc, tmp_path, paletted, ortho)
    assert [r["status"] for r in got] == ["matched"] * len(PIXELS)
    for a, b in zip(plain, got, strict=True):
        assert abs(float(a["dx_m"]) - float(b["dx_m"])) <= 0.01
        assert abs(float(a["dy_m"]) - float(b["dy_m"])) <= 0.01
