"""Multi-section robots: PCC kinematics, the robot file, per-IMU dropouts, filters
against filterpy, the estimators on two sections, and bad robot files."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import bare
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF
from header_helpers import assert_header_refused, imu_columns, renamed
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from continuum_mhe.analysis.observability import observability_report
from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import ekf_update
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.io import write_robot
from continuum_mhe.io.csv_files import DropoutWarning, read_measurements
from continuum_mhe.io.robot_file import RobotFileWarning, read_robot, robot_toml
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.formulations import AT_BOUND_TOL
from continuum_mhe.model.pcc import bend_from_tangent_frames, pose_at
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate_robot

TWO = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
ROBOT_FILE = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/two_section.toml"


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def integrated_backbone(bends: np.ndarray, lengths: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Tip frame and position by integrating ``dR/ds = R [k]x``, ``dp/ds = R e_z`` with
    the piecewise-constant curvature ``k = (b, -a, 0) / L`` of each section (an
    independent route to the composed kinematics)."""
    R, p = np.eye(3), np.zeros(3)
    for (a, b), length in zip(bends, lengths):
        kappa = np.array([b, -a, 0.0]) / length

        def rhs(_s: float, y: np.ndarray, kappa: np.ndarray = kappa) -> np.ndarray:
            Rs = y[:9].reshape(3, 3)
            return np.concatenate([(Rs @ _skew(kappa)).ravel(), Rs[:, 2]])

        sol = solve_ivp(rhs, (0, length), np.concatenate([R.ravel(), p]), rtol=1e-11, atol=1e-12)
        R, p = sol.y[:9, -1].reshape(3, 3), sol.y[9:, -1]
    return R, p


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-2.5, 2.5), min_size=6, max_size=6))
def test_composed_kinematics_equal_integrated_backbone(u: list[float]) -> None:
    bends = np.array(u).reshape(3, 2)
    lengths = [0.1, 0.07, 0.05]
    R, p = pose_at(bends, lengths, 2)
    R_ref, p_ref = integrated_backbone(bends, lengths)
    assert_allclose(R, R_ref, atol=1e-8)
    assert_allclose(p, p_ref, atol=1e-9)


@pytest.mark.parametrize("u", [[0.0, 0.0, 0.0, 0.0], [0.4, -0.3, 0.0, 0.0], [0.0, 0.0, 1e-9, 0]])
def test_output_jacobian_matches_finite_differences_including_straight(u: list[float]) -> None:
    f = make_formulation("bend", TWO)
    x = np.array([*u, 0.0, 0.0, 0.0, 0.0])
    import casadi as ca

    xs = ca.SX.sym("x", f.nx)
    jac = ca.Function("j", [xs], [ca.jacobian(f.output_sym(xs)[[0, 1, 2, 5, 6, 7]], xs[:4])])
    J = np.asarray(jac(x), dtype=float)
    h = 1e-6
    fd = np.zeros_like(J)
    cols = [0, 1, 2, 5, 6, 7]
    for j in range(4):
        e = np.zeros(f.nx)
        e[j] = h
        fd[:, j] = (f.output(x + e)[cols] - f.output(x - e)[cols]) / (2 * h)
    assert np.all(np.isfinite(J))
    assert_allclose(J, fd, atol=1e-8)


def test_same_curvature_sections_equal_one_longer_section() -> None:
    # two sections with the same bend per unit length form one arc of the total length
    one = make_formulation("bend", Robot.single(0.3, 3.0))
    two = make_formulation("bend", TWO)
    a, b = 1.1, -0.4  # total bend of the arc
    x_two = np.array([a * 0.16 / 0.3, b * 0.16 / 0.3, a * 0.14 / 0.3, b * 0.14 / 0.3, 0, 0, 0, 0])
    x_one = np.array([a, b, 0, 0])
    assert_allclose(two.output(x_two)[:3], one.output(x_one)[:3], atol=1e-14)
    h_one = np.asarray(one.functions.observe(x_one), dtype=float).ravel()
    h_two = np.asarray(two.functions.observe(x_two), dtype=float).ravel()
    assert_allclose(h_two[2:], h_one, atol=1e-12)  # the tip IMU reads the same tilt


def test_straight_second_section_equals_one_section_model() -> None:
    one = make_formulation("bend", Robot.single(0.16, 3.0))
    two = make_formulation("bend", TWO)
    x_two = np.array([0.7, 0.2, 0.0, 0.0, 0, 0, 0, 0])
    out = two.output(x_two)
    names = [o.name for o in two.outputs]
    ref = one.output(np.array([0.7, 0.2, 0.0, 0.0]))  # x, y, z, theta, phi
    got = [out[names.index(n)] for n in ("x_1", "y_1", "z_1", "theta_1", "phi_1")]
    assert_allclose(got, ref, atol=1e-15)
    h = np.asarray(two.functions.observe(x_two), dtype=float).ravel()
    assert_allclose(h[2:], h[:2], atol=1e-14)  # a straight section does not turn the IMU


def test_imu_inside_a_section_sees_the_partial_bend() -> None:
    mid = Robot((Section(0.2),), (ImuPlacement(0, 0.5),))
    f = make_formulation("bend", mid)
    tip = make_formulation("bend", Robot.single(0.2))
    h_mid = np.asarray(f.functions.observe([0.6, 0.2, 0, 0]), dtype=float).ravel()
    h_tip = np.asarray(tip.functions.observe([0.3, 0.1, 0, 0]), dtype=float).ravel()
    assert_allclose(h_mid, h_tip, atol=1e-14)


def test_bend_from_tangent_frames_inverts_the_kinematics() -> None:
    bends = np.array([[0.5, -1.2], [-0.9, 0.3]])
    R1 = pose_at(bends, [0.16, 0.14], 0)[0]
    R2 = pose_at(bends, [0.16, 0.14], 1)[0]
    assert_allclose(bend_from_tangent_frames(np.eye(3), R1), bends[0], atol=1e-12)
    assert_allclose(bend_from_tangent_frames(R1, R2), bends[1], atol=1e-12)


@pytest.mark.parametrize("name", ["bend", "direct"])
@pytest.mark.parametrize("at", [(1.0, 1.0), (0.5, 0.5), (1 / 3, 1.0)])
def test_initial_state_inverts_the_measurement(name: str, at: tuple[float, float]) -> None:
    """The start's bends from the readings of IMUs at the sections' ends or part-way
    along them (``at``): the readings' own shape."""
    robot = Robot(TWO.sections, (ImuPlacement(0, at[0]), ImuPlacement(1, at[1])), TWO.mounting)
    f = make_formulation(name, robot)
    if name == "direct":  # the bends and rates alone
        f = replace(f, estimate_gyro_bias=False)
    x = np.array([0.3, -0.2, 0.5, 0.4, 0.1, 0.2, -0.1, 0.3])
    h = np.asarray(f.functions.observe(x), dtype=float).ravel()
    x0 = f.initial_state(h)
    assert_allclose(x0[:4], x[:4], atol=1e-7)
    if name == "direct":
        assert_allclose(x0[4:], x[4:], atol=1e-7)


# --- per-IMU dropouts ---------------------------------------------------------------------
def test_ekf_update_with_one_imu_masked_equals_the_robot_without_that_imu() -> None:
    f = make_formulation("bend", TWO)
    only_first = make_formulation("bend", Robot(TWO.sections, (ImuPlacement(0),), TWO.mounting))
    x = np.array([0.3, -0.2, 0.5, 0.4, 0.1, 0.2, -0.1, 0.3])
    P = np.diag(np.linspace(0.01, 0.2, 8))
    z = np.array([0.21, -0.3, np.nan, np.nan])
    mask = f.measurement_mask(z)
    assert_allclose(mask, [1, 1, 0, 0])
    x1, P1 = ekf_update(f, x, P, z, f.meas_cov(), mask)
    x2, P2 = ekf_update(only_first, x, P, z[:2], only_first.meas_cov())
    assert_allclose(x1, x2, atol=1e-14)
    assert_allclose(P1, P2, atol=1e-14)


@pytest.mark.parametrize(
    ("method", "solver"), [("ekf", "fast"), ("ukf", "fast"), ("mhe", "ipopt"), ("mhe", "fast")]
)
def test_one_imu_dropout_keeps_the_other(method: str, solver: str) -> None:
    rec = simulate_robot("s-curve", TWO, duration=4.0, dt=0.05, seed=2)
    z = rec.z.copy()
    z[20:45, 2:] = np.nan  # IMU 2 drops out for 1.25 s
    f = make_formulation("bend", TWO)
    est = make_estimator(method, f, MHESettings(horizon=10, solver=solver))  # type: ignore[arg-type]
    series = est.run(rec.t, z)
    assert np.all(np.isfinite(series.output))
    # IMU 1 still updates; the tip may be too uncertain to trust without IMU 2
    assert set(series.status[20:45]) <= {"ok", "fallback-ipopt", "uncertain"}
    # section 1's end during the dropout is the run's without it, to well under the 29 mm
    # by which a run that loses both IMUs there departs from it (that run to the
    # dropout's end: an estimate depends on no later reading)
    again = make_estimator(method, f, MHESettings(horizon=10, solver=solver))  # type: ignore[arg-type]
    whole = again.run(rec.t[:45], rec.z[:45])
    names = [o.name for o in f.outputs]
    end_1 = [names.index(c) for c in ("x_1", "y_1", "z_1")]
    apart = np.abs(series.output[20:45][:, end_1] - whole.output[20:45][:, end_1])
    assert apart.max() < 0.002
    m = compute_metrics(series.output, rec.truth, TWO.length, names)
    assert m.section_end_mean_mm["1"] < 8.0


def _two_imu_file(path: Path, edit: dict[int, str]) -> tuple[Path, list[str]]:
    """A simulated two-IMU tilt CSV (41 rows) with rows ``edit`` replaced (0-based)."""
    rec = simulate_robot("s-curve", TWO, duration=2.0, dt=0.05, seed=2)
    rows = [",".join(f"{v:.6f}" for v in (t, *z)) for t, z in zip(rec.t, rec.z)]
    for i, fields in edit.items():
        rows[i] = f"{rec.t[i]:.6f},{fields}"
    path.write_text("\n".join(["t,roll_1,pitch_1,roll_2,pitch_2", *rows]) + "\n")
    return path, rows


def test_partial_dropouts_are_counted_and_the_status_says_dropout_only_without_any_imu(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 2 missing on two rows and IMU 1 on one: the summary counts the samples
    estimated without every IMU, per IMU, and says the bad value was read as a dropout
    of its IMU (not 'skipped' for a kept row); only a row without any IMU says
    ``dropout``."""
    meas, _ = _two_imu_file(tmp_path / "m.csv", {
        5: "0.1,0.1,,", 6: "0.1,0.1,,",  # IMU 2 empty: its dropout, IMU 1 used
        10: "nan,0.1,0.2,0.2",  # IMU 1 bad: with --skip-bad its dropout, IMU 2 used
        20: ",,,",  # no IMU: a dropout of the sample
    })  # fmt: skip
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "-o", str(out), "--robot", str(ROBOT_FILE), "--method", "ekf"]
    assert main([*argv, "--skip-bad"]) == 0
    err = capsys.readouterr().err
    status = read_state_table(out).status
    assert list(np.flatnonzero(status == "dropout")) == [20]
    # the partial samples are estimated from the IMU they have (row 10's IMU 2 reading,
    # edited by hand, may disagree with the estimate: inconsistent, not a dropout)
    assert status[0] == "uncertain"  # the start, unconfirmed
    # ... and the rows within a second of a reading beyond one sample's limit (row 10's)
    t = read_state_table(out).t
    jumped = t[status == "inconsistent"]
    near = np.array([np.any((tj >= jumped) & (tj - jumped < 1.0)) for tj in t])
    rest = np.ones(len(t), dtype=bool)
    rest[[0, 20]] = False
    assert set(status[rest & ~near]) <= {"ok", "inconsistent"}
    assert set(status[rest & near]) <= {"uncertain", "inconsistent"}
    assert status[5] == status[6] == "ok"
    assert (
        "; 3 sample(s) estimated without every IMU (missing: IMU 1 in 2 samples, "
        "IMU 2 in 3 samples); "
        "bad rows: 1 sample(s) with a bad value, read as a dropout of its IMU; first: "
        "line 12: column roll_1 is nan (a dropout; --skip-bad keeps it, skip_bad=True in Python)"
    ) in err
    assert err.count("\n") == 1 and "dropout: 1," in err and "skipped" not in err


def test_an_imu_that_never_reports_warns_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 2 empty on every row: the estimates from IMU 1 come with one warning that
    IMU 2 never reported."""
    meas, _ = _two_imu_file(tmp_path / "m.csv", {})
    meas.write_text("\n".join(
        ",".join([*r.split(",")[:3], "", ""]) for r in meas.read_text().splitlines()
    ).replace("t,roll_1,pitch_1,,", "t,roll_1,pitch_1,roll_2,pitch_2") + "\n")  # fmt: skip
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "-o", str(out), "--robot", str(ROBOT_FILE), "--method", "ekf"]
    said = (
        f"{meas}: IMU 2 never reported (no valid reading in 41 samples): estimated from IMU 1 "
        "only; check its wiring or the file's columns"
    )
    with pytest.warns(DropoutWarning) as seen:
        assert main(argv) == 0
    assert [str(w.message) for w in seen if w.category is DropoutWarning] == [said]
    assert "41 sample(s) estimated without every IMU (missing: IMU 2 in 41 samples)" in (
        capsys.readouterr().err
    )
    with pytest.warns(DropoutWarning, match="IMU 2 never reported"):
        assert np.isnan(read_measurements(meas, n_imus=2).z[:, 2:]).all()


# --- filters against filterpy on the two-section model -----------------------------------
def test_ekf_matches_filterpy_on_two_sections() -> None:
    f = make_formulation("direct", TWO, estimate_gyro_bias=False)
    rec = simulate_robot("spatial", TWO, duration=2.0, dt=0.05, seed=1)
    # direct measurements of the true states plus noise (any model-consistent data)
    x_true = np.concatenate([_bends(rec), np.zeros((len(rec.t), 4))], axis=1)
    rng = np.random.default_rng(0)
    z = np.asarray(f.functions.observe(x_true.T), dtype=float).reshape(f.nz, -1).T
    z += rng.normal(scale=0.02, size=z.shape)
    ekf = make_estimator("ekf", f, recovery=bare())  # filterpy has no recovery
    ours = np.array([ekf.step(Measurement(float(t), zi)).state for t, zi in zip(rec.t, z)])
    fns, nx = f.functions, f.nx
    peer = FilterpyEKF(dim_x=nx, dim_z=f.nz)
    peer.x, peer.P, peer.R = f.initial_state(z[0]), f.initial_cov(), f.meas_cov()

    def hx(x: np.ndarray) -> np.ndarray:
        return np.asarray(fns.observe(x), dtype=float).ravel()

    def H(x: np.ndarray) -> np.ndarray:
        return np.asarray(fns.measure(x)[1], dtype=float).reshape(f.nz, nx)

    peer.update(z[0], H, hx)
    states = [peer.x.copy()]
    for k in range(1, len(rec.t)):
        dt = float(rec.t[k] - rec.t[k - 1])
        xn, F, Q = (np.asarray(v, dtype=float) for v in fns.predict(peer.x, [], dt))
        peer.F, peer.Q = F.reshape(nx, nx), Q.reshape(nx, nx)
        peer.predict_x = lambda u=0, xn=xn: setattr(peer, "x", xn.ravel())
        peer.predict()
        peer.update(z[k], H, hx)
        states.append(peer.x.copy())
    assert_allclose(ours, np.array(states), atol=1e-9)


def _bends(rec) -> np.ndarray:  # type: ignore[no-untyped-def]
    names = [o.name for o in rec.outputs]
    cols = []
    for k in (1, 2):
        th, ph = rec.truth[:, names.index(f"theta_{k}")], rec.truth[:, names.index(f"phi_{k}")]
        cols += [th * np.cos(ph), th * np.sin(ph)]
    return np.column_stack(cols)


# --- estimators on two sections -----------------------------------------------------------
@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_two_section_tilt_estimates_track_the_s_curve(method: str) -> None:
    rec = simulate_robot("s-curve", TWO, duration=6.0, dt=0.05, seed=0)
    f = make_formulation("bend", TWO)
    series = make_estimator(method, f, MHESettings(horizon=15)).run(rec.t, rec.z)  # type: ignore[arg-type]
    names = [o.name for o in f.outputs]
    m = compute_metrics(series.output, rec.truth, TWO.length, names)
    # the motion model averages the readings' noise: clearly better than each sample's
    # readings inverted alone (two tilt IMUs fix the four bend coordinates)
    alone = np.array([np.asarray(f.output(f.initial_state(z))).ravel() for z in rec.z])
    m_alone = compute_metrics(alone, rec.truth, TWO.length, names)
    assert m.tip_mean_mm < 0.8 * m_alone.tip_mean_mm, (m, m_alone)
    assert set(m.section_end_mean_mm) == {"1", "2"}


# --- observability ------------------------------------------------------------------------
def test_check_robot_finds_the_unobservable_case_and_the_gyro_fixes_it() -> None:
    r = observability_report(TWO, samples=200)
    assert r.known_case["tilt"] < 1e-10  # section 2 bending about the vertical
    assert r.known_case["gyro_window"] > 1e-3
    assert r.gyro_window.full_rank_fraction == 1.0
    single = observability_report(Robot.single(0.2, 3.0), samples=200)
    assert single.tilt.full_rank_fraction > 0.99


# --- the robot file -----------------------------------------------------------------------
def test_robot_file_round_trip(tmp_path: Path) -> None:
    robot = read_robot(ROBOT_FILE)
    assert robot == TWO
    assert robot.describe().startswith("2 sections")
    hanging = Robot(
        (Section(0.1 + 0.2, 1.25), Section(0.07, math.pi / 3), Section(0.123456789012345)),
        (ImuPlacement(0, 0.5, (1.5, -30.0, 90.0)), ImuPlacement(2), ImuPlacement(1, 1 / 3)),
        "z-down",
    )
    for k, original in enumerate((robot, hanging, Robot.single(0.2))):
        path = tmp_path / f"robot{k}.toml"
        write_robot(path, original)
        assert path.read_text(encoding="utf-8") == robot_toml(original)
        if original is hanging:  # the IMUs' order is kept, and said to be out of base order
            with pytest.warns(RobotFileWarning, match="imu 2 .* but listed after it"):
                assert read_robot(path) == original, path.read_text()
        else:
            assert read_robot(path) == original, path.read_text()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[[section]]\n[[imu]]\nsection = 1\n", "section 1: missing key 'length'"),
        ("[[section]]\nlength = -0.1\n[[imu]]\nsection = 1\n", "section 1: length: section"),
        (
            "[[section]]\nlength = 0.1\n[[imu]]\nsection = 2\n",
            "imu 1: section must be 1, the robot's only section, got 2",
        ),
        (
            "[[section]]\nlength = 0.1\n[[section]]\nlength = 0.1\n[[imu]]\nsection = 3\n",
            "imu 1: section must be a whole section number from 1 to 2, got 3",
        ),
        (
            "[[section]]\nlength = 0.1\n[[imu]]\nsection = 1.0\n",
            "imu 1: section must be 1, the robot's only section, got 1.0 (write 1, "
            "without a decimal point)",
        ),
        ("[[section]]\nlength = 0.1\n[[imu]]\nsection = 1\nat = 1.5\n", "imu 1: at must lie"),
        ("[[section]]\nlength = 0.1\n[[imu]]\nsection = 1\nat = 0\n", "imu 1: at must lie"),
        ("[[section]]\nlength = 0.1\ncolour = 1\n[[imu]]\nsection = 1\n", "unknown key 'colour'"),
        ("[[section]]\nlength = 0.1\n", "no [[imu]]"),
        ("[[section]]\nlength = 200\n[[imu]]\nsection = 1\n", "millimetres or centimetres?"),
        ("[[section]]\nlength = 0.1\ntheta_max = 90\n[[imu]]\nsection = 1\n", "degrees?"),
        ("mounting = 'sideways'\n[[section]]\nlength = 0.1\n[[imu]]\nsection = 1\n", "mounting"),
        ("[[section]\n", "robot.toml: line 1: not valid TOML: "),
        ("[[section]]\nlength = 0.1\n[[imu]\n", "robot.toml: line 3: not valid TOML: Expected"),
        (
            "[[section]]\nlength = 0.1\n[imu]\nsection = 1\n[[imu]]\nsection = 1\nat = 0.5\n",
            "; line 3: [imu] is one table, and every imu is a [[imu]] (double brackets)",
        ),
    ],
)
def test_bad_robot_file_is_one_line_exit_2_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    robot = tmp_path / "robot.toml"
    robot.write_text(text)
    with pytest.raises(InputError, match=None) as info:
        read_robot(robot)
    assert message in str(info.value) and str(robot) in str(info.value)
    out = tmp_path / "m.csv"
    assert main(["simulate", "s-curve", "--robot", str(robot), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not out.exists()


@pytest.mark.parametrize(
    ("header", "robot", "needle"),
    [
        ("t,roll_1,pitch_1,roll_2,pitch_2,roll_3,pitch_3", True,
         "tilt columns for 3 IMU(s) (roll_1 ... roll_3) but the robot describes 2; "
         "pass --robot FILE with a robot file of 3 IMU(s); for a robot of fewer of them, "
         "cut the file to their columns, numbered from 1 in the robot file's order"),
        # --robot forgotten: refused, not IMU 1's columns estimated as a one-section robot
        ("t,roll_1,pitch_1,roll_2,pitch_2", False,
         "tilt columns for 2 IMU(s) (roll_1 ... roll_2) but the robot describes 1; "
         "pass --robot FILE with a robot file of 2 IMU(s)"),
        # not only "pass --robot FILE with a robot file of 1 IMU(s)": leaving --robot out too
        ("t,roll,pitch", True, "tilt columns for 1 IMU(s) (roll, pitch) but the robot "
         "describes 2; pass --robot FILE with a robot file of 1 IMU(s), or leave --robot "
         "out: one section with its IMU at the tip needs no robot file"),
        ("t,ax,ay,az", True, "raw columns for 1 IMU(s) (ax, ay, az) but the robot describes "
         "2; pass --robot FILE with a robot file of 1 IMU(s), or leave --robot out: one "
         "section with its IMU at the tip needs no robot file"),
        ("t,ax_1,ay_1,az_1,ax_2,ay_2,az_2", False,
         "raw columns for 2 IMU(s) (ax_1 ... ax_2) but the robot describes 1; pass --robot"),
    ],
)  # fmt: skip
def test_measurement_file_with_the_wrong_imu_count(  # type: ignore[no-untyped-def]
    tmp_path: Path, capsys, header: str, robot: bool, needle: str
) -> None:
    meas = tmp_path / "m.csv"
    row = ",".join(["0"] + ["0.1"] * header.count(","))
    meas.write_text(f"{header}\n{row}\n")
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "-o", str(out), "--method", "ekf"]
    assert main([*argv, *(["--robot", str(ROBOT_FILE)] if robot else [])]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{meas}: line 1: the file has {needle}" in err
    assert not out.exists()


_THREE_TILTS = imu_columns(("roll", "pitch"), 3)


@pytest.mark.parametrize(
    ("header", "n_imus", "message"),
    [
        # not "tilt columns for 4 IMU(s) ... pass --robot FILE with a robot file of 4"
        (renamed(_THREE_TILTS, {"roll_3": "roll_4"}), 3,
         "IMU 3 has no roll_3 column; the header has roll_4 (a typo?)"),
        # not "missing column(s) roll_2" without roll2
        (renamed(_THREE_TILTS, {"roll_2": "roll2"}), 3,
         "IMU 2 has no roll_2 column; the header has roll2 (a typo?)"),
        (renamed(_THREE_TILTS, {"roll_1": "roll_0"}), 3,
         "IMU 1 has no roll_1 column; the header has roll_0 (a typo?)"),
        # not IMU 1 read alone where the robot has one IMU
        (renamed(_THREE_TILTS, {"pitch_3": "pitch3"}), 1,
         "IMU 3 has no pitch_3 column; the header has pitch3 (a typo?)"),
        ("t,rol,pitch", 1, "the IMU has no roll column; the header has rol (a typo?)"),
        ("t,rol,pich", 1, "the IMU has no roll, pitch columns; the header has rol, pich (typos?)"),
    ],
)  # fmt: skip
def test_a_tilt_header_typo_names_the_missing_column_and_the_typo(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], header: str, n_imus: int, message: str
) -> None:
    def read(path: Path) -> object:
        return read_measurements(path, n_imus=n_imus)

    assert_header_refused(tmp_path, capsys, header, n_imus, message, read)


def test_read_measurements_refuses_another_imu_count(tmp_path: Path) -> None:
    """read_measurements of a two-IMU file refuses it without n_imus=2 (it does not
    return IMU 1's columns alone); one numbered IMU is one IMU."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll_1,pitch_1,roll_2,pitch_2\n0,0.1,0.2,0.3,0.4\n")
    with pytest.raises(InputError, match=r"for 2 IMU\(s\).*describes 1; .*n_imus=2 in Python"):
        read_measurements(meas)
    assert_allclose(read_measurements(meas, n_imus=2).z, [[0.1, 0.2, 0.3, 0.4]])
    meas.write_text("t,roll_1,pitch_1\n0,0.1,0.2\n")  # one numbered IMU is one IMU
    assert_allclose(read_measurements(meas).z, [[0.1, 0.2]])


def test_truth_without_a_tip_is_refused(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n")
    truth = tmp_path / "t.csv"
    truth.write_text("t,theta_1,phi_1\n0,0,0\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert "missing column(s) x, y, z" in capsys.readouterr().err


def test_cli_round_trip_two_sections(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    robot = ["--robot", str(ROBOT_FILE)]
    assert main(["simulate", "s-curve", "-o", str(meas), "--truth", str(truth),
                 "--duration", "4", *robot]) == 0  # fmt: skip
    assert meas.read_text().splitlines()[0] == "t,roll_1,pitch_1,roll_2,pitch_2"
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", *robot]) == 0
    table = read_state_table(est)
    assert table.names == (
        "x", "y", "z", "theta_1", "phi_1", "x_1", "y_1", "z_1",
        "theta_2", "phi_2", "x_2", "y_2", "z_2",
    )  # fmt: skip
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), *robot]) == 0
    out = capsys.readouterr().out
    assert "section 1 end error" in out and "section 2 end error" in out
    # the numbers: each section end's mean distance, computed here from the two files
    assert main(["evaluate", str(est), str(truth), *robot, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    true = read_state_table(truth)
    for k in ("1", "2"):
        cols = [f"x_{k}", f"y_{k}", f"z_{k}"]
        e = np.column_stack([table.column(c) for c in cols])
        tr = np.column_stack([true.column(c) for c in cols])
        distance_mm = 1e3 * np.linalg.norm(e - tr, axis=1)
        assert report["section_end_mean_mm"][k] == pytest.approx(distance_mm.mean(), rel=1e-9)
        assert report["section_end_max_mm"][k] == pytest.approx(distance_mm.max(), rel=1e-9)
    assert report["tip_mean_mm"] == pytest.approx(report["section_end_mean_mm"]["2"], rel=1e-12)
    assert_allclose(table.column("x"), table.column("x_2"))
    assert math.isfinite(float(table.column("theta_2").max()))


# --- the fast backend on two sections ------------------------------------------------------
@pytest.mark.parametrize("name", ["bend", "direct"])
def test_fast_backend_agrees_with_ipopt_on_two_sections_with_active_bounds(name: str) -> None:
    import warnings

    from continuum_mhe.estimators.fast import feasible_set

    tight = Robot((Section(0.16, 0.8), Section(0.14, 0.8)), TWO.imus)
    f = make_formulation(name, tight)
    if name == "direct":  # the readings below carry 0.03 of noise on the gyros too
        f = replace(f, gyro_std=0.05, estimate_gyro_bias=False)
    fs = feasible_set(f)
    assert fs.ball_idx.tolist() == [[0, 1], [2, 3]]
    rec = simulate_robot("s-curve", TWO, duration=4.0, dt=0.05, seed=3)  # beyond the bound
    # the first 3.5 s: the dropout, both sections on their bounds, each also alone (the
    # IPOPT runs' time grows with the samples on the bound)
    n = 70
    if name == "direct":  # model-consistent raw measurements of the (clipped) truth
        b = _bends(rec)
        for k in (0, 2):
            r = np.hypot(b[:, k], b[:, k + 1])
            b[:, k : k + 2] *= np.minimum(1.0, 0.8 / np.maximum(r, 1e-12))[:, None]
        rates = np.gradient(b, rec.t, axis=0)
        x = np.concatenate([b, rates], axis=1)
        z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
        z += np.random.default_rng(0).normal(scale=0.03, size=z.shape)
    else:
        z = rec.z.copy()
    z[30:45, f.measurement_blocks[1].slice] = np.nan  # one IMU drops out
    out = {}
    for solver in ("fast", "ipopt"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # the fast backend must take this problem
            est = make_estimator("mhe", f, MHESettings(horizon=12, solver=solver))  # type: ignore[arg-type]
        series = est.run(rec.t[:n], z[:n])
        # uncertain: IMU 2 out; at-bound: a section on theta_max (and IMU 2 reporting)
        assert set(series.status) <= {"ok", "uncertain", "at-bound"}
        out[solver] = series
    assert np.array_equal(out["fast"].status, out["ipopt"].status)
    status = out["fast"].status
    bend = np.maximum(out["fast"].column("theta_1"), out["fast"].column("theta_2"))
    on_bound = bend >= 0.8 - AT_BOUND_TOL
    assert np.array_equal(status == "at-bound", on_bound & (status != "uncertain"))
    assert np.any(status == "at-bound")
    angles = [i for i, o in enumerate(f.outputs) if o.unit == "rad"]
    assert_allclose(out["fast"].output[:, angles], out["ipopt"].output[:, angles], atol=1e-6)
    for k in ("theta_1", "theta_2"):  # each section held on its own bound, by both
        assert out["fast"].column(k).max() <= 0.8 + 1e-12
        assert out["ipopt"].column(k).max() <= 0.8 + 1e-7
        assert out["fast"].column(k).max() > 0.8 - 1e-6  # the bound is active
    held = [out["fast"].column(k) > 0.8 - 1e-6 for k in ("theta_1", "theta_2")]
    assert np.any(held[0] & ~held[1]) and np.any(held[1] & ~held[0])  # each also alone


def test_robot_benchmark_reports_fast_against_ipopt_on_the_same_windows() -> None:
    from continuum_mhe.benchmark.harness import run_robot_benchmark

    report = run_robot_benchmark(TWO, [6], 1.0)
    (row,) = report["rows"]
    assert row["fallbacks"] == 0
    assert row["max_diff_vs_ipopt"] < 1e-6
    assert row["ipopt_over_fast"] == pytest.approx(row["ipopt_median_us"] / row["fast_median_us"])


@pytest.mark.parametrize("name", ["bend", "paper", "direct"])
def test_compiled_ekf_equals_the_casadi_ekf(name: str) -> None:
    from continuum_mhe.benchmark.harness import raw_imu_recording
    from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, ExtendedKalmanFilter

    robot = TWO if name == "direct" else Robot.single(0.2)
    f = make_formulation(name, robot)
    if name == "direct":
        rec = raw_imu_recording(TWO, 3.0)
    else:
        rec = simulate_robot("paper3d", robot, duration=3.0)
    z = rec.z.copy()
    z[10:20, : f.measurement_blocks[0].size] = np.nan  # the first IMU drops out
    a = CasadiExtendedKalmanFilter(f).run(rec.t, z)
    b = ExtendedKalmanFilter(f).run(rec.t, z)
    assert list(a.status) == list(b.status)
    assert_allclose(b.output, a.output, rtol=0, atol=1e-9)


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_a_single_estimate_reads_its_outputs_by_name(method: str) -> None:
    """``Estimate.value`` and ``Estimate.std`` read the outputs a step returns by the
    formulation's names, the same numbers as the series' columns of ``run``; NaN for a
    sample without an estimate; an unknown name is a KeyError that lists the outputs."""
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=1.0, seed=0)
    est = make_estimator(method, f)
    steps = [est.step(Measurement(float(t), z)) for t, z in zip(rec.t, rec.z)]
    series = make_estimator(method, f).run(rec.t, rec.z)
    last = steps[-1]
    assert [o.name for o in last.outputs] == [o.name for o in f.outputs]
    for name in ("x", "z_1", "theta_2", "phi_2"):
        assert last.value(name) == series.column(name)[-1]
        assert last.std(name) == series.std_column(name)[-1]
        assert math.isfinite(last.std(name)) and last.std(name) > 0
    with pytest.raises(KeyError, match="no output 'theta_3' .*theta_2"):
        last.value("theta_3")
    from continuum_mhe.results import Estimate, Status

    none = Estimate(1.0, None, None, None, Status.NO_ESTIMATE, 0.0, outputs=f.outputs)
    assert math.isnan(none.value("x")) and math.isnan(none.std("theta_2"))


def test_three_section_certified_answers_lie_within_the_error_tolerance() -> None:
    """The quadratic-rate estimate on three sections (tilt IMUs, ``spatial``, 20 s, N =
    30: the ``tools/sections_ratio.py`` recording), window by window against the answer
    iterated to 1e-13: within ``err_tol`` in the certificate's norm. The rate
    ``|d_k| / |d_k-1|^2`` of the last two steps alone let two windows through at 5.0e-8
    and 2.9e-8 (a first step that contracted slowly, rate 4.5 to 6.8, then one at 0.07);
    the largest rate over the window's steps holds them."""
    from estimator_helpers import fast_windows, worst_certified_error

    from continuum_mhe.estimators.fast import FastOptions
    from continuum_mhe.estimators.mhe import MovingHorizonEstimator

    robot = Robot(
        tuple(Section(0.3 / 3, 3.0) for _ in range(3)), tuple(ImuPlacement(i) for i in range(3))
    )
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=20.0, seed=0)
    est = MovingHorizonEstimator(f, MHESettings(horizon=30, solver="fast"), FastOptions())
    windows = fast_windows(est, rec.t, rec.z)
    model = est.inference._fast
    assert model is not None and len(windows) > 390
    assert worst_certified_error(model, windows) <= FastOptions().err_tol
