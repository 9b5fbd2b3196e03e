"""Benchmark: attribution of a whole block (``attribution:apply``, ``attribution:merge``) at the
bench city's size and at 10x, whole process, with peak memory (issue 31: big data).

    .venv/bin/python bench/attribution_bench.py                    # 1x and 10x, writes results
    .venv/bin/python bench/attribution_bench.py --sizes 26         # 1x only
    .venv/bin/python bench/attribution_bench.py --sizes 83 --data-only DIR   # inputs only
    .venv/bin/python bench/attribution_bench.py --sizes 83 --profile 83      # + cProfile

The block is a grid of cells (120 m x 100 m, EPSG:3003 near Siena, as in
``bench/topology_bench.py``), plotted in stereo models that are strips of ``--model-cells``
columns of cells (so a bigger block has more models, as a real one would). Every cell holds two
rows of ten closed buildings (``FAB01002``), a closed sidewalk ring (``MAR01001``), a courtyard
green area (``VEG01001``), three spot heights (``QUO01001``), four trees (``ALB01001``) and a
place name (``TOP01001``); street edges (``STR02001``, vertex every 20 m) run along every street
and contours (``CUR01001``, a vertex every 4 m) across every cell row. The codes, colours and
parameters are the demo's (``toolbox/demo/samples/restitution.py``: reattach 0.20 m / 0.10 m,
closure 0.50 m, 3 decimals, coordinates stored relative to the false origin).

Lines that cross a model edge are plotted piecewise, one piece per model, 0.05 m apart (the merge
joins them); in the last cell column of every model but the last, one building and one spot
height are plotted again in the next model a few centimetres off (the merge removes them).
Seeded defects, counted: buildings left open by 0.3 m (closed), buildings open by 1.2 m
(``unclosed_polygon``), an unknown code every 50 cells, a one-vertex street edge every 100
cells (``degenerate``), one street edge whose pieces differ by 0.6 m in height at the first model
edge (join refused).

Cases, each ``toolbox run`` as a whole process under ``/usr/bin/time -v`` (wall, user + system
CPU, peak RSS):

- ``apply, ASCII models``: the models' ASCII exports (several INPUT), merged and coded;
- ``apply, two tables``: the same entities as one descriptions + coordinates table (no merge:
  the pieces and the copies stay);
- ``merge``: ``attribution:merge`` of the ASCII models.

The output is checked: features per layer (per code), unresolved per reason, merge counts must
equal what was generated, else the bench fails (exit status 1) after writing what it measured.
Results go to bench/results/attribution.md.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, write_results

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

CRS = "EPSG:3003"
CELL_W, CELL_H = 120.0, 100.0
ROW = 10  # buildings per row
BW, BD = 9.0, 12.0  # building width and depth
STREET_STEP, CONTOUR_STEP = 20.0, 4.0  # vertex spacing of street edges and contours
GAP = 0.05  # between the pieces of a line at a model edge


def _e0n0():
    from toolbox.demo.samples.restitution import E0, FALSE_ORIGIN, N0

    return E0, N0, FALSE_ORIGIN


def _polyline(x0: float, x1: float, y, step: float) -> np.ndarray:
    """Vertices from x0 to x1 (both kept) every ``step``; y a constant or a function of x."""
    n = max(1, math.ceil((x1 - x0) / step))
    xs = np.linspace(x0, x1, n + 1)
    ys = y(xs) if callable(y) else np.full_like(xs, y)
    return np.column_stack([xs, ys])


class Block:
    """The generated restitution: ``models[k]`` a list of (code, (n, 3) local vertices), and the
    counts the outputs must show."""

    def __init__(self, cells: int, model_cells: int, seed: int = 20090331):
        rng = np.random.default_rng(seed)
        self.cells, self.model_cells = cells, model_cells
        nx = ny = cells
        nmodels = math.ceil(nx / model_cells)
        self.models: list[list[tuple[str, np.ndarray]]] = [[] for _ in range(nmodels)]
        self.ok: Counter = Counter()  # resolvable entities per code, as plotted
        self.duplicates: Counter = Counter()
        self.joins: Counter = Counter()
        self.unresolved: Counter = Counter()
        self.polygons_closed = 0
        self.refused = 0
        edges = [k * model_cells * CELL_W for k in range(1, nmodels)]  # model edges (x)

        def model_of(x: float) -> int:
            return min(int(x // (model_cells * CELL_W)), nmodels - 1)

        def add(model: int, code: str, pts, ok: bool = True) -> None:
            pts = np.asarray(pts, float)
            self.models[model].append((code, pts))
            if ok:
                self.ok[code] += 1

        def split_line(code: str, xy: np.ndarray, z: float, dz_at_first: float = 0.0) -> None:
            """A line across the block plotted piecewise, one piece per model it crosses."""
            cuts = [xy[0, 0], *[e for e in edges if xy[0, 0] < e < xy[-1, 0]], xy[-1, 0]]
            for k in range(len(cuts) - 1):
                a = cuts[k] + (GAP / 2 if k else 0.0)
                b = cuts[k + 1] - (GAP / 2 if k < len(cuts) - 2 else 0.0)
                inner = xy[(xy[:, 0] > a) & (xy[:, 0] < b)]
                yfun = np.interp([a, b], xy[:, 0], xy[:, 1])
                piece = np.vstack([[a, yfun[0]], inner, [b, yfun[1]]])
                zz = z + (dz_at_first if k >= 1 and dz_at_first else 0.0)
                if k == 1 and dz_at_first:  # pieces differ in height at the first edge
                    self.refused += 1
                elif k:
                    self.joins[code] += 1
                add(model_of((a + b) / 2), code,
                    np.column_stack([piece, np.full(len(piece), zz)]))

        width, height = nx * CELL_W, ny * CELL_H
        # street edges: along every street, 5 m each side of the cell boundary
        for j in range(ny + 1):
            for side, dy in enumerate((-5.0, 5.0)):
                dz = 0.6 if (j == 1 and side == 0 and edges) else 0.0
                split_line("STR02001", _polyline(-10.0, width + 10.0, j * CELL_H + dy,
                                                 STREET_STEP), 300.0 + 0.1 * j, dz)
        for i in range(nx + 1):
            for dx in (-5.0, 5.0):
                x = i * CELL_W + dx
                xy = _polyline(-10.0, height + 10.0, x, STREET_STEP)[:, ::-1]
                add(model_of(max(x, 0.0)), "STR02001",
                    np.column_stack([xy, np.full(len(xy), 300.0)]))
        # contours across every cell row
        for j in range(ny):
            y0 = j * CELL_H + 50.0
            split_line("CUR01001", _polyline(0.0, width, lambda x, y0=y0:
                                             y0 + 3.0 * np.sin(x / 40.0), CONTOUR_STEP),
                       305.0 + j)
        for i in range(nx):
            m = model_of(i * CELL_W + 1.0)
            last_column = (i + 1) % model_cells == 0 and m < nmodels - 1
            for j in range(ny):
                x0, y0 = i * CELL_W, j * CELL_H
                z = 310.0 + 0.01 * j
                serial = i * ny + j
                add(m, "MAR01001", [(x0 + 8, y0 + 8, z), (x0 + 112, y0 + 8, z),
                                    (x0 + 112, y0 + 92, z), (x0 + 8, y0 + 92, z),
                                    (x0 + 8, y0 + 8, z)])
                for yb in (y0 + 12, y0 + 66):
                    for k in range(ROW):
                        xb = x0 + 15 + k * BW
                        ring = [(xb, yb), (xb + BW, yb), (xb + BW, yb + BD), (xb, yb + BD),
                                (xb, yb)]
                        r = rng.random()
                        ok = True
                        if r < 0.005:  # open by 1.2 m: unresolved
                            ring[-1] = (xb, yb + 1.2)
                            ok = False
                            self.unresolved["unclosed_polygon"] += 1
                        elif r < 0.025:  # open by 0.3 m: closed
                            ring[-1] = (xb, yb + 0.3)
                            self.polygons_closed += 1
                        hz = z + 8.0 + k % 3
                        add(m, "FAB01002", [(x, y, hz) for x, y in ring], ok)
                        if last_column and yb == y0 + 12 and k == 0 and ok:
                            # the same building plotted again in the next model
                            add(m + 1, "FAB01002", [(x + 0.03, y - 0.02, hz + 0.01)
                                                    for x, y in ring], False)
                            self.duplicates["FAB01002"] += 1
                green = [(x0 + 20 + 80 * 0.5 * (1 + math.cos(t)) * 0.9, y0 + 30 + 30 * 0.5 *
                          (1 + math.sin(t)), z) for t in np.linspace(0, 2 * math.pi, 9)[:-1]]
                add(m, "VEG01001", [*green, green[0]])
                for s in range(3):
                    add(m, "QUO01001", [(x0 + 30 + 30 * s, y0 + 95.0, z + 0.1 * s)])
                if last_column:
                    add(m + 1, "QUO01001", [(x0 + 30.02, y0 + 95.01, z + 0.01)], False)
                    self.duplicates["QUO01001"] += 1
                for s in range(4):
                    add(m, "ALB01001", [(x0 + 25 + 20 * s, y0 + 45.0, z)])
                add(m, "TOP01001", [(x0 + 60, y0 + 62.0, z)])
                if serial % 50 == 0:
                    add(m, "XYZ99999", [(x0 + 50, y0 + 40, z), (x0 + 55, y0 + 40, z)], False)
                    self.unresolved["unknown_code"] += 1
                if serial % 100 == 7:
                    add(m, "STR02001", [(x0 + 2, y0 + 50, z)], False)
                    self.unresolved["degenerate"] += 1

    @property
    def entities(self) -> int:
        return sum(len(m) for m in self.models)

    @property
    def segments(self) -> int:
        return sum(max(len(p) - 1, 0) for m in self.models for _, p in m)

    def expected_layers(self, merged: bool) -> dict[str, int]:
        """Features per code layer of ``attribution:apply`` (merged: the models merged)."""
        out = Counter(self.ok)
        if merged:
            out.subtract(self.joins)
        else:  # the copies stay (and are resolvable)
            out.update(self.duplicates)
        return dict(out)

    def expected_merge_layers(self) -> dict[str, int]:
        """Features per geometry layer of ``attribution:merge`` (nothing unresolved there)."""
        points = lines = 0
        for model in self.models:
            for _, pts in model:
                if len(pts) == 1:
                    points += 1
                else:
                    lines += 1
        dup = self.duplicates
        return {"points": points - dup["QUO01001"],
                "lines": lines - dup["FAB01002"] - sum(self.joins.values())}


def write_ascii(block: Block, folder: Path) -> list[Path]:
    """One ASCII export per model (coordinates relative to the false origin, 3 decimals)."""
    e0, n0, origin = _e0n0()
    paths = []
    for k, model in enumerate(block.models, start=1):
        path = folder / f"blocco_modello_{k:02d}.txt"
        with open(path, "w", encoding="utf-8") as out:
            out.write(f"# esportazione ASCII della restituzione - modello {k}\n")
            for code, pts in model:
                out.write(f"CODE {code}\n")
                shifted = pts + (e0 - origin[0], n0 - origin[1], 0.0)
                out.write("".join(f"{x:.3f} {y:.3f} {z:.3f}\n" for x, y, z in shifted))
                out.write("END\n")
        paths.append(path)
    return paths


def write_two_tables(block: Block, folder: Path) -> tuple[Path, Path]:
    """The descriptions and coordinates tables (§2.2.4) of every model's entities in one set."""
    e0, n0, origin = _e0n0()
    desc, coords = folder / "blocco_descrizioni.txt", folder / "blocco_coordinate.txt"
    first = 1
    with open(desc, "w", encoding="utf-8") as d, open(coords, "w", encoding="utf-8") as c:
        d.write("record;code;vertices;colour;source;xmin;ymin;xmax;ymax;first\n")
        c.write("colour;E;N;Z\n")
        record = 0
        for k, model in enumerate(block.models, start=1):
            for code, pts in model:
                record += 1
                shifted = pts + (e0 - origin[0], n0 - origin[1], 0.0)
                lo, hi = shifted.min(axis=0), shifted.max(axis=0)
                d.write(f"{record};{code};{len(pts)};;{k};{lo[0]:.3f};{lo[1]:.3f};"
                        f"{hi[0]:.3f};{hi[1]:.3f};{first}\n")
                c.write("".join(f";{x:.3f};{y:.3f};{z:.3f}\n" for x, y, z in shifted))
                first += len(pts)
    return desc, coords


def write_auxiliary(folder: Path) -> dict[str, Path]:
    from toolbox.demo.samples.restitution import CODE_FILE_TEXT, COLOUR_FILE_TEXT, PARAMETER_FILE_TEXT

    paths = {"codes": folder / "codici.txt", "colours": folder / "colori.txt",
             "parameters": folder / "parametri.txt"}
    paths["codes"].write_bytes(CODE_FILE_TEXT.encode("latin-1"))
    paths["colours"].write_text(COLOUR_FILE_TEXT, encoding="utf-8")
    paths["parameters"].write_text(PARAMETER_FILE_TEXT, encoding="utf-8")
    return paths


def toolbox_cli() -> list[str]:
    exe = Path(sys.executable).with_name("toolbox")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "toolbox"]


def timed_run(cmd: list[str], profile: Path | None = None, timeout: float | None = None
              ) -> dict:
    """Run ``cmd`` under ``/usr/bin/time -v``: wall, user + system CPU, peak RSS, exit code."""
    if profile is not None:  # the same run under cProfile (the toolbox entry point's module)
        cmd = [sys.executable, "-m", "cProfile", "-o", str(profile), "-m", "toolbox", *cmd[1:]]
    timer = shutil.which("time") or "/usr/bin/time"
    with tempfile.NamedTemporaryFile("w+", suffix=".time") as log:
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([timer, "-v", "-o", log.name, *cmd], capture_output=True,
                                  text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"wall": time.perf_counter() - t0, "cpu": math.nan, "peak_mb": math.nan,
                    "rc": -9, "stderr": f"killed after {timeout:.0f} s"}
        wall = time.perf_counter() - t0
        text = Path(log.name).read_text()

    def field(name: str) -> float:
        found = re.search(rf"{re.escape(name)}: ([0-9.:]+)", text)
        return float(found.group(1)) if found else math.nan

    return {"wall": wall, "cpu": field("User time (seconds)") + field("System time (seconds)"),
            "peak_mb": field("Maximum resident set size (kbytes)") / 1024.0,
            "rc": proc.returncode, "stderr": proc.stderr[-2000:]}


def layer_counts(gpkg: Path) -> dict[str, int]:
    """Features per feature table of a GeoPackage (read with sqlite3, not the toolbox)."""
    with sqlite3.connect(gpkg) as db:
        names = [r[0] for r in db.execute(
            "SELECT table_name FROM gpkg_contents WHERE data_type = 'features'")]
        return {n: db.execute(f'SELECT count(*) FROM "{n}"').fetchone()[0] for n in names}


def reason_counts(gpkg: Path) -> dict[str, int]:
    with sqlite3.connect(gpkg) as db:
        return dict(db.execute("SELECT reason, count(*) FROM unresolved GROUP BY reason"))


def kind_counts(gpkg: Path) -> dict[str, int]:
    with sqlite3.connect(gpkg) as db:
        return dict(db.execute("SELECT kind, count(*) FROM merge GROUP BY kind"))


def check_apply(block: Block, gpkg: Path, merged: bool) -> list[str]:
    """What differs between the output and the generated block (empty: all as generated)."""
    problems = []
    got = layer_counts(gpkg)
    for code, n in sorted(block.expected_layers(merged).items()):
        if got.get(code) != n:
            problems.append(f"layer {code}: {got.get(code)} features, generated {n}")
    reasons = reason_counts(gpkg)
    if reasons != dict(block.unresolved):
        problems.append(f"unresolved {reasons}, generated {dict(block.unresolved)}")
    if merged:
        problems += merge_event_problems(block, gpkg)
    return problems


def merge_event_problems(block: Block, gpkg: Path) -> list[str]:
    """The merge's events (duplicates removed, joins, refused joins) against the generated ones."""
    kinds = kind_counts(gpkg)
    want = {"duplicate_removed": sum(block.duplicates.values()),
            "joined": sum(block.joins.values()), "join_refused": block.refused}
    if {k: kinds.get(k, 0) for k in want} != want:
        return [f"merge events {kinds}, generated {want}"]
    return []


def check_merge(block: Block, gpkg: Path) -> list[str]:
    got = layer_counts(gpkg)
    problems = [f"layer {k}: {got.get(k)} features, generated {n}"
                for k, n in block.expected_merge_layers().items() if got.get(k) != n]
    return problems + merge_event_problems(block, gpkg)


def run_size(cells: int, model_cells: int, work: Path, cases: list[str],
             profile: bool, timeout: float | None) -> dict:
    t0 = time.perf_counter()
    block = Block(cells, model_cells)
    work.mkdir(parents=True, exist_ok=True)
    aux = write_auxiliary(work)
    models = write_ascii(block, work)
    tables = write_two_tables(block, work) if "tables" in cases else None
    print(f"{cells} x {cells} cells: {len(block.models)} models, {block.entities} entities, "
          f"{block.segments} segments, written in {time.perf_counter() - t0:.1f} s", flush=True)
    common = ["--CODES", str(aux["codes"]), "--COLOURS", str(aux["colours"]),
              "--PARAMETERS", str(aux["parameters"]), "--CRS", CRS]
    inputs = [a for p in models for a in ("--INPUT", str(p))]
    runs = {}
    commands = {
        "ascii": ["run", "attribution:apply", *inputs, *common],
        "tables": ["run", "attribution:apply", "--INPUT", str(tables[0]) if tables else "",
                   "--COORDINATES", str(tables[1]) if tables else "", *common],
        "merge": ["run", "attribution:merge", *inputs, "--PARAMETERS", str(aux["parameters"]),
                  "--CRS", CRS],
    }
    for case in cases:
        out = work / f"out_{case}.gpkg"
        out.unlink(missing_ok=True)
        prof = work / f"{case}.prof" if profile else None
        cmd = [*toolbox_cli(), *commands[case], "--OUTPUT", str(out)]
        load = os.getloadavg()[0]
        result = timed_run(cmd, prof, timeout)
        result["load"] = load
        if result["rc"] != 0 or not out.exists():  # (cProfile exits 0 whatever the run did)
            result["problems"] = [f"exit {result['rc']}, no output: {result['stderr'][-600:]}"
                                  if not out.exists() else
                                  f"exit {result['rc']}: {result['stderr'][-600:]}"]
            result["rc"] = result["rc"] or 1
        elif case == "merge":
            result["problems"] = check_merge(block, out)
        else:
            result["problems"] = check_apply(block, out, merged=case == "ascii")
        if result["rc"] == 0:
            result["layers"] = layer_counts(out)
        if prof is not None and prof.exists():
            result["profile"] = top_of_profile(prof)
        print(f"  {case}: wall {result['wall']:.1f} s, CPU {result['cpu']:.1f} s, peak "
              f"{result['peak_mb']:.0f} MB, load {load:.1f}, problems {result['problems']}",
              flush=True)
        runs[case] = result
    return {"cells": cells, "models": len(block.models), "entities": block.entities,
            "segments": block.segments, "block": block, "runs": runs}


def top_of_profile(path: Path, n: int = 12) -> list[tuple[str, float, float]]:
    """(function, cumulative s, own s) of the ``n`` toolbox functions with most cumulative time
    (the command line's and the runner's wrappers left out)."""
    import pstats

    stats = pstats.Stats(str(path))
    rows = []
    for (file, _line, func), (_, _, own, cum, _) in stats.stats.items():
        if ("/toolbox/" in file or "/algorithms/" in file) and "/cli/" not in file \
                and "/runner/" not in file and not file.endswith(("__main__.py", "algorithm.py")):
            rows.append((f"{Path(file).parent.name}/{Path(file).name}:{func}", cum, own))
    rows.sort(key=lambda r: -r[1])
    return rows[:n]


CASE_NAMES = {"ascii": "`attribution:apply`, ASCII models (merged)",
              "tables": "`attribution:apply`, two tables (one set, no merge)",
              "merge": "`attribution:merge`, ASCII models"}


def report(sizes: list[dict], facts: str, model_cells: int) -> list[str]:
    lines = [
        "## Attribution of a whole block (issue 31: big data)", "",
        f"Machine: {facts}.", "",
        "Generated by `bench/attribution_bench.py` (see its docstring): a block of cells "
        f"120 m x 100 m, stereo models of {model_cells} cell columns each, the demo's code, "
        "colour and parameter files; whole process `toolbox run ...` under `/usr/bin/time -v` "
        "(CPU = user + system; peak = max RSS); load = 1-minute load average at the start. "
        "Every output checked against the generated counts (features per code layer, "
        "unresolved per reason, merge events).", "",
        "| block | models | entities | segments | case | wall | CPU | peak RSS | load | "
        "output as generated |",
        "|---|---:|---:|---:|---|---:|---:|---:|---:|---|"]
    for s in sizes:
        for case, r in s["runs"].items():
            ok = "yes" if not r["problems"] else "**NO**: " + "; ".join(r["problems"])[:300]
            lines.append(f"| {s['cells']} x {s['cells']} cells | {s['models']} | "
                         f"{s['entities']:,} | {s['segments']:,} | {CASE_NAMES[case]} | "
                         f"{r['wall']:.1f} s | {r['cpu']:.1f} s | {r['peak_mb']:.0f} MB | "
                         f"{r['load']:.1f} | {ok} |")
    for s in sizes:
        r = s["runs"].get("ascii")
        if r and r.get("layers"):
            lines += ["", f"Features per layer, {s['cells']} x {s['cells']} cells, ASCII models: "
                      + ", ".join(f"{k} {v:,}" for k, v in sorted(r["layers"].items())) + "."]
    for s in sizes:
        for case, r in s["runs"].items():
            if r.get("profile"):
                lines += ["", f"cProfile, {s['cells']} x {s['cells']} cells, {case} "
                          "(cumulative / own s, under the profiler): "
                          + "; ".join(f"`{f}` {c:.1f} / {o:.1f}" for f, c, o in r["profile"])
                          + "."]
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[26, 83],
                        help="cells per side of each block (26: ~100k segments, the bench "
                             "city; 83: ~10x)")
    parser.add_argument("--model-cells", type=int, default=6,
                        help="cell columns per stereo model (6)")
    parser.add_argument("--cases", nargs="+", choices=list(CASE_NAMES),
                        default=list(CASE_NAMES), help="which runs (all)")
    parser.add_argument("--profile", type=int, nargs="*", default=[], metavar="CELLS",
                        help="run these sizes under cProfile (times then include its overhead)")
    parser.add_argument("--timeout", type=float, default=None,
                        help="kill a run after this many seconds (reported as exit -9)")
    parser.add_argument("--work", type=Path, default=None,
                        help="folder for inputs and outputs (kept); default a temporary one")
    parser.add_argument("--data-only", type=Path, metavar="DIR",
                        help="write the inputs of every size to DIR/<cells> and stop")
    parser.add_argument("--no-results", action="store_true",
                        help="do not write bench/results/attribution.md")
    args = parser.parse_args(argv)
    if args.data_only:
        for cells in args.sizes:
            block = Block(cells, args.model_cells)
            folder = args.data_only / str(cells)
            folder.mkdir(parents=True, exist_ok=True)
            write_auxiliary(folder)
            write_ascii(block, folder)
            write_two_tables(block, folder)
            print(f"{folder}: {len(block.models)} models, {block.entities} entities, "
                  f"{block.segments} segments", flush=True)
        return 0
    facts = machine_facts() + f"; {load_note()}"
    work = args.work or Path(tempfile.mkdtemp(prefix="attribution_bench_"))
    sizes = []
    try:
        for cells in args.sizes:
            sizes.append(run_size(cells, args.model_cells, work / str(cells), args.cases,
                                  cells in args.profile, args.timeout))
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    if not args.no_results:
        write_results(HERE / "results" / "attribution.md", report(sizes, facts,
                                                                   args.model_cells))
    failed = [(s["cells"], c, r["problems"]) for s in sizes for c, r in s["runs"].items()
              if r["problems"]]
    for cells, case, problems in failed:
        print(f"FAILED: {cells} cells, {case}: {problems}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
