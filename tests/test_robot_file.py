"""Robot files that read but are likely slips: IMUs out of base-to-tip order or listed
twice, an ``at`` written in metres, a ``mount_rpy`` in radians. Each is one warning,
given once by every command that reads the file; and the robot classes' own checks."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import figures_drawn_small

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io.csv_files import UnitWarning
from continuum_mhe.io.robot_file import RobotFileWarning, read_robot
from continuum_mhe.model.robot import mount_rpy_hint

SECTIONS = "".join(f"[[section]]\nlength = {v}\ntheta_max = 3.0\n" for v in (0.16, 0.14))


def _robot(path: Path, *imus: str) -> Path:
    path.write_text(SECTIONS + "".join(f"[[imu]]\n{imu}\n" for imu in imus))
    return path


def _said(path: Path) -> list[str]:
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        read_robot(path)
    return [str(w.message) for w in seen]


def test_imus_out_of_base_order_warn(tmp_path: Path) -> None:
    """IMUs listed out of base-to-tip order (section 2 before section 1, or nearer the
    base within one section) warn: the measurement columns follow the file's order, so
    estimate would pair roll_1 with the tip IMU (ok rows 64 mm off)."""
    robot = _robot(tmp_path / "r.toml", "section = 2", "section = 1")
    assert _said(robot) == [
        f"{robot}: imu 2 (section 1, at 1) is nearer the base than imu 1 (section 2, at 1) "
        "but listed after it: the measurement columns follow the file's order, and IMU 1 is "
        "expected nearest the base; list the [[imu]] entries from base to tip (or check that "
        "the columns follow this order)"
    ]
    within = _robot(tmp_path / "w.toml", "section = 1\nat = 1.0", "section = 1\nat = 0.5")
    assert [m.split(":")[1] for m in _said(within)] == [
        " imu 2 (section 1, at 0.5) is nearer the base than imu 1 (section 1, at 1) but listed "
        "after it"
    ]


@pytest.mark.parametrize(
    "imus",
    [
        ("section = 1", "section = 2"),
        ("section = 1\nat = 0.5", "section = 1", "section = 2\nat = 0.25", "section = 2"),
        ("section = 2",),
    ],
)
def test_imus_from_base_to_tip_read_silently(tmp_path: Path, imus: tuple[str, ...]) -> None:
    assert _said(_robot(tmp_path / "r.toml", *imus)) == []


def test_one_place_listed_twice_warns(tmp_path: Path) -> None:
    robot = _robot(tmp_path / "r.toml", "section = 1", "section = 2", "section = 2\nat = 1.0")
    assert _said(robot) == [
        f"{robot}: imu 3 is at the same place as imu 2 (section 2, at 1): two IMUs listed at "
        "one place (a copied entry?)"
    ]


def test_the_order_warning_is_given_once_per_command(tmp_path: Path, capsys) -> None:
    """estimate reads the robot file more than once; the warning is said once."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "spatial", "--robot", "two-section", "--duration", "1",
                 "-o", str(meas)]) == 0  # fmt: skip
    robot = _robot(tmp_path / "r.toml", "section = 2", "section = 1")
    argv = ["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--robot", str(robot)]
    for command in (["check-robot", str(robot), "--samples", "20"], [*argv, "--method", "ekf"]):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("default")
            assert main(command) == 0
        said = [str(w.message) for w in seen if w.category is RobotFileWarning]
        assert len(said) == 1 and "is nearer the base than imu 1" in said[0], command


def test_the_order_warning_is_given_once_by_the_readers_of_an_estimate(
    tmp_path: Path, monkeypatch
) -> None:
    """evaluate and plot given ``--robot r.toml`` of an estimate whose options line names
    the same file by its full path say the robot file's warning once: the recorded
    file, read only to compare it with the given one, adds no second warning."""
    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "spatial", "--robot", "two-section", "--duration", "1",
                 "-o", "m.csv", "--truth", "t.csv"]) == 0  # fmt: skip
    _robot(tmp_path / "r.toml", "section = 2", "section = 1")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["estimate", "m.csv", "-o", "e.csv", "--robot", "r.toml"]) == 0
    assert str(tmp_path / "r.toml") in (tmp_path / "e.csv").read_text()  # its full path
    for command in (
        ["evaluate", "e.csv", "t.csv", "--robot", "r.toml"],
        ["plot", "e.csv", "--truth", "t.csv", "--robot", "r.toml", "-o", "p.png"],
    ):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("default")
            assert main(command) == 0
        said = [str(w.message) for w in seen if w.category is RobotFileWarning]
        assert len(said) == 1 and "is nearer the base than imu 1" in said[0], (command, said)


@pytest.mark.parametrize(("length", "at"), [(0.18, 0.18), (0.12, 0.12), (0.16, 0.1604)])
def test_at_written_in_metres_warns(tmp_path: Path, length: float, at: float) -> None:
    """``at = 0.18`` on a 0.18 m section (the length in metres) warns, and is read as
    written: 18 % of the section."""
    robot = tmp_path / "r.toml"
    robot.write_text(f"[[section]]\nlength = {length}\n[[imu]]\nsection = 1\nat = {at}\n")
    with pytest.warns(UnitWarning) as seen:
        assert read_robot(robot).imus[0].at == at  # read as written
    assert [str(w.message) for w in seen] == [
        f"{robot}: imu 1: at is a fraction of the section's length; {at:g} equals section "
        "1's length in m: metres? (at = 1 is its end, 0.5 its middle)"
    ]


@pytest.mark.parametrize(
    ("length", "at"),
    [(1.0, 1.0), (0.16, 0.5), (0.16, 0.15), (0.2, 0.25), (0.16, None), (0.5, 0.5)],
)
def test_at_as_a_fraction_reads_silently(tmp_path: Path, length: float, at: float | None) -> None:
    """A 1 m section's end is at = 1 either way; the default at = 1 is no slip; a 0.5 m
    section's at = 0.5 is its middle."""
    robot = tmp_path / "r.toml"
    given = "" if at is None else f"at = {at}\n"
    robot.write_text(f"[[section]]\nlength = {length}\n[[imu]]\nsection = 1\n{given}")
    assert _said(robot) == []


@pytest.mark.parametrize(
    ("rpy", "degrees"),
    [
        ((0, 1.5708, 3.14159), "[0, 90, 180]"),
        ((0, 0, 0.7854), "[0, 0, 45]"),
        ((6.2832, 0, 0), "[360, 0, 0]"),
        ((0, -4.7124, 0), "[0, -270, 0]"),
        ((1.57, 0.3, 0), "[90, 17.2, 0]"),  # a right angle to two decimals
    ],
)
def test_mount_rpy_in_radians_gets_a_hint(rpy: tuple[float, ...], degrees: str) -> None:
    assert mount_rpy_hint(rpy) == (
        f"radians? mount_rpy is in degrees ({degrees} if these are radians)"
    )


@pytest.mark.parametrize(
    "rpy",
    [(0, 0, 0), (0, 90, 180), (3, 6, 0), (0, 0, 3), (30.5, 0, 0), (1, 2, 4), (0.5, -1.5, 2.5),
     (0, 0, 45), (3.14, 0, 0), (90, 0, 1.5708), (-0.001, -0.004, 0.0), (0.0005, 0, 0)],
)  # fmt: skip
def test_mount_rpy_in_degrees_gets_no_hint(rpy: tuple[float, ...]) -> None:
    """Whole degrees are never within 1e-3 of a multiple of pi/4; beside a value over
    2 pi (90) the others are degrees too; values within 1e-3 of 0 (a well-mounted IMU
    as calibrate writes it) are no quarter turn."""
    assert mount_rpy_hint(rpy) == ""


def test_mount_rpy_in_radians_warns(tmp_path: Path, capsys) -> None:
    """mount_rpy = [0, 1.5708, 3.14159], which rotates raw readings by 1.6 and 3.1
    degrees, warns that it looks like radians; --mount-rpy 0,1.5708,0 likewise."""
    robot = _robot(tmp_path / "r.toml", "section = 1\nmount_rpy = [0, 1.5708, 3.14159]",
                   "section = 2")  # fmt: skip
    with pytest.warns(UnitWarning) as seen:
        assert read_robot(robot).imus[0].mount_rpy == (0, 1.5708, 3.14159)  # as written
    assert [str(w.message) for w in seen] == [
        f"{robot}: imu 1: mount_rpy = [0, 1.5708, 3.14159] is read in degrees: radians? "
        "mount_rpy is in degrees ([0, 90, 180] if these are radians)"
    ]
    meas = tmp_path / "m.csv"
    meas.write_text("t,ax,ay,az\n0,0,0,9.81\n0.05,0,0,9.81\n")
    argv = ["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--method", "ekf"]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("default")
        assert main([*argv, "--mount-rpy", "0,1.5708,0"]) == 0
    assert [str(w.message) for w in said if w.category is UnitWarning] == [
        "--mount-rpy 0,1.5708,0 is read in degrees: radians? --mount-rpy is in degrees "
        "([0, 90, 0] if these are radians)"
    ]


def test_a_folder_given_as_robot_file_is_named_a_folder(tmp_path: Path) -> None:
    """A folder given as a robot file (``check-robot /tmp``) is named a folder, not 'no
    such robot file'."""
    with pytest.raises(InputError, match=r": a folder, not a robot file \(shipped robots"):
        read_robot(tmp_path)
    with pytest.raises(InputError, match=r": no such robot file \(shipped robots"):
        read_robot(tmp_path / "missing.toml")


@pytest.mark.parametrize("mark", [b"", b"\xef\xbb\xbf"])
def test_a_robot_file_in_an_8_bit_encoding_is_named_at_its_line_and_byte(
    tmp_path: Path, capsys, mark: bytes
) -> None:
    """A robot file saved in Windows-1252 (an umlaut in a comment) is refused at the
    line and byte that are no UTF-8, with the character they are in Windows-1252 and the
    command that converts the file, as a CSV file is (with a byte-order mark too, the
    byte counted after it); UTF-16 text is named as such; a file of control bytes is
    said to be no text."""
    path = tmp_path / "latin.toml"
    path.write_bytes(
        mark + b'mounting = "z-up"\n# Roboter f\xfcr Tests\n[[section]]\nlength = 0.2\n'
    )
    capsys.readouterr()
    assert main(["check-robot", str(path)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {path}: line 2: not UTF-8 text: byte 12 of the line, 0xFC "
        "('\u00fc' in Windows-1252), text saved in an 8-bit encoding; save it as UTF-8 "
        f"(iconv -f CP1252 -t UTF-8 {path} > NEW.toml)\n"
    )
    # on the first line after a byte-order mark: the byte counted after the mark
    path.write_bytes(mark + b'mounting = "z-up" # f\xfcr\n')
    with pytest.raises(InputError, match=r"line 1: not UTF-8 text: byte 22 of the line, 0xFC"):
        read_robot(path)
    utf16 = tmp_path / "utf16.toml"
    utf16.write_bytes('mounting = "z-up"\n'.encode("utf-16"))
    with pytest.raises(InputError, match=r"utf16\.toml: not UTF-8 text but UTF-16: save it as"):
        read_robot(utf16)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b'mounting = "z-up"\n\x01\x02\xff\n')
    with pytest.raises(
        InputError, match=r"binary\.toml: line 2: not UTF-8 text \(a binary file\?\)$"
    ):
        read_robot(binary)


def test_robot_classes_take_numpy_numbers_and_refuse_bools_and_slips() -> None:
    """numpy's reals and integers are numbers, taken; bools are not, refused (not taken
    as 1); a tendon angle beyond a full turn is degrees given to a class that
    takes radians; a backbone or tendon that is not one is refused where it is given."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.robot import Backbone, ImuPlacement, Robot, Section, Tendon

    assert ImuPlacement(0, np.float32(0.5)).at == 0.5
    assert Section(0.2, disks=np.int64(10)).disks == 10
    assert Tendon(0, np.float32(1.0), np.float32(0.01)).angle == 1.0
    assert Backbone(np.float64(54e9), 20e9, 7e-4).youngs_modulus == 54e9
    assert ImuPlacement(0, mount_rpy=np.array([0.0, 0.0, 90.0])).mount_rpy == (0.0, 0.0, 90.0)
    one = ((Section(0.2),), (ImuPlacement(0),))
    bad = {
        "'at' must be a number": lambda: ImuPlacement(0, True),
        "tendon angle must be a finite number": lambda: Tendon(0, True, 0.01),
        "beyond a full turn: Tendon takes radians": lambda: Tendon(0, 120, 0.01),
        "mount_rpy must be three angles": lambda: ImuPlacement(0, mount_rpy=(True, 0, 0)),
        "Robot backbone must be a Backbone": lambda: Robot(*one, backbone=(54e9, 20e9, 7e-4)),
        "Robot tendons item must be Tendon": lambda: Robot(
            *one, backbone=Backbone(54e9, 20e9, 7e-4), tendons=[(0, 0, 0.01)]
        ),
    }
    for needle, make in bad.items():
        with pytest.raises(UserError, match=re.escape(needle)):
            make()


@pytest.mark.parametrize("at", ["0", "-0.25", "1.0000001", "2"])
def test_an_imu_at_a_fraction_outside_0_to_1_is_refused_naming_its_line(
    tmp_path: Path, at: str
) -> None:
    """``at`` is a fraction of the section in (0, 1]: 0 (the section's base, the end of
    the one before), a negative one or one past the end is one InputError naming the
    file, the line of its ``at`` and the range, and a UserError from the library's
    ``ImuPlacement``; 1 (the end) is read."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.robot import ImuPlacement

    robot = _robot(tmp_path / "r.toml", "section = 1", f"section = 2\nat = {at}")
    said = f"at must lie in (0, 1] (fraction of the section), got {float(at)!r}"
    with pytest.raises(InputError, match=rf"r\.toml: line 11: imu 2: {re.escape(said)}$"):
        read_robot(robot)
    said = f"IMU 'at' must be a number in (0, 1] (a fraction of the section), got {float(at)!r}"
    with pytest.raises(UserError, match=f"^{re.escape(said)}$"):
        ImuPlacement(1, float(at))
    assert read_robot(_robot(robot, "section = 1", "section = 2\nat = 1")).imus[1].at == 1.0
    assert ImuPlacement(1, 1.0).at == 1.0


def test_an_imu_at_a_subnormal_fraction_is_refused_where_it_is_given(tmp_path: Path) -> None:
    """``at = 5e-324`` (a subnormal fraction, in (0, 1] but 1 / at overflows: a raw
    recording's start failed in scipy's least squares) is refused by ``ImuPlacement``
    and, naming its line, by the robot file; the smallest normal float is taken."""
    import sys

    from continuum_mhe.errors import UserError
    from continuum_mhe.model.robot import ImuPlacement

    said = "IMU 'at' must be a fraction of the section of at least 2.2250738585072014e-308"
    for at in (5e-324, 1e-310):
        with pytest.raises(UserError, match=re.escape(f"{said} (the smallest normal float)")):
            ImuPlacement(0, at)
    assert ImuPlacement(0, sys.float_info.min).at == 2.2250738585072014e-308
    robot = _robot(tmp_path / "r.toml", "section = 1\nat = 5e-324", "section = 2")
    with pytest.raises(InputError, match=rf"r\.toml: line 7: imu 1: {re.escape(said)}"):
        read_robot(robot)


def test_a_gyro_bias_in_deg_s_warns(tmp_path: Path) -> None:
    """gyro_bias = [0.5, -1.2, 0.8] (deg/s written for rad/s: 69 deg/s read) warns, and
    is read as written; a MEMS gyro's bias in rad/s does not."""
    robot = tmp_path / "r.toml"
    base = "[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n"
    robot.write_text(base + "gyro_bias = [0.5, -1.2, 0.8]\n")
    with pytest.warns(UnitWarning, match=r"gyro_bias = \[0.5, -1.2, 0.8\] is read in rad/s"):
        assert read_robot(robot).imus[0].gyro_bias == (0.5, -1.2, 0.8)
    robot.write_text(base + "gyro_bias = [0.01, -0.02, 0.005]\n")
    assert _said(robot) == []


def test_a_tendon_radius_and_a_single_bracket_table_are_named_on_their_line(tmp_path) -> None:
    """A tendon's radius of 0 names the ``radius =`` line, not its ``[[tendon]]`` line;
    ``[section]`` (one table, where a list is meant) names its own line."""
    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    lines = shipped.read_text().splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.strip() == "[[tendon]]")
    at = next(i for i in range(first, len(lines)) if lines[i].startswith("radius"))
    lines[at] = "radius = 0"
    robot = tmp_path / "r.toml"
    robot.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=rf"r\.toml: line {at + 1}: tendon 1: radius = 0: "):
        read_robot(robot)
    single = tmp_path / "s.toml"
    single.write_text("# a robot\n[section]\nlength = 0.2\n[[imu]]\nsection = 1\n")
    with pytest.raises(InputError, match=r"s\.toml: line 2: 'section' must be a list of tables"):
        read_robot(single)


def test_a_single_bracket_table_after_a_key_of_its_name_names_the_table(tmp_path) -> None:
    """``section = 1`` inside an ``[[imu]]`` before a ``[section]`` table: the line named
    is the table's, not the IMU's key."""
    robot = tmp_path / "r.toml"
    robot.write_text("[[imu]]\nsection = 1\n\n[section]\nlength = 0.2\n")
    with pytest.raises(InputError, match=r"r\.toml: line 4: 'section' must be a list of tables"):
        read_robot(robot)


def test_a_robot_of_more_sections_than_the_models_take_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Past MAX_SECTIONS (16) the models' symbolic Jacobians make a check or a first
    estimate impractical (docs/formats.md): a robot file of 17 sections is refused in
    one line naming it, exit 2, and so is such a Robot in Python; one of 16 is a robot."""
    from continuum_mhe.cli import main
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.robot import MAX_SECTIONS, ImuPlacement, Robot, Section

    def robot_file(n: int) -> Path:
        path = tmp_path / f"r{n}.toml"
        path.write_text("[[section]]\nlength = 0.01\n" * n + "[[imu]]\nsection = 1\n")
        return path

    assert MAX_SECTIONS == 16 and read_robot(robot_file(16)).n_sections == 16
    assert main(["check-robot", str(robot_file(17)), "--samples", "10"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(
        f"continuum-mhe: error: {robot_file(17)}: 17 sections: a robot has at most 16"
    ), err
    with pytest.raises(UserError, match=r"^17 sections: a robot has at most 16 \(the models'"):
        Robot((Section(0.01),) * 17, (ImuPlacement(0),))


def test_two_tendons_on_one_path_are_said(tmp_path: Path) -> None:
    """A copied [[tendon]] entry (the same section, angle and radius) is read with a
    one-line warning naming both (each tendon adds a tensions column); the shipped
    tendon robot, whose tendons are all apart, reads without one."""
    from continuum_mhe.io.robot_file import RobotFileWarning

    shipped = (
        Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    ).read_text()
    twin = tmp_path / "twin.toml"
    twin.write_text(shipped + "\n[[tendon]]\nsection = 1\nangle = 0\nradius = 0.01\n")
    # the same angle a turn apart (360 for 0), and -120 for 240: the same paths
    for angle, first in (("360", "tendon 1 (section 1, angle 360"), ("-120", "tendon 3 (")):
        turned = tmp_path / f"turned{angle}.toml"
        turned.write_text(shipped + f"\n[[tendon]]\nsection = 1\nangle = {angle}\nradius = 0.01\n")
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            read_robot(turned)
        (line,) = [str(w.message) for w in seen if w.category is RobotFileWarning]
        assert "is at the same place as " + first in line, line
    for path, said in ((twin, True), (tmp_path / "apart.toml", False)):
        if not said:
            path.write_text(shipped)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            robot = read_robot(path)
        lines = [str(w.message) for w in seen if w.category is RobotFileWarning]
        if said:
            n = robot.n_tendons
            assert lines == [
                f"{path}: tendon {n} is at the same place as tendon 1 (section 1, angle 0 "
                "deg, radius 0.01 m): two tendons listed on one path (a copied entry? each "
                "adds a tensions column)"
            ]
        else:
            assert lines == []


def test_a_section_of_metres_is_said_as_centimetres_read_as_metres(tmp_path: Path) -> None:
    """A section of 3 "m" (3 cm written as 3) is under the 5 m refused as millimetres,
    and longer than any continuum robot's section: a warning naming the file and the
    section says so; 2 m and less, none."""
    import warnings

    from continuum_mhe.io.robot_file import RobotFileWarning, read_robot

    path = tmp_path / "cm.toml"
    path.write_text("[[section]]\nlength = 0.2\n[[section]]\nlength = 3\n[[imu]]\nsection = 2\n")
    with pytest.warns(RobotFileWarning, match=r"cm\.toml: section 2: length 3 m .*is 0\.03\)"):
        read_robot(str(path))
    path.write_text("[[section]]\nlength = 2\n[[imu]]\nsection = 1\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_robot(str(path))


def test_a_disk_route_mistake_names_its_line(tmp_path: Path) -> None:
    """``tendon_route = "disks"`` on a robot without tendons names the key's line; on a
    robot whose tendons pass a section without ``disks``, that section's line (where the
    disks go): each refused in one line with its line number, as any robot-file problem."""
    robot = tmp_path / "r.toml"
    robot.write_text(
        '# a robot\ntendon_route = "disks"\n[[section]]\nlength = 0.2\ndisks = 5\n'
        "[[imu]]\nsection = 1\n"
    )
    with pytest.raises(
        InputError, match=r'r\.toml: line 2: tendon_route = "disks" is for a robot with'
    ):
        read_robot(robot)
    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    lines = shipped.read_text().splitlines()
    sections = [i for i, ln in enumerate(lines) if ln.strip() == "[[section]]"]
    no_disks = [ln for i, ln in enumerate(lines) if not (i > sections[1] and "disks" in ln)]
    robot.write_text('tendon_route = "disks"\n' + "\n".join(no_disks) + "\n")
    # the second [[section]] header, one line further down for the tendon_route line
    with pytest.raises(InputError, match=rf"r\.toml: line {sections[1] + 2}: section 2: "):
        read_robot(robot)


def test_a_backbone_without_density_is_said_once(tmp_path: Path) -> None:
    """A [backbone] without its density is read as weightless with a one-line warning
    naming the file and the key (the weight is then read as a tip force); the shipped
    tendon robot, which gives it, reads without one; the command line says it once."""
    shipped_path = (
        Path(__file__).parents[1] / "src/continuum_mhe/data/robots/tendon_two_section.toml"
    )
    shipped = shipped_path.read_text()
    lines = shipped.splitlines()
    assert sum(line.startswith("density") for line in lines) == 1
    weightless = tmp_path / "weightless.toml"
    weightless.write_text("\n".join(x for x in lines if not x.startswith("density")) + "\n")
    for path, said in ((weightless, True), (shipped_path, False)):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            robot = read_robot(path)
        found = [str(w.message) for w in seen if w.category is RobotFileWarning]
        assert robot.backbone is not None
        assert (robot.backbone.density is None) is said
        if said:
            (line,) = found
            assert line.startswith(f"{weightless}: backbone: no density: "), line
            assert "weightless" in line and "kg/m^3" in line and "\n" not in line
        else:
            assert found == []
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("default")
        assert main(["check-robot", str(weightless), "--samples", "20"]) == 0
    said = [str(w.message) for w in seen if w.category is RobotFileWarning]
    assert len(said) == 1 and "no density" in said[0], said
