"""The bad-start check (``RecoverySettings.bad_start``, :mod:`.estimators.start_check`).

Known answers on ``paper3d``: the first 0.5 s of readings 60 deg off on roll and pitch
(samples 0-9), right from sample 10: every estimator (compiled and CasADi EKF, UKF, MHE
on both backends) restarts exactly once, at sample 11 (the second inconsistent reading),
and is within 1 cm from there on, while without the check the filters overshoot for
several samples. On clean data the check never fires and every estimate is bit-for-bit
the one without it.

An IMU back after a silence (two-section robot, ``spatial``): no estimate after its
return is ``ok`` more than 5 of its own standard deviations off, with the check off (the
estimate is held ``uncertain`` until the returned readings agree with it) and on (it
also restarts the EKF from the returned reading).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.stats
from estimator_helpers import bare, recovery_estimators
from numpy.testing import assert_array_equal
from scipy.optimize import brentq
from tendon_helpers import shipped_recording

from continuum_mhe.cli import main
from continuum_mhe.estimators import make_estimator, start_check
from continuum_mhe.estimators.base import Inference, Measurement, Status
from continuum_mhe.estimators.run_notices import restarts_notice
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.estimators.start_check import SAMPLES
from continuum_mhe.io.estimate_csv import write_measurements
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.reproduce.beyond import BeyondSpec, run_beyond
from continuum_mhe.results import Diagnostics
from continuum_mhe.settings import RecoverySettings
from continuum_mhe.simulation.scenarios import simulate, simulate_robot

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
    est = estimators(bare(bad_start=2.0))[index]
    s = est.run(rec.t, z)
    at = FIRST_GOOD + SAMPLES - 1
    assert list(np.flatnonzero(s.status == "reset")) == [at] and est.diagnostics.bad_starts == 1
    # the restart fits one reading: not ok until the next two agree with it
    assert list(s.status[at + 1 : at + 3]) == ["uncertain", "ok"]
    tip = np.linalg.norm(s.output[:, :3] - rec.truth[:, :3], axis=1)
    assert tip[at:].max() < 0.01  # m: back on the robot from the restart on
    plain = estimators(bare())[index].run(rec.t, z)
    assert "reset" not in set(plain.status)  # without it
    late = np.linalg.norm(plain.output[at:, :3] - rec.truth[at:, :3], axis=1)
    assert late.max() > 0.015  # without it: still walking back after the restart time


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_no_row_after_a_forced_restart_is_ok_before_readings_confirm_it(
    tmp_path: Path, method: str
) -> None:
    """The shipped ``spatial`` rod (raw IMUs; its tip twists 120 degrees about the
    tangent, which the PCC model cannot follow) restarts about 200 times on readings
    that contradict the estimate. No ``ok`` row is 50 mm off, the sample after a restart's
    fit of one reading included (t = 1.44 s, MHE, 150 mm off if it were ``ok``)."""
    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    out = tmp_path / "e.csv"
    argv = ["estimate", str(data / "spatial_raw.csv"), "--robot", "two-section",
            "--method", method, "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    est, truth = read_state_table(out), read_state_table(data / "spatial_truth.csv")
    tip = [est.names.index(c) for c in "xyz"]
    off = np.linalg.norm(
        est.values[:, tip] - truth.values[:, [truth.names.index(c) for c in "xyz"]], axis=1
    )
    assert np.count_nonzero(est.status == "reset") > 100
    assert np.all(off[est.status == "ok"] < 0.05)


def test_many_restarts_say_the_readings_do_not_fit_the_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording of CSV readings on which more than 5 % of the samples restart the
    estimator (the shipped ``spatial`` rod, raw IMUs: its backbone twists, which the
    PCC model cannot follow) ends with one warning naming the file and the share; its
    readings are inconsistent too, and what to check in the robot file is said once, in
    the warning on inconsistent estimates that follows, which the restarts' warning
    points to; the planar S (no restart) has none."""
    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    for name, warned in (("spatial_raw.csv", True), ("planar-s_raw.csv", False)):
        capsys.readouterr()
        argv = ["estimate", str(data / name), "--robot", "two-section", "--method", "ekf",
                "-o", str(tmp_path / f"{name}.est.csv")]  # fmt: skip
        assert main(argv) == 0
        err = capsys.readouterr().err
        said = [ln for ln in err.splitlines() if "restarted the estimator" in ln]
        if not warned:
            assert said == []
            continue
        assert len(said) == 1
        head, share = said[0].split(" samples (")
        restarts, samples = (int(v) for v in head.rsplit(": ", 1)[1].split(" of "))
        assert head.startswith(f"continuum-mhe: warning: {data / name}: ")
        assert samples == 601 and restarts > 0.05 * samples
        assert share.startswith(f"{100 * restarts / samples:.0f} %) restarted the estimator")
        assert said[0].endswith(
            "the readings do not fit the model of the robot (what to check: the warning on "
            "inconsistent estimates, which follows)"
        )
        lines = err.splitlines()
        follows = lines[lines.index(said[0]) + 1 :]
        assert any(" are inconsistent: " in ln for ln in follows)
        assert err.count("check the robot file against the robot (the IMUs' order") == 1


def test_the_restarts_warning_lists_the_causes_where_no_other_warning_does() -> None:
    """Without the warning on inconsistent estimates after it, the restarts' warning says
    what to check itself; with it, it points there."""
    alone = restarts_notice(601, 200)
    assert alone is not None
    assert alone.endswith(
        "the readings do not fit the model of the robot; check the robot file against the "
        "robot (the IMUs' order, their mount_rpy and at, the sections' lengths; check-robot "
        "lists them), or the robot does what the model cannot follow (a backbone that "
        "twists about itself)"
    )
    pointing = restarts_notice(601, 200, causes_follow=True)
    assert pointing is not None and "check the robot file" not in pointing
    assert pointing.endswith(
        "(what to check: the warning on inconsistent estimates, which follows)"
    )
    assert restarts_notice(601, 30, causes_follow=True) is None  # 5 % or less: not said


def test_a_burst_of_wild_readings_does_not_count_as_a_held_back_chain() -> None:
    """A formulation whose bad-start restarts stop after three in a row: a burst of
    four wild readings restarts three times (on it, within it, after it); no restart is
    held back, so ``bad_start_chains`` stays 0 (it counts the chains in which the check
    held one back, as ``estimate``'s "stopped restarting" says). From the second restart
    of the chain the rows are ``uncertain`` until the last one has held for the
    probation time (2 s), and ``ok`` after it."""
    from dataclasses import dataclass

    from continuum_mhe.model.bend import BendFormulation

    @dataclass(frozen=True)
    class Chained(BendFormulation):
        bad_start_chain = 3

    rec = simulate("paper3d", duration=4.0, seed=1)
    z = rec.z.copy()
    z[20:24] = np.random.default_rng(1).uniform(-1.5, 1.5, size=(4, 2))
    est = make_estimator("ekf", Chained())
    s = est.run(rec.t, z)
    assert est.diagnostics.bad_starts == 3
    assert est.diagnostics.bad_start_chains == 0
    restarts = np.flatnonzero(s.status == "reset")
    assert list(restarts) == [21, 23, 25]
    held = rec.t > rec.t[25] + 2.0 + 1e-9  # the chain's end: its last restart held
    assert set(s.status[26:][~held[26:]]) == {"uncertain"}
    assert set(s.status[held]) == {"ok"} and held.sum() > 10


# --- the end of a held-back chain -------------------------------------------------------
@dataclass(frozen=True)
class ChainOfThree(BendFormulation):
    """The bend formulation whose bad-start restarts stop after three in a row."""

    bad_start_chain = 3


STILL = (0.2, 0.3)  # rad: roll and pitch of the robot at rest
#: readings that contradict each restart's fit of the one before: a restart on every
#: second of them
SWING = ((0.6, 0.6), (-0.6, -0.6))
BEYOND = (2.9, 0.0)  # rad: a roll that carries the bend past theta_max + 1 rad
NONE = (math.nan, math.nan)
#: samples of the middle stretch between the two swings (1.2 s at 20 Hz)
MIDDLE = 24
#: the first sample after the middle
AFTER = 20 + 2 * 5 + MIDDLE
#: the chain's restarts; the check holds back the one after them
FIRST_CHAIN = [21, 23, 25]
#: the probation time (s): the chain's last restart (1.25 s) is held back beyond the
#: recording's end (3.45 s), so only the event ends the chain
PROBATION = 4.0


def chain_run(middle: list[tuple[float, float]], **recovery: Any) -> tuple[list[int], Diagnostics]:
    """The compiled EKF of :class:`ChainOfThree` (``bare(bad_start=PROBATION,
    **recovery)``) on 20 Hz readings: 1 s at rest, 0.5 s of ``SWING`` (restarts at
    ``FIRST_CHAIN``, then held back), the ``MIDDLE`` readings ``middle`` and 0.8 s of
    ``SWING`` again; returns the samples of status ``reset`` and the diagnostics."""
    assert len(middle) == MIDDLE
    z = np.array([STILL] * 20 + [*SWING] * 5 + middle + [*SWING] * 8)
    t = 0.05 * np.arange(len(z))
    est = make_estimator("ekf", ChainOfThree(), recovery=bare(bad_start=PROBATION, **recovery))
    s = est.run(t, z)
    assert s.diagnostics is not None
    return [int(i) for i in np.flatnonzero(s.status == "reset")], s.diagnostics


def assert_held_back(resets: list[int], d: Diagnostics) -> None:
    """The check held the chain back to the end: no restart after its three."""
    assert resets == FIRST_CHAIN
    assert (d.bad_starts, d.bad_start_chains, d.restarts, d.gap_resets) == (3, 1, 0, 0)


def assert_chained_again(resets: list[int], d: Diagnostics, restarts: list[int]) -> None:
    """The chain ended: the swing after the middle restarts at ``restarts`` (a new chain
    of three bad starts, held back in turn)."""
    assert resets == FIRST_CHAIN + restarts
    assert (d.bad_starts, d.bad_start_chains) == (6, 2)


def test_a_held_back_chain_lasts_the_probation_time_of_its_last_restart() -> None:
    """Readings that swing from 1 s to the end of the probation time (2 s) of the
    chain's last restart (1.25 s, sample 25): the check holds back every restart after
    the three, to the last sample (3.25 s). A chain also ends when the last restart
    holds through its probation time; the check is closed from then on, and every
    event that opens it again ends the chain too (the tests below)."""
    z = np.array([STILL] * 20 + [*SWING] * 23)
    t = 0.05 * np.arange(len(z))
    assert t[-1] == pytest.approx(1.25 + 2.0)
    est = make_estimator("ekf", ChainOfThree(), recovery=bare(bad_start=2.0))
    s = est.run(t, z)
    assert list(np.flatnonzero(s.status == "reset")) == FIRST_CHAIN
    assert (est.diagnostics.bad_starts, est.diagnostics.bad_start_chains) == (3, 1)
    assert set(s.status[26:]) == {"inconsistent"}


def test_a_gap_reset_ends_a_held_back_chain() -> None:
    """No reading for 1.2 s after a held-back chain, the gap reset 1 s: the first
    reading after the gap restarts the estimator (sample 54) and the swing after it
    restarts three times more, a second chain; at rest instead of the gap, the chain
    stays held back."""
    resets, d = chain_run([NONE] * MIDDLE, gap_reset=1.0)
    assert d.gap_resets == 1 and d.restarts == 0
    assert_chained_again(resets, d, [AFTER, AFTER + 2, AFTER + 4, AFTER + 6])
    assert_held_back(*chain_run([STILL] * MIDDLE, gap_reset=1.0))


def test_a_restart_of_another_kind_ends_a_held_back_chain() -> None:
    """Four readings of a roll that carries the bend out of the workspace after a
    held-back chain: the estimate diverges at the last of them (sample 53) and
    restarts, and the swing after it restarts three times more, a second chain; at
    rest instead, the chain stays held back. (A numerical failure and a covariance
    beyond the workspace restart the same way as a divergence.)"""
    resets, d = chain_run([STILL] * (MIDDLE - 4) + [BEYOND] * 4)
    assert d.restarts == 1 and d.gap_resets == 0
    assert_chained_again(resets, d, [AFTER - 1, AFTER + 1, AFTER + 3, AFTER + 5])
    assert_held_back(*chain_run([STILL] * MIDDLE))


@pytest.mark.parametrize(
    ("middle", "recovery", "restarts"),
    [
        ([NONE] * MIDDLE, {}, [AFTER + 3, AFTER + 5, AFTER + 7]),
        ([STILL] * MIDDLE, {"freeze": 1.0}, [AFTER + 2, AFTER + 4, AFTER + 6]),
    ],
    ids=["silence", "freeze"],
)
def test_an_imu_back_ends_a_held_back_chain(
    middle: list[tuple[float, float]], recovery: dict[str, float], restarts: list[int]
) -> None:
    """The IMU silent (NaN), or frozen (its reading repeated exactly, with the freeze
    detection of 1 s), for 1.2 s after a held-back chain, with no gap reset: its
    return opens the check again and the swing after it restarts three times, a second
    chain; readings at rest instead, with no freeze detection, keep the chain held
    back."""
    resets, d = chain_run(middle, **recovery)
    assert d.restarts == 0 and d.gap_resets == 0
    assert d.frozen_samples == (3 if recovery else 0)
    assert_chained_again(resets, d, restarts)
    assert_held_back(*chain_run([STILL] * MIDDLE))


def test_the_callers_restart_ends_a_held_back_chain() -> None:
    """A caller's restart within the recording (``reset(keep_counts=True)``, as
    ``live`` does) after a held-back chain: the swing after it restarts three times, a
    second chain, and the counts go on from the first; without the caller's restart
    the chain stays held back."""
    z = np.array([STILL] * 20 + [*SWING] * 5 + [STILL] * MIDDLE + [*SWING] * 8)
    t = 0.05 * np.arange(len(z))
    est = make_estimator("ekf", ChainOfThree(), recovery=bare(bad_start=PROBATION))
    status = []
    for i in range(len(t)):
        if i == AFTER:
            est.reset(keep_counts=True)
        status.append(est.step(Measurement(float(t[i]), z[i])).status)
    resets = [i for i, s in enumerate(status) if s == "reset"]
    assert_chained_again(resets, est.diagnostics, [AFTER + 2, AFTER + 4, AFTER + 6])
    assert_held_back(*chain_run([STILL] * MIDDLE))


#: A hanging robot of three sections with a rotated IMU at each end
HANGING_THREE_SECTIONS = (
    'mounting = "z-down"\n'
    + "".join(f"[[section]]\nlength = {v}\ntheta_max = 2.0\n" for v in (0.12, 0.10, 0.08))
    + "".join(
        f"[[imu]]\nsection = {k}\nmount_rpy = {rpy}\n"
        for k, rpy in ((1, [0.0, 0.0, 0.0]), (2, [0.0, 0.0, 90.0]), (3, [5.0, -3.0, 180.0]))
    )
)


def test_no_row_is_ok_while_the_readings_keep_forcing_restarts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hanging three-section robot (20 Hz, raw IMUs) whose recording has IMU 2 and
    3's columns swapped: the readings contradict one restart's fit after another (over
    a third of the samples restart). Two readings agree with a restart's fit a few
    samples after it, 45 to 125 mm off; with four or more forced restarts within the
    bad-start probation time those rows are ``uncertain``: no ``ok`` row is 20 mm off,
    and the end warns that the readings do not fit the robot."""
    robot = tmp_path / "robot.toml"
    robot.write_text(HANGING_THREE_SECTIONS)
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    assert main(["simulate", "spatial", "--robot", str(robot), "--imu", "raw", "-o", str(meas),
                 "--truth", str(truth), "--duration", "20", "--seed", "1"]) == 0  # fmt: skip
    header, *rows = meas.read_text().splitlines()
    names = header.split(",")
    two = [names.index(f"{a}_2") for a in ("ax", "ay", "az", "gx", "gy", "gz")]
    three = [names.index(f"{a}_3") for a in ("ax", "ay", "az", "gx", "gy", "gz")]
    swapped = tmp_path / "swapped.csv"
    lines = [header]
    for row in rows:
        cells = row.split(",")
        for i, j in zip(two, three):
            cells[i], cells[j] = row.split(",")[j], row.split(",")[i]
        lines.append(",".join(cells))
    swapped.write_text("\n".join(lines) + "\n")
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(swapped), "--robot", str(robot), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "the readings do not fit the model of the robot (what to check: the warning" in err
    assert err.count("check the robot file against the robot (the IMUs' order") == 1
    est, true = read_state_table(out), read_state_table(truth)
    off = np.linalg.norm(
        est.values[:, [est.names.index(c) for c in "xyz"]]
        - true.values[:, [true.names.index(c) for c in "xyz"]],
        axis=1,
    )
    assert np.count_nonzero(est.status == "reset") > 100
    assert not np.any((est.status == "ok") & (off > 0.02))


@pytest.mark.parametrize("index", range(5), ids=IDS)
def test_clean_data_are_unchanged_by_the_check(index: int) -> None:
    rec = simulate("paper3d", duration=4.0, seed=5)
    on = estimators(bare(bad_start=10.0))[index]
    s_on = on.run(rec.t, rec.z)
    s_off = estimators(bare())[index].run(rec.t, rec.z)
    assert on.diagnostics.bad_starts == 0
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
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", "--overwrite"]) == 0
    assert "restarted 1 time(s) after readings inconsistent with the start" in (
        capsys.readouterr().err
    )


def test_not_checked_where_the_covariance_is_a_weight() -> None:
    """The paper formulation's W is a weight, not a noise model: its NIS is not a test
    (the same bad start restarts the bend formulation's EKF)."""
    rec, z = bad_start_recording()
    est = make_estimator("ekf", make_formulation("paper"), recovery=bare(bad_start=2))
    assert "reset" not in set(est.run(rec.t, z).status) and est.diagnostics.bad_starts == 0
    checked = estimators(bare(bad_start=2))[0]
    checked.run(rec.t, z)
    assert checked.diagnostics.bad_starts == 1


class _HeldInference(Inference):
    """An inference that answers every sample with the same state and covariance: the
    start check's prediction is then known."""

    name = "held"

    def __init__(self, formulation: Formulation, x: np.ndarray, P: np.ndarray) -> None:
        super().__init__(formulation)
        self.x, self.P = x, P

    def forget(self) -> None:
        pass

    def infer(self, measurement: Measurement) -> tuple[np.ndarray, np.ndarray, Status]:
        return self.x.copy(), self.P.copy(), "ok"


def _conditioned_nis(
    f: Formulation, x: np.ndarray, P: np.ndarray, z: np.ndarray, dt: float
) -> tuple[float, int]:
    """The NIS of ``z``'s readings (the consistency check's judged rows) against ``(x,
    P)`` predicted over ``dt`` s, given the other rows (a tendon robot's tip condition
    and tension rates), written out: the NIS of every row less that of the given rows
    (the chain rule of the Gaussian density); and the number of judged rows."""
    judged = (
        np.concatenate([np.full(b.size, b.kind != "equilibrium") for b in f.measurement_blocks])
        & ~f.input_rows()
    )
    x_next, F, Q = (np.asarray(v, float) for v in f.functions.predict(x, f.inputs(None, z, dt), dt))
    r, J = (np.asarray(v, float) for v in f.functions.innovate(z, x_next.ravel()))
    S = J @ (F @ P @ F.T + Q) @ J.T + np.asarray(f.meas_cov(), float)

    def nis(rows: np.ndarray) -> float:
        return float(r.ravel()[rows] @ np.linalg.solve(S[np.ix_(rows, rows)], r.ravel()[rows]))

    return nis(np.arange(f.nz)) - nis(np.flatnonzero(~judged)), int(judged.sum())


@pytest.mark.parametrize("factor", [0.98, 1.02])
def test_a_tendon_robots_start_check_judges_its_readings_alone(factor: float) -> None:
    """The shipped tendon robot (tilt IMUs): the start check judges the IMUs' readings
    and the tensions, 10 rows, given the tip condition (a pseudo-measurement) and the
    tension rates (inputs, whose residual is zero at every state), against the
    chi-square 99.9 % quantile of 10 degrees of freedom (29.59). Two readings in a row
    whose NIS is 2 % inside it (above the quantile of 9, 27.88) restart nothing; 2 %
    beyond it (below the quantile of 11, 31.26, and far below that of the 25 valid rows,
    52.62) they restart the estimator at the second."""
    f, t, z = shipped_recording("unloaded", "tilt")
    x, P = (np.asarray(v, float) for v in f.start_prior(z[0]))
    P = 1e-4 * P  # a start that knows its shape well: the readings' offset shows
    dt = float(t[1] - t[0])
    offset = np.zeros(f.nz)
    offset[: f.n_imu_measurements] = 1.0  # rad, on each IMU's roll and pitch
    dof = _conditioned_nis(f, x, P, z[1], dt)[1]
    assert dof == 10
    limit = float(scipy.stats.chi2.ppf(start_check.QUANTILE, dof))
    # the two NIS values lie between the quantiles of 9 and 11 degrees of freedom
    quantile = scipy.stats.chi2.ppf
    assert quantile(start_check.QUANTILE, 9) < 0.98 * limit
    assert 1.02 * limit < quantile(start_check.QUANTILE, 11)
    scale = brentq(
        lambda a: _conditioned_nis(f, x, P, z[1] + a * offset, dt)[0] - factor * limit, 0.0, 0.5
    )
    off = z[1] + scale * offset
    est = Estimator(_HeldInference(f, x, P), bare(bad_start=2.0))
    series = est.run(t[:3], np.vstack([z[0], off, off]))
    fires = factor > 1.0
    assert est.diagnostics.bad_starts == int(fires)
    assert list(series.status == "reset") == [False, False, fires]


# --- an IMU back after a silence --------------------------------------------------------
TWO_SECTIONS = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/two_section.toml"
#: ``(seed, silent IMU, from t s, for s)`` on the two-section ``spatial`` scenario. After
#: the return the estimates are up to (tip error, and in units of its own standard
#: deviation): tip IMU 3 s: EKF 138 mm (1.1), UKF 157 mm (1.7); middle IMU 3 s: EKF
#: 67 mm (2.5), UKF 115 mm (2.1); tip IMU 2 s: 10 mm (1.0). Their standard deviations
#: widen with the readings' disagreement, so SIGMAS guards against a covariance that
#: collapses on a wrong estimate (an EKF's first update with a returned IMU can do so).
SILENCES = [(1, 1, 8.0, 3.0), (0, 0, 6.0, 3.0), (5, 1, 10.0, 2.0)]
SIGMAS = 5.0  # no "ok" estimate may be further off than this many of its own std


def silent_imu_recording(seed: int, imu: int, t0: float, seconds: float):
    """Two-section ``spatial`` recording, one IMU NaN from ``t0`` for ``seconds``, cut
    2 s after its return; returns ``(formulation, t, z, truth)``."""
    robot = read_robot(TWO_SECTIONS)
    rec = simulate_robot("spatial", robot, duration=20.0, dt=0.05, seed=seed)
    keep = rec.t < t0 + seconds + 2.0
    t, z, truth = rec.t[keep], rec.z[keep].copy(), rec.truth[keep]
    z[(t >= t0) & (t < t0 + seconds), 2 * imu : 2 * imu + 2] = np.nan
    return make_formulation("bend", robot), t, z, truth


def sigmas_off(s, truth) -> np.ndarray:
    """Tip error of each estimate in units of its own tip standard deviation."""
    err = np.linalg.norm(s.output[:, :3] - truth[:, :3], axis=1)
    return err / np.linalg.norm(s.output_std[:, :3], axis=1)


#: the MHE on IPOPT (the slowest estimator) on the silence the MHE gets wrong; the
#: policy that flags a return is the same for every estimator
SILENCE_CASES = [
    pytest.param(index, silence, id=f"{IDS[index]}-{name}")
    for name, silence in zip(["tip-3s", "middle-3s", "tip-2s"], SILENCES)
    for index in range(5)
    if IDS[index] != "mhe-ipopt" or name == "tip-2s"
]


@pytest.mark.parametrize(("index", "silence"), SILENCE_CASES)
def test_an_imu_back_from_a_silence_is_never_ok_far_off(index: int, silence) -> None:
    """An IMU back after more than the gap reset (1 s, also when it is off) without a
    reading: the EKF's first update with it can land far off with a small covariance
    (up to 143 standard deviations in tools/imu_return_study.py's 120 returns without
    this check). The estimate is ``uncertain`` until the returned IMU's readings have
    agreed with it for as long (library default: flagged, no restart)."""
    f, t, z, truth = silent_imu_recording(*silence)
    # from 3 s before the silence (the IPOPT MHE's time grows with the samples): from
    # the silence on, every status is the whole recording's, each output within 3e-5
    keep = t >= silence[2] - 3.0
    t, z, truth = t[keep], z[keep], truth[keep]
    est = recovery_estimators(bare(), f)[index]
    s = est.run(t, z)
    assert sigmas_off(s, truth)[s.status == "ok"].max() < SIGMAS
    back = t >= silence[2] + silence[3]
    assert s.status[back][0] in ("uncertain", "reset") and est.diagnostics.bad_starts == 0
    if index < 3:  # the filters are confirmed within the 2 s; the MHE (N = 10) is not
        assert s.status[-1] == "ok"  # after tip-2s: 38 mm, 6.6 std off, readings disagree


# not the MHE on IPOPT: it steps through the policy as the CasADi EKF and the UKF do
@pytest.mark.parametrize("index", range(4), ids=IDS[:4])
def test_the_bad_start_check_reopens_for_an_imu_back_from_a_silence(index: int) -> None:
    """With ``bad_start`` the check reopens when the IMU returns: the EKF, up to 138 mm
    off, restarts from the reading two samples later (0.4 s earlier than
    its own divergence check would) and is within 1.5 cm from there on; the same
    recording without the silence gets no status but ``ok``."""
    f, t, z, truth = silent_imu_recording(*SILENCES[0])
    est = recovery_estimators(bare(gap_reset=1.0, bad_start=2.0), f)[index]
    s = est.run(t, z)
    assert sigmas_off(s, truth)[s.status == "ok"].max() < SIGMAS
    back = np.flatnonzero(t >= 11.0)[0]
    if index < 2:  # the EKFs: inconsistent at back + 1 and back + 2
        assert (
            list(np.flatnonzero(s.status == "reset")) == [back + SAMPLES]
            and est.diagnostics.bad_starts == 1
        )
        tip = np.linalg.norm(s.output[:, :3] - truth[:, :3], axis=1)
        assert tip[back + SAMPLES :].max() < 0.015
    _, t, z, _ = silent_imu_recording(1, 1, 11.0, 0.0)  # the same, without the silence
    quiet = est.run(t, z)
    # ok but where the reported tip std exceeds the uncertain fraction of the robot's
    # length (uncertain: section 2 near straight across a horizontal section 1, whose
    # bend about the vertical no gravity direction shows; 23 of the 260 rows)
    limit = RecoverySettings().uncertain_fraction * f.robot.length
    wide = np.linalg.norm(quiet.output_std[:, :3], axis=1) > limit
    assert quiet.status[0] == "uncertain"  # the start, unconfirmed
    assert np.array_equal(quiet.status[1:] == "uncertain", wide[1:]) and wide.sum() <= 25
    assert set(quiet.status) <= {"ok", "uncertain"}


def test_an_imu_that_reports_only_later_restarts_the_estimate() -> None:
    """The tip IMU first reporting at 3 s: the rows before are ``uncertain`` (the
    shape is not observed), its first reading restarts the estimate (the gap reset's
    restart, which keeps the sensors' states) and the rows after are ``ok`` within
    their standard deviations; with the gap reset off it is held ``uncertain`` as an
    IMU back from a silence until its readings agree."""
    f, t, z, truth = silent_imu_recording(1, 1, 0.0, 3.0)
    first = np.flatnonzero(t >= 3.0)[0]
    est = make_estimator("ekf", f)
    s = est.run(t, z)
    assert set(s.status[:first]) == {"uncertain"} and s.status[first] == "reset"
    assert est.diagnostics.late_imu_starts == 1 and est.diagnostics.gap_resets == 0
    assert s.status[-1] == "ok" and sigmas_off(s, truth)[s.status == "ok"].max() < SIGMAS
    held = make_estimator("ekf", f, recovery=replace(RecoverySettings(), gap_reset=None))
    s = held.run(t, z)
    assert set(s.status[: first + 1]) == {"uncertain"}
    assert held.diagnostics.late_imu_starts == 0
    assert s.status[-1] == "ok" and sigmas_off(s, truth)[s.status == "ok"].max() < SIGMAS


@pytest.fixture(scope="module")
def imu_2_late(tmp_path_factory) -> tuple[Path, Path, Path]:
    """A two-section raw recording (``spatial``, 3 s at 100 Hz, bent from the start),
    IMU 2's fields empty in the first three rows (a log whose second IMU topic starts
    30 ms after the first), the same from the fourth row on, and the truth."""
    folder = tmp_path_factory.mktemp("late")
    raw, truth = folder / "raw.csv", folder / "truth.csv"
    assert (
        main(
            ["simulate", "spatial", "--robot", "two-section", "--imu", "raw", "--dt", "0.01"]
            + ["--duration", "3", "-o", str(raw), "--truth", str(truth)]
        )
        == 0
    )
    lines = raw.read_text().splitlines()
    width = len(lines[0].split(",")) // 2  # t and IMU 1's six fields
    late = folder / "late.csv"
    blanked = [",".join(row.split(",")[: width + 1] + [""] * width) for row in lines[1:4]]
    late.write_text("\n".join([lines[0], *blanked, *lines[4:]]) + "\n")
    whole = folder / "from_row_4.csv"
    whole.write_text("\n".join([lines[0], *lines[4:]]) + "\n")
    return late, whole, truth


def _tip_errors(estimate: Path, truth: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``t`` (s), the tip error (m) and the status of each row of ``estimate``."""
    est, true = read_state_table(estimate), read_state_table(truth)
    got = np.column_stack([est.column(c) for c in ("x", "y", "z")])
    want = np.column_stack([true.column(c) for c in ("x", "y", "z")])
    rows = np.searchsorted(true.t, est.t)
    return est.t, np.linalg.norm(got - want[rows], axis=1), est.status


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_an_imu_that_starts_late_restarts_the_estimate_with_it(
    imu_2_late, tmp_path, method: str, capsys
) -> None:
    """The first reading of an IMU the start had none of restarts the estimate (status
    ``reset``, counted and said), and from there on it is the estimate of the recording
    that starts there, within 0.5 mm; without the restart (``--gap-reset 0``) the MHE is
    far off for about a second (the gyros' biases having taken up the second section's
    jump onto its first readings), and none of those rows is ``ok``: the start's rows,
    without IMU 2, carry section 2's spread over its reach, the rows after a row that
    wide stay ``uncertain`` for the unobserved window, and the rest are
    ``inconsistent``."""
    late, whole, truth = imu_2_late
    got, want, off = tmp_path / "got.csv", tmp_path / "want.csv", tmp_path / "off.csv"
    for source, out, extra in (
        (late, got, []),
        (whole, want, []),
        (late, off, ["--gap-reset", "0"]),
    ):
        command = ["estimate", str(source), "--robot", "two-section", "--method", method]
        assert main([*command, "-o", str(out), *extra]) == 0
        said = capsys.readouterr().err
        assert ("restarted 1 time(s) at an IMU's first reading" in said) == (out is got)
    t, err, status = _tip_errors(got, truth)
    assert list(status[:4]) == ["uncertain"] * 3 + ["reset"]
    t_want, err_want, _ = _tip_errors(want, truth)
    assert np.allclose(t[3:], t_want)
    assert np.abs(err[3:] - err_want).max() < 5e-4
    if method == "mhe":
        _, err_off, status_off = _tip_errors(off, truth)
        assert err_off.max() > 0.03
        assert not np.any((status_off == "ok") & (err_off > 0.01))


def _blanked(source: Path, out: Path, imu_rows: dict[int, range]) -> Path:
    """``source`` (a two-IMU raw recording) with IMU ``k``'s six fields (k = 1, 2) empty
    in the data rows ``imu_rows[k]`` (0-based)."""
    header, *rows = source.read_text().splitlines()
    cells = [row.split(",") for row in rows]
    for k, which in imu_rows.items():
        for i in which:
            cells[i][1 + 6 * (k - 1) : 7 + 6 * (k - 1)] = [""] * 6
    out.write_text("\n".join([header, *(",".join(c) for c in cells)]) + "\n")
    return out


def test_a_late_imus_restart_waits_for_a_sample_every_imu_reads(imu_2_late, tmp_path, capsys):
    """IMU 2 missing in the first three samples and IMU 1 in the fourth (IMU 2's first
    reading on a sample without IMU 1's): the restart waits for the fifth, the first
    that both read (not dropped, which would leave the MHE 12 mm off); IMUs at different
    rates (IMU 2 on every other sample from the first) restart nothing, whatever
    restarts else."""
    _, whole, truth = imu_2_late
    raw = whole.parent / "raw.csv"
    partial = _blanked(raw, tmp_path / "partial.csv", {2: range(3), 1: range(3, 4)})
    est = tmp_path / "e.csv"
    assert main(["estimate", str(partial), "--robot", "two-section", "-o", str(est)]) == 0
    assert "restarted 1 time(s) at an IMU's first reading" in capsys.readouterr().err
    _, err, status = _tip_errors(est, truth)
    assert "ok" not in status[:4] and status[4] == "reset"
    assert err[status == "ok"].max() < 0.008
    rates = _blanked(raw, tmp_path / "rates.csv", {2: range(1, 300, 2)})
    assert main(["estimate", str(rates), "--robot", "two-section", "-o", str(est),
                 "--overwrite"]) == 0  # fmt: skip
    assert "at an IMU's first reading" not in capsys.readouterr().err
