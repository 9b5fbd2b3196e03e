"""orientation:control given a DEM but no ORTHO: the DEM only casts the orthophoto's chip into
the photo (``help``: "DEM: with ORTHO"), so alone it did nothing, in silence (exit 0, a template
of predictions as without it). It is now refused with one line naming DEM and ORTHO, exit 2,
and nothing written (as MEASURED without ORTHO)."""

from __future__ import annotations

from test_control_ortho import scene  # noqa: F401  (the module's scene, reused)


def test_control_dem_without_ortho_is_refused(scene, tmp_path):  # noqa: F811
    from conftest import run_cli

    dem = scene["folder"] / "dem.tif"
    before = dem.read_bytes()
    res = run_cli("run", "orientation:control", "--PROJECT", scene["project"], "--CONTROL",
                  scene["control"], "--DEM", dem, "--OUTPUT", tmp_path / "template.csv",
                  "--CHIPS", tmp_path / "chips")
    assert res.returncode == 2, res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert line == (f"toolbox: error: DEM '{dem}' needs ORTHO (the DEM casts the orthophoto's "
                    "chip into the photo; without ORTHO nothing is matched): give ORTHO or "
                    "leave DEM out"), line
    assert "Traceback" not in res.stderr
    assert not (tmp_path / "template.csv").exists() and not (tmp_path / "chips").exists()
    assert dem.read_bytes() == before
