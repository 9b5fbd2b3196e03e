"""A warning logged on a worker thread of a run (ortho:batch opens its photos on the threads of
WORKERS) reaches the run's feedback and its JSON report, once each: the runner kept only its
own thread's (the EXIF-orientation warning of two photos reached the console only). Scoped by
run: a second run at the same time on another thread keeps its own warnings, not the other's."""

from __future__ import annotations

import json
import logging
import sys
import threading
from pathlib import Path

import numpy as np
import rasterio
import yaml
from PIL import Image

import toolbox
from tests.helpers_threads import run_in_threads

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402

SECOND = (scene.CENTRE[0] + 500.0, scene.CENTRE[1] - 80.0, scene.CENTRE[2] + 30.0)
EXIF = "has EXIF Orientation 6"


def turned_jpeg(path: Path, grey: np.ndarray) -> None:
    """``grey`` as a JPEG whose EXIF says "rotate 90 CW to view" (tag 6); GDAL keeps the grid."""
    image = Image.fromarray(grey)
    exif = image.getexif()
    exif[0x0112] = 6
    image.save(path, exif=exif, quality=95)
    with rasterio.open(path) as src:
        assert src.tags().get("EXIF_Orientation") == "6" and src.shape == grey.shape


def two_turned_photos(folder: Path):
    from toolbox.photogrammetry.synthetic import frame_photo, render_photo

    sc = scene.make_scene(folder)
    with rasterio.open(sc.photo_path) as src:
        turned_jpeg(folder / "p1.jpg", src.read(1))
    second = frame_photo(SECOND, (-0.01, 0.02, 0.35), width=scene.SIZE, height=scene.SIZE,
                         crs=scene.CRS)
    image = render_photo(second, sc.dem, sc.transform, sc.texture, dtype="uint8")
    turned_jpeg(folder / "p2.jpg", np.asarray(image).reshape(-1, scene.SIZE, scene.SIZE)[0])
    doc = yaml.safe_load(sc.project_path.read_text())
    doc["photos"][0]["image"] = "p1.jpg"
    keys = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    doc["photos"].append({"id": "p2", "camera": "synthetic", "image": "p2.jpg",
                          "exterior": dict(zip(keys, [*SECOND, -0.01, 0.02, 0.35], strict=True))})
    project = folder / "block.yaml"
    project.write_text(yaml.safe_dump(doc))
    return sc, project


def batch(folder: Path, sc, project: Path, feedback: toolbox.Feedback) -> None:
    toolbox.run("ortho:batch", {"PROJECT": project, "DEM": sc.dem_path, "CELL_SIZE": 25.0,
                                "OVERVIEWS": False, "FOLDER": str(folder / "orthos"),
                                "WORKERS": 2, "OUTPUT": folder / "block.json"},
                feedback=feedback, report=folder / "run.json")


def test_worker_thread_warnings_reach_feedback_and_report_once(tmp_path, caplog):
    sc, project = two_turned_photos(tmp_path)
    feedback = toolbox.Feedback()
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        batch(tmp_path, sc, project, feedback)
    # the photos were opened on the pool's threads, not the run's (what the fix is about)
    threads = {r.threadName for r in caplog.records if EXIF in r.getMessage()}
    assert threads and threading.current_thread().name not in threads, threads
    expected = sorted(f"{tmp_path / name} {EXIF}" for name in ("p1.jpg", "p2.jpg"))
    shown = sorted(w.split(": ", 1)[1].split(" (the view", 1)[0]
                   for w in feedback.warnings if EXIF in w)
    assert shown == expected, feedback.warnings
    report = json.loads((tmp_path / "run.json").read_text())["warnings"]
    assert sorted(w for w in report if EXIF in w) == sorted(w for w in feedback.warnings
                                                            if EXIF in w)


def test_two_runs_at_once_keep_their_own_worker_warnings(tmp_path):
    """The run on the second thread opens upright copies: none of the first run's warnings."""
    turned, upright = tmp_path / "turned", tmp_path / "upright"
    turned.mkdir()
    upright.mkdir()
    sc, project = two_turned_photos(turned)
    sc2 = scene.make_scene(upright)
    doc = yaml.safe_load(project.read_text())
    for photo in doc["photos"]:
        with rasterio.open(turned / photo["image"]) as src:
            Image.fromarray(src.read(1)).save(upright / photo["image"], quality=95)
    (upright / "block.yaml").write_text(yaml.safe_dump(doc))
    first, second = toolbox.Feedback(), toolbox.Feedback()
    run_in_threads(lambda: batch(upright, sc2, upright / "block.yaml", second),
                  lambda: batch(turned, sc, project, first))
    assert len([w for w in first.warnings if EXIF in w]) == 2, first.warnings
    assert not [w for w in second.warnings if EXIF in w], second.warnings
