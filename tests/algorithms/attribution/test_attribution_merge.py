"""The model merge ("fusione"): lines joined across the model edge, duplicates removed."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely
from restitution_files import make_files  # the test folder's helper module

import toolbox
from tests.toolbox.export_files import write_export
from toolbox.attribution.model_merge import merge_models
from toolbox.attribution.restitution import entity_frame


@pytest.fixture
def files(tmp_path):
    """Code, colour, parameter files and an ASCII export with every defect (see make_files)."""
    return make_files(tmp_path)

E0, N0 = 1688600.0, 4799900.0


def _model(entities):
    rows = [{"entity": k + 1, "code": c, "kind": "line" if len(p) > 1 else "point",
             "file": "m", "line": None} for k, (c, p) in enumerate(entities)]
    geoms = [shapely.LineString(p) if len(p) > 1 else shapely.Point(p[0]) for _, p in entities]
    return entity_frame(rows, geoms, "EPSG:3003")


WEST = [
    ("STR02001", [(0, 0, 320.0), (49.95, 0.05, 320.4)]),      # 1 joins east 1 (gap 0.112)
    ("STR02001", [(0, 10, 320.0), (50, 10, 320.3)]),          # 2 meets east 2, dz 0.5: refused
    ("FAB01002", [(45, 20, 330), (55, 20, 330), (55, 30, 330), (45, 30, 330), (45, 20, 330)]),
    ("MUR01001", [(0, 40, 321), (50, 40, 321)]),              # 4 east 4 is another code
    ("STR02001", [(10, 50, 320), (20, 50, 320)]),             # 5 and 6: same model, not joined
    ("STR02001", [(20.05, 50, 320), (30, 50, 320)]),
    ("QUO01001", [(48, 5, 320.5)]),                           # 7 spot height in both models
]
EAST = [
    ("STR02001", [(100, 0, 320.9), (50.05, 0, 320.45)]),      # plotted the other way round
    ("STR02001", [(50.02, 10, 320.8), (100, 10, 321)]),
    ("FAB01002", [(45.03, 20.02, 330.02), (55, 20, 330), (55.04, 30, 330), (45, 30.01, 330),
                  (45.03, 20.02, 330.02)]),                   # 3 again: duplicate
    ("SIE01001", [(50.05, 40, 321), (100, 40, 321)]),
    ("QUO01001", [(48.02, 5.01, 320.55)]),                    # duplicate spot height
]


def test_merge_kernel():
    result = merge_models([_model(WEST), _model(EAST)], 0.2, 0.1)
    assert result.statistics == {"models": 2, "entities_in": 12, "duplicates_removed": 2,
                                 "joins": 1, "joins_refused_height": 1, "entities_out": 9}
    merged = result.entities
    joined = merged[(merged["model"] == 1) & (merged["entity"] == 1)].geometry.iloc[0]
    np.testing.assert_allclose(shapely.get_coordinates(joined, include_z=True), [
        [0, 0, 320.0], [50.0, 0.025, 320.425], [100, 0, 320.9]], atol=1e-9)
    kinds = [(e["kind"], e["detail"]) for e in result.events]
    assert ("duplicate_removed", "model 2 entity 3 duplicates model 1 entity 3") in kinds
    assert ("duplicate_removed", "model 2 entity 5 duplicates model 1 entity 7") in kinds
    assert ("joined", "model 2 entity 1 joined to model 1 entity 1 (gap 0.112)") in kinds
    refused = [d for k, d in kinds if k == "join_refused"]
    assert refused == ["model 1 entity 2 and model 2 entity 2 meet in plan (0.020) but differ "
                       "by 0.500 in height (tolerance 0.1)"]
    # same-model ends and different codes are never joined
    assert len(merged[merged["code"] == "STR02001"]) == 5 and len(merged) == 9


def test_merge_joins_short_lines_in_map_coordinates():
    # a 10 m road edge at map coordinates (E 1.69e6): its ends are distinct points, so it is an
    # open line and joins its continuation (a relative tolerance would have called it closed)
    west = [("STR02001", [(E0, N0, 320.0), (E0 + 10, N0, 320.0)])]
    east = [("STR02001", [(E0 + 10.05, N0, 320.02), (E0 + 20, N0, 320.0)])]
    result = merge_models([_model(west), _model(east)], 0.2, 0.1)
    assert result.statistics["joins"] == 1 and len(result.entities) == 1
    np.testing.assert_allclose(
        shapely.get_coordinates(result.entities.geometry.iloc[0], include_z=True),
        [[E0, N0, 320.0], [E0 + 10.025, N0, 320.01], [E0 + 20, N0, 320.0]], atol=1e-6)


def test_merge_chains_through_a_line_of_the_same_model():
    # 1 (model 1) meets 2 (model 2); 2 meets 3 (also model 2): 2 and 3 are not joined alone, but
    # once 2 is part of model 1's line its far end joins 3; 4 (model 3) then joins the end of 3
    # plotted the other way round; the closest ends are joined first
    m1 = [("STR02001", [(0, 0, 320.0), (10, 0, 320.0)])]
    m2 = [("STR02001", [(10.1, 0, 320.0), (20, 0, 320.0)]),
          ("STR02001", [(20.04, 0, 320.0), (30, 0, 320.0)])]
    m3 = [("STR02001", [(40, 0, 320.0), (30.02, 0, 320.0)])]
    result = merge_models([_model(m1), _model(m2), _model(m3)], 0.2, 0.1)
    assert result.statistics["joins"] == 3 and len(result.entities) == 1
    np.testing.assert_allclose(
        shapely.get_coordinates(result.entities.geometry.iloc[0]),
        [[0, 0], [10.05, 0], [20.02, 0], [30.01, 0], [40, 0]], atol=1e-9)
    assert [e["detail"] for e in result.events] == [
        "model 3 entity 1 joined to model 2 entity 2 (gap 0.020)",
        "model 2 entity 1 joined to model 1 entity 1 (gap 0.100)",
        "model 2 entity 2 joined to model 1 entity 1 (gap 0.040)"]


def test_apply_merges_models(files, tmp_path):
    def export(entities, name):
        return write_export(tmp_path / name, entities)

    out = tmp_path / "merged.gpkg"
    stats = toolbox.run("attribution:apply", {
        "INPUT": [export(WEST, "ovest.txt"), export(EAST, "est.txt")], "CODES": files["codes"],
        "SNAP_TOLERANCE": 0.2, "HEIGHT_SNAP_TOLERANCE": 0.1, "CRS": "EPSG:3003",
        "OUTPUT": out})["STATISTICS"]
    assert stats["merge"]["joins"] == 1 and stats["merge"]["duplicates_removed"] == 2
    roads = gpd.read_file(out, layer="STR02001")
    assert len(roads) == 5 and roads["length"].max() == np.round(
        np.hypot(50, 0.025) + np.hypot(50, 0.025), 6)
    report = gpd.read_file(out, layer="merge")
    assert sorted(report["kind"]) == ["duplicate_removed", "duplicate_removed", "join_refused",
                                      "joined"]
    assert stats["unknown_codes"] == ["MUR01001", "SIE01001"]  # not in the code file


def test_merge_algorithm(tmp_path):
    paths = []
    for name, entities in (("ovest", WEST), ("est", EAST)):
        lines = []
        for code, pts in entities:
            lines.append(f"CODE {code}")
            lines += [f"{x:.3f} {y:.3f} {z:.3f}" for x, y, z in pts]  # stored: map - translation
            lines.append("END")
        paths.append(tmp_path / f"{name}.txt")
        paths[-1].write_text("\n".join(lines) + "\n")
    params = tmp_path / "parametri.txt"
    params.write_text(f"traslazione delle coordinate = {E0:.0f} {N0:.0f}\n"
                      "tolleranza di riattacco planimetrico = 0.2\n"
                      "tolleranza di riattacco altimetrico = 0.1\n"
                      "tolleranza di chiusura = 0.5\n")
    out = tmp_path / "fusione.gpkg"
    feedback = toolbox.Feedback()
    stats = toolbox.run("attribution:merge", {"INPUT": paths, "PARAMETERS": params,
                                              "CRS": "EPSG:3003", "OUTPUT": out},
                        feedback=feedback)["STATISTICS"]
    assert stats["joins"] == 1 and stats["duplicates_removed"] == 2
    assert stats["layers"] == {"points": 1, "lines": 8, "merge": 4}
    lines = gpd.read_file(out, layer="lines")
    assert lines.total_bounds.tolist() == [E0, N0, E0 + 100, N0 + 50]
    infos = [text for level, text in feedback.messages if level == "info"]
    assert any("'tolleranza di chiusura' (line 4)" in m for m in infos)  # for other steps
    assert not any("tolleranza di chiusura" in w for w in feedback.warnings)
    with pytest.raises(toolbox.ToolboxError, match="at least two models"):
        toolbox.run("attribution:merge", {"INPUT": paths[:1], "OUTPUT": tmp_path / "x.gpkg"})


@pytest.mark.parametrize("algorithm", ["attribution:merge", "attribution:apply"])
def test_models_in_two_crs_are_refused_naming_them(files, tmp_path, algorithm):
    """Two models' layers in EPSG:3003 and in UTM: one line naming both (it stopped with an
    internal error, geopandas' 'Cannot determine common CRS for concatenation')."""
    paths = []
    for (name, entities), crs in zip((("ovest", WEST), ("est", EAST)),
                                     ("EPSG:3003", "EPSG:32632"), strict=True):
        frame = gpd.GeoDataFrame(
            {"code": [code for code, _ in entities]},
            geometry=[shapely.LineString([(E0 + x, N0 + y, z) for x, y, z in pts])
                      if len(pts) > 1 else shapely.Point(E0 + pts[0][0], N0 + pts[0][1])
                      for _, pts in entities], crs="EPSG:3003").to_crs(crs)
        paths.append(tmp_path / f"{name}.gpkg")
        frame[frame.geom_type == "LineString"].to_file(paths[-1])
    params = {"INPUT": paths, "OUTPUT": tmp_path / "out.gpkg"} | (
        {"CODES": files["codes"]} if algorithm == "attribution:apply" else {})
    with pytest.raises(toolbox.InputDataError, match="INPUT 2 is in EPSG:32632 but INPUT 1 is "
                                                     "in EPSG:3003"):
        toolbox.run(algorithm, params)
    assert not (tmp_path / "out.gpkg").exists()


@pytest.mark.parametrize("algorithm", ["attribution:merge", "attribution:apply"])
def test_a_snap_tolerance_larger_than_the_features_warns(files, tmp_path, algorithm):
    """SNAP_TOLERANCE had no size check in the model merge (topology warns above a quarter of
    the median line extent): the models' bounding-box diagonals, by hand, are 9.95, 10, 14.14,
    14.2, 49.95, 49.95, 49.95, 49.98, 50, 50 (points left out): median 49.95, a quarter 12.49,
    so 20 m warns and 12 m does not."""
    paths = []
    for name, entities in (("ovest", WEST), ("est", EAST)):
        lines = []
        for code, pts in entities:
            lines.append(f"CODE {code}")
            lines += [f"{E0 + x:.3f} {N0 + y:.3f} {z:.3f}" for x, y, z in pts]
            lines.append("END")
        paths.append(tmp_path / f"{name}.txt")
        paths[-1].write_text("\n".join(lines) + "\n")
    extra = {"CODES": files["codes"]} if algorithm == "attribution:apply" else {}
    for snap, warns in ((20.0, True), (12.0, False)):
        feedback = toolbox.Feedback()
        toolbox.run(algorithm, {"INPUT": paths, "SNAP_TOLERANCE": snap, "CRS": "EPSG:3003",
                                "OUTPUT": tmp_path / f"{snap}.gpkg", **extra}, feedback=feedback)
        hits = [w for w in feedback.warnings if w.startswith(f"SNAP_TOLERANCE {snap:g} is large")]
        assert bool(hits) is warns, feedback.warnings
        if warns:
            assert "median input line extent (bounding-box diagonal) is 49.9" in hits[0]
