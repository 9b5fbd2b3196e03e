"""Each cleaning kernel on tiny linework with a known answer (local coordinates, metres)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely import LineString as L

from toolbox.topology.arcs import build_arcs, build_nodes
from toolbox.topology.closure import close_lines
from toolbox.topology.faces import face_sides, polygonize_edges, sliver_edges
from toolbox.topology.graph import dangle_chains, edge_graph, remove_short_dangles
from toolbox.topology.labels import assign_labels, blank_mask
from toolbox.topology.noding import node_lines
from toolbox.topology.prepare import prepare_lines
from toolbox.topology.snap import snap_endpoints

P = 0.001


def arr(*geoms):
    return np.array(geoms, dtype=object)


def ends(line):
    c = shapely.get_coordinates(line)
    return tuple(c[0]), tuple(c[-1])


# -- snap -----------------------------------------------------------------------------------------
def test_snap_end_goes_to_the_existing_node():
    # two lines already meet at (10, 0); a third ends 0.1 away: it joins them, they do not move
    lines = arr(L([(0, 0), (10, 0)]), L([(10, 0), (10, 10)]), L([(20, 0), (10.1, 0.05)]))
    out = snap_endpoints(lines, 0.2, P)
    assert ends(out.lines[2])[1] == (10.0, 0.0)
    assert ends(out.lines[0]) == ((0, 0), (10, 0)) and ends(out.lines[1])[0] == (10, 0)
    assert out.counts == {"node": 1, "vertex": 0, "segment": 0, "degenerate": 0}
    assert list(out.move_kind) == ["node"] and out.move_line[0] == 2 and out.move_end[0] == 1


def test_snap_prefers_a_vertex_to_a_closer_segment():
    # vertex (5, 0) is 0.15 away, the segment point (5.12, 0) only 0.1
    lines = arr(L([(0, 0), (5, 0), (10, 0)]), L([(5.12, 5), (5.12, 0.1)]))
    out = snap_endpoints(lines, 0.2, P)
    assert ends(out.lines[1])[1] == (5.0, 0.0)
    assert list(out.move_kind) == ["vertex"]


def test_snap_undershoot_onto_a_segment():
    lines = arr(L([(0, 0), (10, 0)]), L([(4, 5), (4, 0.15)]))
    out = snap_endpoints(lines, 0.2, P)
    assert ends(out.lines[1])[1] == pytest.approx((4.0, 0.0))
    assert list(out.move_kind) == ["segment"]
    assert out.move_from[0] == pytest.approx([4, 0.15]) and out.move_to[0] == pytest.approx([4, 0])


def test_snap_leaves_touching_ends_far_ends_and_own_ends_alone():
    lines = arr(L([(0, 0), (10, 0)]),            # target
                L([(3, 0), (3, 5)]),              # already on it (T)
                L([(6, 0.5), (6, 5)]),            # 0.5 away: beyond the tolerance
                L([(20, 0), (30, 0), (30, 5), (20.1, 0)]))  # own ends 0.1 apart: closure's job
    out = snap_endpoints(lines, 0.2, P)
    assert len(out.move_line) == 0
    assert shapely.equals_exact(out.lines, lines, 0).all()


def test_snap_tolerance_zero_changes_nothing():
    lines = arr(L([(0, 0), (10, 0)]), L([(10.05, 0), (20, 0)]))
    out = snap_endpoints(lines, 0.0, P)
    assert shapely.equals_exact(out.lines, lines, 0).all() and len(out.move_line) == 0


def test_snap_does_not_depend_on_input_order():
    lines = arr(L([(0, 0), (10, 0)]), L([(10.1, 0), (20, 0)]), L([(10.05, 0.1), (10, 10)]),
                L([(9.95, -0.05), (10, -10)]))
    first = snap_endpoints(lines, 0.2, P)
    order = np.array([3, 1, 0, 2])
    second = snap_endpoints(lines[order], 0.2, P)
    assert shapely.equals_exact(second.lines, first.lines[order], 0).all()
    # one node: the lowest (x, y) of the four ends, all of multiplicity 1
    assert {ends(g)[0] for g in first.lines[1:2]} == {(9.95, -0.05)}


def test_snap_collapsing_line_is_dropped():
    lines = arr(L([(0, 0), (10, 0)]), L([(10, 10), (20, 10)]), L([(10.05, 0), (10.1, 0.05)]))
    out = snap_endpoints(lines, 0.2, P)
    assert list(out.degenerate) == [2] and list(out.kept) == [0, 1]


# -- closure --------------------------------------------------------------------------------------
def test_closure_adds_the_closing_segment():
    square = L([(0, 0), (10, 0), (10, 10), (0, 10), (0, 0.3)])
    out = close_lines(arr(square), 0.5, P)
    assert list(out.closed) == [0] and out.gaps[0] == pytest.approx(0.3)
    c = shapely.get_coordinates(out.lines[0])
    assert (c[0] == c[-1]).all() and len(c) == 6  # every plotted vertex kept
    assert shapely.area(shapely.Polygon(c)) == pytest.approx(100.0)


def test_closure_refuses_attached_short_and_far_lines():
    lines = arr(L([(0, 0), (10, 0), (10, 10), (0, 10), (0, 0.3)]),   # start touches line 1
                L([(-5, 0), (0, 0)]),
                L([(20, 0), (20.3, 0)]),                             # two vertices only
                L([(30, 0), (40, 0), (40, 10), (30, 10), (30, 0.8)]))  # 0.8 > 0.5
    out = close_lines(lines, 0.5, P)
    assert len(out.closed) == 0
    assert list(out.open_free) == [2, 3] and out.open_gaps[1] == pytest.approx(0.8)


# -- noding ---------------------------------------------------------------------------------------
def test_noding_crossings_duplicates_and_provenance():
    lines = arr(L([(0, 0), (10, 0)]), L([(5, -5), (5, 5)]),     # X crossing without vertex
                L([(2, 0), (4, 0)]),                            # overlaps line 0
                L([(10, 0), (0, 0)]),                           # line 0 reversed
                L([(8, 0), (8, 3)]))                            # T on a vertex-less point
    out = node_lines(lines, P)
    assert out.counts["crossings_noded"] == 1  # (5, 0); (8, 0) is line 4's own vertex
    assert out.crossings == pytest.approx(np.array([[5.0, 0.0]]))
    assert list(out.exact_duplicates) == [3]
    piece = np.flatnonzero(shapely.dwithin(out.edges, shapely.Point(3, 0), 1e-9))
    assert len(piece) == 1 and list(out.sources_of(piece[0])) == [0, 2, 3]
    assert shapely.length(out.edges[piece[0]]) == pytest.approx(2.0)
    assert out.counts["duplicate_length"] == pytest.approx(10.0 + 2.0)
    total = shapely.length(out.edges).sum()
    assert total == pytest.approx(10 + 10 + 3)  # every piece once


def test_self_intersections_are_found():
    lines = arr(L([(0, 0), (10, 0), (10, 5), (5, 5), (5, -5)]), L([(20, 0), (30, 0)]))
    out = node_lines(lines, P)
    assert list(out.self_intersecting) == [0]


# -- dangles --------------------------------------------------------------------------------------
def _network(lines):
    out = node_lines(arr(*lines), P)
    return out, edge_graph(out.edges, P)


def test_overshoot_dangle_and_isolated_line():
    square = L([(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)])
    lines = [square,
             L([(5, 5), (5, 10.4)]),        # crosses the top, 0.4 m overshoot; also inside
             L([(10, 5), (10.6, 5)]),       # stub on the right wall
             L([(20, 0), (20, 0.5)]),       # isolated short line
             L([(-3, 0), (-3, 4)])]         # isolated long line
    out, graph = _network(lines)
    removal = remove_short_dangles(out.edges, graph, out.indptr, out.sources, 1.0)
    kinds = sorted(kind for _, kind in removal.removed)
    assert kinds == ["dangle", "isolated", "overshoot"]
    lengths = sorted(round(chain.length, 3) for chain, _ in removal.removed)
    assert lengths == [0.4, 0.5, 0.6]
    kept = dangle_chains(graph, shapely.length(out.edges), removal.alive)
    assert sorted((round(c.length, 3), c.isolated) for c in kept) == [(4.0, True), (5.0, False)]


def test_dangle_chain_judged_on_its_whole_length():
    # a 1.2 m dangle plotted as two 0.6 m lines: kept with a 1.0 m minimum
    lines = [L([(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]), L([(10, 5), (10.6, 5)]),
             L([(10.6, 5), (11.2, 5)])]
    out, graph = _network(lines)
    removal = remove_short_dangles(out.edges, graph, out.indptr, out.sources, 1.0)
    assert removal.removed == []
    removal = remove_short_dangles(out.edges, graph, out.indptr, out.sources, 1.5)
    assert [(kind, round(c.length, 3), len(c.edges)) for c, kind in removal.removed] == [
        ("dangle", 1.2, 2)]


# -- faces ----------------------------------------------------------------------------------------
def test_left_and_right_of_shared_and_outer_edges():
    lines = [L([(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]),
             L([(10, 0), (20, 0), (20, 10), (10, 10)]), L([(2, 2), (3, 2)])]
    out, _ = _network(lines)
    faces = polygonize_edges(out.edges)
    assert sorted(shapely.area(faces)) == [100.0, 100.0]
    west = int(np.flatnonzero(shapely.contains_xy(faces, 5, 5))[0])
    east = 1 - west
    probe = arr(L([(10, 0), (10, 10)]), L([(10, 10), (10, 0)]), L([(0, 0), (10, 0)]),
                L([(2, 2), (3, 2)]))
    left, right = face_sides(probe, faces, P)
    assert (left[0], right[0]) == (west, east)   # going north, west is on the left
    assert (left[1], right[1]) == (east, west)
    assert (left[2], right[2]) == (west, -1)     # the south wall: outside on the right
    assert (left[3], right[3]) == (west, west)   # a dangle inside: same face both sides


def test_sliver_goes_to_the_neighbour_with_the_longest_boundary():
    # a 0.8 m2 triangle between a straight edge (40 m) and a bent one (40.00008 m)
    lines = [L([(0, 0), (90, 0), (90, 40), (0, 40), (0, 0)]),
             L([(100, 0), (100, 40)]), L([(90, 0), (100, 0)]), L([(90, 40), (100, 40)]),
             L([(90, 40), (89.96, 20), (90, 0)])]
    out, _ = _network(lines)
    faces = polygonize_edges(out.edges)
    left, right = face_sides(out.edges, faces, P)
    drop, merges = sliver_edges(faces, out.edges, left, right, 1.0)
    assert len(merges) == 1 and merges[0].area == pytest.approx(0.8)
    big = int(np.argmax(shapely.area(faces)))
    assert merges[0].into == big
    assert shapely.length(out.edges[drop]).sum() == pytest.approx(2 * np.hypot(20, 0.04))


# -- labels ---------------------------------------------------------------------------------------
def test_labels_codes_attributes_conflicts_and_outside():
    faces = arr(shapely.box(0, 0, 10, 10), shapely.box(10, 0, 20, 10), shapely.box(20, 0, 30, 10))
    points = shapely.points([(5, 5), (6, 6), (15, 5), (16, 5), (25, 5), (10, 5), (50, 5)])
    codes = np.array(["A", None, "B", "C", " ", "A", "A"], dtype=object)
    quota = np.array([1.0, 2.0, np.nan, np.nan, 7.5, 1.0, 1.0], dtype=object)
    out = assign_labels(faces, points, codes, {"quota": quota})
    assert list(out.label_face) == [0, 0, 1, 1, 2, -1, -1]  # (10, 5) is on a boundary
    assert list(out.face_code) == ["A", "B", None]
    assert list(out.face_attributes["quota"]) == [1.0, None, 7.5]
    assert list(out.face_labels) == [2, 2, 1]
    assert out.conflicts == {0: "2 labels give quota 1, 2: 1 (the first label's) is used",
                             1: "2 labels give area codes B, C: B (the first label's) is used"}


def test_blank_values():
    values = np.array([None, np.nan, "", "  ", "x", 0, 0.0, float("nan")], dtype=object)
    assert list(blank_mask(values)) == [True, True, True, True, False, False, False, True]


# -- arcs and nodes -------------------------------------------------------------------------------
def test_arcs_merge_only_where_the_code_stays_the_same():
    # a ring plotted as three lines: two with code A, one with code B
    lines = arr(L([(0, 0), (10, 0)]), L([(10, 0), (10, 10), (0, 10)]), L([(0, 10), (0, 0)]))
    codes = np.array(["A", "A", "B"], dtype=object)
    out = node_lines(lines, P)
    graph = edge_graph(out.edges, P)
    arcs = build_arcs(out.edges, graph, out.indptr, out.sources, codes, P)
    assert sorted(arcs.code_key) == ["A", "B"]
    a = list(arcs.code_key).index("A")
    assert shapely.length(arcs.geoms[a]) == pytest.approx(30.0)
    assert list(arcs.sources(a)) == [0, 1]
    nodes = build_nodes(arcs.geoms, P)
    assert sorted(map(tuple, nodes.xy)) == [(0.0, 0.0), (0.0, 10.0)]
    assert list(nodes.kind) == ["pseudo", "pseudo"]


def test_free_ring_arc_starts_at_its_lowest_vertex_counter_clockwise():
    lines = arr(L([(5, 5), (5, 0), (0, 0), (0, 5), (5, 5)]))
    out = node_lines(lines, P)
    arcs = build_arcs(out.edges, edge_graph(out.edges, P), out.indptr, out.sources,
                      np.array(["A"], dtype=object), P)
    c = shapely.get_coordinates(arcs.geoms[0])
    assert tuple(c[0]) == (0.0, 0.0) and shapely.is_ccw(arcs.geoms[0])
    nodes = build_nodes(arcs.geoms, P)
    assert list(nodes.kind) == ["ring"] and list(nodes.degree) == [2]


# -- prepare --------------------------------------------------------------------------------------
def test_prepare_explodes_parts_and_uses_polygon_rings():
    geoms = arr(shapely.MultiLineString([[(0, 0), (1, 0)], [(2, 0), (3, 0)]]),
                shapely.Polygon([(0, 0), (4, 0), (4, 4), (0, 0)], [[(1, 0.5), (3, 0.5), (3, 2),
                                                                     (1, 0.5)]]),
                L([(0, 0, 5), (1, 1, 6), (1, 1, 6)]))
    out = prepare_lines(geoms)
    assert list(out.source) == [0, 0, 1, 1, 2]
    assert out.counts["parts_exploded"] == 1 and out.counts["polygon_rings"] == 2
    assert not shapely.has_z(out.lines).any()
    assert shapely.get_num_coordinates(out.lines[4]) == 2  # repeated vertex removed
