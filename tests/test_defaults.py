"""Right by default: the bound a robot file leaves out, estimates on a bound, raw IMUs
with their gyros, the mounting against gravity (known answers on the shipped
two-section rod recordings and on data made here)."""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.registry import make_formulation

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data"
ROD = DATA / "rod2"

TWO_SECTIONS = """mounting = "{mounting}"
[[section]]
length = 0.16{bound}
[[section]]
length = 0.14{bound}
[[imu]]
section = 1
[[imu]]
section = 2
"""


def _robot(tmp_path: Path, bound: str = "", mounting: str = "z-up") -> Path:
    p = tmp_path / f"robot{len(bound)}{mounting}.toml"
    p.write_text(TWO_SECTIONS.format(bound=bound, mounting=mounting), encoding="utf-8")
    return p


def _tip_errors_mm(est: Path, truth: Path) -> tuple[np.ndarray, np.ndarray]:
    e, t = read_state_table(est), read_state_table(truth)
    err = np.linalg.norm([e.column(c) - t.column(c) for c in ("x", "y", "z")], axis=0) * 1e3
    return err, e.status


def test_a_robot_file_without_theta_max_does_not_bound_the_bend_at_90_degrees(tmp_path):
    """The spatial rod's first section bends to 110 degrees: a robot file that leaves
    theta_max out gets a bound the rod never reaches, not 90 degrees."""
    robot = read_robot(_robot(tmp_path))
    assert all(s.theta_max > math.radians(150) for s in robot.sections)


def _bound_warning(err: str) -> str:
    """The one line of ``err`` that counts the estimates on a bending bound."""
    (line,) = [ln for ln in err.splitlines() if "bending bound" in ln]
    return line


def _bends(est: Path, bound: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(theta, on, status)`` of an estimate file: each section's bend (n, 2), the rows
    whose bend reaches ``bound`` (within 1e-3 rad), the statuses."""
    table = read_state_table(est)
    theta = np.column_stack([table.column("theta_1"), table.column("theta_2")])
    return theta, (theta >= bound - 1e-3).any(axis=1), table.status


def _by_status(status: np.ndarray) -> str:
    kinds, counts = np.unique(status, return_counts=True)
    return ", ".join(f"{k} {c}" for k, c in zip(kinds, counts))


def test_estimates_on_a_given_bound_are_at_bound_and_counted(tmp_path, capsys):
    """theta_max = pi/2 on a rod that bends to 110 degrees: the rows the bound clips say
    ``at-bound``, never ``ok``, and one warning counts them."""
    robot = _robot(tmp_path, "\ntheta_max = 1.5707963")
    est = tmp_path / "e.csv"
    args = ["estimate", str(ROD / "spatial_tilt.csv"), "--robot", str(robot), "-o", str(est)]
    assert main([*args, "--method", "ekf"]) == 0
    theta, on_bound, status = _bends(est, math.pi / 2)
    assert on_bound.sum() > 20
    assert not np.any(status[on_bound] == "ok")
    assert not np.any(status[~on_bound] == "at-bound")
    count = int(np.sum(status == "at-bound"))
    assert count > 20
    line = _bound_warning(capsys.readouterr().err)
    assert f"{on_bound.sum()} of 601 estimates have a section's bend on or beyond" in line


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_the_bound_warning_says_whether_the_estimator_holds_the_bound(tmp_path, capsys, method):
    """theta_max = pi/2 on the spatial rod's tilt: the MHE holds its estimates to the
    bound (none past it), and its warning says they are on it and the bound set them;
    the EKF's and UKF's pass it, and theirs says on or beyond, and how far."""
    robot = _robot(tmp_path, "\ntheta_max = 1.5707963")
    est, meas = tmp_path / "e.csv", tmp_path / "spatial_tilt.csv"
    lines = (ROD / "spatial_tilt.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    meas.write_text("".join(lines[:201]), encoding="utf-8")  # its first 4 s: bends past pi/2
    argv = ["estimate", str(meas), "--robot", str(robot), "-o", str(est)]
    assert main([*argv, "--method", method]) == 0
    theta, on, status = _bends(est, math.pi / 2)
    line = _bound_warning(capsys.readouterr().err)
    assert on.sum() > 10
    counted = f"{on.sum()} of 200 estimates have a section's bend on"
    if method == "mhe":
        assert np.nanmax(theta) <= math.pi / 2 + 1e-6
        assert f"{counted} its bending bound theta_max (1.571, 1.571 rad;" in line
        assert "the MHE holds its estimates to the bound, so the bound, not the data," in line
    else:
        largest = np.nanmax(theta, axis=0)
        assert largest.max() > math.pi / 2 + 0.1  # past the bound
        assert f"{counted} or beyond its bending bound theta_max (1.571, 1.571 rad;" in line
        beyond = [f"section {k + 1} up to {big:.3g} rad" for k, big in enumerate(largest)
                  if big >= math.pi / 2 - 1e-3]  # fmt: skip
        assert f"), {', '.join(beyond)}: the {method.upper()} does not hold" in line, line
        assert "the bound, not the data" not in line


def test_the_bound_warning_counts_every_row_on_the_bound_by_status(tmp_path, capsys):
    """The spatial rod's raw recording (its first 4 s) with a robot file that leaves
    theta_max out (3.0 rad): the MHE restarts on the bound, and those rows are
    ``reset``, not ``at-bound``; the warning counts what the file shows, every row whose
    theta_k is on the bound, by status."""
    est, meas = tmp_path / "e.csv", tmp_path / "spatial_raw.csv"
    lines = (ROD / "spatial_raw.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    meas.write_text("".join(lines[:201]), encoding="utf-8")  # its first 4 s: both statuses
    argv = ["estimate", str(meas), "--robot", str(_robot(tmp_path))]
    assert main([*argv, "-o", str(est)]) == 0
    _, on, status = _bends(est, 3.0)
    assert np.sum(status[on] == "reset") > 10 and np.sum(status[on] == "at-bound") > 10
    line = _bound_warning(capsys.readouterr().err)
    assert line.startswith(
        f"continuum-mhe: warning: {on.sum()} of 200 estimates have a section's bend on its "
        f"bending bound theta_max (3, 3 rad; by status: {_by_status(status[on])}): "
    ), line


def test_the_bound_warning_names_the_robot_files_key_or_the_option(tmp_path, capsys):
    """With a robot file, the bound is raised in it (``--theta-max`` is refused beside
    it); without one, by ``--theta-max``."""
    robot = _robot(tmp_path, "\ntheta_max = 1.5707963")
    argv = ["estimate", str(ROD / "spatial_tilt.csv"), "--method", "ekf"]
    assert main([*argv, "--robot", str(robot), "-o", str(tmp_path / "a.csv")]) == 0
    line = _bound_warning(capsys.readouterr().err)
    assert line.endswith(f"raise theta_max in the robot file {robot} if it bends so far")
    assert "--theta-max" not in line
    one = Path(__file__).parent / "data" / "repro" / "gimbal_flip.csv"
    assert main(["estimate", str(one), "--method", "ekf", "-o", str(tmp_path / "b.csv")]) == 0
    line = _bound_warning(capsys.readouterr().err)
    assert line.endswith("raise --theta-max if it bends so far") and "robot file" not in line


def test_a_bound_reached_by_readings_that_restart_the_estimator_puts_the_robot_file_first(
    tmp_path, capsys
):
    """The spatial rod's raw recording (its first 2 s) with its two IMUs' columns swapped
    in the header, and a robot file bounding each bend at 2 rad: the readings restart
    the estimator on many samples (warned of), and estimates sit on the bound; the
    bound's warning, besides raising the bound, says that where the robot file does not
    describe the robot raising it does not help. (Restarts of an estimate that diverged past a
    bound the robot passes do not: the spatial rod's tilt with a 90-degree bound,
    test_the_bound_warning_names_the_robot_files_key_or_the_option.)"""
    lines = (ROD / "spatial_raw.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    swapped = lines[0].replace("_1", "_X").replace("_2", "_1").replace("_X", "_2")
    meas = tmp_path / "swapped_raw.csv"
    meas.write_text(swapped + "".join(lines[1:101]), encoding="utf-8")
    robot = _robot(tmp_path, "\ntheta_max = 2.0")
    assert main(["estimate", str(meas), "--robot", str(robot), "-o", str(tmp_path / "e.csv")]) == 0
    err = capsys.readouterr().err
    assert "restarted the estimator (readings inconsistent with its estimate" in err
    line = _bound_warning(err)
    assert line.endswith(
        f"raise theta_max in the robot file {robot} if it bends so far (but the restarts "
        "warned of above say that readings contradicted the estimates: where the robot "
        "file does not describe the robot, as with IMUs swapped or turned over, raising "
        "the bound does not help)"
    ), line


def test_a_bound_no_robot_reaches_points_to_the_robot_file_not_to_raising_it(tmp_path, capsys):
    """Estimates held at the default bound (3 rad, 172 degrees) come from readings the
    model does not explain (here a rod that twists about itself), not from a robot
    bending that far: the warning says so, not to raise the bound; and the rows that
    disagree with their readings for most of the run get a line of their own after it
    (with the summary's count alone, an ``ok`` share could be read as reassurance),
    which says what to check in the robot file, once: the bound's warning points to it."""
    argv = ["estimate", str(ROD / "spatial_tilt.csv"), "--method", "ekf"]
    assert main([*argv, "--robot", str(_robot(tmp_path)), "-o", str(tmp_path / "a.csv")]) == 0
    err = capsys.readouterr().err
    line = _bound_warning(err)
    assert "if it bends so far" not in line and "raise theta_max" not in line
    assert line.endswith(
        "and a bound of 3 rad or more is one a robot does not reach: readings that the model "
        "of the robot does not explain pushed the estimates there (what to check: the "
        "warning on inconsistent estimates, which follows)"
    ), line
    (warned,) = [ln for ln in err.splitlines() if "are inconsistent:" in ln]
    assert err.index(line) < err.index(warned)
    assert "check the robot file against the robot (the IMUs' order" in warned
    assert err.count("check the robot file against the robot") == 1
    status = read_state_table(tmp_path / "a.csv").status
    bad = int(np.sum(status == "inconsistent"))
    assert bad > 0.25 * len(status)
    assert warned.startswith(
        f"continuum-mhe: warning: {bad} of {len(status)} estimates "
        f"({100 * bad / len(status):.0f} %) are inconsistent: their readings disagree"
    ), warned


def test_the_bound_warning_lists_the_causes_where_no_other_warning_does(tmp_path) -> None:
    """Estimates on a default bound that no robot reaches: without the warning on
    inconsistent estimates after it, the bound's warning says what to check itself; with
    it, it points there."""
    from continuum_mhe.estimators.run_notices import BendsOnBound
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.registry import make_formulation

    f = make_formulation("bend", read_robot(_robot(tmp_path)))
    tally = BendsOnBound(f)
    names = [o.name for o in f.outputs]
    out = np.zeros((4, len(names)))
    out[:, names.index("theta_2")] = 3.0  # the default bound
    tally.add(out, ["at-bound"] * 4)
    own, pointing = (
        tally.notice(10, "mhe", True, "raise theta_max", causes_follow=follow)
        for follow in (False, True)
    )
    assert own is not None and pointing is not None
    reached = "readings that the model of the robot does not explain pushed the estimates there"
    assert own.endswith(
        f"{reached}; check the robot file against the robot (the IMUs' order, section, at "
        "and mount_rpy, the sections' lengths and order, the mounting; check-robot lists "
        "them), or the robot does what the model cannot follow (a backbone that twists "
        "about itself)"
    ), own
    assert pointing.endswith(
        f"{reached} (what to check: the warning on inconsistent estimates, which follows)"
    ), pointing


def test_no_inconsistency_line_where_the_readings_fit(tmp_path, capsys):
    """The planar S rod, which the model follows: few rows inconsistent, no line."""
    argv = ["estimate", str(ROD / "planar-s_raw.csv"), "--method", "ekf"]
    assert main([*argv, "--robot", str(_robot(tmp_path)), "-o", str(tmp_path / "a.csv")]) == 0
    assert "are inconsistent" not in capsys.readouterr().err


def test_the_inconsistency_line_counts_and_names_what_to_check() -> None:
    """Known answers of the threshold: more than a quarter of the estimates, and five."""
    from continuum_mhe.estimators.run_notices import inconsistent_notice
    from continuum_mhe.model.registry import make_formulation

    f = make_formulation("bend")
    assert inconsistent_notice(25, 100, f) is None
    assert inconsistent_notice(4, 5, f) is None
    line = inconsistent_notice(26, 100, f)
    assert line is not None and line.startswith("26 of 100 estimates (26 %) are inconsistent")
    # a run the model does not fit: its ok rows are suspect too (a swapped or turned IMU
    # fits a planar motion's readings on many rows, ok and far off)
    assert line.endswith("Until the cause is found its ok rows are not to be trusted either: "
                         "a wrong robot file can fit some readings exactly, and an ok row "
                         "between inconsistent ones can be far off within a narrow standard "
                         "deviation")  # fmt: skip
    assert "--own-acceleration" not in line  # tilt readings: no own acceleration to model
    raw = make_formulation("direct")
    line = inconsistent_notice(5, 6, raw)
    assert line is not None and "--own-acceleration models it)" in line
    # the gyros' biases are states (the raw default): a step in one is named
    assert "a bias that steps (a change of temperature, a board's power cycled)" in line
    assert "bias that steps" not in (inconsistent_notice(26, 100, f) or "")
    assert "quiet readings at 50 Hz or more, as simulate --imu raw writes them" in line
    # a robot faster than the motion model (a bending plane turning at 2 turns a second:
    # 96 % of the rows inconsistent, every one but 16 ok with --accel-psd 1000) is told
    # more than to check its robot file: where --accel-psd sets the process noise it is named
    assert "a larger --accel-psd, NoiseSettings.bend_accel_psd, follows a faster" in line
    from dataclasses import replace

    own = replace(raw, own_acceleration=True)  # its white jerk, not --accel-psd
    line = inconsistent_notice(5, 6, own)
    assert line is not None and "--accel-psd" not in line
    # readings noisier in motion than assumed (5 degrees against the default 2 on a
    # three-section robot: 260 of 401 rows inconsistent, 132 restarts; with --noise-deg 5
    # none inconsistent): the noise they are judged against is named, with its value
    assert "readings noisier in motion than --noise-deg 2 (degrees) assumes" in line
    from continuum_mhe.settings import NoiseSettings

    noisy = replace(f, noise=NoiseSettings(measurement_std=math.radians(0.5)))
    line = inconsistent_notice(26, 100, noisy)
    assert line is not None and "than --noise-deg 0.5 (degrees) assumes" in line


def test_a_hanging_recording_with_a_z_up_robot_is_refused_naming_the_mounting(tmp_path, capsys):
    """A robot hanging from its base (simulated z-down) estimated as z-up: one line
    naming ``mounting``, exit 2, nothing written; as z-down it runs."""
    meas, est = tmp_path / "hang.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--mounting", "z-down", "-o", str(meas)]) == 0
    capsys.readouterr()
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(est)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "mounting" in err[0] and "z-down" in err[0]
    # without a robot file the option is the fix; with one, only its key (the option
    # is refused beside it)
    assert err[0].endswith("the robot hangs from its base? give --mounting z-down"), err[0]
    assert not est.exists()
    robot = tmp_path / "robot.toml"
    robot.write_text("[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n")
    assert main(["estimate", str(meas), "--robot", str(robot), "-o", str(est)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--mounting" not in err[0]
    assert f'set mounting = "z-down" in the robot file {robot}' in err[0], err[0]
    # theta_max 3.0 (172 degrees) reaches the 169 degrees read: a start curled so far
    # reads the same, and the line says so
    assert "or a start bent 169 degrees, within the sections' theta_max" in err[0], err[0]
    args = ["estimate", str(meas), "--method", "ekf", "--mounting", "z-down", "-o", str(est)]
    assert main(args) == 0


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_a_hanging_recording_run_from_python_on_a_z_up_robot_is_refused(method: str) -> None:
    """The library's ``run`` checks the first readings against the robot's mounting as
    the command line's reader does: arrays of a hanging two-section robot run on the
    same robot described z-up are refused in one line naming ``mounting`` and the
    Robot's field (without the check the UKF gives 59 of 81 rows ``ok``, 450 mm off);
    on the robot as it hangs they run."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    sections = (Section(0.16, theta_max=3.0), Section(0.14, theta_max=3.0))
    imus = (ImuPlacement(0), ImuPlacement(1))
    down = Robot(sections, imus, mounting="z-down")
    rec = simulate_robot("s-curve", down, duration=1.0, seed=1)
    up = make_estimator(method, make_formulation("bend", Robot(sections, imus)))
    with pytest.raises(UserError) as refused:
        up.run(rec.t, rec.z)
    message = str(refused.value)
    assert "\n" not in message and message.startswith("run: mounting: the robot is described")
    assert message.endswith(
        'the robot hangs from its base? make the Robot with mounting="z-down" (or set '
        'mounting = "z-down" in its robot file)'
    )
    series = make_estimator(method, make_formulation("bend", down)).run(rec.t, rec.z)
    assert len(series.t) == len(rec.t)


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_step_and_continue_run_check_the_first_readings_against_the_mounting(method: str) -> None:
    """``step`` and ``continue_run`` check the first 25 readings after a reset as ``run``
    checks a recording's: a hanging robot stepped as z-up is refused at its 25th sample
    in one line naming ``mounting`` (``step``: 24 estimates before it; without the check
    they would go on at the bound), and every later sample until a reset; ``continue_run``
    refuses a first block that holds them before stepping any sample; as it hangs, both
    run on."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import MOUNTING_START_SAMPLES, MountingError
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.results import Measurement
    from continuum_mhe.settings import MHESettings
    from continuum_mhe.simulation.scenarios import simulate_robot

    sections = (Section(0.16, theta_max=3.0), Section(0.14, theta_max=3.0))
    imus = (ImuPlacement(0), ImuPlacement(1))
    down = Robot(sections, imus, mounting="z-down")
    rec = simulate_robot("s-curve", down, duration=2.0, seed=1)
    # a short window: the readings 180 degrees off below send the MHE's windows to IPOPT
    up = make_estimator(
        method, make_formulation("bend", Robot(sections, imus)), MHESettings(horizon=5)
    )
    said = "step: mounting: the robot is described as z-up, but at the start gravity puts IMU 1"
    stepped = 0
    with pytest.raises(MountingError, match=said) as refused:
        for t, z in zip(rec.t, rec.z):
            up.step(Measurement(float(t), z))
            stepped += 1
    assert stepped == MOUNTING_START_SAMPLES - 1 and "\n" not in str(refused.value)
    assert str(refused.value).endswith(
        'make the Robot with mounting="z-down" (or set mounting = "z-down" in its robot file)'
    )
    with pytest.raises(MountingError):  # every later sample, until a reset
        up.step(Measurement(float(rec.t[stepped + 1]), rec.z[stepped + 1]))
    # a sample the policy refuses (a time not after the last) is not one of the 25
    from continuum_mhe.errors import SampleTimeError

    up.reset()
    for t, z in zip(rec.t[:24], rec.z[:24]):
        up.step(Measurement(float(t), z))
    with pytest.raises(SampleTimeError):
        up.step(Measurement(float(rec.t[23]), rec.z[24]))
    with pytest.raises(MountingError):
        up.step(Measurement(float(rec.t[24]), rec.z[24]))
    up.reset()
    with pytest.raises(MountingError, match="continue_run: mounting: the robot is described"):
        up.continue_run(rec.t, rec.z)
    up.reset()
    assert len(up.continue_run(rec.t[:10], rec.z[:10]).status) == 10  # not yet 25 samples
    # run checks its recording's start; a continue_run after it goes on mid-recording,
    # where the robot may be bent anyhow: not checked as a start again
    up.reset()
    with pytest.raises(MountingError, match="^run: mounting"):
        up.run(rec.t, rec.z)
    standing = simulate_robot("rest", Robot(sections, imus), duration=2.0, seed=1)
    up.run(standing.t, standing.z)  # a z-up start, checked; then readings 180 degrees off
    n = MOUNTING_START_SAMPLES + 1  # past the check of a start's readings
    later = rec.t[:n] + standing.t[-1] + 0.02
    assert len(up.continue_run(later, rec.z[:n]).status) == n
    hanging = make_estimator(method, make_formulation("bend", down))
    assert all(hanging.step(Measurement(float(t), z)) is not None for t, z in zip(rec.t, rec.z))
    hanging.reset()
    assert len(hanging.continue_run(rec.t, rec.z).status) == len(rec.t)


def test_a_hanging_robot_that_starts_bent_is_said_naming_the_mounting(tmp_path) -> None:
    """A hanging two-section robot whose recording starts bent (spatial: IMU 1 about 80
    degrees from hanging straight, 100 from standing) estimated with a z-up robot file:
    a warning naming ``mounting`` and the other mounting (the start is within what the
    sections' theta_max reach, so it is not refused); with the right mounting, none. A
    start beyond the sections' reach says that too (a theta_max too low is the other
    cause)."""
    import warnings

    from continuum_mhe.io.input_options import MountingWarning

    hang = tmp_path / "hang.toml"
    text = (DATA / "robots/two_section.toml").read_text()
    hang.write_text(text.replace('mounting = "z-up"', 'mounting = "z-down"'))
    meas = tmp_path / "m.csv"
    assert main(["simulate", "spatial", "--robot", str(hang), "-o", str(meas)]) == 0
    said = []
    for robot in ("two-section", str(hang)):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            argv = ["estimate", str(meas), "--robot", robot, "--method", "ekf", "-o",
                    str(tmp_path / "e.csv"), "--overwrite"]  # fmt: skip
            assert main(argv) == 0
        said.append([str(w.message) for w in seen if w.category is MountingWarning])
    assert len(said[0]) == 1 and said[1] == []
    assert "mounting: the robot is described as z-up" in said[0][0]
    # a shipped robot: a copy of its file, named where the package is installed
    import continuum_mhe

    shipped = Path(continuum_mhe.__file__).parent / "data" / "robots" / "two_section.toml"
    assert (
        f'if the robot hangs from its base, set mounting = "z-down" in a copy of the shipped '
        f"robot file {shipped} (given as --robot two-section) (the estimates"
    ) in said[0][0]
    # sections that cannot bend that far (theta_max 1.2 rad): the warning says so too
    low = tmp_path / "low.toml"
    low.write_text(text.replace("theta_max = 3.0", "theta_max = 1.2"))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        argv = ["estimate", str(meas), "--robot", str(low), "--method", "ekf", "-o",
                str(tmp_path / "e2.csv")]  # fmt: skip
        assert main(argv) == 0
    (message,) = [str(w.message) for w in seen if w.category is MountingWarning]
    assert message.endswith(
        "; it is beyond the 69 degrees the sections' theta_max let it bend (if the robot "
        f"does bend so far, raise theta_max in the robot file {low})"
    )


def test_a_recording_read_whole_in_python_is_said_once_about_its_mounting(tmp_path) -> None:
    """``load_input`` checks a recording's readings against the robot's mounting, and an
    estimator's ``run`` on the array it read does not say the same again (one
    MountingWarning for the hanging robot that starts bent, described as z-up); ``run``
    on another array (a copy) checks it."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import InputOptions, MountingWarning
    from continuum_mhe.io.inputs import load_input

    hang = tmp_path / "hang.toml"
    text = (DATA / "robots/two_section.toml").read_text()
    hang.write_text(text.replace('mounting = "z-up"', 'mounting = "z-down"'))
    meas = tmp_path / "m.csv"
    assert (
        main(["simulate", "spatial", "--robot", str(hang), "--duration", "2", "-o", str(meas)]) == 0
    )
    f = make_formulation("bend", read_robot("two-section"))

    def said(action) -> list[str]:  # type: ignore[no-untyped-def]
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            action()
        return [str(w.message) for w in seen if w.category is MountingWarning]

    got = []
    assert len(said(lambda: got.append(load_input(meas, InputOptions(), f)))) == 1
    data = got[0]
    est = make_estimator("ekf", data.formulation)
    assert said(lambda: est.run(data.t, data.z)) == []
    (again,) = said(lambda: est.run(data.t, data.z.copy()))
    assert again.startswith("run: mounting: the robot is described as z-up")


def test_raw_readings_of_a_hanging_rod_are_checked_against_the_robot_files_mounting(tmp_path):
    """The two-section rod's raw recording turned upside down (the specific force
    reversed: the rod hangs): refused with a z-up robot file, run with z-down."""
    text = (ROD / "spatial_raw.csv").read_text(encoding="utf-8").splitlines()
    header = text[0].split(",")
    flip = [i for i, h in enumerate(header) if h.startswith(("ax", "ay", "az"))]
    rows = []
    for line in text[1:]:
        v = line.split(",")
        rows.append(",".join(f"{-float(x)!r}" if i in flip else x for i, x in enumerate(v)))
    meas, est = tmp_path / "hang_raw.csv", tmp_path / "e.csv"
    meas.write_text("\n".join([text[0], *rows]) + "\n", encoding="utf-8")
    args = ["estimate", str(meas), "--method", "ekf", "-o", str(est)]
    assert main([*args, "--robot", str(_robot(tmp_path))]) == 2
    assert not est.exists()
    assert main([*args, "--robot", str(_robot(tmp_path, mounting="z-down"))]) == 0


def _mounting_refusal(capsys, meas: Path, robot: Path, est: Path) -> str:  # type: ignore[no-untyped-def]
    """The one line of ``estimate``'s refusal of ``meas`` on ``robot`` (z-up) for its
    mounting, the EKF writing ``est``."""
    capsys.readouterr()
    argv = ["estimate", str(meas), "--method", "ekf", "--robot", str(robot), "-o", str(est)]
    assert main(argv) == 2
    err: str = capsys.readouterr().err
    assert err.count("\n") == 1 and "mounting: the robot is described as z-up" in err
    return err


def test_one_imu_upside_down_is_named_as_that_imus_mounting(tmp_path, capsys) -> None:
    """IMU 1 alone mounted upside down (its specific force reversed, IMU 2 upright):
    the refusal names mounting and asks whether IMU 1 alone is upside down (its
    mount_rpy), not only whether the robot hangs."""
    text = (ROD / "spatial_raw.csv").read_text(encoding="utf-8").splitlines()
    header = text[0].split(",")
    flip = [i for i, h in enumerate(header) if h in ("ax_1", "ay_1", "az_1")]
    assert len(flip) == 3
    rows = [",".join(f"{-float(x)!r}" if i in flip else x for i, x in enumerate(ln.split(",")))
            for ln in text[1:]]  # fmt: skip
    meas, est = tmp_path / "imu1_flipped.csv", tmp_path / "e.csv"
    meas.write_text("\n".join([text[0], *rows]) + "\n", encoding="utf-8")
    err = _mounting_refusal(capsys, meas, _robot(tmp_path), est)
    assert err.rstrip().endswith(
        "(IMU 2 reads upright: is IMU 1 alone mounted upside down? its mount_rpy; or the "
        "IMUs in another order? IMU 1 is the one nearest the base: the columns' order, or "
        "the --topic order of a bag; or a start bent this far, within the sections' "
        "theta_max? start the recording where the robot is nearer straight)"
    )
    assert not est.exists()


def test_two_imus_reading_the_other_way_are_both_named_not_one_alone(tmp_path, capsys) -> None:
    """An upright robot of three sections and four IMUs (one mid-section) bent 54 degrees
    a section, described as z-down: IMU 1 and 2 read more than 90 degrees off z-down, IMU
    3 and 4 within it. The refusal names both IMU 1 and 2 as reading the other way, not
    "is IMU 1 alone mounted upside down?"."""
    sections = "".join(f"[[section]]\nlength = {v}\ntheta_max = 3.0\n" for v in (0.12, 0.1, 0.08))
    imus = "[[imu]]\nsection = 1\nat = 0.5\n" + "".join(
        f"[[imu]]\nsection = {i}\n" for i in (1, 2, 3)
    )
    upright, hanging = tmp_path / "up.toml", tmp_path / "down.toml"
    upright.write_text(f'mounting = "z-up"\n{sections}{imus}')
    hanging.write_text(f'mounting = "z-down"\n{sections}{imus}')
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    argv = ["simulate", "spatial", "--robot", str(upright), "--imu", "raw", "--duration", "2"]
    assert main([*argv, "-o", str(meas)]) == 0
    capsys.readouterr()
    argv = ["estimate", str(meas), "--method", "ekf", "--robot", str(hanging), "-o", str(est)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the robot is described as z-down" in err, err
    assert "alone" not in err, err
    assert (
        f'set mounting = "z-up" in the robot file {hanging} (IMU 3, 4 read upright, IMU 1, 2 '
        "the other way: are IMU 1, 2 mounted upside down? their mount_rpy; or the IMUs in "
        "another order?"
    ) in err, err
    assert not est.exists()


def test_swapped_columns_of_a_board_declared_upside_down_name_the_order(tmp_path, capsys) -> None:
    """IMU 2's board mounted upside down (rolled 180 degrees), its robot file saying so
    (``mount_rpy = [180, 0, 0]``), and the two IMUs' columns swapped: both read upside
    down at the start, and the refusal names the columns' order as well as the
    mounting (following the mounting alone gives estimates far off)."""
    text = (ROD / "spatial_raw.csv").read_text(encoding="utf-8").splitlines()
    header = text[0].split(",")
    flip = {header.index(c) for c in ("ay_2", "az_2", "gy_2", "gz_2")}
    swap = {
        header.index(f"{c}_1"): header.index(f"{c}_2") for c in ("ax", "ay", "az", "gx", "gy", "gz")
    }
    swap.update({j: i for i, j in swap.items()})
    rows = []
    for line in text[1:]:
        v = [f"{-float(x)!r}" if i in flip else x for i, x in enumerate(line.split(","))]
        rows.append(",".join(v[swap.get(i, i)] for i in range(len(v))))
    meas, est = tmp_path / "swapped.csv", tmp_path / "e.csv"
    meas.write_text("\n".join([text[0], *rows]) + "\n", encoding="utf-8")
    robot = tmp_path / "robot.toml"
    robot.write_text(
        TWO_SECTIONS.format(bound="", mounting="z-up") + "mount_rpy = [180, 0, 0]\n",
        encoding="utf-8",
    )
    err = _mounting_refusal(capsys, meas, robot, est)
    assert err.rstrip().endswith(
        "(or the IMUs in another order? IMU 1 is the one nearest the base: the columns' "
        "order, or the --topic order of a bag; IMU 2 is mounted upside down in the robot "
        "file's mount_rpy, so another IMU's readings in its columns read upside down too)"
    )
    assert not est.exists()


def test_a_lone_imu_declared_upside_down_gets_no_column_order_hint(tmp_path, capsys) -> None:
    """A one-IMU robot whose file mounts its board upside down, fed readings of a board
    mounted upright: refused for its mounting, with no word of the columns' order (one
    IMU has no other columns)."""
    raw = tmp_path / "raw.csv"
    assert main(["simulate", "paper3d", "--imu", "raw", "--duration", "2", "-o", str(raw)]) == 0
    robot = tmp_path / "one.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n'
        "mount_rpy = [180, 0, 0]\n",
        encoding="utf-8",
    )
    err = _mounting_refusal(capsys, raw, robot, tmp_path / "e.csv")
    assert "another order" not in err and "columns" not in err


def test_an_imu_further_out_upside_down_is_named(tmp_path) -> None:
    """IMU 2 mounted upside down (rolled 180 degrees: y and z of its accelerometer and
    gyro reversed) on a robot that starts straight, IMU 1 upright: the estimate is made
    (a section may start bent that far) with one MountingWarning naming IMU 2 and its
    mount_rpy; the recording as it is gives none."""
    import warnings

    from continuum_mhe.io.input_options import MountingWarning

    source = ROD / "spatial_raw.csv"
    text = source.read_text(encoding="utf-8").splitlines()
    header = text[0].split(",")
    flip = [i for i, h in enumerate(header) if h in ("ay_2", "az_2", "gy_2", "gz_2")]
    assert len(flip) == 4
    rows = [",".join(f"{-float(x)!r}" if i in flip else x for i, x in enumerate(ln.split(",")))
            for ln in text[1:]]  # fmt: skip
    meas = tmp_path / "imu2_flipped.csv"
    meas.write_text("\n".join([text[0], *rows]) + "\n", encoding="utf-8")
    argv = ["estimate", str(meas), "--method", "ekf", "--robot", str(_robot(tmp_path))]
    with pytest.warns(MountingWarning) as caught:
        assert main([*argv, "-o", str(tmp_path / "e.csv")]) == 0
    said = [str(w.message) for w in caught if issubclass(w.category, MountingWarning)]
    assert len(said) == 1
    assert re.match(
        rf"{re.escape(str(meas))}: mounting: at the start gravity puts IMU 2 17\d degrees from "
        r"the straight pose and IMU 1 \d degrees: the robot between them would start bent "
        r"17\d degrees or more; is IMU 2 mounted upside down\? \(its mount_rpy",
        said[0],
    ), said[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", MountingWarning)
        args = [str(source), "--method", "ekf", "--robot", str(_robot(tmp_path))]
        assert main(["estimate", *args, "-o", str(tmp_path / "f.csv")]) == 0


def test_the_imus_further_out_are_judged_where_both_read_and_within_theta_max() -> None:
    """The check of an IMU against the one before it: 178 degrees between them warns;
    150 degrees, which the section's theta_max of 3.0 rad can bend, does not; nor does
    an IMU silent at the start whose first readings come when the robot has bent (its
    angle is compared with the other IMU's at the same rows)."""
    import warnings

    from continuum_mhe.io.input_options import MountingWarning, check_imu_mountings
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    f = make_formulation("bend", read_robot(DATA / "robots/two_section.toml"))  # 3.0 rad each
    stiff = Robot(  # sections that bend 2.0 rad (115 degrees) at most
        (Section(0.16, theta_max=2.0), Section(0.14, theta_max=2.0)),
        (ImuPlacement(section=0), ImuPlacement(section=1)),
    )

    def start(second: float, first: float = 0.0, rows: int = 30) -> np.ndarray:
        z = np.zeros((rows, 4))
        z[:, 0], z[:, 2] = math.radians(first), math.radians(second)  # roll: the tilt
        return z

    with pytest.warns(MountingWarning, match=r"puts IMU 2 178 degrees .* and IMU 1 0 degrees"):
        check_imu_mountings("m.csv", start(178.0), f)
    late = np.vstack([start(150.0), start(142.0, first=62.0)])
    late[:30, 2:] = np.nan  # IMU 2 silent while IMU 1 reads straight, then 80 degrees apart
    with pytest.warns(MountingWarning, match=r"puts IMU 2 150 degrees"):
        check_imu_mountings("m.csv", start(150.0), make_formulation("bend", stiff))
    with warnings.catch_warnings():
        warnings.simplefilter("error", MountingWarning)
        check_imu_mountings("m.csv", start(150.0), f)
        check_imu_mountings("m.csv", late, make_formulation("bend", stiff))
    three = Robot(  # IMU 2 silent throughout: IMU 3 is compared with IMU 1
        tuple(Section(0.1, theta_max=3.0) for _ in range(3)),
        tuple(ImuPlacement(section=k) for k in range(3)),
    )
    z = np.zeros((30, 6))
    z[:, 2:4] = np.nan
    z[:, 4] = math.radians(179.0)
    with pytest.warns(MountingWarning, match=r"puts IMU 3 179 degrees .* and IMU 1 0 degrees"):
        check_imu_mountings("m.csv", z, make_formulation("bend", three))


def test_raw_imus_use_their_gyros_by_default() -> None:
    """A raw file with gyro columns and only a robot file: the direct model with each
    gyro's bias estimated and a MEMS gyro's noise; without gyro columns, tilt."""
    from continuum_mhe.io.input_options import DEFAULT_GYRO_STD, InputOptions
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.model.direct import DirectFormulation

    robot = read_robot(DATA / "robots/two_section.toml")
    base = make_formulation("bend", robot)
    with open_input(ROD / "planar-s_raw.csv", InputOptions(), base) as stream:
        f = stream.formulation
    assert isinstance(f, DirectFormulation) and f.estimate_gyro_bias
    assert f.gyro_std == DEFAULT_GYRO_STD <= 0.02


def test_the_library_s_raw_formulations_estimate_the_gyro_biases_by_default() -> None:
    """``make_formulation`` for raw IMUs, ``"direct"`` or ``"tendon"`` with
    ``imu_model="direct"``, estimates each gyro's bias as the command line does; an
    explicit False stays."""
    tendon = read_robot(DATA / "robots/tendon_two_section.toml")
    assert make_formulation(
        "direct", read_robot(DATA / "robots/two_section.toml")
    ).estimate_gyro_bias
    assert make_formulation("tendon", tendon, imu_model="direct").estimate_gyro_bias
    assert not make_formulation("tendon", tendon).estimate_gyro_bias  # tilt: no gyros
    off = make_formulation("tendon", tendon, imu_model="direct", estimate_gyro_bias=False)
    assert not off.estimate_gyro_bias


def test_the_default_raw_estimate_is_the_better_one(tmp_path) -> None:
    """The planar S rod's raw recording (EKF): the default (gyros fused, biases
    estimated) against accelerometer tilt alone, 3.8 against 5.0 mm mean tip error."""
    robot = str(DATA / "robots/two_section.toml")
    args = ["estimate", str(ROD / "planar-s_raw.csv"), "--robot", robot, "--method", "ekf"]
    means = {}
    for name, extra in (("default", []), ("tilt", ["--imu-model", "tilt"])):
        est = tmp_path / f"{name}.csv"
        assert main([*args, *extra, "-o", str(est)]) == 0
        means[name] = float(np.mean(_tip_errors_mm(est, ROD / "planar-s_truth.csv")[0]))
    assert means["default"] < 0.85 * means["tilt"], means  # 0.76 of it


def test_the_model_error_floor_widens_the_std_and_zero_turns_it_off(tmp_path) -> None:
    """``--model-error-floor-deg``: the default carries a constant-curvature model's error
    in every standard deviation from the first row; 0 (data the model generated) leaves
    the readings' own noise and bias; the estimates themselves do not change."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "2", "--seed", "0"]) == 0
    tables = {}
    for floor in ("default", "0", "4"):
        out = tmp_path / f"e{floor}.csv"
        extra = [] if floor == "default" else ["--model-error-floor-deg", floor]
        assert main(["estimate", str(meas), "-o", str(out), "--method", "ekf", *extra]) == 0
        tables[floor] = read_state_table(out)
    assert all(t.std is not None for t in tables.values())
    i = tables["0"].names.index("x")
    std = {k: t.std[5:, i] for k, t in tables.items()}  # type: ignore[index]
    assert np.all(std["0"] < std["default"]) and np.all(std["default"] < std["4"])
    for k in ("0", "4"):
        np.testing.assert_array_equal(tables[k].column("x"), tables["default"].column("x"))


def test_simulated_readings_are_covered_at_their_level_without_the_constant_errors(
    tmp_path,
) -> None:
    """``--reading-bias-deg 0`` with ``--model-error-floor-deg 0``: on readings that
    ``simulate`` drew from the model with noise alone (no constant error, no model
    error) the tip's 95 % intervals cover the truth at their level, not always (the
    defaults, made for a real robot's IMUs, cover every row); the estimates do not
    change."""
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    argv = ["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--seed", "0"]
    assert main(argv) == 0
    tip = ["x", "y", "z"]
    true_tip = np.column_stack([read_state_table(truth).column(c) for c in tip])
    coverage, tables = {}, {}
    for name, extra in (("default", []), ("none", ["--model-error-floor-deg", "0",
                                                   "--reading-bias-deg", "0"])):  # fmt: skip
        out = tmp_path / f"e-{name}.csv"
        assert main(["estimate", str(meas), "-o", str(out), "--method", "ekf", *extra]) == 0
        t = tables[name] = read_state_table(out)
        est = np.column_stack([t.column(c) for c in tip])
        std = t.std[:, [t.names.index(c) for c in tip]]  # type: ignore[index]
        coverage[name] = np.mean(np.abs(est - true_tip) <= 1.96 * std, axis=0)
    assert np.all(coverage["default"] > 0.995)
    assert np.all((coverage["none"] > 0.9) & (coverage["none"] < 0.99)), coverage
    np.testing.assert_array_equal(tables["none"].column("x"), tables["default"].column("x"))


def test_the_library_recovers_as_the_command_line_does() -> None:
    """``RecoverySettings()`` is what ``estimate`` runs without recovery options (gap
    reset, freeze, bad-start check and reject reset on); ``off()`` turns them off."""
    from continuum_mhe.cli.app import build_parser
    from continuum_mhe.cli.recovery_options import recovery_settings_from_args
    from continuum_mhe.settings import RecoverySettings

    args = build_parser().parse_args(["estimate", "m.csv", "-o", "e.csv"])
    assert recovery_settings_from_args(args) == RecoverySettings()
    assert None not in (RecoverySettings().gap_reset, RecoverySettings().bad_start)
    off = RecoverySettings.off()
    assert (off.gap_reset, off.freeze, off.bad_start, off.reject_reset) == (None,) * 4


def test_a_start_bent_past_90_degrees_with_the_next_imu_upright_is_said_as_either(
    tmp_path,
) -> None:
    """The spatial rod from t = 8.1 s: IMU 1 starts 109 degrees from straight, IMU 2
    upright. The estimate is made (the sections reach that far), and the warning gives
    both readings: a start bent that way, or IMU 1 alone upside down."""
    import warnings

    from continuum_mhe.io.input_options import MountingWarning

    lines = (ROD / "spatial_raw.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    start = next(i for i, ln in enumerate(lines) if ln.startswith("8.1,"))
    meas = tmp_path / "bent_start.csv"
    meas.write_text("".join([lines[0], *lines[start : start + 60]]), encoding="utf-8")
    argv = ["estimate", str(meas), "--robot", "two-section", "--method", "ekf"]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main([*argv, "-o", str(tmp_path / "e.csv")]) == 0
    (said,) = [str(w.message) for w in seen if w.category is MountingWarning]
    assert "gravity puts IMU 1 109 degrees from that mounting's straight pose" in said
    assert said.endswith(
        "(IMU 2 reads upright: a start bent this way, or IMU 1 alone mounted upside down, "
        "its mount_rpy; or the IMUs in another order? IMU 1 is the one nearest the base: "
        "the columns' order, or the --topic order of a bag)"
    ), said


def test_dropout_rows_past_the_bound_are_not_counted_against_theta_max() -> None:
    """Rows without a reading (``dropout``: the motion model's prediction) that reach
    theta_max say nothing of how far the robot bends: the bound's notice counts the
    rows with readings that reach it, and every ``at-bound`` row, not them."""
    from continuum_mhe.estimators.run_notices import BendsOnBound
    from continuum_mhe.settings import RobotSettings

    f = make_formulation("bend", RobotSettings(theta_max=1.5))
    theta = f.outputs.index(next(o for o in f.outputs if o.name == "theta"))
    output = np.zeros((4, f.ny))
    output[:, theta] = [1.6, 1.6, 0.3, 1.0]
    bends = BendsOnBound(f)
    bends.add(output, ["dropout", "ok", "at-bound", "dropout"])
    assert bends.count == 2 and dict(bends.statuses) == {"ok": 1, "at-bound": 1}
    assert bends.largest == [1.6]


def test_bound_rows_while_an_imu_was_missing_are_said_as_its_dropout() -> None:
    """Rows on the bound whose sample lacked one IMU's reading (another's given): the
    bends that IMU leaves free drifted there, which says nothing of how far the robot
    bends; where every such row lacked one, the notice says so instead of advising to
    raise theta_max, and where some did, it counts them beside that advice. Rows with
    every reading, or none (a dropout's, not counted), are not such rows."""
    from continuum_mhe.estimators.run_notices import BendsOnBound
    from continuum_mhe.io.robot_file import read_robot

    f = make_formulation("bend", read_robot("two-section"))
    theta_2 = [o.name for o in f.outputs].index("theta_2")
    bound = f.robot.sections[1].theta_max
    output = np.zeros((4, f.ny))
    output[:, theta_2] = bound
    z = np.zeros((4, f.nz))
    z[0:2, 2:4] = np.nan  # IMU 2 missing in rows 0 and 1
    z[3] = np.nan  # no reading at all
    raise_it = "raise theta_max in the robot file R"
    bends = BendsOnBound(f)
    bends.add(output[:2], ["at-bound", "uncertain"], z[:2])
    assert bends.count == 2 and bends.partial == 2
    line = bends.notice(4, "mhe", True, raise_it)
    assert line is not None and raise_it not in line
    assert line.endswith(
        "and all of them while an IMU's reading was missing (a dropout): the bends the other "
        "IMUs leave free drift to the bound, which says nothing of how far the robot bends"
    )
    bends.add(output[2:], ["at-bound", "dropout"], z[2:])
    assert bends.count == 3 and bends.partial == 2
    line = bends.notice(4, "mhe", True, raise_it)  # a bound of 3 rad: no robot's
    assert line is not None and (
        "is one a robot does not reach (2 of them while an IMU's reading was missing, where "
        "the bends the other IMUs leave free drift): readings that the model" in line
    )


def test_a_tip_imu_bent_past_the_refusal_angle_is_said_not_refused(tmp_path, capsys):
    """The only IMU of a two-section robot at its tip reads a start bent 129 degrees
    from upright (the ``spatial`` scenario bends both sections): the sections before it,
    which no IMU reads, may bend it so far, so the start is not refused as a robot
    mounted the other way (as it is where the IMU nearest the base is on section 1):
    the warning names both readings."""
    robot = tmp_path / "tip.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n'
        "[[imu]]\nsection = 2\n"
    )
    meas = tmp_path / "m.csv"
    assert (
        main(["simulate", "spatial", "--robot", str(robot), "--duration", "2", "-o", str(meas)])
        == 0
    )
    from continuum_mhe.io.input_options import MountingWarning

    with pytest.warns(MountingWarning) as said:
        code = main(["estimate", str(meas), "--robot", str(robot), "--method", "ekf",
                     "-o", str(tmp_path / "e.csv")])  # fmt: skip
    assert code == 0
    (line,) = [str(w.message) for w in said if "mounting:" in str(w.message)]
    assert "puts IMU 1 129 degrees from that mounting's straight pose" in line
    assert line.endswith(
        "IMU 1 is on section 2, and the sections before it, whose bends the robot's IMUs do "
        "not determine, may bend it this far"
    )


def test_a_hanging_robot_whose_imus_are_all_on_section_2_is_still_refused(tmp_path, capsys):
    """Two IMUs on section 2 (at 0.5 and 1) determine both sections' bends: a hanging
    recording estimated as z-up is refused naming the mounting, as with an IMU on
    section 1 (the leniency is for robots whose IMUs do not determine the sections
    before them)."""
    text = (
        'mounting = "{m}"\n[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n'
        "[[imu]]\nsection = 2\nat = 0.5\n[[imu]]\nsection = 2\n"
    )
    down, up = tmp_path / "down.toml", tmp_path / "up.toml"
    down.write_text(text.format(m="z-down"))
    up.write_text(text.format(m="z-up"))
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert (
        main(["simulate", "s-curve", "--robot", str(down), "--duration", "2", "-o", str(meas)]) == 0
    )
    capsys.readouterr()
    assert main(["estimate", str(meas), "--robot", str(up), "--method", "ekf", "-o", str(est)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "mounting" in err[0] and "hangs from its base?" in err[0], err
    assert not est.exists()


def test_the_bound_warning_of_an_unobservable_robot_says_its_bends_drift(tmp_path, capsys):
    """One IMU on two sections: the bends the IMU leaves free drift to the bound, which
    the warning says (not that readings the model does not explain pushed them there).
    6 s of the spatial scenario are enough: the bends reach the bound within them."""
    robot = tmp_path / "tip.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n'
        "[[imu]]\nsection = 2\n"
    )
    meas = tmp_path / "m.csv"
    argv = ["simulate", "spatial", "--robot", str(robot), "--duration", "6", "-o", str(meas)]
    assert main(argv) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the unobservable robot's and the mounting's
        assert main(["estimate", str(meas), "--robot", str(robot), "--method", "mhe",
                     "-o", str(tmp_path / "e.csv")]) == 0  # fmt: skip
    line = _bound_warning(capsys.readouterr().err)
    drifted = re.search(r"(\d+) of 121 estimates have a section's bend on its bending bound", line)
    assert drifted and int(drifted[1]) > 10, line  # the drift to the bound is within the 6 s
    assert line.endswith(
        "and the robot's IMUs do not determine its shape: the bends they leave free drift "
        "to the bound (one IMU per section determines them; check-robot tells)"
    ), line


def test_a_recording_that_only_the_other_mounting_explains_is_said(tmp_path) -> None:
    """The paper's robot (theta_max 90 degrees) described standing, its tilt readings
    those of a hanging robot whose recording starts bent 95 degrees (85 from standing
    straight: the start check passes) and straightens: most readings lie beyond what
    theta_max lets a standing robot bend, none beyond what it lets a hanging one. The
    library's ``run`` warns naming ``mounting``; the same motion kept within 60 degrees
    of standing straight, or readings beyond the bound either way up, are not said."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import MountingWarning

    t = np.arange(200) * 0.05
    f = make_formulation("bend")

    def said(angle_deg: np.ndarray) -> list[str]:
        z = np.column_stack([np.radians(angle_deg), np.zeros_like(t)])  # roll: the angle
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            make_estimator("ekf", f).run(t, z)
        return [str(w.message) for w in seen if w.category is MountingWarning]

    hanging = 85.0 + 90.0 * np.clip((t - 2.0) / 4.0, 0.0, 1.0)  # 85, then to 175 degrees
    (message,) = said(hanging)
    assert message.startswith("run: mounting: ") and 'mounting="z-down"' in message
    assert "further from the z-up straight pose than the 90 degrees" in message
    # estimate's reading of a recording says it too, naming the file and the option
    path = tmp_path / "hang.csv"
    rows = "".join(f"{ti:.2f},{math.radians(a):.6f},0\n" for ti, a in zip(t, hanging))
    path.write_text("t,roll,pitch\n" + rows)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["estimate", str(path), "--method", "ekf", "-o", str(tmp_path / "e.csv")]) == 0
    (line,) = [str(w.message) for w in seen if w.category is MountingWarning]
    assert line.startswith(f"{path}: mounting: ") and "--mounting z-down" in line
    assert said(60.0 * np.sin(t) ** 2) == []
    (start,) = said(120.0 + 55.0 * np.clip((t - 2.0) / 4.0, 0.0, 1.0))  # the start's alone
    assert "at the start gravity puts IMU 1 120 degrees" in start
    assert said(70.0 + 40.0 * np.sin(t) ** 2) == []  # 70 to 110: beyond either way up


def test_a_filter_s_bound_notice_of_unobservable_bends_says_they_pass_the_bound() -> None:
    """A filter does not hold its bends to the bound: where the robot's IMUs do not
    determine its shape (one IMU on two sections), or every row lacked an IMU's
    reading, the free bends drift to the bound and past it, and the readings did not
    set them; the notice says so rather than that the readings set those shapes."""
    from continuum_mhe.estimators.run_notices import BendsOnBound

    f = make_formulation("bend", read_robot("two-section"))
    theta_2 = [o.name for o in f.outputs].index("theta_2")
    output = np.zeros((2, f.ny))
    output[:, theta_2] = [3.5, 4.0]
    raise_it = "raise theta_max in the robot file R"
    bends = BendsOnBound(f)
    bends.add(output, ["uncertain", "uncertain"])
    line = bends.notice(2, "ekf", False, raise_it, observable=False)
    assert line is not None and "section 2 up to 4 rad" in line
    assert "the readings, not the bound, set those shapes" not in line, line
    assert line.endswith(
        "the EKF does not hold its estimates to the bound, and the robot's IMUs do not "
        "determine its shape: the bends they leave free drift to the bound and past it (one "
        "IMU per section determines them; check-robot tells)"
    ), line
    z = np.zeros((2, f.nz))
    z[:, 2:4] = np.nan  # IMU 2 missing in both rows
    bends = BendsOnBound(f)
    bends.add(output, ["uncertain", "uncertain"], z)
    line = bends.notice(2, "ukf", False, raise_it)
    assert line is not None and "the readings, not the bound, set those shapes" not in line
    assert "the bends the other IMUs leave free drift to the bound and past it" in line, line
    bends = BendsOnBound(f)
    bends.add(output, ["ok", "ok"])
    line = bends.notice(2, "ekf", False, raise_it)
    assert line is not None and "so the readings, not the bound, set those shapes" in line


def test_the_bound_notice_of_an_unobservable_robot_names_a_determined_bend_on_it(
    tmp_path: Path,
) -> None:
    """A hanging robot of three sections with IMUs at the ends of sections 1 and 3: the
    IMUs leave sections 2 and 3 free, and section 1's IMU determines its bend. Section 1
    on its bound of 1.5708 rad did not drift there: the notice names it and says to
    raise its theta_max if the robot bends so far (it had said only that the free bends
    drift); free bends alone on the bound keep the drift's sentence alone."""
    from continuum_mhe.estimators.run_notices import BendsOnBound

    path = tmp_path / "three.toml"
    sections = "".join(
        f"[[section]]\nlength = {L}\ntheta_max = 1.5708\n" for L in (0.12, 0.18, 0.09)
    )
    path.write_text(
        f'mounting = "z-down"\n{sections}[[imu]]\nsection = 1\n[[imu]]\nsection = 3\n',
        encoding="utf-8",
    )
    f = make_formulation("bend", read_robot(str(path)))
    names = [o.name for o in f.outputs]
    raise_it = "raise theta_max in the robot file R"
    drift_only = (
        "and the robot's IMUs do not determine its shape: the bends they leave free drift "
        "to the bound (one IMU per section determines them; check-robot tells)"
    )
    output = np.zeros((2, f.ny))
    output[:, names.index("theta_2")] = 1.5708
    bends = BendsOnBound(f)
    bends.add(output, ["uncertain", "uncertain"])
    line = bends.notice(2, "mhe", True, raise_it, observable=False)
    assert line is not None and line.endswith(drift_only), line
    output[1, names.index("theta_1")] = 1.5708
    bends = BendsOnBound(f)
    bends.add(output, ["uncertain", "uncertain"])
    line = bends.notice(2, "mhe", True, raise_it, observable=False)
    assert line is not None and line.endswith(
        drift_only + "; but the IMUs determine the bend of section(s) 1, which reached the "
        "bound too: the robot may bend further than the bound allows; raise theta_max in "
        "the robot file R if it bends so far"
    ), line
    only_determined = np.zeros((2, f.ny))
    only_determined[:, names.index("theta_1")] = 1.5708  # no free bend on its bound
    bends = BendsOnBound(f)
    bends.add(only_determined, ["uncertain", "uncertain"])
    line = bends.notice(2, "mhe", True, raise_it, observable=False)
    assert line is not None and line.endswith(
        "and the robot's IMUs do not determine its shape (check-robot tells); but the IMUs "
        "determine the bend of section(s) 1, which reached the bound: the robot may bend "
        "further than the bound allows; raise theta_max in the robot file R if it bends so far"
    ), line
    assert "drift" not in line
