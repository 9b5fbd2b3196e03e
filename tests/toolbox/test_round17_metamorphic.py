"""Round 17, metamorphic relations: results that must not change when the input is only
reordered. The stereo pairs of a strip listed out of flight order (orientation:precision,
orientation:footprints)."""

from __future__ import annotations

import geopandas as gpd
import pytest

import toolbox

X0, Y0 = 1688000.0, 4799000.0
BASE = 552.0  # c = 150 mm, 900 m above Z = 100: side 1380 m, forward overlap 60 %


def strip_project(path, order, strip=True):
    """Two strips of four nadir photos (a0..a3, b0..b3 every BASE m, strips 1104 m apart),
    listed in ``order`` (indexes into a0..a3, b0..b3)."""
    photos = [(f"a{i}", "1", X0 + BASE * i, Y0) for i in range(4)] + \
             [(f"b{i}", "2", X0 + BASE * i, Y0 + 1104.0) for i in range(4)]
    lines = ["version: 1", "crs: EPSG:3003", "angle_unit: rad", "cameras:",
             "  - {name: cam, principal_distance_mm: 150.0, frame_size_mm: [230.0, 230.0],",
             "     image_size_px: [11500, 11500], pixel_size_mm: 0.02}", "photos:"]
    for pid, name, x, y in (photos[k] for k in order):
        lines.append(f"  - {{id: {pid}, camera: cam, strip: '{name}', exterior: {{X0: {x}, "
                     f"Y0: {y}, Z0: 1000.0, omega: 0.0, phi: 0.0, kappa: 0.0}}}}")
    path.write_text("\n".join(lines) + "\n")
    return path


NEIGHBOURS = {frozenset(p) for s in "ab" for p in
              [(f"{s}0", f"{s}1"), (f"{s}1", f"{s}2"), (f"{s}2", f"{s}3")]}


@pytest.mark.parametrize("order", [[2, 0, 3, 1, 6, 4, 7, 5], [1, 3, 0, 2, 5, 7, 4, 6]])
def test_precision_pairs_neighbours_of_a_strip_listed_out_of_order(tmp_path, order):
    """Photos listed out of flight order (by name, or as another tool wrote them): the stereo
    pairs are still the neighbours along the strip, base 552 m, not photos two or three
    spacings apart (a 1656 m base of photos that do not even overlap, sigma Z 3 x too good)."""
    out = toolbox.run("orientation:precision", {
        "PROJECT": strip_project(tmp_path / "p.yaml", order), "MEAN_HEIGHT": 100.0,
        "OUTPUT": tmp_path / "pr.json"})
    pairs = out["PRECISION"]
    assert {frozenset((r["photo_a"], r["photo_b"])) for r in pairs} == NEIGHBOURS
    assert [r["base_m"] for r in pairs] == pytest.approx([BASE] * 6)


def test_footprints_forward_overlap_of_a_strip_listed_out_of_order(tmp_path):
    out = toolbox.run("orientation:footprints", {
        "PROJECT": strip_project(tmp_path / "p.yaml", [2, 0, 3, 1, 6, 4, 7, 5]),
        "MEAN_HEIGHT": 100.0, "POINTS_PER_SIDE": 2, "OUTPUT": tmp_path / "fp.gpkg"})
    overlaps = gpd.read_file(out["OUTPUT"], layer="overlaps")
    forward = overlaps[overlaps["kind"] == "forward"]
    assert {frozenset(p) for p in zip(forward["photo_a"], forward["photo_b"])} == NEIGHBOURS
    assert forward["pct_of_a"].to_numpy() == pytest.approx(60.0)
    fp = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert fp["forward_overlap_pct"].dropna().to_numpy() == pytest.approx([60.0] * 6)
    assert not out["STATISTICS"]["design"]["failures"]


@pytest.mark.parametrize("order", [list(range(8)), [3, 2, 1, 0, 7, 6, 5, 4]])
def test_a_strip_in_flight_order_keeps_its_pairs_and_direction(tmp_path, order):
    from toolbox.photogrammetry.project import load_project

    project = load_project(strip_project(tmp_path / "p.yaml", order))
    listed = [p for p in project.photos]
    assert [(a.id, b.id) for a, b in project.consecutive_pairs()] == \
        [(listed[k], listed[k + 1]) for k in (0, 1, 2, 4, 5, 6)]


# -- mosaic:seamlines: the orthos' input order ------------------------------------------------
def three_orthos(folder):
    """Three overlapping RGB orthos of one smooth random scene (1 m cells, nodata 0), the second
    10 grey levels brighter."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(21)
    scene = np.clip(rng.normal(120, 40, (3, 150, 220)), 1, 255).astype(np.uint8)
    scene = np.stack([gaussian_filter(b.astype(float), 2) for b in scene]).astype(np.uint8)
    parts = {"sA": (scene[:, :100, :100], 0, 0),
             "sB": (np.clip(scene[:, :100, 70:170].astype(int) + 10, 1, 255).astype(np.uint8),
                    70, 0),
             "sC": (scene[:, 60:150, 40:220], 40, 60)}
    paths = {}
    for name, (arr, dx, dy) in parts.items():
        paths[name] = folder / f"{name}.tif"
        with rasterio.open(paths[name], "w", driver="GTiff", width=arr.shape[2],
                           height=arr.shape[1], count=3, dtype="uint8", crs="EPSG:3003",
                           transform=from_origin(1688000.0 + dx, 4800000.0 - dy, 1, 1),
                           nodata=0) as dst:
            dst.write(arr)
    return paths


def test_least_cost_cut_polygons_do_not_depend_on_the_input_order(tmp_path):
    """The same three orthos given as A, B, C and as C, A, B: the least-cost seams were routed
    from ends that differed by the rounding of the Voronoi polygons (computed in input order),
    so the cut polygons differed by 108 m² of 8464 (and in the order A, C, B one seam was left
    on the Voronoi line); now the same partition, each polygon keeping its input number."""
    paths = three_orthos(tmp_path)
    cuts = {}
    for order in (["sA", "sB", "sC"], ["sC", "sA", "sB"], ["sA", "sC", "sB"]):
        out = toolbox.run("mosaic:seamlines", {
            "INPUT": [paths[n] for n in order], "METHOD": "least_cost", "CENTRES": "footprint",
            "OUTPUT": tmp_path / f"{''.join(order)}.gpkg"})
        assert all(s["method"] == "least_cost" for s in out["STATISTICS"]["seams"])
        frame = gpd.read_file(out["OUTPUT"], layer="cut_polygons").set_index("source")
        assert {n: frame.loc[n, "source_id"] for n in order} == \
            {n: k + 1 for k, n in enumerate(order)}
        cuts[tuple(order)] = frame.geometry
    first, *others = cuts.values()
    for other in others:
        for name in ("sA", "sB", "sC"):
            assert first[name].symmetric_difference(other[name]).area < 1e-6


# -- orientation:models: heights of a planimetric block ---------------------------------------
def test_planimetric_models_write_no_made_up_height(tmp_path):
    """MODE planimetric adjusts X, Y only: the points were written with Z = 0 (a height nobody
    measured, and one that does not follow the control: shifting every control Z by 100 m left
    it at 0); now they are 2D points, as OGR reads them back. Spatial mode keeps its Z."""
    import shapely

    from toolbox.demo.samples.bundle_block import make

    sample = make(tmp_path / "data", {})
    for mode, with_z in (("planimetric", False), ("spatial", True)):
        out = toolbox.run("orientation:models", {
            "INPUT": sample["bundle_models"], "CONTROL": sample["bundle_control"],
            "CRS": "EPSG:3003", "MODE": mode, "OUTPUT": tmp_path / f"{mode}.gpkg"})
        points = gpd.read_file(out["OUTPUT"], layer="points")
        assert len(points) > 200
        assert (shapely.has_z(points.geometry.values) == with_z).all()
        if with_z:  # terrain 200-450 m high (not a plane at 0), projection centres above
            ground = points[~points["point_id"].str.startswith("O_")]
            assert 150 < ground.geometry.z.min() < ground.geometry.z.max() < 600
