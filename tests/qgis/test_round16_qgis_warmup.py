"""Round 16 (misc2): PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP=0 must not disable the plugin's warm-up."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

PLUGIN = Path(__file__).resolve().parents[2] / "qgis_plugin"
sys.path.insert(0, str(PLUGIN))
from photogrammetry_toolbox import toolbox_cli  # noqa: E402


@pytest.mark.parametrize("value, disabled", [
    (None, False), ("", False), ("0", False), ("false", False), ("no", False),
    ("1", True), ("true", True), ("YES", True), (" 1 ", True)])
def test_no_warmup_variable_accepts_only_1_true_yes(monkeypatch, value, disabled):
    if value is None:
        monkeypatch.delenv("PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP", raising=False)
    else:
        monkeypatch.setenv("PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP", value)
    assert toolbox_cli.warmup_disabled() is disabled


def test_provider_decides_warmup_through_the_helper():
    source = (PLUGIN / "photogrammetry_toolbox" / "provider.py").read_text()
    assert "warmup_disabled()" in source
    assert 'environ.get("PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP")' not in source
