"""PROJ database searches kept between runs (toolbox.io.crs.remembered): the identification of
a CRS without a code and the UTM zone of a point give the same answers from the user cache as
from PROJ, and a fresh process finds them there."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from pyproj import CRS

from toolbox.io import crs as crs_module

LOCAL_TM = ("+proj=tmerc +lat_0=0 +lon_0=9 +k=0.9996 +x_0=1500000 +y_0=0 +ellps=intl "
            "+towgs84=-104.1,-49.1,-9.9,0.971,-2.917,0.714,-11.68 +units=m +no_defs")


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    crs_module._stored_lookups.cache_clear()
    crs_module._authority_matches.cache_clear()
    yield tmp_path
    crs_module._stored_lookups.cache_clear()
    crs_module._authority_matches.cache_clear()


def test_identification_from_the_cache_equals_proj(fresh_cache):
    from toolbox.exchange.geodesy import utm_crs

    crs = CRS.from_proj4(LOCAL_TM)
    truth = [(m.auth_name, m.code) for m in crs.list_authority(auth_name="EPSG",
                                                                min_confidence=70)]
    first = crs_module.crs_authority(crs, 70, "EPSG")
    utm = utm_crs.__wrapped__(12.4, 43.3)
    stored = json.loads((fresh_cache / "photogrammetry-toolbox" /
                         crs_module.LOOKUP_CACHE).read_text())
    assert len(stored) == 2
    crs_module._stored_lookups.cache_clear()
    crs_module._authority_matches.cache_clear()
    assert crs_module.crs_authority(crs, 70, "EPSG") == first
    assert first == (truth[0] if truth else None)
    assert utm_crs.__wrapped__(12.4, 43.3) == utm == CRS.from_epsg(32633)
    # a fresh process reads the answers and does not ask PROJ's database again
    code = ("import toolbox.io.crs as c, pyproj\n"
            "calls = []\n"
            "orig = pyproj.CRS.list_authority\n"
            "pyproj.CRS.list_authority = lambda self, **k: calls.append(1) or orig(self, **k)\n"
            f"print(c.crs_authority(pyproj.CRS.from_proj4({LOCAL_TM!r}), 70, 'EPSG'), len(calls))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**__import__("os").environ, "XDG_CACHE_HOME": str(fresh_cache)})
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-1] == "0"


def test_an_unwritable_cache_is_left_alone(fresh_cache, monkeypatch):
    (fresh_cache / "photogrammetry-toolbox").write_text("a file where the folder should be")
    crs_module.remember("question", [1, 2])  # no error
    assert crs_module.remembered("question") == [1, 2]  # in this process still
