"""The error contract, over EVERY registered algorithm (those that land later too, with no new code).

Valid parameters come from the demo pipeline (toolbox/demo/pipeline/*.yaml, run once per session);
each case then breaks one thing, the way users do: a missing, empty, wrong-type or truncated input,
absurd numbers, an output that is an input (through every destination and --run-report), an output
under a file, in a read-only folder, in a full one, in a folder that does not exist yet. Whatever
the mistake, the CLI ends with exit 2 and ONE line naming the parameter (exit 0 is accepted only
where the mistake can give a valid result: absurd but legal numbers, a truncated text file that is
still readable, a small output that fits), never a traceback; no file is left behind and every input
is byte-identical afterwards.
"""

from __future__ import annotations

import hashlib
import os
import random
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import trust_data
from click.testing import CliRunner

import toolbox
from tests.helpers_cli import assert_cannot_write, cli, one_error, register_testing, run_on_full_disk
from toolbox.batch import REF_RE
from toolbox.cli import main
from toolbox.parameters import (
    Destination,
    File,
    Integer,
    MultipleLayers,
    Number,
    OutputFile,
    RasterLayer,
    VectorLayer,
)
from toolbox.runner import validate

pytestmark = [  # what the deliberately broken test data make the libraries say
    pytest.mark.filterwarnings("ignore:'crs' was not provided:UserWarning"),
    pytest.mark.filterwarnings("ignore:invalid value encountered in from_wkb:RuntimeWarning"),
    pytest.mark.filterwarnings("ignore:GeoSeries.notna:UserWarning"),
]
ALGORITHMS = sorted(a.id for a in toolbox.algorithms() if not a.id.startswith("testing:"))
INPUT_TYPES = (VectorLayer, RasterLayer, File, MultipleLayers)


# -- session data: the demo, run once ---------------------------------------------------------------
@pytest.fixture(scope="session")
def demo():
    """(demo folder, {variable: value}, {algorithm: first demo step's params}, {(step, NAME):
    value})."""
    from toolbox.demo import demo_pipeline_doc

    out, variables = trust_data.demo()
    steps: dict[str, dict] = {}
    values = {}
    for raw in demo_pipeline_doc()["steps"]:
        steps.setdefault(raw["algorithm"], raw.get("params") or {})
        for key, value in (raw.get("params") or {}).items():
            values[(raw["name"], key)] = value
    return out, variables, steps, values


def _resolve(value, variables: dict, values: dict):
    """A demo parameter value with ${variable} and ${step.NAME} replaced by demo paths."""
    if isinstance(value, list):
        return [_resolve(v, variables, values) for v in value]
    if not isinstance(value, str):
        return value

    def repl(match):
        step, name = match.group(1), match.group(2)
        if name is None:
            return str(variables[step])
        return str(_resolve(values[(step, name)], variables, values))

    return REF_RE.sub(repl, value)


def _names_a_file(p, value) -> bool:
    """A text (not path-typed) input parameter whose value is one existing file."""
    from toolbox.parameters import String

    if not isinstance(p, String) or p.is_output or not isinstance(value, (str, Path)):
        return False
    try:
        return str(value).strip() != "" and Path(str(value)).is_file()
    except (OSError, ValueError):
        return False


def _borrowed_steps(alg, steps: dict) -> list[dict]:
    """Other algorithms' demo parameters that may fit ``alg`` (dem:nearest takes
    dem:quadratic's), same group first."""
    names = {p.name for p in alg.parameters}
    required = {p.name for p in alg.parameters if not p.optional}
    fits = [(other.split(":")[0] != alg.group_id(), params) for other, params in steps.items()
            if set(params) <= names and required <= set(params)]
    return [params for _, params in sorted(fits, key=lambda f: f[0])]


# -- one case ----------------------------------------------------------------------------------
class Case:
    """Inputs copied into ``in/``, outputs directed into ``out/``; ``run`` checks the contract."""

    def __init__(self, alg_id: str, demo, tmp_path: Path):
        demo_out, variables, steps, values = demo
        self.alg = toolbox.get(alg_id)
        self.root = tmp_path
        self.inputs_dir = tmp_path / "in"
        self.out = tmp_path / "out"
        self.out.mkdir()
        shutil.copytree(demo_out / "data", self.inputs_dir / "data")
        for raw in [steps[alg_id]] if alg_id in steps else _borrowed_steps(self.alg, steps):
            self.params = self._localise(raw, variables, values, demo_out)
            try:
                validate(self.alg, self.params)
                break
            except toolbox.ToolboxError:
                continue
        else:
            pytest.skip(f"{alg_id} has no step in the demo pipeline (add one: it gives the "
                        "error contract its valid parameters)")

    def _localise(self, raw: dict, variables: dict, values: dict, demo_out: Path) -> dict:
        params = {}
        for key, value in raw.items():
            value = _resolve(value, variables, values)
            p = self.alg.parameter(key)
            if isinstance(p, Destination):
                value = str(self.out / Path(str(value)).name)
            elif _names_a_file(p, value):  # a text parameter naming files (convert's INPUT)
                value = self._copy_in(value, demo_out)
            elif isinstance(p, Folder) and not p.is_output and Path(str(value)).is_dir():
                target = self.inputs_dir / "folders" / p.name  # an input folder: its files too
                shutil.copytree(str(value), target)
                value = str(target)
            elif isinstance(p, INPUT_TYPES):
                value = [self._copy_in(v, demo_out) for v in value] if isinstance(value, list) \
                    else self._copy_in(value, demo_out)
            params[key] = value
        return params

    def _copy_in(self, value: str, demo_out: Path) -> str:
        path = Path(str(value).split("|")[0])
        try:
            rel = path.relative_to(demo_out / "data")
            return str(self.inputs_dir / "data" / rel) + str(value)[len(str(path)):]
        except ValueError:
            target = self.inputs_dir / "produced" / path.name
            target.parent.mkdir(exist_ok=True)
            shutil.copy2(path, target)
            return str(target) + str(value)[len(str(path)):]

    def input_params(self) -> list:
        return [p for p in self.alg.parameters
                if (isinstance(p, INPUT_TYPES) or _names_a_file(p, self.params.get(p.name)))
                and self.params.get(p.name) is not None]

    def destinations(self) -> list:
        return [p for p in self.alg.destinations() if self.params.get(p.name) is not None]

    def args(self, **changes) -> list[str]:
        params = dict(self.params) | changes
        out = []
        for key, value in params.items():
            if value is None:
                continue
            for item in value if isinstance(value, list) else [value]:
                out += [f"--{key}", str(item).lower() if isinstance(item, bool) else str(item)]
        return out

    def snapshot(self) -> dict:
        return {str(p.relative_to(self.root)): hashlib.sha256(p.read_bytes()).hexdigest()
                for p in sorted(self.inputs_dir.rglob("*")) if p.is_file()}

    def run(self, args: list[str], name: str | tuple | None, may_succeed: bool = False,
            words: str | None = None, out_dirs: tuple[Path, ...] = ()) -> str:
        """Run ``toolbox run ID args`` and check the contract; return the error line."""
        before = self.snapshot()
        result = CliRunner().invoke(main, ["run", self.alg.id, *args])
        stderr = self.last_stderr = result.stderr
        assert "Traceback" not in stderr and "internal error" not in stderr, stderr
        assert result.exit_code in ((0, 2) if may_succeed else (2,)), (args, result.exit_code,
                                                                       stderr, result.exception)
        assert self.snapshot() == before, f"an input was modified by {args}"
        if result.exit_code == 0:
            for folder in (self.out, *out_dirs):  # a success may write: clear for the next case
                for item in folder.iterdir():
                    shutil.rmtree(item) if item.is_dir() else item.unlink()
            return ""
        lines = [line for line in stderr.strip().splitlines() if not line.startswith("WARNING:")
                 and not line.startswith("INFO:")]
        gdal_noise = [line for line in lines if not line.startswith("toolbox:")]
        errors = [line for line in lines if line.startswith("toolbox: error:")]
        assert len(errors) == 1 and len(lines) - len(gdal_noise) == 1, stderr
        if name is not None:  # the parameter (or, from a reader, the file the user gave it)
            names = (name,) if isinstance(name, str) else name
            assert any(n in errors[0] for n in names), (names, errors[0])
        if words is not None:
            assert re.search(words, errors[0], re.I), (words, errors[0])
        for folder in (self.out, *out_dirs):
            left = [str(p) for p in folder.rglob("*")]
            assert left == [], f"{args} left {left}"
        return errors[0]


@pytest.fixture
def case(request, demo, tmp_path):
    return Case(request.param, demo, tmp_path)


def _cases():
    return pytest.mark.parametrize("case", ALGORITHMS, indirect=True)


# -- inputs -------------------------------------------------------------------------------------
@_cases()
def test_missing_empty_and_wrong_type_inputs(case):
    if not case.input_params():
        pytest.skip("no file input")
    for p in case.input_params():
        value = case.params[p.name]
        first = value[0] if isinstance(value, list) else value
        suffix = Path(str(first).split("|")[0]).suffix
        missing = case.root / f"missing{suffix}"
        empty = case.root / f"empty{suffix}"
        empty.write_bytes(b"")
        wrong = case.root / f"wrong{suffix}"
        wrong.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4 if suffix in (
            ".csv", ".txt", ".yaml", ".yml", ".json") else b"x;y\n1;2\n")
        for bad in (missing, empty, wrong):
            case.run(case.args(**{p.name: str(bad)}), (p.name, bad.name))


# duplicate-ok: one parametrised test per kind of bad input, written out on purpose
@_cases()
def test_truncated_inputs(case):
    if not case.input_params():
        pytest.skip("no file input")
    for p in case.input_params():
        value = case.params[p.name]
        first = Path(str(value[0] if isinstance(value, list) else value).split("|")[0])
        cut = case.root / f"cut_{p.name}{first.suffix}"
        data = first.read_bytes()
        cut.write_bytes(data[: max(1, len(data) * 2 // 3)])
        layer = str(value[0] if isinstance(value, list) else value)[len(str(first)):]
        # a main raster INPUT whose header opens but whose last blocks are gone must fail (its
        # pixels are read); a TEMPLATE is only a grid, a DEM may be sampled where it is intact,
        # a shortened text or GeoPackage may still be readable
        strict = isinstance(p, RasterLayer) and p.name == "INPUT"
        case.run(case.args(**{p.name: str(cut) + layer}), (p.name, cut.name) if strict else None,
                 may_succeed=not strict)


@_cases()
def test_absurd_numbers(case):
    numbers = [p for p in case.alg.parameters if isinstance(p, Number)]
    if not numbers:
        pytest.skip("no number parameter")
    rng = random.Random(case.alg.id)  # a sample per algorithm, the same on every run
    for p in rng.sample(numbers, min(2, len(numbers))):
        value = rng.choice(["1e308", "-1e308", "nan", "1e-320"] if not isinstance(p, Integer)
                           else ["-1", "1e12", "0.5"])
        case.run(case.args(**{p.name: value}), p.name, may_succeed=True)


# -- outputs ------------------------------------------------------------------------------------
@_cases()
def test_output_equal_to_an_input_is_refused(case):
    """Through every destination (via '..' and via a symlink) and --run-report, with
    --overwrite: refused, the input intact."""
    files = []
    for p in case.input_params():
        value = case.params[p.name]
        files += [str(v).split("|")[0] for v in (value if isinstance(value, list) else [value])]
    if not files:
        pytest.skip("no file input")
    link = case.root / "link_to_input"
    checked = 0
    for dest in case.destinations():
        victim = next((f for f in files if not dest.extensions
                       or Path(f).suffix.lower() in dest.extensions), None)
        if victim is None:
            continue  # no input of that extension: an output of this type cannot be one
        victim = Path(victim)
        dotted = f"{victim.parent}/../{victim.parent.name}/{victim.name}"
        case.run(case.args(**{dest.name: dotted}) + ["--overwrite"], dest.name)
        link.symlink_to(victim)
        try:
            case.run(case.args(**{dest.name: str(link)}) + ["--overwrite"], dest.name)
        finally:
            link.unlink()
        checked += 1
    for path in files:
        case.run(case.args() + ["--overwrite", "--run-report", path], "--run-report")


@_cases()
def test_output_folder_mistakes(case):
    dests = case.destinations()
    if not dests:
        pytest.skip("no output file")
    dest = dests[0]
    name = Path(case.params[dest.name]).name
    a_file = case.out.parent / "a_file"
    a_file.write_text("not a folder")
    case.run(case.args(**{dest.name: str(a_file / name)}), dest.name, out_dirs=())
    case.run(case.args(**{dest.name: str(case.out / ("n" * 300 + Path(name).suffix))}),
             dest.name)
    # a run that fails leaves no folder it created
    numbers = [p for p in case.alg.parameters if isinstance(p, Number)
               and p.min_value is not None]
    inputs = case.input_params()
    if numbers:
        bad = {numbers[0].name: str(numbers[0].min_value - 1)}
        expect = numbers[0].name
    elif inputs:
        bad = {inputs[0].name: str(case.root / "missing.gpkg")}
        expect = inputs[0].name
    else:
        return
    case.run(case.args(**bad, **{dest.name: str(case.out / "new" / "deeper" / name)}), expect)


def _mount_tmpfs(folder: Path, options: str) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                          capture_output=True)
    return proc.returncode == 0


@_cases()
def test_read_only_and_full_output_folders(case):
    dests = case.destinations()
    if not dests:
        pytest.skip("no output file")
    for options, words in (("ro,size=64k", "read-only|cannot write"),
                           ("size=4k", "no space left on device")):
        folder = case.root / f"mnt_{options.split(',')[0]}"
        folder.mkdir()
        mounted = _mount_tmpfs(folder, options)
        if not mounted and options.startswith("ro") and os.geteuid() != 0:
            folder.chmod(0o555)  # not root: permissions make it read-only
        elif not mounted:
            pytest.skip("needs root to mount a small tmpfs (a full output folder)")
        try:
            for dest in dests[:1]:  # the first output: the runner's checks are per run
                target = folder / Path(case.params[dest.name]).name
                changes = {dest.name: str(target)}
                case.run(case.args(**changes), dest.name, may_succeed=options.startswith("size"),
                         words=words, out_dirs=(folder,))
        finally:
            if mounted:
                subprocess.run(["umount", "-l", str(folder)], check=True)  # lazy: a reader may linger
            else:
                folder.chmod(0o755)


# -- the families of mistakes of issue #11, one by one ---------------------------------------------
@pytest.fixture(scope="module")
def points(demo, tmp_path_factory):
    """Point layers for the degenerate cases, written from the demo mass points."""
    import geopandas as gpd
    import numpy as np
    import shapely

    folder = tmp_path_factory.mktemp("contract_points")
    mass = gpd.read_file(demo[1]["mass_points"])
    made = {"mass": Path(demo[1]["mass_points"])}
    mass.to_crs(4326).to_file(made.setdefault("geographic", folder / "geo.gpkg"))
    mass.set_crs(32632, allow_override=True).to_file(made.setdefault("utm", folder / "utm.gpkg"))
    mass.to_crs(4326).set_crs(3003, allow_override=True).to_file(
        made.setdefault("lonlat_as_3003", folder / "lonlat.gpkg"))
    t = np.linspace(0, 1000, 200)
    rng = np.random.default_rng(1)
    line = gpd.GeoDataFrame({"h": t}, geometry=shapely.points(
        1688000 + t, 4799000 + 0.5 * t + rng.normal(0, 1e-10, 200), 300 + 0.01 * t), crs=3003)
    line.to_file(made.setdefault("nearly_collinear", folder / "line.gpkg"))
    line.iloc[:2].to_file(made.setdefault("two", folder / "two.gpkg"))
    dup = line.iloc[[0, 0, 0]]
    dup.to_file(made.setdefault("duplicates", folder / "dup.gpkg"))
    return made


@pytest.mark.parametrize("alg", ["dem:idw", "tin:delaunay"])
def test_geographic_crs_and_area_of_use(points, alg, tmp_path):
    extra = ["--CELL_SIZE", "20"] if alg.startswith("dem") else []
    out = tmp_path / ("o.tif" if alg.startswith("dem") else "o.gpkg")
    code, _, err = cli("run", alg, "--INPUT", points["geographic"], *extra, "--OUTPUT", out)
    line = one_error(err)
    assert code == 2 and "INPUT" in line and "EPSG:4326" in line and "geographic" in line
    for key, crs in (("utm", "EPSG:32632"), ("lonlat_as_3003", "EPSG:3003")):
        code, _, err = cli("run", alg, "--INPUT", points[key], *extra, "--OUTPUT", out)
        line = one_error(err)
        assert code == 2 and "INPUT" in line and crs in line and "area of use" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("extent, words", [
    ("980000,190000,990000,200000 [EPSG:2263]", "easting unit is the US survey foot"),
    ("750000,1090000,760000,1100000 [EPSG:2222]", "easting unit is the foot")])
def test_a_crs_in_feet_is_refused_where_metres_are_meant(tmp_path, extent, words):
    """carto:grid's 1:5000 grid is 500 m on the ground: in a feet CRS it was drawn 500 ft apart
    in silence. Refused in one line naming EXTENT, the CRS and its unit."""
    out = tmp_path / "g.gpkg"
    code, _, err = cli("run", "carto:grid", "--EXTENT", extent, "--SCALE", "5000",
                       "--OUTPUT", out)
    line = one_error(err)
    assert code == 2 and line.startswith("toolbox: error: EXTENT is in") and words in line, line
    assert "works in metres, x east and y north" in line and not out.exists()


@pytest.mark.parametrize("crs, words", [
    ("EPSG:2053", "westing axis points west"),             # Lo29: westing/southing axes
    ("EPSG:4978", "geocentric")])                          # Earth-centred X, Y, Z
def test_crs_not_east_north_in_one_unit_is_refused(points, tmp_path, crs, words):
    """West/south axes (aspect was 180 degrees off) and a geocentric CRS (a "DEM" of
    geocentric Z) are refused even by the algorithms whose lengths are the CRS's unit; a CRS in
    feet is accepted by the gridding and gives the unlabelled run's DEM, numbers unchanged."""
    import geopandas as gpd
    import numpy as np
    import rasterio

    mass = gpd.read_file(points["mass"])
    mass.set_crs(crs, allow_override=True).to_file(tmp_path / "in.gpkg")
    in_new_york = mass.translate(1_000_000 - 1_688_000, 200_000 - 4_799_000)  # its area of use
    for name, label in (("ft", "EPSG:2263+6360"), ("m", None)):
        gpd.GeoDataFrame(geometry=in_new_york.set_crs(label, allow_override=True)).to_file(
            tmp_path / f"{name}.gpkg")
    out = tmp_path / "o.tif"
    code, _, err = cli("run", "dem:idw", "--INPUT", tmp_path / "in.gpkg", "--CELL_SIZE", "20",
                       "--OUTPUT", out)
    line = one_error(err)
    assert code == 2 and line.startswith("toolbox: error: INPUT is in") and words in line, line
    assert not out.exists()
    for name in ("ft", "m"):
        code, _, err = cli("run", "dem:idw", "--INPUT", tmp_path / f"{name}.gpkg",
                           "--CELL_SIZE", "20", "--OUTPUT", tmp_path / f"{name}.tif", "-q")
        assert code == 0, err
    with rasterio.open(tmp_path / "ft.tif") as ft, rasterio.open(tmp_path / "m.tif") as m:
        assert ft.crs.linear_units.lower().startswith("us survey foot")
        assert ft.transform == m.transform and np.array_equal(ft.read(), m.read(), equal_nan=True)


def test_slopes_need_heights_in_the_unit_of_x_and_y(tmp_path):
    """A compound CRS with x, y in US feet and heights in metres: dem:slope mixed them (a 5.71
    degree plane came out 1.75 degrees); refused in one line. The gridding, where heights never
    meet x and y, accepts such a CRS (the public COPC sample: Oregon LCC metres + NAVD88 feet)."""
    import numpy as np
    import rasterio
    from affine import Affine

    dem = tmp_path / "dem.tif"
    z = np.add.outer(np.zeros(20), np.arange(20) * 10.0).astype("float32")  # 0.1 per foot
    with rasterio.open(dem, "w", driver="GTiff", width=20, height=20, count=1, dtype="float32",
                       crs="EPSG:2263+5703",
                       transform=Affine(100, 0, 1_000_000, 0, -100, 200_000)) as dst:
        dst.write(z, 1)
    code, _, err = cli("run", "dem:slope", "--INPUT", dem, "--OUTPUT", tmp_path / "s.tif")
    line = one_error(err)
    assert code == 2 and "gravity-related height unit (metre) is not its easting unit (US " \
        "survey foot)" in line and "works in one length unit" in line, line
    assert not (tmp_path / "s.tif").exists()


def test_a_project_in_feet_is_refused(tmp_path):
    """A project (YAML or another program's file) in a feet CRS: refused naming PROJECT (its
    photo scales, tolerances and _m fields were feet taken as metres)."""
    import yaml

    from toolbox.demo.samples.siena import BUNDLED

    shutil.copytree(BUNDLED, tmp_path, dirs_exist_ok=True)  # the files the project names
    doc = yaml.safe_load((BUNDLED / "siena_project.yaml").read_text())
    doc["crs"] = "EPSG:2263"
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(doc))
    code, _, err = cli("run", "orientation:precision", "--PROJECT", tmp_path / "p.yaml",
                       "--MEAN_HEIGHT", "300",
                       "--OUTPUT", tmp_path / "o.json")
    line = one_error(err)
    assert code == 2 and "PROJECT" in line and "US survey foot" in line, line
    assert not (tmp_path / "o.json").exists()


@pytest.mark.parametrize("alg", ["dem:idw", "dem:quadratic", "tin:delaunay"])
def test_degenerate_point_sets(points, alg, tmp_path):
    extra = ["--CELL_SIZE", "20"] if alg.startswith("dem") else []
    out = tmp_path / ("o.tif" if alg.startswith("dem") else "o.gpkg")
    for key, words in (("nearly_collinear", "collinear"),
                       ("two", r"at least \d+ (distinct data )?points"),
                       ("duplicates", r"duplicate")):
        code, _, err = cli("run", alg, "--INPUT", points[key], *extra, "--OUTPUT", out)
        assert code == 2 and re.search(words, one_error(err)), (key, err)
    assert list(tmp_path.iterdir()) == []


def test_raster_output_without_a_valid_cell_is_an_error(points, demo, tmp_path):
    far = "1600000,4700000,1601000,4701000"
    cases = [("dem:idw", "--INPUT", points["mass"], "--CELL_SIZE", "5", "--EXTENT", far),
             ("dem:idw", "--INPUT", points["mass"], "--CELL_SIZE", "5000"),
             ("tin:to_raster", "--TIN", demo[0] / "tin.gpkg", "--CELL_SIZE", "5", "--EXTENT",
              far)]
    for args in cases:
        code, _, err = cli("run", *args, "--OUTPUT", tmp_path / "o.tif")
        assert code == 2 and "OUTPUT would have no valid cell" in one_error(err), err
    assert list(tmp_path.iterdir()) == []


def test_interpolate_refuses_an_existing_field(demo, tmp_path):
    import pyogrio

    check_points = demo[1]["tin_check_points"]
    before = Path(check_points).read_bytes()
    args = ["run", "tin:interpolate", "--INPUT", check_points, "--TIN", demo[0] / "tin.gpkg",
            "--FIELD", "ID", "--OUTPUT", tmp_path / "o.gpkg"]
    code, _, err = cli(*args)
    assert code == 2 and "FIELD 'ID' is already a field of INPUT" in one_error(err)
    code, _, err = cli(*args, "--REPLACE_FIELD")
    assert code == 0, err
    frame = pyogrio.read_dataframe(tmp_path / "o.gpkg")
    assert "id" not in frame.columns and frame["ID"].between(200, 400).all()
    assert Path(check_points).read_bytes() == before


def test_cli_mistakes_are_one_line(demo, tmp_path):
    dem = demo[1]["dem"]
    for args, words in ((["run"], "missing the algorithm id"),
                        (["nope"], "No such command 'nope'"),
                        (["batch", tmp_path / "none.yaml"], "does not exist"),
                        (["run", "raster:hillshade", "--INPUT", dem, "--OUTPUT",
                          tmp_path / "a.tif", "--BAND", "2"], "BAND must be <= 1"),
                        (["run", "orientation:precision", "--PROJECT", demo[1]["siena_project"],
                          "--DEM", dem, "--BAND", "5", "--OUTPUT", tmp_path / "p.json"],
                         "BAND must be <= 1"),
                        (["run", "dem:idw", "--INPUT", demo[1]["mass_points"], "--CELL_SIZE",
                          "1e-320", "--OUTPUT", tmp_path / "a.tif"], "CELL_SIZE is too small"),
                        (["run", "rectify:image", "--INPUT", demo[1]["photo"], "--TRANSFORM",
                          demo[0] / "rectify" / "photo_transform.json", "--OUTSIDE", "nodata",
                          "--NODATA", "-9999", "--OUTPUT", tmp_path / "a.tif"],
                         "NODATA -9999 does not fit the uint8")):
        code, _, err = cli(*args)
        assert code == 2 and words in one_error(err), (args, err)
    code, _, err = cli("run", "dem:idw", "--INPUT", demo[1]["mass_points"], "--CELL_SIZE", "5",
                       "--OUTPUT", tmp_path / "a.tif", env={"TOOLBOX_MAX_CELLS": "abc"})
    assert code == 2 and "TOOLBOX_MAX_CELLS" in one_error(err)
    assert list(tmp_path.iterdir()) == []


def test_help_and_quiet_after_the_id(demo, tmp_path):
    code, out, _ = cli("run", "--help")
    assert code == 0 and "run [OPTIONS] [ALGORITHM_ID]" in out
    code, out, _ = cli("run", "raster:hillshade", "--help")
    assert code == 0 and "--AZIMUTH" in out
    # --quiet after the id: no information messages, but warnings still show
    code, out, err = cli("run", "rectify:estimate", "--INPUT", demo[1]["photo_gcps"], "--CRS",
                         "EPSG:3003", "--MODEL", "homography", "--ROBUST", "snooping",
                         "--OUTPUT", tmp_path / "t.json", "--quiet")
    assert code == 0 and "WARNING: gross errors rejected" in err and "INFO" not in err


def test_internal_errors_are_one_line_exit_3(tmp_path):
    def process(self, params, feedback):
        params["OUTPUT"].write_text("half")
        return {}["missing"]

    register_testing("bug", OutputFile("OUTPUT", extensions=[".txt"]), process,
                     "Fails with a bug (not a user mistake).")
    code, _, err = cli("run", "testing:bug", "--OUTPUT", tmp_path / "a.txt")
    lines = err.strip().splitlines()
    assert code == 3 and len(lines) == 1, err
    assert lines[0].startswith("toolbox: internal error in testing:bug: KeyError") \
        and "please report" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_commit_never_replaces_a_file_that_appeared(tmp_path):
    """Two runs writing one path: the second to finish fails (without --overwrite) and the
    first one's file is left as it was."""
    from toolbox.errors import OutputExistsError

    def process(self, params, feedback):
        params["OUTPUT"].write_text("mine")
        (tmp_path / "a.txt").write_text("the other run's")  # appears meanwhile
        return {"OUTPUT": params["OUTPUT"]}

    register_testing("racer", OutputFile("OUTPUT", extensions=[".txt"]), process,
                     "Another run writes the same output while this one works.")
    with pytest.raises(OutputExistsError, match="appeared during the run"):
        toolbox.run("testing:racer", {"OUTPUT": tmp_path / "a.txt"})
    assert (tmp_path / "a.txt").read_text() == "the other run's"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_batch_validate_checks_values(demo, tmp_path):
    dem = demo[1]["dem"]
    head = f"variables: {{dem: {dem}}}\nsteps:\n"
    shade = "  - name: {name}\n    algorithm: raster:hillshade\n    params: {params}\n"
    cases = {
        "bad range": (shade.format(name="a", params="{INPUT: '${dem}', OUTPUT: a.tif}")
                      + shade.format(name="b", params="{INPUT: '${dem}', Z_FACTOR: -1, "
                                                      "OUTPUT: b.tif}"),
                      "step 2 of 2 (dem:hillshade 'b'): Z_FACTOR must be > 0"),
        "bad type": (shade.format(name="a", params="{INPUT: '${dem}', AZIMUTH: east, "
                                                   "OUTPUT: a.tif}"), "AZIMUTH must be a number"),
        "two steps, one file": (shade.format(name="a", params="{INPUT: '${dem}', OUTPUT: a.tif}")
                                + shade.format(name="b", params="{INPUT: '${dem}', "
                                                                "OUTPUT: a.tif}"),
                                "is also written by a.OUTPUT"),
        "own input": (shade.format(name="a", params="{INPUT: '${dem}', OUTPUT: a.tif}")
                      + shade.format(name="b", params="{INPUT: '${a.OUTPUT}', "
                                                      "OUTPUT: a.tif}"), "this step's input"),
        "earlier input": (shade.format(name="a", params="{INPUT: c.tif, OUTPUT: b.tif}")
                          .replace("c.tif", str(dem))
                          + shade.format(name="b", params=f"{{INPUT: b.tif, OUTPUT: {dem}}}"),
                          "input a.INPUT of an earlier step"),
        "unset optional output": (
            "  - name: i\n    algorithm: dem:idw\n    params: {INPUT: "
            f"{demo[1]['mass_points']}, CELL_SIZE: 20, OUTPUT: i.tif}}\n"
            + shade.format(name="b", params="{INPUT: '${i.QUALITY}', OUTPUT: b.tif}"),
            "does not set its optional output QUALITY"),
    }
    for label, (steps, words) in cases.items():
        pipe = tmp_path / "p.yaml"
        pipe.write_text(head + steps)
        for extra in (["--validate"], []):
            code, _, err = cli("batch", pipe, *extra)
            assert code == 2 and words in one_error(err), (label, err)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml"], label
    for text, words in (("steps: [a, b\n", "at line 2, column 1"), ("variables: [1]\nsteps: [{}]\n",
                                                       "'variables' must be a mapping")):
        (tmp_path / "p.yaml").write_text(text)
        code, _, err = cli("batch", tmp_path / "p.yaml", "--validate")
        assert code == 2 and words in one_error(err), err
    (tmp_path / "p.yaml").write_bytes(b"steps:\n  - algorithm: raster:hillshade # \xe8\n")
    code, _, err = cli("batch", tmp_path / "p.yaml", "--validate")
    assert code == 2 and "UTF-8" in one_error(err)


def test_zmap_line_that_does_not_parse_is_an_error(demo, tmp_path):
    from toolbox.errors import InputDataError
    from toolbox.photogrammetry.readers.zmap_log import parse_zmap_log

    text = (Path(demo[1]["siena"]) / "zmap_strip1.log").read_text(encoding="latin-1")
    lines = text.splitlines()
    n = next(i for i, line in enumerate(lines) if line.strip().startswith("Omega"))
    lines[n] = "Omega x.yz, Phi 0.1, Kappa 0.2"
    with pytest.raises(InputDataError, match=f"line {n + 1}: cannot read 'Omega x.yz"):
        parse_zmap_log("\n".join(lines), "log")


@pytest.mark.parametrize("old, new", [
    ("pixel_size_mm: 0.014", "pixel_size_mm: abc"),
    ('fiducials_mm:\n      "01": [-106.0, 106.0]', 'fiducials_mm:\n      - [-106.0, 106.0]'),
    ("principal_point_mm: [0.0, 0.0]", "principal_point_mm: [0.0, 0.0, [1]]"),
    ("format: orientation-project", "format: orientation-project\n  bad: [indent"),
])
def test_malformed_project_values_are_one_line(demo, tmp_path, old, new):
    siena = Path(demo[1]["siena"])
    text = (siena / "siena_project.yaml").read_text(encoding="utf-8")
    assert old in text
    bad = siena / "bad_project.yaml"  # beside the original: its relative paths work
    bad.write_text(text.replace(old, new, 1), encoding="utf-8")
    try:
        code, _, err = cli("run", "orientation:footprints", "--PROJECT", bad, "--MEAN_HEIGHT",
                           "300", "--OUTPUT", tmp_path / "f.gpkg")
    finally:
        bad.unlink()
    assert code == 2 and "bad_project.yaml" in one_error(err), err
    assert list(tmp_path.iterdir()) == []


def test_coordinates_a_little_outside_the_area_of_use_warn(tmp_path):
    """EPSG:3003 is for Italy west of 12°E: points at 13.5°E (1.5° out) are a warning, at 12.5°E
    (within the margin) nothing, at 25°E an error."""
    import geopandas as gpd
    import numpy as np
    import shapely

    from toolbox.errors import InputDataError
    from toolbox.feedback import Feedback

    rng = np.random.default_rng(2)
    warnings = {}
    for lon in (12.5, 13.5, 25.0):
        lonlat = gpd.GeoSeries(shapely.points(lon + rng.uniform(0, 0.01, 20),
                                              43 + rng.uniform(0, 0.01, 20)), crs=4326)
        xy = shapely.get_coordinates(lonlat.to_crs(3003).values)
        frame = gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1],
                                                         rng.uniform(0, 9, 20)), crs=3003)
        path = tmp_path / f"p{lon}.gpkg"
        frame.to_file(path)
        feedback = Feedback()
        params = {"INPUT": path, "CELL_SIZE": 50, "OUTPUT": tmp_path / f"d{lon}.tif"}
        if lon > 20:
            with pytest.raises(InputDataError, match="outside the area of use of EPSG:3003"):
                toolbox.run("dem:idw", params, feedback=feedback)
            continue
        toolbox.run("dem:idw", params, feedback=feedback)
        warnings[lon] = [w for w in feedback.warnings if "area of use" in w]
    assert warnings[12.5] == []
    assert len(warnings[13.5]) == 1 and warnings[13.5][0].startswith("INPUT: coordinates")


def test_files_a_project_names_are_inputs_too(demo, tmp_path):
    """An output may not replace a file the project YAML refers to (an orientation file)."""
    siena = tmp_path / "siena"
    shutil.copytree(demo[1]["siena"], siena)
    project = siena / "siena_project.yaml"
    project.write_text(project.read_text(encoding="utf-8").replace(
        "exterior_orientations:", "exterior_orientations:\n  - path: exterior_orientation.csv\n"
        "    where: {run: strip1, stage: final}", 1), encoding="utf-8")
    victim = siena / "exterior_orientation.csv"
    before = victim.read_bytes()
    code, _, err = cli("run", "orientation:interior", "--INPUT", siena / "fiducials.csv",
                       "--PROJECT", project, "--SOURCE", "log_block", "--OUTPUT",
                       tmp_path / "i.json", "--RESIDUALS", victim, "--overwrite")
    assert code == 2 and "RESIDUALS" in one_error(err) and "is the input PROJECT" in err
    assert victim.read_bytes() == before and not (tmp_path / "i.json").exists()


@_cases()
def test_nan_coordinates_no_crs_and_mixed_crs(case):
    """Per vector input: a feature with NaN coordinates, the layer without a CRS, the layer
    reprojected to another (valid) CRS. NaN and a missing CRS may be handled (exit 0) or refused
    (exit 2); a CRS different from the other inputs' must be refused."""
    import geopandas as gpd
    import shapely

    vectors = [p for p in case.input_params() if isinstance(p, VectorLayer)]
    if not vectors:
        pytest.skip("no vector input")
    for p in vectors:
        path, _, option = str(case.params[p.name]).partition("|")
        path = Path(path)
        if path.suffix.lower() != ".gpkg":
            continue
        # the layer named, else the first (a styled GeoPackage also holds layer_styles)
        frame = gpd.read_file(path, layer=option.partition("=")[2] if option.startswith(
            "layername=") else 0)
        if frame.crs is None or not len(frame):
            continue
        coords = shapely.get_coordinates(frame.geometry.values, include_z=True)
        coords[1] = float("nan")  # the second vertex: a ring stays closed
        nan = frame.copy()
        nan.geometry = shapely.set_coordinates(frame.geometry.values.copy(), coords)
        variants = {"nan": nan, "no_crs": frame.set_crs(None, allow_override=True),
                    "utm": frame.to_crs(32632)}
        others = [q for q in case.input_params() if q is not p
                  and isinstance(q, (VectorLayer, RasterLayer))
                  and getattr(validate(case.alg, case.params)[q.name], "crs", None) is not None]
        for label, variant in variants.items():
            target = case.root / f"{label}_{p.name}.gpkg"
            variant.to_file(target)
            line = case.run(case.args(**{p.name: str(target)}), None, may_succeed=True)
            if label == "utm" and others and not line:  # accepted: only if it said what it did
                assert "EPSG:32632" in case.last_stderr, (p.name, case.last_stderr)


@_cases()
def test_raster_without_crs_or_in_degrees(case):
    """Per GeoTIFF input: without a CRS (may be handled), in EPSG:4326 (refused by every
    algorithm that works in metres, naming the parameter)."""
    import rasterio

    rasters = [p for p in case.input_params() if isinstance(p, RasterLayer)
               and Path(str(case.params[p.name])).suffix.lower() in (".tif", ".tiff")]
    if not rasters:
        pytest.skip("no GeoTIFF input")
    for p in rasters:
        source = Path(str(case.params[p.name]))
        for label, crs in (("no_crs", None), ("degrees", "EPSG:4326")):
            target = case.root / f"{label}_{p.name}.tif"
            with rasterio.open(source) as src:
                profile, data = src.profile, src.read()
            profile.update(crs=crs)
            if crs:  # degrees near Siena, a 1e-5 degree cell
                profile.update(transform=rasterio.Affine(1e-5, 0, 11.3, 0, -1e-5, 43.3))
            with rasterio.open(target, "w", **profile) as dst:
                dst.write(data)
            degrees = crs is not None and case.alg.projected_crs_only
            case.run(case.args(**{p.name: str(target)}), p.name if degrees else None,
                     may_succeed=not degrees)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_FSIZE fault injection")
@pytest.mark.parametrize("args", [
    ["raster:hillshade", "--INPUT", "{dem}", "--OUTPUT", "{out}/o.tif"],
    ["rectify:image", "--INPUT", "{photo}", "--TRANSFORM", "{demo}/rectify/photo_transform.json",
     "--CELL_SIZE", "1", "--OUTPUT", "{out}/o.tif"],
    ["tin:delaunay", "--INPUT", "{mass_points}", "--OUTPUT", "{out}/o.gpkg"],
], ids=lambda a: a[0])
def test_a_write_that_fails_midway_is_one_line(demo, tmp_path, args):
    """A file-size limit (works without root, unlike a full tmpfs) makes every write past 20 kB
    fail, as a full disk does: exit 2, one line naming OUTPUT, nothing left."""
    out = tmp_path / "out"
    names = {**demo[1], "demo": demo[0], "out": out}
    assert_cannot_write(run_on_full_disk([a.format(**names) for a in args]), out)


def test_commit_main_file_first_and_stale_sidecars_replaced(tmp_path):
    from toolbox.errors import OutputExistsError
    from toolbox.io.staging import OutputStaging

    final = tmp_path / "a.tif"
    (tmp_path / "a.tif.aux.xml").write_text("stale statistics of a deleted a.tif")
    staging = OutputStaging()
    staged = staging.stage(final)
    staged.write_text("new")
    (staged.parent / "a.tif.aux.xml").write_text("new statistics")
    assert staging.commit(overwrite=False) == [final]
    assert (tmp_path / "a.tif.aux.xml").read_text() == "new statistics"
    # a main file that appeared meanwhile: nothing of this run is moved, not even its sidecar
    other = tmp_path / "b.tif"
    staging = OutputStaging()
    staged = staging.stage(other)
    staged.write_text("mine")
    (staged.parent / "b.tif.aux.xml").write_text("mine")
    other.write_text("theirs")
    with pytest.raises(OutputExistsError):
        staging.commit(overwrite=False)
    staging.rollback()
    assert other.read_text() == "theirs" and not (tmp_path / "b.tif.aux.xml").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.tif", "a.tif.aux.xml", "b.tif"]


# -- the property-based sweep (hypothesis): generated bad values for every parameter -------------
# Every registered algorithm, every parameter, values drawn by parameter type: numbers out of
# range, NaN, infinite, huge, subnormal or not numbers; junk text; enums outside their list; CRS
# junk; inverted, empty and non-finite extents; input paths that do not exist, are folders, are
# empty, are garbage or truncated copies of the real input. Each example runs in-process through
# the CLI (click's runner) and must keep the contract: exit 0 or 2, one line, no traceback, every
# input byte-identical, nothing staged or half-written left. Examples per algorithm: a few in the
# default tier, many more in the slow tier (TOOLBOX_SWEEP_EXAMPLES overrides both).
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from toolbox.parameters import (  # noqa: E402
    Boolean,
    Crs,
    Enum,
    ExtentParameter,
    Folder,
    OutputFolder,
    String,
)


def _sweep_settings(examples: int) -> settings:
    return settings(max_examples=int(os.environ.get("TOOLBOX_SWEEP_EXAMPLES", examples)),
                    deadline=None, database=None, derandomize=True, print_blob=True,
                    suppress_health_check=list(HealthCheck))


JUNK = st.text(st.characters(blacklist_categories=("Cs",)), max_size=30)
NUMBER_WORDS = ["nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "-0", "0", "-1", "1e30",
                "-1e30", "1e-30", "abc", "", " ", "1,5", "0x10", "1e999", "++1", "1_000"]
CRS_JUNK = ["EPSG:0", "EPSG:99999999", "abc", "+proj=junk", "EPSG:4326", "EPSG:32632",
            "EPSG:3857", "EPSG:4978", "ESRI:1", "urn:ogc:def:crs:EPSG::4979", "EPSG:", "",
            "+proj=longlat +datum=WGS84", 'GEOGCS["x"', "EPSG:3003 EPSG:3004"]
EXTENT_JUNK = ["1,2,3", "4,3,2,1", "nan,0,1,1", "0,0,0,0", "1e308,1e308,-1e308,-1e308",
               "0,0,1e15,1e15", "abc", "", "0,0,1,inf", "1688000,4799000,1688001,4799000",
               "0,0,1,1 [EPSG:4326]", "0,0,1,1 [junk]", "0 0 1 1 1", "1,1,0,0 [EPSG:3003]"]
PATH_DAMAGE = ["missing", "folder", "empty", "garbage", "truncated", "other_input"]


def _number_values(p: Number):
    edges = []
    for bound in (p.min_value, p.max_value):
        if bound is not None:
            edges += [repr(bound), repr(bound - 1), repr(bound + 1), repr(bound - 1e-9),
                      repr(bound + 1e-9)]
    return st.one_of(st.sampled_from(NUMBER_WORDS + edges),
                     st.floats(allow_nan=True, allow_infinity=True).map(repr),
                     st.integers(-2 ** 70, 2 ** 70).map(str), JUNK)


def _bad_value(p):
    """A strategy of bad values for parameter ``p``: text as on the command line, or a
    ``("path", damage, fraction)`` tuple that :func:`_damaged_path` turns into a file."""
    if isinstance(p, Number):
        return _number_values(p)
    if isinstance(p, Boolean):
        return st.one_of(st.sampled_from(["maybe", "2", "", "-1", "yes please", "nan"]), JUNK)
    if isinstance(p, Enum):
        return JUNK.filter(lambda t: t.strip().lower() not in p.options)
    if isinstance(p, Crs):
        return st.one_of(st.sampled_from(CRS_JUNK), JUNK)
    if isinstance(p, ExtentParameter):
        floats = st.floats(allow_nan=True, allow_infinity=True)
        return st.one_of(st.sampled_from(EXTENT_JUNK), JUNK,
                         st.tuples(floats, floats, floats, floats).map(
                             lambda t: ",".join(repr(v) for v in t)))
    if isinstance(p, (*INPUT_TYPES, Folder)):
        return st.tuples(st.just("path"), st.sampled_from(PATH_DAMAGE), st.floats(0, 1))
    if isinstance(p, String):
        return st.one_of(st.sampled_from(["", " ", "\x00", ";;;", "1e999", "../../x", "a" * 5000,
                                          "${undefined}", "1,2,3,4,5,6,7,8,9", "nan,nan"]), JUNK)
    return JUNK  # Field and any type added later: junk names


def _damaged_path(case: Case, p, damage: str, fraction: float) -> str:
    """A path for input ``p``: missing, a folder, empty, garbage, a truncated copy of the real
    input, or another input of the case (of another type)."""
    value = case.params.get(p.name)
    first = value[0] if isinstance(value, list) else value
    real = Path(str(first).split("|")[0]) if first is not None else None
    suffix = real.suffix if real is not None else ".dat"
    bad = case.root / "bad"
    bad.mkdir(exist_ok=True)
    target = bad / f"{damage}_{p.name}{suffix}"
    if target.is_dir():
        shutil.rmtree(target)
    elif target.exists():
        target.unlink()
    if damage == "folder":
        target.mkdir()
    elif damage == "empty":
        target.write_bytes(b"")
    elif damage == "garbage":
        target.write_bytes(random.Random(fraction).randbytes(1 + int(fraction * 4000)))
    elif damage == "truncated" and real is not None and real.is_file():
        data = real.read_bytes()
        target.write_bytes(data[: int(len(data) * fraction)])
    elif damage == "other_input":
        others = [Path(str(v).split("|")[0]) for q in case.input_params() if q is not p
                  for v in _flatten_values(case.params[q.name])]
        if others:
            return str(others[int(fraction * (len(others) - 1))])
    return str(target)


def _flatten_values(value) -> list:
    return list(value) if isinstance(value, list) else [value]


def _input_files(case: Case) -> dict[str, str]:
    """sha256 of every file under the case's inputs (the copied demo data)."""
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(case.inputs_dir.rglob("*")) if p.is_file()}


def _contract_run(case: Case, args: list[str]) -> int:
    """Run ``toolbox run ID args`` in-process and check the contract; return the exit code.
    A success may write new files (even beside the inputs, for an output folder): those are
    removed afterwards, every file that existed must be byte-identical."""
    before = _input_files(case)
    result = CliRunner().invoke(main, ["run", case.alg.id, *args])
    stderr = result.stderr
    assert "Traceback" not in stderr and "internal error" not in stderr, (args, stderr)
    assert result.exit_code in (0, 2), (args, result.exit_code, stderr, result.exception)
    after = _input_files(case)
    changed = [p for p, digest in before.items() if after.get(p) != digest]
    assert not changed, f"{args} modified or removed inputs {changed}"
    parts = [str(p) for p in case.root.rglob("*.part")]
    assert not parts, f"{args} left staging folders {parts}"
    created = [Path(p) for p in after if p not in before]
    if result.exit_code == 2:
        lines = [line for line in stderr.strip().splitlines() if line.startswith("toolbox:")]
        errors = [line for line in lines if line.startswith("toolbox: error:")]
        assert len(errors) == 1 and len(lines) == 1, (args, stderr)
        assert not created, f"{args} failed but wrote {created}"
        left = [str(p) for p in case.out.rglob("*")]
        assert not left, f"{args} failed but left {left}"
    for path in created:
        path.unlink()
    for item in case.out.iterdir():
        shutil.rmtree(item) if item.is_dir() else item.unlink()
    return result.exit_code


def _swept_parameters(case: Case) -> list:
    return [p for p in case.alg.parameters if not p.is_output]


_SWEEP_STARTED: dict[tuple[str, str], float | None] = {}


def _sweep(case: Case, data, tier: str, budget_s: float) -> None:
    """One example; once an algorithm has used ``budget_s`` of its tier (examples that pass
    validation run the whole algorithm: report:quality takes seconds) the rest are no-ops,
    unless one failed (hypothesis replays it to shrink it: it must run again)."""
    import time

    params = _swept_parameters(case)
    if not params:
        pytest.skip("no input parameter")
    key = (tier, case.alg.id)
    started = _SWEEP_STARTED.setdefault(key, time.monotonic())
    p = data.draw(st.sampled_from(params), label="parameter")
    value = data.draw(_bad_value(p), label=p.name)
    if started is not None and time.monotonic() - started > budget_s:
        return  # drawn all the same: hypothesis replays draws
    if isinstance(value, tuple):
        value = _damaged_path(case, p, value[1], value[2])
        if isinstance(p, MultipleLayers) and isinstance(case.params.get(p.name), list):
            value = [value, *case.params[p.name][1:]]
    try:
        _contract_run(case, case.args(**{p.name: value}))
    except BaseException:
        _SWEEP_STARTED[key] = None  # no budget any more: the failure's replays must run
        raise


@_cases()
@_sweep_settings(4)
@given(data=st.data())
def test_generated_bad_values(case, data):
    _sweep(case, data, "default", budget_s=1.5)


@pytest.mark.slow
@_cases()
@_sweep_settings(60)
@given(data=st.data())
def test_generated_bad_values_slow(case, data):
    _sweep(case, data, "slow", budget_s=2.5)


def _victims(case: Case, every: bool) -> list[Path]:
    """The input files an output is pointed at: each input parameter's files (and, with
    ``every``, every file the inputs name, a project's photos included)."""
    from toolbox.runner import input_paths

    files = [Path(str(v).split("|")[0]) for p in case.input_params()
             for v in _flatten_values(case.params[p.name])]
    files += _folder_files(case)
    if every:
        files += [p for p in input_paths(case.alg, validate(case.alg, case.params))
                  if p.is_file()]
    return list(dict.fromkeys(p.resolve() for p in files))


def _folder_files(case: Case) -> list[Path]:
    """The files directly inside the case's input folders (report:quality's REPORTS)."""
    return [f for p in case.alg.parameters if isinstance(p, Folder) and not p.is_output
            and case.params.get(p.name) is not None
            for f in sorted(Path(str(case.params[p.name])).iterdir()) if f.is_file()]


def _outputs_at_inputs(case: Case, every: bool) -> None:
    dests = case.destinations()
    victims = _victims(case, every)
    if not dests or not victims:
        pytest.skip("no output or no file input")
    for victim in _folder_files(case)[:3]:  # --run-report too: the folder's files are inputs
        code = _contract_run(case, case.args() + ["--overwrite", "--run-report", str(victim)])
        assert code == 2, ("--run-report", victim)
    for dest in dests:
        for victim in victims:
            targets = [victim]
            if isinstance(dest, OutputFolder):  # the folder holding the input, and the input
                targets.insert(0, victim.parent)
            for target in targets:
                for extra in ([], ["--overwrite"]):
                    code = _contract_run(case, case.args(**{dest.name: str(target)}) + extra)
                    assert code == 2 or target.is_dir(), (dest.name, target, extra)


@_cases()
def test_every_output_at_every_input(case):
    """Every destination (file or folder) pointed at every input parameter's file, with and
    without --overwrite: refused, the input intact (an output folder may be the inputs' folder
    when none of its files is an input)."""
    _outputs_at_inputs(case, every=False)


@pytest.mark.slow
@_cases()
def test_every_output_at_every_file_the_inputs_name(case):
    _outputs_at_inputs(case, every=True)


def test_a_mark_larger_than_the_scan_is_refused(demo, tmp_path):
    """Found by the sweep: MARK_SIZE 1.76e43 mm made orientation:fiducials allocate a template
    of that many pixels (ValueError: Maximum allowed size exceeded)."""
    code, _, err = cli("run", "orientation:fiducials", "--PROJECT",
                       demo[1]["fiducial_scans_project"], "--MARK_SIZE", "1.76e43", "--OUTPUT",
                       tmp_path / "f.json")
    line = one_error(err)
    assert code == 2 and line.startswith("toolbox: error: MARK_SIZE 1.76e+43 mm is ")
    assert "more than the whole scan" in line and list(tmp_path.iterdir()) == []
