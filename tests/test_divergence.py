"""Never ``ok`` when wrong: every estimator detects divergence or a numerical failure,
flags the sample ``reset`` and restarts from the measurement (on the reproducers in
tests/data/repro)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import reading_by_reading

from continuum_mhe.cli import main
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.io.state_tables import read_states
from continuum_mhe.model.formulations import AT_BOUND_TOL
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.results import STATUS_MEANINGS, Measurement
from continuum_mhe.settings import MHESettings, RecoverySettings
from continuum_mhe.simulation.scenarios import simulate

REPRO = Path(__file__).parent / "data" / "repro"


#: the flag each reproducer's contradictory readings must raise somewhere (a sample
#: not "ok"): pitch +90 then -90 deg 10 ms apart, and roll 180 deg with pitch 93 deg
FLAGGED = {
    ("gimbal_flip.csv", "mhe"): "reset",
    ("gimbal_flip.csv", "ekf"): "reset",
    # (the UKF's start is uncertain, not on the bound: the half turn 10 ms after it is
    # skipped as a glitch)
    ("gimbal_flip.csv", "ukf"): "inconsistent",
    ("mhe_stops.csv", "mhe"): "reset",
    ("mhe_stops.csv", "ekf"): "reset",
    ("mhe_stops.csv", "ukf"): "reset",
}


@pytest.mark.parametrize(("name", "method"), sorted(FLAGGED))
def test_reproducers_give_finite_flagged_estimates(tmp_path: Path, method: str, name: str) -> None:
    out = tmp_path / "o.csv"
    assert main(["estimate", str(REPRO / name), "-o", str(out), "--method", method]) == 0
    t, x, status = read_states(out)
    assert np.all(np.isfinite(x))
    assert set(status) <= set(STATUS_MEANINGS)
    assert FLAGGED[name, method] in set(status), list(status)
    # the first reading alone contradicts nothing: a start from it is unconfirmed
    # (gimbal_flip's is a bend of exactly theta_max = pi/2: on the bound)
    first = ("uncertain", "at-bound") if name == "gimbal_flip.csv" else ("uncertain",)
    assert status[0] in first


def test_ekf_gimbal_flip_is_flagged_not_ok() -> None:
    data = read_measurements(REPRO / "gimbal_flip.csv")
    series = make_estimator("ekf", make_formulation("bend")).run(data.t, data.z)
    assert np.all(np.isfinite(series.output))
    assert series.status[-1] == "reset"


def test_ukf_gimbal_flip_is_not_ok_with_a_collapsed_covariance() -> None:
    # its sigma points' tangent-plane residuals straddle the singularity at a half turn
    # (-1414 against +130): an unchecked update keeps x = +0.127 m where the reading says
    # -0.127, status ok, with std y 1e-6 m. The reading, a half turn 10 ms after the
    # start's first estimate, is skipped as a glitch (the row inconsistent, the estimate
    # its prediction); with the glitch test off, the update fails and restarts the UKF
    # from it
    data = read_measurements(REPRO / "gimbal_flip.csv")
    est = make_estimator("ukf", make_formulation("bend"))
    series = est.run(data.t, data.z)
    assert list(series.status) == ["uncertain", "inconsistent"]
    assert est.diagnostics.glitches == 1 and est.diagnostics.restarts == 0
    assert series.output_std[1, 1] > 1e-3
    est = make_estimator("ukf", make_formulation("bend"), recovery=RecoverySettings(glitch=None))
    series = est.run(data.t, data.z)
    assert list(series.status) == ["uncertain", "reset"]
    assert est.diagnostics.restarts == 1 and "half turn" in str(est.diagnostics.last_failure)
    assert series.output[1, 0] < 0  # restarted from the second reading
    assert series.output_std[1, 1] > 1e-3


def test_ukf_chart_check_knows_a_singularity_from_a_wrap() -> None:
    # gimbal_flip.csv's second reading is a half turn from the first: the bend
    # formulation's tangent-plane residual does not wrap, and its sigma points' residuals
    # straddle its singularity (a jump of 1.54e3); the paper formulation's Euler angles
    # wrap, and there a jump across +-pi is no singularity
    data = read_measurements(REPRO / "gimbal_flip.csv")
    dt = float(data.t[1] - data.t[0])
    for name, refused in (("bend", True), ("paper", False)):
        inf = make_estimator("ukf", make_formulation(name)).inference
        f = inf.formulation
        x, P, _ = inf.infer(Measurement(float(data.t[0]), data.z[0]))
        xp, Pp = inf._predict(x, P, np.zeros(f.nu), dt)
        mask = f.measurement_mask(data.z[1])
        if refused:
            with pytest.raises(ArithmeticError, match="pitch residuals span 1.54e"):
                inf._update(xp, Pp, data.z[1], mask)
        else:
            assert np.all(np.isfinite(inf._update(xp, Pp, data.z[1], mask)[0]))
        inf._x = None  # a (re)start's first update: its prior is the reading's own
        assert np.all(np.isfinite(inf._update(xp, Pp, data.z[1], mask)[0]))
    # a reading near the prediction passes the check
    inf = make_estimator("ukf", make_formulation("bend")).inference
    x, P, _ = inf.infer(Measurement(0.0, np.array([0.0, 0.3])))
    xp, Pp = inf._predict(x, P, np.zeros(0), 0.01)
    near = np.array([0.02, 0.31])
    assert np.all(np.isfinite(inf._update(xp, Pp, near, np.ones(2))[0]))


def test_a_ukf_rate_prior_that_spreads_its_sigma_points_past_its_chart_is_warned_of() -> None:
    """``initial_rate_std = 50`` rad/s on ``paper3d`` (0.05 s steps): the UKF's first
    prediction after a start spreads its sigma points 0.5 sqrt(4) 50 0.05 = 2.5 rad of
    tilt apart, past 2 atan(pi / 2) = 2.01 rad, and every later sample restarts it
    (``reset``); ``run`` and ``step`` say so once, naming the largest rate within 0.95 of
    that limit (0.95 * 2 atan(pi / 2) / 0.05 = 38.1 rad/s); the EKF and the MHE take the prior
    (``ok``) and are not warned, nor is the UKF at 38 rad/s, where no sample restarts."""
    import math
    import warnings

    from continuum_mhe.io.input_options import OptionWarning
    from continuum_mhe.model.settings import NoiseSettings

    rec = simulate("paper3d", duration=5)
    limit = 0.95 * 2 * math.atan(math.pi / 2) / 0.05
    said = (
        r"^run: initial_rate_std 50 rad/s spreads the UKF's sigma points up to 2.5 rad of "
        r"tilt from its prediction over the 0.05 s between samples, near or past the 2.01 "
        rf"rad .* give initial_rate_std at most {limit:.3g} rad/s"
    )
    wide = make_formulation("bend", noise=NoiseSettings(initial_rate_std=50.0))
    with pytest.warns(OptionWarning, match=said) as caught:
        series = make_estimator("ukf", wide).run(rec.t, rec.z)
    assert len(caught) == 1
    assert list(series.status[1:]) == ["reset"] * (len(rec.t) - 1)
    ukf = make_estimator("ukf", wide)
    with pytest.warns(OptionWarning, match=said.replace("^run:", "^step:")) as caught:
        for k in range(6):
            ukf.step(Measurement(float(rec.t[k]), rec.z[k]))
    assert len(caught) == 1
    for method, rate in (("ekf", 50.0), ("mhe", 50.0), ("ukf", 38.0)):
        f = make_formulation("bend", noise=NoiseSettings(initial_rate_std=rate))
        with warnings.catch_warnings():
            warnings.simplefilter("error", OptionWarning)
            series = make_estimator(method, f).run(rec.t, rec.z)
        assert list(series.status[1:]) == ["ok"] * (len(rec.t) - 1), method


def test_a_ukf_process_noise_spreading_its_settled_sigma_points_past_its_chart_is_warned() -> None:
    """``bend_accel_psd = 1e5`` on ``paper3d`` (0.05 s steps): once settled, the UKF's
    predicted covariance spreads its sigma points 2.79 rad of tilt apart, past 2 atan(pi /
    2) = 2.01 rad, and most samples restart it (``reset``); ``run`` says so once, naming
    the setting. At 1e3 (spread 0.29 rad, and two innovation standard deviations 0.59
    rad more: within the limit) it is not warned of and no sample restarts; nor are the
    EKF and the MHE at 1e5, nor the UKF with the default at 1 Hz (spread 0.57 rad)."""
    import warnings

    from continuum_mhe.io.input_options import OptionWarning
    from continuum_mhe.model.settings import NoiseSettings

    rec = simulate("paper3d", duration=3)
    noisy = make_formulation("bend", noise=NoiseSettings(bend_accel_psd=1e5))
    said = (
        r"^run: bend_accel_psd \(--accel-psd\) 100000 spreads the UKF's sigma points up to "
        r"2\.79 rad of tilt .* once the filter has settled, .* past the 2\.01 rad .* a "
        r"smaller bend_accel_psd narrows the spread"
    )
    with pytest.warns(OptionWarning, match=said) as caught:
        series = make_estimator("ukf", noisy).run(rec.t, rec.z)
    assert len(caught) == 1
    assert np.mean(series.status == "reset") > 0.5
    slow = simulate("paper3d", duration=30)
    for method, psd, step in (("ukf", 1e3, 1), ("ekf", 1e5, 1), ("mhe", 1e5, 1), ("ukf", 0.5, 20)):
        f = make_formulation("bend", noise=NoiseSettings(bend_accel_psd=psd))
        t, z = (rec.t, rec.z) if step == 1 else (slow.t[::step], slow.z[::step])
        with warnings.catch_warnings():
            warnings.simplefilter("error", OptionWarning)
            series = make_estimator(method, f).run(t, z)
        assert "reset" not in set(series.status), method


def test_mhe_survives_the_rows_that_stopped_it() -> None:
    data = read_measurements(REPRO / "mhe_stops.csv")
    est = make_estimator("mhe", make_formulation("bend"))
    series = est.run(data.t, data.z)
    assert np.all(np.isfinite(series.output))
    # a flip onto the bound leaves a window's model non-finite at IPOPT's start (a
    # window the fast solver does not certify): the MHE restarts from that reading, as
    # the EKF and UKF do, instead of keeping the start as its answer (not-converged) on
    # every later row
    statuses = list(series.status)
    assert est.diagnostics.restarts >= 1 and "reset" in statuses[:8], statuses
    assert "Invalid_Number_Detected" in str(est.diagnostics.last_failure)
    assert "not-converged" not in set(series.status)
    # and it follows the readings again: the bend leaves the bound where they do
    _leaves_the_bound_where_the_readings_do(data.z, series.output[:, 3])


def _leaves_the_bound_where_the_readings_do(z: np.ndarray, theta: np.ndarray) -> None:
    """Every row whose reading alone bends less than 1 rad (three of ``mhe_stops.csv``,
    past its flips) has a bend at least 0.3 rad inside the pi/2 bound."""
    inside = reading_by_reading(z)[:, 0] < 1.0
    assert inside[3:].sum() >= 3
    assert np.all(theta[3:][inside[3:]] < np.pi / 2 - 0.3), theta[inside]


@pytest.mark.parametrize("solver", ["fast", "ipopt"])
def test_mhe_restarts_after_the_flip_on_both_backends(solver: str) -> None:
    data = read_measurements(REPRO / "mhe_stops.csv")
    est = make_estimator("mhe", make_formulation("bend"), MHESettings(solver=solver))
    series = est.run(data.t, data.z)
    assert est.diagnostics.restarts >= 1 and "reset" in set(series.status)
    # not the flip's answer kept on every later row (not-converged, 1.571 rad throughout)
    after = series.status[3:]
    assert np.mean(after == "not-converged") < 0.25, list(series.status)
    _leaves_the_bound_where_the_readings_do(data.z, series.output[:, 3])


def test_slow_sampling_ekf_never_reports_absurd_bends_as_ok() -> None:
    # 1 s sampling: an unchecked EKF runs off to bends of thousands of radians; none may say "ok"
    rec = simulate("paper3d", duration=200, dt=1.0, seed=0)
    f = make_formulation("bend")
    series = make_estimator("ekf", f).run(rec.t, rec.z)
    ok = series.status == "ok"
    assert ok.sum() > 20
    # an ok row is off its bound (a bend within AT_BOUND_TOL of it is at-bound) ...
    assert np.all(series.output[ok, 3] < f.robot.theta_max - AT_BOUND_TOL)
    # ... and near the truth: no ok row 50 to 64 mm or up to 25 std off;
    # x and y within 4 of their std (z near straight is the linearised std's limit)
    off = np.abs(series.output[:, :3] - rec.truth[:, :3])
    assert np.all(off[ok] < 0.025)
    assert np.all(off[ok, :2] < 4.0 * series.std[ok, :2])
    assert "reset" in set(series.status)


@pytest.mark.parametrize("method", ["ekf", "ukf"])
def test_filters_restart_after_a_long_gap(method: str) -> None:
    rec = simulate("paper3d", duration=80, dt=0.05, seed=0)
    keep = (rec.t < 10) | (rec.t > 70)  # a 60 s gap
    f = make_formulation("bend")
    series = make_estimator(method, f).run(rec.t[keep], rec.z[keep])
    first_after = int(np.argmax(series.t > 70))
    assert series.status[first_after] == "reset"
    err = np.linalg.norm(
        series.output[first_after:, :3] - rec.truth[keep][first_after:, :3], axis=1
    )
    unfiltered = reading_by_reading(rec.z[keep][first_after:])[:, 2:]
    # filtering again (0.70 of the readings' own error), not 58 rad off
    assert np.mean(err) < 0.8 * np.mean(
        np.linalg.norm(unfiltered - rec.truth[keep][first_after:, :3], axis=1)
    )


def test_status_vocabulary_is_documented() -> None:
    """Every status is named in the README and explained in the estimate file's format."""
    root = Path(__file__).parents[1]
    readme = (root / "README.md").read_text()
    formats = (root / "docs" / "formats.md").read_text().split("## Estimate CSV", 1)[1]
    for status in STATUS_MEANINGS:
        assert f"`{status}`" in readme, status
        assert f"`{status}`" in formats, status


def test_reset_rows_round_trip_through_the_csv(tmp_path: Path) -> None:
    out = tmp_path / "o.csv"
    assert (
        main(["estimate", str(REPRO / "gimbal_flip.csv"), "-o", str(out), "--method", "ekf"]) == 0
    )
    rows = list(csv.DictReader(ln for ln in out.open() if not ln.startswith("#")))
    assert rows[-1]["status"] == "reset" and rows[-1]["theta"] != ""


def test_skip_bad_keeps_an_infinite_angle_as_a_dropout(tmp_path: Path) -> None:
    out = tmp_path / "o.csv"
    src = str(REPRO / "inf_skip_bad.csv")
    assert main(["estimate", src, "-o", str(out)]) == 2  # without the flag: one-line error
    assert not out.exists()
    assert main(["estimate", src, "-o", str(out), "--skip-bad"]) == 0
    _, x, status = read_states(out)
    assert list(status) == ["uncertain", "dropout", "ok", *status[3:]]
    assert np.all(np.isfinite(x))


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_a_first_reading_upside_down_gives_no_ok_row_far_off(method: str) -> None:
    """The first estimate fits its one reading alone: with that reading upside down
    (roll plus or minus pi, pitch negated) it is 170 to 360 mm off the two-section
    robot's tip, and not ok; with the right one it is uncertain too, and the next
    reading that agrees confirms it (ok)."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=4, seed=0)
    clean = make_estimator(method, f).run(rec.t, rec.z)
    assert list(clean.status[:3]) == ["uncertain", "ok", "ok"]
    for imu in (0, 1):
        z = rec.z.copy()
        roll, pitch = z[0, 2 * imu : 2 * imu + 2]
        z[0, 2 * imu : 2 * imu + 2] = (roll - np.pi if roll > 0 else roll + np.pi, -pitch)
        series = make_estimator(method, f).run(rec.t, z)
        off = np.linalg.norm(series.output[:, :3] - rec.truth[:, :3], axis=1)
        assert off[0] > 0.15  # the start on the upside-down reading
        assert not np.any((series.status == "ok") & (off > 0.05)), (imu, series.status[:5])


@pytest.mark.parametrize("seed", [0, 2, 4])
@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_an_imu_upside_down_from_the_start_gives_no_ok_row_far_off(
    tmp_path: Path, method: str, seed: int
) -> None:
    """A two-section raw recording whose second IMU's accelerometer reads negated from the
    first sample (mounted upside down, or its axes' signs wrong): a wrong shape fits a
    few of its readings in a row between the disagreeing ones, and none of those rows
    may be ok (they are 170 mm off with a 9 mm standard deviation)."""
    robot = tmp_path / "r2.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\ntheta_max = 2.5\n'
        "[[section]]\nlength = 0.14\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    argv = ["simulate", "spatial", "--robot", str(robot), "--imu", "raw", "--seed", str(seed)]
    assert main([*argv, "--duration", "3", "-o", str(meas), "--truth", str(truth)]) == 0
    lines = meas.read_text().splitlines()
    header = lines[0].split(",")
    flip = [header.index(c) for c in ("ax_2", "ay_2", "az_2")]
    rows = []
    for ln in lines[1:]:
        cells = ln.split(",")
        for j in flip:
            cells[j] = repr(-float(cells[j]))
        rows.append(",".join(cells))
    flipped = tmp_path / "flipped.csv"
    flipped.write_text("\n".join([lines[0], *rows]) + "\n")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(flipped), "--robot", str(robot), "-o", str(out),
                 "--method", method]) == 0  # fmt: skip
    from continuum_mhe.io.state_tables import read_state_table

    est, tru = read_state_table(out), read_state_table(truth)
    assert np.array_equal(est.t, tru.t)
    off = np.linalg.norm(est.values[:, :3] - tru.values[:, :3], axis=1)
    far_ok = (est.status == "ok") & (off > 0.05)
    assert not far_ok.any(), (est.t[far_ok], off[far_ok])
