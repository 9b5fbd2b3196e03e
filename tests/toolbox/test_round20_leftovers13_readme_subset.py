"""The README's `|subset=` example filters something: it read `|subset=z > 0` over the demo's
mass points, all of them above 287 m, so it kept all 4,000. The example is run as the README
gives it and the count it states is checked against a numpy count of the points' heights."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pyogrio

import toolbox
from toolbox.demo.samples import terrain

README = Path(__file__).resolve().parents[2] / "README.md"


def test_the_readme_subset_example_keeps_the_points_it_says(tmp_path):
    text = README.read_text()
    example = re.search(r'tin:delaunay --INPUT "demo_out/data/mass_points\.gpkg\|layerid=0\|'
                        r'subset=(\w+) > ([0-9.]+)"', text)
    assert example, "the README's subset example is gone"
    field, limit = example.group(1), float(example.group(2))
    made = terrain.make(tmp_path, {})
    z = pyogrio.read_dataframe(made["mass_points"], read_geometry=False)[field].to_numpy()
    expected = int(np.count_nonzero(z > limit))  # the independent count
    assert len(z) == 4000 and 0 < expected < len(z), expected  # the subset filters something
    result = toolbox.run("tin:delaunay", {
        "INPUT": f"{made['mass_points']}|layerid=0|subset={field} > {example.group(2)}",
        "OUTPUT": str(tmp_path / "tin_subset.gpkg")})
    assert result["STATISTICS"]["nodes"] == expected
    said = text[example.end():example.end() + 400]
    assert f"keeps the {expected:,} of the demo's 4,000 mass points above {example.group(2)} m" \
        in " ".join(said.split()), said
