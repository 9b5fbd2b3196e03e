"""Round 16, sweep "docs": what the help and the docs state is what a run does."""

import math

import pytest

import toolbox


def test_precision_without_project_edge_is_at_the_edge_of_a_23cm_frame(tmp_path):
    """The help: sigma X/Y "at the edge of the format (XI default: half the format width)".
    Without PROJECT the edge fields were the centre's (xi = eta = 0) in silence; now the edge of
    a standard 23 x 23 cm frame, by hand: m_b·sqrt((ξ·Z/(c·B))²·σp² + σξ²)."""
    out = toolbox.run("orientation:precision", {"PRINCIPAL_DISTANCE": 152, "BASE": 1520,
                                                "DISTANCE": 1520, "OUTPUT": tmp_path / "p.json"})
    (row,) = out["PRECISION"]
    mb, sp = 1520 / 0.152, 5e-6
    edge = mb * math.sqrt((0.115 * 1520 / (0.152 * 1520)) ** 2 * sp ** 2 + sp ** 2 / 2)
    assert row["xi_edge_mm"] == row["eta_edge_mm"] == 115.0
    assert row["sigma_x_edge_m"] == pytest.approx(edge, rel=1e-9)
    assert row["sigma_y_edge_m"] == pytest.approx(edge, rel=1e-9)
    assert row["sigma_x_centre_m"] == pytest.approx(mb * sp / math.sqrt(2), rel=1e-9)
    out = toolbox.run("orientation:precision", {"PRINCIPAL_DISTANCE": 152, "BASE": 1520,
                                                "DISTANCE": 1520, "XI": 50, "ETA": 0,
                                                "OUTPUT": tmp_path / "q.json"})
    (row,) = out["PRECISION"]
    assert (row["xi_edge_mm"], row["eta_edge_mm"]) == (50, 0)
    assert row["sigma_y_edge_m"] == pytest.approx(row["sigma_y_centre_m"])
