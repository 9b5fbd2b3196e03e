"""Fixtures of the mosaic tests: the demo's standard pair of orthos and its seamlines (built once
per test module, in :mod:`mosaic_scene`)."""

import mosaic_scene
import pytest


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    return mosaic_scene.standard_pair(tmp_path_factory)


@pytest.fixture(scope="module")
def seams(tmp_path_factory):
    return mosaic_scene.standard_seams(tmp_path_factory)
