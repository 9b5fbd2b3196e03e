"""Space intersection: synthetic photos recover known 3D points; the normal case's closed form;
flagged points; orientation:intersect end to end (CSV and GeoPackage input)."""

import numpy as np
import pytest

import toolbox
from toolbox.errors import InputDataError
from toolbox.photogrammetry.collinearity import ground_to_image
from toolbox.photogrammetry.forward_intersection import (
    PARALLEL_RAYS,
    SINGLE_RAY,
    intersect,
    normal_case_coordinates,
)
from toolbox.photogrammetry.rotation import rotation_matrix

C = 303.55
PHOTOS = {  # a Siena-like block: two strips, tilts up to 0.02 rad
    "a1": ((1688135.0, 4799812.0, 1463.2), (0.014, -0.001, 0.050)),
    "a2": ((1688323.8, 4799814.2, 1464.7), (-0.009, -0.001, 0.050)),
    "b1": ((1688391.7, 4799470.2, 1465.9), (-0.000, 0.020, 3.122)),
    "b2": ((1688161.9, 4799464.6, 1466.7), (0.001, -0.006, 3.111)),
}


def observations(points, names, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    idx, xy, centres, rots = [], [], [], []
    for name in names:
        centre, angles = PHOTOS[name]
        r = rotation_matrix(*angles)
        img = ground_to_image(points, np.array(centre), r, C) + rng.normal(0, noise, (len(points), 2))
        idx.append(np.arange(len(points)))
        xy.append(img)
        centres.append(np.repeat([centre], len(points), axis=0))
        rots.append(np.repeat(r[None], len(points), axis=0))
    return np.concatenate(idx), np.vstack(xy), np.vstack(centres), np.concatenate(rots)


def ground_points(n=40, seed=1):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(1688150, 1688320, n), rng.uniform(4799550, 4799750, n),
                            rng.uniform(287, 343, n)])


@pytest.mark.parametrize("names", [("a1", "a2"), ("a1", "b1"), ("a1", "a2", "b1", "b2")])
def test_known_points_recovered_exactly(names):
    pts = ground_points()
    idx, xy, centres, rots = observations(pts, names)
    result = intersect(idx, xy, centres, rots, np.full(len(idx), C))
    assert result.ok.all()
    assert np.abs(result.xyz - pts).max() < 1e-6
    assert np.nanmax(result.max_ray_distance) < 1e-6
    assert np.abs(result.residuals_mm).max() < 1e-9


def test_noise_gives_matching_sigma0_and_std():
    pts = ground_points(400)
    sigma = 0.004  # mm, 4 um per image coordinate
    idx, xy, centres, rots = observations(pts, ("a1", "a2", "b1", "b2"), noise=sigma, seed=5)
    result = intersect(idx, xy, centres, rots, np.full(len(idx), C))
    # E[sigma0^2] = sigma^2 per point (r = 5): the mean over 400 points is close to it
    assert np.sqrt(np.nanmean(result.sigma0_mm ** 2)) == pytest.approx(sigma, rel=0.06)
    err = result.xyz - pts
    predicted = np.sqrt(np.nanmean(result.std_xyz ** 2, axis=0))
    np.testing.assert_allclose(np.sqrt(np.mean(err ** 2, axis=0)), predicted, rtol=0.15)


def test_normal_case_closed_form_equals_least_squares():
    """Brief section 7: O1 = (0,0,0), O2 = (B,0,0), R = I gives Z = -cB/p, X = B xi1/p."""
    base, c = 300.0, 150.0
    pts = np.array([[100.0, 50.0, -1500.0], [250.0, -80.0, -1450.0], [10.0, 10.0, -1600.0]])
    left = ground_to_image(pts, np.zeros(3), np.eye(3), c)
    right = ground_to_image(pts, np.array([base, 0, 0]), np.eye(3), c)
    np.testing.assert_allclose(left[:, 1], right[:, 1], atol=1e-12)  # no y-parallax
    x, y, z = normal_case_coordinates(left[:, 0], left[:, 1], right[:, 0], c, base)
    np.testing.assert_allclose(np.column_stack([x, y, z]), pts, atol=1e-9)
    idx = np.concatenate([np.arange(3), np.arange(3)])
    result = intersect(idx, np.vstack([left, right]), np.vstack([np.zeros((3, 3)),
                                                                 np.tile([base, 0, 0], (3, 1))]),
                       np.repeat(np.eye(3)[None], 6, axis=0), np.full(6, c))
    np.testing.assert_allclose(result.xyz, pts, atol=1e-9)


def test_single_ray_and_parallel_rays_are_flagged():
    pts = ground_points(3)
    idx, xy, centres, rots = observations(pts, ("a1", "a2"))
    keep = ~((idx == 0) & (np.arange(len(idx)) >= 3))  # point 0 only on the first photo
    idx, xy, centres, rots = idx[keep], xy[keep], centres[keep], rots[keep]
    # point 2: its second ray replaced by a ray parallel to the first (same direction, shifted)
    second = np.flatnonzero(idx == 2)[1]
    centres[second] = centres[np.flatnonzero(idx == 2)[0]] + [5.0, 0.0, 0.0]
    rots[second] = rots[np.flatnonzero(idx == 2)[0]]
    xy[second] = xy[np.flatnonzero(idx == 2)[0]]
    result = intersect(idx, xy, centres, rots, np.full(len(idx), C))
    assert result.status.tolist() == [SINGLE_RAY, 0, PARALLEL_RAYS]
    assert np.isnan(result.xyz[[0, 2]]).all() and np.isfinite(result.xyz[1]).all()


def siena_like_project(tmp_path):
    lines = ["version: 1", "crs: EPSG:3003", "angle_unit: rad", "cameras:",
             "  - {name: rc30, principal_distance_mm: 303.55, image_size_px: [16644, 16644],",
             "     pixel_size_mm: 0.014, frame_size_mm: [230, 230]}", "photos:"]
    for name, (centre, angles) in PHOTOS.items():
        lines.append(f"  - {{id: {name}, camera: rc30, strip: '{name[0]}', exterior: {{X0: "
                     f"{centre[0]}, Y0: {centre[1]}, Z0: {centre[2]}, omega: {angles[0]}, "
                     f"phi: {angles[1]}, kappa: {angles[2]}}}}}")
    path = tmp_path / "block.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_algorithm_from_pixels_in_csv_and_gpkg(tmp_path):
    import geopandas as gpd
    import pandas as pd

    from toolbox.photogrammetry.project import load_project

    project_path = siena_like_project(tmp_path)
    project = load_project(project_path)
    pts = ground_points(6, seed=3)
    rows = []
    for name in ("a1", "a2", "b1"):
        px = project.photos[name].ground_to_pixel(pts)
        rows += [{"point_id": f"P{k}", "photo": name, "col_px": c, "row_px": r}
                 for k, (c, r) in enumerate(px)]
    rows.append({"point_id": "lonely", "photo": "a1", "col_px": 8000.0, "row_px": 8000.0})
    table = tmp_path / "pts.csv"
    pd.DataFrame(rows).to_csv(table, index=False)
    out = toolbox.run("orientation:intersect", {"PROJECT": project_path, "INPUT": table,
                                                "OUTPUT": tmp_path / "out.gpkg",
                                                "REPORT": tmp_path / "out.json"})
    assert out["STATISTICS"]["status"] == {"ok": 6, "single_ray": 1}
    points = gpd.read_file(out["OUTPUT"], layer="points")
    assert points.crs.to_epsg() == 3003 and points.geometry.has_z.sum() == 6
    got = np.array([[g.x, g.y, g.z] for g in points.geometry[:6]])
    assert np.abs(got - pts).max() < 1e-6
    assert points.loc[6, "status"] == "single_ray" and points.geometry[6] is None
    rays = gpd.read_file(out["OUTPUT"], layer="rays")
    assert len(rays) == 18 and np.abs(rays["res_u_px"]).max() < 1e-6
    # the same table as a GeoPackage attribute table
    gpkg = tmp_path / "pts.gpkg"
    gpd.GeoDataFrame(pd.DataFrame(rows), geometry=[None] * len(rows), crs="EPSG:3003").to_file(
        gpkg, layer="obs")
    again = toolbox.run("orientation:intersect", {"PROJECT": project_path, "INPUT": gpkg,
                                                  "LAYER": "obs", "OUTPUT": tmp_path / "o2.gpkg"})
    assert again["STATISTICS"]["status"]["ok"] == 6


def test_algorithm_refuses_unknown_photos(tmp_path):
    project_path = siena_like_project(tmp_path)
    table = tmp_path / "pts.csv"
    table.write_text("point_id,photo,x_mm,y_mm\nP1,a1,1.0,2.0\nP1,zz,3.0,4.0\n")
    with pytest.raises(InputDataError, match="INPUT names photo\\(s\\) 'zz' that PROJECT does not"):
        toolbox.run("orientation:intersect", {"PROJECT": project_path, "INPUT": table,
                                              "OUTPUT": tmp_path / "o.gpkg"})
    table.write_text("point_id,photo,col\nP1,a1,1.0\n")
    with pytest.raises(InputDataError, match="needs columns col_px/row_px or x_mm/y_mm"):
        toolbox.run("orientation:intersect", {"PROJECT": project_path, "INPUT": table,
                                              "OUTPUT": tmp_path / "o.gpkg"})
    assert not (tmp_path / "o.gpkg").exists()
