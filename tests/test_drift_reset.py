"""A tendon robot's estimate that drifts after a fault has passed (an IMU frozen for a
second, a tension wrong for a fifth of a second) restarts from the sensor states of its
last ``ok`` estimate (``RecoverySettings.drift_reset``), where it stayed far off for the
rest of the recording."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from tendon_helpers import DATA, default_ekf_run

from continuum_mhe.cli import main
from continuum_mhe.errors import UserError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import open_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import RecoverySettings

ROBOT = "tendon-two-section"


def _recording(tensions: Path) -> tuple[object, np.ndarray, np.ndarray]:
    base = make_formulation("bend", read_robot(ROBOT))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open_input(DATA / "force-29_raw.csv", InputOptions(tensions=str(tensions)), base) as s:
            f = s.formulation
            blocks = list(s.blocks)
    return f, np.concatenate([b[0] for b in blocks]), np.vstack([b[1] for b in blocks])


def _tension_off(folder: Path) -> Path:
    """force-29's tensions with tension_1 0.05 N too high from 1 to 1.2 s."""
    lines = (DATA / "force-29_tensions.csv").read_text().splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    for r in rows:
        if 1.0 <= float(r[0]) < 1.2:
            r[1] = f"{float(r[1]) + 0.05:.6f}"
    path = folder / "tension_off.csv"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    return path


def _tip_errors(f: object, series: object) -> tuple[np.ndarray, np.ndarray]:
    """The tip's error (mm) and its largest error on an axis in standard deviations."""
    names = [o.name for o in f.outputs]  # type: ignore[attr-defined]
    cols = [names.index(c) for c in "xyz"]
    truth = read_state_table(DATA / "force-29_truth.csv")
    tip = np.asarray(series.output, float)[:, cols]  # type: ignore[attr-defined]
    std = np.asarray(series.output_std, float)[:, cols]  # type: ignore[attr-defined]
    off = tip - np.stack([truth.column(c) for c in "xyz"], axis=1)[: len(tip)]
    return 1000.0 * np.linalg.norm(off, axis=1), np.max(np.abs(off) / std, axis=1)


@pytest.mark.parametrize("fault", ["frozen-tip-imu", "tension-off"])
def test_a_passing_fault_keeps_the_rest_of_the_recording(tmp_path: Path, fault: str) -> None:
    """``force-29`` (raw, EKF): the tip IMU repeating one reading from 2 to 3 s, or
    tension_1 0.05 N too high from 1 to 1.2 s. Without the drift reset the estimate
    stays off to the end (over 50 mm on average after 4 s: 255 and 80 mm); with it,
    it restarts from the last ok estimate's IMU errors and is within 10 mm on average
    after 4 s (2.4 and 1.6 mm), no ok row more than 4 standard deviations off."""
    f, t, z = _recording(DATA / "force-29_tensions.csv")
    if fault == "frozen-tip-imu":
        imu = [i for i, n in enumerate(f.measurement_names) if n.endswith("_2")]  # type: ignore[attr-defined]
        held = (t > 2.0) & (t <= 3.0)
        z[np.ix_(held, imu)] = z[np.argmax(held), imu]
    else:
        f, t, z = _recording(_tension_off(tmp_path))
    late = t > 4.0
    without = make_estimator("ekf", f, recovery=RecoverySettings(drift_reset=None))  # type: ignore[arg-type]
    lost, _ = _tip_errors(f, without.run(t, z))
    assert lost[late].mean() > 50.0 and without.diagnostics.drift_resets == 0
    est = make_estimator("ekf", f)  # type: ignore[arg-type]
    series = est.run(t, z)
    err, sigmas = _tip_errors(f, series)
    assert est.diagnostics.drift_resets >= 1
    assert err[late].mean() < 10.0
    ok = np.asarray(series.status) == "ok"
    assert not np.any(ok & (sigmas > 4.0))


def test_the_drift_reset_is_a_tendon_robots_and_off_with_zero(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording without faults is not restarted; ``--drift-reset 0`` turns it off and
    the summary names the restarts where there are (the first 4 s of ``force-29`` with
    the tip IMU repeating one reading from 2 to 3 s: the drift reset at 2.66 s); 0 s in
    Python is refused (None is never)."""
    assert default_ekf_run("force-29", "raw").estimator.diagnostics.drift_resets == 0
    with pytest.raises(UserError, match="drift_reset must be positive"):
        RecoverySettings(drift_reset=0)
    held = tmp_path / "held.csv"
    lines = (DATA / "force-29_raw.csv").read_text().splitlines()
    header = lines[0].split(",")
    cols = [header.index(c) for c in header if c.endswith("_2")]
    rows = [ln.split(",") for ln in lines[1:]]
    for r in rows[101:151]:
        for c in cols:
            r[c] = rows[100][c]
    held.write_text("\n".join([lines[0], *(",".join(r) for r in rows[:201])]) + "\n")
    argv = ["estimate", str(held), "--robot", ROBOT, "--inputs",
            str(DATA / "force-29_tensions.csv"), "-o", str(tmp_path / "e.csv")]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "time(s) from the last ok estimate's IMU errors after 0.5 s of drifted rows" in err
    assert main([*argv[:-1], str(tmp_path / "off.csv"), "--drift-reset", "0"]) == 0
    assert "from the last ok estimate's IMU errors" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("robot", "extra", "refused"),
    [
        ([], [], "--drift-reset does not apply: it restarts a tendon robot's estimate"),
        (["--formulation", "paper", "--method", "ekf"], [], "this model has no such states"),
        (
            ["--robot", ROBOT, "--inputs", str(DATA / "force-29_tensions.csv")],
            ["--estimate-tension-gain"],
            "--drift-reset does not apply with --estimate-tension-gain",
        ),
    ],
)
def test_drift_reset_where_it_changes_nothing_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], robot, extra, refused
) -> None:
    """``--drift-reset`` typed for a model without drifting IMU error states (a robot
    without tendons), or with tension gains estimated (whose drift is their settling):
    one line, exit 2, nothing written."""
    meas = tmp_path / "m.csv"
    if robot[:1] == ["--robot"]:
        meas.write_text("\n".join((DATA / "force-29_raw.csv").read_text().splitlines()[:30]))
    else:
        assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    capsys.readouterr()
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), *robot, *extra, "--drift-reset", "1", "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and refused in err[0], err
    assert not out.exists()


def test_a_restart_starts_the_drift_anew(tmp_path: Path) -> None:
    """Two rows drifted (a tension 0.05 N off), then a gap: the gap's restart at 2.3 s
    is the only one; the drifted rows before it do not time a drift reset of the start
    after it (which would restart it again at the next sample). The bad-start check is
    off: the wrong tension falls within the probation time of the recording's start,
    where the check restarts the estimate that followed it, and the gap's restart after
    that keeps no sensor states (a fresh start under load, whose rows drift)."""
    f, t, z = _recording(_tension_off(tmp_path))
    kept = (t < 1.05) | (t > 2.3 - 1e-9)
    est = make_estimator("ekf", f, recovery=RecoverySettings(bad_start=None))  # type: ignore[arg-type]
    status = np.asarray(est.run(t[kept], z[kept]).status)
    assert np.count_nonzero(status[t[kept] < 1.05] == "drifted") >= 1
    assert est.diagnostics.gap_resets == 1 and est.diagnostics.drift_resets == 0
    assert np.count_nonzero(status == "reset") == 1


def _streamed_with_tensions_missing(
    start: float, end: float
) -> tuple[object, np.ndarray, np.ndarray]:
    """``force-29``'s raw readings and tensions as the library guide streams them (a
    ``TensionStream`` a sample at a time), every tension missing from ``start`` to
    ``end`` s: ``(formulation, t, z)`` of the rows it gives."""
    from continuum_mhe.io import TensionStream, raw_measurements, read_raw_imus

    robot = read_robot(ROBOT)
    raw = read_raw_imus(DATA / "force-29_raw.csv", robot.n_imus)
    acc = np.stack([imu.acc for imu in raw.imus], axis=1)
    gyr = np.stack([imu.gyr for imu in raw.imus], axis=1)
    imus = raw_measurements(robot, raw.t, acc, gyr)
    given = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)[:, 1:]
    given[(raw.t >= start - 1e-9) & (raw.t < end - 1e-9)] = np.nan
    f = make_formulation("tendon", robot, imu_model="direct")
    stream = TensionStream(n_tendons=robot.n_tendons)
    by_t = {float(tk): imus[k] for k, tk in enumerate(raw.t)}
    ready = [a for tk, g in zip(raw.t, given) for a in stream.push(float(tk), g)]
    ready += stream.end()
    t = np.array([a.t for a in ready])
    z = np.array([f.measurement_row(by_t[a.t], a.values, a.rates, a.accelerations)
                  for a in ready])  # fmt: skip
    return f, t, z


def test_the_return_of_the_tensions_after_a_fraction_of_a_second_restarts_as_a_gap() -> None:
    """``force-29`` (raw, EKF, streamed as the library guide does) with every tension
    missing from 3.0 to 3.4 s, the IMUs reading throughout: those samples use no
    reading (the IMUs' model needs the tensions) and the prediction has no tensions to
    follow. Their return restarts as after a gap, keeping the sensors' states: no ok
    row after it more than 5 mm or 4 standard deviations off (``gap_reset=None``, which
    this restart follows, leaves ok rows over 10 mm off, 4 to 5.5 standard deviations)."""
    f, t, z = _streamed_with_tensions_missing(3.0, 3.4)
    after = t >= 3.4 - 1e-9
    without = make_estimator("ekf", f, recovery=RecoverySettings(gap_reset=None))  # type: ignore[arg-type]
    series = without.run(t, z)
    err, sigmas = _tip_errors(f, series)
    ok = np.asarray(series.status) == "ok"
    assert np.count_nonzero(ok & after & (err > 5.0)) > 10
    est = make_estimator("ekf", f)  # type: ignore[arg-type]
    series = est.run(t, z)
    err, sigmas = _tip_errors(f, series)
    ok = np.asarray(series.status) == "ok"
    assert est.diagnostics.gap_resets == 1
    assert not np.any(ok & after & ((err > 5.0) | (sigmas > 4.0)))
    # one sample's tensions missing (five samples without them): no restart (in the
    # second after their return, where the restart above comes)
    f, t, z = _streamed_with_tensions_missing(3.0, 3.02)
    first = t < 4.0
    est = make_estimator("ekf", f)  # type: ignore[arg-type]
    status = np.asarray(est.run(t[first], z[first]).status)
    assert np.count_nonzero(status == "dropout") == 5 and est.diagnostics.gap_resets == 0


def test_rows_drifted_again_soon_after_a_restart_keep_its_hold() -> None:
    """``twist-29`` (raw, EKF) without gyro biases, their rates' noise taken as 0.015
    rad/s (at the default 0.01 the readings disagree with this model from the first
    sample, and no row is ``ok`` to restart from): the drift resets at 0.78 and 2.82 s
    restart a model that does not follow, whose rows drift again from 4.08 to 4.34 s.
    The rows after those drifted ones are held as the restart's are (uncertain within
    the probation time of the last drifted row): the 23 of them from 4.36 to 4.8 s are
    up to 4.1 standard deviations off the truth on a tip axis. No ok row is more than 4
    off."""
    options = InputOptions(
        tensions=str(DATA / "twist-29_tensions.csv"), estimate_gyro_bias=False, gyro_std=0.015
    )
    base = make_formulation("bend", read_robot(ROBOT))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open_input(DATA / "twist-29_raw.csv", options, base) as s:
            f = s.formulation
            blocks = list(s.blocks)
    t = np.concatenate([b[0] for b in blocks])
    z = np.vstack([b[1] for b in blocks])
    est = make_estimator("ekf", f)  # type: ignore[arg-type]
    series = est.run(t, z)
    status = np.asarray(series.status)
    assert est.diagnostics.drift_resets >= 2
    assert np.count_nonzero(status[(t > 2.83) & (t < 4.35)] == "drifted") >= 5
    names = [o.name for o in f.outputs]
    cols = [names.index(c) for c in "xyz"]
    truth = read_state_table(DATA / "twist-29_truth.csv")
    off = np.asarray(series.output, float)[:, cols] - np.stack(
        [truth.column(c) for c in "xyz"], axis=1
    )
    sigmas = np.max(np.abs(off) / np.asarray(series.output_std, float)[:, cols], axis=1)
    assert np.count_nonzero(status == "ok") >= 8
    assert not np.any((status == "ok") & (sigmas > 4.0)), t[(status == "ok") & (sigmas > 4.0)]
    held = (t >= 4.36 - 1e-9) & (t <= 4.8 + 1e-9)
    assert np.count_nonzero(held) == 23 and np.all(status[held] == "uncertain"), status[held]
    assert sigmas[held].max() > 4.0
