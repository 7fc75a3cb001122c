"""Tendon-driven robots' model: the robot file, the statics against known answers and
an independent peer, the formulation's Jacobians against finite differences, slack
tendons."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from tendon_helpers import (
    BACKBONE,
    DATA,
    EI,
    TENDON_FILE,
    one_section_robot,
)

from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.robot_file import read_robot, robot_toml
from continuum_mhe.io.state_tables import StateTable, read_state_table
from continuum_mhe.io.tensions import read_tensions
from continuum_mhe.model.robot import Backbone, ImuPlacement, Robot, Section, Tendon
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.model.tendon_statics import (
    STEPS_PER_SECTION,
    Station,
    TendonStatics,
    _compiled_drawing,
    _compiled_statics,
    _statics_functions,
)

GJ = BACKBONE.torsional_stiffness

# --- the robot file --------------------------------------------------------------------


def test_the_tendon_robot_file_is_read(tmp_path: Path) -> None:
    path = tmp_path / "r.toml"
    path.write_text(TENDON_FILE)
    robot = read_robot(path)
    assert robot.backbone == BACKBONE
    assert robot.sections[0].disks == 10
    (td,) = robot.tendons
    assert td.section == 0 and td.radius == 0.01
    assert td.offset == pytest.approx((0.0, 0.01), abs=1e-15)
    assert robot.imus[0].at == 0.5  # disk 5 of 10
    again = tmp_path / "again.toml"
    again.write_text(robot_toml(robot))
    assert read_robot(again) == robot


def test_a_pcc_robot_file_reads_as_before() -> None:
    robot = read_robot("two-section")
    assert robot.backbone is None and robot.tendons == ()
    assert robot == Robot(
        (Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1))
    )


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("[backbone]\nyoungs_modulus = 54e9\nshear_modulus = 20.77e9\nradius = 0.0007\n", ""),
         "1 [[tendon]] but no [backbone]"),
        (("youngs_modulus = 54e9", "youngs_modulus = -1"), "line 3: backbone youngs_modulus (Pa)"),
        (("youngs_modulus = 54e9", "youngs_modulus = 54"), "line 3: backbone youngs_modulus 54.0"),
        (("radius = 0.0007", "radius = 0.7"), "line 5: backbone radius 0.7 m is over 0.1 m"),
        (("shear_modulus = 20.77e9\n", ""), "backbone: missing key 'shear_modulus'"),
        (("angle = 90", "angle = 90\npitch = 1"), "tendon 1: unknown key 'pitch'"),
        (("section = 1\nangle", "section = 2\nangle"), "tendon 1: section must be"),
        (("radius = 0.01", "radius = 0"), "tendon 1: radius = 0: tendon radius (m) must be"),
        (("disk = 5", "disk = 11"), "imu 1: disk must be a disk number from 1 to 10"),
        (("disks = 10", "disks = 2.5"), "section 1: disks must be a whole number"),
    ],
)  # fmt: skip
def test_bad_tendon_robot_files_are_one_line_errors(
    tmp_path: Path, edit: tuple[str, str], message: str
) -> None:
    path = tmp_path / "r.toml"
    path.write_text(TENDON_FILE.replace(*edit))
    with pytest.raises(InputError) as err:
        read_robot(path)
    text = str(err.value)
    assert text.startswith(f"{path}: ") and message in text and "\n" not in text


# --- the statics against known answers ------------------------------------------------------
def test_one_tendon_on_a_straight_rod_gives_a_circular_arc() -> None:
    """Curvature ``tension * radius / EI`` towards the tendon, no twist."""
    for angle in (0.0, 2.0):
        robot = one_section_robot(Tendon(0, angle, 0.01))
        tau = 1.5
        _, poses = TendonStatics(robot).solve(np.zeros(3), np.array([tau]))
        R, p = poses[Station(0, 1.0)]
        kappa = tau * 0.01 / EI
        theta = kappa * 0.2
        towards = np.array([math.cos(angle), math.sin(angle), 0.0])
        expected = (1 - math.cos(theta)) / kappa * towards + [0, 0, math.sin(theta) / kappa]
        np.testing.assert_allclose(p, expected, atol=1e-8)
        tangent = math.sin(theta) * towards + [0, 0, math.cos(theta)]
        np.testing.assert_allclose(R[:, 2], tangent, atol=1e-8)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-7)


def test_shape_gives_the_arc_of_one_tendon_and_phi_0_where_straight() -> None:
    """``TendonFormulation.shape``: one tendon at 0 deg on a weightless section bends it
    to ``tension * radius / EI * L`` towards +x (``phi`` pi: the tangent is
    ``(-cos phi sin theta, -sin phi sin theta, cos theta)``), its end where the arc
    ends; with no tension the section is straight and its ``phi`` is 0, not -pi (the
    exact clip of a slack tendon: a one-IMU robot's default smooth one pulls 0.5 mN)."""
    robot = one_section_robot(Tendon(0, 0.0, 0.01))
    f = TendonFormulation(robot, slack_smoothing=0.0)
    straight = f.shape([0.0])
    assert straight["theta_1"] == 0.0 and straight["phi_1"] == 0.0
    assert straight["psi_1"] == 0.0 and straight["z"] == pytest.approx(0.2, abs=1e-12)
    bent = f.shape([1.5])
    kappa = 1.5 * 0.01 / EI
    assert bent["theta_1"] == pytest.approx(kappa * 0.2, rel=1e-9)
    assert abs(bent["phi_1"]) == pytest.approx(math.pi, abs=1e-9)
    assert bent["x"] == pytest.approx((1 - math.cos(kappa * 0.2)) / kappa, rel=1e-7)
    assert bent["z"] == pytest.approx(math.sin(kappa * 0.2) / kappa, rel=1e-9)
    assert (bent["fx"], bent["fy"], bent["fz"]) == (0.0, 0.0, 0.0)
    with pytest.raises(UserError, match="non-negative tensions"):
        f.shape([-1.0])
    with pytest.raises(UserError, match="1 finite"):
        f.shape([1.0, 2.0])


def test_the_backbone_points_of_one_tendon_lie_on_its_arc_evenly_spaced() -> None:
    """The drawn backbone (``backbone_points``) of a straight rod pulled by one tendon:
    every point on the circle of curvature ``tension * radius / EI`` through the base,
    in the tendon's plane, at arc lengths ``L j / m``."""
    robot = one_section_robot(Tendon(0, 2.0, 0.01))
    tau, m = 1.5, 8
    points = TendonStatics(robot).backbone_points(np.zeros(3), np.array([tau]), m)
    kappa = tau * 0.01 / EI
    s = 0.2 * np.arange(m + 1) / m
    towards = np.array([math.cos(2.0), math.sin(2.0), 0.0])
    expected = ((1 - np.cos(kappa * s)) / kappa)[:, None] * towards
    expected[:, 2] = np.sin(kappa * s) / kappa
    np.testing.assert_allclose(points, expected, atol=1e-8)


def test_the_backbone_points_pass_through_the_models_section_ends() -> None:
    """Under a tip force that twists a bent two-section robot, the drawn backbone ends
    each section where the estimators' model puts its end: to the error of the model's
    two steps a section (2e-5 m on this bend), which the drawn curve's 16 do not share."""
    robot = read_robot("tendon-two-section")
    statics = TendonStatics(robot)
    tension = np.zeros(robot.n_tendons)
    tension[0] = 3.0
    force = np.array([0.05, 0.1, 0.0])
    points = statics.backbone_points(force, tension, 16)
    _, poses = statics.solve(force, tension)
    assert points.shape == (33, 3)
    for k in range(2):
        np.testing.assert_allclose(points[16 * (k + 1)], poses[Station(k, 1.0)][1], atol=5e-5)
    assert np.linalg.norm(points[-1] - points[0]) > 0.1  # a bend, not a straight rod


def test_the_statics_evaluated_by_the_core_are_casadis_values() -> None:
    """The statics' functions as :meth:`TendonStatics.solve` and ``backbone_points``
    evaluate them (the compiled core, from their tapes) give CasADi's own values, bit for
    bit, at loads that bend and twist the robot and at a slack tendon."""
    statics = TendonStatics(read_robot("tendon-two-section"))
    rng = np.random.default_rng(3)
    compiled = (*_compiled_statics(statics), _compiled_drawing(statics, 16))
    references = (statics.function, *_statics_functions(statics)[1:], statics.drawing_function(16))
    for _ in range(3):
        k0, force = rng.normal(0.0, 3.0, 3), rng.normal(0.0, 0.1, 3)
        tension = np.abs(rng.normal(0.0, 2.0, statics.robot.n_tendons))
        tension[1] = 0.0
        for fast, casadi in zip(compiled, references):
            got = fast(k0, force, tension)
            want = [np.asarray(v, dtype=float) for v in casadi(k0, force, tension)]
            assert [g.shape for g in got] == [w.shape for w in want]
            for g, w in zip(got, want):
                np.testing.assert_array_equal(g, w)


def test_the_statics_refuse_tensions_of_another_count() -> None:
    """Tensions or a force of another size than the robot's are an error, as CasADi's
    own evaluation makes them: not a shape from values beyond the arrays given."""
    statics = TendonStatics(read_robot("tendon-two-section"))
    force = np.array([0.0, 0.05, 0.0])
    for tension in (np.ones(5), np.ones(7)):
        with pytest.raises(ValueError, match=r"not \[3, 3, 6\]"):
            statics.solve(force, tension)
    with pytest.raises(ValueError, match="sizes"):
        statics.backbone_points(np.zeros(2), np.ones(6))


@pytest.mark.parametrize("scenario", ["force-29", "twist-29"])
def test_the_statics_solve_the_loaded_recordings_from_the_straight_rod(scenario: str) -> None:
    """``TendonStatics.solve`` from the straight rod (as ``plot`` draws a row) under the
    true tip force and tensions of every 10th sample of a loaded recording: each tip
    within 0.6 mm of the recording's truth (the model floor: the generator's own
    rod is not this model). A plain Newton from the straight rod leaves 16 of force-29's
    41 rows 250 to 640 mm off and raises LinAlgError on 8."""
    truth = read_state_table(DATA / f"{scenario}_truth.csv")
    tensions = read_tensions(DATA / f"{scenario}_tensions.csv", 6)
    statics = TendonStatics(read_robot("tendon-two-section"))
    force = np.stack([truth.column(c) for c in ("fx", "fy", "fz")], axis=1)
    tip = np.stack([truth.column(c) for c in ("x", "y", "z")], axis=1)
    for row in range(0, len(truth.t), 10):
        _, poses = statics.solve(force[row], tensions.at(float(truth.t[row]))[0])
        assert np.linalg.norm(poses[Station(1, 1.0)][1] - tip[row]) < 6e-4, row


def test_the_statics_say_when_the_rod_holds_no_equilibrium() -> None:
    """Loads that are not finite have no equilibrium: ``ArithmeticError`` (not
    numpy's singular matrix)."""
    statics = TendonStatics(read_robot("tendon-two-section"))
    with pytest.raises(ArithmeticError, match="no equilibrium"):
        statics.solve(np.array([np.nan, 0.0, 0.0]), np.zeros(6))


SOFT_TENDON_FILE = (
    """
[backbone]
youngs_modulus = 60e9
shear_modulus = 23e9
radius = 0.0004
density = 6450
[[section]]
length = 0.15
disks = 8
[[section]]
length = 0.25
disks = 12
"""
    + "".join(
        f"[[tendon]]\nsection = {k}\nangle = {a}\nradius = {r}\n"
        for k, r, angles in ((1, 0.008, (45, 135, 225, 315)), (2, 0.006, (0, 90, 180, 270)))
        for a in angles
    )
    + "[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
)


def test_a_drawn_backbone_follows_the_rows_where_the_loads_hold_two_equilibria(
    tmp_path: Path,
) -> None:
    """A soft backbone under a tip force eleven times its buckling load holds more than
    one equilibrium: solved from the straight rod, the last of 41 rows whose loads grow
    in proportion reaches one whose tip is over 100 mm from the one the rows come
    through, each solved from the one before (as the generator's rod and ``view`` follow
    them). ``plot``'s backbone of that row (``tendon_backbone``) is the rows' one."""
    from continuum_mhe.evaluation.estimate_tables import tendon_backbone

    path = tmp_path / "soft.toml"
    path.write_text(SOFT_TENDON_FILE)
    robot = read_robot(path)
    statics = TendonStatics(robot)
    force = np.array([0.0571, 0.1093, 0.0925])  # a generator recording's, at t = 1.56 s
    tension = np.array([1.0598, 0.5874, 0.003, 0.4753, 1.5312, 0.4865, 0.063, 1.1077])
    scale = np.linspace(0.0, 1.0, 41)
    t = 0.02 * np.arange(len(scale))
    k0 = None
    for s in scale:
        k0, poses = statics.solve(s * force, s * tension, k0)
    followed = poses[Station(1, 1.0)][1]
    _, cold = statics.solve(force, tension)
    assert np.linalg.norm(cold[Station(1, 1.0)][1] - followed) > 0.1  # another one
    table_path = tmp_path / "tensions.csv"
    names = ["t"] + [f"tension_{j}" for j in range(1, 9)]
    write_table(table_path, names, [[tk, *(s * tension)] for tk, s in zip(t, scale)])
    tensions = read_tensions(table_path, 8)
    table = StateTable(
        t=t,
        names=("fx", "fy", "fz"),
        values=scale[:, None] * force,
        status=np.array(["ok"] * len(t)),
    )
    points = tendon_backbone(robot, tensions)
    np.testing.assert_allclose(points(table, len(t) - 1)[-1], followed, atol=1e-3)


def test_a_small_tip_force_gives_the_cantilever_deflection() -> None:
    """``F L^3 / (3 EI)`` for a force across the straight rod, to first order."""
    robot = one_section_robot()
    force = 1e-4
    _, poses = TendonStatics(robot).solve(np.array([0.0, force, 0.0]), np.zeros(0))
    _, p = poses[Station(0, 1.0)]
    assert p[1] == pytest.approx(force * 0.2**3 / (3 * EI), rel=1e-4)


def test_the_base_moment_balances_the_tip_force_and_twists_a_bent_rod() -> None:
    """With no weight the base carries ``p_tip x F`` (exact), its twist part is resisted
    by ``GJ + tau r^2``; a force across a rod bent towards +x twists it positively about
    its tangent."""
    tau = 8.0  # bends the 0.2 m rod by about 90 degrees towards +x
    robot = one_section_robot(Tendon(0, 0.0, 0.01))
    force = np.array([0.0, 0.01, 0.0])
    statics = TendonStatics(robot)
    k0, poses = statics.solve(force, np.array([tau]))
    R_tip, p_tip = poses[Station(0, 1.0)]
    np.testing.assert_allclose(k0 * EI, np.cross(p_tip, force), rtol=1e-9, atol=1e-14)
    u = np.asarray(statics.curvature_sym(ca.DM(k0 * EI), [(tau, 0.01, 0.0)]), float).ravel()
    assert u[2] == pytest.approx(p_tip[0] * force[1] / (GJ + tau * 1e-4), rel=1e-12)
    f = TendonFormulation(robot=robot)
    x = np.zeros(f.nx)
    x[:3], x[3:6], x[6] = k0, force, tau
    names = [o.name for o in f.outputs]
    psi = f.output(x)[names.index("psi_1")]
    assert psi > 0.005
    # the mirror image (force along -y) twists the other way by as much
    k0m, _ = statics.solve(-force, np.array([tau]))
    x[:3], x[3:6] = k0m, -force
    assert f.output(x)[names.index("psi_1")] == pytest.approx(-psi, rel=1e-9)


def test_the_shooting_converges_with_its_steps() -> None:
    """The default steps agree with four times as many to 0.05 mm on a large bend with a
    tip force (the integrator is of fourth order: four times the steps leave a 256th of
    the error)."""
    robot = Robot(
        (Section(0.2, 3.0, 10), Section(0.2, 3.0, 10)),
        (ImuPlacement(0), ImuPlacement(1)),
        "z-up",
        Backbone(54e9, 20.77e9, 0.0007, density=6450),
        (Tendon(0, 0.0, 0.01), Tendon(1, 2.0, 0.01)),
    )
    args = (np.array([0.05, -0.03, 0.02]), np.array([4.0, 6.0]))
    _, coarse = TendonStatics(robot).solve(*args)
    _, fine = TendonStatics(robot, steps_per_section=4 * STEPS_PER_SECTION).solve(*args)
    tip = Station(1, 1.0)
    assert np.linalg.norm(coarse[tip][1] - fine[tip][1]) < 5e-5


def _rod_section_ends(robot: Robot, tau: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Both section ends (3, 2) of :func:`~continuum_mhe.simulation.cosserat_tendon.
    energy_equilibrium` extrapolated to zero segment length: it converges as ``ds^2``, so
    Richardson on 1 and 2 segments per disk; the rod's two distances between them show
    that the bend is large enough for the extrapolation to matter."""
    from continuum_mhe.simulation.cosserat_tendon import energy_equilibrium

    ends = {}
    for per in (1, 2):
        _, frames = energy_equilibrium(robot, tau, force, segments_per_disk=per)
        ends[per] = frames[9:, [10 * per - 1, 20 * per - 1]]
    for k in range(2):
        assert np.linalg.norm(ends[2][:, k] - ends[1][:, k]) > 5e-5
    return ends[2] + (ends[2] - ends[1]) / 3


def test_the_shooting_agrees_with_an_independent_energy_minimisation() -> None:
    """The discrete rod of :func:`~continuum_mhe.simulation.cosserat_tendon.energy_equilibrium`
    (energy minimised, tendons as polylines through every segment's end), extrapolated
    to zero segment length: the section ends agree to 0.05 mm on a loaded spatial
    bend."""
    robot = read_robot("tendon-two-section")
    tau = np.array([2.0, 0.5, 0.5, 3.0, 0.7, 0.8])
    force = np.array([0.05, 0.0, 0.0])
    _, poses = TendonStatics(robot).solve(force, tau)
    limit = _rod_section_ends(robot, tau, force)
    for k in range(2):
        assert np.linalg.norm(poses[Station(k, 1.0)][1] - limit[:, k]) < 5e-5


def test_tendons_drawn_from_disk_to_disk_bend_a_section_further(tmp_path: Path) -> None:
    """One tendon on a section of four disks (5 cm apart), 1.5 N: routed continuously,
    the generator's rod bends by ``tension * radius * length / EI`` (to 0.1 %); drawn
    straight from disk to disk, the chords run nearer the bend's centre, a longer lever,
    and it bends further (by more than 1 %). The generator draws a robot file's
    ``tendon_route`` by default, ``--route`` another, and its info says which."""
    import json

    from continuum_mhe.cli import main
    from continuum_mhe.simulation.cosserat_tendon import energy_equilibrium

    length = 0.2
    robot = Robot((Section(length, 3.0, 4),), (ImuPlacement(0, 1.0),), "z-up", BACKBONE,
                  (Tendon(0, 0.0, 0.01),))  # fmt: skip
    ei = BACKBONE.youngs_modulus * math.pi * BACKBONE.radius**4 / 4
    bends = {}
    for route in ("continuous", "disks"):
        _, frames = energy_equilibrium(robot, np.array([1.5]), np.zeros(3), route=route)
        tangent = frames[:9, -1].reshape(3, 3, order="F")[:, 2]
        bends[route] = math.acos(min(1.0, abs(float(tangent[2]))))
    assert bends["continuous"] == pytest.approx(1.5 * 0.01 * length / ei, rel=1e-3)
    assert bends["disks"] > 1.01 * bends["continuous"]
    text = (DATA.parent / "robots" / "tendon_two_section.toml").read_text()
    robot_file = tmp_path / "r.toml"  # two disks a section: a quick rod
    robot_file.write_text('tendon_route = "disks"\n' + text.replace("disks = 10", "disks = 2"))
    assert main(["rod", "tendon", "--robot", str(robot_file), "--segments-per-disk", "0", "-o",
                     str(tmp_path / "none")]) == 2  # fmt: skip
    assert not (tmp_path / "none").exists()
    for extra, route in (([], "disks"), (["--route", "continuous"], "continuous")):
        out = tmp_path / f"rec-{route}"
        argv = ["--robot", str(robot_file), "--duration", "0.1", "-o", str(out), *extra]
        assert main(["rod", "tendon", *argv]) == 0
        assert json.loads((out / "unloaded_info.json").read_text())["route"] == route


@pytest.mark.parametrize(
    ("disks", "tendons", "per_disk", "within_mm", "continuous_off_mm"),
    [(4, ((0.0, 8.0), (120.0, 6.0), (240.0, 6.0)), 8, 0.2, 30.0),
     (5, ((0.0, 12.0), (115.0, 3.6)), 4, 2.5, 40.0)],
)  # fmt: skip
def test_the_disk_routed_model_agrees_with_the_discrete_rod_drawn_so(
    disks: int, tendons: tuple[tuple[float, float], ...], per_disk: int, within_mm: float,
    continuous_off_mm: float,
) -> None:  # fmt: skip
    """A 0.2 m section with tendons drawn straight from disk to disk, against the
    generator's discrete rod drawn so (extrapolated to zero segment length from
    ``per_disk`` and twice as many segments per disk: 8 and 16 on 4 disks, 4 and 8 on 5,
    each within 0.03 mm of the extrapolation from 16 and 32): 4 disks (5 cm apart) and
    three pretensioned tendons, 20 N in all (0.41 of the section's bending stiffness in
    the chords' term), bent by 41 degrees, within 0.2 mm where the continuous tendons'
    model is over 30 mm off; 5 disks and two tendons bent by 154 degrees, within 2.5 mm
    where it is over 40 mm off."""
    from continuum_mhe.simulation.cosserat_tendon import energy_equilibrium

    robot = Robot((Section(0.2, 3.0, disks),), (ImuPlacement(0, 1.0),), "z-up", BACKBONE,
                  tuple(Tendon(0, math.radians(a), 0.01) for a, _ in tendons))  # fmt: skip
    tau = np.array([t for _, t in tendons])
    ends = {}
    for per in (per_disk, 2 * per_disk):
        _, frames = energy_equilibrium(
            robot, tau, np.zeros(3), route="disks", segments_per_disk=per
        )
        ends[per] = frames[9:, -1]
    rod = ends[2 * per_disk] + (ends[2 * per_disk] - ends[per_disk]) / 3
    tips = {}
    for route in ("continuous", "disks"):
        _, poses = TendonStatics(replace(robot, tendon_route=route)).solve(np.zeros(3), tau)
        tips[route] = poses[Station(0, 1.0)][1]
    assert np.linalg.norm(tips["disks"] - rod) < within_mm * 1e-3
    assert np.linalg.norm(tips["continuous"] - rod) > continuous_off_mm * 1e-3


def test_a_disk_routed_robot_file_round_trips_and_its_mistakes_are_one_line(tmp_path: Path) -> None:
    """``tendon_route = "disks"`` is read and written back; another word, the key on a
    robot without tendons, or a section its tendons pass without disks: refused naming
    the file and the key."""
    from continuum_mhe.io.robot_file import robot_toml

    text = (DATA.parent / "robots" / "tendon_two_section.toml").read_text()
    path = tmp_path / "r.toml"
    path.write_text('tendon_route = "disks"\n' + text)
    robot = read_robot(path)
    assert robot.tendon_route == "disks"
    assert robot.describe().endswith(", 6 tendons from disk to disk")  # in every summary
    again = tmp_path / "again.toml"
    again.write_text(robot_toml(robot))
    assert read_robot(again) == robot
    # the first [[section]]'s line in the file with tendon_route put first
    first = 2 + [ln.strip() for ln in text.splitlines()].index("[[section]]")
    bad = [
        ('tendon_route = "chords"\n' + text, 'tendon_route: must be one of continuous, disks'),
        ('tendon_route = "disks"\n' + text.replace("disks = 10", "disks = 0", 1),
         f'line {first}: section 1: no disks, which tendons pass with tendon_route = "disks"'),
        ('tendon_route = "disks"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n',
         'line 1: tendon_route = "disks" is for a robot with [[tendon]]s'),
    ]  # fmt: skip
    for body, message in bad:
        path.write_text(body)
        with pytest.raises(InputError, match=re.escape(message)) as info:
            read_robot(path)
        assert str(info.value).startswith(str(path)), info.value
    # written after a table's header, TOML puts it in that table: said as a top-level key
    path.write_text(text + '\ntendon_route = "disks"\n')
    with pytest.raises(InputError, match=re.escape(
            "unknown key 'tendon_route' (a top-level key: write it before the file's "
            "first [table])")):  # fmt: skip
        read_robot(path)


def test_the_model_floor_on_a_bend_past_120_degrees() -> None:
    """The largest bend of the ``unloaded`` recording (121 and 102 degrees, tendons of
    up to 12 N, the backbone's weight): the shooting agrees with the discrete rod
    extrapolated to zero segment length within 0.05 mm at both section ends, a tenth of
    the 0.5 mm a reduced model may be off by."""
    robot = read_robot("tendon-two-section")
    tau = np.array([0.078876, 1.79768, 1.123444, 3.904776, 11.91665, 2.178574])
    _, poses = TendonStatics(robot).solve(np.zeros(3), tau)
    limit = _rod_section_ends(robot, tau, np.zeros(3))
    for k in range(2):
        assert np.linalg.norm(poses[Station(k, 1.0)][1] - limit[:, k]) < 5e-5


def test_a_slack_tendon_pulls_nothing() -> None:
    """A negative tension (a state can stray there) acts as zero, with the exact clip
    (``slack_smoothing=0``; this one-IMU robot's default clip is the smooth one, whose
    slack tendon pulls half its width: ``test_load_hypotheses_mhe.py``)."""
    robot = one_section_robot(Tendon(0, 0.0, 0.01), Tendon(0, math.pi, 0.01))
    f = TendonFormulation(robot=robot, slack_smoothing=0.0)
    x = np.zeros(f.nx)
    x[3:6] = [0.02, 0.0, 0.0]
    x[6:8] = [1.0, -3.0]
    slack = x.copy()
    slack[7] = 0.0
    np.testing.assert_array_equal(f.output(x)[:9], f.output(slack)[:9])


def test_the_imus_own_acceleration_is_the_second_derivative_along_the_equilibria() -> None:
    """Tensions and a tip force that change in time with known derivatives, the force
    accelerating: the model's IMU acceleration matches the second central difference of
    the positions of the solved equilibria (a known answer the formulation does not
    compute itself). The force's acceleration alone moves the IMUs by over 0.1 m/s^2
    here; a model that takes the force at constant velocity misses it."""
    robot = read_robot("tendon-two-section")
    f = TendonFormulation(robot=robot, acceleration_from_force_rate=True)
    statics = f.statics

    def tau(t: float) -> np.ndarray:
        return np.array([3.0 + 2.0 * math.sin(1.3 * t + i) ** 2 for i in range(6)])

    force_ddot = np.array([-0.3, 0.2, 0.05])  # N/s^2

    def force(t: float) -> np.ndarray:
        return np.array([0.02 * t, -0.01 * t, 0.005 * t]) + force_ddot * t**2 / 2

    t0, h = 0.7, 1e-3
    positions = []
    for t in (t0 - h, t0, t0 + h):
        _, poses = statics.solve(force(t), tau(t))
        positions.append(np.array([poses[Station(i.section, i.at)][1] for i in robot.imus]))
    expected = (positions[0] - 2 * positions[1] + positions[2]) / h**2
    tau_dot = (tau(t0 + h) - tau(t0 - h)) / (2 * h)
    tau_ddot = (tau(t0 + h) - 2 * tau(t0) + tau(t0 - h)) / h**2
    k0, poses = statics.solve(force(t0), tau(t0))
    v, v_dot = ca.SX.sym("v", 12), ca.SX.sym("v_dot", 12)
    force_dot = (force(t0 + h) - force(t0 - h)) / (2 * h)
    v_dd = ca.SX.sym("v_ddot", 9)  # the force's and the tensions' second derivatives
    poses_sym, res = statics.shoot(v[:3], v[3:6], v[6:])
    accel = ca.Function(
        "a",
        [v, v_dot, v_dd],
        [ca.horzcat(*f._imu_accelerations(v, v_dot, v_dd, res, poses_sym))],
    )
    # the base curvature's rate in the state is ignored: the equilibrium sets it
    state, rates = np.r_[k0, force(t0), tau(t0)], np.r_[[9.0] * 3, force_dot, tau_dot]
    got = np.asarray(accel(state, rates, np.r_[force_ddot, tau_ddot]), float).T
    at_constant_velocity = np.asarray(accel(state, rates, np.r_[[0.0] * 3, tau_ddot]), float).T
    assert np.abs(expected).max() > 0.5  # metres per second squared: it matters
    assert np.abs(at_constant_velocity - expected).max() > 0.1
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-3 * np.abs(expected).max())


# --- the formulation -------------------------------------------------------------------
def test_with_raw_imus_the_tip_force_moves_at_constant_acceleration() -> None:
    """With ``estimate_force_acceleration`` the tip force's acceleration is a state,
    and the force's transition and process noise are those of a triple integrator driven
    by white jerk and a white acceleration beside it (by default none with two IMUs;
    with one, the one-IMU defaults, as given), computed independently here by Van Loan's
    matrix exponential; by default that state is there with raw IMUs only."""
    from scipy.linalg import expm

    from continuum_mhe.errors import UserError
    from continuum_mhe.model.tendon import (
        FORCE_JERK_PSD,
        SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD,
        SINGLE_IMU_FORCE_JERK_PSD,
    )

    two = read_robot("tendon-two-section")
    one = replace(two, imus=two.imus[-1:])
    cases = ((two, {}, FORCE_JERK_PSD, 0.0),
             (one, {}, SINGLE_IMU_FORCE_JERK_PSD, SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD),
             (one, {"force_jerk_psd": 0.5, "force_accel_psd": 0.02}, 0.5, 0.02))  # fmt: skip
    for robot, given, jerk, accel_psd in cases:
        f = TendonFormulation(
            robot=robot, imu_model="direct", estimate_gyro_bias=True,
            estimate_force_acceleration=True, **given,  # type: ignore[arg-type]
        )  # fmt: skip
        assert (f.jerk_psd, f.force_psd) == (jerk, accel_psd)
        names = f.state_names
        force = [names.index(f"f{c}") for c in "xyz"]
        rate = [names.index(f"f{c}_dot") for c in "xyz"]
        accel = [names.index(f"f{c}_ddot") for c in "xyz"]
        dt = 0.02
        a = np.diag([1.0, 1.0], 1)  # (F, its rate, its acceleration) of one component
        qc = np.diag([0.0, accel_psd, jerk])  # white acceleration and white jerk
        van_loan = expm(np.block([[-a, qc], [np.zeros((3, 3)), a.T]]) * dt)
        phi = van_loan[3:, 3:].T
        q_expected = phi @ van_loan[:3, 3:]
        x = np.random.default_rng(0).normal(size=f.nx)
        x_sym, dt_sym = ca.SX.sym("x", f.nx), ca.SX.sym("dt")
        transition = f.transition_sym(x_sym, ca.SX.zeros(f.nu), dt_sym)
        step = ca.Function("f", [x_sym, dt_sym], [transition])
        q = np.asarray(ca.Function("q", [dt_sym], [f.process_cov_sym(dt_sym)])(dt), float)
        moved = np.asarray(step(x, dt), float).ravel()
        for c in range(3):
            chain = [force[c], rate[c], accel[c]]
            np.testing.assert_allclose(moved[chain], phi @ x[chain], rtol=1e-12)
            np.testing.assert_allclose(q[np.ix_(chain, chain)], q_expected, rtol=1e-9)

    def has_force_acceleration(robot: Robot, imu_model: str) -> bool:
        names = TendonFormulation(robot=robot, imu_model=imu_model).state_names  # type: ignore[arg-type]
        return any(n.endswith("_ddot") for n in names)

    # by default: raw IMUs (one or more); not tilt
    assert has_force_acceleration(two, "direct")
    assert has_force_acceleration(one, "direct")
    assert not has_force_acceleration(two, "tilt")
    assert not has_force_acceleration(one, "tilt")
    with pytest.raises(UserError, match="estimate_force_acceleration"):
        TendonFormulation(robot=two, estimate_force_acceleration=True)  # tilt IMUs


def test_a_zero_force_accel_psd_is_the_default_where_the_force_acceleration_is_a_state() -> None:
    """Where the tip force's acceleration is a state its jerk alone drives the force by
    default (``force_psd`` 0): ``force_accel_psd=0`` says the same, the same process
    noise; at constant velocity, where the force's white acceleration is all its noise,
    0 is refused in one line, as a negative value is in both."""
    two = read_robot("tendon-two-section")
    raw = {"imu_model": "direct", "estimate_gyro_bias": True}

    def q(f: TendonFormulation) -> np.ndarray:
        dt = ca.SX.sym("dt")
        return np.asarray(ca.Function("q", [dt], [f.process_cov_sym(dt)])(0.02), float)

    default = TendonFormulation(robot=two, **raw)  # type: ignore[arg-type]
    zero = TendonFormulation(robot=two, force_accel_psd=0.0, **raw)  # type: ignore[arg-type]
    assert default.n_force_acceleration == zero.n_force_acceleration == 3
    assert default.force_psd == zero.force_psd == 0.0
    np.testing.assert_array_equal(q(zero), q(default))
    with pytest.raises(UserError, match=r"^force_accel_psd must be a 0 or more finite number"):
        TendonFormulation(robot=two, force_accel_psd=-1.0, **raw)  # type: ignore[arg-type]
    # at constant velocity (tilt IMUs, or the acceleration left out)
    for kwargs in ({"robot": two}, {"estimate_force_acceleration": False, "robot": two, **raw}):
        with pytest.raises(UserError, match=r"^force_accel_psd must be a positive finite number"):
            TendonFormulation(force_accel_psd=0.0, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("imu_errors", [False, True])
@pytest.mark.parametrize("imu_model", ["tilt", "direct"])
def test_the_residual_jacobian_matches_finite_differences(imu_model: str, imu_errors: bool) -> None:
    """Also with the IMUs' own errors as states (misalignment, accelerometer bias, and
    the gyro bias with raw IMUs) and the tension gain."""
    robot = Robot(
        (Section(0.15, 3.0, 5),),
        (ImuPlacement(0, 0.6), ImuPlacement(0, 1.0)),
        "z-up",
        BACKBONE,
        (Tendon(0, 0.3, 0.01), Tendon(0, 2.5, 0.008)),
    )
    f = TendonFormulation(
        robot=robot,
        imu_model=imu_model,  # type: ignore[arg-type]
        estimate_misalignment=imu_errors,
        estimate_accel_bias=imu_errors,
        estimate_gyro_bias=imu_errors and imu_model == "direct",
        estimate_tension_gain=imu_errors,
    )
    rng = np.random.default_rng(3)
    x = np.zeros(f.nx)
    x[:3] = rng.normal(0, 1.0, 3)
    x[3:6] = rng.normal(0, 0.02, 3)
    x[6:8] = [2.0, 1.0]
    x[8:] = rng.normal(0, 0.5, f.nx - 8)
    imu = rng.normal(0, 0.3, f.n_imu_measurements)
    z = f.measurement_row(imu, np.array([2.1, 0.9]), np.array([0.3, -0.2]), np.array([-1.5, 0.8]))
    r, J = (np.asarray(v, float) for v in f.functions.innovate(z, x))
    for i in range(f.nx):
        h = 1e-6 * max(1.0, abs(x[i]))
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        fd = (np.asarray(f.functions.innovate(z, up)[0], float)
              - np.asarray(f.functions.innovate(z, down)[0], float)) / (2 * h)  # fmt: skip
        np.testing.assert_allclose(
            J[:, i], fd.ravel(), rtol=1e-5, atol=1e-6 * max(1.0, np.abs(fd).max())
        )


def test_the_imu_error_states_turn_and_shift_the_specific_force_as_a_board_would() -> None:
    """Raw IMUs at rest (no own acceleration): with a misalignment ``m`` and an
    accelerometer bias ``c`` (m/s^2, board frame) as states, each IMU's predicted
    direction is ``(Rb^T g up + c) / |...|`` with the board's frame ``Rb = R (I +
    [m]x)``, ``R`` the disk frame from the statics; known values, computed here apart."""
    robot = read_robot("tendon-two-section")
    f = TendonFormulation(robot=robot, imu_model="direct", own_acceleration=False)
    tau = np.array([2.0, 0.5, 0.0, 0.0, 1.5, 0.3])
    force = np.array([0.02, -0.01, 0.01])
    k0, poses = f.statics.solve(force, tau)
    x = np.zeros(f.nx)
    x[:3], x[3:6], x[6:12] = k0, force, tau
    names = f.state_names
    mis = np.array([[0.02, -0.01, 0.03], [-0.015, 0.01, -0.02]])
    bias = np.array([[0.1, -0.2, 0.15], [-0.1, 0.05, 0.2]])
    for i in range(2):
        x[names.index(f"misx_{i + 1}") : names.index(f"misz_{i + 1}") + 1] = mis[i]
        x[names.index(f"bax_{i + 1}") : names.index(f"baz_{i + 1}") + 1] = bias[i]
    h = np.asarray(f.functions.observe(x), float).ravel()
    for i, imu in enumerate(robot.imus):
        R = poses[Station(imu.section, imu.at)][0]
        m = mis[i]
        skew = np.array([[0, -m[2], m[1]], [m[2], 0, -m[0]], [-m[1], m[0], 0]])
        board = R @ (np.eye(3) + skew)
        specific = board.T @ np.array([0.0, 0.0, 9.80665]) + bias[i]
        np.testing.assert_allclose(
            h[6 * i : 6 * i + 3], specific / np.linalg.norm(specific), atol=1e-9
        )
