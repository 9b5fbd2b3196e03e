"""Fuzz every text reader with seeded mutations of real files: only ToolboxError may escape.

Seeds are the Siena case-study files and the demo's sample data (orientation CSV, Z-Map logs,
fiducial and image-point CSVs, the project YAML, the topology parameter file, a transform JSON
written by rectify:estimate, a pipeline). Each mutation is the kind of damage files really
suffer: a truncation, a deleted or doubled line, a line with one field more, a number turned into
text, a non-UTF-8 byte, a NUL, swapped lines, a YAML/JSON structure broken. Deterministic (seeded)
and bounded: a fixed number of mutations per reader and a time budget.
"""

from __future__ import annotations

import random
import re
import time
from pathlib import Path

import pytest
import trust_data

import toolbox
from toolbox.errors import ToolboxError

MUTATIONS_PER_READER = 100
BUDGET_S = 2.0  # per reader


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
    return folder, {"orientation_csv": siena / "exterior_orientation.csv",
                    "zmap_log": siena / "zmap_strip1.log",
                    "fiducials_csv": made["siena_fiducials"],
                    "image_points_csv": made["siena_control_image_points"],
                    "project_yaml": made["siena_project"],
                    "camera_yaml": siena / "camera.yaml",
                    "parameter_file": made["linework_parameters"],
                    "transform_json": transform,
                    "pipeline_yaml": pipeline}


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

    return {
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
    }


READERS = ["orientation file (auto)", "Z-Map log", "Z-Map log (auto)", "fiducial CSV",
           "image-point CSV", "project YAML", "parameter file", "transform JSON",
           "pipeline YAML"]


@pytest.mark.parametrize("reader", READERS)
def test_only_toolbox_errors_escape(seeds, reader, tmp_path):
    folder, files = seeds
    key, read = _readers(folder)[reader]
    seed = Path(files[key])
    data = seed.read_bytes()
    read(seed)  # the unmutated file reads
    rng = random.Random(reader)
    crashes = []
    started = time.monotonic()
    for n in range(MUTATIONS_PER_READER):
        if time.monotonic() - started > BUDGET_S:
            break
        mutated = _mutate(data, rng)
        path = seed.parent / f"fuzz_{n}{seed.suffix}"  # beside the seed: relative paths work
        path.write_bytes(mutated)
        try:
            read(path)
        except ToolboxError as exc:
            assert "\n" not in str(exc).strip() or reader.startswith("pipeline"), str(exc)
        except Exception as exc:  # noqa: BLE001 - the point of the test
            crashes.append(f"mutation {n}: {type(exc).__name__}: {str(exc)[:160]}")
            (tmp_path / f"crash_{n}{seed.suffix}").write_bytes(mutated)
        finally:
            path.unlink()
    assert not crashes, f"{reader}: {len(crashes)} crashes (inputs kept in {tmp_path}):\n" + \
        "\n".join(crashes[:10])
