"""The Cosserat-rod generators (PyElastica): the two-section rod's tendon drive and its
twist about the tangent (known answers; one short simulation of each drive), the
shipped recordings' info against their own files, short runs of both generators and the
one-section recording regenerated from its settings. Every test that runs PyElastica is
here, so that one test process compiles its kernels."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe.cli import main
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.pcc import section_frames_from_bends
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation import cosserat
from continuum_mhe.simulation.cosserat_sections import (
    SectionRodSettings,
    SectionTrajectory,
    couples,
    pcc_truth,
    simulate_sections,
    tangent_twist,
)

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"


def _rod_sections(argv: list[str]) -> int:
    """``continuum-mhe rod sections ARGV``'s exit status."""
    return main(["rod", "sections", *argv])


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = 1.0
    return out


def test_twist_about_the_tangent_is_recovered() -> None:
    """Rod frames made of PCC frames turned about the tangent by known angles: the
    bends come back from the tangents, and the twist is each known angle."""
    rng = np.random.default_rng(4)
    n = 50
    bends = rng.uniform(-1.2, 1.2, size=(n, 2, 2))
    twist = rng.uniform(-2.5, 2.5, size=(n, 2))
    R_true = section_frames_from_bends(bends, (0.16, 0.14)) @ _rot_z(twist)
    directors = np.transpose(R_true, (0, 1, 3, 2))  # PyElastica: rows are d1, d2, d3
    z = np.zeros((n, 2, 3))
    traj = SectionTrajectory(
        np.arange(n) * 1e-3, np.zeros((n, 3, 31)), directors, z, z, np.zeros(n), (16, 30)
    )
    got, _ = pcc_truth(traj, (0.16, 0.14))
    assert_allclose(got, bends, atol=1e-9)
    assert_allclose(tangent_twist(traj, got), twist, atol=1e-9)


def test_tendon_couples_are_follower_couples_with_the_section_moments() -> None:
    """Tendon drive: both couples are perpendicular to the tangent in their own frame,
    section 2 carries ``M_2`` and section 1 ``M_1 = c_1 + c_2``; the planar S bends the
    sections in opposite senses; the base drive is unchanged."""
    s = SectionRodSettings(drive="tendon")
    t = 0.5 * s.period  # the hold: full pull
    for scenario in ("planar-s", "spatial"):
        c1, c2 = couples(scenario, t, s)
        assert c1[2] == 0.0 and c2[2] == 0.0
        assert np.linalg.norm(c2) == pytest.approx(s.tendon_gain[1] * s.max_moment)
        assert np.linalg.norm(c1 + c2) == pytest.approx(s.tendon_gain[0] * s.max_moment)
    c1, c2 = couples("planar-s", t, s)
    assert (c1 + c2)[0] > 0 > c2[0]
    base1, base2 = couples("spatial", t, SectionRodSettings())
    m = 1.3 * SectionRodSettings().max_moment
    assert np.linalg.norm(base2) == pytest.approx(m) and math.isclose(base1[2], 0.0)
    with pytest.raises(ValueError, match="drive"):
        SectionRodSettings(drive="cable")


@pytest.mark.parametrize("lengths", [(0.25,), (0.16, 0.14), (0.12, 0.1, 0.055), (0.1,) * 4])
def test_each_section_carries_its_moment_and_bends_no_further_than_on_the_shipped_rod(
    lengths: tuple[float, ...],
) -> None:
    """On one to four sections, both drives and both motions: section ``k`` carries the
    couples of every end beyond its base, and they add up to its moment ``M_k``; a
    section's moment times its length (its bend) is its role's on the shipped rod (the
    tip section's as section 2's, every other's as section 1's) where it is longer, and
    as curved where it is shorter, times ``1 / (n - 1)`` past two sections;
    ``planar-s`` bends the sections the opposite ways in turn, about base x. The bend
    recording's couples (one per end) turn the tip as far as on the shipped rod; a rod
    shorter than the shipped one is damped more."""
    from continuum_mhe.simulation.cosserat_sections import (
        BEND,
        ROLE_LENGTHS,
        robot_damping,
        section_moments,
    )

    n = len(lengths)
    t = 2.4  # the hold: full pull
    for drive in ("base", "tendon"):
        s = SectionRodSettings(lengths=lengths, drive=drive)
        shipped = SectionRodSettings(drive=drive)
        for scenario in ("planar-s", "spatial"):
            moments = section_moments(scenario, t, s.max_moment, s)
            ref = section_moments(scenario, t, s.max_moment, shipped)
            cs = couples(scenario, t, s)
            assert len(cs) == len(moments) == n
            for k in range(n):
                assert_allclose(np.sum(cs[k:], axis=0), moments[k], atol=1e-15)
                role = 1 if k == n - 1 else 0
                bend = np.linalg.norm(moments[k]) * lengths[k]
                shorter = min(ROLE_LENGTHS[role], lengths[k])  # bends less, as curved
                want = np.linalg.norm(ref[role]) * shorter / max(1, n - 1)
                assert bend == pytest.approx(want, rel=1e-12)
                if scenario == "planar-s":
                    assert moments[k][0] * (-1) ** k > 0 and abs(moments[k][2]) == 0.0
    turn = [sum(c[1] * sum(s.lengths[: k + 1]) for k, c in enumerate(couples(BEND, 3.0, s)))
            for s in (SectionRodSettings(lengths=lengths), SectionRodSettings())]  # fmt: skip
    assert turn[0] == pytest.approx(turn[1], rel=1e-12) and turn[0] < 0
    # a rod shorter than the shipped one is damped more, as its modes are faster
    damping = robot_damping(4.0, lengths)
    assert damping == pytest.approx(4.0 * max(1.0, (0.3 / sum(lengths)) ** 2), rel=1e-12)


def test_shipped_info_agrees_with_its_recordings() -> None:
    """Every shipped recording's info states what its files hold: as many samples as
    each file has rows, each section's largest bend of the truth file, and the PCC floor:
    the distance from the rod's tip (the truth's x, y, z) to the tip the estimators' own
    model (the two-section bend formulation, CasADi) gives for the truth's bends."""
    f = make_formulation("bend", read_robot("two-section"))
    infos = {
        p.name[: -len("_info.json")]: json.loads(p.read_text()) for p in DATA.glob("*_info.json")
    }
    assert {"planar-s", "spatial", "spatial-stiff-torsion", "spatial-tendon"} <= set(infos)
    for name, info in infos.items():
        truth = read_state_table(DATA / f"{name}_truth.csv")
        assert truth.names == tuple(o.name for o in f.outputs), name
        for kind in ("tilt", "raw"):
            rows = np.loadtxt(DATA / f"{name}_{kind}.csv", delimiter=",", skiprows=1)
            assert len(rows) == len(truth.t) == info["samples"], (name, kind)
        theta = np.column_stack([truth.column(f"theta_{k}") for k in (1, 2)])
        phi = np.column_stack([truth.column(f"phi_{k}") for k in (1, 2)])
        assert_allclose(np.degrees(theta.max(axis=0)), info["theta_max_deg"], atol=1e-6)
        states = np.zeros((len(truth.t), f.nx))
        states[:, 0:4:2], states[:, 1:4:2] = theta * np.cos(phi), theta * np.sin(phi)
        floor = np.linalg.norm(f.output(states)[:, :3] - truth.values[:, :3], axis=1) * 1e3
        assert floor.mean() == pytest.approx(info["pcc_floor_mean_mm"], abs=1e-6), name
        assert floor.max() == pytest.approx(info["pcc_floor_max_mm"], abs=1e-6), name
    for p in DATA.iterdir():
        assert p.stat().st_size < 200_000, p.name  # shipped data stays small


def test_tendon_drive_bends_with_little_twist_where_base_couples_twist() -> None:
    """docs/model.md: base-frame couples twist the bent rod about its tangent, tendon
    (follower) couples do not. The same spatial pull, one quick 1.5 s cycle (0.75 s:
    pull and hold): both bend each section past 90 deg; the base drive twists the tip by
    over 45 deg, the tendon drive by under 15 deg at both section ends. On a coarser rod
    than the generator's (15 elements, a 40 us step, whose bends and twists are a 25 us
    step's within 1e-3 deg; the default rod's within 8 % in bend and 4 deg in twist):
    what is compared is the drive, not the discretisation."""
    twist = {}
    for drive in ("base", "tendon"):
        s = SectionRodSettings(period=1.5, drive=drive, n_elements=15, sim_dt=4e-5)
        traj = simulate_sections(s, "spatial", 0.75)
        bends, _ = pcc_truth(traj, s.lengths)
        assert np.all(np.degrees(np.hypot(bends[..., 0], bends[..., 1])).max(axis=0) > 90)
        twist[drive] = np.degrees(np.abs(tangent_twist(traj, bends))).max(axis=0)
    assert twist["base"][1] > 45 and np.all(twist["tendon"] < 15), twist


# --- the two-section Cosserat rod ---------------------------------------------------------
def test_two_section_rod_generator_short_run(tmp_path: Path) -> None:
    """A short two-section rod run: truth section ends on the centreline, the PCC floor
    far below a one-section model's error, and files every reader accepts."""
    from continuum_mhe.simulation.cosserat_sections import (
        SectionRodSettings,
        write_section_recording,
    )

    info = write_section_recording(
        tmp_path, "r", SectionRodSettings(), "planar-s", 0.6, bend_duration=0.2
    )
    assert (tmp_path / "r_bend.csv").read_text().startswith("t,ax_1,ay_1,az_1,gx_1,")
    assert float(info["pcc_floor_mean_mm"]) < 0.2 * float(info["one_section_mean_mm"])  # type: ignore[arg-type]
    assert json.loads((tmp_path / "r_info.json").read_text())["samples"] == info["samples"]
    truth = read_state_table(tmp_path / "r_truth.csv")
    assert truth.names[:3] == ("x", "y", "z")
    assert_allclose(
        truth.column("x"), truth.column("x_2"), atol=1e-12
    )  # the tip is section 2's end
    lengths = np.hypot(truth.column("y_1"), truth.column("z_1"))
    assert np.all(lengths <= 0.16 + 1e-3)  # section 1's end within its arc length
    for name in ("r_raw.csv", "r_tilt.csv"):  # raw: the direct model, the default
        out = tmp_path / f"e_{name}"
        args = ["estimate", str(tmp_path / name), "-o", str(out), "--robot", "two-section"]
        assert main(args) == 0
        assert (
            main(["evaluate", str(out), str(tmp_path / "r_truth.csv"), "--robot", "two-section"])
            == 0
        )


# --- a robot file's sections ---------------------------------------------------------------
#: one section of 0.25 m, its IMU at the end
ONE_SECTION = """
mounting = "z-up"
[[section]]
length = 0.25
[[imu]]
section = 1
"""

#: three sections (0.12 m with 4 disks, 0.1 m, 0.055 m: elements of 1 cm, 1 cm and
#: 1.1 cm, the rod's nodes not evenly spaced), an IMU on section 1's disk 2 and one at
#: each section's end
THREE_SECTIONS = """
mounting = "z-up"
[[section]]
length = 0.12
disks = 4
[[section]]
length = 0.1
[[section]]
length = 0.055
[[imu]]
section = 1
disk = 2
[[imu]]
section = 1
[[imu]]
section = 2
[[imu]]
section = 3
"""


def _short_bend(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bend recording's simulation a tenth of a second long (its 5 s are not what
    these tests check)."""
    from continuum_mhe.simulation import cosserat_sections

    bend = cosserat_sections.bend_trajectory

    def short(settings: SectionRodSettings, duration: float = 5.0) -> SectionTrajectory:
        return bend(settings, 0.1)

    monkeypatch.setattr(cosserat_sections, "bend_trajectory", short)


def test_a_straight_rod_of_three_sections_stands_and_its_imus_read_gravity(
    tmp_path: Path,
) -> None:
    """The three-section robot file's rod with no couple (the IMUs without noise, bias
    or misalignment), 0.2 s under gravity: it stands straight, its tip at (0, 0, L)
    and each section's end at its arc length up the z axis (within its weight's
    compression), its bends 0; every IMU (one on a disk) reads gravity in its own frame,
    (0, 0, g), and no rate, to the 16-bit quantisation; the files' columns follow the
    robot's three sections and four IMUs."""
    from continuum_mhe.model.descriptions import output_names, pcc_outputs
    from continuum_mhe.model.imu import STANDARD_GRAVITY
    from continuum_mhe.simulation.cosserat_sections import (
        DEFAULT_IMU,
        rod_layout,
        rod_settings,
        write_trajectory_recording,
    )

    path = tmp_path / "three.toml"
    path.write_text(THREE_SECTIONS)
    settings = dataclasses.replace(rod_settings(read_robot(str(path))), max_moment=0.0)
    layout = rod_layout(settings)
    assert layout.elements == (12, 10, 5) and not layout.uniform
    assert layout.imu_nodes == (6, 12, 22, 27) and layout.end_nodes == (12, 22, 27)
    quiet = dataclasses.replace(
        DEFAULT_IMU, accel_noise=0.0, accel_bias=0.0, gyro_noise=0.0, gyro_bias=0.0,
        misalignment_deg=0.0,
    )  # fmt: skip
    traj = simulate_sections(settings, "planar-s", 0.2)
    write_trajectory_recording(tmp_path, "s", traj, settings, "planar-s", quiet)
    truth = read_state_table(tmp_path / "s_truth.csv")
    assert truth.names == output_names(pcc_outputs(3)) and len(truth.t) == 11
    for end, z in (("", 0.275), ("_1", 0.12), ("_2", 0.22), ("_3", 0.275)):
        assert_allclose(truth.column(f"x{end}"), 0.0, atol=1e-9)
        assert_allclose(truth.column(f"y{end}"), 0.0, atol=1e-9)
        assert_allclose(truth.column(f"z{end}"), z, atol=1e-4)  # its weight: 1e-5 m
    for k in (1, 2, 3):
        assert np.all(truth.column(f"theta_{k}") < 1e-6)
    raw_text = (tmp_path / "s_raw.csv").read_text()
    assert raw_text.startswith("t," + ",".join(
        f"{q}{a}_{k}" for k in range(1, 5) for q in "ag" for a in "xyz"
    ) + "\n")  # fmt: skip
    step = 2 * quiet.accel_range / 2**quiet.bits  # the quantisation
    g = np.tile([0.0, 0.0, STANDARD_GRAVITY], (11, 1))
    for kind in ("rest", "raw"):
        raw = np.loadtxt(tmp_path / f"s_{kind}.csv", delimiter=",", skiprows=1)
        for k in range(4):
            accel, gyro = raw[:, 1 + 6 * k : 4 + 6 * k], raw[:, 4 + 6 * k : 7 + 6 * k]
            assert_allclose(gyro, 0.0, atol=2 * quiet.gyro_range / 2**quiet.bits)
            if kind == "rest":  # the straight rod held still
                assert_allclose(accel, g, atol=step)
            else:  # the rod settling under its weight rings along its axis, 0.4 m/s^2
                assert_allclose(accel[:, :2], 0.0, atol=step)
                assert_allclose(accel[:, 2].mean(), STANDARD_GRAVITY, atol=0.1)
    tilt = (tmp_path / "s_tilt.csv").read_text().splitlines()[0]
    assert tilt == "t," + ",".join(f"roll_{k},pitch_{k}" for k in range(1, 5))


@pytest.mark.parametrize(
    ("text", "scenario", "mean_mm"),
    [(ONE_SECTION, "spatial", 8.0), (THREE_SECTIONS, "planar-s", 4.0)],
    ids=["one-section", "three-sections"],
)
def test_a_robot_files_sections_are_recorded_and_estimate_follows_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    text: str, scenario: str, mean_mm: float,
) -> None:  # fmt: skip
    """``rod sections --robot`` of one section and of three (an IMU on a disk), 1.5 s:
    the files' columns are the robot's (one section's ``theta, phi``, one IMU's
    unnumbered columns), the first truth row the straight rod's tip (0, 0, L), the rest
    recording's IMUs (calibrated) read gravity; the rod's tip lies near the
    constant-curvature arcs of the truth's bends (the PCC floor: 6.2 and 0.3 mm at
    most); and ``estimate`` of the raw recording with the robot file, ``evaluate``d
    against the truth, follows the rod's tip (measured 3.8 and 1.0 mm mean, the
    sections bent to 75 degrees, and 10 to 25)."""
    from continuum_mhe.model.descriptions import output_names, pcc_outputs
    from continuum_mhe.model.imu import STANDARD_GRAVITY

    _short_bend(monkeypatch)
    robot_path = tmp_path / "robot.toml"
    robot_path.write_text(text)
    robot = read_robot(str(robot_path))
    out = tmp_path / "rec"
    argv = ["--robot", str(robot_path), "--scenario", scenario, "--duration", "1.5"]
    assert _rod_sections([*argv, "--calibrated", "-o", str(out)]) == 0
    info = json.loads((out / f"{scenario}_info.json").read_text())
    assert info["robot"] == str(robot_path) and info["samples"] == 76
    truth = read_state_table(out / f"{scenario}_truth.csv")
    assert truth.names == output_names(pcc_outputs(robot.n_sections))
    tip = truth.values[:, :3]
    assert_allclose(tip[0], [0.0, 0.0, robot.length], atol=1e-12)
    assert min(info["theta_max_deg"]) > 8  # the couples bent every section
    raw_head = (out / f"{scenario}_raw.csv").read_text().splitlines()[0]
    rest = np.loadtxt(out / f"{scenario}_rest.csv", delimiter=",", skiprows=1)
    assert (out / f"{scenario}_rest.csv").read_text().splitlines()[0] == raw_head
    assert raw_head.count("ax") == robot.n_imus and ("ax_1" in raw_head) == (robot.n_imus > 1)
    for k in range(robot.n_imus):
        accel = rest[:, 1 + 6 * k : 4 + 6 * k].mean(axis=0)
        assert_allclose(accel, [0.0, 0.0, STANDARD_GRAVITY], atol=0.02)
    # the rod against the PCC model of its own section-end tangents
    f = make_formulation("bend", robot)
    theta = np.column_stack([truth.column(c) for c in truth.names if c.startswith("theta")])
    phi = np.column_stack([truth.column(c) for c in truth.names if c.startswith("phi")])
    states = np.zeros((len(truth.t), f.nx))
    states[:, 0 : 2 * robot.n_sections : 2] = theta * np.cos(phi)
    states[:, 1 : 2 * robot.n_sections : 2] = theta * np.sin(phi)
    floor = np.linalg.norm(f.output(states)[:, :3] - tip, axis=1) * 1e3
    assert floor.mean() == pytest.approx(info["pcc_floor_mean_mm"], abs=1e-6)
    assert floor.max() < 10.0
    est = tmp_path / "est.csv"
    raw = out / f"{scenario}_raw.csv"
    assert main(["estimate", str(raw), "--robot", str(robot_path), "-o", str(est)]) == 0
    capsys.readouterr()
    truth_path = str(out / f"{scenario}_truth.csv")
    assert main(["evaluate", str(est), truth_path, "--robot", str(robot_path), "--json"]) == 0
    tip_mm = json.loads(capsys.readouterr().out)["tip_mean_mm"]
    assert tip_mm < mean_mm, tip_mm


def test_the_two_section_robot_file_writes_the_default_rods_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--robot two-section`` (the shipped rod's sections and IMUs) writes the files
    written without ``--robot``, byte for byte, its info naming the robot besides."""
    _short_bend(monkeypatch)
    argv = ["--scenario", "spatial", "--duration", "0.1", "--seed", "4"]
    assert _rod_sections([*argv, "-o", str(tmp_path / "default")]) == 0
    assert _rod_sections([*argv, "--robot", "two-section", "-o", str(tmp_path / "robot")]) == 0
    for kind in ("raw.csv", "tilt.csv", "truth.csv", "rest.csv", "bend.csv"):
        name = f"spatial_{kind}"
        assert (tmp_path / "robot" / name).read_bytes() == (
            tmp_path / "default" / name
        ).read_bytes()
    info = json.loads((tmp_path / "robot" / "spatial_info.json").read_text())
    assert info.pop("robot") == "two-section"
    assert info == json.loads((tmp_path / "default" / "spatial_info.json").read_text())


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (("", "[backbone]\nyoungs_modulus = 54e9\nshear_modulus = 20.77e9\nradius = 0.0007\n"
              "density = 6450\n"),
         "the section-rod generator drives its own rod (radius 5 mm, E = 30 MPa)"),
        (('mounting = "z-up"', 'mounting = "z-down"'), "mounting = 'z-down': the section-rod"),
        (("disk = 2", "disk = 2\nmount_rpy = [0, 0, 90]"), "IMU 1 has a mount_rpy"),
        (("disk = 2", "at = 0.513"), "IMU 1 at 0.513 of section 1 lies between the generator's "
         "rod nodes (section 1 of 12 to 36 elements): place each at the section's end or on a "
         "disk"),
    ],
    ids=["backbone", "z-down", "mount-rpy", "between-nodes"],
)  # fmt: skip
def test_the_section_rod_generator_refuses_a_robot_it_does_not_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
    edit: tuple[str, str], said: str,
) -> None:  # fmt: skip
    """A robot file with a backbone (its rod is the generator's own), hanging, with an
    IMU turned on its section or between the rod's nodes: one line naming the file,
    exit 2, before any simulation, nothing written."""
    from continuum_mhe.simulation import cosserat_sections

    def no_simulation(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated")

    monkeypatch.setattr(cosserat_sections, "simulate_sections", no_simulation)
    text = THREE_SECTIONS.replace(*edit) if edit[0] else THREE_SECTIONS + edit[1]
    (tmp_path / "robot.toml").write_text(text)
    out = tmp_path / "out"
    assert _rod_sections(["--robot", str(tmp_path / "robot.toml"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{ERROR} {tmp_path / 'robot.toml'}: "), err
    assert said in err[0], err
    assert not out.exists()


# --- the one-section Cosserat rod ---------------------------------------------------------
@pytest.mark.slow
def test_rod_generator_short_run(tmp_path: Path) -> None:
    import elastica  # noqa: F401  (a test dependency: fail loudly if missing)

    rod = cosserat.RodSettings(n_elements=8, period=0.4, sim_dt=4e-5)
    rec = cosserat.make_recording(rod, cosserat.ImuSettings(), duration=0.3, seed=1)
    cols = rec.columns
    assert set(cols) == set(cosserat.COLUMNS) and len(cols["t"]) == 7
    assert cols["theta_tangent"][0] == 0.0 and cols["z_true"][0] == pytest.approx(0.2)
    assert np.max(cols["theta_fit"]) > 0.05  # the cable bent it
    path = tmp_path / "rod.csv"
    cosserat.write_recording(path, rec)
    back = cosserat.read_recording(path).columns
    np.testing.assert_allclose(back["roll"], cols["roll"], rtol=1e-6, atol=1e-9)
    assert main(["rod", "single", "-o", str(tmp_path / "x.csv"), "--duration", "-1"]) == 2


@pytest.mark.slow
def test_shipped_rod_recording_comes_from_its_generator_settings() -> None:
    """The settings shipped beside rod_planar.csv (which the report prints) regenerate
    its first samples to the CSV's 7 digits."""
    import elastica  # noqa: F401  (a test dependency: fail loudly if missing)

    info = cosserat.read_generator_info(cosserat.default_data_path())
    assert info is not None and info["duration"] == 20.0
    rod, imu = cosserat.RodSettings(**info["rod"]), cosserat.ImuSettings(**info["imu"])
    again = cosserat.make_recording(rod, imu, duration=0.3, seed=info["seed"]).columns
    shipped = cosserat.read_recording(cosserat.default_data_path()).columns
    for name in ("roll", "pitch", "y_true", "z_true", "theta_fit"):
        k = len(again[name])
        np.testing.assert_allclose(again[name], shipped[name][:k], rtol=1e-6, atol=1e-7)


@pytest.mark.slow
def test_rod_generator_writes_its_settings_beside_the_recording(tmp_path: Path) -> None:
    out = tmp_path / "rod.csv"
    assert main(["rod", "single", "-o", str(out), "--duration", "0.1", "--seed", "3"]) == 0
    info = cosserat.read_generator_info(out)
    assert info is not None and (info["seed"], info["duration"]) == (3, 0.1)
    assert info["generator"] == "continuum-mhe rod single"
    assert info["rod"] == dataclasses.asdict(cosserat.RodSettings())
    (tmp_path / "rod_info.json").write_text("{")
    with pytest.raises(ValueError, match="rod_info.json"):
        cosserat.read_generator_info(out)


def test_the_rod_generator_refuses_a_missing_folder_before_it_simulates(tmp_path, capsys) -> None:
    """``continuum-mhe rod single -o DIR/x.csv`` with no DIR: one line,
    exit 2, before the minute of simulation (not a traceback after it)."""

    assert main(["rod", "single", "-o", str(tmp_path / "none" / "x.csv"), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "folder" in err[0] and "does not exist" in err[0]


def test_the_rod_generator_asks_for_its_output_and_replaces_none_unasked(tmp_path, capsys) -> None:
    """``continuum-mhe rod single`` without ``-o`` is refused (no
    default inside the installed package, whose shipped recording it would replace),
    and an existing file (or its settings beside it) without ``--overwrite`` is one line,
    exit 2, before the simulation, the file left as it was."""

    with pytest.raises(SystemExit) as info:
        main(["rod", "single", "--duration", "0.1"])
    assert info.value.code == 2
    assert "the following arguments are required: -o/--output" in capsys.readouterr().err
    out = tmp_path / "rod.csv"
    for existing in (out, tmp_path / "rod_info.json"):
        existing.write_text("kept\n")
        assert main(["rod", "single", "-o", str(out), "--duration", "0.1"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--overwrite" in err[0] and existing.name in err[0]
        assert existing.read_text() == "kept\n"
        existing.unlink()


def test_the_section_rod_generator_makes_its_folder_and_refuses_a_mistyped_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``-o DIR`` of a folder not there yet: made, as the tendon generator makes its
    own (not refused, "no such folder": the docs' commands name a new DIR); a
    folder in a folder that does not exist, or a file, is one line, exit 2. (The bend
    recording's simulation and writer are stood in for: the folder is the point.)"""
    from continuum_mhe.simulation import cosserat_sections

    def write_bend(out: Path, name: str, *args: object, **kwargs: object) -> Path:
        (out / f"{name}_bend.csv").write_text("t\n0\n")
        return out / f"{name}_bend.csv"

    monkeypatch.setattr(cosserat_sections, "bend_trajectory", lambda *a: None)
    monkeypatch.setattr(cosserat_sections, "write_bend_recording", write_bend)
    new = tmp_path / "DIR"
    assert _rod_sections(["--scenario", "planar-s", "--bend-only", "-o", str(new)]) == 0
    assert (new / "planar-s_bend.csv").stat().st_size > 0
    capsys.readouterr()
    assert (
        _rod_sections(["--scenario", "planar-s", "--bend-only", "-o", str(tmp_path / "a" / "b")])
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(f"folder {tmp_path / 'a'} does not exist"), err
    assert not (tmp_path / "a").exists()
    (tmp_path / "file").write_text("x\n")
    assert (
        _rod_sections(["--scenario", "planar-s", "--bend-only", "-o", str(tmp_path / "file")]) == 2
    )
    assert capsys.readouterr().err.strip().endswith("exists and is not a folder")


def test_the_section_rod_generator_picks_a_stable_step_and_says_a_divergence(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A stiffer torsion needs a shorter explicit step: without ``--sim-dt`` the
    generator takes ``default_sim_dt`` (the default rod's 2e-5 s, shorter as the
    torsional waves speed up: under the 1e-5 and 5e-6 s that ran at G = 2E and 5E);
    with a step that diverges it says so in one line naming ``--sim-dt``, exit 2 (not a
    traceback); a shear ratio that is not a ratio is refused in one line."""
    from continuum_mhe.simulation.cosserat_sections import BASE_SIM_DT, default_sim_dt

    assert default_sim_dt(1.0 / 3.0) == BASE_SIM_DT == default_sim_dt(0.1)
    assert default_sim_dt(2.0) < 1e-5 and default_sim_dt(5.0) < 5e-6
    assert default_sim_dt(5.0) == pytest.approx(0.9 * BASE_SIM_DT / math.sqrt(15.0))
    argv = ["--scenario", "spatial", "--shear-ratio", "5", "--duration", "0.2"]
    assert _rod_sections([*argv, "--sim-dt", "2e-5", "-o", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "diverged" in err[0] and "--sim-dt 2e-05" in err[0], err
    assert not (tmp_path / "d").exists()
    for bad in ("-1", "0", "nan"):
        assert _rod_sections(["--shear-ratio", bad, "-o", str(tmp_path / "e")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--shear-ratio must be G / E > 0" in err[0], err


# --- the generators' refusals: before any simulation ----------------------------------------
#: how the command line's errors begin
ERROR = "continuum-mhe: error:"


def _straight_frame(n_elements: int = 30, length: float = 0.3) -> tuple[np.ndarray, ...]:
    """A straight rod along z: positions (3, k+1), directors (3, 3, k), rest lengths."""
    positions = np.zeros((3, n_elements + 1))
    positions[2] = np.linspace(0.0, length, n_elements + 1)
    directors = np.repeat(np.eye(3)[:, :, None], n_elements, axis=2)
    return positions, directors, np.full(n_elements, length / n_elements)


def test_a_blown_up_rod_frame_is_refused_though_finite() -> None:
    """A rod whose explicit integration blew up stays finite (at 2.5 times the default
    step the tip went 7.5 m from the base of the 0.3 m rod): an element strained (stretch
    or shear) past ``MAX_STRAIN`` is a divergence, the documented runs' few 1e-4 are not."""
    from continuum_mhe.simulation.cosserat_sections import (
        MAX_STRAIN,
        RodDivergedError,
        check_rod_frame,
        rod_strain,
    )

    x, q, rest = _straight_frame()
    assert rod_strain(x, q, rest) == pytest.approx(0.0, abs=1e-12)
    check_rod_frame(x, q, rest, 0.5)
    settled = x.copy()
    settled[2] *= 1 - 4e-4  # the default run's largest strain, 3.6e-4, and a little more
    check_rod_frame(settled, q, rest, 0.5)
    blown = x * 25.0  # the tip 7.5 m from the base
    with pytest.raises(RodDivergedError, match=r"diverged at t = 0\.5000 s \(an element strained"):
        check_rod_frame(blown, q, rest, 0.5)
    stretched = x.copy()
    stretched[2, 20:] += 2 * MAX_STRAIN * rest[0]  # one element 2 % longer
    assert rod_strain(stretched, q, rest) == pytest.approx(2 * MAX_STRAIN)
    with pytest.raises(RodDivergedError):
        check_rod_frame(stretched, q, rest, 0.1)
    sheared = q.copy()  # one element's frame turned off its tangent by 0.05 rad
    c, s = math.cos(0.05), math.sin(0.05)
    sheared[:, :, 7] = np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])
    assert rod_strain(x, sheared, rest) == pytest.approx(0.05, rel=1e-3)
    with pytest.raises(RodDivergedError):
        check_rod_frame(x, sheared, rest, 0.1)
    x[0, 3] = np.nan
    with pytest.raises(RodDivergedError, match="not finite"):
        check_rod_frame(x, q, rest, 0.1)


def test_a_step_that_blows_the_rod_up_is_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--sim-dt 5e-5`` (2.5 times the default) blows the rod up within its first
    recorded millisecond: one line naming ``--sim-dt``, exit 2, no folder (it wrote all
    six files of a 7.5 m tip, exit 0)."""

    out = tmp_path / "d"
    assert _rod_sections(["--sim-dt", "5e-5", "--duration", "0.05", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{ERROR} rod simulation"), err
    assert "strained" in err[0] and "--sim-dt 5e-05: give a shorter step" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--duration", "-1"], "--duration must be at least the IMUs' sample time, 0.02 s"),
        (["--duration", "0"], "--duration must be at least"),
        (["--duration", "0.01"], "--duration must be at least"),
        (["--duration", "nan"], "--duration must be at least"),
        (["--duration", "1e9"], "--duration must be at most 600 s"),
        (["--seed", "-3"], "--seed must be an integer >= 0, got -3"),
        (["--shear-ratio", "1e3"], "--shear-ratio must be G / E > 0 and at most 100"),
        (["--shear-ratio", "inf"], "--shear-ratio must be"),
        (["--sim-dt", "0"], "--sim-dt must be a step of 1e-07 to 0.001 s"),
        (["--sim-dt", "nan"], "--sim-dt must be"),
        (["--sim-dt", "0.01"], "--sim-dt must be"),
        (["--name", "../escape"], "--name '../escape': a file name prefix without a path"),
        (["--name", ".."], "--name '..'"),
    ],
)
def test_the_section_rod_generator_refuses_bad_numbers_before_it_simulates(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
    said: str,
) -> None:
    """A number out of range is one line naming its option, exit 2, before any
    simulation (not a traceback, nor a numpy memory error at 1e9 s after it), no
    folder made; a ``--name`` with a path separator would write outside ``-o``."""
    from continuum_mhe.simulation import cosserat_sections

    def no_simulation(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated")

    monkeypatch.setattr(cosserat_sections, "simulate_sections", no_simulation)
    out = tmp_path / "out"
    assert main(["rod", "sections", *argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{ERROR} {said}"), err
    assert list(tmp_path.iterdir()) == []


#: Each generator's ``--help`` after its usage line (at 100 columns), word for word: every
#: option, default and help text of each subcommand.
GENERATOR_HELP = {
    "single": """\
Simulate a cable-driven Cosserat rod with a tip MPU9250-like IMU and write the recording CSV.

options:
  -h, --help            show this help message and exit
  -o OUTPUT, --output OUTPUT
                        CSV to write, its settings beside it as NAME_info.json (the shipped
                        recording is src/continuum_mhe/data/rod_planar.csv in a clone of the
                        repository)
  --overwrite           replace an existing -o file (else refused)
  --duration DURATION   seconds (default 20)
  --seed SEED           sensor noise seed (default 0)
""",
    "sections": """\
Simulate a Cosserat rod of sections (a robot file's, two by default) with an IMU at each section's
end or where the robot file places them.

options:
  -h, --help            show this help message and exit
  -o OUT, --out OUT     folder for the files
  --overwrite           replace the recording's files in -o where they exist (else refused)
  --scenario {planar-s,spatial}
                        the couples' motion: planar-s (in one plane, the sections bent the
                        opposite ways in turn: an S on two) or spatial (bending planes turning;
                        bends past 90 degrees on the default rod) (default planar-s)
  --name NAME           file name prefix (default: the scenario)
  --robot ROBOT         a robot file (or shipped name) whose sections and IMUs to simulate:
                        standing on its base, its IMUs at section ends or on disks, no [backbone]
                        (default: two-section's, 0.16 m + 0.14 m, an IMU at each end)
  --duration DURATION   seconds, 0.02 (the IMUs' sample time) to 600 (default 12)
  --shear-ratio SHEAR_RATIO
                        G / E, above 0 and at most 100 (default 1/3)
  --sim-dt SIM_DT       integration step in s, 1e-7 to 1e-3 (default: 2e-5, shorter for a stiffer
                        torsion or elements under 1 cm: default_sim_dt)
  --drive {base,tendon}
                        couples fixed in the base frame (default) or in each section's frame
                        (tendon)
  --calibrated          IMUs without accelerometer bias and board misalignment (as after a
                        calibration); noise, quantisation and gyro bias stay
  --seed SEED           draws the IMUs' errors and noise, an integer >= 0 (default 0)
  --bend-only           write only NAME_bend.csv (the bend calibration recording of the IMUs that
                        these options give the recording)
""",
    "tendon": """\
Recordings of a tendon-driven robot that its estimator's model did not generate.

options:
  -h, --help            show this help message and exit
  --scenario {unloaded,planar-s,force-08,force-29,twist-08,twist-29,static}
                        the motion (default: unloaded)
  --duration DURATION   s, 0.02 (the IMUs' sample time) to 600; the shipped recordings' is 8
                        (default: 8.0)
  --robot ROBOT         a robot file (or shipped name) with a [backbone], tendons and disks,
                        standing on its base, its IMUs on disks or section ends (default: tendon-
                        two-section)
  --name NAME           the files' prefix, the scenario's name if not given
  --route {continuous,disks}
                        the tendons' path: continuous along the backbone at their radius, or
                        straight from disk to disk, as through a real robot's spacer disks
                        (default: the robot file's tendon_route, continuous where it gives none)
  --segments-per-disk SEGMENTS_PER_DISK
                        the discrete rod's segments between two disks, 1 to 32: more resolve
                        tendons drawn from disk to disk on widely spaced disks (each doubling
                        takes about eight times as long) (default: 4)
  --seed SEED           draws the IMUs' errors and noise, an integer >= 0 (default: 0)
  -o OUTPUT, --output OUTPUT
                        the folder to write to (made in a folder that exists)
  --overwrite           replace the recording's files in -o where they exist (else refused)
""",
}  # fmt: skip


@pytest.mark.parametrize("command", list(GENERATOR_HELP))
def test_each_generators_help_lists_the_options_it_had(
    command: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``continuum-mhe rod COMMAND --help`` calls itself so, and its description and
    options are those the generator had as a module's command line, word for word."""
    monkeypatch.setenv("COLUMNS", "100")  # argparse wraps at the terminal's width
    with pytest.raises(SystemExit) as exit_:
        main(["rod", command, "--help"])
    assert exit_.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"usage: continuum-mhe rod {command} [-h]"), text[:80]
    assert text.split("\n\n", 1)[1] == GENERATOR_HELP[command]


def test_rod_lists_its_three_generators(capsys: pytest.CaptureFixture[str]) -> None:
    """``continuum-mhe rod`` without a generator, or with a misspelt one, is one line
    naming the three, exit 2."""
    for argv, said in (
        ([], "the following arguments are required: COMMAND"),
        (["sigle"], "'sigle' is not a command: expected one of single, sections, tendon; "
         "did you mean single?"),
    ):  # fmt: skip
        with pytest.raises(SystemExit) as exit_:
            main(["rod", *argv])
        assert exit_.value.code == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert line.startswith(f"continuum-mhe rod: error: {said}"), line


def _tendon_robot(tmp_path: Path, edit: tuple[str, str] = ("", "")) -> Path:
    from continuum_mhe.io.robot_file import shipped_robots

    text = Path(shipped_robots()["tendon-two-section"]).read_text()
    path = tmp_path / "robot.toml"
    path.write_text(text.replace(*edit))
    return path


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--duration", "-1"], "--duration must be at least the IMUs' sample time, 0.02 s"),
        (["--duration", "0"], "--duration must be at least"),
        (["--duration", "0.01"], "--duration must be at least"),
        (["--duration", "nan"], "--duration must be at least"),
        (["--duration", "1e9"], "--duration must be at most 600 s"),
        (["--seed", "-1"], "--seed must be an integer >= 0, got -1"),
        (["--name", "../escape"], "--name '../escape': a file name prefix without a path"),
        (["-o", "{tmp}/none/dir/x"], "{tmp}/none/dir/x: folder {tmp}/none/dir does not exist"),
        (["-o", "{tmp}/file"], "{tmp}/file: exists and is not a folder"),
        (["--robot", "{tmp}/z-down.toml"], "{tmp}/z-down.toml: mounting = 'z-down': "),
        (
            ["--robot", "{tmp}/soft.toml"],  # a thinner backbone curls through turns
            "{tmp}/soft.toml: --scenario unloaded: its tensions, sized for tendon-two-section, "
            "would bend section 1 through 3.08 full turns at t = 4.96 s",
        ),
    ],
)
def test_the_tendon_generator_refuses_bad_arguments_before_it_simulates(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
    said: str,
) -> None:
    """The tendon generator's numbers, ``-o`` and robot layout: one line naming the
    option (or the robot file), exit 2, before the rod is simulated (not a traceback
    after 10 s of it; a missing parent of ``-o`` is not made, an existing file not a
    FileExistsError after the simulation), nothing written."""
    from continuum_mhe.simulation import cosserat_tendon

    def no_simulation(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated")

    monkeypatch.setattr(cosserat_tendon, "quasi_static_trajectory", no_simulation)
    (tmp_path / "file").write_text("x\n")
    _tendon_robot(tmp_path, ('mounting = "z-up"', 'mounting = "z-down"')).rename(
        tmp_path / "z-down.toml"
    )
    _tendon_robot(tmp_path, ("radius = 0.0007", "radius = 0.0004")).rename(tmp_path / "soft.toml")
    before = sorted(tmp_path.iterdir())
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    if "-o" not in argv:
        argv += ["-o", str(tmp_path / "out")]
    assert main(["rod", "tendon", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    said = said.replace("{tmp}", str(tmp_path))
    assert len(err) == 1 and err[0].startswith(f"{ERROR} {said}"), err
    assert sorted(tmp_path.iterdir()) == before


def test_an_equilibrium_the_tendon_generator_cannot_find_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """An energy minimisation that does not converge (a backbone far softer than the
    tensions are sized for): one line naming the robot file, the time and the likely
    cause, exit 2, nothing written (not a RuntimeError traceback)."""
    from continuum_mhe.simulation import cosserat_tendon

    def not_converged(*args: object, **kwargs: object) -> None:
        raise cosserat_tendon.EquilibriumError("the rod's energy minimisation did not converge")

    monkeypatch.setattr(cosserat_tendon, "energy_equilibrium", not_converged)
    robot, out = _tendon_robot(tmp_path), tmp_path / "out"
    assert main(["rod", "tendon", "--robot", str(robot), "--duration", "0.1", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(
        f"{ERROR} {robot}: the rod's energy minimisation did not converge at "
        "t = 0.00 s (--scenario unloaded): the tensions, sized for tendon-two-section"
    ), err
    assert "a stiffer backbone" in err[0] and not out.exists()


def test_the_tendon_truth_of_a_straight_robot_has_phi_0_and_no_minus_zero(
    tmp_path: Path,
) -> None:
    """A straight section's ``phi`` is 0 (docs/formats.md; not -pi, which
    ``atan2(-0, -0)`` gives), and no file holds a ``-0`` cell. (A straight trajectory given to
    the writer stands in for the rod's simulation.)"""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.cosserat_tendon import (
        TendonTrajectory,
        write_tendon_recording,
    )

    n, k = 5, 81
    t = np.arange(n, dtype=np.float64) * 0.02
    nodes = np.zeros((n, 3, k))
    nodes[:, 2] = np.linspace(0.0, 0.4, k)
    nodes[:, 0, -1] = -1e-12  # rounds to -0
    dirs = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
    z = np.zeros((n, 2, 3))
    sec = SectionTrajectory(t, nodes, dirs, z, z.copy(), np.zeros(n), (40, 80))
    traj = TendonTrajectory(sec, dirs, (40, 80), np.zeros((n, 6)), np.zeros((n, 3)))
    robot = read_robot("tendon-two-section")
    write_tendon_recording(tmp_path, "s", robot, "unloaded", 0.08, trajectory=traj)
    truth = read_state_table(tmp_path / "s_truth.csv")
    for c in ("phi_1", "phi_2", "theta_1", "theta_2"):
        assert np.all(truth.column(c) == 0.0), c
    for path in tmp_path.glob("s_*.csv"):
        cells = path.read_text().replace("\n", ",").split(",")
        assert "-0" not in cells, path.name


def test_a_tendon_recording_comes_with_a_rest_recording_of_its_imus(tmp_path: Path) -> None:
    """``rod tendon``'s ``NAME_rest.csv``: the recording's IMUs (the same misalignments
    and biases) with the rod in its first state, straight and still: without noise
    every row reads what the recording's first row reads, biases included. (A straight
    trajectory given to the writer stands in for the rod's simulation.)"""
    from dataclasses import replace

    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.cosserat_sections import DEFAULT_IMU
    from continuum_mhe.simulation.cosserat_tendon import (
        TendonTrajectory,
        recording_files,
        write_tendon_recording,
    )

    n, k = 5, 81
    nodes = np.zeros((n, 3, k))
    nodes[:, 2] = np.linspace(0.0, 0.4, k)
    dirs = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
    z = np.zeros((n, 2, 3))
    sec = SectionTrajectory(np.arange(n) * 0.02, nodes, dirs, z, z.copy(), np.zeros(n), (40, 80))
    traj = TendonTrajectory(sec, dirs, (40, 80), np.zeros((n, 6)), np.zeros((n, 3)))
    quiet = replace(DEFAULT_IMU, accel_noise=0.0, gyro_noise=0.0)
    robot = read_robot("tendon-two-section")
    write_tendon_recording(tmp_path, "s", robot, "unloaded", 0.08, imu=quiet, seed=3,
                           trajectory=traj)  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(recording_files("s"))
    raw = np.loadtxt(tmp_path / "s_raw.csv", delimiter=",", skiprows=1, ndmin=2)
    rest_lines = (tmp_path / "s_rest.csv").read_text().splitlines()
    assert rest_lines[0] == (tmp_path / "s_raw.csv").read_text().splitlines()[0]
    rest = np.loadtxt(rest_lines[1:], delimiter=",", ndmin=2)
    assert len(rest) == len(raw)
    np.testing.assert_allclose(rest[:, 1:], np.tile(raw[0, 1:], (len(rest), 1)), atol=1e-6)
    gyro = [4, 5, 6, 10, 11, 12]
    assert np.abs(raw[0, gyro]).min() > 1e-4  # the seed's gyro biases, read at rest too


def test_the_section_truth_of_a_straight_rod_has_phi_0_and_no_minus_zero(
    tmp_path: Path,
) -> None:
    """The section generator's files of a straight, still rod: ``phi`` 0 and no ``-0``
    cell (the quantised readings wrote ``-0``). (A straight trajectory given to the
    writer stands in for the rod's simulation.)"""
    from continuum_mhe.simulation.cosserat_sections import write_trajectory_recording

    n = 2001
    nodes = np.zeros((n, 3, 31))
    nodes[:, 2] = np.linspace(0.0, 0.3, 31)
    dirs = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
    z = np.zeros((n, 2, 3))
    t = np.arange(n, dtype=np.float64) * 1e-3
    traj = SectionTrajectory(t, nodes, dirs, z, z.copy(), np.zeros(n), (16, 30))
    write_trajectory_recording(tmp_path, "s", traj, SectionRodSettings(), "planar-s")
    truth = read_state_table(tmp_path / "s_truth.csv")
    assert np.all(truth.column("phi_1") == 0.0) and np.all(truth.column("phi_2") == 0.0)
    for path in tmp_path.glob("s_*.csv"):
        cells = path.read_text().replace("\n", ",").split(",")
        assert "-0" not in cells, path.name


@pytest.mark.parametrize(
    ("module", "command"),
    [("cosserat", "single"), ("cosserat_sections", "sections"), ("cosserat_tendon", "tendon")],
)
def test_a_generators_module_run_as_a_script_names_its_command(module, command) -> None:
    """``python -m continuum_mhe.simulation.MODULE`` writes nothing and exits 2 with the
    one line that names the command line's ``rod`` subcommand (not a silent success)."""
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-m", f"continuum_mhe.simulation.{module}", "-o", "x.csv"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert (run.returncode, run.stdout) == (2, "")
    assert run.stderr == (
        f"continuum-mhe: error: this module is not a command: run continuum-mhe rod {command}\n"
    )


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["single", "-o", "{tmp}/s.csv", "--seed", "-1", "--duration", "0.05"],
         "continuum-mhe: error: --seed must be an integer >= 0, got -1"),
        (["single", "-o", "{tmp}/s.csv", "--duration", "1e9"],
         "continuum-mhe: error: --duration must be at most 600 s"),
        (["tendon", "-o", ""],
         "continuum-mhe rod tendon: error: argument -o/--output: an empty value"),
    ],
)  # fmt: skip
def test_the_rod_commands_refuse_a_seed_a_duration_and_an_empty_output_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
    argv: list[str], said: str,
) -> None:  # fmt: skip
    """``rod single``'s seed and duration are held to the other generators' limits, and
    ``rod tendon -o ''`` is an empty value (not the current folder): one line, exit 2,
    nothing written anywhere."""
    monkeypatch.chdir(tmp_path)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    try:
        status = main(["rod", *argv])
    except SystemExit as exc:  # the parser's own refusal
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(said), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["sections", "tendon"])
def test_a_rod_recording_is_not_replaced_without_overwrite(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """A folder that holds a recording of the same name: ``rod sections`` and ``rod
    tendon`` refuse in one line naming the first file, exit 2, before they simulate and
    with the files as they were; another ``--name`` in that folder is written."""
    from continuum_mhe.simulation import cosserat_sections, cosserat_tendon

    module = cosserat_sections if command == "sections" else cosserat_tendon
    out = tmp_path / "rec"
    out.mkdir()
    kept = out / f"{'planar-s' if command == 'sections' else 'unloaded'}_tilt.csv"
    kept.write_text("t,roll_1,pitch_1,roll_2,pitch_2\n")

    simulated: list[str] = []

    def no_simulation(out: Path, name: str, *args: object, **kwargs: object) -> dict:
        simulated.append(name)
        return {}

    for writer in ("write_section_recording", "write_tendon_recording"):
        if hasattr(module, writer):
            monkeypatch.setattr(module, writer, no_simulation)
    assert main(["rod", command, "-o", str(out), "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {out}/"), err
    assert "exists; give --overwrite to replace it" in err[0]
    assert kept.read_text() == "t,roll_1,pitch_1,roll_2,pitch_2\n" and simulated == []
    assert main(["rod", command, "-o", str(out), "--duration", "0.1", "--name", "other"]) == 0
    assert main(["rod", command, "-o", str(out), "--duration", "0.1", "--overwrite"]) == 0
    assert simulated == ["other", kept.name.split("_")[0]]
