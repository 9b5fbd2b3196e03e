"""Round 15, numerics at real-world coordinates: results must not change when the data set is
translated to projected coordinates (a UTM northing of 5,000,000, EPSG:3857 far from 0)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from toolbox.raster.grid_request import GridRequest


@pytest.mark.parametrize("x0, y0", [(0.0, 0.0), (500_000.0, 5_000_000.0),
                                    (1_688_000.0, 4_799_500.0), (20_000_000.0, 10_000_000.0)])
def test_extent_of_whole_cells_gives_the_same_grid_at_any_origin(x0, y0):
    """EXTENT 0.14 m wide, 5 mm cells: 28 x 28 cells wherever it lies (at a northing of
    5,000,000 the subtraction's last bit was 6e-9 of a cell, over the old 1e-9 slack: 29)."""
    ext = SimpleNamespace(bounds=(x0, y0, x0 + 0.14, y0 + 0.14), crs=None)
    grid = GridRequest(cell_size=0.005, extent=ext).grid(None, None)
    assert (grid.width, grid.height) == (28, 28)


@pytest.mark.parametrize("x0, y0", [(0.0, 0.0), (500_000.0, 5_000_000.0)])
def test_data_bounds_snapped_give_the_same_grid_at_any_origin(x0, y0):
    """Data over [-0.002, 0.143] snapped to 5 mm: [-0.005, 0.145], 30 cells each way."""
    grid = GridRequest(cell_size=0.005).grid((x0 - 0.002, y0 - 0.002, x0 + 0.143, y0 + 0.143),
                                             None)
    assert (grid.width, grid.height) == (30, 30)


@pytest.mark.parametrize("x0, y0", [(0.0, 0.0), (500_000.0, 5_000_000.0)])
def test_extent_on_a_template_lattice_at_any_origin(x0, y0):
    """A TEMPLATE at the origin cut to an EXTENT of 28 x 28 of its 5 mm cells."""
    from affine import Affine

    template = SimpleNamespace(transform=Affine(0.005, 0, x0, 0, -0.005, y0 + 1.0),
                               width=200, height=200, crs=None)
    ext = SimpleNamespace(bounds=(x0, y0 + 0.5, x0 + 0.14, y0 + 0.64), crs=None)
    grid = GridRequest(extent=ext, template=template).grid(None, None)
    assert (grid.width, grid.height) == (28, 28)
    assert grid.transform.c == pytest.approx(x0, abs=1e-9)


def _plane_models(ground_offset, model_offset):
    """Four overlapping models (4 x 3 points at 500 m spacing, 6 common with the next), each
    the ground rotated by 0.3·m rad about its centre and shifted to ``model_offset``; 6 XY
    control points, 2 mm noise on the model coordinates."""
    from toolbox.triangulation.models import ModelsRequest

    rng = np.random.default_rng(3)
    ground = {f"p{i}_{j}": np.array([i * 500.0, j * 500.0]) for i in range(9) for j in range(3)}
    mids, pids, xyz = [], [], []
    for m, i0 in enumerate([0, 2, 4, 5]):
        ids = [f"p{i}_{j}" for i in range(i0, i0 + 4) for j in range(3)]
        c, s = np.cos(0.3 * m), np.sin(0.3 * m)
        centre = np.mean([ground[p] for p in ids], axis=0)
        for p in ids:
            d = ground[p] - centre
            xy = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]) + model_offset
            mids.append(f"m{m}")
            pids.append(p)
            xyz.append([*(xy + rng.normal(0, 0.002, 2)), 300.0])
    control = ["p0_0", "p0_2", "p8_0", "p8_2", "p4_0", "p4_2"]
    cxyz = np.array([[*(ground[p] + ground_offset), 300.0] for p in control])
    truth = {p: g + ground_offset for p, g in ground.items()}
    return ModelsRequest(mids, pids, np.array(xyz), control, cxyz, "planimetric"), truth


def test_planimetric_models_do_not_depend_on_where_the_coordinates_lie():
    """The same block with model coordinates near 0 and ground near 0, then model coordinates
    near Siena's (EPSG:3003) and ground at EPSG:3857 magnitudes: the same sigma0 and the same
    adjusted points after shifting back (the raw normal equations gave sigma0 7.0 mm instead
    of 2.2 mm and points 1.5 cm off)."""
    from toolbox.triangulation.models import planimetric

    base_req, base_truth = _plane_models(np.zeros(2), np.zeros(2))
    base = planimetric(base_req)
    far = np.array([20_000_000.0, 10_000_000.0])
    req, truth = _plane_models(far, np.array([1_688_000.0, 4_799_500.0]))
    res = planimetric(req)
    assert res.sigma0_m == pytest.approx(base.sigma0_m, rel=1e-6)
    assert np.allclose(res.ground - far, base.ground, atol=1e-6)
    err = np.array([res.ground[k] - truth[p] for k, p in enumerate(res.points)])
    assert np.abs(err).max() < 0.01  # 2 mm noise
    # the parameters are the model -> ground transform of the raw model coordinates
    xu, yu, a, b = res.parameters[0]
    x, y = req.xyz[0, :2]
    p0 = res.points.index(req.point_ids[0])
    assert np.allclose([xu + a * x - b * y, yu + a * y + b * x], res.ground[p0], atol=0.01)


def test_tin_clipped_to_a_boundary_keeps_no_sliver_with_a_vertex_outside():
    """tin:delaunay with BOUNDARY, a boundary corner outside the data's hull: the boundary edge
    meets the hull edge next to a hull vertex outside the boundary; that vertex, the crossing
    and a boundary node made a zero-area triangle (4.7e-20 m², slope 90°) whose centroid fell
    inside by rounding. No node of a clipped TIN lies outside the boundary (shapely)."""
    import shapely

    from toolbox.terrain.tin.build import build_tin

    rng = np.random.default_rng(19)
    xy = rng.uniform(0, 0.2, (120, 2))
    lines = np.array([[0.01, 0.1, 3000.5], [0.19, 0.1000001, 3000.6],
                      [0.01, 0.1000002, 3000.2], [0.19, 0.0999999, 3000.1]])
    boundary = shapely.Polygon([[0.02, 0.02], [0.18, 0.03], [0.17, 0.17], [0.03, 0.18]])
    tin = build_tin(np.c_[xy, 3000 + 0.1 * xy[:, 0]], lines, np.array([0, 0, 1, 1]),
                    boundary=boundary)
    outside = shapely.distance(boundary, shapely.points(tin.xyz[:, :2])) > 1e-9
    assert not outside.any(), tin.xyz[outside]
    p = tin.xyz[tin.triangles]
    area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    assert area.min() > 1e-12  # the thinnest real triangles: the breaklines 1e-7 apart


def _tin_data(tmp_path, x0, y0, boundary):
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(19)
    xy = rng.uniform(0, 0.2, (120, 2)) + [x0, y0]
    gpd.GeoDataFrame(geometry=shapely.points(np.c_[xy, 3000 + 0.1 * (xy[:, 0] - x0)]),
                     crs="EPSG:32632").to_file(tmp_path / "p.gpkg")
    gpd.GeoDataFrame(geometry=[shapely.Polygon(np.array(boundary) + [x0, y0])],
                     crs="EPSG:32632").to_file(tmp_path / "b.gpkg")


def test_tin_boundary_inside_the_hull_is_not_warned_about_at_utm_coordinates(tmp_path):
    """A BOUNDARY inside the points' hull at a northing of 5,000,000 was reported 3.5e-18
    square units outside it, warned as 'BOUNDARY extends 0.0 square units beyond the points'
    convex hull'; a real 4.7e-5 m² outside (cm data) was also printed as 0.0."""
    import toolbox
    from toolbox.feedback import Feedback

    _tin_data(tmp_path, 500_000.0, 5_000_000.0,
              [[0.03, 0.03], [0.17, 0.035], [0.16, 0.16], [0.04, 0.17]])
    feedback = Feedback()
    stats = toolbox.run("tin:delaunay", {"INPUT": tmp_path / "p.gpkg", "BOUNDARY":
                                         tmp_path / "b.gpkg", "OUTPUT": tmp_path / "t.gpkg"},
                        feedback=feedback)["STATISTICS"]
    assert stats["boundary"]["boundary_area_outside_data_hull"] == 0.0
    assert not any("BOUNDARY extends" in w for w in feedback.warnings)
    _tin_data(tmp_path, 0.0, 0.0, [[0.02, 0.02], [0.18, 0.03], [0.17, 0.17], [0.03, 0.18]])
    feedback = Feedback()
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "p.gpkg", "BOUNDARY": tmp_path / "b.gpkg",
                                 "OUTPUT": tmp_path / "t.gpkg", "OVERWRITE": True},
                feedback=feedback)
    assert any("BOUNDARY extends 4.715" in w for w in feedback.warnings), feedback.warnings


@pytest.mark.parametrize("x0, y0, cell, n", [(3_661_007.95, 3_179_740.4, 0.05, 1091),
                                             (4_260_589.9, 3_202_960.35, 0.05, 1027),
                                             (2_843_595.4, 4_681_854.8, 0.1, 561)])
def test_ortho_and_mosaic_grids_on_the_lattice_get_no_extra_cell(x0, y0, cell, n):
    """Bounds on the cell lattice (an ortho EXTENT, a mosaic sheet) n cells wide: n x n cells.
    With the fixed 1e-9-cell slack about 1 grid in 4 at such coordinates got an extra
    column or row."""
    import shapely
    from affine import Affine

    from toolbox.mosaic.block import mosaic_grid
    from toolbox.ortho.plan import lattice_grid

    x1, y1 = round(x0 + n * cell, 6), round(y0 + n * cell, 6)
    grid = lattice_grid((x0, y0, x1, y1), cell, None)
    assert (grid.width, grid.height) == (n, n)
    src = SimpleNamespace(res=(cell, cell), name="a",
                          transform=Affine(cell, 0, x0 - 10 * cell, 0, -cell, y1 + 10 * cell))
    grid = mosaic_grid([src], None, None, shapely.box(x0, y0, x1, y1))
    assert (grid.width, grid.height) == (n, n)
    assert grid.transform.c == pytest.approx(x0, abs=1e-6)


@pytest.mark.parametrize("x0, y0, crs", [(0.0, 0.0, "EPSG:32632"),
                                         (20_000_000.0, 10_000_000.0, "EPSG:3857")])
@pytest.mark.parametrize("method", ["tin_linear", "nearest"])
def test_points_on_the_grid_lattice_fill_every_cell(tmp_path, x0, y0, crs, method):
    """20 x 20 points at the 1 cm cell centres gridded at 1 cm: every cell is a data point, so
    every cell has its height (z = 3000 + x). dem:tin_linear lost the north row at any origin
    (a 4e-16-cell rounding put the hull edge outside the centres) and at EPSG:3857 magnitudes
    every method lost the south row (the hull test's 1e-9-cell slack)."""
    import geopandas as gpd
    import rasterio
    import shapely

    import toolbox

    n, cell = 20, 0.01
    gx, gy = np.meshgrid((np.arange(n) + 0.5) * cell, (np.arange(n) + 0.5) * cell)
    xy = np.c_[gx.ravel(), gy.ravel()]
    gpd.GeoDataFrame(geometry=shapely.points(np.c_[xy + [x0, y0], 3000 + xy[:, 0]]),
                     crs=crs).to_file(tmp_path / "p.gpkg")
    out = tmp_path / "d.tif"
    toolbox.run(f"dem:{method}", {"INPUT": tmp_path / "p.gpkg", "CELL_SIZE": cell, "OUTPUT": out,
                                  "EXTENT": f"{x0},{y0},{x0 + n * cell},{y0 + n * cell}"})
    with rasterio.open(out) as src:
        z = src.read(1, masked=True)
    assert z.count() == n * n
    expected = 3000 + (np.arange(n) + 0.5) * cell
    np.testing.assert_allclose(z.filled(np.nan), np.broadcast_to(expected, (n, n)), atol=1e-3)


def test_tin_raster_of_a_lattice_tin_covers_its_border_cells():
    """rasterize_tin of the TIN of the cell centres themselves: no NaN (the north row was)."""
    from toolbox.terrain.tin.kernels import rasterize_tin, triangulate

    n, cell = 20, 0.01
    gx, gy = np.meshgrid((np.arange(n) + 0.5) * cell, (np.arange(n) + 0.5) * cell)
    xy = np.c_[gx.ravel(), gy.ravel()]
    tri = triangulate(xy)
    for compiled in (True, False):
        z = rasterize_tin(np.c_[xy, xy[:, 0]], tri, 0.0, n * cell, cell, cell, n, n,
                          compiled=compiled)
        assert not np.isnan(z).any(), (compiled, np.flatnonzero(np.isnan(z).all(axis=1)))


@pytest.mark.parametrize("lo, hi, n", [(5_735_344.0, 5_735_345.6, 16), (19_561_212.9, 19_561_213.7, 8),
                                       (9_686_271.0, 9_686_274.2, 32)])
def test_map_grid_keeps_the_lines_on_the_frame_edges(lo, hi, n):
    """carto:grid every 0.1 m over a frame whose edges are multiples of it: n + 1 lines, inside
    the frame (the 1e-9 slack dropped an edge line at these coordinates, and k x 0.1 an ulp
    beyond the edge was clipped away by the sheet)."""
    from toolbox.cartography.grid import grid_values

    values = grid_values(lo, hi, 0.1)
    assert len(values) == n + 1
    assert lo <= values[0] <= lo + 1e-6 and hi - 1e-6 <= values[-1] <= hi  # inside the frame


def test_tin_warnings_print_millimetre_z_spreads(tmp_path):
    """Duplicates 0.4 mm apart in Z and breaklines crossing 0.3 mm apart: the warnings said
    'largest Z spread 0.000' and 'disagreement 0.000'."""
    import geopandas as gpd
    import shapely

    import toolbox
    from toolbox.feedback import Feedback

    xyz = np.array([[0, 0, 10], [1, 0, 10], [0, 1, 10], [1, 1, 10], [1, 1, 10.0004]])
    gpd.GeoDataFrame(geometry=shapely.points(xyz), crs="EPSG:32632").to_file(tmp_path / "p.gpkg")
    lines = [[(0.1, 0.5, 10.0), (0.9, 0.5, 10.0)], [(0.5, 0.1, 10.0003), (0.5, 0.9, 10.0003)]]
    gpd.GeoDataFrame(geometry=[shapely.LineString(v) for v in lines],
                     crs="EPSG:32632").to_file(tmp_path / "b.gpkg")
    feedback = Feedback()
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "p.gpkg", "BREAKLINES": tmp_path / "b.gpkg",
                                 "OUTPUT": tmp_path / "t.gpkg"}, feedback=feedback)
    assert any("largest Z spread 0.0004" in w for w in feedback.warnings), feedback.warnings
    assert any("largest disagreement 0.0003" in w for w in feedback.warnings), feedback.warnings
    feedback = Feedback()
    toolbox.run("dem:tin_linear", {"INPUT": tmp_path / "p.gpkg", "BREAKLINES": tmp_path / "b.gpkg",
                                   "CELL_SIZE": 0.1, "OUTPUT": tmp_path / "d.tif"},
                feedback=feedback)
    assert any("in Z by up to 0.0003" in w for w in feedback.warnings), feedback.warnings
