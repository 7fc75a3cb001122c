"""The bad-start check (``RecoverySettings.bad_start``, :mod:`.estimators.start_check`).

Known answers on ``paper3d``: the first 0.5 s of readings 60 deg off on roll and pitch
(samples 0-9), right from sample 10: every estimator (compiled and CasADi EKF, UKF, MHE
on both backends) restarts exactly once, at sample 11 (the second inconsistent reading),
and is within 1 cm from there on, while without the check the filters overshoot for
several samples. On clean data the check never fires and every estimate is bit-for-bit
the one without it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from estimator_helpers import recovery_estimators
from numpy.testing import assert_array_equal

from continuum_mhe.cli import main
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.start_check import SAMPLES
from continuum_mhe.io.csv_files import write_measurements
from continuum_mhe.reproduce.beyond import BeyondSpec, run_beyond
from continuum_mhe.settings import RecoverySettings
from continuum_mhe.simulation.scenarios import simulate

IDS = ["ekf-c", "ekf", "ukf", "mhe-fast", "mhe-ipopt"]
FIRST_GOOD = 10  # samples 0-9 (t < 0.5 s at 20 Hz) are off


estimators = recovery_estimators


def bad_start_recording(duration: float = 3.0):
    rec = simulate("paper3d", duration=duration, seed=0)
    z = rec.z.copy()
    z[:FIRST_GOOD] += math.radians(60.0)
    z[:, 1] = np.clip(z[:, 1], -math.pi / 2, math.pi / 2)
    return rec, z


@pytest.mark.parametrize("index", range(5), ids=IDS)
def test_a_bad_start_is_noticed_and_restarted_from_the_readings(index: int) -> None:
    rec, z = bad_start_recording()
    est = estimators(RecoverySettings(bad_start=2.0))[index]
    s = est.run(rec.t, z)
    at = FIRST_GOOD + SAMPLES - 1
    assert list(np.flatnonzero(s.status == "reset")) == [at] and est.bad_starts == 1
    tip = np.linalg.norm(s.output[:, :3] - rec.truth[:, :3], axis=1)
    assert tip[at:].max() < 0.01  # m: back on the robot from the restart on
    plain = estimators(RecoverySettings())[index].run(rec.t, z)
    assert "reset" not in set(plain.status)  # off by default in the library
    late = np.linalg.norm(plain.output[at:, :3] - rec.truth[at:, :3], axis=1)
    assert late.max() > 0.015  # without it: still walking back after the restart time


@pytest.mark.parametrize("index", range(5), ids=IDS)
def test_clean_data_are_unchanged_by_the_check(index: int) -> None:
    rec = simulate("paper3d", duration=4.0, seed=5)
    on = estimators(RecoverySettings(bad_start=10.0))[index]
    s_on = on.run(rec.t, rec.z)
    s_off = estimators(RecoverySettings())[index].run(rec.t, rec.z)
    assert on.bad_starts == 0
    assert_array_equal(s_on.output, s_off.output)
    assert_array_equal(s_on.status, s_off.status)


def test_the_reproduce_group_measures_off_and_on() -> None:
    out = run_beyond(BeyondSpec("bad-start", 0, 10.0))["methods"]
    for m in ("mhe", "ekf", "ukf"):
        assert out[f"{m} on"]["clean_fired"] == 0 and out[f"{m} on"]["clean_diff_mm"] == 0
        assert out[f"{m} on"]["tip_mean_mm"] < out[f"{m} off"]["tip_mean_mm"]


def test_bad_start_option(tmp_path, capsys) -> None:
    with pytest.raises(ValueError, match="bad_start"):
        RecoverySettings(bad_start=-1.0)
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "1"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--bad-start", "-1"]) == 2
    assert "error: --bad-start -1.0 is outside its valid range" in capsys.readouterr().err
    assert not est.exists()
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0  # default on
    capsys.readouterr()
    rec, z = bad_start_recording()  # the restart is said in the summary line
    write_measurements(meas, rec.t, z)
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    assert "restarted 1 time(s) after readings inconsistent with the start" in (
        capsys.readouterr().err
    )


def test_not_checked_where_the_covariance_is_a_weight(monkeypatch) -> None:
    """The paper formulation's W is a weight, not a noise model: its NIS is not a test."""
    from continuum_mhe.estimators.start_check import StartCheck
    from continuum_mhe.model.registry import make_formulation

    def never(*args, **kwargs):
        raise AssertionError("the bad-start check ran")

    monkeypatch.setattr(StartCheck, "inconsistent", never)
    rec, z = bad_start_recording()
    est = make_estimator("ekf", make_formulation("paper"), recovery=RecoverySettings(bad_start=2))
    assert "reset" not in set(est.run(rec.t, z).status) and est.bad_starts == 0
    with pytest.raises(AssertionError, match="check ran"):  # the bend formulation is checked
        estimators(RecoverySettings(bad_start=2))[0].run(rec.t, z)
