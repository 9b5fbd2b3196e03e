"""Fuzz every text reader with seeded mutations of real files: only ToolboxError may escape.

Seeds are the Siena case-study files and the demo's sample data (orientation CSV, Z-Map logs,
fiducial and image-point CSVs, the project YAML, the topology parameter file, a transform JSON
written by rectify:estimate, a pipeline). Each mutation is the kind of damage files really
suffer: a truncation, a deleted or doubled line, a line with one field more, a number turned into
text, a non-UTF-8 byte, a NUL, swapped lines, a YAML/JSON structure broken. Deterministic (seeded)
and bounded: a fixed number of mutations per reader and a time budget, and each case under a
time limit (a hang fails). The slow tier runs a few thousand mutations over all readers.

Readers: the orientation file (native CSV, OPK text), the Z-Map log, fiducial and image-point
CSVs, the project YAML, the camera YAML, the topology parameter file, the transform JSON, the
pipeline YAML, the restitution's code, colour and parameter files, ASCII, DXF and two-table
forms, and the exchange formats (OpenSfM reconstruction.json and cameras.json, Orthority
interior YAML / exterior GeoJSON / CSV, Metashape XML and OPK text, PAT-B, ODM gcp_list.txt,
EXIF/XMP of a drone JPEG).
"""

from __future__ import annotations

import contextlib
import logging
import os
import random
import re
import signal
import time
import warnings
from pathlib import Path

import pytest
import trust_data

import toolbox
from toolbox.errors import ToolboxError

MUTATIONS_PER_READER = 100
BUDGET_S = 1.0  # per reader (the slow tier runs thousands)
SLOW_MUTATIONS_PER_READER = int(os.environ.get("TOOLBOX_FUZZ_MUTATIONS", 400))
SLOW_BUDGET_S = 20.0
CASE_LIMIT_S = 10  # one mutated file read longer than this is a hang

# mutated files make GDAL and numpy warn (odd separators, NaN arithmetic): expected here, where
# only crashes and hangs count
pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning", "ignore::UserWarning")


def _mutate(data: bytes, rng: random.Random) -> bytes:
    lines = data.split(b"\n")
    kind = rng.randrange(12)
    i = rng.randrange(len(lines))
    if kind == 0:  # truncation
        return data[: rng.randrange(len(data) + 1)]
    if kind == 1:  # a line deleted
        return b"\n".join(lines[:i] + lines[i + 1:])
    if kind == 2:  # a line doubled
        return b"\n".join(lines[: i + 1] + lines[i:])
    if kind == 3:  # one field more
        lines[i] += rng.choice([b",", b",x", b";1", b"\t2", b", 3"])
        return b"\n".join(lines)
    if kind == 4:  # a number turned into text
        numbers = list(re.finditer(rb"\d+(\.\d+)?", data))
        if numbers:
            m = rng.choice(numbers)
            return data[: m.start()] + rng.choice([b"x.yz", b"abc", b"", b"1e999", b"nan", b"-"]) \
                + data[m.end():]
    if kind == 5:  # Latin-1 / binary bytes
        pos = rng.randrange(len(data) + 1)
        return data[:pos] + rng.choice([b"\xe0\xe8", b"\xff\xfe", b"\x00", b"\x89PNG"]) + data[pos:]
    if kind == 6:  # two lines swapped
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        return b"\n".join(lines)
    if kind == 7:  # structure characters
        pos = rng.randrange(len(data) + 1)
        return data[:pos] + rng.choice([b":", b"- ", b"{", b"[", b"]", b"\"", b"'", b"  ", b"|",
                                        b"&a", b"*a", b"!!python/object:os.system"]) + data[pos:]
    if kind == 8:  # a line emptied or blanked
        lines[i] = rng.choice([b"", b"   ", b"#", b","])
        return b"\n".join(lines)
    if kind == 9:  # a chunk deleted
        a = rng.randrange(len(data) + 1)
        return data[:a] + data[a + rng.randrange(1, 200):]
    if kind == 10:  # only the first lines (header only)
        return b"\n".join(lines[: rng.randrange(1, 3)])
    return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))  # garbage


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    demo_folder, made = trust_data.demo()
    made = {k: Path(v) for k, v in made.items()}
    folder = tmp_path_factory.mktemp("fuzz_seeds")
    transform = demo_folder / "rectify" / "photo_transform.json"
    pipeline = folder / "pipeline.yaml"
    pipeline.write_text(f"""variables:
  dem: {made['dem']}
steps:
  - name: shade
    algorithm: raster:hillshade
    params: {{INPUT: '${{dem}}', Z_FACTOR: 2, OUTPUT: out/shade.tif}}
  - name: again
    algorithm: raster:hillshade
    params:
      INPUT: ${{shade.OUTPUT}}
      AZIMUTH: 90
      OUTPUT: out/again.tif
""")
    siena = made["siena"]
    exchange = _exchange_seeds(demo_folder, folder)
    return folder, {**exchange,
                    "code_file": made["restitution_codes"],
                    "colour_file": made["restitution_colours"],
                    "restitution_parameters": made["restitution_parameters"],
                    "restitution_ascii": made["restitution_model_12"],
                    "restitution_dxf": made["restitution_dxf"],
                    "orientation_csv": siena / "exterior_orientation.csv",
                    "zmap_log": siena / "zmap_strip1.log",
                    "fiducials_csv": made["siena_fiducials"],
                    "image_points_csv": made["siena_control_image_points"],
                    "project_yaml": made["siena_project"],
                    "camera_yaml": siena / "camera.yaml",
                    "parameter_file": made["linework_parameters"],
                    "transform_json": transform,
                    "pipeline_yaml": pipeline, **_orientation_table_seeds(made, folder)}


def _orientation_table_seeds(made: dict[str, Path], folder: Path) -> dict[str, Path]:
    """The tables of the adjustment tools: control, GNSS centres, IMU attitudes, model
    coordinates, rectification control points (GNSS and IMU written here, two strips)."""
    import shutil

    gnss, imu = folder / "gnss.csv", folder / "imu.csv"
    photos = [(f"{s}_{k:02d}", 1688000.0 + 600 * k, 4799000.0 + 1200 * s) for s in (1, 2)
              for k in range(1, 6)]
    gnss.write_text("photo,X,Y,Z,sigma_xy,sigma_z,strip,time\n" + "".join(
        f"{pid},{x:.3f},{y:.3f},1850.25,0.05,0.1,{pid[0]},{k * 2.5}\n"
        for k, (pid, x, y) in enumerate(photos)))
    imu.write_text("photo,omega,phi,kappa,sigma\n" + "".join(
        f"{pid},0.0012,-0.0031,{3.1416 * (int(pid[0]) - 1):.4f},0.001\n"
        for pid, _, _ in photos))
    shutil.copy(made["bundle_control"], folder / "control.csv")  # the models' CONTROL
    return {"control_csv": made["bundle_control"], "gnss_csv": gnss, "imu_csv": imu,
            "models_csv": made["bundle_models"], "ground_csv": made["siena_control_ground"],
            "gcps_csv": made["photo_gcps"]}


def _exchange_seeds(demo_folder: Path, folder: Path) -> dict[str, Path]:
    """Files of every exchange format: the demo's Orthority export of the Siena bundle, the
    other formats written from it, a synthetic OpenSfM reconstruction and Metashape XML (the
    exchange tests' generators), a gcp_list, a two-table restitution, an OPK text and a drone
    JPEG with GNSS/gimbal tags."""
    import json

    import numpy as np
    import rasterio

    from tests.toolbox.exchange import exchange_synthetic as syn
    from tests.toolbox.exchange.test_exchange_formats import metashape_xml
    from toolbox.exchange import formats

    orientation = demo_folder / "orientation"
    exterior = orientation / "siena_bundle_ext_param.geojson"
    oset = formats.read_orientations([exterior])
    seeds = {"orthority_exterior": exterior,
             "orthority_interior": orientation / "siena_bundle_int_param.yaml",
             "orthority_csv": folder / "block.csv", "patb": folder / "block.ori",
             "opensfm": syn.reconstruction(folder / "reconstruction.json"),
             "metashape_xml": folder / "cameras.xml", "gcp_list": folder / "gcp_list.txt",
             "opensfm_cameras": folder / "cameras.json", "metashape_opk": folder / "opk.txt",
             "two_table_descriptions": folder / "descriptions.txt",
             "two_table_coordinates": folder / "coordinates.txt", "exif": folder / "drone.jpg"}
    formats.write_orientations(oset, "csv", seeds["orthority_csv"])
    formats.write_orientations(oset, "patb", seeds["patb"])
    metashape_xml(seeds["metashape_xml"])
    camera = json.loads(seeds["opensfm"].read_text())[0]["cameras"]
    seeds["opensfm_cameras"].write_text(json.dumps(camera, indent=1))
    seeds["gcp_list"].write_text("EPSG:4326\n11.30 43.30 300.0 100 200 IMG_1.JPG gcp_a\n"
                                 "11.30\t43.30\t300.0\t150.5\t220.5\tIMG_2.JPG\tgcp_a\n"
                                 "11.31 43.31 310.0 500 400 IMG_1.JPG\n")
    seeds["metashape_opk"].write_text(
        "# Cameras (2)\n# PhotoID, X, Y, Z, Omega, Phi, Kappa\n"
        "DSC_1.JPG\t500000.5\t4800000.25\t450.0\t1.5\t-2.0\t90.0\n"
        "DSC_2.JPG\t500100.5\t4800000.25\t451.0\t0.5\t-1.0\t91.0\n")
    seeds["two_table_coordinates"].write_text(
        "colour;E;N;Z\n1;1688000;4799000;10\n1;1688010;4799010;11\n2;1688020;4799000;12\n")
    seeds["two_table_descriptions"].write_text(
        "record;code;vertices;colour;source;xmin;ymin;xmax;ymax;first\n"
        "1;STR02001;2;3;m;1688000;4799000;1688010;4799010;1\n"
        "2;QUO01001;1;3;m;1688020;4799000;1688020;4799000;3\n")
    xmp = ('<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/'
           '22-rdf-syntax-ns#"><rdf:Description xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/"'
           ' drone-dji:GpsLatitude="43.30" drone-dji:GpsLongtitude="11.30" '
           'drone-dji:AbsoluteAltitude="420.5" drone-dji:GimbalRollDegree="0.0" '
           'drone-dji:GimbalPitchDegree="-90.0" drone-dji:GimbalYawDegree="45.0"/></rdf:RDF>'
           '</x:xmpmeta>')
    tags = {"EXIF_Make": "DJI", "EXIF_Model": "FC6310", "EXIF_FocalLengthIn35mmFilm": "24",
            "EXIF_PixelXDimension": "64", "EXIF_PixelYDimension": "48",
            "EXIF_GPSLatitude": "(43) (18) (0)", "EXIF_GPSLatitudeRef": "N",
            "EXIF_GPSLongitude": "(11) (18) (0)", "EXIF_GPSLongitudeRef": "E",
            "EXIF_GPSAltitude": "(420.5)"}
    mem = folder / "drone_src.tif"
    with rasterio.open(mem, "w", driver="GTiff", width=64, height=48, count=3,
                       dtype="uint8") as dst:
        dst.write(np.random.default_rng(0).integers(0, 255, (3, 48, 64), dtype="uint8"))
        dst.update_tags(**tags)
        dst.update_tags(ns="xml:XMP", **{"xml:XMP": xmp})
    import rasterio.shutil

    rasterio.shutil.copy(mem, seeds["exif"], driver="JPEG")
    return seeds


def _readers(folder: Path):
    """name -> (seed key, function of the mutated file path)."""
    from toolbox.batch import load_pipeline, validate_pipeline
    from toolbox.io.parameter_file import read_parameter_file
    from toolbox.photogrammetry.project import load_project
    from toolbox.photogrammetry.readers import read_exterior_orientations
    from toolbox.photogrammetry.readers.zmap_log import read_zmap_log
    from toolbox.photogrammetry.tables import image_measurements
    from toolbox.transforms.rectification import load_transform

    def fiducials(path):  # the CSV through orientation:interior (its parsing is there)
        toolbox.run("orientation:interior", {"INPUT": path, "SOURCE": "log_block",
                                             "TRANSFORMATION": "from_input",
                                             "OUTPUT": folder / "interior.json",
                                             "OVERWRITE": True})

    def pipeline(path):
        validate_pipeline(load_pipeline(path), overwrite=True)

    from toolbox.attribution.restitution import read_ascii, read_dxf, read_two_tables
    from toolbox.exchange import exif, formats, odm_gcp
    from toolbox.io.code_file import read_code_file, read_colour_file
    from toolbox.io.parameter_file import read_parameter_file as read_restitution_parameters
    from toolbox.photogrammetry.tables import ground_points
    from toolbox.triangulation.inputs import read_attitudes, read_centres, read_control

    def run(algorithm, **params):  # a table parsed inside its algorithm
        return lambda p: toolbox.run(algorithm, {**params, "INPUT": p}, overwrite=True)

    def exchange(fmt, crs=None):
        return lambda p: formats.read_orientations([p], fmt=fmt, crs=crs)

    def two_tables(which):
        def read(p):
            other = folder / ("coordinates.txt" if which == "descriptions" else "descriptions.txt")
            pair = (p, other) if which == "descriptions" else (other, p)
            read_two_tables(*pair, crs="EPSG:3003")
        return read

    return {
        "code file": ("code_file", read_code_file),
        "colour file": ("colour_file", read_colour_file),
        "restitution parameter file": ("restitution_parameters", read_restitution_parameters),
        "restitution ASCII": ("restitution_ascii", lambda p: read_ascii(p, crs="EPSG:3003")),
        "restitution DXF": ("restitution_dxf", lambda p: read_dxf(p, crs="EPSG:3003")),
        "two-table descriptions": ("two_table_descriptions", two_tables("descriptions")),
        "two-table coordinates": ("two_table_coordinates", two_tables("coordinates")),
        "OPK text": ("metashape_opk", lambda p: read_exterior_orientations(
            p, fmt="opk", angle_unit="deg")),
        "OpenSfM reconstruction.json": ("opensfm", exchange("opensfm")),
        "OpenSfM cameras.json": ("opensfm_cameras", exchange("opensfm_cameras")),
        "Orthority interior YAML": ("orthority_interior", exchange("orthority_interior")),
        "Orthority exterior GeoJSON": ("orthority_exterior", exchange("orthority_exterior")),
        "Orthority CSV": ("orthority_csv", exchange("csv", "EPSG:3003")),
        "Metashape XML": ("metashape_xml", exchange(
            "metashape", "+proj=tmerc +lon_0=11 +x_0=500000 +ellps=WGS84 +units=m")),
        "Metashape OPK text": ("metashape_opk", exchange("metashape_opk", "EPSG:32632")),
        "PAT-B": ("patb", exchange("patb", "EPSG:3003")),
        "ODM gcp_list.txt": ("gcp_list", lambda p: odm_gcp.read_gcp_list(p, "EPSG:32632")),
        "EXIF/XMP (drone JPEG)": ("exif", lambda p: exif.read_images([p])),
        "format detection": ("orthority_exterior", lambda p: formats.read_orientations([p])),
        "orientation file (auto)": ("orientation_csv", lambda p: read_exterior_orientations(
            p, where={"run": "strip1", "stage": "final"})),
        "Z-Map log": ("zmap_log", read_zmap_log),
        "Z-Map log (auto)": ("zmap_log", read_exterior_orientations),
        "fiducial CSV": ("fiducials_csv", fiducials),
        "image-point CSV": ("image_points_csv",
                            lambda p: image_measurements(p, None, "auto")),
        "project YAML": ("project_yaml", load_project),
        "parameter file": ("parameter_file", read_parameter_file),
        "transform JSON": ("transform_json", load_transform),
        "pipeline YAML": ("pipeline_yaml", pipeline),
        "control CSV": ("control_csv", read_control),
        "GNSS CSV": ("gnss_csv", read_centres),
        "IMU CSV": ("imu_csv", lambda p: read_attitudes(p, "rad")),
        "ground-point CSV": ("ground_csv", ground_points),
        "model coordinates CSV": ("models_csv", run(
            "orientation:models", CONTROL=folder / "control.csv", MODE="planimetric",
            OUTPUT=folder / "models.gpkg")),
        "rectification GCP CSV": ("gcps_csv", run(
            "rectify:estimate", CRS="EPSG:3003", MODEL="homography",
            OUTPUT=folder / "transform.json")),
    }


READERS = ["orientation file (auto)", "Z-Map log", "Z-Map log (auto)", "fiducial CSV",
           "image-point CSV", "project YAML", "parameter file", "transform JSON",
           "pipeline YAML", "code file", "colour file", "restitution parameter file",
           "restitution ASCII", "restitution DXF", "two-table descriptions",
           "two-table coordinates", "OPK text", "OpenSfM reconstruction.json",
           "OpenSfM cameras.json", "Orthority interior YAML", "Orthority exterior GeoJSON",
           "Orthority CSV", "Metashape XML", "Metashape OPK text", "PAT-B", "ODM gcp_list.txt",
           "EXIF/XMP (drone JPEG)", "format detection", "control CSV", "GNSS CSV", "IMU CSV",
           "ground-point CSV", "model coordinates CSV", "rectification GCP CSV"]


class Hang(Exception):
    """A read that outlived :data:`CASE_LIMIT_S`."""


def _alarm(signum, frame):
    raise Hang()


def _fuzz(seeds, reader: str, tmp_path: Path, mutations: int, budget_s: float) -> int:
    """Read ``mutations`` mutated copies of the reader's seed (within ``budget_s``); fail on
    any exception but a one-line ToolboxError, and on a read longer than CASE_LIMIT_S."""
    folder, files = seeds
    key, read = _readers(folder)[reader]
    seed = Path(files[key])
    data = seed.read_bytes()
    read(seed)  # the unmutated file reads
    rng = random.Random(reader)
    crashes = []
    started = time.monotonic()
    previous = signal.signal(signal.SIGALRM, _alarm)
    n = 0
    try:
        for n in range(mutations):
            if time.monotonic() - started > budget_s:
                break
            mutated = _mutate(data, rng)
            path = seed.parent / f"fuzz_{n}{seed.suffix}"  # beside the seed: relative paths work
            path.write_bytes(mutated)
            signal.setitimer(signal.ITIMER_REAL, CASE_LIMIT_S)
            try:
                read(path)
            except ToolboxError as exc:
                assert "\n" not in str(exc).strip() or reader.startswith("pipeline"), str(exc)
            except Hang:
                crashes.append(f"mutation {n}: hang (over {CASE_LIMIT_S} s)")
                (tmp_path / f"hang_{n}{seed.suffix}").write_bytes(mutated)
            except Exception as exc:  # noqa: BLE001 - the point of the test
                crashes.append(f"mutation {n}: {type(exc).__name__}: {str(exc)[:160]}")
                (tmp_path / f"crash_{n}{seed.suffix}").write_bytes(mutated)
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
                path.unlink()
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert not crashes, f"{reader}: {len(crashes)} crashes (inputs kept in {tmp_path}):\n" + \
        "\n".join(crashes[:10])
    return n + 1


@contextlib.contextmanager
def _libraries_quiet():
    """No log records or warnings from the readers' libraries: they quote the mutated bytes
    (ezdxf: lone surrogates, which a pytest-xdist worker cannot send back); the fuzz test is
    about exceptions only."""
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(logging.NOTSET)


@pytest.mark.parametrize("reader", READERS)
def test_only_toolbox_errors_escape(seeds, reader, tmp_path):
    with _libraries_quiet():
        _fuzz(seeds, reader, tmp_path, MUTATIONS_PER_READER, BUDGET_S)


@pytest.mark.slow
@pytest.mark.parametrize("reader", READERS)
def test_only_toolbox_errors_escape_slow(seeds, reader, tmp_path):
    """A few thousand mutations over all readers (TOOLBOX_FUZZ_MUTATIONS per reader)."""
    with _libraries_quiet():
        _fuzz(seeds, reader, tmp_path, SLOW_MUTATIONS_PER_READER, SLOW_BUDGET_S)
