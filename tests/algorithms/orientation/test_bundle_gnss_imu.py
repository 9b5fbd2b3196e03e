"""orientation:bundle with GNSS centres carrying a shift per strip and IMU attitudes (degrees)
carrying a boresight, on the sample block (truth: the synthetic block it is made from); GNSS/IMU
observations made with scipy's rotations; the bad-input contract of the new parameters."""

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_bundle import _bad, _params, _write

import toolbox
from toolbox.demo.samples.bundle_block import make
from toolbox.triangulation.synthetic import SyntheticBlockSpec, make_block

SHIFT = {"1": np.array([0.6, -0.8, 1.0]), "2": np.array([-0.7, 0.5, -0.9])}
BORESIGHT_DEG = np.array([0.10, -0.08, 0.15])


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    return make(tmp_path_factory.mktemp("bundle_sample"), {})


def _files(tmp_path):
    truth = make_block(SyntheticBlockSpec(digital=True, seed=7)).project
    rng = np.random.default_rng(11)
    gnss = [["photo", "X", "Y", "Z", "strip"]]
    imu = [["photo", "omega", "phi", "kappa"]]
    for pid, p in truth.photos.items():
        strip = pid.split("_")[0]
        x, y, z = np.asarray(p.exterior.centre) + SHIFT[strip] + rng.normal(0, 0.02, 3)
        gnss.append([pid, f"{x:.4f}", f"{y:.4f}", f"{z:.4f}", strip])
        e = p.exterior
        r = Rotation.from_euler("XYZ", [e.omega, e.phi, e.kappa]) * \
            Rotation.from_euler("XYZ", np.radians(BORESIGHT_DEG))
        angles = np.degrees(r.as_euler("XYZ")) + rng.normal(0, 0.003, 3)
        imu.append([pid, *[f"{a:.6f}" for a in angles]])
    return _write(tmp_path / "gnss.csv", gnss), _write(tmp_path / "imu.csv", imu)


def test_gnss_shift_per_strip_and_imu_boresight_through_the_algorithm(sample, tmp_path):
    gnss, imu = _files(tmp_path)
    out = toolbox.run("orientation:bundle", _params(
        sample, tmp_path, GNSS=gnss, GNSS_SIGMA_XY=0.02, GNSS_SIGMA_Z=0.02, GNSS_SHIFT=True,
        IMU=imu, IMU_SIGMA=0.003, BORESIGHT=True))
    assert 0.8 < out["STATISTICS"]["sigma0"] < 1.25
    gi = json.loads((tmp_path / "bundle.json").read_text())["summary"]["gnss_imu"]
    for row in gi["gnss_shift"]["strips"]:
        for k, a in enumerate("XYZ"):
            assert abs(row[a] - SHIFT[row["strip"]][k]) < 4 * row[f"std_{a}"]
            assert row[f"std_{a}"] < 0.25  # the 0.5-1 m shifts are really measured
    bore = gi["imu"]["boresight"]
    for k, n in enumerate(("omega", "phi", "kappa")):
        assert abs(np.degrees(bore[n]) - BORESIGHT_DEG[k]) < 4 * np.degrees(bore[f"std_{n}"])
        assert np.degrees(bore[f"std_{n}"]) < 0.01


def test_boresight_without_imu_and_shift_without_gnss_are_refused(sample, tmp_path):
    _bad(sample, tmp_path, "BORESIGHT.*IMU", BORESIGHT=True)
    _bad(sample, tmp_path, "GNSS_DRIFT.*GNSS", GNSS_DRIFT=True)


def test_imu_sigma_not_positive_is_refused(sample, tmp_path):
    _, imu = _files(tmp_path)
    rows = [r.split(",") for r in imu.read_text().splitlines()]
    rows[0].append("sigma")
    for r in rows[1:]:
        r.append("0")
    _bad(sample, tmp_path, "sigma must be > 0", IMU=_write(tmp_path / "bad.csv", rows))


@pytest.mark.parametrize("unit", ["rad", "gon"])
def test_imu_angles_in_another_unit_than_declared_are_refused(sample, tmp_path, unit):
    """The IMU file is in degrees; declared rad or gon, the angles contradict the block's
    approximate orientations while read as degrees they agree: one line naming the unit."""
    _, imu = _files(tmp_path)
    _bad(sample, tmp_path, f"IMU_ANGLE_UNIT.*is {unit}.*give IMU_ANGLE_UNIT deg", IMU=imu,
         IMU_ANGLE_UNIT=unit)


# round 15 (sweep_numerics): GNSS times far from 0
DRIFT = {"1": np.array([0.01, 0.02, -0.01]), "2": np.array([-0.02, 0.01, 0.015])}


def _gnss_with_drift(path, t0):
    """GNSS centres of the sample block's truth with a shift and a drift per strip, 4 s between
    photos from ``t0`` (0, or POSIX seconds)."""
    import csv

    truth = make_block(SyntheticBlockSpec(digital=True, seed=7)).project
    rng = np.random.default_rng(11)
    rows = [["photo", "X", "Y", "Z", "strip", "time"]]
    for k, (pid, p) in enumerate(truth.photos.items()):
        strip, t = pid.split("_")[0], 4.0 * k
        xyz = np.asarray(p.exterior.centre) + SHIFT[strip] + DRIFT[strip] * t
        xyz += rng.normal(0, 0.02, 3)
        rows.append([pid, *(f"{v:.4f}" for v in xyz), strip, repr(t0 + t)])
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return path


def test_gnss_shift_and_drift_with_posix_times(sample, tmp_path):
    """GNSS times as POSIX seconds (1.7e9) made the shift and drift columns parallel: refused as
    'near-singular ... weak geometry' (exit 2). Now each strip is solved about its mean time and
    the shift reported at that time: it equals the true shift + drift x (at_time - t0)."""
    t0 = 1.7e9
    out = toolbox.run("orientation:bundle", _params(
        sample, tmp_path, GNSS=_gnss_with_drift(tmp_path / "gnss.csv", t0), GNSS_SIGMA_XY=0.02,
        GNSS_SIGMA_Z=0.02, GNSS_SHIFT=True, GNSS_DRIFT=True))
    assert 0.8 < out["STATISTICS"]["sigma0"] < 1.25
    gi = json.loads((tmp_path / "bundle.json").read_text())["summary"]["gnss_imu"]
    for row in gi["gnss_shift"]["strips"]:
        dt = row["at_time"] - t0
        assert 0 <= dt <= 28
        expected = SHIFT[row["strip"]] + DRIFT[row["strip"]] * dt
        for k, a in enumerate("XYZ"):
            assert abs(row[a] - expected[k]) < 4 * row[f"std_{a}"]
            assert row[f"std_{a}"] < 0.25
