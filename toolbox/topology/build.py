"""Area topology from restitution linework: the whole cleaning chain as one kernel.

Steps (thesis S002 §2.4 checks, each counted and reported):

1. prepare: explode, drop Z, refuse unusable features (``invalid_geometry``);
2. snap line ends to nodes / vertices / segments within the snap tolerance (``near_miss``);
3. close polylines whose free ends miss by less than the closure tolerance (``unclosed_line``);
4. node every crossing, dissolve exact and overlapping duplicates (``crossing_without_node``,
   ``self_intersection``, ``duplicate_line``);
5. remove overshoots and dangles shorter than the minimum (``overshoot``, ``dangle``), polygonize,
   merge slivers below the minimum area into their neighbour (``sliver``); repeated until stable,
   since merging a sliver can leave a new dangle;
6. report what stays for the operator: dangles kept, unclosed lines;
7. label areas from label points (``unlabelled_area``, ``conflicting_labels``, ``label_outside``);
8. arcs (each boundary once, with left/right areas and original codes) and nodes.

Closure runs before noding (the ends of an input polyline are only its own before noding splits
it). Slivers are merged before labelling so a label inside a sliver labels the merged area.
Coordinates are shifted to a local origin and snap-rounded to the precision grid; the output is
shifted back. Ids are numbered from the geometry alone (bounds, then size), so the same input gives
the same ids.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import shapely

from toolbox.feedback import Feedback
from toolbox.terrain.points import local_origin
from toolbox.topology.arcs import build_arcs, build_nodes
from toolbox.topology.area_codes import AreaCodes
from toolbox.topology.closure import chain_closures, close_lines
from toolbox.topology.faces import face_sides, polygonize_edges, sliver_edges
from toolbox.topology.graph import (
    Chain,
    chain_geometry,
    dangle_chains,
    edge_graph,
    remove_short_dangles,
)
from toolbox.topology.issues import ERROR, FIXABLE, FIXED, Issue
from toolbox.topology.labels import assign_labels, outline_codes
from toolbox.topology.noding import node_lines, self_intersection_points
from toolbox.topology.output import (
    Layer,
    TopologyOutput,
    issues_layer,
    joined_rows,
    order_key,
    shift,
    subset_csr,
)
from toolbox.topology.prepare import prepare_lines
from toolbox.topology.snap import snap_endpoints
from toolbox.topology.tolerances import Tolerances, large_snap_warning

MAX_ROUNDS = 20


class _Progress:
    def __init__(self, feedback: Feedback | None):
        self.feedback = feedback or Feedback()

    def step(self, percent: float, message: str) -> None:
        self.feedback.check_canceled()
        self.feedback.set_progress(percent, message)
        self.feedback.push_info(message)


def build_topology(line_geoms: np.ndarray, line_codes: np.ndarray | None = None,
                   label_geoms: np.ndarray | None = None, label_codes: np.ndarray | None = None,
                   label_attributes: dict[str, np.ndarray] | None = None,
                   tolerances: Tolerances | None = None,
                   feedback: Feedback | None = None, mode: str = "build",
                   area_codes: AreaCodes | None = None) -> TopologyOutput:
    """Clean linework and build coded areas, arcs, nodes and the errors layer.

    Parameters
    ----------
    line_geoms : (N,) shapely geometries (lines; map coordinates, metres).
    line_codes : (N,) codes of the lines (text or None), optional.
    label_geoms : (L,) Points, optional. label_codes : (L,) codes (blank = attributes only).
    label_attributes : dict name -> (L,) values carried to the areas.
    tolerances : Tolerances (defaults: :class:`Tolerances`).
    feedback : Feedback for progress, step messages and cancellation.
    mode : {"build", "check"}
        ``"check"`` diagnoses only: what the cleaning changes is reported with severity
        ``fixable`` instead of ``fixed``, and the areas, arcs and nodes layers are left empty.
        Without label points (``label_geoms`` None) no label check is made.
    area_codes : which codes are area codes (from the code file, see
        :mod:`toolbox.topology.area_codes`); None: a closed line's code fills an uncoded face
        and never conflicts with a label.

    Returns
    -------
    TopologyOutput
        Layers in map coordinates. ``errors`` rows have ``lines`` (1-based input feature
        numbers, ``;``-joined), ``area_id`` and ``label_id`` (1-based label feature number), 0
        where not applicable.
    """
    if mode not in ("build", "check"):
        raise ValueError(f"mode must be 'build' or 'check', got {mode!r}")
    FIX = FIXED if mode == "build" else FIXABLE  # noqa: N806 - a constant for this run
    check_labels = label_geoms is not None
    tol = tolerances or Tolerances()
    prec = tol.precision
    progress = _Progress(feedback)
    timed = progress.feedback.timed
    line_geoms = np.asarray(line_geoms, dtype=object)
    n_input = len(line_geoms)
    line_codes = (np.full(n_input, None, dtype=object) if line_codes is None
                  else np.asarray(line_codes, dtype=object))
    label_geoms = np.zeros(0, dtype=object) if label_geoms is None else np.asarray(label_geoms,
                                                                                   dtype=object)
    label_codes = (np.full(len(label_geoms), None, dtype=object) if label_codes is None
                   else np.asarray(label_codes, dtype=object))
    label_attributes = label_attributes or {}
    stats: dict[str, Any] = {"tolerances": tol.as_dict()}
    issues: list[Issue] = []

    # 1. prepare ---------------------------------------------------------------------------------
    with timed("prepare"):
        prepared = prepare_lines(line_geoms)
    stats["input"] = prepared.counts
    progress.step(5, f"input: {prepared.counts['features']} features, "
                     f"{prepared.counts['lines']} lines, {prepared.counts['invalid']} invalid")
    lines, src = prepared.lines, prepared.source
    if len(lines):
        b = shapely.total_bounds(lines)
        origin = local_origin(np.array([[b[0], b[1]], [b[2], b[3]]]))
    else:
        origin = np.zeros(2)
    # the origin is a round number (a multiple of the grid), so the grid is the same in both frames
    origin = np.round(origin / prec) * prec
    lines = shift(lines, -origin)
    for issue in prepared.issues:  # every issue geometry in the local frame
        if issue.geometry is not None:
            issue.geometry = shift(np.array([issue.geometry], dtype=object), -origin)[0]
        issues.append(issue)
    # vertices onto the precision grid first: every distance below is then measured on the same
    # coordinates a second run on the output would see (tolerance decisions stay the same)
    gridded = shapely.remove_repeated_points(
        shapely.set_precision(lines, prec, mode="pointwise"), 0.0)
    tiny = shapely.length(gridded) == 0
    for i in np.flatnonzero(tiny):
        issues.append(Issue("invalid_geometry", ERROR, shapely.get_point(lines[i], 0),
                            f"shorter than the coordinate precision ({prec:g})", (int(src[i]),)))
    lines, src = gridded[~tiny], src[~tiny]
    warning = large_snap_warning(tol.snap, lines)
    if warning:
        progress.feedback.push_warning(warning)
    stats["input"]["invalid"] += int(tiny.sum())
    stats["input"]["lines"] -= int(tiny.sum())
    codes_of_src = line_codes  # indexed by input row

    # 2. snap ------------------------------------------------------------------------------------
    with timed("snap"):
        snap = snap_endpoints(lines, tol.snap, prec)
    for i in range(len(snap.move_line)):
        a, b = snap.move_from[i], snap.move_to[i]
        issues.append(Issue("near_miss", FIX, shapely.LineString([a, b]),
                            f"end {np.hypot(*(b - a)):.3f} from a {snap.move_kind[i]} "
                            f"(snap tolerance {tol.snap:g})", (int(src[snap.move_line[i]]),)))
    for i in snap.degenerate:
        issues.append(Issue("near_miss", FIX, lines[i],
                            f"line shorter than the snap tolerance ({tol.snap:g}) collapses",
                            (int(src[i]),)))
    stats["snap"] = {"ends_to_node": snap.counts["node"], "ends_to_vertex": snap.counts["vertex"],
                     "ends_to_segment": snap.counts["segment"],
                     "collapsed_lines": snap.counts["degenerate"]}
    lines, src = snap.lines, src[snap.kept]
    progress.step(15, "snap: {ends_to_node} ends to nodes, {ends_to_vertex} to vertices, "
                      "{ends_to_segment} to segments, {collapsed_lines} lines collapsed".format(
                          **stats["snap"]))

    # 3. close -----------------------------------------------------------------------------------
    with timed("close"):
        closure = close_lines(lines, tol.closure, prec)
    for i, gap in zip(closure.closed, closure.gaps, strict=True):
        c = shapely.get_coordinates(lines[i])
        issues.append(Issue("unclosed_line", FIX, shapely.LineString([c[-1], c[0]]),
                            f"ends miss by {gap:.3f} (closure tolerance {tol.closure:g})",
                            (int(src[i]),)))
    lines = closure.lines
    # closed coded lines also code the area they bound (a building plotted closed)
    closed_line = shapely.distance(shapely.get_point(lines, 0), shapely.get_point(lines, -1)) \
        <= prec / 2 if len(lines) else np.zeros(0, bool)
    outlines, outline_src = lines[closed_line], src[closed_line]
    stats["close"] = {"closed": len(closure.closed)}
    progress.step(20, f"close: {len(closure.closed)} polylines closed")

    # 4. node and dissolve -----------------------------------------------------------------------
    with timed("node"):
        noding = node_lines(lines, prec)
        # a polyline plotted in several pieces: an isolated chain whose free ends miss by less
        # than the closure tolerance is closed too (its output arc would be closable on a
        # second run otherwise)
        closing = chain_closures(noding, tol.closure, prec)
        if closing:
            for segment, chain_lines, gap in closing:
                issues.append(Issue("unclosed_line", FIX, segment, f"ends of a chain of "
                                    f"{len(chain_lines)} lines miss by {gap:.3f} (closure "
                                    f"tolerance {tol.closure:g})",
                                    tuple(int(src[i]) for i in chain_lines)))
            lines = np.concatenate([lines, np.array([c[0] for c in closing], dtype=object)])
            src = np.concatenate([src, [src[c[1][0]] for c in closing]]).astype(np.int64)
            noding = node_lines(lines, prec)
            stats["close"]["closed"] += len(closing)
    if len(noding.crossings):
        points = shapely.points(noding.crossings)
        pi, li = shapely.STRtree(lines).query(points, predicate="dwithin", distance=prec)
        through: list[set[int]] = [set() for _ in range(len(points))]
        for k, j in zip(pi.tolist(), src[li].tolist(), strict=True):
            through[k].add(j)
        for point, rows in zip(points, map(sorted, through), strict=True):
            issues.append(Issue("crossing_without_node", FIX, point,
                                f"{len(rows)} lines cross or touch without a vertex", tuple(rows)))
    for i in noding.self_intersecting:
        for where in self_intersection_points(lines[i], prec):
            issues.append(Issue("self_intersection", FIX, where, "line crosses or touches itself",
                                (int(src[i]),)))
    exact = set(noding.exact_duplicates.tolist())
    for i in noding.exact_duplicates:
        issues.append(Issue("duplicate_line", FIX, lines[i], "exact duplicate of another line",
                            (int(src[i]),)))
    overlap_pieces = 0
    for e in noding.duplicate_edges:
        srcs = noding.sources_of(e)
        if len(set(srcs.tolist()) - exact) <= 1:
            continue  # only an exact duplicate line plotted it again: reported above
        overlap_pieces += 1
        issues.append(Issue("duplicate_line", FIX, noding.edges[e],
                            f"piece plotted {len(srcs)} times",
                            tuple(int(src[s]) for s in srcs)))
    stats["node"] = {"edges": noding.counts["edges"],
                     "crossings_noded": noding.counts["crossings_noded"],
                     "self_intersections_noded": noding.counts["self_intersections"]}
    stats["duplicates"] = {"exact_duplicate_lines": noding.counts["exact_duplicates"],
                           "overlapping_pieces": overlap_pieces,
                           "duplicate_length": round(noding.counts["duplicate_length"], 6)}
    progress.step(40, "node: {crossings_noded} crossings noded, {self_intersections_noded} "
                      "self-intersections noded; ".format(**stats["node"])
                  + "duplicates: {exact_duplicate_lines} exact, {overlapping_pieces} overlapping "
                    "pieces".format(**stats["duplicates"]))
    edges = noding.edges
    edge_src = src[noding.sources]  # provenance as input rows
    indptr = noding.indptr

    # 5. dangles, polygonize, slivers ------------------------------------------------------------
    graph = edge_graph(edges, prec)
    lengths = shapely.length(edges)
    alive = np.ones(len(edges), dtype=bool)
    removed = []
    slivers = []
    rounds = 0
    with timed("dangles_polygonize_slivers"):
        while True:
            rounds += 1
            removal = remove_short_dangles(edges, graph, indptr, noding.sources, tol.min_dangle,
                                           alive, progress.feedback.check_canceled)
            alive = removal.alive
            removed += removal.removed
            live = np.flatnonzero(alive)
            faces = polygonize_edges(edges[live])
            left, right = face_sides(edges[live], faces, prec)
            drop, merges = sliver_edges(faces, edges[live], left, right, tol.min_area)
            if not merges or rounds >= MAX_ROUNDS:
                if merges:
                    progress.feedback.push_warning(f"slivers still left after {MAX_ROUNDS} rounds")
                break
            slivers += merges
            alive[live[drop]] = False
    def chain_rows(chain: Chain) -> list[int]:
        return sorted({int(r) for e in chain.edges for r in edge_src[indptr[e]:indptr[e + 1]]})

    kinds = {"overshoot": 0, "dangle": 0, "isolated": 0}
    for chain, kind in removed:
        kinds[kind] += 1
        geom = chain_geometry(edges, chain)
        chain_lines = chain_rows(chain)
        what = {"overshoot": "overshoot", "dangle": "dangle", "isolated": "isolated line"}[kind]
        issues.append(Issue("overshoot" if kind == "overshoot" else "dangle", FIX, geom,
                            f"{what} {chain.length:.3f} long (minimum dangle length "
                            f"{tol.min_dangle:g})", tuple(chain_lines)))
    kept_chains = dangle_chains(graph, lengths, alive)
    kept_dangles = [c for c in kept_chains if not c.isolated]
    unclosed = [c for c in kept_chains if c.isolated]
    for chain in kept_dangles:
        chain_lines = chain_rows(chain)
        issues.append(Issue("dangle", ERROR, chain_geometry(edges, chain),
                            f"dangle kept: {chain.length:.3f} long (minimum dangle length "
                            f"{tol.min_dangle:g}), free end not connected", tuple(chain_lines)))
    for chain in unclosed:
        chain_lines = chain_rows(chain)
        gap = float(np.hypot(*(graph.xy[chain.free_node] - graph.xy[chain.stop_node])))
        issues.append(Issue("unclosed_line", ERROR, chain_geometry(edges, chain),
                            f"line bounds no area: its free ends are {gap:.3f} apart "
                            f"(closure tolerance {tol.closure:g})", tuple(chain_lines)))
    stats["dangles"] = {"overshoots_trimmed": kinds["overshoot"],
                        "dangles_removed": kinds["dangle"] + kinds["isolated"],
                        "dangles_kept": len(kept_dangles), "unclosed_lines": len(unclosed)}
    stats["polygonize"] = {"faces": len(faces), "rounds": rounds}
    stats["slivers"] = {"merged": sum(1 for s in slivers if s.into >= 0),
                        "dropped": sum(1 for s in slivers if s.into < 0)}
    progress.step(70, "dangles: {overshoots_trimmed} overshoots trimmed, {dangles_removed} "
                      "removed, {dangles_kept} kept, {unclosed_lines} unclosed lines; ".format(
                          **stats["dangles"])
                  + f"polygonize: {len(faces)} areas; slivers: {len(slivers)} merged")

    # 7. labels ----------------------------------------------------------------------------------
    label_local = shift(label_geoms, -origin) if len(label_geoms) else label_geoms
    with timed("labels"):
        by_outline = outline_codes(faces, outlines, codes_of_src[outline_src], prec, area_codes)
        labels = assign_labels(faces, label_local, label_codes, label_attributes, by_outline,
                               area_codes)
    face_order = order_key(faces, prec)
    face_id = np.empty(len(faces), dtype=np.int64)
    face_id[face_order] = np.arange(1, len(faces) + 1)

    def area_id(face: int) -> int:
        return int(face_id[face]) if face >= 0 and mode == "build" else 0

    if check_labels:
        bare = np.flatnonzero((labels.face_labels == 0) & np.array([not o for o in by_outline],
                                                                    dtype=bool))
        for f, where, size in zip(bare, shapely.point_on_surface(faces[bare]),
                                  shapely.area(faces[bare]), strict=True):
            issues.append(Issue("unlabelled_area", ERROR, where,
                                f"area of {size:.3f} has no label point", area=int(f)))
        for f, text in labels.conflicts.items():
            issues.append(Issue("conflicting_labels", ERROR, shapely.point_on_surface(faces[f]),
                                text, area=f, label=int(labels.face_first_label[f])))
        for i in np.flatnonzero(labels.label_face < 0):
            geom = label_local[i]
            if geom is None or shapely.is_empty(geom):
                issues.append(Issue("label_outside", ERROR, None, "label without geometry",
                                    label=int(i)))
            else:
                issues.append(Issue("label_outside", ERROR, geom, "label point inside no area "
                                    "(outside the linework or on a boundary)", label=int(i)))
    if slivers:
        final = {}
        if len(faces):
            probes = shapely.point_on_surface([sl.polygon for sl in slivers])
            pi, fi = shapely.STRtree(faces).query(probes, predicate="intersects")
            final = dict(zip(pi.tolist(), fi.tolist(), strict=True))
        for k, sl in enumerate(slivers):
            into = final.get(k, -1)
            where = "" if mode == "check" else (
                f": merged into area {area_id(into)}" if into >= 0 else ": dropped")
            ring = shapely.linestrings(shapely.get_coordinates(shapely.get_exterior_ring(
                sl.polygon)))
            issues.append(Issue("sliver", FIX, ring, f"area {sl.area:.3f} (minimum area "
                                f"{tol.min_area:g}){where}", area=into))
    stats["labels"] = {"checked": False}
    if check_labels:
        stats["labels"] = {"checked": True, "labels": len(label_geoms),
                           "labelled_areas": int(np.sum(labels.face_labels > 0)),
                           "unlabelled_areas": int(np.sum(labels.face_labels == 0)),
                           "conflicting_areas": len(labels.conflicts),
                           "labels_outside": int(np.sum(labels.label_face < 0))}
        progress.step(80, "labels: {labelled_areas} areas labelled, {unlabelled_areas} "
                          "unlabelled, {conflicting_areas} conflicting, {labels_outside} labels "
                          "outside".format(**stats["labels"]))

    # 8. arcs, nodes and layers ------------------------------------------------------------------
    if mode == "build":
        with timed("arcs"):
            live_ptr, live_src = subset_csr(indptr, edge_src, live)
            live_graph = edge_graph(edges[live], prec)
            arcs = build_arcs(edges[live], live_graph, live_ptr, live_src, codes_of_src, prec)
            arc_left, arc_right = face_sides(arcs.geoms, faces, prec)
            nodes = build_nodes(arcs.geoms, prec)
        id_or_zero = np.concatenate([[0], face_id])  # face -1 (outside) -> 0
        fo = face_order
        area_cols: dict[str, Any] = {"id": np.arange(1, len(faces) + 1),
                                     "code": labels.face_code[fo]}
        for name, values in labels.face_attributes.items():
            area_cols[name] = values[fo]
        area_cols["labels"] = labels.face_labels[fo]
        area_cols["area"] = np.round(shapely.area(faces[fo]), 6)
        area_cols["perimeter"] = np.round(shapely.length(faces[fo]), 6)
        areas = Layer(shift(faces[fo], origin), area_cols)
        ao = order_key(arcs.geoms, prec)
        arc_layer = Layer(shift(arcs.geoms[ao], origin), {
            "id": np.arange(1, len(ao) + 1),
            "left_area": id_or_zero[arc_left[ao] + 1],
            "right_area": id_or_zero[arc_right[ao] + 1],
            "codes": arcs.code_key[ao],
            "lines": joined_rows(arcs.src_ptr, arcs.src_rows)[ao],
            "length": np.round(shapely.length(arcs.geoms[ao]), 6)})
        node_layer = Layer(shift(shapely.points(nodes.xy), origin) if len(nodes.xy) else
                           np.zeros(0, dtype=object),
                           {"id": np.arange(1, len(nodes.xy) + 1), "degree": nodes.degree,
                            "kind": nodes.kind})
    else:
        areas = Layer(np.zeros(0, dtype=object), {"id": np.zeros(0, np.int64)})
        arc_layer = Layer(np.zeros(0, dtype=object), {"id": np.zeros(0, np.int64)})
        node_layer = Layer(np.zeros(0, dtype=object), {"id": np.zeros(0, np.int64)})
    errors = issues_layer(issues, origin, area_id)
    severity = errors.columns["severity"]
    stats["output"] = {"areas": len(areas), "arcs": len(arc_layer), "nodes": len(node_layer),
                       "errors": int(np.sum(severity == ERROR)),
                       "fixed" if mode == "build" else "fixable": int(np.sum(severity == FIX))}
    progress.step(100, f"output: {len(areas)} areas, {len(arc_layer)} arcs, {len(node_layer)} "
                       f"nodes, {stats['output']['errors']} errors for the operator, "
                       f"{int(np.sum(severity == FIX))} {FIX}")
    return TopologyOutput(areas, arc_layer, node_layer, errors, stats)
