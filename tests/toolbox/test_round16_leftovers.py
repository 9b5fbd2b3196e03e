"""Round 16 leftovers: defects left by the last round, each with the test that failed before."""

from __future__ import annotations

import json
import tracemalloc

import geopandas as gpd
import numpy as np
import shapely

import toolbox
from toolbox.feedback import Feedback
from toolbox.topology.build import build_topology
from toolbox.topology.tolerances import Tolerances


# -- 1. topology: a snap tolerance large for the features is warned about ------------------------
def _buildings(n=4, size=10.0, spacing=20.0):
    """n x n closed square outlines of ``size`` m (bounding-box diagonal size*sqrt(2))."""
    return np.array([shapely.LineString([(x, y), (x + size, y), (x + size, y + size),
                                         (x, y + size), (x, y)])
                     for i in range(n) for j in range(n)
                     for x, y in [(1_500_000 + spacing * i, 5_000_000 + spacing * j)]],
                    dtype=object)


def test_large_snap_tolerance_warns_naming_parameter_value_and_size():
    fb = Feedback()
    out = build_topology(_buildings(), tolerances=Tolerances(snap=200.0), feedback=fb)
    [warning] = [w for w in fb.warnings if "SNAP_TOLERANCE" in w]
    assert "200" in warning and "14.1" in warning  # 10 m squares: diagonal 14.14 m
    assert len(out.areas) != 16  # the buildings are mangled indeed: the warning is deserved


def test_usual_snap_tolerance_is_silent():
    fb = Feedback()
    out = build_topology(_buildings(), tolerances=Tolerances(snap=0.2), feedback=fb)
    assert len(out.areas) == 16
    assert not [w for w in fb.warnings if "SNAP_TOLERANCE" in w]
    fb = Feedback()  # 3 m: just under a quarter of the 14.14 m diagonal, still silent
    build_topology(_buildings(), tolerances=Tolerances(snap=3.0), feedback=fb)
    assert not [w for w in fb.warnings if "SNAP_TOLERANCE" in w]


def test_large_snap_warning_reaches_the_run_report(tmp_path):
    src = tmp_path / "b.gpkg"
    gpd.GeoDataFrame({"code": ["FAB"] * 16}, geometry=list(_buildings()),
                     crs="EPSG:3003").to_file(src)
    report = tmp_path / "run.json"
    toolbox.run("topology:build_areas", {"INPUT": str(src), "SNAP_TOLERANCE": 200,
                                         "OUTPUT": str(tmp_path / "o.gpkg")}, report=report)
    doc = json.loads(report.read_text())
    assert any("SNAP_TOLERANCE 200" in w for w in doc["warnings"])


# -- 2. attribution:sample keeps its moved_vertices rows in arrays, written block by block ------
def _lines(tmp_path, lengths):
    src = tmp_path / "lines.gpkg"
    g = [shapely.LineString([(1_500_000, 5_000_000 + 10 * i), (1_500_000 + n, 5_000_000 + 10 * i)])
         for i, n in enumerate(lengths)]
    gpd.GeoDataFrame({"code": ["A"] * len(g)}, geometry=g, crs="EPSG:3003").to_file(src)
    return src


def test_densify_moved_vertices_memory_per_row_is_tens_of_bytes(tmp_path, monkeypatch):
    import toolbox.attribution.edit_io as edit_io

    monkeypatch.setattr(edit_io, "MOVED_BLOCK", 1000, raising=False)
    src = _lines(tmp_path, [2000] * 10)  # 10 x 1999 added vertices with DISTANCE 1
    params = {"INPUT": str(src), "METHOD": "densify", "DISTANCE": 1,
              "OUTPUT": str(tmp_path / "o.gpkg")}
    toolbox.run("attribution:sample", params)  # imports and caches out of the measure
    tracemalloc.start()
    try:
        toolbox.run("attribution:sample", params, overwrite=True)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    rows = 10 * 1999
    assert peak / rows < 200  # a dict a row took about 600 B (1 kB in RSS); arrays about 60


def test_densify_moved_vertices_rows_across_blocks(tmp_path, monkeypatch):
    import toolbox.attribution.edit_io as edit_io

    monkeypatch.setattr(edit_io, "MOVED_BLOCK", 4, raising=False)
    src = _lines(tmp_path, [10, 3, 5])  # DISTANCE 1: 9, 2 and 4 vertices added
    out = tmp_path / "o.gpkg"
    toolbox.run("attribution:sample", {"INPUT": str(src), "METHOD": "densify", "DISTANCE": 1,
                                       "OUTPUT": str(out)})
    m = gpd.read_file(out, layer="moved_vertices")
    want = [(f, k + 1, 1_500_000 + k, 5_000_000 + 10 * (f - 1))
            for f, n in ((1, 10), (2, 3), (3, 5)) for k in range(1, n)]
    got = list(zip(m["feature"].astype(int), m["vertex"], m.geometry.x, m.geometry.y,
                   strict=True))
    assert got == want
    assert set(m["change"]) == {"added"} and not m[["dx", "dy", "displacement"]].any().any()
    assert m.crs.to_epsg() == 3003


# -- 3. toolbox.run from Python: a Ctrl-C during the commit waits for its end -------------------
def _square_layer(tmp_path):
    src = tmp_path / "in.gpkg"
    ring = np.array([(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]) + (1_500_000, 5_000_000)
    gpd.GeoDataFrame({"code": ["A"]}, geometry=[shapely.LineString(ring)],
                     crs="EPSG:3003").to_file(src)
    return src


def test_api_commit_holds_sigint_until_every_file_is_in_place(tmp_path, monkeypatch):
    import signal

    import pytest

    import toolbox.io.staging as staging

    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # as in a script
    original, moves = staging._move_no_replace, []

    def move(item, target):  # Ctrl-C right after the first file was moved into place
        original(item, target)
        moves.append(target)
        if len(moves) == 1:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(staging, "_move_no_replace", move)
    out = tmp_path / "out.shp"  # five layers, five files each, and the .qml/.sld beside the
    # three styled ones (areas, errors_points, errors_lines): 31 moves
    with pytest.raises(KeyboardInterrupt):
        toolbox.run("topology:build_areas", {"INPUT": str(_square_layer(tmp_path)),
                                             "OUTPUT": str(out)})
    written = sorted(p.name for p in tmp_path.glob("out*"))
    assert len(moves) == 31 and written == sorted(p.name for p in moves)  # all, not out.shp only
    for layer in ("", "_arcs", "_nodes", "_errors_points", "_errors_lines"):
        for ext in (".shp", ".shx", ".dbf"):
            assert (tmp_path / f"out{layer}{ext}").exists()
    assert not list(tmp_path.glob(".*.part"))
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back


def test_commit_section_in_another_thread_installs_no_handler():
    import signal
    import threading

    import toolbox.io.staging as staging

    before = {s: signal.getsignal(s) for s in staging.HELD_SIGNALS}
    seen, errors = [], []

    def work():
        try:
            with staging._signals_held():
                seen.append({s: signal.getsignal(s) for s in staging.HELD_SIGNALS})
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    t = threading.Thread(target=work)
    t.start()
    t.join()
    assert not errors and seen == [before]
    with staging._signals_held():  # the main thread's section holds, then puts them back
        assert signal.getsignal(signal.SIGINT) is not before[signal.SIGINT]
    assert {s: signal.getsignal(s) for s in staging.HELD_SIGNALS} == before


# -- 4. a failing pipeline step is numbered and named; GDAL's warnings reach the run report -----
def _pipeline(tmp_path):
    ok = _square_layer(tmp_path)
    zero = tmp_path / "zero.gpkg"  # a zero-length line: attribution:sample refuses it at run time
    gpd.GeoDataFrame({"code": ["A"]}, geometry=[shapely.LineString([(1_500_000, 5_000_000)] * 2)],
                     crs="EPSG:3003").to_file(zero)
    pipe = tmp_path / "p.yaml"
    pipe.write_text(
        "steps:\n"
        f"  - {{name: areas, algorithm: topology:build_areas, params: {{INPUT: {ok}, "
        "OUTPUT: a.gpkg}}\n"
        f"  - {{name: resample, algorithm: attribution:sample, params: {{INPUT: {zero}, "
        "METHOD: densify, DISTANCE: 1, OUTPUT: s.gpkg}}\n"
        f"  - {{name: last, algorithm: attribution:sample, params: {{INPUT: {ok}, "
        "METHOD: densify, DISTANCE: 1, OUTPUT: s2.gpkg}}\n")
    return pipe


def test_failing_pipeline_step_is_numbered_and_named(tmp_path):
    import pytest

    from toolbox.batch import load_pipeline, run_pipeline
    from toolbox.errors import PipelineError

    with pytest.raises(PipelineError) as info:
        run_pipeline(load_pipeline(_pipeline(tmp_path)))
    assert str(info.value).startswith("step 2 of 3 (attribution:sample 'resample'): INPUT "
                                      "feature 1 has zero length")
    assert (tmp_path / "a.gpkg").exists() and not (tmp_path / "s.gpkg").exists()


def test_interrupted_or_broken_pipeline_step_is_numbered_and_named(tmp_path, monkeypatch):
    import pytest

    from toolbox.batch import load_pipeline, run_pipeline
    from toolbox.cli.app import interrupted_message
    from toolbox.registry import get

    def broken(self, params, feedback):
        raise ValueError("a bug")

    monkeypatch.setattr(get("attribution:sample"), "process", broken)
    with pytest.raises(ValueError) as info:  # an internal error: the CLI names the step too
        run_pipeline(load_pipeline(_pipeline(tmp_path)))
    assert info.value.step == "step 2 of 3 (attribution:sample 'resample')"
    assert interrupted_message(2, info.value).startswith(
        "canceled during step 2 of 3 (attribution:sample 'resample');")


def test_gdal_warning_logged_through_rasterio_is_in_the_run_report(tmp_path, monkeypatch):
    import rasterio
    from rasterio.transform import from_origin

    from toolbox.registry import get

    alg = get("topology:build_areas")
    process = alg.process

    def noisy(self, params, feedback):  # GDAL: "driver GTiff does not support creation option"
        with rasterio.open(tmp_path / "side.tif", "w", driver="GTiff", width=2, height=2,
                           count=1, dtype="uint8", crs="EPSG:3003",
                           transform=from_origin(1_500_000, 5_000_002, 1, 1), foo="yes") as d:
            d.write(np.zeros((1, 2, 2), "uint8"))
        return process(self, params, feedback)

    monkeypatch.setattr(alg, "process", noisy)
    report = tmp_path / "r.json"
    toolbox.run("topology:build_areas", {"INPUT": str(_square_layer(tmp_path)),
                                         "OUTPUT": str(tmp_path / "o.gpkg")}, report=report)
    warnings = json.loads(report.read_text())["warnings"]
    assert [w for w in warnings if "creation option FOO" in w and w.startswith("GDAL")]
