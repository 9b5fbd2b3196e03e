"""topology:build_areas, topology:check and topology:overlay through the runner and the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely

import toolbox
from toolbox.demo.samples import linework as sample
from toolbox.errors import InputDataError, ParameterError

E0, N0 = sample.E0, sample.N0


def read_errors(path):
    """The errors_points and errors_lines layers together (by id); each holds one kind only."""
    import pandas as pd

    points = gpd.read_file(path, layer="errors_points")
    lines = gpd.read_file(path, layer="errors_lines")
    assert set(points.geom_type.dropna()) <= {"Point"}
    assert set(lines.geom_type) <= {"LineString", "MultiLineString"}
    assert points.crs == lines.crs and points.crs is not None
    both = pd.concat([points, lines], ignore_index=True).sort_values("id")
    assert list(both["id"]) == list(range(1, len(both) + 1))  # ids unique across both
    return gpd.GeoDataFrame(both.reset_index(drop=True), crs=points.crs)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("linework")
    return sample.make(folder, {}) | {"folder": folder}


@pytest.fixture(scope="module")
def built(data):
    out = data["folder"] / "areas.gpkg"
    result = toolbox.run("topology:build_areas", {
        "INPUT": data["linework"], "LABELS": data["linework_labels"],
        "PARAMETERS": data["linework_parameters"], "OUTPUT": out})
    return out, result


def test_build_areas_writes_four_layers(built):
    out, result = built
    assert result["OUTPUT"] == str(out)
    layers = {str(name): str(kind) for name, kind in pyogrio.list_layers(out)}
    assert layers == {"areas": "Polygon", "arcs": "LineString", "nodes": "Point",
                      "errors_points": "Point", "errors_lines": "LineString",
                      "layer_styles": "None"}  # the default styles of areas and errors
    areas = gpd.read_file(out, layer="areas")
    assert areas.crs.to_epsg() == 3003
    assert list(areas.columns) == ["id", "code", "quota", "labels", "area", "perimeter",
                                   "geometry"]
    assert sorted(areas["area"].round(6)) == [40.0, 400.0, 400.0, 600.0, 1800.0, 2760.0]
    assert areas["quota"].dtype.kind == "f"
    road = areas[areas.contains(shapely.Point(E0 + 5, N0 + 30))].iloc[0]
    assert road["code"] == "STR01001" and road["quota"] == pytest.approx(321.0)
    arcs = gpd.read_file(out, layer="arcs")
    assert list(arcs.columns) == ["id", "left_area", "right_area", "codes", "lines", "length",
                                  "geometry"]
    errors = read_errors(out)
    assert set(errors.geom_type) == {"Point", "LineString"}  # both kinds, one per layer
    assert (errors["severity"] == "error").sum() == 5
    stats = result["STATISTICS"]
    assert stats["tolerance_sources"] == {"snap": "file", "closure": "file",
                                          "min_dangle": "file", "min_area": "file",
                                          "precision": "file"}
    assert stats["code_field"] == "code" and stats["crs"] == "EPSG:3003"
    json.dumps(stats)  # the run report needs plain JSON


def test_explicit_tolerance_overrides_the_file(data, tmp_path):
    result = toolbox.run("topology:build_areas", {
        "INPUT": data["linework"], "LABELS": data["linework_labels"],
        "PARAMETERS": data["linework_parameters"], "CLOSURE_TOLERANCE": 0.2,
        "OUTPUT": tmp_path / "a.gpkg"})
    stats = result["STATISTICS"]
    assert stats["tolerance_sources"]["closure"] == "parameter"
    assert stats["close"]["closed"] == 0  # B1's 0.3 m gap stays open
    assert stats["output"]["areas"] == 5  # B1 is no area; garden and pavement merge


def test_rerun_on_own_arcs_changes_nothing(built, tmp_path):
    out, result = built
    again = toolbox.run("topology:build_areas", {
        "INPUT": f"{out}|layername=arcs", "CODE_FIELD": "codes",
        "LABELS": str(sample_labels_path(built)), "OUTPUT": tmp_path / "again.gpkg"})
    first = gpd.read_file(out, layer="areas")
    second = gpd.read_file(tmp_path / "again.gpkg", layer="areas")
    assert again["STATISTICS"]["output"]["fixed"] == 0
    assert shapely.equals_exact(first.geometry.values, second.geometry.values, 1e-9).all()
    assert list(first["code"].fillna("")) == list(second["code"].fillna(""))


def sample_labels_path(built):
    return built[0].parent / "siena_labels.gpkg"


def test_check_writes_only_errors(data, tmp_path):
    out = tmp_path / "check.gpkg"
    result = toolbox.run("topology:check", {"INPUT": data["linework"], "OUTPUT": out})
    assert [str(n) for n, _ in pyogrio.list_layers(out)] == ["errors_points", "errors_lines",
                                                             "layer_styles"]
    errors = read_errors(out)
    assert set(errors["severity"]) == {"fixable", "error"}
    assert not errors["type"].isin(["unlabelled_area", "label_outside"]).any()  # no LABELS
    assert result["STATISTICS"]["output"] == {"errors": 2, "fixable": 15}
    # the input is untouched
    assert shapely.equals_exact(gpd.read_file(data["linework"]).geometry.values,
                                sample.sheet_lines().geometry.values, 1e-6).all()


def test_geodataframe_inputs_with_invalid_features(tmp_path):
    lines = sample.sheet_lines()
    extra = gpd.GeoDataFrame({"code": ["X", "Y"]},
                             geometry=[None, shapely.Point(E0 + 1, N0 + 1)], crs=lines.crs)
    frame = gpd.GeoDataFrame(np.concatenate([lines.values, extra.values]),
                             columns=lines.columns, geometry="geometry", crs=lines.crs)
    result = toolbox.run("topology:build_areas", {"INPUT": frame, "OUTPUT": tmp_path / "x.gpkg"})
    assert result["STATISTICS"]["input"]["invalid"] == 2
    errors = read_errors(tmp_path / "x.gpkg")
    invalid = errors[errors["type"] == "invalid_geometry"]
    assert sorted(invalid["lines"]) == ["15", "16"]


def test_crs_mismatch_refused(data, tmp_path):
    labels = sample.sheet_labels().to_crs("EPSG:3004")
    with pytest.raises(InputDataError, match="LABELS is in EPSG:3004 but INPUT is in EPSG:3003"):
        toolbox.run("topology:build_areas", {"INPUT": data["linework"], "LABELS": labels,
                                             "OUTPUT": tmp_path / "x.gpkg"})
    assert not (tmp_path / "x.gpkg").exists()


def test_bad_parameter_file_fails_before_any_output(data, tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("tolleranza di chiusura = mezzo metro\n")
    with pytest.raises(InputDataError, match="line 1: 'tolleranza di chiusura' must be a number"):
        toolbox.run("topology:build_areas", {"INPUT": data["linework"], "PARAMETERS": bad,
                                             "OUTPUT": tmp_path / "x.gpkg"})
    assert not (tmp_path / "x.gpkg").exists()


def test_wrong_layer_kind_and_unknown_field(data, tmp_path):
    with pytest.raises(ParameterError, match="LABELS must be a point layer"):
        toolbox.run("topology:build_areas", {"INPUT": data["linework"],
                                             "LABELS": data["linework"],
                                             "OUTPUT": tmp_path / "x.gpkg"})
    with pytest.raises(ParameterError, match="CODE_FIELD field 'codice' is not in"):
        toolbox.run("topology:build_areas", {"INPUT": data["linework"], "CODE_FIELD": "codice",
                                             "OUTPUT": tmp_path / "x.gpkg"})


def test_cli_run_and_user_error(data, tmp_path):
    from click.testing import CliRunner

    from toolbox.cli import main

    out = tmp_path / "cli.gpkg"
    runner = CliRunner()
    res = runner.invoke(main, ["-q", "run", "topology:check", "--INPUT", str(data["linework"]),
                               "--LABELS", str(data["linework_labels"]), "--SNAP_TOLERANCE",
                               "0.2", "--OUTPUT", str(out)])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["STATISTICS"]["output"]["errors"] == 5
    res = runner.invoke(main, ["run", "topology:build_areas", "--INPUT", str(data["linework"]),
                               "--MIN_AREA", "-1", "--OUTPUT", str(tmp_path / "y.gpkg")])
    assert res.exit_code == 2
    assert "MIN_AREA must be >= 0, got '-1'" in res.stderr
    assert "Traceback" not in res.output


def test_cli_subprocess_help():
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "help", "topology:build_areas"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    for name in ("SNAP_TOLERANCE", "CLOSURE_TOLERANCE", "MIN_DANGLE_LENGTH", "MIN_AREA",
                 "PARAMETERS", "LABELS"):
        assert name in proc.stdout


# -- overlay --------------------------------------------------------------------------------------
def squares(crs="EPSG:3003"):
    a = gpd.GeoDataFrame({"name": ["A"], "n": [1]},
                         geometry=[shapely.box(E0, N0, E0 + 20, N0 + 20)], crs=crs)
    b = gpd.GeoDataFrame({"zone": ["Z"], "n": [2]},
                         geometry=[shapely.box(E0 + 10, N0 + 10, E0 + 30, N0 + 30)], crs=crs)
    return a, b


@pytest.mark.parametrize("operation, parts", [
    ("intersection", {"ab": 100.0}),
    ("difference", {"a": 300.0}),
    ("symmetric_difference", {"a": 300.0, "b": 300.0}),
    ("union", {"ab": 100.0, "a": 300.0, "b": 300.0}),
])
def test_overlay_known_areas_and_both_sides_attributes(tmp_path, operation, parts):
    a, b = squares()
    out = tmp_path / f"{operation}.gpkg"
    result = toolbox.run("topology:overlay", {"INPUT": a, "OVERLAY": b, "OPERATION": operation,
                                              "OUTPUT": out})
    frame = gpd.read_file(out, layer=operation)
    assert dict(zip(frame["part"], frame["area"].round(6), strict=True)) == parts
    assert result["STATISTICS"]["pieces"] == len(parts)
    for _, row in frame.iterrows():
        assert shapely.area(row.geometry) == pytest.approx(row["area"])
        assert (row["a_name"] == "A") == ("a" in row["part"])
        if operation != "difference":
            assert (row["b_zone"] == "Z") == ("b" in row["part"])
            assert (row["b_n"] == 2) == ("b" in row["part"])
    if operation == "difference":
        assert "b_zone" not in frame.columns
    assert len(read_errors(out)) == 0


def test_overlay_repairs_and_reports_invalid_areas(tmp_path):
    a, b = squares()
    bowtie = shapely.Polygon([(E0, N0), (E0 + 10, N0 + 10), (E0 + 10, N0), (E0, N0 + 10)])
    flat = shapely.Polygon([(E0, N0), (E0 + 5, N0), (E0 + 10, N0)])
    a = gpd.GeoDataFrame({"name": ["A", "bow", "flat"], "n": [1, 2, 3]},
                         geometry=[a.geometry[0], bowtie, flat], crs=a.crs)
    out = tmp_path / "o.gpkg"
    result = toolbox.run("topology:overlay", {"INPUT": a, "OVERLAY": b, "OUTPUT": out,
                                              "OPERATION": "union"})
    errors = read_errors(out)
    assert sorted(zip(errors["type"], errors["severity"], errors["lines"], strict=True)) == [
        ("self_intersection", "error", "3"), ("self_intersection", "fixed", "2")]
    fixed = errors[errors["severity"] == "fixed"].geometry.iloc[0]
    assert fixed.equals(shapely.Point(E0 + 5, N0 + 5))  # where GEOS found the crossing
    assert result["STATISTICS"]["input"] == {"features": 3, "skipped": 1, "repaired": 1}
    frame = gpd.read_file(out, layer="union")
    bow = frame[frame["a_name"] == "bow"]
    assert bow["area"].sum() == pytest.approx(50.0)  # two triangles of 25 m²


def test_overlay_prefix_clash(tmp_path):
    a, b = squares()
    with pytest.raises(ParameterError, match="OVERLAY_PREFIX 'a_' gives field 'a_n' to both"):
        toolbox.run("topology:overlay", {"INPUT": a, "OVERLAY": b, "OVERLAY_PREFIX": "a_",
                                         "OUTPUT": tmp_path / "o.gpkg"})
    c = b.rename(columns={"zone": "rea"})
    with pytest.raises(ParameterError, match="OVERLAY_PREFIX 'a' makes field 'area', which the "
                                             "output uses itself"):
        toolbox.run("topology:overlay", {"INPUT": a, "OVERLAY": c, "OVERLAY_PREFIX": "a",
                                         "OUTPUT": tmp_path / "o.gpkg"})


def test_3d_spot_heights_become_label_z(data, tmp_path):
    labels = sample.sheet_labels()
    labels["geometry"] = shapely.force_3d(labels.geometry.values, 300.0 + np.arange(len(labels)))
    labels.loc[6, "geometry"] = None  # a label without geometry is reported, not fatal
    out = tmp_path / "z.gpkg"
    toolbox.run("topology:build_areas", {"INPUT": data["linework"], "LABELS": labels,
                                         "OUTPUT": out})
    areas = gpd.read_file(out, layer="areas")
    assert "label_z" in areas.columns and areas["label_z"].dtype.kind == "f"
    b1 = areas[areas.contains(shapely.Point(E0 + 30, N0 + 30))].iloc[0]
    assert b1["label_z"] == pytest.approx(301.0)  # label 2
    errors = read_errors(out)
    assert sorted(errors.loc[errors["type"] == "label_outside", "label_id"]) == [7, 8]


def test_one_point_multipoint_labels_count_and_several_points_are_refused(data, tmp_path):
    """Labels stored as MultiPoints (as shapefiles store points): a one-point MultiPoint labels
    its area as the Point does (it was reported "inside no area", its area "without label",
    and written as a MULTIPOINT into the Point errors layer); one of several points is refused
    naming LABELS and the feature, since which area it labels is ambiguous."""
    labels = sample.sheet_labels()
    reference = toolbox.run("topology:build_areas", {"INPUT": data["linework"], "LABELS": labels,
                                                     "OUTPUT": tmp_path / "p.gpkg"})
    multi = labels.copy()
    multi["geometry"] = [shapely.MultiPoint([g]) if g is not None else None
                         for g in labels.geometry]
    result = toolbox.run("topology:build_areas", {"INPUT": data["linework"], "LABELS": multi,
                                                  "OUTPUT": tmp_path / "m.gpkg"})
    assert result["STATISTICS"] == reference["STATISTICS"]
    ours, theirs = (gpd.read_file(tmp_path / f, layer="areas") for f in ("m.gpkg", "p.gpkg"))
    assert ours.drop(columns="geometry").equals(theirs.drop(columns="geometry"))
    read_errors(tmp_path / "m.gpkg")  # one kind per layer: Points only in errors_points
    multi.loc[2, "geometry"] = shapely.MultiPoint([(E0 + 30, N0 + 30), (E0 + 70, N0 + 30)])
    with pytest.raises(ParameterError, match=r"LABELS must hold one point per feature: "
                                             r"feature row\(s\) 3 hold several points"):
        toolbox.run("topology:build_areas", {"INPUT": data["linework"], "LABELS": multi,
                                             "OUTPUT": tmp_path / "x.gpkg"})
    assert not (tmp_path / "x.gpkg").exists()


def test_all_invalid_input_writes_empty_layers(tmp_path):
    frame = gpd.GeoDataFrame({"code": ["A", "B"]},
                             geometry=[shapely.LineString([(E0, N0), (E0, N0)]), None],
                             crs="EPSG:3003")
    out = tmp_path / "empty.gpkg"
    result = toolbox.run("topology:build_areas", {"INPUT": frame, "OUTPUT": out})
    assert result["STATISTICS"]["output"]["areas"] == 0
    layers = {str(name): str(kind) for name, kind in pyogrio.list_layers(out)}
    assert layers == {"areas": "Polygon", "arcs": "LineString", "nodes": "Point",
                      "errors_points": "Point", "errors_lines": "LineString",
                      "layer_styles": "None"}  # the default styles of areas and errors
    errors = read_errors(out)
    assert list(errors["type"]) == ["invalid_geometry"] * 2
    assert sorted(errors["lines"]) == ["1", "2"]
