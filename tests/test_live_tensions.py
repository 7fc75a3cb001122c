"""``live`` on a tendon robot: its tensions from the serial line (after the IMUs'
fields) or from a tensions file, against ``estimate`` on the same samples (the first
samples of the shipped ``unloaded`` recording); bad tensions skipped and counted; the
recording replayed with its tensions. The tendon EKF's first step reads the model's
tape (tens of seconds): every estimate here comes from one module fixture's runs."""

from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import assert_ok_after_the_start

from continuum_mhe.cli import main
from continuum_mhe.cli.config import recorded_tensions
from continuum_mhe.errors import InputError
from continuum_mhe.estimators import Estimate, Measurement, make_estimator
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import SerialInput, open_input, serial_input
from continuum_mhe.io.robot_file import read_robot, shipped_robots
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.tension_derivatives import central_differences
from continuum_mhe.io.tensions import TensionStream, read_tensions
from continuum_mhe.live.run import run_live
from continuum_mhe.live.session import LiveSession, LiveSettings
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings, NoiseSettings
from continuum_mhe.stream.protocol import GarbledLine, field_count_hint, parse_line, value_columns
from continuum_mhe.stream.recording import RowFile

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
ROBOT = "tendon-two-section"
N = 20  # samples of the recording used


def _rows(path: Path, n: int) -> tuple[list[str], list[list[str]]]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), [ln.split(",") for ln in lines[1 : n + 1]]


def _first_samples(tmp: Path) -> tuple[Path, Path, list[str], list[str]]:
    """The first N samples of ``unloaded`` (raw IMUs, tensions) as files, and as serial
    lines: ``t_ms``, the IMUs' fields as written in the file, then the tensions (and the
    same lines without the tensions)."""
    head, raw = _rows(DATA / "unloaded_raw.csv", N)
    t_head, ten = _rows(DATA / "unloaded_tensions.csv", N)
    assert [r[0] for r in raw] == [r[0] for r in ten]  # the same times
    raw_path, ten_path = tmp / "raw.csv", tmp / "tensions.csv"
    raw_path.write_text("\n".join(",".join(r) for r in [head, *raw]) + "\n")
    ten_path.write_text("\n".join(",".join(r) for r in [t_head, *ten]) + "\n")
    t_ms = [f"{round(float(r[0]) * 1000)}" for r in raw]
    with_tensions = [",".join([t, *r[1:], *s[1:]]) for t, r, s in zip(t_ms, raw, ten)]
    imus_only = [",".join([t, *r[1:]]) for t, r in zip(t_ms, raw)]
    return raw_path, ten_path, with_tensions, imus_only


class _Port:
    """A serial port stand-in: ``data`` in one read, then reads time out."""

    def __init__(self, data: bytes) -> None:
        self.data = bytearray(data)

    @property
    def in_waiting(self) -> int:
        return len(self.data)

    def read(self, n: int) -> bytes:
        if not self.data:
            time.sleep(0.01)
        chunk = bytes(self.data[:n])
        del self.data[:n]
        return chunk

    def close(self) -> None:
        pass


@dataclass
class Runs:
    estimator: Estimator  # the one EKF of every run (reset between them)
    batch: list[Estimate]  # estimate's pipeline on the files
    batch_z: np.ndarray
    line: list[Estimate]  # live, tensions on the line, with bad lines between
    line_session: LiveSession
    recording: Path
    file: list[Estimate]  # live, tensions from the file
    record_z: np.ndarray  # estimate's pipeline on live's recording
    base: Formulation  # the robot's formulation before its tensions


def _live(
    serial: SerialInput,
    estimator: Estimator,
    lines: list[str],
    record: RowFile | None = None,
    duration: float = 0.5,
) -> tuple[LiveSession, list[Estimate], list[str]]:
    """``run_live`` on ``lines`` through a port stand-in, as the command line sets it
    up from ``serial``: the session, its estimates and what it said."""
    said: list[str] = []
    made: list[Estimate] = []
    settings = LiveSettings(port="/dev/ttyTEN", duration=duration)
    s = LiveSession(
        settings, estimator, serial.converters, None, said.append, record, serial.tensions
    )
    s.on_estimate = made.append
    run_live(settings, s, _Port("".join(ln + "\n" for ln in lines).encode()))
    return s, made, said


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Runs:
    tmp = tmp_path_factory.mktemp("tensions")
    raw_path, ten_path, with_tensions, imus_only = _first_samples(tmp)
    base = make_formulation("bend", read_robot(shipped_robots()[ROBOT]), NoiseSettings())
    with open_input(raw_path, InputOptions(tensions=str(ten_path)), base, ROBOT) as stream:
        formulation, samples = stream.formulation, list(stream.samples)
    est = make_estimator("ekf", formulation, MHESettings())
    est.reset()
    batch = [est.step(Measurement(t, z)) for t, z in samples]

    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    assert serial.formulation == formulation and serial.tensions_on_line == 6
    bad = [
        with_tensions[3].rsplit(",", 1)[0] + ",-0.5",  # a negative tension
        with_tensions[3].rsplit(",", 1)[0] + ",nan",  # a non-finite one
        with_tensions[3].rsplit(",", 1)[0],  # one tension short
        with_tensions[3] + ",1.0",  # one too many
    ]
    lines = [*with_tensions[:5], *bad, *with_tensions[5:]]
    recording = tmp / "recorded.csv"
    record = RowFile(recording, ("t", *value_columns("raw", 2, 6)), overwrite=False)
    session, line, _ = _live(serial, est, lines, record)
    record.close()
    with open_input(recording, InputOptions(), base) as stream:
        record_z = np.array([z for _, z in stream.samples])

    by_file = serial_input("/dev/ttyTEN", "raw", InputOptions(tensions=str(ten_path)), base)
    assert by_file.tensions is not None and by_file.tensions_on_line == 0
    _, file, _ = _live(by_file, est, imus_only)
    batch_z = np.array([z for _, z in samples])
    return Runs(est, batch, batch_z, line, session, recording, file, record_z, base)


def _same_estimates(live: list[Estimate], batch: list[Estimate]) -> None:
    assert [e.t for e in live] == [e.t for e in batch]
    assert [e.status for e in live] == [e.status for e in batch]
    for a, b in zip(live, batch):
        assert a.output is not None and b.output is not None
        assert a.output_std is not None and b.output_std is not None
        np.testing.assert_allclose(a.output, b.output, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.output_std, b.output_std, rtol=0, atol=1e-9)


def test_live_with_tensions_on_the_line_gives_estimates_estimate_gives(runs: Runs) -> None:
    assert len(runs.batch) == N
    _same_estimates(runs.line, runs.batch)
    names = [o.name for o in runs.line_session.formulation.outputs]
    for name in ("fx", "fy", "fz", "psi_1", "psi_2"):
        assert name in names
    assert_ok_after_the_start([e.status for e in runs.batch])


def test_bad_tensions_on_the_line_are_skipped_counted_and_said(runs: Runs) -> None:
    c = runs.line_session.counts
    assert (c.samples, c.estimates, c.garbled) == (N, N, 4)
    summary = runs.line_session.summary()
    assert "4 garbled" in summary
    assert "a negative tension" in summary and "a tension: non-finite value" in summary
    assert "expected 19 fields, found 18" in summary and "found 20" in summary


def test_the_recording_keeps_the_tensions_and_replays_to_the_same_measurements(
    runs: Runs,
) -> None:
    header = runs.recording.read_text().splitlines()[0].split(",")
    assert header[-6:] == [f"tension_{i}" for i in range(1, 7)]
    # estimate reads the recording's own tension columns: the same measurements, bit
    # for bit, as from the files, so the same estimates
    np.testing.assert_array_equal(runs.record_z, runs.batch_z)


def test_live_with_a_tensions_file_gives_estimates_estimate_gives(runs: Runs) -> None:
    _same_estimates(runs.file, runs.batch)


def test_the_command_line_live_writes_the_tip_force_and_replays(
    runs: Runs,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``continuum-mhe live --robot tendon-two-section -o --record`` (the port a
    stand-in), then ``estimate`` on the recording: the estimate file's columns come from
    the model (the tip force with its standard deviations), its rows are those of
    ``estimate``'s pipeline, and the replay gives the same file. (The EKF's model
    functions are those the module's runs built: the same formulation.)"""
    with_tensions, _ = _first_samples_lines()
    data = "".join(ln + "\n" for ln in [*with_tensions[:3], "20,1,2", *with_tensions[3:]])
    monkeypatch.setattr("continuum_mhe.cli.live.open_port", lambda *a: _Port(data.encode()))
    est, rec, replay = tmp_path / "est.csv", tmp_path / "rec.csv", tmp_path / "replay.csv"
    argv = ["live", "--port", "/dev/ttyTEN", "--robot", ROBOT, "-o", str(est), "--record",
            str(rec), "--duration", "0.5", "--status-every", "0.001"]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "(t_ms,ax_1," in err and ",gz_2,tension_1,tension_2," in err and "tip force=(" in err
    assert f"{N} samples, {N} estimates; 1 garbled" in err
    assert rec.read_text().splitlines()[0].endswith(",gz_2,tension_1,tension_2,tension_3,"
                                                     "tension_4,tension_5,tension_6")  # fmt: skip
    live = read_state_table(est)
    assert live.names[-3:] == ("fx", "fy", "fz") and live.std is not None
    # its first line names the recording, whose tension columns plot and view draw with
    assert est.read_text().splitlines()[0].endswith(f' live, recorded in {rec.resolve()}"')
    recorded = recorded_tensions(str(est))
    assert recorded is not None and recorded.own_columns and Path(recorded.path) == rec
    batch_out = np.array([e.output for e in runs.batch])
    np.testing.assert_allclose(live.values, batch_out, rtol=1e-9, atol=1e-12)
    assert main(["estimate", str(rec), "--robot", ROBOT, "-o", str(replay)]) == 0
    again = read_state_table(replay)
    np.testing.assert_array_equal(again.t, live.t)
    np.testing.assert_array_equal(again.values, live.values)
    np.testing.assert_array_equal(again.std, live.std)
    assert list(again.status) == list(live.status) == ["uncertain"] + ["ok"] * (N - 1)


def test_lines_without_the_tensions_are_garbled_and_say_how_to_send_them(runs: Runs) -> None:
    """A tendon robot's stream without tensions (and no --inputs): no sample, one line
    naming the cause and the fix, as for any stream of garbled lines."""
    _, imus_only = _first_samples_lines()
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), runs.base)
    with pytest.raises(InputError, match="no valid sample") as err:
        _live(serial, runs.estimator, imus_only[:6])
    assert "a line without the robot's 6 tendon tensions" in str(err.value)
    assert "--inputs TENSIONS.csv" in str(err.value)


def test_a_tensions_file_that_does_not_cover_the_stream_stops_it_before_writing(
    runs: Runs, tmp_path: Path
) -> None:
    with_tensions, imus_only = _first_samples_lines()
    short = tmp_path / "short.csv"
    write_table(short, ["t", *(f"tension_{i}" for i in range(1, 7))], [[1.0, *[0.0] * 6]])
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(tensions=str(short)), runs.base)
    recording = tmp_path / "rec.csv"
    record = RowFile(recording, ("t", *value_columns("raw", 2)), overwrite=False)
    with pytest.raises(InputError) as err:
        _live(serial, runs.estimator, imus_only[:6], record)
    assert str(err.value) == (
        f"{short}: line 2: the tensions cover t = 1 to 1 s, but a sample of /dev/ttyTEN is at "
        "t = 0 s "
        "(the device clock): the tensions must cover the stream"
    )
    assert not recording.exists()  # nothing written


def test_tensions_in_mn_on_the_line_stop_the_session_in_one_line(runs: Runs) -> None:
    """Tensions in mN on the line (each a thousand times the newtons) stop the session
    at the first sample whose tensions would bend a section through turns, as a
    tensions file in mN is refused, not estimated with every row lost and the session
    behind the stream. (The lines from t = 0.14 s: one sample whose tensions in mN
    pass, then t = 0.16 s, the first that does not; the eight samples from t = 0 before
    them, which this check does not need, are left out.)"""
    with_tensions, _ = _first_samples_lines()
    in_mn = []
    for ln in with_tensions[7:20]:
        cells = ln.split(",")
        in_mn.append(",".join([*cells[:-6], *(f"{float(v) * 1000:g}" for v in cells[-6:])]))
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), runs.base)
    with pytest.raises(
        InputError,
        match=r"^/dev/ttyTEN: the tensions on the line: at t = 0.16 s .* "
        r"would bend section 1 through .* full turns .*\(mN or grams\?\)",
    ):
        _live(serial, runs.estimator, in_mn)


def test_a_stream_that_starts_well_into_its_tensions_file_is_said(runs: Runs) -> None:
    """A device clock that starts 1 s into the tensions file (a file that starts with the
    stream but on another clock: every tension from another time) is said at the first
    sample; one that starts with the file is not. (Six samples each: the check is at
    the first.)"""
    _, imus_only = _first_samples_lines()
    imus_only = imus_only[:6]
    late = [f"{int(ln.split(',', 1)[0]) + 1000},{ln.split(',', 1)[1]}" for ln in imus_only]
    options = InputOptions(tensions=str(DATA / "unloaded_tensions.csv"))
    for lines, warned in ((late, True), (imus_only, False)):
        serial = serial_input("/dev/ttyTEN", "raw", options, runs.base)
        _, made, said = _live(serial, runs.estimator, lines)
        assert made
        starts = [m for m in said if m.startswith("the stream starts at t = ")]
        if warned:
            assert len(starts) == 1 and "1 s after the first row of" in starts[0], said
        else:
            assert not starts, said


def _first_samples_lines() -> tuple[list[str], list[str]]:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        _, _, with_tensions, imus_only = _first_samples(Path(tmp))
    return with_tensions, imus_only


# --- the parts, without an estimator -----------------------------------------------------------
def test_parse_line_reads_the_tensions_after_the_imus() -> None:
    s = parse_line("20,0.1,-0.2,0.3,0.4,1.5,0,2.25", "tilt", n_imus=2, n_tensions=3)
    assert s is not None
    np.testing.assert_array_equal(s.values, [0.1, -0.2, 0.3, 0.4])
    np.testing.assert_array_equal(s.tensions, [1.5, 0.0, 2.25])
    assert parse_line("20,0.1,-0.2", "tilt").tensions.shape == (0,)  # type: ignore[union-attr]
    for line, why in [
        ("20,0.1,-0.2,1.5,-0.05", "a negative tension"),
        ("20,0.1,-0.2,1.5,inf", "a tension: non-finite value"),
        ("20,0.1,-0.2,1.5,x", "a tension: non-numeric field"),
        ("20,0.1,-0.2,1.5", "expected 5 fields, found 4"),
        ("20,0.1,-0.2,1.5,2.0,", r"found 6 \(the last one empty: a separator at the end"),
    ]:
        with pytest.raises(GarbledLine, match=why):
            parse_line(line, "tilt", n_tensions=2)


def test_field_count_hint_names_the_missing_tensions() -> None:
    imus_only = "20," + ",".join(["0.1"] * 12)
    assert "a line without the robot's 6 tendon tensions" in field_count_hint(
        imus_only, "raw", 2, n_tensions=6
    )
    # a line with its tensions, in --format raw, read as tilt: the format is named
    tilt_read = "20," + ",".join(["0.1"] * 12) + ",1,1,1,1,1,1"
    assert "--format raw" in field_count_hint(tilt_read, "tilt", 2, n_tensions=6)
    assert field_count_hint(tilt_read, "raw", 2, n_tensions=6) == ""
    # the tensions on the line where --inputs gives them too (not 3 IMUs)
    said = field_count_hint(tilt_read, "raw", 2, file_tensions=6)
    assert said.startswith(
        ": a line of the IMUs and the robot's 6 tendon tensions, which "
        "--inputs gives too; leave --inputs out"
    )


def test_central_differences_are_numpys_gradient() -> None:
    """The written-out formulas against numpy's gradient (its uneven-step formulas
    inside, first order at the ends), on uneven and even steps."""
    rng = np.random.default_rng(3)
    steps = (rng.uniform(0.005, 0.03, 40), np.full(40, 0.25))
    for t in (np.cumsum(h) for h in steps):
        v = rng.normal(size=(40, 3))
        np.testing.assert_allclose(
            central_differences(t, v), np.gradient(v, t, axis=0), rtol=1e-12, atol=1e-9
        )
    assert not central_differences(np.array([0.0]), np.ones((1, 2))).any()  # one row: zero


@pytest.mark.parametrize("n", [1, 2, 3, 4, 9])
def test_a_stream_of_tensions_has_the_derivatives_of_the_same_rows_in_a_file(
    tmp_path: Path, n: int
) -> None:
    """Bit for bit as a recording's own tension columns are read, so that a recording
    replays to the same estimates; each sample's once the two after it are in. (A
    tensions file of its own whose rows scatter, as these do, is smoothed instead:
    tests/test_tension_noise.py.)"""
    rng = np.random.default_rng(n)
    t = np.cumsum(rng.uniform(0.01, 0.03, n))
    v = rng.uniform(0.0, 3.0, (n, 2))
    path = tmp_path / "t.csv"
    write_table(path, ["t", "tension_1", "tension_2"], np.column_stack([t, v]).tolist())
    file = read_tensions(path, 2, other_columns=True)
    stream = TensionStream()
    got = []
    for i in range(n):
        ready = stream.push(float(file.t[i]), file.values[i])
        assert len(ready) == (1 if i >= 2 else 0) and stream.waiting == min(i + 1, 2)
        got += ready
    got += stream.end()
    assert [g.t for g in got] == file.t.tolist()
    np.testing.assert_array_equal([g.values for g in got], file.values)
    np.testing.assert_array_equal([g.rates for g in got], file.rates)
    np.testing.assert_array_equal([g.accelerations for g in got], file.accelerations)


@pytest.mark.parametrize("n_tendons", [None, 2])
def test_a_stream_refuses_a_sample_of_another_count_of_tensions(
    n_tendons: int | None,
) -> None:
    """A sample with another count of tensions than the robot's (or, without it, the
    first sample's) is one UserError naming the stream and the time, and is not added:
    the next good sample continues the stream. A NaN is a missing tension, taken."""
    from continuum_mhe.errors import UserError

    stream = TensionStream("port", n_tendons=n_tendons)
    assert stream.push(0.0, np.array([1.0, 2.0])) == []
    with pytest.raises(UserError, match=r"^port: a sample at t = 0.1 s has tensions of shape"):
        stream.push(0.1, np.array([1.0, 2.0, 3.0]))
    with pytest.raises(UserError, match=r"the robot has 2 tendons: one tension each"):
        stream.push(0.1, np.array([[1.0, 2.0]]))
    assert stream.waiting == 1
    assert stream.push(0.1, np.array([1.0, np.nan])) == []
    ready = stream.push(0.2, np.array([1.0, 2.0]))
    assert [r.t for r in ready] == [0.0] and stream.waiting == 2


def test_live_refuses_inputs_for_a_robot_without_tendons_before_the_port(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tensions = tmp_path / "tensions.csv"
    write_table(tensions, ["t", "tension_1"], [[0.0, 1.0]])
    argv = ["live", "--port", str(tmp_path / "none"), "--robot", "two-section",
            "--inputs", str(tensions), "-o", str(tmp_path / "e.csv")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the robot has no [[tendon]]" in err[0] and str(tensions) in err[0]
    assert not (tmp_path / "e.csv").exists()


def test_the_compiled_ekf_builds_no_symbolic_jacobian_of_the_model(runs: Runs) -> None:
    """The runs above (a start, restarts, live's warm-up) evaluate the tendon model's
    Jacobians in the compiled core only: its symbolic measurement Jacobians (over a
    million CasADi instructions) are never built."""
    built = vars(runs.estimator.formulation.functions)
    assert "innovate" not in built and "measure" not in built


def _tensions_in_ms(tmp_path: Path) -> Path:
    """The shipped unloaded tensions with t in milliseconds, the column still named t."""
    header, rows = _rows(DATA / "unloaded_tensions.csv", 401)
    path = tmp_path / "ten_ms.csv"
    write_table(path, header, [[float(r[0]) * 1000, *map(float, r[1:])] for r in rows])
    return path


def test_live_refuses_a_tensions_file_in_milliseconds_before_the_port(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``live --inputs`` cannot compare the file's times with a recording's before it
    runs: rows more than 2 s apart (t in milliseconds read as seconds, which would give
    every sample the tensions of the file's first rows) are refused in one line, before
    the port, nothing written."""
    argv = ["live", "--port", str(tmp_path / "none"), "--robot", ROBOT,
            "--inputs", str(_tensions_in_ms(tmp_path)), "-o", str(tmp_path / "e.csv")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ten_ms.csv: its t steps by a median of 20 s" in err[0]
    assert "name the column t_ms" in err[0] and not (tmp_path / "e.csv").exists()


@pytest.fixture(scope="module")
def short_estimate(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``estimate``'s file of the first N samples of ``unloaded`` (0 to 0.38 s), for
    both commands of the test below (what they check reads only its times)."""
    tmp = tmp_path_factory.mktemp("short_estimate")
    raw_path, ten_path, _, _ = _first_samples(tmp)
    est = tmp / "e.csv"
    assert main(["estimate", str(raw_path), "--robot", ROBOT, "--inputs", str(ten_path),
                 "-o", str(est)]) == 0  # fmt: skip
    return est


@pytest.mark.parametrize("command", ["plot", "view"])
def test_plot_and_view_refuse_a_tensions_file_in_milliseconds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, short_estimate: Path
) -> None:
    """``plot`` and ``view`` check ``--inputs`` against the estimate's times as
    ``estimate`` checks it against the recording's: one line, exit 2, no figure. (The
    estimate: the first 0.38 s of ``unloaded``; the file spans 8000 s, over a hundred
    times that, in steps of 20 s.)"""
    est = short_estimate
    capsys.readouterr()
    out = tmp_path / ("f.png" if command == "plot" else "v.rrd")
    target = ["-o", str(out)] if command == "plot" else ["--save", str(out)]
    argv = [command, str(est), "--robot", ROBOT, "--inputs", str(_tensions_in_ms(tmp_path)),
            *target]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ten_ms.csv: its t spans 8000 s in steps of 20 s" in err[0]
    assert not out.exists()


def test_live_estimates_the_tension_gain_and_says_where_it_ends_far_from_1(
    tmp_path: Path,
) -> None:
    """``live --estimate-tension-gain`` with the tensions on the line given 1.2 times
    those acting (the first 150 samples of ``unloaded``): the session's gains end near
    1 / 1.2, and its summary says they ended far from 1, as ``estimate`` does."""
    head, raw = _rows(DATA / "unloaded_raw.csv", 150)
    _, ten = _rows(DATA / "unloaded_tensions.csv", 150)
    lines = [
        ",".join([f"{round(float(r[0]) * 1000)}", *r[1:], *(f"{1.2 * float(v)!r}" for v in s[1:])])
        for r, s in zip(raw, ten)
    ]
    base = make_formulation("bend", read_robot(shipped_robots()[ROBOT]), NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(estimate_tension_gain=True), base)
    assert serial.formulation.state_names[-2:] == ("tension_gain_1", "tension_gain_2")
    est = make_estimator("ekf", serial.formulation)
    session, made, _ = _live(serial, est, lines)
    assert len(made) == 150
    assert session.gains.gain is not None
    np.testing.assert_allclose(session.gains.gain, 1 / 1.2, atol=0.03)
    assert "; warning: the estimated tension gains ended more than 3 standard" in (
        session.summary()
    )


def test_a_tension_sample_not_later_than_the_last_is_refused_and_left_out() -> None:
    """``TensionStream.push`` with a time that steps back or repeats: a
    ``SampleTimeError``, and the stream's derivatives are those without that sample."""
    from continuum_mhe.errors import SampleTimeError

    values = [np.array([1.0, 2.0]) + 0.1 * k for k in range(6)]
    times = [0.0, 0.02, 0.04, 0.06, 0.08, 0.10]
    clean, glitched = TensionStream("t.csv", 2), TensionStream("t.csv", 2)
    want = [r for t, v in zip(times, values) for r in clean.push(t, v)]
    got = []
    for k, (t, v) in enumerate(zip(times, values)):
        got += glitched.push(t, v)
        if k == 2:
            for bad in (0.03, 0.04):
                with pytest.raises(SampleTimeError, match="not later than the last one"):
                    glitched.push(bad, v + 5.0)
            with pytest.raises(SampleTimeError, match="a sample's time is nan"):
                glitched.push(float("nan"), v + 5.0)
    assert len(got) == len(want) > 0
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a.rates, b.rates)


def test_live_summary_says_drifted_rows_as_estimate_does(tmp_path: Path) -> None:
    """Tensions on the line twice those acting (another unit): the rows are ``drifted``,
    and ``live``'s summary carries ``estimate``'s warning with their count."""
    n = 200
    head, raw = _rows(DATA / "unloaded_raw.csv", n)
    _, ten = _rows(DATA / "unloaded_tensions.csv", n)
    lines = [
        ",".join([f"{round(float(r[0]) * 1000)}", *r[1:], *(f"{2 * float(v):.6g}" for v in s[1:])])
        for r, s in zip(raw, ten)
    ]
    base = make_formulation("bend", read_robot(shipped_robots()[ROBOT]), NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    est = make_estimator("ekf", serial.formulation, MHESettings())
    session, made, _ = _live(serial, est, lines)
    drifted = sum(str(e.status) == "drifted" for e in made)
    assert drifted > 100
    assert f"warning: {drifted} of {len(made)} estimates drifted: the IMUs' error states" in (
        session.summary()
    )


def test_live_summary_says_the_rows_taken_as_free_of_load(tmp_path: Path) -> None:
    """The shipped ``unloaded`` (raw IMUs and tensions on the line): ``live``'s summary
    says how many estimates the free-of-load hypothesis gave, as ``estimate``'s does;
    here most of them."""
    n = 200
    head, raw = _rows(DATA / "unloaded_raw.csv", n)
    _, ten = _rows(DATA / "unloaded_tensions.csv", n)
    lines = [",".join([f"{round(float(r[0]) * 1000)}", *r[1:], *s[1:]]) for r, s in zip(raw, ten)]
    base = make_formulation("bend", read_robot(shipped_robots()[ROBOT]), NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    est = make_estimator("ekf", serial.formulation, MHESettings())
    session, made, _ = _live(serial, est, lines)
    free = est.inference.free_of_load_samples
    assert len(made) == n and free > 0.9 * n
    assert f"; taken as free of load (tip force 0 N) in {free} of the {n} estimates" in (
        session.summary()
    )


def test_one_line_without_its_tensions_says_so_where_the_device_named_its_fields(
    runs: Runs,
) -> None:
    """A device that names its fields (tensions included) and sends one line of the IMUs'
    fields alone: that line is garbled, and what is said names the missing tensions (a
    line cut elsewhere is said as a cut line, without a hint)."""
    with_tensions, imus_only = _first_samples_lines()
    fields = "# fields: t_ms," + ",".join(
        [*(f"{c}_{i}" for i in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz"))]
        + [f"tension_{j}" for j in range(1, 7)]
    )
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), runs.base)
    lines = [fields, *with_tensions[:5], imus_only[5], *with_tensions[6:]]
    session, _, said = _live(serial, runs.estimator, lines)
    garbled = [s for s in said if s.startswith("garbled line skipped")]
    assert len(garbled) == 1 and "a line without the robot's 6 tendon tensions" in garbled[0], said
    assert session.counts.garbled == 1


def test_live_summary_says_inconsistent_rows_as_estimate_does() -> None:
    """A rod that twists about itself, which the constant-curvature model cannot follow
    (the shipped ``spatial-stiff-torsion``, raw IMUs on the line): most rows are
    ``inconsistent``, and ``live``'s summary carries ``estimate``'s warning with their
    count."""
    rod = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    _, raw = _rows(rod / "spatial-stiff-torsion_raw.csv", 400)
    lines = [",".join([f"{round(float(r[0]) * 1000)}", *r[1:]]) for r in raw]
    base = make_formulation("bend", read_robot(shipped_robots()["two-section"]), NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    est = make_estimator("ekf", serial.formulation, MHESettings())
    session, made, _ = _live(serial, est, lines)
    bad = sum(str(e.status) == "inconsistent" for e in made)
    assert bad > 0.25 * len(made) and len(made) == 400
    summary = session.summary()
    assert f"warning: {bad} of {len(made)} estimates ({100 * bad / len(made):.0f} %) are " in (
        summary
    )
    counts = Counter(str(e.status) for e in made)  # and every status, as estimate says them
    shown = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    assert f"; statuses: {shown}" in summary and f"inconsistent: {bad}" in shown


def test_live_summary_says_a_start_under_load_is_not_trusted() -> None:
    """The shipped ``force-08`` from 3 s, under 0.08 N (raw IMUs and tensions on the
    line): the first reading shows a load the start cannot tell from the IMUs' errors;
    no estimate is ``ok`` and ``live``'s summary says why, as ``estimate``'s does."""
    head, raw = _rows(DATA / "force-08_raw.csv", 251)
    _, ten = _rows(DATA / "force-08_tensions.csv", 251)
    lines = [",".join([f"{round(float(r[0]) * 1000)}", *r[1:], *s[1:]])
             for r, s in zip(raw[150:], ten[150:])]  # fmt: skip
    assert float(raw[150][0]) == 3.0
    base = make_formulation("bend", read_robot(shipped_robots()[ROBOT]), NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    est = make_estimator("ekf", serial.formulation, MHESettings())
    session, made, _ = _live(serial, est, lines)
    assert len(made) == 101 and not any(str(e.status) == "ok" for e in made)
    assert "; warning: 101 of 101 estimates are of a start whose first IMU reading" in (
        session.summary()
    )


def test_live_summary_says_a_tip_force_beyond_every_tension_as_estimate_does() -> None:
    """Tensions on the line a hundredth of those acting (the shipped ``unloaded``): the
    tip force makes up for them, far beyond every tension given, and ``live``'s summary
    carries ``estimate``'s warning."""
    n = 200
    head, raw = _rows(DATA / "unloaded_raw.csv", n)
    _, ten = _rows(DATA / "unloaded_tensions.csv", n)
    lines = [
        ",".join(
            [f"{round(float(r[0]) * 1000)}", *r[1:], *(f"{0.01 * float(v):.6g}" for v in s[1:])]
        )
        for r, s in zip(raw, ten)
    ]
    base = make_formulation("bend", read_robot(shipped_robots()[ROBOT]), NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    est = make_estimator("ekf", serial.formulation, MHESettings())
    session, made, _ = _live(serial, est, lines)
    force = max(
        math.hypot(*(e.value(c) for c in ("fx", "fy", "fz"))) for e in made if e.output is not None
    )
    largest = max(0.01 * float(v) for s in ten for v in s[1:])
    assert force > 3 * largest
    assert (
        f"; warning: the estimated tip force reached {force:.3g} N, beyond the largest tendon "
        f"tension given ({largest:.3g} N)"
    ) in session.summary()


def test_lines_that_arrive_but_give_no_estimate_are_not_called_no_sample(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A session whose lines all arrive garbled (a non-number in a field) does not say
    that no sample arrived: it names what arrived and that no estimate was made of it."""
    data = "".join(f"{20 * k},abc,0.1\n" for k in range(5))  # the first read as partial
    monkeypatch.setattr("continuum_mhe.cli.live.open_port", lambda *a: _Port(data.encode()))
    est = tmp_path / "est.csv"
    argv = ["live", "--port", "/dev/ttyIMU", "--format", "tilt", "-o", str(est),
            "--duration", "0.3"]  # fmt: skip
    assert main(argv) == 2  # no valid sample: said in one line after the summary
    err = capsys.readouterr().err
    assert "no sample arrived" not in err
    assert "4 garbled line(s) arrived, but no estimate was made of them (the summary says " in err
    assert f"why): {est} not written" in err and not est.exists()


def test_a_sample_beyond_the_tensions_file_is_not_called_no_sample(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A stream whose first samples lie outside the --inputs file's times stops at them:
    the line on the file names the lines that arrived, not "no sample arrived", which
    the error naming the sample would contradict."""
    with_tensions, imus_only = _first_samples_lines()
    short = tmp_path / "late.csv"
    rows = [[100.0 + k, *[0.0] * 6] for k in range(2)]
    write_table(short, ["t", *(f"tension_{i}" for i in range(1, 7))], rows)
    data = "".join(ln + "\n" for ln in imus_only[:4])
    monkeypatch.setattr("continuum_mhe.cli.live.open_port", lambda *a: _Port(data.encode()))
    est = tmp_path / "est.csv"
    argv = ["live", "--port", "/dev/ttyTEN", "--robot", ROBOT, "--inputs", str(short),
            "-o", str(est), "--duration", "0.3"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "the tensions must cover the stream" in err
    assert "no sample arrived" not in err
    assert f"the session stopped before a sample was kept (the error below says why): {est}" in err
    assert not est.exists()


def test_the_samples_the_streams_end_releases_do_not_count_in_the_latency(runs: Runs) -> None:
    """The last two samples of a stream with tensions on the line wait for the tensions
    after them, and at the stream's end for the end itself (here the 0.5 s session's,
    the lines all read at its start): their wait is the quiet line's, not the
    estimator's, and the latency does not count them (which would make its largest the
    session's length)."""
    assert runs.line_session.latency.n == N - 2


def test_tensions_on_the_line_near_a_span_buckling_load_are_said(tmp_path: Path) -> None:
    """A disk-routed robot with one disk a section (its backbone buckles between two
    disks at 2.5 N): tensions on the line beyond 0.6 of that are said in the summary, as
    a tensions file's are when it is read."""
    from dataclasses import replace

    _, _, with_tensions, _ = _first_samples(tmp_path)
    robot = read_robot(shipped_robots()[ROBOT])
    robot = replace(
        robot,
        sections=tuple(replace(sec, disks=1) for sec in robot.sections),
        tendon_route="disks",
    )
    base = make_formulation("bend", robot, NoiseSettings())
    serial = serial_input("/dev/ttyTEN", "raw", InputOptions(), base)
    est = make_estimator("ekf", serial.formulation, MHESettings())
    scaled = []
    for line in with_tensions:
        fields = line.split(",")
        scaled.append(",".join([*fields[:-6], *(f"{3 * float(v):g}" for v in fields[-6:])]))
    session, _, _ = _live(serial, est, scaled)
    assert "/dev/ttyTEN: the tensions on the line: at t = " in session.summary()
    assert "of the load that buckles its backbone between two disks 200 mm apart" in (
        session.summary()
    )
