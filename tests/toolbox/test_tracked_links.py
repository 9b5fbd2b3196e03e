"""No tracked symbolic link points outside the checkout or by an absolute path (one did: it
broke every other clone and the sdist)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                    reason="not a git checkout")
def test_tracked_symlinks_are_relative_and_inside():
    listing = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-s"], capture_output=True,
                             text=True, check=True).stdout.splitlines()
    assert len(listing) > 100
    links = [line.split("\t", 1)[1] for line in listing if line.startswith("120000 ")]
    for link in links:
        blob = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-p", f":{link}"],
                              capture_output=True, text=True, check=True).stdout
        assert not blob.startswith("/"), f"{link} -> {blob} (absolute)"
        target = (ROOT / link).parent / blob
        assert target.resolve().is_relative_to(ROOT.resolve()), f"{link} -> {blob} (outside)"
