"""Never ``ok`` when wrong, output errors that name the output, one line on stderr."""

from __future__ import annotations

import errno
import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

import continuum_mhe.io.estimate_sink as estimate_sink
import continuum_mhe.io.output_files as output_files
from continuum_mhe import MHESettings, RobotSettings, make_estimator, make_formulation, simulate
from continuum_mhe.cli import main
from continuum_mhe.estimators.window_nlp import objective_scale_exponent
from continuum_mhe.model.kinematics import tip_position
from continuum_mhe.model.paper import DRIFT_FRACTION

REPRO = Path(__file__).parent / "data" / "repro"


# --- IPOPT at 1 kHz: a convergence test scaled to the problem -------------------------
def test_ipopt_at_1khz_converges_and_agrees_with_the_fast_backend() -> None:
    rec = simulate("paper3d", duration=0.12, dt=0.001, seed=0)
    f = make_formulation("bend", RobotSettings())
    ipopt = make_estimator("mhe", f, MHESettings(solver="ipopt")).run(rec.t, rec.z)
    fast = make_estimator("mhe", f, MHESettings(solver="fast")).run(rec.t, rec.z)
    # an unscaled test: 'not-converged' on nearly every row
    assert ipopt.status[0] == "uncertain" and set(ipopt.status[1:]) == {"ok"}
    assert list(fast.status) == list(ipopt.status)
    np.testing.assert_allclose(ipopt.output, fast.output, rtol=0, atol=1e-6)


def test_objective_is_left_unscaled_at_20_hz() -> None:
    rec = simulate("paper3d", duration=3.0, dt=0.05, seed=0)
    est = make_estimator("mhe", make_formulation("bend", RobotSettings()), MHESettings())
    est.run(rec.t, rec.z)
    rinv = 1 / est.formulation.noise.measurement_std**2
    assert objective_scale_exponent(est.inference.window_problem(), rinv) == 0
    fast = make_estimator("mhe", make_formulation("bend", RobotSettings()), MHESettings())
    for t, z in zip(simulate("paper3d", duration=0.05, dt=0.001).t, rec.z):
        fast.step(__import__("continuum_mhe").Measurement(float(t), z))
    assert objective_scale_exponent(fast.inference.window_problem(), rinv) >= 3


def test_the_solvers_of_every_objective_scale_share_derivatives_equal_to_casadis_own() -> None:
    """The NLP's derivatives are formed once and given to IPOPT's solver of every
    objective scale; on a window of a two-section robot with a bend bound active
    (constraints and bounds), the quadratic and a robust loss, scaled and not, the
    answers are those of the solver for which CasADi forms the derivatives itself."""
    import casadi as ca

    from continuum_mhe import Measurement
    from continuum_mhe.estimators.window_nlp import _window_graph, build_nlp, pack_parameters
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot((Section(0.16, 3.0), Section(0.14, 0.5)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = __import__("continuum_mhe").simulate_robot("spatial", robot, duration=1.0, seed=3)
    est = make_estimator("mhe", f, MHESettings(horizon=8))
    for t, z in zip(rec.t, rec.z):
        est.step(Measurement(float(t), z))
    problem = est.inference.window_problem()
    p = pack_parameters(problem)
    X0 = np.tile(problem.xbar, 8) + 0.05
    for loss in ("l2", "huber"):
        graph = _window_graph(f, 8, loss, 1.0)
        assert set(graph.derivatives) == {"hess_lag", "grad_f", "jac_g"}
        for scale_exp in (0, 3):
            nlp = build_nlp(f, 8, 100, 1e-10, loss, 1.0, scale_exp)
            opts = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                    "ipopt.max_iter": 100, "ipopt.tol": 1e-10, "ipopt.acceptable_tol": 1e-6,
                    "calc_lam_p": False}  # fmt: skip
            if scale_exp:
                opts["ipopt.obj_scaling_factor"] = 10.0**-scale_exp
            own = ca.nlpsol("own", "ipopt", graph.nlp, opts)
            bounds = {"lbx": nlp.lbx, "ubx": nlp.ubx, "lbg": nlp.lbg, "ubg": nlp.ubg}
            ours = np.asarray(nlp.solver(x0=X0, p=p, **bounds)["x"], dtype=float)
            theirs = np.asarray(own(x0=X0, p=p, **bounds)["x"], dtype=float)
            assert nlp.solver.stats()["success"] and own.stats()["success"]
            np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12)
            bend_2 = ours.reshape(8, f.nx)[:, 2:4]
            assert np.isclose(np.hypot(*bend_2.T).max(), 0.5, atol=1e-6)  # on the bound
        assert _window_graph(f, 8, loss, 1.0) is graph  # formed once for both scales


# --- the paper formulation: rows that are not one shape are flagged ----------------------
def test_paper_formulation_rows_that_drift_are_flagged() -> None:
    rec = simulate("paper3d", duration=20.0, dt=0.05, seed=0)
    f = make_formulation("paper", RobotSettings())
    for method in ("mhe", "ekf"):
        s = make_estimator(method, f, MHESettings()).run(rec.t, rec.z)
        fk = np.array([tip_position(th, ph, 0.2) for th, ph in s.output[:, 3:5]])
        gap = np.linalg.norm(s.output[:, :3] - fk, axis=1)
        far = gap > DRIFT_FRACTION * 0.2
        assert far.any()  # the paper's separate position state drifts on this recording
        assert not np.any(s.status[far] == "ok")
        assert np.all(s.status[far] == "drifted")
        assert np.all(s.status[~far] != "drifted")


def test_bend_formulation_outputs_are_one_shape() -> None:
    """The bend formulation has no separate position state to drift: each row's tip is
    the constant-curvature arc of its own bend ``(theta, phi)`` (the paper's closed
    form), where the paper formulation's drifts from it (above)."""
    rec = simulate("paper3d", duration=20.0, dt=0.05, seed=0)
    for method in ("mhe", "ekf", "ukf"):
        s = make_estimator(method, make_formulation("bend", RobotSettings())).run(rec.t, rec.z)
        th, ph = s.output[:, 3], s.output[:, 4]
        # the paper's eq. (3): x = L cos(phi) (cos(theta) - 1) / theta, ...
        chord = 0.2 * np.where(np.abs(th) > 1e-4, (np.cos(th) - 1) / th, th**3 / 24 - th / 2)
        arc = np.column_stack([chord * np.cos(ph), chord * np.sin(ph), 0.2 * np.sinc(th / np.pi)])
        np.testing.assert_allclose(s.output[:, :3], arc, rtol=0.0, atol=1e-10)


# --- output errors name the output -------------------------------------------------------
def _meas(tmp_path: Path) -> Path:
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "2"]) == 0
    return meas


def test_output_ending_in_slash_is_an_error(tmp_path, capsys) -> None:
    meas = _meas(tmp_path)
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(tmp_path / "newdir") + "/"]) == 2
    assert "names a folder; give a file name" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


def test_read_only_output_is_not_replaced(tmp_path, capsys) -> None:
    meas = _meas(tmp_path)
    out = tmp_path / "e.csv"
    out.write_text("keep me\n")
    out.chmod(0o444)
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(out), "--method", "ekf"]) == 2
    assert "read-only; not replaced" in capsys.readouterr().err
    assert out.read_text() == "keep me\n"


def test_read_only_folder_names_the_output(tmp_path, capsys, monkeypatch) -> None:
    meas = _meas(tmp_path)
    folder = tmp_path / "ro"
    folder.mkdir()

    def denied(*args: object, **kwargs: object) -> None:  # root ignores a 0555 folder
        raise PermissionError(errno.EACCES, "Permission denied", str(folder / ".e.csv.1.x.tmp"))

    monkeypatch.setattr(output_files.tempfile, "mkstemp", denied)
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(folder / "e.csv"), "--method", "ekf"]) == 2
    err = capsys.readouterr().err
    assert f"{folder / 'e.csv'}: cannot write in folder {folder} (Permission denied)" in err
    assert ".tmp" not in err


@pytest.mark.parametrize(
    "command",
    [
        ["benchmark", "--json", "{folder}/b.json"],
        ["calibrate", "--from", "{rest}", "--write-robot", "{folder}/c.toml"],
        ["simulate", "paper3d", "-o", "{folder}/m.csv"],
        ["plot", "{rest}", "-o", "{folder}/p.png"],
    ],
    ids=["benchmark", "calibrate", "simulate", "plot"],
)
def test_a_read_only_file_system_is_refused_before_the_work(tmp_path, capsys, command) -> None:
    """An output on a read-only file system (which refuses even root, and which a
    folder's mode does not show to root) is one line naming it, exit 2, before any
    work: nothing printed before it (not minutes of benchmark, or calibrate's report,
    and then a failed write)."""
    rest = tmp_path / "rest.csv"
    assert main(["simulate", "rest", "--imu", "raw", "-o", str(rest), "--duration", "3"]) == 0
    folder = tmp_path / "ro"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs",
                              str(folder)], capture_output=True, timeout=60)  # fmt: skip
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        capsys.readouterr()
        args = [a.format(folder=folder, rest=rest) for a in command]
        assert main(args) == 2
        out, err = capsys.readouterr()
        assert out == ""
        assert re.fullmatch(
            rf"continuum-mhe: error: {re.escape(str(folder))}/\w+\.\w+: cannot write in "
            rf"folder {re.escape(str(folder))} \(Read-only file system\)\n",
            err,
        ), err
    finally:
        subprocess.run(["umount", str(folder)], check=False, timeout=60)


def test_a_folder_whose_files_cannot_be_removed_is_refused_naming_the_output(
    tmp_path, capsys, monkeypatch
) -> None:
    """An append-only folder (``chattr +a``: files made, never removed or replaced)
    is refused in one line naming the output, before any work, and the probe file made
    there is not named as the problem."""
    real_unlink = os.unlink

    def append_only(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        if str(path).endswith(".tmp"):
            raise PermissionError(errno.EPERM, "Operation not permitted", str(path))
        return real_unlink(path, *args, **kwargs)

    monkeypatch.setattr(output_files.os, "unlink", append_only)
    capsys.readouterr()
    out = tmp_path / "x.csv"
    assert main(["simulate", "paper3d", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"continuum-mhe: error: {out}: cannot write in folder {tmp_path} (a file made there "
        "cannot be removed or replaced: Operation not permitted)\n"
    )


def test_disk_full_names_the_output(tmp_path, capsys, monkeypatch) -> None:
    meas = _meas(tmp_path)

    def full(*args: object, **kwargs: object) -> str:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(estimate_sink, "estimate_lines", full)
    capsys.readouterr()
    out = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(out), "--method", "ekf"]) == 2
    err = capsys.readouterr().err
    assert err == f"continuum-mhe: error: {out}: No space left on device (nothing written)\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


def test_disk_full_on_a_real_tiny_tmpfs(tmp_path, capsys) -> None:
    small = tmp_path / "small"
    small.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(small)],
        capture_output=True,
        timeout=60,
    )
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        meas = tmp_path / "m.csv"
        assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "100"]) == 0
        capsys.readouterr()
        out = small / "e.csv"
        assert main(["estimate", str(meas), "-o", str(out), "--method", "ekf"]) == 2
        err = capsys.readouterr().err
        assert err == f"continuum-mhe: error: {out}: No space left on device (nothing written)\n"
        assert os.listdir(small) == []
    finally:
        subprocess.run(["umount", str(small)], check=False, timeout=60)


# --- the user sees one line ---------------------------------------------------------------
@pytest.mark.parametrize("name", ["gimbal_flip.csv", "mhe_stops.csv"])
@pytest.mark.parametrize("extra", [[], ["--solver", "ipopt"], ["--method", "ukf"]])
def test_one_line_on_stderr_for_inputs_that_stop_estimators(tmp_path, capfd, name, extra) -> None:
    code = main(["estimate", str(REPRO / name), "-o", str(tmp_path / "o.csv"), *extra])
    err = capfd.readouterr().err
    assert code == 0
    # the summary, after one warning where rows sit on theta_max (these readings bend to
    # pi/2, the bound) and one where many samples restarted: no traceback, no solver output
    *before, summary = err.splitlines()
    assert summary.startswith("wrote "), err
    restarts = [ln for ln in before if re.search("restarted the (estimator|UKF)", ln)]
    before = [ln for ln in before if ln not in restarts]
    for line in restarts:
        assert re.match(
            rf"continuum-mhe: warning: {re.escape(str(REPRO / name))}: \d+ of "
            rf"{summary.split()[1]} samples \(\d+ %\) restarted the "
            rf"{'UKF' if 'ukf' in extra else 'estimator'}",
            line,
        ), err
    on_bound = re.search(r"at-bound: (\d+)", summary)
    if on_bound is None:
        assert before == [], err
    else:
        (warning,) = before
        assert re.fullmatch(
            rf"continuum-mhe: warning: \d+ of {summary.split()[1]} estimates have a section's "
            r"bend on (or beyond )?its bending bound theta_max \(1\.571 rad; by status: "
            rf"(.*, )?at-bound {on_bound[1]}(, .*)?\).*; raise --theta-max if it bends so far"
            # (with the restarts warned of: a robot file that does not describe the robot)
            r"( \(but the restarts warned of above .*\))?",
            warning,
        ), err


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
@pytest.mark.parametrize("case", ["paper3d", "two sections"])
def test_a_burst_of_wrong_readings_is_not_ok_while_the_estimate_follows_it(
    case: str, method: str
) -> None:
    """0.6 rad added to every tilt IMU's roll for a burst of samples (6 of paper3d at
    20 Hz; 10 of a two-section spatial motion at 50 Hz): the first readings of the burst
    are beyond one sample's limit and ``inconsistent``, the estimator moves onto them, and
    the rest of the burst agrees with the moved estimate. Those rows, 50 to 61 mm
    (paper3d) and 104 to 126 mm (two sections) off at up to 13 and 29 of their standard
    deviations, must not be ``ok``: within a second of such a reading no row is ``ok``, and no
    ``ok`` row of the recording is more than 20 mm or 4 of its standard deviations off."""
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    if case == "paper3d":
        f = make_formulation("bend")
        rec = simulate("paper3d", duration=10, seed=0)
        n = 6
    else:
        robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
        f = make_formulation("bend", robot)
        rec = simulate_robot("spatial", robot, duration=10, seed=3, dt=0.02)
        n = 10
    z = rec.z.copy()
    first = int(np.argmax(rec.t >= 4.0 - 1e-9))
    rolls = [b.start for b in f.measurement_blocks]  # each tilt block is (roll, pitch)
    burst = slice(first, first + n)
    z[burst, rolls] = np.angle(np.exp(1j * (z[burst, rolls] + 0.6)))
    s = make_estimator(method, f).run(rec.t, z)
    status = np.asarray(s.statuses())
    err = s.output[:, :3] - rec.truth[:, :3]
    ok = status == "ok"
    assert np.any(np.linalg.norm(err[burst], axis=1) > 0.04)  # the estimate followed it
    assert not np.any(ok[(rec.t >= rec.t[first]) & (rec.t < rec.t[first] + 1.0)])
    assert not np.any(ok & (np.linalg.norm(err, axis=1) > 0.02))
    assert not np.any(ok[:, None] & (np.abs(err) > 4 * s.std[:, :3]))
