"""A twist of each IMU about the backbone's tangent as a state of the raw-IMU model
(``DirectFormulation(imu_twist=True)``, ``--imu-twist``): the readings it predicts
against rotations formed independently (numpy, finite differences in time), a twist
applied to a PCC robot's readings recovered, the fast MHE against IPOPT, the shipped
twisting rod estimated near its PCC floor with standard deviations that cover its
errors, and the command line's rules."""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import fast_and_ipopt_states
from numpy.testing import assert_allclose

from continuum_mhe.cli import main
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.io.input_options import InputOptions, OptionWarning
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.direct import DirectFormulation, direct_measurements
from continuum_mhe.model.pcc import pose_at, up_vector
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.raw_readings import RawNoise, raw_readings
from continuum_mhe.simulation.scenarios import simulate_robot

ROD = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"

#: a two-section robot with an IMU inside section 2 and one at the tip
ROBOT = Robot(
    (Section(0.16, 3.0), Section(0.14, 3.0)),
    (ImuPlacement(1, 0.5), ImuPlacement(1, 1.0)),
    "z-up",
)


def _rz(psi: float) -> np.ndarray:
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _vee(w: np.ndarray) -> np.ndarray:
    return 0.5 * np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]])


def test_state_layout_and_motion() -> None:
    """The twists and their rates come after the gyro biases, move at constant
    velocity, and start at zero with the prior standard deviation."""
    f = DirectFormulation(robot=ROBOT, estimate_gyro_bias=True, imu_twist=True)
    assert f.nx == 8 + 6 + 4
    assert f.state_names[14:] == ("psi_1", "psi_2", "psi_1_dot", "psi_2_dot")
    x = np.random.default_rng(2).normal(size=f.nx) * 0.3
    dt = 0.05
    xn, _, q = (np.asarray(v) for v in f.functions.predict(x, [], dt))
    assert_allclose(xn.ravel()[14:16], x[14:16] + dt * x[16:18], atol=1e-15)
    assert_allclose(xn.ravel()[16:], x[16:], atol=0)
    w = f.twist_accel_psd
    assert_allclose(q[14, 14], w * dt**3 / 3)
    assert_allclose(q[14, 16], w * dt**2 / 2)
    assert_allclose(q[16, 16], w * dt)
    assert_allclose(q[14, 15], 0.0)
    assert_allclose(np.diag(f.initial_cov())[14:], f.initial_twist_std**2)
    z0 = np.asarray(f.functions.observe(np.zeros(f.nx))).ravel()
    assert np.all(f.initial_state(z0)[14:] == 0)


@pytest.mark.parametrize("mounting", ["z-up", "z-down"])
def test_readings_are_the_pcc_frames_turned_by_the_twist(mounting: str) -> None:
    """At a known motion (bends, twists and their rates from functions of time), the
    model's gravity directions equal ``Rz(psi)^T R^T u`` formed with numpy from the
    numeric PCC pose, and its gyros ``vee(R_i^T dR_i/dt)`` of the turned frame
    ``R_i = R Rz(psi)`` by central differences in time, to 1e-6."""
    from dataclasses import replace

    robot = replace(ROBOT, mounting=mounting)
    f = DirectFormulation(robot=robot, imu_twist=True)
    up = up_vector(mounting)  # type: ignore[arg-type]

    def motion(t: float) -> tuple[np.ndarray, np.ndarray]:
        q = np.array([0.9 * math.sin(1.3 * t), 0.4 - 0.3 * t, -1.1 * math.sin(0.9 * t), 0.6])
        psi = np.array([0.7 * math.sin(2.1 * t), -1.3 + 0.8 * t])
        return q, psi

    h = 1e-5
    for tc in (0.3, 1.7):
        (qm, pm), (q, psi), (qp, pp) = (motion(tc + d) for d in (-h, 0.0, h))
        x = np.concatenate([q, (qp - qm) / (2 * h), psi, (pp - pm) / (2 * h)])
        z = np.asarray(f.functions.observe(x)).ravel()

        def frames(q: np.ndarray, psi: np.ndarray) -> list[np.ndarray]:
            out = []
            for i, imu in enumerate(robot.imus):
                R, _ = pose_at(q.reshape(2, 2), robot.lengths, imu.section, imu.at)
                out.append(R @ _rz(psi[i]))
            return out

        now, before, after = frames(q, psi), frames(qm, pm), frames(qp, pp)
        for i, blk in enumerate(f.measurement_blocks):
            gravity = now[i].T @ up
            assert_allclose(z[blk.start : blk.start + 3], gravity, atol=1e-9)
            rate = _vee(now[i].T @ (after[i] - before[i]) / (2 * h))
            assert_allclose(z[blk.start + 3 : blk.start + 6], rate, atol=1e-6)
        plain = np.asarray(DirectFormulation(robot=robot).functions.observe(x[:8])).ravel()
        assert np.max(np.abs(plain - z)) > 0.1  # the twist changes what the IMUs read


def _twisted_recording(seconds: float = 8.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """A PCC robot's raw readings (``spatial``, 20 Hz, white noise, no gyro bias) with a
    known twist of each IMU about its z axis applied to them (the accelerometer turned,
    the gyro turned plus the twist rate): ``(t, z, truth tip, twists)``."""
    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=seconds, seed=2)
    values, names = raw_readings(rec, robot, RawNoise(gyro_bias_std=0.0), seed=2)
    t = rec.t
    # untwisted and not twisting at the start, as the model takes a start
    twists = {0: 0.4 * (1 - np.cos(0.8 * t)), 1: 0.75 * (1 - np.cos(0.6 * t))}
    z_cols = []
    for i in range(robot.n_imus):
        acc, gyr = values[:, 6 * i : 6 * i + 3], values[:, 6 * i + 3 : 6 * i + 6]
        psi = twists[i]
        rate = np.gradient(psi, t)
        acc_t = np.array([_rz(p).T @ a for p, a in zip(psi, acc)])
        gyr_t = np.array([_rz(p).T @ g for p, g in zip(psi, gyr)])
        gyr_t[:, 2] += rate
        z_cols.append(direct_measurements(acc_t, gyr_t))
    names_ = [o.name for o in rec.outputs]
    tip = rec.truth[:, [names_.index(c) for c in ("x", "y", "z")]]
    assert names[:3] == ("ax_1", "ay_1", "az_1")
    return t, np.hstack(z_cols), tip, twists


@pytest.mark.parametrize("method", ["ekf", "mhe", "ukf"])
def test_a_twist_applied_to_the_readings_is_recovered(method: str) -> None:
    """The readings of a PCC robot whose IMUs turn about their z axes by a known twist
    (up to 1.5 rad, from rest): the model with the twist follows the tip to within 7 mm
    on average (the readings hold the IMUs' own acceleration, which the model leaves
    out: 5.3 to 5.5 mm) and each twist to within 0.1 rad after the first second (0.06 to
    0.08); without the twist the tip is over 20 mm off on average."""
    t, z, tip, twists = _twisted_recording()
    robot = read_robot("two-section")
    twisted = DirectFormulation(robot=robot, imu_twist=True)
    plain = DirectFormulation(robot=robot)
    est = make_estimator(method, twisted, MHESettings(horizon=20))
    got = [est.step(Measurement(float(ti), zi)) for ti, zi in zip(t, z)]
    err = np.linalg.norm(np.array([e.output[:3] for e in got]) - tip, axis=1)
    assert np.mean(err) < 7e-3, np.mean(err)
    later = t >= 1.0
    n0 = twisted.n_motion + twisted.n_bias
    for i, truth in twists.items():
        psi = np.array([e.state[n0 + i] for e in got])
        assert np.max(np.abs(psi[later] - truth[later])) < 0.1, (i, method)
    off = make_estimator(method, plain, MHESettings(horizon=20)).run(t, z)
    assert np.mean(np.linalg.norm(off.output[:, :3] - tip, axis=1)) > 20e-3


def test_fast_mhe_agrees_with_ipopt_with_the_twist() -> None:
    """The fast MHE and IPOPT (N = 4) on the model's own readings of a motion with
    twisting IMUs plus noise 0.005, 1 s at 20 Hz: the same states to 1e-6."""
    f = DirectFormulation(robot=ROBOT, imu_twist=True, estimate_gyro_bias=True)
    t = np.arange(20) * 0.05
    q = np.stack([0.9 * np.sin(1.3 * t), 0.5 * np.cos(0.7 * t) - 0.2, -np.sin(0.9 * t),
                  0.6 * np.sin(1.7 * t)], axis=1)  # fmt: skip
    psi = np.stack([0.5 * (1 - np.cos(2.0 * t)), 0.8 * (1 - np.cos(1.5 * t))], axis=1)
    x = np.concatenate(
        [q, np.gradient(q, t, axis=0), np.zeros((len(t), 6)), psi, np.gradient(psi, t, axis=0)],
        axis=1,
    )
    z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z += np.random.default_rng(5).normal(scale=0.005, size=z.shape)
    states = fast_and_ipopt_states(f, t, z, horizon=4)
    assert_allclose(states["fast"], states["ipopt"], atol=1e-6, rtol=0)


def test_the_shipped_twisting_rod_near_its_floor_with_honest_intervals(tmp_path) -> None:
    """The shipped ``spatial`` rod (G = E/3, its tip twisting by up to 122 degrees about
    the tangent; PCC floor 6.3 mm), raw IMUs, the gyros calibrated at rest: with the twist
    the EKF's tip is within 10 mm on average (over 50 mm without it), and no `ok` row
    lies more than 4 of its own standard deviations off on a tip axis."""
    robot_file = tmp_path / "cal.toml"
    assert (
        main(
            [
                "calibrate",
                "--from",
                str(ROD / "spatial_rest.csv"),
                "--robot",
                "two-section",
                "--write-robot",
                str(robot_file),
            ]
        )  # fmt: skip
        == 0
    )
    robot = read_robot(str(robot_file))
    truth = np.genfromtxt(ROD / "spatial_truth.csv", delimiter=",", names=True)
    tip = np.column_stack([truth["x"], truth["y"], truth["z"]])
    errors = {}
    for twist in (False, True):
        options = InputOptions(raw=RawImuSettings(imu_model="direct"), imu_twist=twist)
        data = load_input(ROD / "spatial_raw.csv", options, make_formulation("bend", robot))
        assert data.formulation.estimate_gyro_bias is not twist  # held at the calibration
        run = make_estimator("ekf", data.formulation).run(data.t, data.z)
        e = run.output[:, :3] - tip
        errors[twist] = np.nanmean(np.linalg.norm(e, axis=1))
        if twist:
            ok = np.asarray(run.status) == "ok"
            assert ok.sum() > 300
            assert np.all(np.abs(e[ok]) <= 4 * run.output_std[ok, :3])
            # the tip IMU's twist reaches the rod's own largest twist about the tangent
            # there (its simulator's measure, in the recording's info) within 15 degrees
            info = json.loads((ROD / "spatial_info.json").read_text())
            column = [o.name for o in data.formulation.outputs].index("imu_twist_2")
            largest = np.degrees(np.nanmax(np.abs(run.output[:, column])))
            assert abs(largest - info["tangent_twist_max_deg"][1]) < 15.0, largest
    assert errors[True] < 10e-3 < 50e-3 < errors[False], errors


def test_the_command_line_rules(tmp_path, capsys) -> None:
    """``--imu-twist`` with tilt readings: one line naming it, exit 2, nothing written;
    raw readings and a robot file without calibrated gyro biases: a warning naming
    ``calibrate`` (the biases estimated); with them: no warning, biases held."""
    rec = simulate_robot("spatial", read_robot("two-section"), duration=1.0, seed=0)
    values, names = raw_readings(rec, read_robot("two-section"), seed=0)
    raw = tmp_path / "raw.csv"
    lines = ["t," + ",".join(names)]
    lines += [",".join(f"{v:.9g}" for v in (t, *row)) for t, row in zip(rec.t, values)]
    raw.write_text("\n".join(lines) + "\n")
    tilt = tmp_path / "tilt.csv"
    tilt.write_text("t,roll_1,pitch_1,roll_2,pitch_2\n0,0,0,0,0\n0.05,0,0,0,0\n")
    out = tmp_path / "e.csv"
    code = main(["estimate", str(tilt), "--robot", "two-section", "--imu-twist", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert err.count("\n") == 1 and "--imu-twist" in err
    tendon = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
    argv = ["estimate", str(tendon / "unloaded_raw.csv"), "--robot", "tendon-two-section",
            "--inputs", str(tendon / "unloaded_tensions.csv"), "--imu-twist",
            "-o", str(out)]  # fmt: skip
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(argv) == 2 and not out.exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--imu-twist is not available for a tendon robot" in err
    assert [w for w in seen if issubclass(w.category, UserWarning)] == []  # the refusal alone
    calibrated = tmp_path / "cal.toml"
    imu = "[[imu]]\nsection = {}\ngyro_bias = [0.001, -0.002, 0.0005]\n"
    calibrated.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\ntheta_max = 3.0\n'
        "[[section]]\nlength = 0.14\ntheta_max = 3.0\n" + imu.format(1) + imu.format(2)
    )
    said = []
    for robot in ("two-section", str(calibrated)):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            argv = ["estimate", str(raw), "--robot", robot, "--imu-twist", "-o", str(out)]
            assert main([*argv, "--overwrite"]) == 0
        said.append([str(w.message) for w in seen if w.category is OptionWarning])
        assert "imu-twist = true" in out.read_text()
        header = next(ln for ln in out.read_text().splitlines() if not ln.startswith("#"))
        assert ",imu_twist_1,imu_twist_2,std_x," in header
        assert ",std_imu_twist_1,std_imu_twist_2,status," in header
    assert [len(s) for s in said] == [1, 0]
    assert said[0][0].startswith("--imu-twist without a calibrated gyro_bias")
    assert "their biases are estimated" in said[0][0]
    assert "continuum-mhe calibrate" in said[0][0]
    with pytest.warns(OptionWarning, match="their biases are held at zero"):
        load_input(
            raw,
            InputOptions(imu_twist=True, estimate_gyro_bias=False),
            make_formulation("bend", read_robot("two-section")),
        )
    with warnings.catch_warnings():
        warnings.simplefilter("error", OptionWarning)
        data = load_input(
            raw, InputOptions(imu_twist=True), make_formulation("bend", read_robot(str(calibrated)))
        )
    assert data.formulation.imu_twist and not data.formulation.estimate_gyro_bias


def test_the_mostly_inconsistent_notice_names_the_twist_for_raw_imus() -> None:
    """A run mostly ``inconsistent`` on raw IMUs names ``--imu-twist`` among what the
    model cannot follow; not once the twist is on, nor for tilt IMUs."""
    from continuum_mhe.estimators.run_notices import inconsistent_notice

    robot = read_robot("two-section")
    raw = inconsistent_notice(300, 600, DirectFormulation(robot=robot))
    twisted = inconsistent_notice(300, 600, DirectFormulation(robot=robot, imu_twist=True))
    tilt = inconsistent_notice(300, 600, make_formulation("bend", robot))
    assert raw is not None and "--imu-twist" in raw
    assert twisted is not None and "--imu-twist" not in twisted
    assert tilt is not None and "--imu-twist" not in tilt


@pytest.fixture(scope="module")
def uncalibrated_spatial(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``estimate`` of the shipped ``spatial`` rod with the uncalibrated two-section
    robot file and no twist option: ``(estimate file, what it said on stderr)``, run
    once a module for the tests that read its clauses and its file."""
    out = tmp_path_factory.mktemp("uncalibrated") / "e.csv"
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["estimate", str(ROD / "spatial_raw.csv"), "--robot", "two-section",
                     "-o", str(out)]) == 0  # fmt: skip
    return out, err.getvalue()


def _calibrated(tmp_path: Path, name: str) -> Path:
    """The two-section robot calibrated from the shipped rod recording ``name``'s rest
    (every IMU's gyro_bias written)."""
    cal = tmp_path / f"{name}_cal.toml"
    assert main(["calibrate", "--from", str(ROD / f"{name}_rest.csv"), "--robot",
                 "two-section", "--write-robot", str(cal)]) == 0  # fmt: skip
    return cal


def test_the_readings_evidence_tells_a_twisting_rod_from_one_that_does_not(tmp_path) -> None:
    """The two models' compiled EKFs over the shipped rods, calibrated: on ``spatial``
    (the tip IMU twists up to 122 degrees) the twist model predicts nearly every reading
    better, by hundreds of nats on the median one; on the planar S (no twist) none, the
    twist model's wider predictions costing a few nats a reading."""
    from continuum_mhe.estimators.twist_evidence import twist_evidence, twisted_formulation

    evidence = {}
    for name in ("spatial", "planar-s"):
        robot = read_robot(str(_calibrated(tmp_path, name)))
        data = load_input(ROD / f"{name}_raw.csv", InputOptions(), make_formulation("bend", robot))
        twisted = load_input(ROD / f"{name}_raw.csv", InputOptions(imu_twist=True),
                             make_formulation("bend", robot))  # fmt: skip
        assert twisted_formulation(data.formulation) == twisted.formulation  # --imu-twist's
        evidence[name] = twist_evidence(data.formulation, data.t, data.z)
    spatial, planar = evidence["spatial"], evidence["planar-s"]
    assert spatial.twists and spatial.samples == 600
    assert spatial.median > 100.0 and spatial.share > 0.9
    assert not planar.twists and planar.samples == 600
    assert -10.0 < planar.median < 0.0 and planar.share < 0.05


@pytest.mark.parametrize("block", [1, 7, 64, 1000])
def test_the_streamed_evidence_is_the_recordings_whatever_its_blocks(
    tmp_path, monkeypatch, block
) -> None:
    """Live's evidence, its filters stepped a block at a time as samples arrive, is bit
    for bit the recording's (both filters run over it at once) for any block size: the
    shipped ``spatial`` rod, calibrated (every block waiting allowed: the samples come
    faster than a stream's). A formulation it does not weigh (the twist given) is not
    active and has none."""
    from continuum_mhe.estimators import twist_evidence as te

    robot = read_robot(str(_calibrated(tmp_path, "spatial")))
    data = load_input(ROD / "spatial_raw.csv", InputOptions(), make_formulation("bend", robot))
    whole = te.twist_evidence(data.formulation, data.t, data.z)
    monkeypatch.setattr(te, "STREAM_BLOCK", block)
    monkeypatch.setattr(te, "STREAM_BACKLOG", len(data.t) + 1)
    streamed = te.StreamedTwistEvidence(data.formulation)
    for ti, zi in zip(data.t, data.z):
        streamed.add(ti, zi)
    assert streamed.evidence() == whole and whole.samples == 600
    given = te.StreamedTwistEvidence(te.twisted_formulation(data.formulation))
    given.add(0.0, data.z[0])
    assert not given.active and given.evidence() is None


def test_the_streamed_evidence_survives_its_worker_going_idle(tmp_path, monkeypatch) -> None:
    """Live's evidence thread ends after a pause in the stream and another starts with
    the next block; blocks left behind by a worker that ended are stepped in their
    order: the evidence is still bit for bit the recording's."""
    import time

    from continuum_mhe.estimators import twist_evidence as te

    robot = read_robot(str(_calibrated(tmp_path, "spatial")))
    data = load_input(ROD / "spatial_raw.csv", InputOptions(), make_formulation("bend", robot))
    whole = te.twist_evidence(data.formulation, data.t, data.z)
    monkeypatch.setattr(te, "STREAM_IDLE_S", 0.005)
    streamed = te.StreamedTwistEvidence(data.formulation)
    workers = []  # held, so that no two share an id
    for k, (ti, zi) in enumerate(zip(data.t, data.z)):
        streamed.add(ti, zi)
        if k % 150 == 149:
            workers.append(streamed._worker)
            end = time.monotonic() + 60.0  # a hung worker fails the test, not the suite
            while streamed._worker is not None and time.monotonic() < end:
                time.sleep(0.01)  # the worker steps what it has, goes idle and ends
            assert streamed._worker is None
    assert len({id(w) for w in workers}) == 4 and streamed.evidence() == whole


def test_the_streamed_evidence_ends_where_its_filters_fall_behind(tmp_path, monkeypatch) -> None:
    """Filters that cannot keep up with the stream (here each block takes 50 ms) end
    the evidence once STREAM_BACKLOG blocks wait, instead of holding a backlog that the
    summary would wait for: no evidence, and the stream's adds return at once."""
    import time

    from continuum_mhe.estimators import twist_evidence as te

    robot = read_robot(str(_calibrated(tmp_path, "spatial")))
    data = load_input(ROD / "spatial_raw.csv", InputOptions(), make_formulation("bend", robot))
    monkeypatch.setattr(te, "STREAM_BLOCK", 4)
    monkeypatch.setattr(te, "STREAM_BACKLOG", 3)
    streamed = te.StreamedTwistEvidence(data.formulation)
    stepped = streamed._pair.differences

    def slow(*args: object, **kwargs: object) -> np.ndarray:
        time.sleep(0.05)
        return stepped(*args, **kwargs)

    monkeypatch.setattr(streamed._pair, "differences", slow)
    for ti, zi in zip(data.t[:200], data.z[:200]):
        streamed.add(ti, zi)
    assert not streamed.active and streamed.evidence() is None


def test_the_streamed_evidence_ends_on_its_filters_failure_and_not_the_stream(
    tmp_path, monkeypatch
) -> None:
    """Live's twist evidence is a hint: an exception of its filters (on their thread)
    ends it, with no evidence, and nothing is raised into the stream."""
    from continuum_mhe.estimators import twist_evidence as te

    robot = read_robot(str(_calibrated(tmp_path, "spatial")))
    data = load_input(ROD / "spatial_raw.csv", InputOptions(), make_formulation("bend", robot))
    streamed = te.StreamedTwistEvidence(data.formulation)

    def fail(*_: object, **__: object) -> np.ndarray:
        raise RuntimeError("singular")

    monkeypatch.setattr(streamed._pair, "differences", fail)
    for ti, zi in zip(data.t[:200], data.z[:200]):
        streamed.add(ti, zi)
    assert streamed.evidence() is None and not streamed.active


def test_the_evidence_s_compiled_run_is_the_filter_stepped_sample_by_sample(tmp_path) -> None:
    """``KalmanInference.log_likelihoods`` (the evidence's filters, each over the whole
    recording in one compiled call) gives each sample's innovation log-density as the
    compiled EKF stepped one :meth:`infer` at a time does: the calibrated ``spatial`` rod,
    twist model and frames, with one IMU's readings missing on some samples and every
    reading on others (NaN where there is none). The masks are :meth:`measurement_mask`'s,
    row by row."""
    from continuum_mhe.estimators.base import Measurement
    from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
    from continuum_mhe.estimators.twist_evidence import twisted_formulation

    robot = read_robot(str(_calibrated(tmp_path, "spatial")))
    data = load_input(ROD / "spatial_raw.csv", InputOptions(), make_formulation("bend", robot))
    t, z = data.t[:200], data.z[:200].copy()
    imu_2 = data.formulation.measurement_blocks[1].slice
    z[50:53, imu_2] = np.nan  # IMU 2 silent
    z[80] = np.nan  # no reading at all
    for formulation in (data.formulation, twisted_formulation(data.formulation)):
        masks = formulation.measurement_masks(z)
        assert np.array_equal(masks, [formulation.measurement_mask(zk) for zk in z])
        assert masks[51, imu_2].sum() == 0 and masks[51].sum() > 0 and masks[80].sum() == 0
        stepped = CompiledExtendedKalmanInference(formulation).policy_inference()
        assert stepped is not None
        batch = np.full(len(t), np.nan)
        stepped.log_likelihoods(t, np.ascontiguousarray(z), masks, batch)
        one_by_one = CompiledExtendedKalmanInference(formulation)
        expected = []
        for tk, zk in zip(t, z):
            one_by_one.infer(Measurement(float(tk), zk))
            expected.append(one_by_one.log_likelihood)
        assert np.isnan(batch[0]) and np.isnan(batch[80]) and np.isfinite(batch[51])
        np.testing.assert_allclose(batch, expected, rtol=1e-12, atol=1e-9)
    # refused, not written into a copy or read across: another dtype, readings transposed
    zc = np.ascontiguousarray(z)
    with pytest.raises(TypeError):
        stepped.log_likelihoods(t, zc, masks, np.full(len(t), np.nan, dtype=np.float32))
    with pytest.raises(ValueError, match=r"z must be \(n, nz\)"):
        stepped.log_likelihoods(t, np.ascontiguousarray(zc.T), masks, batch)
    # the UKF's inference has no EKF step to weigh readings with
    from continuum_mhe.estimators.kalman import UnscentedKalmanInference

    unscented = UnscentedKalmanInference(data.formulation).policy_inference()
    assert unscented is not None
    with pytest.raises(ValueError, match="steps the EKF"):
        unscented.log_likelihoods(t, zc, data.formulation.measurement_masks(zc), batch)


def test_estimate_chooses_the_twist_for_a_ros2_bag_folder_as_for_its_csv(tmp_path, capsys) -> None:
    """A ROS 2 bag is a folder: ``estimate`` weighs the twist on it as on the same
    readings in a CSV file (the calibrated ``spatial`` rod's first 200 samples, one
    ``sensor_msgs/msg/Imu`` topic per IMU), with the same choice and evidence."""
    from robot_log_helpers import csv_and_ros2_bag

    cal = _calibrated(tmp_path, "spatial")
    lines = (ROD / "spatial_raw.csv").read_text().splitlines()[:201]
    said = {}
    for name, source, extra in csv_and_ros2_bag(lines, tmp_path):
        out = tmp_path / f"{name}.csv"
        capsys.readouterr()
        assert main(["estimate", str(source), "--robot", str(cal), "-o", str(out), *extra]) == 0
        summary = capsys.readouterr().err.strip().splitlines()[-1]
        said[name] = re.search(r"the IMUs' twist estimated \([^)]*\)", summary)
        assert said[name] is not None, summary
        assert "imu-twist = true" in out.read_text()
    assert said["csv"].group(0) == said["bag"].group(0)


def test_estimate_chooses_the_twist_for_a_calibrated_twisting_rod(
    tmp_path, capsys, uncalibrated_spatial: tuple[Path, str]
) -> None:
    """Without ``--imu-twist`` or ``--no-imu-twist``, ``estimate`` of a calibrated raw
    recording estimates the twist where the readings say so, says it, and records it:
    the shipped ``spatial`` rod within 10 mm of its tip on average (over 50 mm with the
    constant-curvature frames, ``--no-imu-twist``); the planar S keeps the frames; an
    uncalibrated robot file is not weighed (no clause: the module's run)."""
    cal = _calibrated(tmp_path, "spatial")
    truth = np.genfromtxt(ROD / "spatial_truth.csv", delimiter=",", names=True)
    tip = np.column_stack([truth["x"], truth["y"], truth["z"]])
    means, said = {}, {}
    for extra in ([], ["--no-imu-twist"]):
        out = tmp_path / f"e{len(extra)}.csv"
        capsys.readouterr()
        assert main(["estimate", str(ROD / "spatial_raw.csv"), "--robot", str(cal),
                     *extra, "-o", str(out)]) == 0  # fmt: skip
        said[bool(extra)] = capsys.readouterr().err.strip().splitlines()[-1]
        est = read_state_table(out)
        e = np.column_stack([est.column(c) for c in ("x", "y", "z")]) - tip
        means[bool(extra)] = np.nanmean(np.linalg.norm(e, axis=1))
        text = out.read_text()
        assert ("imu-twist = true" in text) is not bool(extra)
        assert ("std_imu_twist_2" in text) is not bool(extra)
    assert means[False] < 10e-3 < 50e-3 < means[True], means
    assert "the IMUs' twist estimated (--imu-twist: the twist model predicted" in said[False]
    # the median is the twist model's gain over the frames, signed, not a log-density
    assert re.search(r"median log-density gain \+\S+ nats per reading", said[False]), said
    assert "twist" not in said[True]  # given: nothing weighed
    planar = _calibrated(tmp_path, "planar-s")
    out = tmp_path / "planar.csv"
    assert main(["estimate", str(ROD / "planar-s_raw.csv"), "--robot", str(planar),
                 "-o", str(out)]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "the IMUs' twist not estimated" in err
    assert re.search(r"median log-density gain -\S+ nats per reading", err), err
    assert "imu-twist = false" in out.read_text() and "std_imu_twist" not in out.read_text()
    uncalibrated, said_uncalibrated = uncalibrated_spatial
    assert "twist" not in said_uncalibrated.strip().splitlines()[-1]
    assert "std_imu_twist" not in uncalibrated.read_text()


def test_a_yaw_the_robot_file_lacks_reads_as_a_twist_and_the_summary_says_so(
    tmp_path, capsys
) -> None:
    """The ``spatial-tendon`` rod hardly twists: calibrated, the frames are kept. With
    IMU 2's yaw 30 degrees off in the robot file the readings favour the twist model,
    which takes the yaw up, and the summary's twist clause says that a yaw the file does
    not give reads as a twist, naming calibrate --bend."""
    cal = _calibrated(tmp_path, "spatial-tendon")
    text = cal.read_text()
    head, imu1, imu2 = text.split("[[imu]]")
    yaw = re.search(r"mount_rpy = \[([^\]]*)\]", imu2)
    assert yaw is not None
    roll, pitch, _ = (float(v) for v in yaw[1].split(","))
    turned = tmp_path / "yaw.toml"
    turned.write_text(
        "[[imu]]".join([head, imu1, imu2.replace(yaw[0], f"mount_rpy = [{roll}, {pitch}, 30.0]")])
    )
    said = {}
    for robot in (cal, turned):
        capsys.readouterr()
        assert main(["estimate", str(ROD / "spatial-tendon_raw.csv"), "--robot", str(robot),
                     "-o", str(tmp_path / f"{robot.stem}.csv")]) == 0  # fmt: skip
        said[robot] = capsys.readouterr().err.strip().splitlines()[-1]
    assert "the IMUs' twist not estimated" in said[cal] and "calibrate --bend" not in said[cal]
    assert "the IMUs' twist estimated (--imu-twist: the twist model predicted 9" in said[turned]
    assert (
        "a board's yaw about the backbone that the robot file does not give reads as a "
        "twist too: where the robot does not twist, measure the yaw, calibrate --bend;"
    ) in said[turned]


def test_imus_in_another_order_choose_the_twist_and_its_clause_names_the_order(
    tmp_path, capsys
) -> None:
    """The ``spatial-tendon`` rod's two IMUs swapped (its columns; a log's --topic order
    alike), estimated with the calibrated robot file: the readings favour the twist
    model, which explains them in part (with the MHE so well that too few samples
    restart for the restart warning that names the order: docs/model.md); the twist
    clause names the order as a cause beside a board's yaw (the EKF here, quicker)."""
    cal = _calibrated(tmp_path, "spatial-tendon")
    lines = (ROD / "spatial-tendon_raw.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[1:] if line]
    swapped = tmp_path / "swapped.csv"
    swapped.write_text(
        "\n".join([lines[0]] + [",".join(r[:1] + r[7:13] + r[1:7]) for r in rows]) + "\n"
    )
    capsys.readouterr()
    assert main(["estimate", str(swapped), "--robot", str(cal), "--method", "ekf", "-o",
                 str(tmp_path / "e.csv")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "the IMUs' twist estimated (--imu-twist: the twist model predicted 9" in err
    assert (
        "calibrate --bend; and so do IMUs in another order than the robot file's: the "
        "columns', or a log's --topic order)"
    ) in err.strip().splitlines()[-1]


def test_an_estimates_twist_past_a_turn_is_read_as_a_twist_not_degrees(tmp_path, capsys) -> None:
    """An IMU's twist is unwrapped: an estimate whose twist has turned past 2 pi (here the
    shipped ``spatial`` rod's estimate with IMU 2's twist moved by a whole turn, the same
    orientation) is read by ``evaluate`` as it is, with the same errors, not refused as
    an angle in degrees; a bend beyond 2 pi still is."""
    cal = _calibrated(tmp_path, "spatial")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(ROD / "spatial_raw.csv"), "--robot", str(cal), "--imu-twist",
                 "-o", str(est)]) == 0  # fmt: skip
    lines = est.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("t,"))
    names = lines[head].split(",")
    col = names.index("imu_twist_2")

    def moved(column: int, by: float) -> Path:
        out = []
        for k, ln in enumerate(lines):
            cells = ln.split(",")
            if k > head and cells[column]:
                cells[column] = repr(float(cells[column]) + by)
            out.append(",".join(cells))
        path = tmp_path / f"moved{column}.csv"
        path.write_text("\n".join(out) + "\n")
        return path

    turned = moved(col, 2 * math.pi)
    truth = str(ROD / "spatial_truth.csv")
    said = {}
    for path in (est, turned):
        capsys.readouterr()
        assert main(["evaluate", str(path), truth, "--robot", str(cal)]) == 0
        said[path] = [ln for ln in capsys.readouterr().out.splitlines() if "tip error" in ln]
    assert said[est] == said[turned] and said[est]
    bent = moved(names.index("theta_1"), 2 * math.pi)
    assert main(["evaluate", str(bent), truth, "--robot", str(cal)]) == 2
    err = capsys.readouterr().err
    assert "theta_1=" in err and "beyond 2 pi: degrees?" in err, err


def test_an_uncalibrated_twisting_rod_is_told_to_calibrate_first(
    tmp_path, capsys, uncalibrated_spatial: tuple[Path, str]
) -> None:
    """An uncalibrated robot file gets no twist chosen for it (its gyro biases, estimated,
    would read as twists), but where the readings do not fit and show the IMUs turning
    about the backbone, ``estimate`` says so after the warning on inconsistent estimates
    and names the calibration that lets the readings choose the twist: the shipped
    ``spatial`` rod (the twist model, estimating the biases too, predicts nearly every
    reading better). Nothing in the estimate changes (the same file as
    ``--no-imu-twist``, which says nothing of it). The ``spatial-tendon`` rod, hardly
    twisting, with readings given as ten times quieter than they are: inconsistent, not
    a twist, no such line."""
    from continuum_mhe.estimators.twist_evidence import twist_evidence, twisted_formulation

    path = ROD / "spatial_raw.csv"
    weighed, said = uncalibrated_spatial  # (the module's run: no twist option)
    errs, files = {False: said.splitlines()}, {False: read_state_table(weighed)}
    out = tmp_path / "u1.csv"
    capsys.readouterr()
    assert main(["estimate", str(path), "--robot", "two-section", "--no-imu-twist",
                 "-o", str(out)]) == 0  # fmt: skip
    errs[True] = capsys.readouterr().err.splitlines()
    files[True] = read_state_table(out)
    lines = errs[False]
    hints = [ln for ln in lines if "turning about the backbone" in ln]
    assert len(hints) == 1
    (inconsistent,) = [i for i, ln in enumerate(lines) if " are inconsistent: " in ln]
    assert lines.index(hints[0]) == inconsistent + 1
    assert hints[0].startswith(
        f"continuum-mhe: warning: {path}: the readings show the IMUs turning about the "
        "backbone, which the constant-curvature frames do not follow (a model of each IMU's "
        "twist predicted 9"
    )
    assert (
        "calibrate the gyro biases with the robot straight and still (continuum-mhe "
        "calibrate --from REST.csv --robot two-section --write-robot CAL.toml) and estimate "
        "with --robot CAL.toml" in hints[0]
    )
    assert not any("turning about the backbone" in ln for ln in errs[True])
    assert files[False].names == files[True].names
    assert_allclose(files[False].values, files[True].values, rtol=0, atol=0)

    from continuum_mhe.io.robot_file import shipped_robots

    shipped = read_robot(shipped_robots()["two-section"])
    data = load_input(path, InputOptions(), make_formulation("bend", shipped))
    assert twisted_formulation(data.formulation).estimate_gyro_bias  # nothing calibrated
    evidence = twist_evidence(data.formulation, data.t, data.z)
    assert evidence.twists and evidence.share > 0.9 and evidence.median > 100.0

    capsys.readouterr()
    out = tmp_path / "tendon.csv"
    assert main(["estimate", str(ROD / "spatial-tendon_raw.csv"), "--robot", "two-section",
                 "--noise-deg", "0.3", "-o", str(out)]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert " are inconsistent: " in err and "turning about the backbone" not in err


@pytest.mark.parametrize(
    ("mounting", "options", "named"),
    [
        ("z-up", [], "--length 0.2"),
        ("z-down", ["--mounting", "z-down", "--theta-max", "2.5"],
         "--length 0.2 --theta-max 2.5 --mounting z-down"),
    ],
)  # fmt: skip
def test_the_calibration_hint_of_a_length_run_names_its_length(
    tmp_path, capsys, mounting, options, named
) -> None:
    """A one-section run given by ``--length`` (no robot file) whose tip IMU turns about
    the backbone (a known twist of up to 2 rad applied to a PCC robot's raw readings): the
    hint names the calibration for that robot, its length, and its bound and mounting
    where given, not a robot file the user does not have."""
    from dataclasses import replace

    robot = replace(Robot.single(0.2), mounting=mounting)
    rec = simulate_robot("paper3d", robot, duration=8.0, seed=2)
    values, _ = raw_readings(rec, robot, RawNoise(gyro_bias_std=0.0), seed=2)
    psi = 1.0 * (1 - np.cos(0.8 * rec.t))
    acc = np.array([_rz(p).T @ a for p, a in zip(psi, values[:, :3])])
    gyr = np.array([_rz(p).T @ g for p, g in zip(psi, values[:, 3:6])])
    gyr[:, 2] += np.gradient(psi, rec.t)
    path = tmp_path / "one_raw.csv"
    rows = np.column_stack([rec.t, acc, gyr])
    np.savetxt(path, rows, delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="", fmt="%.9g")
    capsys.readouterr()
    argv = ["estimate", str(path), "--length", "0.2", *options, "-o", str(tmp_path / "e.csv")]
    assert main(argv) == 0
    (hint,) = [ln for ln in capsys.readouterr().err.splitlines() if "turning about" in ln]
    assert f"(continuum-mhe calibrate --from REST.csv {named} --write-robot CAL.toml)" in hint
    assert "ROBOT.toml" not in hint


def test_a_calibrated_robot_files_refusal_is_in_the_command_lines_words(tmp_path, capsys) -> None:
    """The readings weighed for the twist before the estimate are read again by the
    estimate, which says what is wrong with them: a calibrated robot file that says
    ``z-down`` for the standing ``spatial`` rod is refused naming the robot file's key,
    as for an uncalibrated one, not in the words for a Robot made in Python."""
    cal = _calibrated(tmp_path, "spatial")
    down = tmp_path / "down.toml"
    down.write_text(cal.read_text().replace('mounting = "z-up"', 'mounting = "z-down"'))
    capsys.readouterr()
    out = tmp_path / "e.csv"
    assert main(["estimate", str(ROD / "spatial_raw.csv"), "--robot", str(down),
                 "-o", str(out)]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not out.exists()
    assert err.rstrip().endswith(
        f'the robot stands on its base? set mounting = "z-up" in the robot file {down}'
    )
