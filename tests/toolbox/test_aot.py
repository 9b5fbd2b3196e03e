"""Kernels compiled ahead of time (toolbox.aot): built with numba's pycc into a fresh cache
folder, the contour kernel gives numba's JIT arrays bit for bit (the JIT is checked against
contourpy in tests/toolbox/cartography/test_contour_kernel.py), a run loads it without
importing numba and writes the JIT run's contours; a missing or broken build falls back to the
JIT, and a failed build in the warm-up is a warning."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from toolbox import aot
from toolbox.cartography.contour_kernel import grid_lines

pytestmark = pytest.mark.skipif(
    shutil.which(os.environ.get("CC", "cc")) is None
    or not Path(sysconfig.get_paths()["include"], "Python.h").exists(),
    reason="no C compiler or Python headers: the ahead-of-time build is skipped by design")


@pytest.fixture(scope="module")
def cache_home(tmp_path_factory) -> dict[str, str]:
    """A fresh per-user cache with the kernels built in it (a process of its own, as
    ``toolbox warmup``); numba's JIT cache stays the session's."""
    home = tmp_path_factory.mktemp("cache")
    env = os.environ | {"XDG_CACHE_HOME": str(home)}
    code = ("from toolbox.aot import aot_folder, build_compiled; build_compiled(); "
            "print(aot_folder())")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, check=True)
    return {"env": env, "folder": proc.stdout.strip().splitlines()[-1]}


def surfaces() -> list[tuple[str, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(11)
    smooth = gaussian_filter(rng.normal(size=(160, 210)), 6) * 60.0
    holes = smooth.copy()
    holes[40:55, 60:90] = np.nan
    holes[rng.random(holes.shape) < 0.01] = np.nan
    plateaus = np.round(smooth / 2.0) * 2.0  # heights exactly at the levels
    saddles = np.tile(np.array([[0.0, 1.0], [1.0, 0.0]]), (30, 40))
    return [("smooth", smooth, np.arange(-20.0, 21.0, 1.0)),
            ("holes", holes, np.arange(-20.0, 21.0, 0.5)),
            ("plateaus", plateaus, np.arange(-20.0, 21.0, 2.0)),
            ("saddles", saddles, np.array([0.25, 0.5, 0.75]))]


def nodes(z):
    """The kernel's node coordinates: x of each column, y of each row (grid_lines' default)."""
    return np.arange(z.shape[1], dtype=np.float64), np.arange(z.shape[0], dtype=np.float64)


@pytest.mark.parametrize("case", range(4))
def test_the_compiled_kernel_gives_the_jit_arrays(cache_home, case):
    name, z, levels = surfaces()[case]
    compiled = aot.compiled_kernel("contour_lines", folder=cache_home["folder"])
    assert compiled is not None, os.listdir(cache_home["folder"])
    got = compiled(np.ascontiguousarray(z, dtype=np.float64), levels, *nodes(z))
    want = grid_lines(z, levels)
    assert len(want[1]) > 10, name  # lines to compare
    for a, b in zip(got, want, strict=True):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)


def test_the_compiled_cocircular_count_gives_the_jit_count(cache_home):
    """The TIN's uniqueness check (toolbox.terrain.tin.unique_kernel), compiled: the JIT's
    counts (the JIT is checked against exact arithmetic in test_round18_cdt_unique.py) on a
    lattice with random points (many), and on its perturbed copy (none)."""
    import pythoncdt as cdt

    from toolbox.terrain.tin.unique_kernel import cocircular_edges

    compiled = aot.compiled_kernel("cocircular_edges", folder=cache_home["folder"])
    assert compiled is not None, os.listdir(cache_home["folder"])
    rng = np.random.default_rng(4)
    lattice = np.stack(np.meshgrid(np.arange(50.0), np.arange(50.0)), -1).reshape(-1, 2)
    xy = np.vstack([lattice, rng.uniform(50, 90, (3000, 2))])
    counts = []
    for points in (xy, xy + rng.uniform(-1e-4, 1e-4, xy.shape)):
        t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                              cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
        t.insert_vertices(points)
        coords = t.vertices_array().view(np.float64).reshape(-1, 2)
        rows = t.triangles_array().view(np.uint32).reshape(-1, 6)
        counts.append(cocircular_edges(coords, rows))
        assert compiled(coords, rows) == counts[-1]
    assert counts[0] >= 49 * 49 and counts[1] == 0


def test_arguments_of_another_type_are_refused_before_the_call(cache_home):
    """pycc's wrapper reads any array as the declared type (a float32 grid crashed the process
    in a trial): the guarded kernel refuses it with a TypeError naming the argument."""
    compiled = aot.compiled_kernel("contour_lines", folder=cache_home["folder"])
    grid, levels = np.zeros((5, 6)), np.array([0.5])
    xs, ys = nodes(grid)
    bad = [((grid.astype(np.float32), levels, xs, ys),
            "argument 0 must be a C-contiguous 2-D float64"),
           ((np.zeros((5, 12))[:, ::2], levels, xs, ys),
            "argument 0 must be a C-contiguous 2-D float64"),
           ((grid, [0.5], xs, ys), "argument 1 must be a C-contiguous 1-D float64 array, got list"),
           ((grid, levels.astype(np.float32), xs, ys),
            "argument 1 must be a C-contiguous 1-D float64"),
           ((grid, levels, xs), "takes 4 arguments, got 3"),
           ((grid, levels, np.arange(6), ys), "argument 2 must be a C-contiguous 1-D float64"),
           ((grid,), "takes 4 arguments, got 1")]
    for args, message in bad:
        with pytest.raises(TypeError, match=message):
            compiled(*args)
    points, offsets, level = compiled(grid, levels, *nodes(grid))  # no lines on a flat grid
    assert len(points) == 0 and list(offsets) == [0] and len(level) == 0


def test_the_compiled_page_kernels_write_the_jit_pages(cache_home):
    """The bulk GeoPackage writer's page pass (toolbox.io.page_kernel), compiled: the JIT's
    bytes on pages of rows of every varint length (the JIT is checked against the numpy writer
    and SQLite in tests/toolbox/io/test_round23_page_kernel.py); its integer argument is
    checked too."""
    from toolbox.io import page_kernel

    rng = np.random.default_rng(5)
    n, page_size = 3000, 1024
    rowids = np.cumsum(rng.integers(1, 2**40, n)) - 2**50
    reclen = rng.integers(1, 300, n)
    flat = rng.integers(0, 256, int(reclen.sum())).astype(np.uint8)
    rec_start = np.concatenate([[0], np.cumsum(reclen)[:-1]])
    cells = reclen + 9 + 3 + 2  # generous: 9-byte rowids, 2-byte lengths, a pointer
    starts = np.arange(0, n, 3, dtype=np.int64)
    assert int(cells[:3].sum()) < page_size  # (any three fit a page: checked for this seed)
    ends = np.minimum(starts + 3, n)
    slots = np.arange(starts.size, dtype=np.int64)
    pages = {}
    for name, (cells_of, copy) in {
            "jit": (page_kernel.leaf_cells, page_kernel.copy_records),
            "compiled": (aot.compiled_kernel("leaf_cells", folder=cache_home["folder"]),
                         aot.compiled_kernel("copy_records", folder=cache_home["folder"]))}.items():
        buf = np.zeros(starts.size * page_size, np.uint8)
        positions = cells_of(buf, page_size, rowids, reclen, starts, ends, slots)
        copy(buf, positions, flat, rec_start, reclen)
        pages[name] = buf
    np.testing.assert_array_equal(pages["compiled"], pages["jit"])
    assert pages["jit"][0] == 0x0D and pages["jit"].any()
    compiled = aot.compiled_kernel("leaf_cells", folder=cache_home["folder"])
    with pytest.raises(TypeError, match="argument 1 must be an integer, got float"):
        compiled(buf, 1024.0, rowids, reclen, starts, ends, slots)


def test_the_compiled_edge_kernel_gives_the_jit_arrays(cache_home):
    """The TIN's edge table (toolbox.terrain.tin.edge_kernel), compiled: the JIT's four arrays
    on a triangulation with crossing breaklines (the JIT is checked against numpy in
    tests/toolbox/terrain/test_round24_edge_kernel.py); int64 arrays are refused."""
    from toolbox.terrain.tin.edge_kernel import edge_arrays
    from toolbox.terrain.tin.kernels import triangulate_pslg

    xy = np.random.default_rng(4).uniform(0, 100, (3000, 2)) + [1_688_000.0, 4_799_500.0]
    result = triangulate_pslg(xy, np.arange(200).reshape(-1, 2))
    compiled = aot.compiled_kernel("edge_arrays", folder=cache_home["folder"])
    got = compiled(result.triangles, result.neighbors)
    for a, b in zip(got, edge_arrays(result.triangles, result.neighbors), strict=True):
        assert a.dtype == np.int32
        np.testing.assert_array_equal(a, b)
    with pytest.raises(TypeError, match="argument 0 must be a C-contiguous 2-D int32"):
        compiled(result.triangles.astype(np.int64), result.neighbors)


def test_the_compiled_kernel_releases_the_gil(cache_home):
    """Another thread runs Python while the compiled kernel traces (as ``nogil=True`` JIT
    kernels allow). With a switch interval of 10 us, a kernel holding the GIL would leave the
    other thread at most a few microseconds around the call; one releasing it, the whole call."""
    import threading

    compiled = aot.compiled_kernel("contour_lines", folder=cache_home["folder"])
    rng = np.random.default_rng(2)
    z = np.ascontiguousarray(gaussian_filter(rng.normal(size=(1500, 1500)), 8) * 400.0)
    levels = np.arange(-40.0, 40.0, 0.5)
    compiled(z[:50, :50].copy(), levels, *nodes(z[:50, :50]))  # first call off the clock
    done = threading.Event()
    spins = [0]

    def spin():
        while not done.is_set():
            spins[0] += 1

    interval = sys.getswitchinterval()
    spinner = threading.Thread(target=spin)
    sys.setswitchinterval(1e-5)
    spinner.start()
    try:
        before, t0 = spins[0], time.perf_counter()
        compiled(z, levels, *nodes(z))
        during, elapsed = spins[0] - before, time.perf_counter() - t0
    finally:
        done.set()
        spinner.join()
        sys.setswitchinterval(interval)
    assert elapsed > 0.02, elapsed  # a call long enough to tell
    assert during > 10_000, (during, elapsed)


def test_a_run_loads_it_without_numba_and_writes_the_jit_lines(cache_home, tmp_path):
    import pyogrio
    import rasterio
    from rasterio.transform import from_origin

    rng = np.random.default_rng(3)
    z = 300.0 + gaussian_filter(rng.normal(size=(600, 600)), 20) * 2000.0
    z[100:130, 200:260] = -9999.0
    dem = tmp_path / "dem.tif"
    with rasterio.open(dem, "w", driver="GTiff", width=600, height=600, count=1,
                       dtype="float32", nodata=-9999.0, crs="EPSG:3003",
                       transform=from_origin(1687000, 4800000, 2, 2)) as dst:
        dst.write(z.astype("float32"), 1)
    # the JIT's run takes the kernel too (its fixed cost set aside), to compare the same tracer
    code = ("import sys, toolbox; from toolbox.cartography import contours; "
            "contours.KERNEL_FIXED_S = 0.0; "
            "s = toolbox.run('carto:contours', {{'INPUT': {dem!r}, "
            "'INTERVAL': 1, 'OUTPUT': {out!r}}})['STATISTICS']; "
            "print(s['tracer'], 'numba' in sys.modules, s['kernel_build'].replace(' ', '_'))")
    said = {}
    for mode in ("1", "0"):
        out = str(tmp_path / f"c{mode}.gpkg")
        proc = subprocess.run([sys.executable, "-c", code.format(dem=str(dem), out=out)],
                              env=cache_home["env"] | {"TOOLBOX_AOT": mode},
                              capture_output=True, text=True, check=True)
        said[mode] = proc.stdout.split()
    assert said["1"] == ["kernel", "False", "ahead_of_time"], said  # no numba
    assert said["0"] == ["kernel", "True", "numba_JIT"], said  # TOOLBOX_AOT=0
    ahead = pyogrio.read_dataframe(tmp_path / "c1.gpkg", layer="contours")
    jit = pyogrio.read_dataframe(tmp_path / "c0.gpkg", layer="contours")
    assert len(ahead) > 100
    assert ahead.drop(columns="geometry").equals(jit.drop(columns="geometry"))
    assert (ahead.geometry.to_wkb() == jit.geometry.to_wkb()).all()


def test_a_broken_or_missing_build_falls_back_to_the_jit(tmp_path, monkeypatch):
    broken = Path(aot.module_path("contour_lines", str(tmp_path)))
    broken.write_bytes(b"not a shared object")
    assert aot.load_compiled("contour_lines", folder=str(tmp_path)) is None
    empty = tmp_path / "empty"
    empty.mkdir()
    assert aot.load_compiled("contour_lines", folder=str(empty)) is None
    monkeypatch.setenv("TOOLBOX_AOT", "0")
    assert not aot.compiled_available("contour_lines")


def test_the_cost_model_counts_the_compiled_kernel(monkeypatch):
    """With the kernel compiled ahead of time its fixed cost (numba's import) is gone: a grid
    with enough levels takes it where the JIT's 0.65 s would not pay."""
    from toolbox.cartography import contours

    cells, spanned = 1_000_000, 1_000_000 * 12  # contourpy ~0.096 s, kernel 0.06 s + fixed
    monkeypatch.setattr(aot, "compiled_available", lambda name: False)
    assert contours.choose_tracer(cells, spanned) == "contourpy"
    monkeypatch.setattr(aot, "compiled_available", lambda name: True)
    assert contours.choose_tracer(cells, spanned) == "kernel"


def test_a_failed_build_is_a_warning_and_the_warmup_goes_on(monkeypatch, caplog):
    from toolbox import warmup

    def no_compiler(*args, **kwargs):
        raise OSError("command 'gcc' failed: No such file or directory")

    monkeypatch.setattr(aot, "build_compiled", no_compiler)
    with caplog.at_level("WARNING", logger="toolbox"):
        assert warmup.build_ahead_of_time() == []
    assert "ahead-of-time kernels were not built (OSError: command 'gcc' failed" in caplog.text


@pytest.mark.parametrize("present", [True, False])
def test_the_warmup_command_says_where_the_modules_are(tmp_path, monkeypatch, present):
    """``toolbox warmup``'s last line names the folder and the count; without a module it warns
    that runs use the JIT (the warm-up itself stubbed: the real one takes a minute)."""
    from click.testing import CliRunner

    from toolbox import warmup
    from toolbox.cli.app import main

    monkeypatch.setattr(warmup, "warmup", lambda: 3)
    monkeypatch.setattr(aot, "_folder", [str(tmp_path)])
    if present:
        for name in aot.EXPORTS:
            Path(aot.module_path(name)).write_bytes(b"")
    result = CliRunner().invoke(main, ["warmup"])
    assert result.exit_code == 0, result.output
    total = len(aot.EXPORTS)
    count = f"{total} of {total}" if present else f"0 of {total}"
    assert "Warm-up finished: 3 runs;" in result.output
    assert f"{count} ahead-of-time kernels in {tmp_path}" in result.output
    assert ("runs use numba's JIT" in result.output) is not present
