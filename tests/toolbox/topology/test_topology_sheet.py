"""The hand-built restitution sheet (toolbox.demo.samples.linework): every defect of issue 7 once,
with its exact expected areas, counts and errors worked out by hand from the coordinates."""

from __future__ import annotations

import warnings
from collections import Counter

import numpy as np
import pytest
import shapely

from toolbox.demo.samples import linework as sample
from toolbox.topology.build import build_topology
from toolbox.topology.tolerances import Tolerances

E0, N0 = sample.E0, sample.N0
TOL = Tolerances(snap=0.2, closure=0.5, min_dangle=1.0, min_area=1.0, precision=0.001)

# name: (code, quota, area m², perimeter m, labels inside, a local point inside)
EXPECTED = {
    # 100 x 60 frame minus the 80 x 40 block minus the 10 x 4 island
    "road": ("STR01001", 321.0, 2760.0, 320.0 + 240.0 + 28.0, 2, (5, 30)),
    # block west of wall 8 (20 x 40) minus B1's west half (10 x 20); notch adds 20 m of boundary
    "garden": (None, None, 600.0, 140.0, 0, (15, 45)),
    "B1": ("FAB01002", 331.2, 400.0, 80.0, 1, (30, 30)),
    # block east of wall 8 (60 x 40) minus B1's east half (200) minus B2 (400)
    "pavement": ("MAR01001", 322.4, 1800.0, 200.0 + 20.0 + 40.0, 1, (50, 45)),
    "island": ("VER01001", None, 40.0, 28.0, 2, (45, 5)),
    "B2": ("FAB01002", 328.7, 400.0, 80.0, 1, (70, 20)),
}


def run(lines=None, codes=None, labels=True, mode="build", tol=TOL):
    frame, lab = sample.sheet_lines(), sample.sheet_labels()
    lines = frame.geometry.values if lines is None else lines
    codes = frame["code"].to_numpy(object) if codes is None else codes
    if not labels:
        return build_topology(lines, codes, tolerances=tol, mode=mode)
    return build_topology(lines, codes, lab.geometry.values, lab["code"].to_numpy(object),
                          {"quota": lab["quota"].to_numpy(object)}, tol, mode=mode)


@pytest.fixture(scope="module")
def result():
    return run()


def area_named(result, name):
    x, y = EXPECTED[name][5]
    inside = shapely.contains_xy(result.areas.geometry, E0 + x, N0 + y)
    assert inside.sum() == 1, f"{name}: {inside.sum()} areas contain its point"
    return int(np.flatnonzero(inside)[0])


def errors_table(result):
    cols = result.errors.columns
    return [dict(zip(cols, values, strict=True)) | {"geometry": g}
            for values, g in zip(zip(*cols.values(), strict=True), result.errors.geometry,
                                 strict=True)]


def test_areas_exact(result):
    areas = result.areas
    assert len(areas) == 6
    assert sum(areas.columns["area"]) == pytest.approx(6000.0, abs=1e-6)
    for name, (code, quota, area, perimeter, nlabels, _) in EXPECTED.items():
        i = area_named(result, name)
        assert areas.columns["code"][i] == code, name
        got_quota = areas.columns["quota"][i]
        assert (got_quota is None) if quota is None else got_quota == pytest.approx(quota), name
        assert areas.columns["area"][i] == pytest.approx(area, abs=1e-6), name
        assert shapely.area(areas.geometry[i]) == pytest.approx(area, abs=1e-6), name
        assert areas.columns["perimeter"][i] == pytest.approx(perimeter, abs=1e-6), name
        assert areas.columns["labels"][i] == nlabels, name
    assert list(areas.columns["id"]) == [1, 2, 3, 4, 5, 6]
    assert shapely.is_valid(areas.geometry).all()
    # the island is a hole of the road
    road = areas.geometry[area_named(result, "road")]
    assert len(road.interiors) == 2  # the block and the island


def test_every_step_counted(result):
    s = result.statistics
    assert s["input"] == {"features": 14, "lines": 14, "invalid": 0, "parts_exploded": 0,
                          "polygon_rings": 0}
    assert s["snap"] == {"ends_to_node": 1, "ends_to_vertex": 1, "ends_to_segment": 1,
                         "collapsed_lines": 0}
    assert s["close"] == {"closed": 1}
    assert s["node"]["crossings_noded"] == 2  # (100, 60) and (30, 50)
    assert s["node"]["self_intersections_noded"] == 1  # the island touches its own start
    # B2 plotted twice (perimeter 80) and the pavement edge on the block edge (30)
    assert s["duplicates"] == {"exact_duplicate_lines": 1, "overlapping_pieces": 1,
                               "duplicate_length": 110.0}
    # overshoots: both outer road edges at the corner, wall 7, the island's end
    assert s["dangles"] == {"overshoots_trimmed": 4, "dangles_removed": 1, "dangles_kept": 1,
                            "unclosed_lines": 1}
    assert s["slivers"] == {"merged": 1, "dropped": 0}
    assert s["labels"] == {"checked": True, "labels": 8, "labelled_areas": 5,
                           "unlabelled_areas": 1, "conflicting_areas": 1, "labels_outside": 1}
    assert s["output"]["areas"] == 6 and s["output"]["errors"] == 5
    assert s["output"]["fixed"] == 15


def test_errors_for_the_operator(result):
    rows = errors_table(result)
    errors = sorted((r["type"], r["lines"], r["label_id"]) for r in rows
                    if r["severity"] == "error")
    assert errors == [("conflicting_labels", "", 5), ("dangle", "12", 0),
                      ("label_outside", "", 8), ("unclosed_line", "14", 0),
                      ("unlabelled_area", "", 0)]
    by_type = {r["type"]: r for r in rows if r["severity"] == "error"}
    garden = area_named(result, "garden") + 1
    assert by_type["unlabelled_area"]["area_id"] == garden
    assert by_type["conflicting_labels"]["area_id"] == area_named(result, "island") + 1
    assert "VER01001, STR03001" in by_type["conflicting_labels"]["detail"]
    assert by_type["label_outside"]["geometry"].equals(shapely.Point(E0 + 105, N0 + 30))
    dangle = by_type["dangle"]["geometry"]
    assert dangle.length == pytest.approx(5.0) and "kept" in by_type["dangle"]["detail"]
    assert by_type["unclosed_line"]["geometry"].length == pytest.approx(26.5)
    assert "1.500 apart" in by_type["unclosed_line"]["detail"]


def test_fixes_reported_not_silent(result):
    rows = [r for r in errors_table(result) if r["severity"] == "fixed"]
    assert Counter(r["type"] for r in rows) == Counter({
        "near_miss": 3, "unclosed_line": 1, "crossing_without_node": 2, "self_intersection": 1,
        "duplicate_line": 2, "overshoot": 4, "dangle": 1, "sliver": 1})
    near = {(r["lines"], round(r["geometry"].length, 3)) for r in rows if r["type"] == "near_miss"}
    assert near == {("3", 0.112), ("3", 0.12), ("8", 0.15)}
    crossings = {(r["lines"], tuple(np.round(shapely.get_coordinates(r["geometry"])[0]
                                             - [E0, N0], 3)))
                 for r in rows if r["type"] == "crossing_without_node"}
    assert crossings == {("1;2", (100.0, 60.0)), ("3;7", (30.0, 50.0))}
    self_x = [r for r in rows if r["type"] == "self_intersection"][0]
    assert self_x["geometry"].equals(shapely.Point(E0 + 40, N0 + 3)) and self_x["lines"] == "13"
    overshoots = sorted((r["lines"], round(r["geometry"].length, 3)) for r in rows
                        if r["type"] == "overshoot")
    assert overshoots == [("1", 0.3), ("13", 0.6), ("2", 0.3), ("7", 0.4)]
    stub = [r for r in rows if r["type"] == "dangle"][0]
    assert stub["lines"] == "11" and stub["geometry"].length == pytest.approx(0.6)
    closed = [r for r in rows if r["type"] == "unclosed_line"][0]
    assert closed["lines"] == "4" and closed["geometry"].length == pytest.approx(0.3)
    sliver = [r for r in rows if r["type"] == "sliver"][0]
    assert sliver["area_id"] == area_named(result, "pavement") + 1
    assert "0.800" in sliver["detail"]
    assert {r["lines"] for r in rows if r["type"] == "duplicate_line"} == {"6", "3;9"}


def test_building_pavement_edge_stored_once(result):
    arcs = result.arcs
    b2 = area_named(result, "B2") + 1
    pavement = area_named(result, "pavement") + 1
    road = area_named(result, "road") + 1
    sides = [frozenset((int(a), int(b))) for a, b in zip(arcs.columns["left_area"],
                                                        arcs.columns["right_area"], strict=True)]
    shared = [i for i, s in enumerate(sides) if s == frozenset((b2, pavement))]
    assert len(shared) == 1
    arc = arcs.geometry[shared[0]]
    assert arc.length == pytest.approx(60.0)  # B2's west, north and east walls, once
    assert arcs.columns["codes"][shared[0]] == "FAB01002"
    assert arcs.columns["lines"][shared[0]] == "5;6"  # B2 and its duplicate
    walls = shapely.LineString([(E0 + 60, N0 + 10), (E0 + 60, N0 + 30), (E0 + 80, N0 + 30),
                                (E0 + 80, N0 + 10)])
    assert arc.equals(walls)
    to_road = [i for i, s in enumerate(sides) if s == frozenset((b2, road))]
    assert len(to_road) == 1 and arcs.geometry[to_road[0]].length == pytest.approx(20.0)
    # no piece of boundary is stored twice: arcs meet in points only
    tree = shapely.STRtree(arcs.geometry)
    i, j = tree.query(arcs.geometry, predicate="intersects")
    pairs = i < j
    overlap = shapely.intersection(arcs.geometry[i[pairs]], arcs.geometry[j[pairs]])
    assert (shapely.length(overlap) == 0).all()


def test_arcs_point_to_the_areas_on_their_sides(result):
    arcs, areas = result.arcs, result.areas
    left, right = arcs.columns["left_area"], arcs.columns["right_area"]
    for k, arc in enumerate(arcs.geometry):
        (x0, y0), (x1, y1) = shapely.get_coordinates(arc)[:2]
        mx, my, dx, dy = (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0
        norm = np.hypot(dx, dy)
        for side, sign in ((left[k], 1), (right[k], -1)):  # left = counter-clockwise normal
            px, py = mx - sign * 0.01 * dy / norm, my + sign * 0.01 * dx / norm
            inside = np.flatnonzero(shapely.contains_xy(areas.geometry, px, py))
            assert list(inside + 1) == ([side] if side else []), (k, side)
    # every area's boundary is exactly the arcs pointing to it
    for a in range(1, len(areas) + 1):
        bounding = (left != right) & ((left == a) | (right == a))
        assert arcs.columns["length"][bounding].sum() == pytest.approx(
            areas.columns["perimeter"][a - 1], abs=1e-6)
    inside = left == right
    assert sorted(arcs.columns["codes"][inside]) == ["MUR01001", "VER02001"]  # kept dangle, hedge


def test_nodes(result):
    nodes = result.nodes
    kinds = Counter(nodes.columns["kind"])
    assert kinds["end"] == 3  # the kept wall's free end and the hedge's two ends
    assert kinds["ring"] == 2  # the outer road edge (one arc) and the island
    assert len(nodes) == 14
    xy = shapely.get_coordinates(nodes.geometry)
    assert len(np.unique(np.round(xy, 3), axis=0)) == len(nodes)


def test_idempotent_on_its_own_arcs(result):
    again = run(lines=result.arcs.geometry, codes=result.arcs.columns["codes"])
    assert again.statistics["output"]["fixed"] == 0
    for step in ("snap", "close", "duplicates"):
        assert not any(again.statistics[step].values()), step
    assert again.statistics["node"]["crossings_noded"] == 0
    assert shapely.equals_exact(again.areas.geometry, result.areas.geometry, 0).all()
    assert shapely.equals_exact(again.arcs.geometry, result.arcs.geometry, 0).all()
    assert shapely.equals_exact(again.nodes.geometry, result.nodes.geometry, 0).all()
    for name in ("code", "quota", "area", "perimeter"):
        assert list(again.areas.columns[name]) == list(result.areas.columns[name])
    assert list(again.arcs.columns["codes"]) == list(result.arcs.columns["codes"])
    assert list(again.arcs.columns["left_area"]) == list(result.arcs.columns["left_area"])


def test_same_ids_whatever_the_order_and_direction(result):
    frame = sample.sheet_lines()
    perm = np.random.default_rng(7).permutation(len(frame))
    geoms = shapely.reverse(frame.geometry.values[perm])  # every line plotted the other way
    other = run(lines=geoms, codes=frame["code"].to_numpy(object)[perm])
    assert shapely.equals_exact(other.areas.geometry, result.areas.geometry, 0).all()
    assert list(other.areas.columns["code"]) == list(result.areas.columns["code"])
    assert shapely.equals_exact(other.arcs.geometry, result.arcs.geometry, 0).all()
    assert list(other.arcs.columns["left_area"]) == list(result.arcs.columns["left_area"])
    assert list(other.arcs.columns["codes"]) == list(result.arcs.columns["codes"])
    assert other.statistics["dangles"] == result.statistics["dangles"]


def test_invalid_geometries_reported_not_crashing(result):
    frame = sample.sheet_lines()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # shapely warns about the NaN line
        bad = [None, shapely.LineString(), shapely.Point(E0 + 50, N0 + 30),
               shapely.LineString([(E0, N0), (np.nan, N0 + 5)]),
               shapely.LineString([(E0 + 5, N0 + 5), (E0 + 5, N0 + 5)]),
               shapely.Polygon()]
    geoms = np.concatenate([frame.geometry.values, np.array(bad, dtype=object)])
    codes = np.concatenate([frame["code"].to_numpy(object), np.array(["X"] * len(bad), object)])
    out = run(lines=geoms, codes=codes)
    assert shapely.equals_exact(out.areas.geometry, result.areas.geometry, 0).all()
    rows = [r for r in errors_table(out) if r["type"] == "invalid_geometry"]
    assert sorted(int(r["lines"]) for r in rows) == [15, 16, 17, 18, 19, 20]
    assert all(r["severity"] == "error" for r in rows)
    details = " | ".join(r["detail"] for r in rows)
    for text in ("null geometry", "empty geometry", "Point in a line layer", "NaN",
                 "fewer than two distinct vertices"):
        assert text in details
    assert out.statistics["input"]["invalid"] == 6


def test_check_mode_reports_without_building(result):
    checked = run(mode="check")
    assert len(checked.areas) == len(checked.arcs) == len(checked.nodes) == 0
    built = Counter((t, "fixed" if s == "fixable" else s) for t, s in zip(
        checked.errors.columns["type"], checked.errors.columns["severity"], strict=True))
    assert built == Counter(zip(result.errors.columns["type"], result.errors.columns["severity"],
                                strict=True))
    assert set(checked.errors.columns["severity"]) == {"fixable", "error"}
    assert checked.statistics["output"] == {"areas": 0, "arcs": 0, "nodes": 0, "errors": 5,
                                            "fixable": 15}


def test_without_labels_no_label_checks():
    out = run(labels=False)
    assert len(out.areas) == 6
    # only the buildings plotted closed with their code (B1 closed within the closure tolerance,
    # B2 plotted twice) are coded: by their outline
    codes = out.areas.columns["code"]
    assert {name: codes[area_named(out, name)] for name in EXPECTED} == {
        name: ("FAB01002" if name in ("B1", "B2") else None) for name in EXPECTED}
    assert not {"unlabelled_area", "conflicting_labels", "label_outside"} & set(
        out.errors.columns["type"])
    assert out.statistics["labels"] == {"checked": False}


def test_zero_tolerances_keep_the_defects():
    out = run(tol=Tolerances(snap=0, closure=0, min_dangle=0, min_area=0, precision=0.001))
    s = out.statistics
    assert s["snap"]["ends_to_vertex"] == 0 and s["close"]["closed"] == 0
    assert s["dangles"]["overshoots_trimmed"] == 0 and s["slivers"]["merged"] == 0
    # nothing closes: the block edge misses B2 so road, garden and pavement are one area around
    # B2 (400), the island (40) and the sliver (0.8); open B1 bounds nothing
    areas = sorted(np.round(out.areas.columns["area"], 6))
    assert areas == [0.8, 40.0, 400.0, 6000.0 - 400.0 - 40.0 - 0.8]
    assert s["dangles"]["dangles_kept"] >= 5


@pytest.mark.parametrize("geoms, areas, arcs, errors", [
    ([], 0, 0, 0),
    ([None, shapely.Point(1, 1)], 0, 0, 2),
    ([shapely.LineString([(0, 0), (3, 0)])], 0, 1, 1),        # one open line: unclosed
    ([shapely.LineString([(0, 0), (1, 0), (1, 1), (0, 0)])], 0, 0, 0),  # a 0.5 m² sliver
    ([shapely.LineString([(0, 0), (10, 0), (10, 10), (0, 0)])], 1, 1, 0),
])
def test_degenerate_inputs_do_not_crash(geoms, areas, arcs, errors):
    out = build_topology(np.array(geoms, dtype=object), tolerances=TOL)
    assert (len(out.areas), len(out.arcs)) == (areas, arcs)
    assert out.statistics["output"]["errors"] == errors


def _noisy_blocks(seed: int, sigma: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A 4 x 4 grid of blocks with attached buildings, every vertex jittered by N(0, sigma)."""
    rng = np.random.default_rng(seed)
    lines = []
    for i in range(4):
        for j in range(4):
            x0, y0 = E0 + 60 * i, N0 + 50 * j
            lines.append([(x0 + 5, y0 + 5), (x0 + 55, y0 + 5), (x0 + 55, y0 + 45),
                          (x0 + 5, y0 + 45), (x0 + 5, y0 + 5)])
            lines.append([(x0 + 10, y0 + 10), (x0 + 20, y0 + 10), (x0 + 20, y0 + 22),
                          (x0 + 10, y0 + 22), (x0 + 10, y0 + 10)])
            for k in range(1, 4):
                xa, xb = x0 + 10 + 10 * k, x0 + 20 + 10 * k
                lines.append([(xa, y0 + 10), (xb, y0 + 10), (xb, y0 + 22), (xa, y0 + 22)])
            lines.append([(x0 + 35, y0 + 22), (x0 + 35, y0 + 45)])
    geoms = np.array([shapely.LineString(np.asarray(pts) + rng.normal(0, sigma, (len(pts), 2)))
                      for pts in lines], dtype=object)
    return geoms, np.array(["X"] * len(geoms), dtype=object)


@pytest.mark.parametrize("seed", [1, 2])
def test_idempotent_even_on_noisy_linework(seed):
    geoms, codes = _noisy_blocks(seed)
    first = build_topology(geoms, codes, tolerances=TOL)
    assert first.statistics["snap"]["ends_to_vertex"] > 0  # the noise needed cleaning
    again = build_topology(first.arcs.geometry, first.arcs.columns["codes"], tolerances=TOL)
    assert again.statistics["output"]["fixed"] == 0
    assert shapely.equals_exact(again.areas.geometry, first.areas.geometry, 0).all()
    assert shapely.equals_exact(again.arcs.geometry, first.arcs.geometry, 0).all()


def test_polyline_plotted_in_two_pieces_is_closed():
    # a 10 x 10 building plotted as two polylines whose free ends miss by 0.3 m
    geoms = np.array([shapely.LineString([(E0, N0), (E0 + 10, N0), (E0 + 10, N0 + 10)]),
                      shapely.LineString([(E0 + 10, N0 + 10), (E0, N0 + 10), (E0, N0 + 0.3)])],
                     dtype=object)
    out = build_topology(geoms, np.array(["FAB01002", "FAB01002"], dtype=object), tolerances=TOL)
    assert out.statistics["close"]["closed"] == 1
    assert list(out.areas.columns["area"]) == [100.0]
    fixed = [(t, lines) for t, s, lines in zip(out.errors.columns["type"],
                                               out.errors.columns["severity"],
                                               out.errors.columns["lines"], strict=True)]
    assert fixed == [("unclosed_line", "1;2")]
    again = build_topology(out.arcs.geometry, out.arcs.columns["codes"], tolerances=TOL)
    assert again.statistics["output"]["fixed"] == 0
    assert shapely.equals_exact(again.areas.geometry, out.areas.geometry, 0).all()
