"""mosaic:seamlines on two synthetic orthos: the Voronoi seam is the analytic bisector of the
nadir points, the least-cost seam stays inside the overlap and out of the building (and of
forbidden areas), the cut polygons partition the area exactly; overview + corridor routing."""

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from toolbox.demo.samples.mosaic import ORIGIN, make_block, pair_specs
from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.mosaic.partition import seamlines


def layers(path):
    return (gpd.read_file(path, layer="cut_polygons"), gpd.read_file(path, layer="seamlines"))


def valid_area(orthos):
    """The union of the orthos' valid data, from the generator's known boxes."""
    return shapely.union_all([shapely.box(*o.bounds) for o in orthos])


def overlap(orthos):
    return shapely.box(*orthos[0].bounds).intersection(shapely.box(*orthos[1].bounds))


def assert_partition(cells, area):
    union = shapely.union_all(list(cells.geometry))
    assert union.symmetric_difference(area).area < 1e-6 * area.area
    geoms = list(cells.geometry)
    for i in range(len(geoms)):
        for j in range(i + 1, len(geoms)):
            assert geoms[i].intersection(geoms[j]).area < 1e-6


def test_voronoi_seam_is_the_bisector_of_the_nadir_points(tmp_path):
    # nadir points placed off-axis so the bisector is slanted
    specs = pair_specs()
    specs[0]["nadir"], specs[1]["nadir"] = (260, 120), (740, 300)
    orthos, _ = make_block(tmp_path, specs)
    out = toolbox.run("mosaic:seamlines", {"INPUT": [str(o.path) for o in orthos],
                                           "METHOD": "voronoi", "OUTPUT": str(tmp_path / "v.gpkg")})
    cells, seams = layers(out["OUTPUT"])
    assert_partition(cells, valid_area(orthos))
    # analytic bisector: points p with |p - a| = |p - b|, i.e. (b - a)·p = (|b|² - |a|²) / 2
    a, b = np.array(orthos[0].nadir), np.array(orthos[1].nadir)
    d = b - a
    mid = (a + b) / 2
    along = np.array([-d[1], d[0]]) / np.hypot(*d)
    bisector = shapely.LineString([mid - 1e4 * along, mid + 1e4 * along])
    expected = bisector.intersection(overlap(orthos))
    # the cut polygons meet exactly on the bisector
    (_, _, shared), = seamlines(list(cells.geometry))
    inside = shared.intersection(overlap(orthos).buffer(-1e-6))  # without footprint-edge parts
    assert inside.length > 0.99 * expected.length
    assert inside.hausdorff_distance(expected) < 1e-4  # 0.1 mm (the -1e-6 m clip)
    coords = np.array([c for g in getattr(inside, "geoms", [inside]) for c in g.coords])
    assert np.abs(np.hypot(*(coords - a).T) - np.hypot(*(coords - b).T)).max() < 1e-6
    # the seamline follows the mosaic's cell edges along it: within half a cell diagonal
    cell = out["STATISTICS"]["seam_grid_cell"]
    core = overlap(orthos).buffer(-2 * cell)
    seam = seams.geometry[0].intersection(core)
    assert seam.hausdorff_distance(expected.intersection(core)) <= cell * np.sqrt(0.5) + 1e-6


def test_least_cost_seam_stays_in_the_overlap_and_out_of_the_building(pair, seams):
    orthos, building = pair
    cells, lines = layers(seams["least_cost"]["OUTPUT"])
    seam = shapely.union_all(list(lines.geometry))
    assert overlap(orthos).buffer(1e-6).contains(seam)
    # the building as each ortho shows it: the ground footprint and both displaced roofs
    everywhere = shapely.union_all([building] + [o.roof for o in orthos])
    assert not seam.intersects(everywhere)
    # whereas the Voronoi seam (x = 500 m local) cuts straight through it
    _, vlines = layers(seams["voronoi"]["OUTPUT"])
    assert shapely.union_all(list(vlines.geometry)).intersects(everywhere)
    assert lines["method"].tolist() == ["least_cost"]


def test_cut_polygons_partition_the_area_exactly(pair, seams):
    orthos, _ = pair
    for method in ("voronoi", "least_cost"):
        cells, _ = layers(seams[method]["OUTPUT"])
        assert sorted(cells["source"]) == ["ortho_a", "ortho_b"]
        assert_partition(cells, valid_area(orthos))
        stats = seams[method]["STATISTICS"]
        assert stats["partition_gap_area"] < 1e-6 and stats["max_overlap_area"] < 1e-6


def test_forbidden_areas_are_never_crossed(pair, tmp_path):
    orthos, building = pair
    ox, oy = ORIGIN
    forbidden = shapely.box(ox + 400, oy + 60, ox + 570, oy + 340)  # a gap only at x > 570
    frame = gpd.GeoDataFrame(geometry=[forbidden], crs="EPSG:3003")
    frame.to_file(tmp_path / "forbidden.gpkg")
    out = toolbox.run("mosaic:seamlines", {
        "INPUT": [str(o.path) for o in orthos], "FORBIDDEN": str(tmp_path / "forbidden.gpkg"),
        "OUTPUT": str(tmp_path / "f.gpkg")})
    cells, lines = layers(out["OUTPUT"])
    seam = shapely.union_all(list(lines.geometry))
    assert seam.intersection(forbidden.buffer(-1e-6)).length == 0  # may run along its edge
    assert seam.intersection(shapely.box(ox + 570, oy + 60, ox + 600, oy + 340)).length > 200
    assert_partition(cells, valid_area(orthos))


def test_building_footprint_layer_steers_the_seam(tmp_path):
    # the same wall colour in both orthos and no roof offset: only the footprint layer
    # tells the seam where the building is
    orthos, building = make_block(tmp_path, pair_specs(), displacement=0.0)
    inputs = [str(o.path) for o in orthos]
    gpd.GeoDataFrame(geometry=[building.buffer(5)], crs="EPSG:3003").to_file(tmp_path / "b.gpkg")
    plain = toolbox.run("mosaic:seamlines", {"INPUT": inputs, "DIFFERENCE_WEIGHT": 0,
                                             "GRADIENT_WEIGHT": 0, "OUTPUT": str(tmp_path / "p.gpkg")})
    steered = toolbox.run("mosaic:seamlines", {"INPUT": inputs, "DIFFERENCE_WEIGHT": 0,
                                               "GRADIENT_WEIGHT": 0, "BUILDINGS": str(tmp_path / "b.gpkg"),
                                               "OUTPUT": str(tmp_path / "s.gpkg")})
    seam_plain = shapely.union_all(list(layers(plain["OUTPUT"])[1].geometry))
    seam_steered = shapely.union_all(list(layers(steered["OUTPUT"])[1].geometry))
    assert seam_plain.intersects(building)  # shortest path: straight through
    assert not seam_steered.intersects(building.buffer(4))


def test_overview_then_corridor_matches_the_full_resolution_seam(pair):
    from toolbox.mosaic.partition import voronoi_cells
    from toolbox.mosaic.seams import PairCost, least_cost_cells
    from toolbox.mosaic.sources import open_source, valid_footprint

    orthos, building = pair
    sources = [open_source(o.path, k) for k, o in enumerate(orthos)]
    for s in sources:
        s.footprint = valid_footprint(s)
    footprints = [s.footprint for s in sources]
    cells = voronoi_cells(footprints, [s.nadir for s in sources])

    def cost_for(i, j):
        return PairCost(sources[i], sources[j], sources[0].crs)

    full, _ = least_cost_cells(cells, footprints, cost_for, 1.0, max_cells=10_000_000)
    coarse, report = least_cost_cells(cells, footprints, cost_for, 1.0, max_cells=12_000,
                                      feedback=Feedback())
    assert report[0]["method"] == "least_cost"
    everywhere = shapely.union_all([building] + [o.roof for o in orthos])
    for result in (full, coarse):
        seam = result[0].boundary.intersection(result[1].boundary)
        assert not seam.intersects(everywhere)
        assert shapely.union_all(result).symmetric_difference(shapely.union_all(footprints)).area \
            < 1e-6
    # both routes leave the same ortho owning the building
    for result in (full, coarse):
        assert result[0].contains(building) or result[1].contains(building)
    assert full[0].contains(building) == coarse[0].contains(building)


def test_heights_raster_steers_the_seam(tmp_path):
    # a DSM - DEM raster with the building 12 m tall: the only hint of it (no roof offset,
    # no radiometric terms)
    import rasterio
    from affine import Affine

    orthos, building = make_block(tmp_path, pair_specs(), displacement=0.0)
    ox, oy = ORIGIN
    heights = np.zeros((400, 1000), "float32")
    heights[180 - 3:220 + 3, 480 - 3:520 + 3] = 12.0  # rows from the north edge (y = 400 m)
    with rasterio.open(tmp_path / "h.tif", "w", driver="GTiff", width=1000, height=400, count=1,
                       dtype="float32", crs="EPSG:3003",
                       transform=Affine(1, 0, ox, 0, -1, oy + 400)) as dst:
        dst.write(heights, 1)
    out = toolbox.run("mosaic:seamlines", {
        "INPUT": [str(o.path) for o in orthos], "DIFFERENCE_WEIGHT": 0, "GRADIENT_WEIGHT": 0,
        "HEIGHTS": str(tmp_path / "h.tif"), "OUTPUT": str(tmp_path / "h.gpkg")})
    seam = shapely.union_all(list(layers(out["OUTPUT"])[1].geometry))
    assert not seam.intersects(building.buffer(2))


def nadir_points(folder):
    """nadirs.gpkg: the orthos' nadir points at local x = 300 (ortho_a) and 700 (ortho_b)."""
    ox, oy = ORIGIN
    points = gpd.GeoDataFrame({"photo": ["ortho_b", "ortho_a"]},
                              geometry=shapely.points([(ox + 700, oy + 200), (ox + 300, oy + 200)]),
                              crs="EPSG:3003")
    points.to_file(folder / "nadirs.gpkg")
    return points


def test_nadir_points_layer_sets_the_voronoi_centres(pair, tmp_path):
    orthos, _ = pair
    ox, oy = ORIGIN
    nadir_points(tmp_path)
    out = toolbox.run("mosaic:seamlines", {
        "INPUT": [str(o.path) for o in orthos], "METHOD": "voronoi",
        "NADIR_POINTS": str(tmp_path / "nadirs.gpkg"), "NADIR_FIELD": "photo",
        "OUTPUT": str(tmp_path / "n.gpkg")})
    seam = shapely.union_all(list(layers(out["OUTPUT"])[1].geometry))
    inside = seam.intersection(overlap(orthos).buffer(-1e-6))
    xs = np.array([c[0] for g in getattr(inside, "geoms", [inside]) for c in g.coords])
    assert np.allclose(xs, ox + 500.0)  # bisector of x = 300 and x = 700
    centres = gpd.read_file(out["OUTPUT"], layer="centres")
    assert centres.geometry.x.tolist() == [ox + 300, ox + 700]


@pytest.mark.parametrize("bad", [None, shapely.Point(), shapely.MultiPoint([(0, 0), (1, 1)])])
def test_nadir_points_not_single_points_are_refused(pair, tmp_path, bad):
    """A null, empty or multi-point nadir point is refused naming NADIR_POINTS and the feature
    row (it crashed: 'NoneType' has no attribute 'x'); no output is written."""
    orthos, _ = pair
    points = nadir_points(tmp_path)
    points.loc[1, "geometry"] = bad
    points.to_file(tmp_path / "bad.gpkg")
    with pytest.raises(ParameterError, match=r"NADIR_POINTS must hold one point .* row\(s\) 2 "
                       r"(are empty|hold several)"):
        toolbox.run("mosaic:seamlines", {
            "INPUT": [str(o.path) for o in orthos], "METHOD": "voronoi",
            "NADIR_POINTS": str(tmp_path / "bad.gpkg"), "NADIR_FIELD": "photo",
            "OUTPUT": str(tmp_path / "n.gpkg")})
    assert not (tmp_path / "n.gpkg").exists()


def test_a_cut_polygon_without_geometry_is_warned_about(pair, tmp_path):
    """A CUTLINES feature without geometry leaves its ortho without a cut polygon: the mosaic
    then takes that ortho only where the other has no data (the seam moves), so the run says
    so, naming the feature and the ortho (it was silent)."""
    orthos, _ = pair
    out = toolbox.run("mosaic:seamlines", {"INPUT": [str(o.path) for o in orthos],
                                           "METHOD": "voronoi", "OUTPUT": str(tmp_path / "s.gpkg")})
    cells = layers(out["OUTPUT"])[0]
    cells.loc[cells["source"] == "ortho_b", "geometry"] = None
    cells.to_file(tmp_path / "cut.gpkg", layer="cut_polygons")
    feedback = Feedback()
    toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos],
                                 "CUTLINES": str(tmp_path / "cut.gpkg"), "BLEND": "none",
                                 "OUTPUT": str(tmp_path / "m.tif")}, feedback=feedback)
    assert any("CUTLINES: 1 feature(s) without geometry, ignored: row 2 (ortho_b)" in w
               for w in feedback.warnings)
    assert any("no cut polygon for ortho_b" in w for w in feedback.warnings)


def test_nadir_points_and_cutlines_in_another_crs_are_reprojected(pair, tmp_path):
    """NADIR_POINTS (mosaic:seamlines) and CUTLINES (mosaic:build) in UTM while the orthos are
    in EPSG:3003: reprojected, as BUILDINGS and FORBIDDEN are (they were used with their UTM
    numbers: other centres; a 1000 km wide mosaic that ignored its cut lines)."""
    import rasterio

    orthos, _ = pair
    nadir_points(tmp_path).to_crs("EPSG:32632").to_file(tmp_path / "nadirs_utm.gpkg")
    cut = {}
    for name in ("nadirs", "nadirs_utm"):
        out = toolbox.run("mosaic:seamlines", {
            "INPUT": [str(o.path) for o in orthos], "METHOD": "voronoi",
            "NADIR_POINTS": str(tmp_path / f"{name}.gpkg"), "NADIR_FIELD": "photo",
            "OUTPUT": str(tmp_path / f"{name}_seams.gpkg")})
        cut[name] = layers(out["OUTPUT"])[0]
    for a, b in zip(cut["nadirs"].geometry, cut["nadirs_utm"].geometry, strict=True):
        assert a.symmetric_difference(b).area < 0.5  # m²: the points' round trip, microns
    cells = cut["nadirs"]
    cells.to_crs("EPSG:32632").to_file(tmp_path / "cut_utm.gpkg", layer="cut_polygons")
    for name, path in (("3003", tmp_path / "nadirs_seams.gpkg"),
                       ("utm", tmp_path / "cut_utm.gpkg")):
        toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos], "CUTLINES": str(path),
                                     "BLEND": "none", "OUTPUT": str(tmp_path / f"m_{name}.tif"),
                                     "SOURCE_INDEX": str(tmp_path / f"i_{name}.tif")})
    with rasterio.open(tmp_path / "i_3003.tif") as a, rasterio.open(tmp_path / "i_utm.tif") as b:
        # the reprojected polygons' edges bend by millimetres: the grid may gain a row
        window = rasterio.windows.from_bounds(*a.bounds, transform=b.transform)
        ours, theirs = a.read(1), b.read(1, window=window.round_offsets().round_lengths())
    assert ours.shape == theirs.shape and (ours > 0).mean() > 0.9
    assert (ours != theirs).mean() < 0.005  # cells along the cut line


def test_cutlines_file_read_from_its_cut_polygons_layer_whatever_the_layer_order(pair, tmp_path):
    """mosaic:seamlines' GeoPackage given as CUTLINES without a layer name is read from its
    ``cut_polygons`` layer even where that is not the file's first layer (a copy whose layers
    were reordered): its ``footprints`` layer, first in that copy, also has polygons and a
    ``source`` field, and was taken as the cut polygons in silence (two overlapping "cut
    polygons": the mosaic built from them, not from the seam)."""
    orthos, _ = pair
    inputs = [str(o.path) for o in orthos]
    out = toolbox.run("mosaic:seamlines", {"INPUT": inputs, "METHOD": "voronoi",
                                           "OUTPUT": str(tmp_path / "s.gpkg")})
    reordered = tmp_path / "reordered.gpkg"
    for name in ("footprints", "cut_polygons"):
        gpd.read_file(out["OUTPUT"], layer=name).to_file(reordered, layer=name)
    feedback = Feedback()
    built = toolbox.run("mosaic:build", {"INPUT": inputs, "CUTLINES": str(reordered),
                                         "BLEND": "none", "OUTPUT": str(tmp_path / "r.tif")},
                        feedback=feedback)
    direct = toolbox.run("mosaic:build", {"INPUT": inputs,
                                          "CUTLINES": f"{out['OUTPUT']}|layername=cut_polygons",
                                          "BLEND": "none", "OUTPUT": str(tmp_path / "d.tif")})
    import rasterio

    with rasterio.open(built["OUTPUT"]) as a, rasterio.open(direct["OUTPUT"]) as b:
        assert np.array_equal(a.read(), b.read())
    assert not any("none was named" in w for w in feedback.warnings)
