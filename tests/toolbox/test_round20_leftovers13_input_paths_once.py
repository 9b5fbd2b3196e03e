"""A run works out its input files (every sidecar, a VRT's sources, a project's files: a few
stat calls each) once: validate() did it for the output checks, the planned-file checks and the
run again for the run's protection of its inputs (twice a run, three times with a run report).
At the commit, the protected files' inodes are stat'ed once, not once per output that exists."""

from __future__ import annotations

import os

import numpy as np
import rasterio
from affine import Affine

import toolbox
import toolbox.runner as runner
import toolbox.runner.paths as paths


def dem(path):
    with rasterio.open(path, "w", driver="GTiff", width=30, height=20, count=1, dtype="float32",
                       crs="EPSG:3003", transform=Affine(2, 0, 1688000.0, 0, -2, 4800000.0),
                       nodata=-9999.0) as dst:
        dst.write(np.add.outer(np.arange(20.0), np.arange(30.0)).astype("float32"), 1)
    return path


def counted(monkeypatch):
    calls = []
    original = paths.input_paths

    def input_paths(alg_cls, values):
        calls.append(alg_cls.id)
        return original(alg_cls, values)

    monkeypatch.setattr(paths, "input_paths", input_paths)
    monkeypatch.setattr(runner, "input_paths", input_paths)
    return calls


def test_a_run_works_out_its_input_paths_once(tmp_path, monkeypatch):
    source = dem(tmp_path / "dem.tif")
    calls = counted(monkeypatch)
    toolbox.run("dem:hillshade", {"INPUT": str(source), "OUTPUT": str(tmp_path / "h.tif")})
    assert calls == ["dem:hillshade"]
    calls.clear()
    toolbox.run("dem:hillshade", {"INPUT": str(source), "OUTPUT": str(tmp_path / "h.tif")},
                overwrite=True, report=tmp_path / "run.json")
    assert calls == ["dem:hillshade"]
    assert (tmp_path / "run.json").exists()


def test_the_commit_stats_the_protected_files_once(tmp_path, monkeypatch):
    source = dem(tmp_path / "dem.tif")
    out = tmp_path / "h.tif"
    report = tmp_path / "run.json"
    toolbox.run("dem:hillshade", {"INPUT": str(source), "OUTPUT": str(out)}, report=report)
    protected = set(paths.input_paths(toolbox.registry.get("dem:hillshade"),
                                      {"INPUT": source, "OUTPUT": out}))
    assert source.resolve() in protected and len(protected) > 5  # the sidecars too
    seen = []
    original = os.stat

    def stat(path, *args, **kwargs):
        seen.append(str(path))
        return original(path, *args, **kwargs)

    monkeypatch.setattr(os, "stat", stat)
    # the output and the report exist: the commit checks each is no input by inode too
    toolbox.run("dem:hillshade", {"INPUT": str(source), "OUTPUT": str(out)}, overwrite=True,
                report=report)
    monkeypatch.undo()
    sidecars = {str(p) for p in protected if not p.exists()}
    assert sidecars
    # each missing sidecar: once for the run's input stamps, once for the commit's inodes
    assert max(seen.count(s) for s in sidecars) <= 2, sorted(
        (seen.count(s), s) for s in sidecars)[-3:]
    assert out.exists()


def test_an_input_hard_linked_as_an_output_is_still_found_with_the_inodes_cached(tmp_path):
    """The inode check still holds with the inodes stat'ed once (the output replaced by a hard
    link to the input after validation is what only the commit can see)."""
    from toolbox.io.staging import _is_protected, _ProtectedInodes

    source = dem(tmp_path / "dem.tif")
    link = tmp_path / "link.tif"
    os.link(source, link)
    other = dem(tmp_path / "other.tif")
    protected = {source.resolve(), tmp_path / "dem.tfw"}
    inodes = _ProtectedInodes(protected)
    assert _is_protected(link, protected, inodes)
    assert inodes.known == {(source.stat().st_dev, source.stat().st_ino)}
    assert not _is_protected(other, protected, inodes)
    assert not _is_protected(tmp_path / "none.tif", protected, inodes)
    assert _is_protected(link, protected)  # without a cache, as before
