"""A robot whose IMUs cannot determine its shape: the rank that says so, the verdict of
``check-robot``, and estimates that are never ``ok``."""

from __future__ import annotations

import json
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.analysis.observability import model_check, observability_report, verdict
from continuum_mhe.cli import main
from continuum_mhe.errors import UnobservableShapeWarning
from continuum_mhe.estimators import make_estimator
from continuum_mhe.model.pcc import shape_rank
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings, RecoverySettings
from continuum_mhe.simulation.scenarios import simulate_robot

TWO = (Section(0.16, 3.0), Section(0.14, 3.0))
TIP_ONLY = Robot(TWO, (ImuPlacement(1),))


@pytest.mark.parametrize(
    ("robot", "rank"),
    [
        (Robot.single(), 2),
        (TIP_ONLY, 2),  # the tip's tilt: two readings for four bend coordinates
        (Robot(TWO, (ImuPlacement(0), ImuPlacement(1))), 4),
        (Robot(TWO, (ImuPlacement(1, 0.5), ImuPlacement(1))), 4),  # two along section 2
        (Robot(TWO, (ImuPlacement(1), ImuPlacement(1))), 2),  # two IMUs, one place
        (Robot(TWO, (ImuPlacement(0, 0.5), ImuPlacement(0))), 2),  # none on section 2
        (Robot((Section(0.1),) * 3, (ImuPlacement(0), ImuPlacement(2))), 4),
    ],
)
def test_shape_rank_counts_the_bend_coordinates_the_imus_determine(robot, rank) -> None:
    assert shape_rank(robot) == rank


def test_check_robot_calls_an_under_instrumented_robot_not_observable(
    tmp_path: Path, capsys
) -> None:
    r = observability_report(TIP_ONLY, samples=100)
    assert (r.tilt.rows, r.tilt.cols, r.tilt.max_rank) == (2, 4, 2)
    assert r.tilt.full_rank_fraction == 0.0 and r.tilt_window.full_rank_fraction == 0.0
    assert verdict(r).startswith("NOT observable: tilt determines at most 2 of the 4")
    two = observability_report(Robot(TWO, (ImuPlacement(0), ImuPlacement(1))), samples=100)
    assert two.tilt.full_rank_fraction == 1.0 and verdict(two).startswith("observable:")
    path = tmp_path / "tip_only.toml"
    path.write_text(
        "[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n[[imu]]\nsection = 2\n"
    )
    assert main(["check-robot", str(path), "--samples", "50", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["verdict"].startswith("NOT observable")
    assert report["observable"] == "no"  # for scripts: no prose to search
    assert "above" not in report["verdict"]  # nothing is above it in JSON
    assert report["tilt"]["full_rank_fraction"] == 0.0


def test_the_not_observable_verdict_says_what_the_gyros_determine() -> None:
    """The verdict of a robot tilt cannot place speaks of the gyros as the report finds
    them: a tip IMU alone on three sections leaves the gyros' two-sample Jacobian short
    of rank too, and the verdict says so instead of a rank the gyros do not reach; two
    IMUs on section 1 and one on section 3 leave it full with motion, as the verdict
    says."""
    three = (Section(0.15),) * 3
    tip = observability_report(Robot(three, (ImuPlacement(2),)), samples=50)
    assert tip.gyro_window.full_rank_fraction == 0.0
    line = verdict(tip)
    assert "the gyros do not determine it either" in line
    assert f"at most {tip.gyro_window.max_rank} of the 12 unknowns" in line
    assert "needs motion" not in line
    skip = Robot(three, (ImuPlacement(0, 0.5), ImuPlacement(0), ImuPlacement(2)))
    gap = observability_report(skip, samples=50)
    assert gap.gyro_window.full_rank_fraction > 0.0
    assert "the gyros' two-sample rank of the report needs motion" in verdict(gap)


def test_check_robot_says_whether_tilt_leaves_readings_to_check_the_model(
    tmp_path: Path, capsys
) -> None:
    """Two IMUs on two sections: four tilt readings for four bend coordinates, none left
    over to check the constant-curvature model (said, with the gyros as the remedy); a
    third IMU mid-section leaves two; a robot whose tilt does not determine its shape gets
    no such line (its verdict says more)."""
    two = observability_report(Robot(TWO, (ImuPlacement(0), ImuPlacement(1))), samples=50)
    assert model_check(two) is not None and model_check(two).startswith(
        "tilt gives 4 readings a sample for 4 bend coordinates, none left over:"
    )
    assert "raw IMUs' gyros" in model_check(two)
    three = Robot(TWO, (ImuPlacement(0, 0.5), ImuPlacement(0), ImuPlacement(1)))
    assert model_check(observability_report(three, samples=50)) == (
        "tilt gives 6 readings a sample for 4 bend coordinates: 2 left over check the "
        "constant-curvature model at every sample"
    )
    assert model_check(observability_report(TIP_ONLY, samples=50)) is None
    path = tmp_path / "two.toml"
    path.write_text(
        "[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n"
        "[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    assert main(["check-robot", str(path), "--samples", "50"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2] == f"model check: {model_check(two)}" and lines[-1].startswith("verdict:")
    assert main(["check-robot", str(path), "--samples", "50", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["model_check"] == model_check(two) and report["observable"] == "yes"
    assert "above" not in report["verdict"]  # nothing is above it in JSON
    assert (report["n_imus"], report["n_tendons"]) == (2, 0)  # the robot's own


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_no_estimate_of_an_unobservable_shape_is_ok(method) -> None:
    f = make_formulation("bend", TIP_ONLY)
    rec = simulate_robot("spatial", TIP_ONLY, duration=4.0, dt=0.05, seed=0)
    with pytest.warns(UnobservableShapeWarning, match="determine 2 of its 4 bend coordinates"):
        est = make_estimator(method, f, MHESettings(horizon=10))
    assert not est.shape_observable
    statuses = Counter(est.run(rec.t, rec.z).status.tolist())
    assert "ok" not in statuses and statuses["uncertain"] > 0.9 * len(rec.t)


def test_an_observable_robot_warns_nothing_and_is_ok() -> None:
    robot = Robot(TWO, (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=3.0, dt=0.05, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnobservableShapeWarning)
        est = make_estimator("ekf", f)
    series = est.run(rec.t, rec.z)
    # ok but the start and where the written tip std exceeds the uncertain fraction
    # (section 2 near straight across a horizontal section 1: 10 of the 61 rows)
    limit = RecoverySettings().uncertain_fraction * robot.length
    wide = np.linalg.norm(series.output_std[:, :3], axis=1) > limit
    assert est.shape_observable and wide.sum() <= 12
    assert np.array_equal(series.status[1:] == "uncertain", wide[1:])
    assert set(series.status[1:]) == {"ok", "uncertain"}


def test_fallback_answers_of_an_unobservable_robot_are_uncertain_too(monkeypatch) -> None:
    """An unobservable robot's rows are ``uncertain``, as its warning says, also where
    IPOPT answers every window (a first run): never ``fallback-ipopt``."""
    f = make_formulation("bend", TIP_ONLY)
    rec = simulate_robot("spatial", TIP_ONLY, duration=2.0, dt=0.05, seed=1)
    with pytest.warns(UnobservableShapeWarning):
        est = make_estimator("mhe", f, MHESettings(horizon=8, solver="ipopt"))
    original = type(est.inference).infer

    def fallback(self, m):
        state, cov, status = original(self, m)
        return state, cov, "fallback-ipopt" if status == "ok" else status

    monkeypatch.setattr(type(est.inference), "infer", fallback)
    statuses = Counter(est.run(rec.t, rec.z).status.tolist())
    assert "fallback-ipopt" not in statuses and statuses["uncertain"] > 0.9 * len(rec.t)


def test_a_silent_imu_that_the_shape_needs_makes_the_estimates_uncertain() -> None:
    """A two-section robot whose tip IMU is silent for longer than the gap reset gets
    no ``ok`` row after the restarts (its second section is predicted blindly); an IMU
    whose silence leaves the shape determined (two along section 2 and one on section 1)
    does not make the estimates uncertain."""
    robot = Robot(TWO, (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=6.0, dt=0.05, seed=0)
    z = np.array(rec.z, dtype=float)
    z[40:, 2:] = np.nan  # IMU 2 silent from t = 2 s
    est = make_estimator("ekf", f)
    series = est.run(rec.t, z)
    status = series.status
    # before the silence uncertain only where the written tip std exceeds the uncertain
    # fraction of the robot's length (section 2 near straight across a horizontal
    # section 1: its bend about the vertical moves no gravity direction)
    limit = RecoverySettings().uncertain_fraction * robot.length
    wide = np.linalg.norm(series.output_std[:40, :3], axis=1) > limit
    assert status[0] == "uncertain"  # the start, unconfirmed
    assert np.array_equal(status[1:40] == "uncertain", wide[1:]) and wide.sum() <= 12
    assert "ok" in status[40:48].tolist()  # silent for less than the 1 s gap reset: trusted
    assert set(status[61:].tolist()) <= {"uncertain", "reset"}  # silent for longer: never ok
    three = Robot(TWO, (ImuPlacement(0), ImuPlacement(1, 0.5), ImuPlacement(1)))
    rec3 = simulate_robot("spatial", three, duration=4.0, dt=0.05, seed=0)
    z3 = np.array(rec3.z, dtype=float)
    z3[20:, 4:] = np.nan  # the tip IMU silent: sections 1 and 2 still seen
    est3 = make_estimator("ekf", make_formulation("bend", three))
    after = est3.run(rec3.t, z3)
    limit3 = RecoverySettings().uncertain_fraction * three.length
    wide3 = np.linalg.norm(after.output_std[20:, :3], axis=1) > limit3
    assert np.array_equal(after.status[20:] == "uncertain", wide3) and wide3.sum() <= 8


def test_a_mounting_given_as_a_list_still_builds_an_estimator() -> None:
    """The rank is cached per robot, so a robot must hash: a list mount_rpy (from library
    code) is kept as a tuple, and the estimator builds (no TypeError)."""
    robot = Robot(TWO, (ImuPlacement(0, 1.0, [0, 0, 0]), ImuPlacement(1)))  # type: ignore[arg-type]
    assert robot.imus[0].mount_rpy == (0, 0, 0)
    assert make_estimator("ekf", make_formulation("bend", robot)).shape_observable


def test_check_robot_judges_a_tendon_robot_by_its_mechanics_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tendon robot's report is of the model that estimates it: with its tensions
    given, two IMUs' gravity directions determine the tip force; the tip IMU alone gives
    two of its three components (rank 2 everywhere), so it is not observable from one
    sample. The Jacobian (through the tip condition, by implicit differentiation)
    equals central differences of the solved statics."""
    from continuum_mhe.analysis.observability import _tendon_gravity_jacobian
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.pcc import up_vector
    from continuum_mhe.model.tendon_statics import Station, TendonStatics

    shipped = read_robot("tendon-two-section")
    report = observability_report(shipped, samples=40)
    assert report.tendon_force is not None and report.tendon_samples == 40
    assert report.tendon_force.full_rank_fraction == 1.0
    assert verdict(report).startswith("observable: with the tensions given, one sample of")
    tip_only = tmp_path / "tip.toml"
    text = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    body = text.read_text()
    first = body.index("[[imu]]")
    tip_only.write_text(body[:first] + body[body.index("[[imu]]", first + 1) :])
    assert main(["check-robot", str(tip_only), "--samples", "20"]) == 0
    out = capsys.readouterr().out
    assert "3x3, of full rank (3) at 0.0 % of those (min rank 2)" in out
    assert "NOT observable from one sample" in out
    # the Jacobian against central differences of the solved statics
    statics = TendonStatics(shipped)
    tau = np.zeros(shipped.n_tendons)
    tau[0], tau[4] = 4.0, 2.0
    force = np.array([0.05, -0.03, 0.02])
    stations = [Station(i.section, i.at) for i in shipped.imus]

    def gravity(f: np.ndarray) -> np.ndarray:
        _, poses = statics.solve(f, tau)
        return np.concatenate([poses[s][0].T @ up_vector(shipped.mounting) for s in stations])

    k0, _ = statics.solve(force, tau)
    _, g_f, g_k, r_k, r_f = (
        np.asarray(v, dtype=float) for v in _tendon_gravity_jacobian(shipped)(k0, force, tau)
    )
    jac = g_f - g_k @ np.linalg.solve(r_k, r_f)
    h = 1e-5
    fd = np.column_stack(
        [(gravity(force + h * e) - gravity(force - h * e)) / (2 * h) for e in np.eye(3)]
    )
    np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-6 * np.abs(fd).max())


def test_check_robot_of_a_rod_without_tendons_speaks_of_no_tensions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A backbone without tendons (a passive rod under its tip force) is given no
    tensions: neither its report nor its verdict speaks of tensions given."""
    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    body = shipped.read_text()
    rod = tmp_path / "rod.toml"
    rod.write_text(body[: body.index("[[tendon]]")] + body[body.index("[[imu]]") :])
    assert main(["check-robot", str(rod), "--samples", "20"]) == 0
    out = capsys.readouterr().out
    assert "no tendons: a rod under its tip force" in out
    lines = out.splitlines()
    # the verdict, the mechanics model's, follows its line, before the PCC comparison
    assert lines[1].startswith("tendon model, ") and lines[3].startswith("for comparison")
    said = lines[2]
    assert said.startswith("verdict: observable: one sample of the IMUs' tilt determines the tip")
    assert "tension" not in said, said


def test_the_tip_std_of_one_tilt_sample_known_answer() -> None:
    """A straight section of length L with its IMU at the tip: each bend coordinate
    turns the IMU by as much (tilt Jacobian I) and moves the tip sideways by L/2, so
    a reading noise s gives the tip a standard deviation of s L / 2 on each side axis,
    sqrt(2) s L / 2 in all; an IMU that does not turn with the bend gives infinity."""
    from continuum_mhe.analysis.observability import tip_noise_std

    length, s = 0.2, 0.01
    j_tip = np.array([[[length / 2, 0.0], [0.0, length / 2], [0.0, 0.0]]])
    got = tip_noise_std(np.eye(2)[None], j_tip, s)
    assert got[0] == pytest.approx(np.sqrt(2.0) * s * length / 2, rel=1e-12)
    assert tip_noise_std(np.array([[[1.0, 0.0], [0.0, 0.0]]]), j_tip, s)[0] == np.inf
    # and the report's, at a robot's sampled shapes: the same formula on its Jacobians,
    # so a tip IMU's is about the reading noise times the length
    rep = observability_report(Robot((Section(length, 3.0),), (ImuPlacement(0),)), samples=200)
    assert 0.5 * np.radians(2.0) * length < rep.tip_noise_std < 2.0 * np.radians(2.0) * length


@pytest.mark.parametrize(("at", "weak"), [(1.0, False), (0.05, True)])
def test_check_robot_says_an_imu_near_its_sections_base_sees_the_bend_weakly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], at: float, weak: bool
) -> None:
    """An IMU at 0.05 of its section turns by a twentieth of the bend: one sample of its
    tilt places the tip within 39 % of the robot's length, and the verdict, still
    observable (full rank), says so (a simulated estimate of such a robot is tens of mm
    off with every row uncertain); one at the section's end is not said to be weak."""
    robot = tmp_path / "r.toml"
    robot.write_text(
        f'mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\nat = {at}\n'
    )
    assert main(["check-robot", str(robot), "--samples", "200"]) == 0
    (line,) = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("verdict:")]
    assert line.startswith("verdict: observable: one sample of tilt determines all 2 bend")
    assert ("but weakly: one sample of tilt readings with 2 degrees of noise places the tip "
            "within about" in line) is weak  # fmt: skip


@pytest.mark.parametrize(("at", "weak"), [(0.3, True), (1.0, False)])
def test_check_robot_is_weak_where_estimate_would_mark_rows_uncertain(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], at: float, weak: bool
) -> None:
    """Three sections of 0.1 m with each IMU at 0.3 of its section: one sample of tilt
    places the tip within about a fifth of the length, beyond the tenth at which
    ``estimate`` marks a row uncertain, so the verdict says ``but weakly`` with the share
    of shapes beyond it, and ``--json`` says ``"weakly": true`` beside ``"observable":
    "yes"``; IMUs at the sections' ends are not weak."""
    robot = tmp_path / "r.toml"
    robot.write_text(
        "[[section]]\nlength = 0.1\n" * 3
        + "".join(f"[[imu]]\nsection = {k}\nat = {at}\n" for k in (1, 2, 3))
    )
    assert main(["check-robot", str(robot), "--samples", "300", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["observable"] == "yes" and report["weakly"] is weak
    tip = report["tip_noise_std"]
    assert (tip > 0.1 * report["length"]) is weak
    assert ("beyond 10 % at " in report["verdict"]) is weak
    share = report["tip_wide_share"]
    assert (share > 0.5) is weak and 0.0 <= share <= 1.0


@pytest.mark.parametrize(
    ("imus", "free"),
    [
        ([(0, 1.0), (2, 1.0)], (2, 3)),  # sections 1 and 3 of three: 2 and 3 share a bend
        ([(0, 1e-3), (1, 1.0)], (1, 2)),  # an IMU that barely turns
        ([(0, 1.0), (1, 1.0)], ()),
    ],
)
def test_check_robot_names_the_sections_whose_bend_the_imus_leave_free(
    imus: list[tuple[int, float]], free: tuple[int, ...]
) -> None:
    n = max(k for k, _ in imus) + 1
    robot = Robot(
        tuple(Section(0.15, theta_max=1.5) for _ in range(n)),
        tuple(ImuPlacement(section=k, at=at) for k, at in imus),
    )
    report = observability_report(robot, samples=50)
    assert report.free_sections == free
    said = "the IMUs leave the bend of section(s) "
    assert (
        (said + ", ".join(map(str, free)) in verdict(report))
        if free
        else said not in verdict(report)
    )


def test_check_robot_json_is_strict_json_for_a_robot_the_readings_do_not_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One IMU on two sections: the tip's standard deviation from one sample is not
    finite, and the report says null (JSON has no Infinity), not a value strict parsers
    refuse."""
    robot = tmp_path / "tip.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n'
        "[[imu]]\nsection = 2\n"
    )
    assert main(["check-robot", str(robot), "--samples", "50", "--json"]) == 0

    def refuse(constant: str) -> None:
        raise ValueError(f"not JSON: {constant}")

    report = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert report["tip_noise_std"] is None and report["observable"] == "no"


def test_a_share_of_shapes_under_one_never_reads_100_percent() -> None:
    """check-robot printed a rank drop at 1 of 2000 shapes as "at 100.0 % of shapes (min
    rank 5)": a share under 1 keeps the digits that show it, and one over 0 too."""
    from continuum_mhe.analysis.observability import _percent

    assert [_percent(f) for f in (0.9995, 1.0, 0.0, 1e-5, 0.5, 0.999)] == [
        "99.95", "100.0", "0.0", "0.001", "50.0", "99.9",
    ]  # fmt: skip


@pytest.mark.parametrize(("sections", "noted"), [(9, False), (10, True)])
def test_check_robot_of_many_sections_says_first_that_it_takes_a_while(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
    sections: int, noted: bool,
) -> None:  # fmt: skip
    """From ten sections on, ``check-robot`` says before its long check that it takes a
    minute or more (the check itself stands in here: it is what takes long)."""
    import continuum_mhe.analysis.observability as observability
    from continuum_mhe.errors import UserError

    def refused(*args: object, **kwargs: object) -> None:
        raise UserError("stand-in")

    monkeypatch.setattr(observability, "observability_report", refused)
    path = tmp_path / "many.toml"
    path.write_text("[[section]]\nlength = 0.02\n" * sections + "[[imu]]\nsection = 1\n")
    assert main(["check-robot", str(path)]) == 2
    err = capsys.readouterr().err
    note = f"note: checking {sections} sections: the check's cost grows with about the cube"
    assert (note in err) == noted
