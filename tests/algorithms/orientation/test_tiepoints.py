"""orientation:tiepoints on a rendered 3 x 2 block (truth: the orientations the photos were
rendered with) and on bad input.

The check is independent of the matcher: each tie point is intersected from its measurements
with the TRUE orientations (least squares, :mod:`toolbox.photogrammetry.forward_intersection`)
and projected back into every photo; a wrong or imprecise measurement leaves a residual.
"""

from __future__ import annotations

import csv
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

import toolbox
from toolbox.cli import main

sys.path.insert(0, str(Path(__file__).parents[2] / "toolbox" / "matching"))
import block_scene  # noqa: E402


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    return block_scene.make_block(tmp_path_factory.mktemp("block"))


def read_measurements(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def truth_residuals(rows: list[dict[str, str]], photos: dict) -> np.ndarray:
    """Reprojection residual (px) of every measurement, through the true orientations (inf
    where the point's rays do not intersect: a wrong match)."""
    from toolbox.photogrammetry.forward_intersection import camera_observations, intersect

    ids = list(dict.fromkeys(r["point_id"] for r in rows))
    index = {pid: k for k, pid in enumerate(ids)}
    point = np.array([index[r["point_id"]] for r in rows])
    obs = np.array([[float(r["col_px"]), float(r["row_px"])] for r in rows])
    ph = [photos[r["photo"]] for r in rows]
    result = intersect(point, camera_observations(ph, obs, "pixel"),
                       np.array([p.exterior.centre for p in ph]),
                       np.array([p.exterior.rotation for p in ph]),
                       np.array([p.camera.c for p in ph]), len(ids))
    back = np.full_like(obs, np.inf)  # a point that does not intersect counts as wrong
    names = np.array([r["photo"] for r in rows])
    for name in set(names.tolist()):
        sel = (names == name) & result.ok[point]
        back[sel] = photos[name].ground_to_pixel(result.xyz[point[sel]])
    return np.hypot(*(back - obs).T)


def check_tracks(rows: list[dict[str, str]]) -> None:
    """Every point on >= 2 photos, never twice on one photo."""
    seen = {(r["point_id"], r["photo"]) for r in rows}
    assert len(seen) == len(rows)
    per_point: dict[str, int] = {}
    for r in rows:
        per_point[r["point_id"]] = per_point.get(r["point_id"], 0) + 1
    assert min(per_point.values()) >= 2


def overlapping_pairs(photos: list, height: float = 350.0, percent: float = 5.0) -> set:
    from toolbox.photogrammetry.coverage import overlaps, photo_footprint

    fps = [photo_footprint(p, None, height) for p in photos]
    return {(o.a, o.b) for o in overlaps(fps, set())
            if max(o.percent_of_a, o.percent_of_b) >= percent}


def test_block_with_orientations_matches_the_truth(block, tmp_path):
    import geopandas as gpd

    from toolbox.photogrammetry.surface import DemSurface
    from toolbox.photogrammetry.synthetic import hills_dem

    out = toolbox.run("orientation:tiepoints", {
        "PROJECT": block.project, "TERRAIN_HEIGHT": 350.0, "OUTPUT": tmp_path / "tie.csv",
        "POINTS": tmp_path / "tie.gpkg", "PAIRS": tmp_path / "pairs.csv"})
    stats = out["STATISTICS"]
    assert stats["pair_selection"] == "footprints" and stats["untied_photos"] == []
    rows = read_measurements(tmp_path / "tie.csv")
    assert list(rows[0]) == ["point_id", "photo", "col_px", "row_px", "sigma_px"]
    check_tracks(rows)
    res = truth_residuals(rows, {p.id: p for p in block.photos})
    assert len(res) > 500
    assert np.mean(res <= 0.5) >= 0.99, np.percentile(res, [50, 99, 100])
    # every overlap of the block is tied, with points spread over it
    with open(tmp_path / "pairs.csv", newline="") as f:
        pairs = {(r["photo_a"], r["photo_b"]): r for r in csv.DictReader(f)}
    expected = overlapping_pairs(block.photos)
    assert len(expected) == 15
    for a, b in expected:
        row = pairs.get((a, b)) or pairs[(b, a)]
        assert row["status"] == "ok" and int(row["kept"]) >= 10, row
        # the matches' distance from the epipolar planes of the true orientations
        assert float(row["median_epipolar_px"]) < 0.3, row
    assert sum(int(r["cells_3x3"]) == 9 for r in pairs.values()) >= 8
    assert stats["multi_ray_points"] > stats["points"] / 3
    # ground positions: on the rendered terrain (the DEM the photos were rendered from)
    import pyogrio

    info = pyogrio.read_info(tmp_path / "tie.gpkg", layer="tie_points")
    assert info["geometry_type"] == "Point Z" and info["features"] == stats["points"]
    assert list(info["fields"]) == ["point_id", "n_photos", "photos", "max_residual_px"]
    points = gpd.read_file(tmp_path / "tie.gpkg", layer="tie_points")
    z, transform = hills_dem(block_scene.BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=4)
    surface = DemSurface.from_transform(z.astype("float64"), transform)
    xyz = np.array([[g.x, g.y, g.z] for g in points.geometry])
    dz = xyz[:, 2] - surface.height(xyz[:, 0], xyz[:, 1])
    assert np.percentile(np.abs(dz), 99) < 2.0


def test_block_from_a_folder_without_cameras(block, tmp_path):
    out = toolbox.run("orientation:tiepoints", {
        "IMAGES": str(block.images[0].parent), "OUTPUT": tmp_path / "tie.csv",
        "TARGET": 32})
    assert out["STATISTICS"]["pair_selection"] == "thumbnails"
    assert out["STATISTICS"]["pairs_tied"] == 15
    rows = read_measurements(tmp_path / "tie.csv")
    check_tracks(rows)
    res = truth_residuals(rows, {p.id: p for p in block.photos})
    assert np.mean(res <= 0.5) >= 0.99, np.percentile(res, [50, 99, 100])


def test_block_pairs_from_a_gnss_log(block, tmp_path):
    """Pairs from approximate positions (the true centres with 30 m of noise, a GNSS log):
    each photo's nearest neighbour plus the Delaunay edges, fewer than every pair, all tied,
    and the measurements as good as with every pair."""
    rng = np.random.default_rng(8)
    log = tmp_path / "gnss.csv"
    log.write_text("photo,x,y\n" + "".join(
        f"{p.id},{p.exterior.x0 + rng.normal(0, 30)},{p.exterior.y0 + rng.normal(0, 30)}\n"
        for p in block.photos))
    out = toolbox.run("orientation:tiepoints", {
        "IMAGES": str(block.images[0].parent), "POSITIONS": log, "NEIGHBOURS": 1,
        "OUTPUT": tmp_path / "tie.csv", "PAIRS": tmp_path / "pairs.csv", "TARGET": 32})
    stats = out["STATISTICS"]
    assert stats["pair_selection"] == "neighbours (positions)"
    # 3 x 2 grid: the triangulation's 9 or 10 edges (4 forward, 3 side, 2 or 3 diagonals as
    # the noise falls), not all 15
    assert 9 <= stats["pairs_candidate"] <= 10
    assert stats["pairs_tied"] == stats["pairs_candidate"]
    assert stats["untied_photos"] == []
    rows = read_measurements(tmp_path / "tie.csv")
    check_tracks(rows)
    res = truth_residuals(rows, {p.id: p for p in block.photos})
    assert len(res) > 300
    assert np.mean(res <= 0.5) >= 0.99, np.percentile(res, [50, 99, 100])


@pytest.mark.parametrize("args, words", [
    (["--POSITIONS", "{log}"], ["POSITIONS", "no position", "s2_3"]),
    (["--PAIR_SELECTION", "neighbours"], ["PAIR_SELECTION", "neighbours", "POSITIONS"]),
    (["--PAIR_SELECTION", "footprints"], ["PAIR_SELECTION", "footprints", "TERRAIN_HEIGHT"]),
])
def test_pair_selection_bad_input(block, tmp_path, args, words):
    log = tmp_path / "gnss.csv"
    log.write_text("photo,x,y\n" + "".join(f"{p.id},{p.exterior.x0},{p.exterior.y0}\n"
                                             for p in block.photos[:5]))
    out = tmp_path / "t.csv"
    result = CliRunner().invoke(main, [
        "run", "orientation:tiepoints", "--IMAGES", str(block.images[0].parent),
        *[a.format(log=log) for a in args], "--OUTPUT", str(out)])
    assert result.exit_code == 2, result.output
    message = result.output.strip().splitlines()
    assert len(message) == 1 and all(w in message[0] for w in words), result.output
    assert not out.exists()


def test_textureless_photo_is_listed_with_zero_matches(block, tmp_path):
    from toolbox.photogrammetry.synthetic import write_photo

    folder = tmp_path / "images"
    folder.mkdir()
    for image in block.images[:2]:
        shutil.copy(image, folder / image.name)
    write_photo(folder / "water.tif", np.full((block_scene.SIZE, block_scene.SIZE), 90, np.uint8))
    doc = yaml.safe_load(block.project.read_text())
    keep = {"s1_1", "s1_2"}
    doc["photos"] = [p for p in doc["photos"] if p["id"] in keep]
    doc["photos"].append({**doc["photos"][1], "id": "water", "image": "water.tif"})
    (folder / "block.yaml").write_text(yaml.safe_dump(doc))
    feedback = toolbox.Feedback()
    out = toolbox.run("orientation:tiepoints", {
        "PROJECT": folder / "block.yaml", "TERRAIN_HEIGHT": 350.0, "OUTPUT": tmp_path / "t.csv",
        "PAIRS": tmp_path / "pairs.csv"}, feedback=feedback)
    assert out["STATISTICS"]["untied_photos"] == ["water"]
    with open(tmp_path / "pairs.csv", newline="") as f:
        pairs = list(csv.DictReader(f))
    water = [p for p in pairs if "water" in (p["photo_a"], p["photo_b"])]
    assert len(water) == 2
    assert all(p["status"] == "no_matches" and p["verified"] == "0" for p in water)
    assert any("water" in w for w in feedback.warnings)


def test_photos_without_overlap_fail_cleanly(block, tmp_path):
    doc = yaml.safe_load(block.project.read_text())
    doc["photos"] = doc["photos"][:2]
    doc["photos"][1]["exterior"]["X0"] += 20000.0  # far from the other
    for p in doc["photos"]:
        p["image"] = str(block.images[0].parent / p["image"])
    project = tmp_path / "apart.yaml"
    project.write_text(yaml.safe_dump(doc))
    out = tmp_path / "t.csv"
    result = CliRunner().invoke(main, ["run", "orientation:tiepoints", "--PROJECT", str(project),
                                       "--TERRAIN_HEIGHT", "350", "--OUTPUT", str(out)])
    assert result.exit_code == 2
    message = result.output.strip().splitlines()
    assert len(message) == 1 and "no photo pair" in message[0], result.output
    assert not out.exists()
    both = CliRunner().invoke(main, ["run", "orientation:tiepoints", "--PROJECT", str(project),
                                     "--IMAGES", str(tmp_path), "--OUTPUT", str(out)])
    assert both.exit_code == 2 and "PROJECT" in both.output and "Traceback" not in both.output
    assert not out.exists()


def test_control_template_predicts_the_image_positions(block, tmp_path):
    """orientation:control: the predicted pixels, traced back to the ground by the image ->
    ground ray marcher (monoplotting on the DEM the photos were rendered from, the other
    direction of the collinearity chain), give the control points back."""
    from toolbox.photogrammetry.surface import DemSurface
    from toolbox.photogrammetry.synthetic import hills_dem

    z, transform = hills_dem(block_scene.BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=4)
    surface = DemSurface.from_transform(z.astype("float64"), transform)
    rng = np.random.default_rng(3)
    xy = np.column_stack([rng.uniform(block_scene.X0 - 600, block_scene.X0 + 2200, 12),
                          rng.uniform(block_scene.Y0 - 600, block_scene.Y0 + 2000, 12)])
    xy = np.vstack([xy, [[block_scene.X0 + 30000.0, block_scene.Y0]]])  # on no photo
    heights = surface.height(xy[:, 0], xy[:, 1])
    heights[-1] = 300.0
    control = tmp_path / "control.csv"
    control.write_text("id,X,Y,Z\n" + "".join(f"c{k},{x},{y},{h}\n" for k, (x, y, h) in
                                              enumerate(zip(*xy.T, heights, strict=True))))
    out = toolbox.run("orientation:control", {"PROJECT": block.project, "CONTROL": control,
                                              "OUTPUT": tmp_path / "template.csv",
                                              "CHIPS": str(tmp_path / "chips")})
    assert out["STATISTICS"]["points_on_no_photo"] == ["c12"]
    rows = read_measurements(tmp_path / "template.csv")
    assert len(rows) >= 24 and {r["status"] for r in rows} == {"predicted"}
    photos = {p.id: p for p in block.photos}
    truth = {f"c{k}": xy[k] for k in range(12)}
    for r in rows:
        hit = photos[r["photo"]].monoplot_pixels(
            np.array([[float(r["col_px"]), float(r["row_px"])]]), surface)
        assert hit.ok.all()
        assert np.hypot(*(hit.xyz[0, :2] - truth[r["point_id"]])) < 0.2  # m; pixel ~4.4 m
        assert (tmp_path / "chips" / r["chip"]).exists()
