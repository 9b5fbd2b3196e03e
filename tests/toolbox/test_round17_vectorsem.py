"""Round 17, vector geometry semantics: curves and object coordinate systems of DXF restitution
(attribution:apply's reader), curves of OGR layers (GeoPackage CircularString...)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from toolbox.attribution.restitution import DXF_ARC_TOLERANCE, read_dxf

ezdxf = pytest.importorskip("ezdxf")


def _on_circle(geom, centre, radius):
    """(largest distance of a vertex from the circle, largest sagitta of a chord)."""
    v = shapely.get_coordinates(geom)
    d = np.hypot(v[:, 0] - centre[0], v[:, 1] - centre[1])
    mid = (v[1:] + v[:-1]) / 2
    return abs(d - radius).max(), (radius - np.hypot(mid[:, 0] - centre[0],
                                                     mid[:, 1] - centre[1])).max()


def test_dxf_bulges_arcs_and_circles_are_linearised_within_the_tolerance(tmp_path):
    doc = ezdxf.new()
    msp = doc.modelspace()
    # bulge 1: a half circle of radius 100 from (0, 0) to (200, 0), counter-clockwise (below)
    msp.add_lwpolyline([(0, 0, 0, 0, 1), (200, 0)], format="xyseb",
                       dxfattribs={"layer": "ROAD", "elevation": 5.0})
    # a closed outline of two half circles: the circle of radius 50 about (50, 0)
    msp.add_lwpolyline([(0, 0, 0, 0, 1), (100, 0, 0, 0, 1)], format="xyseb", close=True,
                       dxfattribs={"layer": "POOL"})
    msp.add_arc((0, 0), 100, 0, 90, dxfattribs={"layer": "ARC"})
    msp.add_circle((0, 0), 10, dxfattribs={"layer": "WELL"})
    path = tmp_path / "curves.dxf"
    doc.saveas(path)
    frame, report = read_dxf(path)
    assert report["skipped_dxf_entities"] == {}
    geoms = dict(zip(frame["code"], frame.geometry))
    road = geoms["ROAD"]  # was the straight chord, 200 long
    assert road.length == pytest.approx(100 * math.pi, abs=0.05)
    assert shapely.get_coordinates(road).tolist()[0] == [0, 0]
    assert shapely.get_coordinates(road).tolist()[-1] == [200, 0]
    assert shapely.get_coordinates(road, include_z=True)[:, 2].tolist() == \
        [5.0] * shapely.get_num_coordinates(road)
    assert road.distance(shapely.Point(100, -100)) < 1e-9  # bulge > 0: counter-clockwise
    for code, centre, radius, length in (("ROAD", (100, 0), 100, math.pi * 100),
                                         ("POOL", (50, 0), 50, math.pi * 100),
                                         ("ARC", (0, 0), 100, math.pi * 50),
                                         ("WELL", (0, 0), 10, math.pi * 20)):
        off, sagitta = _on_circle(geoms[code], centre, radius)
        assert off < 1e-9 and 0 < sagitta <= DXF_ARC_TOLERANCE, code
        # chords of sagitta s are shorter than their arcs by about s / 3r of the length
        short = length - geoms[code].length
        assert 0 < short <= length * DXF_ARC_TOLERANCE / (2 * radius), code
    assert geoms["POOL"].is_closed and geoms["WELL"].is_closed  # the pool was degenerate
    lost = math.pi * 2500 - shapely.Polygon(geoms["POOL"]).area  # chord segments: < s per metre
    assert 0 < lost <= math.pi * 100 * DXF_ARC_TOLERANCE


def test_dxf_mirrored_entities_are_put_in_world_coordinates(tmp_path):
    doc = ezdxf.new()
    msp = doc.modelspace()
    doc.blocks.new("TREE").add_circle((0, 0), 1)
    mirror = {"extrusion": (0, 0, -1)}  # OCS x = -WCS x (a mirrored copy in CAD)
    msp.add_lwpolyline([(10, 0), (20, 0), (20, 10)], dxfattribs={"layer": "WALL", **mirror})
    msp.add_blockref("TREE", (500, 500, 3), dxfattribs={"layer": "TREE", "rotation": 30,
                                                        **mirror})
    msp.add_text("A", height=2, rotation=0, dxfattribs={"layer": "NAME", "insert": (7, 8),
                                                        **mirror})
    msp.add_circle((40, 0), 5, dxfattribs={"layer": "WELL", **mirror})
    path = tmp_path / "mirrored.dxf"
    doc.saveas(path)
    frame, _ = read_dxf(path)
    rows = {row.code: row for row in frame.itertuples()}
    assert shapely.get_coordinates(rows["WALL"].geometry).tolist() == \
        [[-10, 0], [-20, 0], [-20, 10]]  # as ezdxf's vertices_in_wcs and GDAL's DXF driver
    tree = rows["TREE"]
    # the OCS's z axis is -z: the insertion point's OCS z 3 is the world's -3
    assert shapely.get_coordinates(tree.geometry, include_z=True).tolist() == [[-500, 500, -3]]
    assert tree.rotation == pytest.approx(150.0) and tree.scale_y == -1.0
    assert shapely.get_coordinates(rows["NAME"].geometry).tolist() == [[-7, 8]]
    assert rows["NAME"].rotation == pytest.approx(180.0)
    assert shapely.centroid(shapely.Polygon(rows["WELL"].geometry)).x == pytest.approx(-40)


def test_dxf_2d_polyline_bulge_and_splines(tmp_path):
    doc = ezdxf.new()
    msp = doc.modelspace()
    msp.add_polyline2d([(0, 0, 0, 0, -1), (20, 0)], format="xyseb",
                       dxfattribs={"layer": "P2D"})  # clockwise half circle: above
    spline = msp.add_spline([(0, 0), (10, 10), (20, 0), (30, 10)],
                            dxfattribs={"layer": "SPL"})
    path = tmp_path / "poly2d.dxf"
    doc.saveas(path)
    frame, report = read_dxf(path)
    assert report["skipped_dxf_entities"] == {}
    geoms = dict(zip(frame["code"], frame.geometry))
    assert geoms["P2D"].length == pytest.approx(10 * math.pi, abs=0.01)
    assert geoms["P2D"].distance(shapely.Point(10, 10)) < 1e-9
    fine = shapely.LineString([tuple(v)[:2] for v in spline.flattening(1e-5)])
    assert shapely.hausdorff_distance(geoms["SPL"], fine) <= DXF_ARC_TOLERANCE


def _curve_gpkg(path, radius=1000.0):
    """A GeoPackage holding one CircularString: the half circle of ``radius`` about
    (radius, 0) through (radius, radius) (ISO WKB written by hand: shapely has no curves)."""
    import struct

    from pyogrio.raw import write

    wkb = struct.pack("<BII6d", 1, 8, 3, 0.0, 0.0, radius, radius, 2 * radius, 0.0)
    write(str(path), geometry=np.array([wkb], dtype=object), field_data=[np.array([1])],
          fields=["code"], geometry_type="Unknown", crs="EPSG:32632", driver="GPKG",
          layer="arcs")


def test_ogr_curves_are_linearised_within_1e5_of_the_radius(tmp_path):
    from toolbox.io.vector import read_geometries, read_vector

    path = tmp_path / "curves.gpkg"
    _curve_gpkg(path)
    for geom in (read_vector(path).geometry.iloc[0], read_geometries(path)[1][0]):
        assert geom.geom_type == "LineString"
        v = shapely.get_coordinates(geom)
        assert abs(np.hypot(v[:, 0] - 1000, v[:, 1]) - 1000).max() < 1e-6  # on the arc
        mid = (v[1:] + v[:-1]) / 2
        # GDAL's default step (4 degrees) left chords 0.61 m inside a 1 km radius
        assert (1000 - np.hypot(mid[:, 0] - 1000, mid[:, 1])).max() <= 0.01
        assert geom.length == pytest.approx(1000 * math.pi, abs=0.02)
        assert geom.bounds[3] == pytest.approx(1000, abs=0.01)


def _overlapping_multipolygon(path):
    """One feature: a MultiPolygon of two 40 x 40 squares overlapping on 20 x 20 (invalid);
    the region it covers is their union, 2800 square units."""
    import geopandas as gpd

    squares = shapely.MultiPolygon([shapely.box(10, 10, 50, 50), shapely.box(30, 30, 70, 70)])
    gpd.GeoDataFrame({"id": [1]}, geometry=[squares], crs="EPSG:32632").to_file(path)


def test_an_area_of_overlapping_parts_is_their_union(tmp_path, caplog):
    from toolbox.io.vector import read_area

    path = tmp_path / "mask.gpkg"
    _overlapping_multipolygon(path)
    with caplog.at_level("WARNING", logger="toolbox"):
        area = read_area(str(path), "MASK")
    # GEOS make_valid's default (linework) method cut the overlap out: 2400
    assert area.area == pytest.approx(2800.0)
    assert area.covers(shapely.box(30, 30, 50, 50))
    assert any("MASK" in r.getMessage() and "invalid polygon" in r.getMessage()
               for r in caplog.records)



def test_mosaic_cut_polygon_of_overlapping_parts_is_their_union():
    from types import SimpleNamespace

    import geopandas as gpd

    from toolbox.mosaic.block import cells_from_layer

    squares = shapely.MultiPolygon([shapely.box(10, 10, 50, 50), shapely.box(30, 30, 70, 70)])
    layer = gpd.GeoDataFrame({"source": ["a"]}, geometry=[squares], crs="EPSG:32632")
    sources = [SimpleNamespace(name="a", index=0)]
    cells = cells_from_layer(layer, "source", sources, crs=layer.crs)
    assert shapely.area(cells[0]) == pytest.approx(2800.0)  # was 2400: the overlap cut out


@pytest.mark.parametrize("column, values", [("fid", [7, 7, -3]), ("FID", ["a", "b", "c"]),
                                            ("Fid", [5, 6, 7]), ("fid", [1, None, 2])])
def test_a_field_named_fid_is_written_as_a_field(tmp_path, column, values):
    """A GeoPackage took a field named fid as its key: repeated numbers -> UNIQUE constraint
    failed (exit 2 blaming OUTPUT), text -> 'Wrong field type for fid' (blamed on INPUT as
    corrupt), unique numbers -> the field left the attribute table."""
    import geopandas as gpd
    import pyogrio

    from toolbox.io.vector_write import write_layers

    frame = gpd.GeoDataFrame({column: values, "code": ["A", "B", "C"]},
                             geometry=shapely.points([0, 1, 2], [0, 0, 0]), crs="EPSG:32632")
    out = write_layers(tmp_path / "out.gpkg", {"layer": frame})
    back = pyogrio.read_dataframe(out, layer="layer")
    assert list(back.columns) == [column, "code", "geometry"]
    assert [None if v != v else v for v in back[column].tolist()] == values


def test_overlay_of_a_geometry_collection_keeps_its_areas():
    """A GeometryCollection of areas and a line (GeoJSON carries them) reached GEOS whole:
    'Overlay input is mixed-dimension', exit 3; its areas may overlap (a valid collection)."""
    from toolbox.topology.setops import clean_polygons, overlay_polygons

    collection = shapely.GeometryCollection([shapely.box(0, 0, 40, 40), shapely.box(20, 20, 60, 60),
                                             shapely.LineString([(0, 0), (-5, -5)])])
    b, issues, _ = clean_polygons(np.array([collection], dtype=object), "OVERLAY")
    assert [i.type for i in issues] == ["invalid_geometry"]
    a = np.array([shapely.box(-100, -100, 100, 100)], dtype=object)
    result = overlay_polygons(a, b, "intersection", 0.001)
    assert shapely.area(result.geoms).sum() == pytest.approx(2800.0)  # the two squares' union


def test_restitution_geometry_collection_is_split_into_its_parts(tmp_path):
    """A GeometryCollection (polygon + line) was one entity of no kind: a closed polygon code
    reported it 'unclosed_polygon, ends 69.6 apart'."""
    import geopandas as gpd

    from toolbox.attribution.restitution import read_ogr

    collection = shapely.GeometryCollection([
        shapely.MultiPolygon([shapely.box(30, 30, 70, 70)]), shapely.LineString([(0, 0), (5, 5)])])
    path = tmp_path / "collection.geojson"
    gpd.GeoDataFrame({"code": ["POOL"]}, geometry=[collection], crs="EPSG:32632").to_file(
        path, driver="GeoJSON")
    frame, report = read_ogr(str(path))
    assert frame["kind"].tolist() == ["polygon", "line"]
    assert frame["entity"].tolist() == [1, 1] and report["multipart_split"] == 1
    assert frame.geometry.iloc[0].equals(shapely.box(30, 30, 70, 70))


def test_dxf_read_through_ogr_leaves_paper_space_out(tmp_path, caplog):
    """GDAL's DXF driver reads the layouts' paper space into the same layer: a point at
    (10, 10, 0) in sheet millimetres became a TIN node beside world coordinates (exit 0)."""
    from toolbox.io.vector import read_geometries, read_vector
    from toolbox.io.vector_points import read_points_xyz

    doc = ezdxf.new()
    world = [(500000, 4800000, 100), (500100, 4800000, 110), (500000, 4800100, 120)]
    for xyz in world:
        doc.modelspace().add_point(xyz, dxfattribs={"layer": "PUNTI"})
    doc.layout("Layout1").add_point((10, 10, 0), dxfattribs={"layer": "PUNTI"})
    path = tmp_path / "paper.dxf"
    doc.saveas(path)
    with caplog.at_level("WARNING", logger="toolbox"):
        xyz = read_points_xyz(str(path))
    assert sorted(map(tuple, xyz.tolist())) == sorted(world)
    assert any("paper space" in r.getMessage() for r in caplog.records)
    assert len(read_vector(str(path))) == 3
    assert len(read_geometries(f"{path}|subset=\"Layer\" = 'PUNTI'")[1]) == 3


def test_dxf_texts_read_as_points_are_warned_about(tmp_path, caplog):
    """GDAL gives a DXF TEXT as a point at its insertion (Z 0 for a height label): it became a
    mass point at 0 m without a word."""
    from toolbox.io.vector_points import read_points_xyz

    doc = ezdxf.new()
    msp = doc.modelspace()
    for x, z in ((0, 100), (10, 110), (0, 120)):
        msp.add_point((x, x + z, z), dxfattribs={"layer": "PUNTI"})
    msp.add_text("110", height=2, dxfattribs={"layer": "QUOTE", "insert": (11, 121, 0)})
    path = tmp_path / "heights.dxf"
    doc.saveas(path)
    with caplog.at_level("WARNING", logger="toolbox"):
        assert len(read_points_xyz(str(path))) == 4  # read, as a point
    assert any("1 of its points are DXF texts (layers QUOTE)" in r.getMessage()
               for r in caplog.records)
    caplog.clear()
    with caplog.at_level("WARNING", logger="toolbox"):
        xyz = read_points_xyz(f'{path}|subset="Text" IS NULL')
    assert sorted(xyz[:, 2].tolist()) == [100, 110, 120]
    assert not any("DXF texts" in r.getMessage() for r in caplog.records)


def test_a_vertex_without_z_among_3d_vertices_is_warned_about(tmp_path, caplog):
    """A GeoJSON breakline [[x, y, 101.2], [x, y], [x, y, 108.8]]: OGR reads the middle vertex
    at Z 0 and the TIN took a breakline vertex at 0 m without a word."""
    import geopandas as gpd

    from toolbox.io.vector_points import vertices_xyz

    path = tmp_path / "breaklines.geojson"
    path.write_text('{"type": "FeatureCollection", "features": ['
                    '{"type": "Feature", "properties": {}, "geometry": {"type": "LineString", '
                    '"coordinates": [[12, 12, 101.2], [52, 52], [88, 88, 108.8]]}}, '
                    '{"type": "Feature", "properties": {}, "geometry": {"type": "LineString", '
                    '"coordinates": [[0, 0, 0], [10, 0, 0]]}}]}')
    frame = gpd.read_file(path)
    with caplog.at_level("WARNING", logger="toolbox"):
        xyz, _ = vertices_xyz(frame, name="BREAKLINES")
    assert xyz[1].tolist() == [52, 52, 0]  # as OGR reads it
    warned = [r.getMessage() for r in caplog.records if "Z = 0" in r.getMessage()]
    assert len(warned) == 1 and "1 feature(s) (row 1," in warned[0]  # not the line all at 0
