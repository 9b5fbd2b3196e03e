"""Round 16, sweep "docs": what the help and the docs state is what a run does."""

import math

import pytest

import toolbox


def test_precision_without_project_edge_is_at_the_edge_of_a_23cm_frame(tmp_path):
    """The help: sigma X/Y "at the edge of the format (XI default: half the format width)".
    Without PROJECT the edge fields were the centre's (xi = eta = 0) in silence; now the edge of
    a standard 23 x 23 cm frame, by hand: m_b·sqrt((ξ·Z/(c·B))²·σp² + σξ²)."""
    out = toolbox.run("orientation:precision", {"PRINCIPAL_DISTANCE": 152, "BASE": 1520,
                                                "DISTANCE": 1520, "OUTPUT": tmp_path / "p.json"})
    (row,) = out["PRECISION"]
    mb, sp = 1520 / 0.152, 5e-6
    edge = mb * math.sqrt((0.115 * 1520 / (0.152 * 1520)) ** 2 * sp ** 2 + sp ** 2 / 2)
    assert row["xi_edge_mm"] == row["eta_edge_mm"] == 115.0
    assert row["sigma_x_edge_m"] == pytest.approx(edge, rel=1e-9)
    assert row["sigma_y_edge_m"] == pytest.approx(edge, rel=1e-9)
    assert row["sigma_x_centre_m"] == pytest.approx(mb * sp / math.sqrt(2), rel=1e-9)
    out = toolbox.run("orientation:precision", {"PRINCIPAL_DISTANCE": 152, "BASE": 1520,
                                                "DISTANCE": 1520, "XI": 50, "ETA": 0,
                                                "OUTPUT": tmp_path / "q.json"})
    (row,) = out["PRECISION"]
    assert (row["xi_edge_mm"], row["eta_edge_mm"]) == (50, 0)
    assert row["sigma_y_edge_m"] == pytest.approx(row["sigma_y_centre_m"])


# rectify.md: "similarity (4: image plane parallel to the ground...)", pixels "rows growing down",
# "fewer control points than 2 / 3 / 4 (similarity / affine / homography) refused". A vertical
# photo in pixels maps onto the ground by a mirrored similarity (rows down, Y up): the direct form
# was fitted, with tens of metres of residuals on exact points (exit 0), and 2 points were refused
# as "collinear".
X0, Y0 = 1688000.0, 4799100.0



def _rows(kappa_deg=20.0, scale=2.0, pts=((0, 0), (60, 0), (60, 40), (0, 40), (30, 20), (10, 33))):
    """Exact control: ground = shift + scale·R(kappa)·(col, -row)."""
    k = math.radians(kappa_deg)
    out = []
    for c, r in pts:
        x, y = c, -r
        out.append((c, r, X0 + scale * (math.cos(k) * x - math.sin(k) * y),
                    Y0 + scale * (math.sin(k) * x + math.cos(k) * y)))
    return out


def test_rectify_similarity_of_a_vertical_photo_in_pixels_is_exact(tmp_path):
    import numpy as np

    rows = _rows()
    path = tmp_path / "gcps.csv"
    path.write_text("id,col,row,X,Y\n" + "".join(f"P{k},{c},{r},{x},{y}\n"
                                                 for k, (c, r, x, y) in enumerate(rows)))
    out = toolbox.run("rectify:estimate", {"INPUT": path, "CRS": "EPSG:3003",
                                           "MODEL": "similarity", "ROBUST": "none",
                                           "OUTPUT": tmp_path / "t.json"})
    stats = out["STATISTICS"]
    assert stats["max_residual"] < 1e-6
    assert stats["ground_size_of_image_unit"] == pytest.approx(2.0)
    m = np.array(stats["image_to_ground"])
    # the pixel (col 50, row 10) lands where the exact model puts it
    (c, r, x, y), = _rows(pts=((50, 10),))
    assert m[:2] @ [c, r, 1] == pytest.approx([x, y], abs=1e-6)


def test_rectify_similarity_from_two_points(tmp_path):
    rows = _rows(pts=((0, 0), (60, 40)))
    path = tmp_path / "gcps.csv"
    path.write_text("id,col,row,X,Y\n" + "".join(f"P{k},{c},{r},{x},{y}\n"
                                                 for k, (c, r, x, y) in enumerate(rows)))
    out = toolbox.run("rectify:estimate", {"INPUT": path, "CRS": "EPSG:3003",
                                           "MODEL": "similarity", "OUTPUT": tmp_path / "t.json"})
    import numpy as np

    m = np.array(out["STATISTICS"]["image_to_ground"])
    (c, r, x, y), = _rows(pts=((50, 10),))
    assert m[:2] @ [c, r, 1] == pytest.approx([x, y], abs=1e-6)


@pytest.mark.parametrize("mirrored", [False, True])
def test_interior_similarity_of_a_scan(mirrored):
    """Pixel -> fiducial mm by a similarity: exact marks of an upright (or mirrored) scan give
    zero residuals and the right mm (0.014 mm pixels, centre at pixel 8000, 8000)."""
    import numpy as np

    from toolbox.photogrammetry.fiducials import InteriorOrientation

    cal = {"1": (-106, 106), "2": (106, 106), "3": (106, -106), "4": (-106, -106), "5": (0, 110)}
    sx = -1 if mirrored else 1
    meas = {k: (8000 + sx * x / 0.014, 8000 - y / 0.014) for k, (x, y) in cal.items()}
    io = InteriorOrientation.fit(cal, meas, "similarity")
    assert io.sigma0_mm < 1e-9
    got = io.pixel_to_image(np.array([[8000 + sx * 100, 7900]]))[0]
    assert got == pytest.approx([1.4, 1.4])


def test_snooping_rejects_nothing_on_exact_control(tmp_path):
    """rectify.md: data snooping names the gross errors. Exact control points (an affine photo)
    had two points rejected with a test value of inf (0/0 of rounding noise); none now."""
    path = tmp_path / "exact.csv"
    path.write_text("id,col,row,X,Y\n" + "".join(
        f"P{k},{c},{r},{1688000.0 + 2 * c},{4799100.0 - 2 * r}\n"
        for k, (c, r) in enumerate([(0, 0), (60, 0), (60, 40), (0, 40), (30, 20), (10, 33)])))
    for model in ("affine", "homography", "similarity"):
        out = toolbox.run("rectify:estimate", {"INPUT": path, "CRS": "EPSG:3003", "MODEL": model,
                                               "OUTPUT": tmp_path / f"{model}.json"})
        assert out["STATISTICS"]["rejected_points"] == [], model
        assert out["STATISTICS"]["used_points"] == 6


def test_footprints_diagonal_neighbours_are_not_side_pairs(tmp_path):
    """orientation.md: SIDE_OVERLAP (20 %) is checked for side pairs, flagged in meets_rule. A
    perfect 2 x 2 block at 60/20 % (c 150 mm, 900 m above ground, 23 cm frame: 1380 m sides,
    base 552 m, strips 1104 m apart) had its diagonal pairs (828 x 276 m: 12 %) called side
    pairs failing the rule, and STATISTICS gave 12 % as the least side overlap; they are
    'other' now, and the side range is 20-20 %."""
    import geopandas as gpd

    from tests.algorithms.orientation.test_orientation_algorithms import nadir_block

    project = nadir_block(tmp_path, second_strip=2)
    out = toolbox.run("orientation:footprints", {"PROJECT": project, "MEAN_HEIGHT": 100,
                                                 "OUTPUT": tmp_path / "f.gpkg"})
    assert out["STATISTICS"]["side_overlap_pct"] == pytest.approx([20.0, 20.0])
    ov = gpd.read_file(tmp_path / "f.gpkg", layer="overlaps")
    kinds = {frozenset((a, b)): k for a, b, k in zip(ov.photo_a, ov.photo_b, ov.kind,
                                                     strict=True)}
    assert kinds == {frozenset(("n1", "n2")): "forward", frozenset(("s1", "s2")): "forward",
                     frozenset(("n1", "s1")): "side", frozenset(("n2", "s2")): "side",
                     frozenset(("n1", "s2")): "other", frozenset(("n2", "s1")): "other"}
    ruled = ov[ov.kind != "other"]
    assert ruled.meets_rule.astype(bool).all()
    assert ov[ov.kind == "other"].meets_rule.isna().all()
