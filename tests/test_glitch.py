"""An IMU reading far beyond the prediction from an ``ok`` estimate is skipped as a
glitch (``RecoverySettings.glitch``, :data:`~continuum_mhe.settings.GLITCH_FACTOR`): the
row is ``inconsistent``, the estimate is the prediction without that IMU, and the next
reading is taken, as the robot may have moved so."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import RecoverySettings
from continuum_mhe.simulation.scenarios import simulate

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"


def _upside_down_raw(path: Path, out: Path, row: int, imu: int) -> None:
    """``path`` with IMU ``imu``'s raw reading of data row ``row`` turned upside down
    (a half turn about its x axis: y and z of the accelerometer and the gyro negated)."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    fields = lines[1 + row].split(",")
    for c in ("ay", "az", "gy", "gz"):
        k = header.index(f"{c}_{imu}")
        fields[k] = repr(-float(fields[k]))
    lines[1 + row] = ",".join(fields)
    out.write_text("\n".join(lines) + "\n")


def _force29(tmp_path: Path, meas: Path, glitch: str) -> tuple[np.ndarray, ...]:
    """``estimate`` of the tendon robot's recording ``meas`` (force-29's raw readings, a
    fault in them) with its tensions and ``--glitch glitch`` (``"0"``: with the drift
    reset off too, which would restart the estimate from the IMU errors before the
    fault: the glitch skip alone is measured): ``(status, tip error m, tip std m)`` per
    row, the error against force-29's truth."""
    tendon = DATA / "tendon"
    out = tmp_path / "est.csv"
    alone = ["--drift-reset", "0"] if glitch == "0" else []
    assert (
        main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
              str(tendon / "force-29_tensions.csv"), "--glitch", glitch, "-o", str(out),
              *alone])
        == 0
    )  # fmt: skip
    with out.open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    with (tendon / "force-29_truth.csv").open() as fh:
        truth = list(csv.DictReader(fh))
    assert np.allclose([float(r["t"]) for r in truth], [float(r["t"]) for r in rows])
    tip = np.array([[float(r[c]) for c in "xyz"] for r in rows])
    true_tip = np.array([[float(r[c]) for c in "xyz"] for r in truth])
    std = np.array([math.hypot(*(float(r[f"std_{c}"]) for c in "xyz")) for r in rows])
    status = np.array([r["status"] for r in rows])
    return status, np.linalg.norm(tip - true_tip, axis=1), std


def _gyro_spike(path: Path, out: Path, row: int) -> None:
    """``path`` with 1 rad/s added to ``gx_1`` of data row ``row``."""
    lines = path.read_text().splitlines()
    k = lines[0].split(",").index("gx_1")
    fields = lines[1 + row].split(",")
    fields[k] = repr(float(fields[k]) + 1.0)
    lines[1 + row] = ",".join(fields)
    out.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("glitch", ["3", "0"])
def test_one_upside_down_raw_reading_does_not_cost_a_tendon_robot_the_recording(
    tmp_path: Path, glitch: str
) -> None:
    """force-29 (raw IMUs, the tendon robot's EKF), IMU 1's reading at 1.2 s upside down.
    Taken (``--glitch 0``), it moves the IMUs' error states, the estimator restarts on
    the readings that then disagree, and a restart under load cannot tell the load
    from those errors: most of the recording is lost (none of it ``ok``). Skipped, the
    rest is estimated as without it."""
    meas = tmp_path / "raw.csv"
    _upside_down_raw(DATA / "tendon" / "force-29_raw.csv", meas, 60, 1)
    status, err, _ = _force29(tmp_path, meas, glitch)
    if glitch == "0":
        assert np.sum(status == "ok") < 100 and np.mean(err) > 0.02
    else:
        assert status[60] == "inconsistent"
        assert np.sum(status == "ok") >= 395
        assert np.mean(err) < 2e-3 and np.max(err[status == "ok"]) < 5e-3


@pytest.mark.parametrize("glitch", ["3", "0"])
def test_one_gyro_spike_leaves_no_ok_row_far_off_on_a_tendon_robot(
    tmp_path: Path, glitch: str
) -> None:
    """force-29 (raw IMUs, the EKF), 1 rad/s added to one reading of IMU 1's x gyro at
    3 s. Taken, it moves the IMUs' error states and the estimate: rows 20 mm and 3 of
    their standard deviations off say ``ok``. Skipped, none does."""
    meas = tmp_path / "raw.csv"
    _gyro_spike(DATA / "tendon" / "force-29_raw.csv", meas, 150)
    status, err, std = _force29(tmp_path, meas, glitch)
    far_ok = (status == "ok") & (err > 0.02) & (err > 3 * std)
    if glitch == "0":
        assert far_ok.sum() > 10
    else:
        assert status[150] == "inconsistent" and not far_ok.any()
        assert np.max(err[status == "ok"]) < 5e-3


def _shipped_rod(path: Path) -> tuple[object, np.ndarray, np.ndarray]:
    """``(formulation, t, z)`` of a two-section rod recording, read as ``estimate``
    reads it with the defaults (raw IMUs: the direct model with gyro biases)."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import open_input

    base = make_formulation("bend", read_robot("two-section"))
    with open_input(path, InputOptions(), base) as stream:
        f = stream.formulation
        blocks = list(stream.blocks)
    return f, np.concatenate([b[0] for b in blocks]), np.vstack([b[1] for b in blocks])


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_an_upside_down_raw_reading_is_skipped_once(tmp_path: Path, method: str) -> None:
    """The shipped two-section rod (spatial-tendon, raw IMUs), IMU 2's reading at 4 s
    upside down: that reading alone is skipped, its row is ``inconsistent``, and the
    estimates from half a second after it are within a millimetre of the clean
    recording's."""
    shipped = DATA / "rod2" / "spatial-tendon_raw.csv"
    flipped = tmp_path / "flipped.csv"
    _upside_down_raw(shipped, flipped, 200, 2)
    f, t, z = _shipped_rod(flipped)
    est = make_estimator(method, f)  # type: ignore[arg-type]
    s = est.run(t, z)
    assert est.diagnostics.glitches == 1
    assert s.status[200] == "inconsistent"
    _, _, z_clean = _shipped_rod(shipped)
    clean = make_estimator(method, f).run(t, z_clean)  # type: ignore[arg-type]
    after = slice(225, None)
    gap = np.linalg.norm(
        np.asarray(s.output)[after, :3] - np.asarray(clean.output)[after, :3], axis=1
    )
    assert np.max(gap) < 1e-3


def test_a_lasting_jump_is_taken_from_its_second_reading() -> None:
    """Readings that jump and stay (the roll of paper3d's tilt IMU 1 rad more from 5 s
    on): the first is skipped, the second taken (the row before it was not ``ok``), and
    the estimate follows them."""
    rec = simulate("paper3d", duration=10.0, seed=0)
    z = rec.z.copy()
    i = int(np.searchsorted(rec.t, 5.0))
    z[i:, 0] += 1.0
    f = make_formulation("bend")
    est = make_estimator("ekf", f)
    s = est.run(rec.t, z)
    assert est.diagnostics.glitches == 1
    assert s.status[i] == "inconsistent"
    moved = make_estimator("ekf", f, recovery=RecoverySettings(glitch=None)).run(rec.t, z)
    # one sample later than the estimator that takes the jump, the same estimates
    late = rec.t >= 7.0
    np.testing.assert_allclose(
        np.asarray(s.output)[late, :3], np.asarray(moved.output)[late, :3], atol=1e-4
    )


@pytest.mark.parametrize("kind", ["raw", "tilt"])
def test_no_reading_of_the_shipped_rods_is_a_glitch(kind: str) -> None:
    """The shipped two-section rod recordings (model errors, restarts and all): the EKF
    skips none of their readings."""
    for name in ("planar-s", "spatial-tendon", "spatial-stiff-torsion"):
        f, t, z = _shipped_rod(DATA / "rod2" / f"{name}_{kind}.csv")
        est = make_estimator("ekf", f)  # type: ignore[arg-type]
        est.run(t, z)
        assert est.diagnostics.glitches == 0, name


def test_glitch_off_and_a_robust_loss_skip_nothing() -> None:
    """``RecoverySettings(glitch=None)`` (``--glitch 0``) and a robust MHE (its loss
    weighs such readings) take every reading; 0 is refused (None means never)."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.settings import MHESettings

    rec = simulate("paper3d", duration=4.0, seed=1)
    z = rec.z.copy()
    z[40, 0] += -math.pi if z[40, 0] > 0 else math.pi  # upside down
    f = make_formulation("bend")
    off = make_estimator("ekf", f, recovery=RecoverySettings(glitch=None))
    off.run(rec.t, z)
    robust = make_estimator("mhe", f, MHESettings(loss="huber"))
    robust.run(rec.t, z)
    on = make_estimator("ekf", f)
    on.run(rec.t, z)
    assert (off.diagnostics.glitches, robust.diagnostics.glitches, on.diagnostics.glitches) == (
        0,
        0,
        1,
    )
    with pytest.raises(UserError, match="glitch"):
        RecoverySettings(glitch=0.0)


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_an_upside_down_tilt_reading_is_skipped(method: str) -> None:
    """paper3d, its reading at 3 s turned upside down (roll plus pi, pitch negated: the
    opposite gravity direction, where the tilt residual and its linearised prediction
    both grow without bound, so that the NIS alone stays small): judged with the
    Jacobian at the reading before, it is skipped, the rows of the second after it are
    ``ok``, and from then on the estimates are within a millimetre of the clean
    recording's."""
    rec = simulate("paper3d", duration=8.0, seed=0)
    z = rec.z.copy()
    i = int(np.searchsorted(rec.t, 3.0))
    z[i, 0] += -math.pi if z[i, 0] > 0 else math.pi
    z[i, 1] = -z[i, 1]
    f = make_formulation("bend")
    est = make_estimator(method, f)
    s = est.run(rec.t, z)
    assert est.diagnostics.glitches == 1 and s.status[i] == "inconsistent"
    after = (rec.t > rec.t[i]) & (rec.t < rec.t[i] + 1.0)
    assert np.all(s.status[after] == "ok")
    clean = make_estimator(method, f).run(rec.t, rec.z)
    later = rec.t >= rec.t[i] + 1.0
    gap = np.linalg.norm(
        np.asarray(s.output)[later, :3] - np.asarray(clean.output)[later, :3], axis=1
    )
    assert np.max(gap) < 1e-3


def test_an_upside_down_tilt_reading_on_a_tendon_robot_is_skipped(tmp_path: Path) -> None:
    """The tendon robot's unloaded recording with tilt IMUs, IMU 2's reading at 1.2 s
    upside down: skipped, the statuses are those of the clean recording but that row's
    (taken, 189 rows are ``drifted``: the IMU error states carry it)."""
    tendon = DATA / "tendon"
    lines = (tendon / "unloaded_tilt.csv").read_text().splitlines()
    header, fields = lines[0].split(","), lines[61].split(",")
    roll, pitch = header.index("roll_2"), header.index("pitch_2")
    r = float(fields[roll])
    fields[roll], fields[pitch] = (
        repr(r - math.pi if r > 0 else r + math.pi),
        repr(-float(fields[pitch])),
    )
    lines[61] = ",".join(fields)
    meas = tmp_path / "tilt.csv"
    meas.write_text("\n".join(lines) + "\n")
    statuses = {}
    for name, path in (("flipped", meas), ("clean", tendon / "unloaded_tilt.csv")):
        out = tmp_path / f"{name}.csv"
        assert (
            main(["estimate", str(path), "--robot", "tendon-two-section", "--inputs",
                  str(tendon / "unloaded_tensions.csv"), "-o", str(out)])
            == 0
        )  # fmt: skip
        with out.open() as fh:
            rows = csv.DictReader(line for line in fh if not line.startswith("#"))
            statuses[name] = np.array([r["status"] for r in rows])
    differ = np.flatnonzero(statuses["flipped"] != statuses["clean"])
    assert list(differ) == [60] and statuses["flipped"][60] == "inconsistent"


def test_glitch_with_a_robust_loss_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--glitch`` with ``--loss``: the robust MHE weighs such readings itself, so the
    option would do nothing; one line says so, exit 2, nothing written."""
    out = tmp_path / "o.csv"
    rc = main(["estimate", str(DATA / "rod2" / "planar-s_tilt.csv"), "--robot", "two-section",
               "--method", "mhe", "--loss", "huber", "--glitch", "5", "-o", str(out)])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and not out.exists()
    assert len(err) == 1 and "--glitch does not apply with --loss huber" in err[0]


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_where_nothing_is_skipped_the_estimates_are_those_without_the_test(method: str) -> None:
    """The shipped spatial-tendon rod (raw IMUs), where no reading is skipped: every
    estimate, standard deviation and status equals, bit for bit, those of a run without
    the glitch test (the consistency check's prediction, kept for the same inputs, is the
    one it would compute)."""
    f, t, z = _shipped_rod(DATA / "rod2" / "spatial-tendon_raw.csv")
    on = make_estimator(method, f)  # type: ignore[arg-type]
    s_on = on.run(t, z)
    s_off = make_estimator(method, f, recovery=RecoverySettings(glitch=None)).run(t, z)  # type: ignore[arg-type]
    assert on.diagnostics.glitches == 0
    np.testing.assert_array_equal(s_on.status, s_off.status)
    np.testing.assert_array_equal(np.asarray(s_on.output), np.asarray(s_off.output))
    np.testing.assert_array_equal(np.asarray(s_on.output_std), np.asarray(s_off.output_std))


def test_a_skip_is_taken_back_when_the_step_fails_and_the_estimator_restarts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A step that fails numerically on a sample with a skipped reading restarts from
    that sample's readings, all of them: the restart sees the reading, and the
    reading is not counted as skipped (the row is ``reset``)."""
    from continuum_mhe.estimators.base import Measurement
    from continuum_mhe.estimators.kalman import (
        CasadiExtendedKalmanFilter,
        ExtendedKalmanInference,
    )

    rec = simulate("paper3d", duration=4.0, seed=1)
    z = rec.z.copy()
    i = 40
    z[i, 0] += -math.pi if z[i, 0] > 0 else math.pi  # upside down
    seen: list[np.ndarray] = []
    infer = ExtendedKalmanInference.infer

    def fail_once_at_i(self: ExtendedKalmanInference, m: Measurement) -> object:
        if m.t == rec.t[i]:
            seen.append(np.array(m.z))
            if len(seen) == 1:
                raise np.linalg.LinAlgError("forced")
        return infer(self, m)

    f = make_formulation("bend")
    skipped = CasadiExtendedKalmanFilter(f)
    skipped.run(rec.t, z)
    assert skipped.diagnostics.glitches == 1  # the reading is a glitch to this estimator

    monkeypatch.setattr(ExtendedKalmanInference, "infer", fail_once_at_i)
    est = CasadiExtendedKalmanFilter(f)
    s = est.run(rec.t, z)
    assert len(seen) == 2
    assert np.isnan(seen[0][0]) and seen[1][0] == z[i, 0]  # skipped, then taken
    assert est.diagnostics.restarts == 1 and est.diagnostics.glitches == 0
    assert s.status[i] == "reset"


@pytest.mark.parametrize(("share", "skipped"), [(0.9, 0), (1.1, 1)])
def test_the_glitch_limit_is_its_factor_times_the_quantile(share: float, skipped: int) -> None:
    """A pitch reading offset so that its normalised innovation against the prediction
    from the ``ok`` estimate before it is 0.9 or 1.1 times ``GLITCH_FACTOR`` times the
    chi-square 99.99 % quantile of its two degrees of freedom (the readings scattered at
    their noise model's level or less): kept, or skipped as a glitch. The innovation is
    computed here from the formulation's own functions: ``x, F, Q = predict(x, u,
    dt)``, ``S = H (F P F^T + Q) H^T + R``."""
    from scipy.stats import chi2

    from continuum_mhe.estimators.consistency import SAMPLE_QUANTILE
    from continuum_mhe.estimators.sensor_health import Measurement
    from continuum_mhe.settings import GLITCH_FACTOR

    assert SAMPLE_QUANTILE == 0.9999  # as docs/options.md states it
    rec = simulate("paper3d", duration=4.0, seed=0)
    f = make_formulation("bend")
    i = int(np.searchsorted(rec.t, 3.0))
    est = make_estimator("ekf", f)
    est.reset()
    for t, z in zip(rec.t[:i], rec.z[:i], strict=True):
        before = est.step(Measurement(float(t), z))
    assert before.status == "ok" and est._consistency.noise_scale <= 1.0
    R = np.asarray(f.meas_cov(), dtype=float)
    dt = float(rec.t[i] - rec.t[i - 1])
    xn, F, Q = (np.asarray(v, dtype=float) for v in f.functions.predict(before.state, [], dt))
    S_pred = F @ before.covariance @ F.T + Q

    def nis(offset: float) -> float:
        z = rec.z[i] + np.array([0.0, offset])
        r, J = (np.asarray(v, dtype=float) for v in f.functions.innovate(z, xn.ravel()))
        S = J @ S_pred @ J.T + R
        return float(r.ravel() @ np.linalg.solve(S, r.ravel()))

    limit = GLITCH_FACTOR * chi2.ppf(0.9999, 2)
    lo, hi = 0.0, 1.0  # rad: bisection for the offset whose NIS is share x the limit
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if nis(mid) < share * limit else (lo, mid)
    z = rec.z[i] + np.array([0.0, hi])
    est.step(Measurement(float(rec.t[i]), z))
    assert est.diagnostics.glitches == skipped


def _rod_tilt(name: str, every: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, z, tip truth)`` of a shipped two-section rod's tilt recording, every
    ``every``-th row of it (50: 1 Hz)."""
    rows = np.genfromtxt(DATA / "rod2" / f"{name}_tilt.csv", delimiter=",", names=True)
    truth = np.genfromtxt(DATA / "rod2" / f"{name}_truth.csv", delimiter=",", names=True)
    rows, truth = rows[::every], truth[::every]
    z = np.column_stack([rows[c] for c in ("roll_1", "pitch_1", "roll_2", "pitch_2")])
    return rows["t"], z, np.column_stack([truth["x"], truth["y"], truth["z"]])


def _turn_upside_down(z: np.ndarray, k: int, imu: int) -> np.ndarray:
    """``z`` with IMU ``imu``'s tilt reading ``k`` upside down (roll plus or minus pi,
    pitch negated)."""
    z = z.copy()
    j = 2 * (imu - 1)
    z[k, j] += -math.pi if z[k, j] > 0 else math.pi
    z[k, j + 1] = -z[k, j + 1]
    return z


def test_the_row_that_one_reading_narrows_after_a_wide_one_is_not_ok_at_1_hz() -> None:
    """The shipped spatial-tendon rod's tilt recording at 1 Hz, IMU 2's reading at 2 s
    upside down. The row at 1 s is ``uncertain``, its tip standard deviation (with the
    readings' constant errors) beyond the fraction; against its prediction, a second
    later, half a turn of IMU 2 is within the noise (NIS below 1 with the Jacobian at
    the reading before), so no test skips it, and the MHE fits it with a shape 177 mm
    from the rod's and a 12 mm standard deviation. The row after a wide one is held
    ``uncertain`` for the unobserved window (1 s), which at 1 Hz ended with the next
    reading; it is held for the first row with a reading as well: no row more than 50
    mm off is ``ok``, in the MHE, the EKF or the UKF."""
    t, z, tip = _rod_tilt("spatial-tendon", 50)
    k = int(np.argmin(np.abs(t - 2.0)))
    f = make_formulation("bend", read_robot("two-section"))
    for method in ("mhe", "ekf", "ukf"):
        s = make_estimator(method, f).run(t, _turn_upside_down(z, k, 2))
        err = np.linalg.norm(np.asarray(s.output)[:, :3] - tip, axis=1)
        if method == "mhe":
            assert err[k] > 0.1  # the MHE fits the reading half a turn off
        assert not np.any((err > 0.05) & (s.status == "ok")), method


@pytest.mark.parametrize(("name", "imu", "k"), [("spatial-tendon", 1, 4), ("spatial", 2, 5)])
def test_an_estimate_moved_beyond_its_prediction_is_not_ok_at_1_hz(name, imu, k) -> None:
    """The shipped rods' tilt recordings at 1 Hz, one reading upside down after a row
    that is not ``ok`` (the glitch test does not judge it): against the prediction a
    second ahead, the reading is near (its linearised NIS within the limit), and the
    MHE's window fits it with a shape 372 mm (``spatial-tendon``) from the rod's, ``ok``
    with a 10 mm standard deviation (on ``spatial`` two rows later, 54 mm). The estimate
    moved from the prediction farther than a linear update by readings within the limit
    can (``x - f(x0)`` in the predicted covariance, beyond the NIS limit): the row is
    ``inconsistent``, and from the reading on no row more than 50 mm off is ``ok``, in
    any estimator (before it, ``spatial``'s second row is the MHE's confirmation of its
    start by one reading, ``ok`` 109 mm off with or without the glitch)."""
    t, z, tip = _rod_tilt(name, 50)
    f = make_formulation("bend", read_robot("two-section"))
    for method in ("mhe", "ekf", "ukf"):
        s = make_estimator(method, f).run(t, _turn_upside_down(z, k, imu))
        err = np.linalg.norm(np.asarray(s.output)[:, :3] - tip, axis=1)
        assert not np.any((err[k:] > 0.05) & (s.status[k:] == "ok")), method


def test_an_upside_down_reading_right_after_the_start_at_1_hz_is_not_ok() -> None:
    """The shipped planar-s rod's tilt recording at 1 Hz (every 50th row), IMU 1's
    second reading upside down: against the first estimate's prediction its NIS is 2.7
    (the tilt residual's linearised prediction widens with it), and taken, the MHE fits
    it with a shape 371 mm from the rod's, ``ok``. The glitch test judges the reading
    after a start's first estimate too (with the Jacobian at the reading before): it is
    skipped as a glitch, its row ``inconsistent``, and no row more than 50 mm off is
    ``ok``, in the MHE or the EKF."""
    t, z, tip = _rod_tilt("planar-s", 50)
    f = make_formulation("bend", read_robot("two-section"))
    for method in ("mhe", "ekf"):
        est = make_estimator(method, f)
        s = est.run(t, _turn_upside_down(z, 1, 1))
        err = np.linalg.norm(np.asarray(s.output)[:, :3] - tip, axis=1)
        assert est.diagnostics.glitches == 1 and s.status[1] == "inconsistent", method
        assert not np.any((err > 0.05) & (s.status == "ok")), method


def test_a_wrong_first_reading_is_left_to_the_bad_start_check_not_the_glitch_test() -> None:
    """The shipped planar-s rod's tilt recording with IMU 1's first roll 1 rad off: the
    start fits it, and the correct readings after it lie far from the start by their
    prediction as well, which says that the start may be wrong: the glitch test, armed
    from a start's first estimate for a reading near the opposite gravity direction
    alone, skips none of them (the bad-start check restarts the estimate), and every
    estimator gives the same rows with the glitch test on as off."""
    t, z, _ = _rod_tilt("planar-s", 1)
    z = z.copy()
    z[0, 0] += 1.0
    f = make_formulation("bend", read_robot("two-section"))
    for method in ("mhe", "ekf", "ukf"):
        on = make_estimator(method, f)
        off = make_estimator(method, f, recovery=RecoverySettings(glitch=None))
        a, b = on.run(t, z), off.run(t, z)
        assert on.diagnostics.glitches == 0, method
        assert list(a.status) == list(b.status) and "reset" in set(a.status), method
        np.testing.assert_array_equal(a.output, b.output)


def test_two_restarts_in_a_row_after_an_upside_down_reading_leave_no_far_row_ok() -> None:
    """The shipped spatial-tendon rod's tilt recording (50 Hz), IMU 1's reading at 8 s
    upside down, after rows that are ``uncertain`` (the glitch test does not judge it):
    the UKF fails on it and restarts from it, fails on the next reading and restarts from
    that one alone, on the other branch of the readings' ambiguous shapes (section 1
    past 90 degrees). Confirmed by two agreeing readings, as a single forced restart is,
    the row at 8.06 s was ``ok``, 134 mm and 15 of its standard deviations off; a
    restart forced before the one before it was confirmed takes five, as an
    unconfirmed first estimate does."""
    t, z, tip = _rod_tilt("spatial-tendon", 1)
    f = make_formulation("bend", read_robot("two-section"))
    s = make_estimator("ukf", f).run(t, _turn_upside_down(z, 400, 1))
    err = np.linalg.norm(np.asarray(s.output)[:, :3] - tip, axis=1)
    near = (t >= 8.0) & (t < 9.0)
    assert np.max(err[near]) > 0.1  # the restarts put the estimate far off
    assert not np.any((err > 0.05) & (s.status == "ok"))


def test_two_restarts_in_a_row_apart_by_a_sample_without_readings_leave_no_far_row_ok() -> None:
    """As above, with a sample that carries no reading (a dropout line) between the two
    restarts: the second still follows the first with no reading between them, and is
    confirmed by five readings (with two, the row at 8.06 s is ``ok`` 134 mm off)."""
    t, z, tip = _rod_tilt("spatial-tendon", 1)
    z = _turn_upside_down(z, 400, 1)
    t = np.insert(t, 401, 8.01)
    z = np.insert(z, 401, np.nan, axis=0)
    tip = np.insert(tip, 401, tip[400], axis=0)
    f = make_formulation("bend", read_robot("two-section"))
    s = make_estimator("ukf", f).run(t, z)
    err = np.linalg.norm(np.asarray(s.output)[:, :3] - tip, axis=1)
    assert not np.any((err > 0.05) & (s.status == "ok"))


def test_a_forward_clock_jump_restarts_and_is_named_not_skipped_as_a_glitch(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped planar-s rod (raw IMUs, 50 Hz) whose clock steps 0.9 s forward at 4 s
    (every later stamp shifted, no reading lost), shorter than the gap reset: the
    readings after the jump disagree with the prediction across it, which is no glitch
    of one reading; the EKF restarts there (``reset``, ``Diagnostics.jump_resets``) and
    the summary names the jump. Skipped as a glitch, that row is 128 mm off and the
    next second ``uncertain``."""
    lines = (DATA / "rod2" / "planar-s_raw.csv").read_text().splitlines()
    shifted = [lines[0]]
    for line in lines[1:]:
        t, rest = line.split(",", 1)
        shifted.append(f"{float(t) + 0.9 if float(t) >= 4.0 - 1e-9 else float(t):.10g},{rest}")
    meas, out = tmp_path / "jumped.csv", tmp_path / "est.csv"
    meas.write_text("\n".join(shifted) + "\n")
    assert main(["estimate", str(meas), "--robot", "two-section", "--method", "ekf",
                 "-o", str(out)]) == 0  # fmt: skip
    said = capsys.readouterr()
    text = said.out + said.err
    assert "restarted after 1 jump(s) in t shorter than 1 s" in text
    assert "0.92 s long, before t = 4.9 s" in text and "glitches" not in text
    assert "estimated across" not in text  # restarted there: not a gap predicted across
    with out.open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    with (DATA / "rod2" / "planar-s_truth.csv").open() as fh:
        truth = list(csv.DictReader(fh))
    after = [i for i, r in enumerate(rows) if 4.9 - 1e-9 <= float(r["t"]) < 5.9]
    assert rows[after[0]]["status"] == "reset"
    for i in after:  # the same sample of the truth: no reading was lost
        err = math.dist(*([float(r[c]) for c in "xyz"] for r in (rows[i], truth[i])))
        assert err < 0.02, rows[i]["t"]
