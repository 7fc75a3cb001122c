"""The input rules (docs/reliability.md, "Input rules"): lines read whole, one line and
exit 2 for every bad input, ambiguous input refused, the firmware's capture read as it
is. The inputs of tests/data/repro/ that exposed each defect are read here."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from continuum_mhe import (
    Formulation,
    Measurement,
    MHESettings,
    NoiseSettings,
    RobotSettings,
    make_estimator,
    make_formulation,
    simulate,
)
from continuum_mhe.analysis.observability import observability_report, verdict
from continuum_mhe.cli import main
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.io.raw_imu import read_raw_imu
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.text_rows import MAX_LINE_BYTES, declared_fields
from continuum_mhe.model.pcc import shape_rank
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.results import Status
from continuum_mhe.stream.protocol import GarbledLine, header_fields, parse_line

REPRO = Path(__file__).parent / "data" / "repro"
HEAD = b"t,roll,pitch\n0,0.1,0.1\n"
E_ACUTE = "\u00e9".encode()  # two bytes in UTF-8


def _one_line_error(capsys: pytest.CaptureFixture[str], code: int, out: Path) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if not ln.startswith("continuum-mhe: note: ")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("continuum-mhe: error: "), err
    assert not out.exists()
    return lines[0]


# --- lines read whole -------------------------------------------------------------------------
def test_a_long_utf8_comment_line_is_read_whole(tmp_path: Path) -> None:
    """utf8_long_comment.csv (generated here): a 65,538-byte comment of two-byte
    characters is read whole, not cut inside a character (as reading 65,537 bytes at a
    time would) and refused as 'not UTF-8'."""
    path = tmp_path / "utf8_long_comment.csv"
    path.write_bytes(HEAD + b"# " + E_ACUTE * 32768 + b"\n0.05,0.1,0.1\n")
    assert path.stat().st_size == 65575  # the reproducer's size
    table = read_measurements(path)
    np.testing.assert_allclose(table.t, [0, 0.05])


def test_text_inside_a_long_comment_never_becomes_a_sample(tmp_path: Path) -> None:
    """utf8_injected_row.csv (generated here): a comment whose text after 65,537 bytes
    reads as a row stays a comment: two samples, not three (as a cut there would give)."""
    path = tmp_path / "utf8_injected_row.csv"
    path.write_bytes(HEAD + b"#" + E_ACUTE * 32768 + b"0.025,1.2,-0.9\n0.05,0.1,0.1\n")
    assert path.stat().st_size == 65588
    table = read_measurements(path)
    np.testing.assert_allclose(table.t, [0, 0.05])
    np.testing.assert_allclose(table.z, [[0.1, 0.1], [0.1, 0.1]])


def test_a_line_over_the_limit_is_one_line_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_bytes(HEAD + b"# " + b"x" * MAX_LINE_BYTES + b"\n0.05,0.1,0.1\n")
    with pytest.raises(InputError) as info:
        read_measurements(path)
    assert (
        str(info.value) == f"{path}: line 3: longer than {MAX_LINE_BYTES} bytes (not a CSV file?)"
    )
    path.write_bytes(HEAD + b"# " + b"x" * (MAX_LINE_BYTES - 2) + b"\r\n0.05,0.1,0.1\n")
    assert len(read_measurements(path).t) == 2  # at the limit (its line end not counted)


def test_cr_only_line_ends_are_one_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """cr_only.csv (3.4 kB, lines ending in CR alone): one short line naming the line
    ends and the fix, not the whole file quoted as one line."""
    out = tmp_path / "e.csv"
    path = REPRO / "cr_only.csv"
    line = _one_line_error(capsys, main(["estimate", str(path), "-o", str(out)]), out)
    assert line == (
        f"continuum-mhe: error: {path}: line 1: lines end in CR alone (classic Mac OS line "
        "ends); save the file with LF or CRLF line ends"
    )


@pytest.mark.parametrize(
    "body",
    [
        "".join(f"{0.02 * i:.2f},0.1,0.1\r" for i in range(80000)),  # over 1 MiB on one "line"
        "# 10\xb0 (a MacRoman or Latin-1 byte)\r0,0.1,0.1\r",  # not UTF-8
    ],
)
def test_cr_only_line_ends_are_said_before_size_and_encoding(tmp_path: Path, body: str) -> None:
    """A file whose lines end in CR alone reads as one line: it is told its line ends
    however long that line is, and whatever bytes the old Mac encoding left in it."""
    path = tmp_path / "m.csv"
    path.write_bytes(("t,roll,pitch\r" + body).encode("latin-1"))
    with pytest.raises(InputError, match=r"m.csv: line 1: lines end in CR alone"):
        read_measurements(path)


def test_a_long_header_is_cut_in_messages(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_text("t," + ",".join(f"c{i}" for i in range(2000)) + "\n0,1\n")
    with pytest.raises(InputError) as info:
        read_measurements(path)
    assert len(str(info.value)) < 400 and "..." in str(info.value)


# --- ambiguous headers and numbers ----------------------------------------------------------
def test_a_column_named_twice_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """dup_header.csv: two roll columns are refused in one line, not the first used."""
    out = tmp_path / "e.csv"
    path = REPRO / "dup_header.csv"
    code = main(["estimate", str(path), "-o", str(out), "--method", "ekf"])
    assert _one_line_error(capsys, code, out).endswith(
        f"{path}: line 1: column 'roll' appears twice in the header (which one holds the "
        "data?); rename or remove one"
    )


def test_tilt_and_raw_columns_in_one_header_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """both_tilt_raw.csv: a header with both tilt and raw columns is refused in one line,
    not read as raw."""
    out = tmp_path / "e.csv"
    path = REPRO / "both_tilt_raw.csv"
    code = main(["estimate", str(path), "-o", str(out), "--method", "ekf"])
    assert _one_line_error(capsys, code, out).endswith(
        f"{path}: line 1: the header has both tilt (roll, pitch) and raw IMU columns (ax, ay, "
        "az); give one kind: remove the tilt or the raw columns"
    )


@pytest.mark.parametrize(
    ("header", "rows", "robot", "message"),
    [
        ("T,Roll_1,Pitch_1", "0,0.1,0.1", "two-section", "tilt columns for 1 IMU(s) (Roll_1) but"),
        ("T,Rol_1,Pitch_1,Roll_2,Pitch_2", "0,0,0,0,0", "two-section", "has Rol_1 (a typo?)"),
        ("T,Roll", "0,0.1", None, "missing column(s) pitch (header has: T, Roll)"),
        ("T_MS,Roll,Pitch", "0,0.1,0.1\n50,x,0.1", None, "line 3: column Roll: 'x' is not"),
        ("T,Roll_0,Pitch_0", "0,0.1,0.1", None, "line 1: column Roll_0: IMU columns are"),
        ("T,Roll,Pitch,roll", "0,0,0,0", None, "columns 'Roll' and 'roll' of the header are one"),
        ("T,AX,AY,AZ,GX,GY,GZ,Roll", "0,0,0,9.8,0,0,0,0", None, "header has both tilt (Roll)"),
    ],
)
def test_a_header_is_quoted_as_the_file_writes_it(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    header: str,
    rows: str,
    robot: str | None,
    message: str,
) -> None:
    """Column names are read in any case; a message quotes the header's names as the
    file writes them (``Roll_1``, ``T_MS``), not in lower case."""
    out = tmp_path / "e.csv"
    path = tmp_path / "m.csv"
    path.write_text(f"{header}\n{rows}\n")
    code = main(["estimate", str(path), "-o", str(out), *(["--robot", robot] if robot else [])])
    line = _one_line_error(capsys, code, out)
    assert line.startswith(f"continuum-mhe: error: {path}: ") and message in line, line


def test_a_tensions_file_given_as_the_readings_is_said_to_belong_to_inputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped tensions file given where the IMU readings go: one line saying it
    looks like a tensions file, which belongs to --inputs (not that it lacks roll, pitch
    columns); the library's reader says the same."""
    tensions = Path(__file__).parents[1] / "src/continuum_mhe/data/tendon/unloaded_tensions.csv"
    out = tmp_path / "e.csv"
    code = main(["estimate", str(tensions), "--robot", "tendon-two-section", "-o", str(out)])
    line = _one_line_error(capsys, code, out)
    assert line.startswith(
        f"continuum-mhe: error: {tensions}: line 1: this looks like a tensions file (columns "
        "tension_1 ... tension_6), not IMU readings: it belongs to --inputs"
    ), line
    assert "missing column" not in line
    with pytest.raises(InputError, match="looks like a tensions file .* belongs to --inputs"):
        read_measurements(tensions, n_imus=2)


@pytest.mark.parametrize("text", ["1_0", "0.1_5", "\uff10.1", "\u0661"])
def test_python_only_numbers_are_not_numbers(tmp_path: Path, text: str) -> None:
    """What float() reads as numbers and a CSV does not hold (1_0 as 10, fullwidth or
    Arabic-Indic digits) is not a number, in files and in live lines."""
    path = tmp_path / "m.csv"
    path.write_text(f"t,roll,pitch\n0,{text},0.1\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"line 2: column roll: .* is not a number"):
        read_measurements(path)
    with pytest.raises(GarbledLine, match="non-numeric"):
        parse_line(f"10,{text},0.1", "tilt")


def test_ordinary_number_spellings_still_read(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_text("t,roll,pitch\n0, 1e-1 ,+.1\n1E-2,-0.,1.\n", encoding="utf-8")
    np.testing.assert_allclose(read_measurements(path).z, [[0.1, 0.1], [0.0, 1.0]])


# --- the firmware's own capture --------------------------------------------------------------
FIRMWARE_CAPTURE = (
    "# continuum_imu 1.2.0 mpu9250 imus=1 who_am_i=0x71 accel_range=+-4g "
    "gyro_range=+-500dps rate_hz=100 baud=115200\n"
    "# fields: t_ms,ax,ay,az,gx,gy,gz (ms, m/s^2, rad/s; sensor frames)\n"
    "# calibrating gyro bias: keep the robot still\n"
    "# gyro bias rad/s, IMU 1: 0.00100,-0.00200,0.00050\n"
    "1532,0.123,-0.045,9.811,0.001,0.002,0.003\n"
    "1542,0.125,-0.044,9.810,0.001,0.002,0.003\n"
)


def test_the_firmware_capture_is_read_by_estimate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The firmware's '# fields:' comment is read as the header, as '# format:' and
    '# columns:' are (not 'line 5: no header line; the first line is data')."""
    path = tmp_path / "capture.txt"
    path.write_text(FIRMWARE_CAPTURE)
    table = read_raw_imu(path)
    np.testing.assert_allclose(table.t, [1.532, 1.542])
    np.testing.assert_allclose(table.acc[0], [0.123, -0.045, 9.811])
    out = tmp_path / "e.csv"
    assert main(["estimate", str(path), "-o", str(out), "--method", "ekf"]) == 0
    rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    assert len(rows) == 3  # the column line and the two samples


def test_a_firmware_capture_across_a_millis_wrap_reads_on(tmp_path: Path) -> None:
    """A capture whose ``t_ms`` wraps (``millis()`` after 2^32 ms, 49.7 days) is read as
    ``live`` takes it, the time going on past 2^32 ms: the same times, in the block
    reader and row by row (a comment among the rows), as a capture whose clock goes on;
    a step back that is no wrap, and one stamp that jumps alone into the wrap's last
    minute, are refused."""
    wrap = 2**32
    ms = wrap - 60 + 20 * np.arange(8)  # the wrap between the third and fourth sample
    rows = [f"{m % wrap},0.1,-0.04,9.81,0.001,0.002,0.003" for m in ms]
    head = "# fields: t_ms,ax,ay,az,gx,gy,gz (ms, m/s^2, rad/s; sensor frames)\n"
    for comment in ("", "# a note\n"):
        path = tmp_path / "capture.txt"
        path.write_text(head + "\n".join(rows[:2]) + "\n" + comment + "\n".join(rows[2:]) + "\n")
        np.testing.assert_allclose(read_raw_imu(path).t, ms * 1e-3, rtol=0, atol=1e-9)
    back = [f"{m},0.1,-0.04,9.81,0.001,0.002,0.003" for m in (5000, 5020, 4000, 4020)]
    path.write_text(head + "\n".join(back) + "\n")
    with pytest.raises(InputError, match="line 4: decreasing timestamp"):
        read_raw_imu(path)
    # one t_ms that jumps alone to the wrap's last minute (-1 as a uint32, a corrupted
    # stamp) is no wrap: the row after it is refused, naming the jump
    ahead = [f"{m},0.1,-0.04,9.81,0.001,0.002,0.003" for m in (1000, 1020, wrap - 1, 1060)]
    path.write_text(head + "\n".join(ahead) + "\n")
    with pytest.raises(InputError, match="line 5: decreasing timestamp.*jumps ahead"):
        read_raw_imu(path)


@pytest.mark.parametrize(
    ("comment", "fields"),
    [
        ("# fields: t_ms,ax,ay,az (ms, m/s^2)", ("t_ms", "ax", "ay", "az")),
        ("#fields:t_ms,roll_1,pitch_1", ("t_ms", "roll_1", "pitch_1")),
        ("# format: t_ms,roll,pitch", ("t_ms", "roll", "pitch")),
        ("# columns: t;roll;pitch", ("t", "roll", "pitch")),
        ("# gyro bias rad/s, IMU 1: 0.001,0.002,0.003", None),
        ("# fields:", None),
    ],
)
def test_one_reading_of_the_header_comment_for_files_and_live(
    comment: str, fields: tuple[str, ...] | None
) -> None:
    assert declared_fields(comment) == fields
    assert header_fields(comment) == fields
    assert header_fields(comment.lstrip("#")) is None  # live: only a comment declares


# --- robot files --------------------------------------------------------------------------
ROBOT = "[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n"


def test_deeply_nested_robot_file_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """deep_nesting.toml: one line, exit 2 (not a RecursionError in the TOML parser,
    exit 70)."""
    path = REPRO / "deep_nesting.toml"
    assert main(["check-robot", str(path)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {path}: not a robot file (nested too deeply for TOML's parser)\n"
    )


def test_a_byte_order_mark_is_read_in_robot_files_as_in_csvs(tmp_path: Path) -> None:
    """A BOM is read in robot files (not refused as 'not valid TOML') as in CSVs."""
    path = tmp_path / "r.toml"
    path.write_bytes(b"\xef\xbb\xbf" + ROBOT.encode())
    assert read_robot(path).sections[0].length == 0.2
    csv_path = tmp_path / "m.csv"
    csv_path.write_bytes(b"\xef\xbb\xbf" + HEAD)
    assert len(read_measurements(csv_path).t) == 1


@pytest.mark.parametrize(
    ("entry", "message"),
    [  # the line: the key's where the message names one, else its table's header
        (
            "length = 1e-300",
            "line 2: section 1: length: section length 1e-300 m is under 1 mm, too short",
        ),
        ("length = 0.0005", "line 2: section 1: length: section length 0.0005 m is under 1 mm"),
        (
            "mount_rpy = [1e300, 0, 0]",
            "line 5: imu 1: mount_rpy must be angles in degrees within +-360",
        ),
        (
            "mount_rpy = [0, -361, 0]",
            "line 5: imu 1: mount_rpy must be angles in degrees within +-360",
        ),
    ],
)
def test_absurd_robot_values_are_refused_naming_the_file(
    tmp_path: Path, entry: str, message: str
) -> None:
    text = ROBOT.replace("length = 0.2", entry) if "length" in entry else ROBOT + entry + "\n"
    path = tmp_path / "r.toml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        read_robot(path)
    assert str(info.value).startswith(f"{path}: {message}")


def test_library_robot_values_have_the_same_limits() -> None:
    with pytest.raises(UserError, match="under 1 mm"):
        Section(1e-300)
    with pytest.raises(UserError, match=r"within \+-360"):
        ImuPlacement(0, 1.0, (1e300, 0.0, 0.0))
    assert ImuPlacement(0, 1.0, (np.float64(90.0), 0, -360)).mount_rpy[0] == 90.0


def test_an_imu_at_the_very_base_is_not_called_observable(tmp_path: Path) -> None:
    """at = 1e-300: the IMU does not move with the bend, and check-robot does not call
    it observable (the singular values' ratio is 1 when all are 1e-300)."""
    robot = Robot((Section(0.2),), (ImuPlacement(0, 1e-300),))
    report = observability_report(robot, samples=20)
    assert report.tilt.full_rank_fraction == 0.0 and verdict(report).startswith("NOT")
    assert shape_rank(robot) == 0
    well = Robot((Section(0.2),), (ImuPlacement(0, 0.05),))  # 1 cm up: it sees the bend
    assert observability_report(well, samples=20).tilt.full_rank_fraction == 1.0
    assert shape_rank(well) == 2


# --- one line and exit 2, never exit 70 or a usage dump ------------------------------------
@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        ("--horizon", "3.5", "--horizon '3.5': expected a whole number"),
        ("--noise-deg", "two", "--noise-deg 'two': expected a number"),
        ("--method", "ekff", "--method 'ekff': expected one of mhe, ekf, ukf; did you mean ekf?"),
        ("--method", "EKF", "--method 'EKF': expected one of mhe, ekf, ukf; did you mean ekf?"),
        ("--method", "Mhe", "--method 'Mhe': expected one of mhe, ekf, ukf; did you mean mhe?"),
        ("--imu-model", "gyro", "--imu-model 'gyro': expected one of tilt, direct ("),
    ],
)
def test_an_option_of_the_wrong_type_is_one_line_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str, expected: str
) -> None:
    """One line naming the option and what it expects, not argparse's 22-line usage
    then the error."""
    out = tmp_path / "e.csv"
    with pytest.raises(SystemExit) as exit_:
        main(["estimate", str(REPRO / "gimbal_flip.csv"), "-o", str(out), option, value])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"continuum-mhe estimate: error: {expected}"), err
    assert err.endswith("(continuum-mhe estimate --help lists the options)\n")


def test_a_misspelt_command_is_one_line_with_the_closest(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """'estimat': one line naming the closest command (did you mean estimate?), not
    argparse's choices alone."""
    with pytest.raises(SystemExit) as exit_:
        main(["estimat", "x.csv"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1, err
    assert err.startswith("continuum-mhe: error: 'estimat' is not a command: expected one of ")
    assert "; did you mean estimate? (continuum-mhe --help lists the options)" in err


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_a_vanishing_noise_is_one_line_not_a_singular_matrix(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], method: str
) -> None:
    """--noise-deg 1e-300: one line naming the smallest noise the estimators take, exit
    2 (not 'LinAlgError: Singular matrix', exit 70)."""
    out = tmp_path / "e.csv"
    argv = ["estimate", str(REPRO / "gimbal_flip.csv"), "-o", str(out), "--method", method]
    line = _one_line_error(capsys, main([*argv, "--noise-deg", "1e-300"]), out)
    assert line.startswith(
        "continuum-mhe: error: --noise-deg 1e-300: below the smallest measurement noise the "
        "estimators take, 5.7e-05 deg"
    )
    with pytest.raises(UserError, match="measurement_std 1e-300 rad is below 1e-06 rad"):
        NoiseSettings(measurement_std=1e-300)


@pytest.mark.parametrize("name", ["initial_bend_std", "initial_rate_std"])
def test_a_vanishing_start_prior_is_refused_not_every_row_without_an_estimate(name: str) -> None:
    """A start prior of 1e-300 (its variance underflows to 0, which would give the MHE and
    the UKF no estimate on any row of paper3d, without a word) is refused naming the
    setting. 1e-9, the smallest taken, still estimates every row."""
    rec = simulate("paper3d", duration=2, seed=0)
    with pytest.raises(UserError, match=rf"^{name} 1e-300 is below 1e-09: a start held"):
        NoiseSettings(**{name: 1e-300})
    f = make_formulation("bend", noise=NoiseSettings(**{name: 1e-9}))
    for method in ("mhe", "ukf", "ekf"):
        assert "no-estimate" not in set(make_estimator(method, f).run(rec.t, rec.z).statuses())


def test_estimate_from_a_closed_standard_input_is_one_line(tmp_path: Path) -> None:
    """`estimate - <&-`: one line saying standard input is closed, exit 2 (not an
    AttributeError, exit 70)."""
    out = tmp_path / "e.csv"
    # the shell closes the standard input (a preexec_fn, run between fork and exec, may
    # block on a lock another thread of the test's process held)
    cmd = [sys.executable, "-m", "continuum_mhe.cli", "estimate", "-", "-o", str(out)]
    proc = subprocess.run(
        ["sh", "-c", 'exec "$0" "$@" <&-', *cmd], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == (
        "continuum-mhe: error: -: standard input is closed; pipe the CSV in or name a file\n"
    )
    assert not out.exists()


@pytest.mark.parametrize("source", ["good", "missing"])
def test_estimate_with_stderr_closed_keeps_its_status_and_stdout(
    tmp_path: Path, source: str
) -> None:
    """`estimate ... 2>&-`: the run's status as with stderr open (0, or 2 for a missing
    file, not 70), and its messages do not go into standard output."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.12\n0.1,0.11,0.12\n")
    out = tmp_path / "e.csv"
    name = str(meas) if source == "good" else str(tmp_path / "missing.csv")
    for cli in (["-m", "continuum_mhe"], ["-m", "continuum_mhe.cli"]):
        cmd = [sys.executable, *cli, "estimate", name, "-o", str(out), "--overwrite"]
        proc = subprocess.run(
            ["sh", "-c", 'exec "$0" "$@" 2>&-', *cmd], capture_output=True, text=True, timeout=300
        )
        assert proc.returncode == (0 if source == "good" else 2)
        assert proc.stdout == ""
        assert out.exists() == (source == "good")


def test_a_huge_horizon_is_a_user_error_in_the_library() -> None:
    """horizon=10**9 is a UserError naming the range (not CasADi's std::bad_alloc)."""
    for horizon in (10**9, 1001, 2.5, True):
        with pytest.raises(UserError, match="horizon must be an integer from 2 to 1000"):
            MHESettings(horizon=horizon)
    assert MHESettings(horizon=1000).horizon == 1000


# --- library calls with arguments of the wrong type ---------------------------------------
def _bend() -> Formulation:
    return make_formulation("bend", RobotSettings())


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: make_formulation("bend", "0.2"), "robot must be a Robot, RobotSettings or None"),
        (lambda: make_formulation("bend", None, 2.0), "noise must be NoiseSettings or None"),
        (lambda: make_estimator("ekf", "bend"), "formulation must be a Formulation"),
        (lambda: make_estimator("mhe", _bend(), {"horizon": 10}), "mhe must be MHESettings"),
        (lambda: make_estimator("ekf", _bend()).step((0.0, [0, 0])), "must be a Measurement"),
        (lambda: Measurement("0.1", np.zeros(2)), "measurement t must be a number, got '0.1'"),
        (lambda: Measurement(0.1, "ab"), "measurement z must be numbers"),
        (lambda: Measurement(0.1, np.array([0.1 + 1j, 0.2])), "measurement z must be real"),
        (
            lambda: make_estimator("ekf", _bend()).run(np.zeros(2), np.ones((2, 2)) * 1j),
            "arrays of real numbers",
        ),  # fmt: skip
        (lambda: make_estimator("ekf", _bend()).run("abc", "def"), "arrays of numbers"),
        (lambda: make_estimator("ekf", _bend()).run(None, None), "z is None: give the readings"),
        (lambda: simulate("paper3d", dt="0.05"), "dt must be a number, got '0.05'"),
        (lambda: simulate("paper3d", noise_deg="2"), "noise_deg must be a number"),
        (lambda: read_measurements(5), "path must be a file name"),  # type: ignore[arg-type]
        (lambda: read_robot(None), "path must be a file name"),  # type: ignore[arg-type]
        (lambda: Robot(Section(0.2), ()), "Robot sections must be a sequence of Section"),
        (lambda: Robot((Section(0.2),), ("imu",)), "Robot imus item must be ImuPlacement"),
        (lambda: ImuPlacement(0, 1.0, 5), "mount_rpy must be three angles"),  # type: ignore
    ],
)
def test_wrong_argument_types_raise_the_projects_user_error(call: Any, message: str) -> None:
    """Each is the project's one-line UserError, not a plain TypeError, ValueError or
    AttributeError."""
    with pytest.raises(UserError) as info:
        call()
    assert message in str(info.value) and "\n" not in str(info.value)


def test_a_robust_loss_for_a_filter_is_refused_and_the_window_settings_are_the_mhes() -> None:
    """``mhe`` settings describe the MHE's window: the EKF and the UKF take them without
    using them (one settings object for a loop over the methods: the same estimates as
    without), and refuse a robust loss, which they cannot give (a ValueError naming what
    to pass instead), rather than give an l2 estimate in its place."""
    f = _bend()
    rec = simulate("paper3d", duration=1.0, seed=0)
    for method in ("ekf", "ukf"):
        for loss in ("huber", "cauchy", "welsch"):
            with pytest.raises(ValueError, match=rf"loss='{loss}' .*the {method} keeps the l2"):
                make_estimator(method, f, MHESettings(loss=loss))  # type: ignore[arg-type]
        shared = make_estimator(method, f, MHESettings(horizon=10)).run(rec.t, rec.z)  # type: ignore[arg-type]
        alone = make_estimator(method, f).run(rec.t, rec.z)  # type: ignore[arg-type]
        np.testing.assert_array_equal(shared.output, alone.output)
    robust = make_estimator("mhe", f, MHESettings(horizon=10, loss="huber"))
    assert robust.flags_outliers


# --- messages that name the right cause ------------------------------------------------------
def test_an_infinite_reading_is_not_called_degrees_nor_a_dropout() -> None:
    """step() with roll = inf names an infinite value, not an angle out of range (which
    45 gets, as degrees); so does run() with an infinite tension of a tendon robot
    (taken as a dropout, it would leave the next second uncertain)."""
    est = make_estimator("ekf", _bend())
    with pytest.raises(UserError, match=r"roll=inf: an infinite value; a reading that"):
        est.step(Measurement(0.0, np.array([np.inf, 0.1])))
    with pytest.raises(UserError, match=r"beyond pi, out of range: degrees\?"):
        est.step(Measurement(0.0, np.array([45.0, 0.1])))
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.registry import make_formulation

    tendon = make_formulation("tendon", read_robot("tendon-two-section"))
    z = np.zeros((3, tendon.nz))
    z[:, tendon.measurement_names.index("tension_2")] = [0.1, np.inf, 0.1]
    with pytest.raises(UserError, match=r"t=0\.02 s: tension_2=inf: an infinite value"):
        make_estimator("ekf", tendon).run(np.array([0.0, 0.02, 0.04]), z)
    z[1, tendon.measurement_names.index("tension_2")] = -np.inf  # infinite, not negative
    with pytest.raises(UserError, match=r"t=0\.02 s: tension_2=-inf: an infinite value"):
        make_estimator("ekf", tendon).run(np.array([0.0, 0.02, 0.04]), z)


def test_a_robust_loss_that_rejects_every_sample_is_not_called_dropouts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """When the robust loss rejects every sample, none a dropout, 'no sample gave an
    estimate' names the loss and the fix, not 'every sample is a dropout' (which
    dropouts get)."""
    from continuum_mhe.estimators.sensor_health import STATUSES, Batch, Estimator

    def rejected(
        self: Estimator, t: np.ndarray, z: np.ndarray, *args: object, **kwargs: object
    ) -> Batch:
        n, ny = len(t), self.formulation.ny
        return Batch(
            status=np.full(n, STATUSES.index(Status.NO_ESTIMATE), dtype=np.int32),
            solve_ms=np.zeros(n),
            outlier=np.ones(n, dtype=np.bool_),
            frozen=np.zeros(n, dtype=np.bool_),
            output=np.full((n, ny), np.nan),
            output_std=np.full((n, ny), np.nan),
        )

    monkeypatch.setattr(Estimator, "continue_run", rejected)
    out = tmp_path / "e.csv"
    path = REPRO / "gimbal_flip.csv"
    argv = ["estimate", str(path), "-o", str(out), "--solver", "ipopt", "--loss", "huber"]
    assert _one_line_error(capsys, main(argv), out).endswith(
        f"{path}: no sample gave an estimate (2 samples; the robust loss rejected 2 sample(s) "
        "as outliers (--loss huber; a larger --loss-scale, or --loss l2)); nothing written"
    )
    path = tmp_path / "dropouts.csv"
    path.write_text("t,roll,pitch\n0,nan,nan\n0.1,,\n")
    argv = ["estimate", str(path), "-o", str(out), "--method", "ekf", "--skip-bad"]
    assert "every sample is a dropout" in _one_line_error(capsys, main(argv), out)


def test_a_huge_robot_file_value_is_cut_in_the_message(tmp_path: Path) -> None:
    path = tmp_path / "r.toml"
    path.write_text(ROBOT.replace("0.2", "[" + ", ".join(["1"] * 5000) + "]"))
    with pytest.raises(InputError) as info:
        read_robot(path)
    assert str(info.value).startswith(
        f"{path}: line 2: section 1: length: expected a finite number"
    )
    assert len(str(info.value)) < 200 + len(str(path))


def test_a_signal_during_the_shutdown_after_a_command_keeps_its_status(tmp_path: Path) -> None:
    """SIGTERM while the interpreter shuts down after a complete command does not kill
    it (status -15): the status stays 0, the output complete. An exit handler sends it
    here, at that very moment."""
    script = tmp_path / "late_signal.py"
    script.write_text(
        "import atexit, os, signal, sys, time\n"
        f"sys.argv = ['continuum-mhe', 'simulate', 'paper3d', '-o', {str(tmp_path / 's.csv')!r},"
        " '--duration', '1']\n"
        "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGTERM), time.sleep(0.2)))\n"
        "from continuum_mhe.cli.entry import main\n"
        "sys.exit(main())\n"
    )
    proc = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, (proc.returncode, proc.stderr)
    from continuum_mhe.io.csv_files import read_measurements

    written = read_measurements(tmp_path / "s.csv")  # complete: every sample to t = 1 s
    assert written.t[0] == 0.0 and written.t[-1] == pytest.approx(1.0) and len(written.t) == 21


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('# mine\nmounting = "up"\n' + ROBOT, 'line 2: mounting: must be one of z-up, z-down'),
        (ROBOT + "[[section]]\n# the tip\ntheta_max = 3.0\n",
         "line 5: section 2: missing key 'length'"),
        (ROBOT.replace("length = 0.2", "length = 0.2\nlenght = 0.1"),
         "line 3: section 1: unknown key 'lenght' (length?) (allowed: disks, length, "
         "theta_max)"),
        (ROBOT + "[[imu]]\nsection = 1\nmount_rpy = [1, 2]\n", "line 7: imu 2: mount_rpy must be"),
        (ROBOT + "[backbone]\nradius = 0.0007\n", "line 5: backbone: missing key"),
        ('mounting = "z-up"\nmountin = "z-down"\n' + ROBOT,
         "line 2: top level: unknown key 'mountin'"),
        (ROBOT + "\n[[imus]]\nsection = 1\n", "line 6: top level: unknown key 'imus' (imu?)"),
        (ROBOT + "[extra.part]\nx = 1\n", "line 5: top level: unknown key 'extra'"),
        (ROBOT + "[[section]]\n\nlength = -0.14\n", "line 7: section 2: length: section "
         "length must be positive, got -0.14 m"),
        (ROBOT.replace("length = 0.2", "length = 0.2\ntheta_max = 4"), "line 3: section 1: "
         "theta_max must lie in [0.01, pi) rad"),
        (ROBOT.replace("length = 0.2", "length = 0.2\ndisks = -1"), "line 3: section 1: "
         "disks must be a whole number"),
        (ROBOT.replace("length = 0.2", "length = 2000-01-01"), "line 2: section 1: length: "
         "expected a finite number, got 2000-01-01 (a TOML date or time)"),
    ],
)  # fmt: skip
def test_a_robot_file_problem_names_its_line(tmp_path: Path, text: str, message: str) -> None:
    """A robot file's problem names its line, as every other input's does: the key's
    line where the message names a key, else its table's header."""
    path = tmp_path / "r.toml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        read_robot(path)
    assert str(info.value).startswith(f"{path}: {message}"), str(info.value)


def test_library_mistakes_are_one_line_user_errors() -> None:
    """Mistakes from a library user's trial are one-line UserErrors: an unknown
    formulation option (not Python's TypeError), a robot name for simulate_robot (not an
    AttributeError nine frames deep), and freeze=0 (the command line's "never"), which
    says that None means never."""
    from continuum_mhe import make_formulation, simulate_robot
    from continuum_mhe.errors import UserError
    from continuum_mhe.settings import RecoverySettings

    with pytest.raises(UserError, match="the bend formulation has no option 'gyro_std'"):
        make_formulation("bend", gyro_std=0.1)
    with pytest.raises(UserError, match="no option 'gyro_stdd' \\(its options: .*gyro_std"):
        make_formulation("direct", gyro_stdd=0.1)
    with pytest.raises(UserError, match="robot must be a Robot \\(read_robot"):
        simulate_robot("s-curve", "two-section")  # type: ignore[arg-type]
    with pytest.raises(UserError, match="freeze must be positive, or None for never"):
        RecoverySettings(freeze=0)
    # numpy's scalars are numbers; a string, a bool or None is a one-line error naming
    # the field (not a TypeError from math)
    from continuum_mhe.settings import MHESettings, NoiseSettings, RobotSettings

    assert MHESettings(horizon=np.int64(12)).horizon == 12
    assert RecoverySettings(gap_reset=np.float32(1.0)).gap_reset == 1.0
    assert RobotSettings(length=np.float32(0.2)).length == pytest.approx(0.2)
    robot = make_formulation("bend", RobotSettings(length=np.float32(0.2))).robot
    assert robot.length == pytest.approx(0.2)  # the model's sections take it too
    assert simulate("paper3d", duration=0.2, length=np.float32(0.2)).length == pytest.approx(0.2)
    mistakes = [
        (lambda: NoiseSettings(measurement_std=2.0), r"beyond 90 degrees: degrees\? it is in "),
        (lambda: NoiseSettings(reading_bias_std=1.7), r"^reading_bias_std 1.7 rad .* degrees\?"),
        (lambda: NoiseSettings(model_error_std=4.0), r"^model_error_std 4.0 rad .* degrees\?"),
        (lambda: simulate("paper3d", length=200.0), "millimetres"),
        # refused where it is made, as the settings promise, not later in the model
        (lambda: RobotSettings(length=200.0), "section length 200.0 m is over 5.0 m"),
        (lambda: MHESettings(paper_start="yes"), "paper_start must be True"),
        (lambda: MHESettings(max_iter=True), "max_iter must be an integer from 1 to"),
        (lambda: NoiseSettings(reading_bias_std="0.1"), "reading_bias_std must"),
        (lambda: NoiseSettings(model_error_std=None), "model_error_std must"),
    ]
    for make, why in mistakes:
        with pytest.raises(UserError, match=why):
            make()


def test_run_says_when_t_looks_like_milliseconds() -> None:
    """Estimator.run with t in milliseconds (each step a gap of 50 s, a restart at
    every sample) warns, as the CSV readers do."""
    from continuum_mhe import make_estimator, make_formulation, simulate
    from continuum_mhe.io.csv_files import UnitWarning

    rec = simulate("paper3d", duration=2.0)
    ekf = make_estimator("ekf", make_formulation("bend"))
    with pytest.warns(UnitWarning, match="median of 50 s per sample; t must be in seconds"):
        ekf.run(rec.t * 1000.0, rec.z)


def test_step_and_continue_run_say_when_t_looks_like_milliseconds() -> None:
    """Samples handed over one at a time (step) or a block at a time (continue_run) with
    t in milliseconds warn once, after the first steps, as run does; a reset warns
    again for the next recording; times in seconds do not warn; a recording run warned
    of is not warned of again as it continues; times handed over again after a stop
    count once."""
    import warnings

    from continuum_mhe import Measurement, make_estimator, make_formulation, simulate
    from continuum_mhe.io.csv_files import UnitWarning

    rec = simulate("paper3d", duration=1.0)
    ekf = make_estimator("ekf", make_formulation("bend"))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        for t, z in zip(rec.t * 1000.0, rec.z):
            ekf.step(Measurement(float(t), z))
        ekf.reset()
        ekf.continue_run(rec.t[:2] * 1000.0, rec.z[:2])  # one step: not judged yet
        ekf.continue_run(rec.t[2:] * 1000.0, rec.z[2:])
        ekf.reset()
        for t, z in zip(rec.t, rec.z):
            ekf.step(Measurement(float(t), z))
        ekf.continue_run(rec.t + rec.t[-1] + 0.05, rec.z)
        ekf.run(rec.t * 1000.0, rec.z)  # run warns of the whole recording, once:
        ekf.continue_run(rec.t[-1] * 1000.0 + rec.t[1:] * 1000.0, rec.z[1:])  # not again
        ekf.reset()  # samples handed over again after a stop count once
        for _ in range(4):
            stopped = ekf.continue_run(rec.t[:1] * 1000.0, rec.z[:1], should_stop=lambda: True)
            assert len(stopped.status) == 0
        ekf.continue_run(rec.t[:5] * 1000.0, rec.z[:5])
    units = [str(w.message) for w in seen if issubclass(w.category, UnitWarning)]
    assert [u[:52] for u in units] == [
        "step: t advances by a median of 50 s per sample over",
        "continue_run: t advances by a median of 50 s per sam",
        "run: t advances by a median of 50 s per sample; t mu",
        "continue_run: t advances by a median of 50 s per sam",
    ]
    # each says what milliseconds read as seconds do: every step a gap that restarts
    gap = "(milliseconds? every step longer than the gap reset restarts the estimate)"
    assert all(u.endswith(gap) for u in units), units
    assert all(w.filename == __file__ for w in seen if issubclass(w.category, UnitWarning))


def test_run_on_a_recording_without_a_reading_warns_that_nothing_was_estimated() -> None:
    """Every reading NaN (each a dropout): ``run`` returns a series of ``no-estimate``
    rows, and says so in a warning (not nothing, which would let an empty result read
    as a quiet one). One sample with readings gives an estimate and no warning."""
    from continuum_mhe.io.csv_files import DropoutWarning

    rec = simulate("straight", seed=1, duration=2.0)
    z = np.full_like(rec.z, np.nan)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.warns(DropoutWarning, match=r"run: none of the \d+ samples gave an estimate"):
        series = est.run(rec.t, z)
    assert set(series.status) == {"no-estimate"}
    z[5] = rec.z[5]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DropoutWarning)
        series = est.run(rec.t, z)
    assert "no-estimate" in set(series.status) and len(set(series.status)) > 1


def test_paper_start_with_a_horizon_beyond_the_recording_is_named_as_the_cause() -> None:
    """``paper_start`` makes no estimate until its window is full: on a recording shorter
    than the horizon the warning that nothing was estimated names that, not the
    diagnostics (whose counts are all zero there)."""
    from continuum_mhe.io.csv_files import DropoutWarning

    rec = simulate("paper3d", seed=1, duration=2.0)
    est = make_estimator(
        "mhe", make_formulation("bend"), MHESettings(horizon=100, paper_start=True)
    )
    with pytest.warns(DropoutWarning, match=r"paper_start makes no estimate before the window's "
                      r"horizon of 100 samples is full"):  # fmt: skip
        series = est.run(rec.t, rec.z)
    assert set(series.status) == {"no-estimate"}


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: simulate("straight", noise_std=(np.nan, 0.01)), "noise_std must be two finite"),
        (lambda: simulate("straight", noise_std=(-0.01, 0.01)), "noise_std must be two finite"),
        (lambda: simulate("straight", noise_std=(0.01,) * 3), "noise_std must be two finite"),
        (lambda: simulate("straight", duration=1, dt=50), "dt in milliseconds?"),
        (lambda: _raw(seed=-1), "seed must be a non-negative integer, got -1"),
        (lambda: _raw(robot=Robot((Section(0.2),), (ImuPlacement(0),))), "of another robot"),
        (
            lambda: _raw(
                robot=Robot((Section(0.1), Section(0.1)), (ImuPlacement(0), ImuPlacement(1)))
            ),
            "of another robot",
        ),  # fmt: skip
        (lambda: _ekf_run(progress=True), "progress must be a callable"),
        (lambda: _ekf_continue(starts=[0, 50]), "starts needs block"),
    ],
    ids=[
        "nan-std",
        "negative-std",
        "three-stds",
        "dt-in-ms",
        "raw-seed",
        "raw-one-section",
        "raw-other-lengths",
        "progress-true",
        "starts-without-block",
    ],  # fmt: skip
)
def test_the_librarys_simulation_and_run_arguments_are_checked(call: Any, message: str) -> None:
    """Arguments a researcher gets wrong are one UserError naming them, not numpy's
    error from deep inside or a recording silently made wrong (NaN readings, one
    sample)."""
    with pytest.raises(UserError, match=message.replace("?", r"\?")):
        call()


def _raw(robot: Robot | None = None, seed: int = 0) -> Any:
    from continuum_mhe.simulation.raw_readings import raw_readings
    from continuum_mhe.simulation.scenarios import simulate_robot

    two = read_robot("two-section")
    return raw_readings(simulate_robot("spatial", two, duration=1.0), robot or two, seed=seed)


def _ekf_run(progress: Any) -> Any:
    rec = simulate("paper3d", duration=1.0)
    return make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z, progress=progress)


def _ekf_continue(starts: list[int]) -> Any:
    rec = simulate("paper3d", duration=5.0)
    return make_estimator("ekf", make_formulation("bend")).continue_run(rec.t, rec.z, starts=starts)


def test_series_rows_refuses_what_selects_no_rows_of_it() -> None:
    """``EstimateSeries.rows`` takes a slice, a mask of its length or indices (negative
    from the end, none at all): a mask of another length, an index outside the series
    (a bare numpy IndexError) or indices that are not integers are one UserError."""
    rec = simulate("paper3d", duration=1.0, seed=0)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    np.testing.assert_array_equal(s.rows([0, 2, -1]).t, rec.t[[0, 2, -1]])
    assert len(s.rows([]).t) == 0 and len(s.rows(s.t >= 0.5).t) == 11
    for which, said in (
        ([21], "row index 21 is outside the series of 21 samples"),
        ([-22], "row index -22 is outside the series of 21 samples"),
        ([0.5], "rows takes a slice, a boolean mask or integer indices"),
        (np.ones(3, dtype=bool), "a row mask has shape (3,), expected (21,)"),
    ):
        with pytest.raises(UserError) as refused:
            s.rows(which)
        assert str(refused.value).startswith(said), refused.value


def test_an_impossible_reading_of_one_of_several_imus_is_refused_or_said(tmp_path, capsys):
    """An acceleration of 1e6 m/s^2 in IMU 1's columns of a two-IMU recording is refused
    in one line naming its line and IMU, nothing written, as for one IMU and as a NaN
    there (not read as a silent dropout, the run exit 0 with every row ``ok``);
    ``--skip-bad`` reads it as that IMU's dropout and says which line and why."""
    from continuum_mhe.cli import main

    data = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    lines = (data / "spatial-tendon_raw.csv").read_text().splitlines()[:21]
    cells = lines[5].split(",")
    cells[1] = "1e6"
    lines[5] = ",".join(cells)
    meas = tmp_path / "m.csv"
    meas.write_text("\n".join(lines) + "\n")
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", "two-section", "-o", str(out)]
    assert main(argv) == 2 and not out.exists()
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(
        f"continuum-mhe: error: {meas}: line 6: IMU 1: a reading beyond any IMU's range (|a| 1e+06"
    ), err
    assert main([*argv, "--skip-bad"]) == 0
    err = capsys.readouterr().err
    assert "(missing: IMU 1 in 1 sample)" in err
    assert "first: line 6: IMU 1: a reading beyond any IMU's range" in err
