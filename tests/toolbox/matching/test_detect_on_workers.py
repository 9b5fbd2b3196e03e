"""Tie-point detection through the executor: on a Dask worker the photo travels as its path
(no open dataset, lock or pixel copy), is read there, and the grey stretch the worker computed
comes back to the client, so the client's later reads (refinement windows) stretch a 16-bit photo
exactly as a local run does. The worker is simulated by a pickle round trip of each task."""

from __future__ import annotations

import pickle
import threading

import numpy as np
import rasterio

from toolbox.matching.block import BlockPhoto, TiePointOptions, detect_photos
from toolbox.matching.images import ImageSource


def _photo16(path) -> None:
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:300, 0:400]
    z = 20000 + 9000 * np.sin(x / 13.0) * np.cos(y / 17.0) + rng.normal(0, 800, (300, 400))
    with rasterio.open(path, "w", driver="GTiff", width=400, height=300, count=1,
                       dtype="uint16") as dst:
        dst.write(np.clip(z, 0, 65535).astype("uint16"), 1)


def test_image_source_pickles_without_its_handle_lock_or_pixels(tmp_path):
    _photo16(tmp_path / "a.tif")
    src = ImageSource.open(tmp_path / "a.tif")
    src.window(0, 0, 50, 50)  # holds the whole grey photo and sets the stretch
    assert src._grey_full is not None and src.stretch is not None
    copy = pickle.loads(pickle.dumps(src))
    assert copy._grey_full is None and copy._handle is None
    assert isinstance(copy._lock, type(threading.Lock())) and copy._lock is not src._lock
    assert (copy.path, copy.width, copy.height, copy.stretch) == \
        (src.path, src.width, src.height, src.stretch)
    np.testing.assert_array_equal(copy.window(10, 20, 30, 40), src.window(10, 20, 30, 40))


def test_detection_on_workers_is_the_local_one_and_hands_the_stretch_back(tmp_path,
                                                                          monkeypatch):
    paths = [tmp_path / "a.tif", tmp_path / "b.tif"]
    for p in paths:
        _photo16(p)
    opts = TiePointOptions(max_size=300, tile=300)
    local_photos = [BlockPhoto(p.stem, ImageSource.open(p)) for p in paths]
    local = list(detect_photos(local_photos, [0, 1], opts))

    seen = []

    def on_a_worker(func, tasks, executor):  # each task pickled as Dask does
        for task in tasks:
            seen.append(task)
            yield func(pickle.loads(pickle.dumps(task)))

    monkeypatch.setattr("toolbox.executor.map_tiles", on_a_worker)
    cluster = type("Dask", (), {"kind": "dask"})()
    remote_photos = [BlockPhoto(p.stem, ImageSource.open(p)) for p in paths]
    remote = list(detect_photos(remote_photos, [0, 1], TiePointOptions(
        max_size=300, tile=300, executor=cluster)))
    assert all(t.photo.photo is None and t.opts.executor is None for t in seen)
    for (k, f, s), (k2, f2, s2) in zip(local, remote, strict=True):
        assert (k, s, len(f)) == (k2, s2, len(f2)) and len(f) > 50
        np.testing.assert_array_equal(f.xy, f2.xy)
        np.testing.assert_array_equal(f.descriptors, f2.descriptors)
    for lp, rp in zip(local_photos, remote_photos, strict=True):
        assert rp.source.stretch == lp.source.stretch is not None  # the worker's, handed back
        np.testing.assert_array_equal(rp.source.window(5, 5, 64, 64),
                                      lp.source.window(5, 5, 64, 64))


def test_thumbnails_detected_on_workers_are_the_local_ones(tmp_path, monkeypatch):
    """The thumbnail pass (pairs without orientations or positions) on workers: the same
    thumbnails (from the detection level when the client would keep it, else a decimated read)
    and features as locally, and the stretch handed back."""
    paths = [tmp_path / "a.tif", tmp_path / "b.tif"]
    for p in paths:
        _photo16(p)
    opts = TiePointOptions(max_size=300, tile=300, thumbnail_size=120)
    for keep in (False, True):
        local_photos = [BlockPhoto(p.stem, ImageSource.open(p)) for p in paths]
        local = list(detect_photos(local_photos, [0, 1], opts, thumbnail=True, keep=keep))
        with monkeypatch.context() as m:
            m.setattr("toolbox.executor.map_tiles", lambda func, tasks, executor: (
                func(pickle.loads(pickle.dumps(t))) for t in tasks))
            remote_photos = [BlockPhoto(p.stem, ImageSource.open(p)) for p in paths]
            cluster = type("Dask", (), {"kind": "dask"})()
            remote = list(detect_photos(remote_photos, [0, 1], TiePointOptions(
                max_size=300, tile=300, thumbnail_size=120, executor=cluster),
                thumbnail=True, keep=keep))
        for (_, f, s), (_, f2, s2) in zip(local, remote, strict=True):
            assert s == s2 and len(f) == len(f2) > 10
            np.testing.assert_array_equal(f.descriptors, f2.descriptors)
        assert [p.source.stretch for p in remote_photos] == \
            [p.source.stretch for p in local_photos]
        assert all(p.level is None for p in remote_photos)  # nothing kept on the client
        assert all((p.level is not None) == keep for p in local_photos)


def test_a_worker_keeps_each_photo_once_across_refinement_tasks(tmp_path, monkeypatch):
    """Refinement batches on a worker share one copy of each photo (read whole once), keyed
    by its file and stretch; a photo written again, or another stretch, is another copy; at
    most WORKER_IMAGES are kept."""
    from toolbox.matching import block

    monkeypatch.setattr(block, "_WORKER_IMAGES", {})
    _photo16(tmp_path / "a.tif")
    src = ImageSource.open(tmp_path / "a.tif")
    src.window(0, 0, 8, 8)  # the stretch
    first = block.worker_image(pickle.loads(pickle.dumps(src)))
    first.window(0, 0, 8, 8)
    assert first._grey_full is not None  # read whole once
    assert block.worker_image(pickle.loads(pickle.dumps(src))) is first  # the next task
    other = pickle.loads(pickle.dumps(src))
    other.stretch = (0.0, 1000.0)
    assert block.worker_image(other) is other
    for i in range(block.WORKER_IMAGES):
        _photo16(tmp_path / f"b{i}.tif")
        block.worker_image(ImageSource.open(tmp_path / f"b{i}.tif"))
    assert len(block._WORKER_IMAGES) == block.WORKER_IMAGES
    assert all(kept is not first for kept in block._WORKER_IMAGES.values())  # the oldest
    assert first._grey_full is not None  # dropped, not closed: a running task may still read it
