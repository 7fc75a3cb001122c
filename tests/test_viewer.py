"""The Rerun view, checked without a display: the stream is written to an .rrd file and
read back (rerun.chunk.RrdReader) for its entities, sizes, timestamps and geometry
against the estimate CSV (the formulation's outputs) and the robot's lengths."""

from __future__ import annotations

import contextlib
import math
import re
import sys
import warnings
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.descriptions import pcc_outputs
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import Estimate
from continuum_mhe.viewer import BackboneView, ViewerSink, ViewWarning

POINTS = 8


def read_rrd(path: Path) -> dict[str, list[tuple[int | None, dict[str, Any]]]]:
    """``entity -> [(t_ns or None for static, {component: value})]`` sorted by time."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    rows: dict[str, list[tuple[int | None, dict[str, Any]]]] = defaultdict(list)
    for chunk in RrdReader(path).stream().to_chunks():
        rb = chunk.to_record_batch()
        names = [n for n in rb.schema.names if ":" in n]
        t = rb.column("t").cast(pa.int64()).to_pylist() if "t" in rb.schema.names else None
        cols = {n: rb.column(n).to_pylist() for n in names}
        for k in range(rb.num_rows):
            rows[chunk.entity_path].append(
                (None if t is None else t[k], {n: cols[n][k] for n in names})
            )
    for v in rows.values():
        v.sort(key=lambda r: -1 if r[0] is None else r[0])
    return dict(rows)


def _ns(t: np.ndarray) -> list[int]:
    return [round(v * 1e9) for v in t]


def _two_section_run(tmp: Path) -> tuple[Path, Path, Path]:
    meas, truth, est = tmp / "m.csv", tmp / "t.csv", tmp / "e.csv"
    args = ["--robot", "two-section"]
    assert main(["simulate", "spatial", "-o", str(meas), "--truth", str(truth),
                 "--duration", "2", *args]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", *args]) == 0
    return meas, truth, est


@pytest.fixture(scope="module")
def two_section(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("view")
    meas, truth, est = _two_section_run(tmp)
    rrd = tmp / "view.rrd"
    code = main(["view", str(est), "--robot", "two-section", "--truth", str(truth),
                 "--save", str(rrd), "--points", str(POINTS)])  # fmt: skip
    assert code == 0
    return {"meas": meas, "est": est, "truth": truth, "rrd": rrd, "rows": read_rrd(rrd)}


def test_view_file_entities_and_timestamps(two_section: dict[str, Any]) -> None:
    rows, robot = two_section["rows"], read_robot("two-section")
    est = read_state_table(two_section["est"], ())
    truth = read_state_table(two_section["truth"], ())
    expected = {
        "/world", "/world/base", "/world/estimate/backbone", "/world/estimate/tip",
        "/world/estimate/tip_trail", "/world/truth/backbone", "/world/truth/tip",
        "/world/truth/tip_trail", "/world/truth/section_ends", "/status",
        *(f"/world/estimate/imu_{i + 1}" for i in range(robot.n_imus)),
        *(f"/outputs/{o.unit}" for o in pcc_outputs(robot.n_sections)),
    }  # fmt: skip
    assert expected <= set(rows)
    assert not {e for e in rows if e.startswith("/world")} - expected
    timed = lambda e: [t for t, _ in rows[e] if t is not None]  # noqa: E731
    assert timed("/world/estimate/backbone") == _ns(est.t)
    for i in range(robot.n_imus):
        assert timed(f"/world/estimate/imu_{i + 1}") == _ns(est.t)
    assert timed("/world/estimate/tip_trail") == _ns(est.t[1:])
    assert timed("/world/truth/backbone") == _ns(truth.t)
    ends = np.array([r["Points3D:positions"] for _, r in rows["/world/truth/section_ends"]])
    for k in range(robot.n_sections):
        want = np.column_stack([truth.column(f"{c}_{k + 1}") for c in "xyz"])
        np.testing.assert_allclose(ends[:, k], want, atol=1e-6)
    tip = np.array([r["Points3D:positions"][0] for _, r in rows["/world/truth/tip"]])
    np.testing.assert_allclose(tip, np.column_stack([truth.column(c) for c in "xyz"]), atol=1e-6)
    for unit in ("m", "rad"):
        assert timed(f"/outputs/{unit}") == _ns(est.t)
        (names,) = [r["SeriesLines:names"] for t, r in rows[f"/outputs/{unit}"] if t is None]
        assert names == [o.name for o in pcc_outputs(robot.n_sections) if o.unit == unit]
        got = np.array([r["Scalars:scalars"] for t, r in rows[f"/outputs/{unit}"] if t is not None])
        want = np.column_stack([est.column(n) for n in names])
        np.testing.assert_allclose(got, want, rtol=1e-6)


def test_view_geometry_matches_outputs_and_lengths(two_section: dict[str, Any]) -> None:
    """Each row: one strip per section of POINTS + 1 points, joined end to start; the
    strip ends are the CSV's section ends and tip (the formulation's output function,
    float32 in the file); each strip's polyline length is its section's length to the
    chord error of POINTS points; the IMU frames sit at the section ends, rotations
    orthonormal with z along the backbone's last chord."""
    rows, robot = two_section["rows"], read_robot("two-section")
    est = read_state_table(two_section["est"], ())
    strips = np.array([r["LineStrips3D:strips"] for _, r in rows["/world/estimate/backbone"]])
    assert strips.shape == (len(est.t), robot.n_sections, POINTS + 1, 3)
    np.testing.assert_array_equal(strips[:, 0, 0], 0.0)
    np.testing.assert_allclose(strips[:, 1, 0], strips[:, 0, -1], atol=0)
    for k in range(robot.n_sections):
        end = np.column_stack([est.column(f"{c}_{k + 1}") for c in "xyz"])
        np.testing.assert_allclose(strips[:, k, -1], end, atol=1e-6)
        arc = np.linalg.norm(np.diff(strips[:, k], axis=1), axis=2).sum(axis=1)
        theta = est.column(f"theta_{k + 1}")
        chord_rel = 1 - np.sinc(theta / POINTS / 2 / np.pi)  # chord/arc = sinc(half angle)
        np.testing.assert_allclose(arc, robot.sections[k].length * (1 - chord_rel), rtol=1e-5)
    tip = np.column_stack([est.column(c) for c in "xyz"])
    np.testing.assert_allclose(strips[:, -1, -1], tip, atol=1e-6)
    for i, imu in enumerate(robot.imus):
        frames = rows[f"/world/estimate/imu_{i + 1}"]
        pos = np.array([r["Transform3D:translation"][0] for _, r in frames])
        mat = np.array([r["Transform3D:mat3x3"][0] for _, r in frames]).reshape(-1, 3, 3)
        mat = mat.transpose(0, 2, 1)  # Rerun stores 3x3 matrices column-major
        assert imu.at == 1.0
        np.testing.assert_allclose(pos, strips[:, imu.section, -1], atol=1e-7)
        np.testing.assert_allclose(
            mat @ mat.transpose(0, 2, 1), np.broadcast_to(np.eye(3), mat.shape), atol=1e-6
        )
        chord = strips[:, imu.section, -1] - strips[:, imu.section, -2]
        chord /= np.linalg.norm(chord, axis=1, keepdims=True)
        angle = np.arccos(np.clip(np.sum(chord * mat[:, :, 2], axis=1), -1, 1))
        half_step = est.column(f"theta_{imu.section + 1}") / POINTS / 2
        np.testing.assert_allclose(angle, half_step, atol=1e-5)
    trail = [np.array(r["LineStrips3D:strips"][0]) for _, r in rows["/world/estimate/tip_trail"]]
    np.testing.assert_allclose([s[0] for s in trail], tip[:-1], atol=1e-6)
    np.testing.assert_allclose([s[1] for s in trail], tip[1:], atol=1e-6)


def _estimates(robot: Robot) -> list[Estimate]:
    outs = pcc_outputs(robot.n_sections)
    rng = np.random.default_rng(1)
    ests = []
    for k in range(6):
        out = np.zeros(len(outs))
        for j, o in enumerate(outs):
            out[j] = rng.uniform(0.1, 1.0) if o.unit == "rad" else rng.uniform(-0.1, 0.1)
        status = "no-estimate" if k == 3 else ("dropout" if k == 4 else "ok")
        ests.append(Estimate(0.1 * k, None, None if k == 3 else out, None, status, 0.1))  # type: ignore[arg-type]
    return ests


def _same(x: Any, y: Any) -> bool:
    try:
        return bool(np.allclose(np.array(x, dtype=float), np.array(y, dtype=float), atol=1e-7))
    except (TypeError, ValueError):
        return bool(x == y)


def test_live_hook_draws_what_replay_draws(tmp_path: Path) -> None:
    """``log_estimate`` (one entity at a time, as ``live`` calls it) and ``log_rows``
    (columns, as ``view`` sends a recording) give the same file content; a sample
    without an estimate clears the shape and breaks the trail."""
    robot = read_robot("two-section")
    outs = pcc_outputs(robot.n_sections)
    ests = _estimates(robot)
    live, replay = tmp_path / "live.rrd", tmp_path / "replay.rrd"
    view = BackboneView(robot, outs, ViewerSink("save", live), points_per_section=POINTS)
    for e in ests:
        view.log_estimate(e)
    view.close()
    view = BackboneView(robot, outs, ViewerSink("save", replay), points_per_section=POINTS)
    values = np.array(
        [np.full(len(outs), math.nan) if e.output is None else e.output for e in ests]
    )
    view.log_rows(np.array([e.t for e in ests]), values, [e.status for e in ests])
    view.close()
    a, b = read_rrd(live), read_rrd(replay)
    assert set(a) == set(b)
    for entity in a:
        if entity == "/__properties":
            continue
        assert [t for t, _ in a[entity]] == [t for t, _ in b[entity]], entity
        for (_, ra), (_, rb) in zip(a[entity], b[entity]):
            assert set(ra) == set(rb), entity
            for comp in ra:
                assert _same(ra[comp], rb[comp]), (entity, comp)
    t_ns = _ns(np.array([e.t for e in ests]))
    clears = [t for t, r in a["/world/estimate"] if "Clear:is_recursive" in r]
    assert clears == [t_ns[3]]
    assert [t for t, _ in a["/world/estimate/backbone"]] == [t_ns[k] for k in (0, 1, 2, 4, 5)]
    assert [t for t, _ in a["/world/estimate/tip_trail"]] == [t_ns[k] for k in (1, 2, 5)]
    texts = [(t, r["TextLog:text"][0]) for t, r in a["/status"]]
    assert texts == [(t_ns[0], "status: ok"), (t_ns[3], "status: no-estimate"),
                     (t_ns[4], "status: dropout"), (t_ns[5], "status: ok")]  # fmt: skip


def _one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("continuum-mhe: error: ")
    return err[0]


def test_view_without_rerun_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    assert main(["view", str(est), "--save", str(tmp_path / "v.rrd")]) == 2
    assert "pip install 'continuum-mhe[view]'" in _one_error_line(capsys)
    assert list(tmp_path.iterdir()) == [est]


def test_view_user_mistakes_are_one_line(
    tmp_path: Path, two_section: dict[str, Any], monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    est = str(two_section["est"])
    out = tmp_path / "v.rrd"
    # two-section columns with a one-section --length: that robot does not fit
    assert main(["view", est, "--length", "0.3", "--save", str(out)]) == 2
    assert "pass --robot with the robot it was estimated on" in _one_error_line(capsys)
    assert main(["view", est, "--robot", "two-section", "--save", str(tmp_path / "v.txt")]) == 2
    assert ".rrd" in _one_error_line(capsys)
    # an estimate given as the truth, and a truth in mm: one line each, as plot says them
    argv = ["view", est, "--robot", "two-section", "--save", str(out), "--truth"]
    assert main([*argv, est]) == 2
    assert "an estimate, not a truth" in _one_error_line(capsys)
    truth = read_state_table(two_section["truth"], ())
    mm = tmp_path / "mm.csv"
    write_table(mm, ["t", "x", "y", "z"],
                np.column_stack([truth.t, *(1000 * truth.column(c) for c in "xyz")]))  # fmt: skip
    assert main([*argv, str(mm)]) == 2
    assert "positions in mm?" in _one_error_line(capsys)
    mm.unlink()
    # the robot the options line names is said in a note, and another robot file in a
    # warning, only where the file is drawn: a refusal is its one line alone
    empty = tmp_path / "empty.csv"
    empty.write_text("".join(ln for ln in Path(est).read_text().splitlines(keepends=True)
                             if ln.startswith(("#", "t,"))))  # fmt: skip
    assert main(["view", str(empty), "--save", str(out)]) == 2
    assert "has no data rows" in _one_error_line(capsys)
    empty.unlink()
    three = tmp_path / "three.toml"
    three.write_text("[[section]]\nlength = 0.1\n" * 3 + "[[imu]]\nsection = 3\n")
    assert main(["view", est, "--robot", str(three), "--save", str(out)]) == 2
    assert "missing theta_3" in _one_error_line(capsys)
    three.unlink()
    if sys.platform.startswith("linux"):
        monkeypatch.delenv("DISPLAY", raising=False)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        assert main(["view", est, "--robot", "two-section", "--spawn"]) == 2
        assert "needs a display" in _one_error_line(capsys)
        # the default says it is the default, where the user gave no --spawn
        assert main(["view", est, "--robot", "two-section"]) == 2
        assert "--spawn (the default) needs a display" in _one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_live_hook_max_hz(tmp_path: Path) -> None:
    """At 100 Hz of sample time and at most 30 drawn per second: every 4th estimate
    (0.03 s < 1/30 s < 0.04 s), the one where the status changes, and the last one,
    drawn at the end."""
    robot = Robot.single(0.2)
    outs = pcc_outputs(1)
    out = tmp_path / "v.rrd"
    view = BackboneView(robot, outs, ViewerSink("save", out), max_hz=30.0)
    for k in range(20):
        status = "ok" if k < 10 else "dropout"
        view.log_estimate(Estimate(0.01 * k, None, np.array([0, 0, 0.2, 0.1, 0.2]), None,
                                   status, 0.1))  # type: ignore[arg-type]  # fmt: skip
    view.close()
    drawn = [t for t, _ in read_rrd(out)["/world/estimate/backbone"]]
    assert drawn == _ns(0.01 * np.array([0, 4, 8, 10, 14, 18, 19]))


def test_imu_frame_includes_its_mounting(tmp_path: Path) -> None:
    """A straight robot: the local frame is the base frame, so an IMU mounted with yaw
    90 deg has its sensor x axis along base y (``v_tip = Rz(90) v_sensor``)."""
    from continuum_mhe.model.robot import ImuPlacement, Section
    from continuum_mhe.viewer import backbone_geometry

    robot = Robot((Section(0.1), Section(0.2)), (ImuPlacement(1, 0.5, (0.0, 0.0, 90.0)),))
    g = backbone_geometry(robot, np.zeros((1, 2, 2)), 4)
    np.testing.assert_allclose(g.imu_rotation[0, 0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
                               atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(g.imu_position[0, 0], [0, 0, 0.2], atol=1e-12)
    np.testing.assert_allclose(g.sections[0, 1, :, 2], np.linspace(0.1, 0.3, 5), atol=1e-12)


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_live_view_through_a_pty(tmp_path: Path) -> None:
    """``live --view FILE.rrd --view-hz 0`` on a pseudo-terminal: the file holds one
    backbone per estimate row of ``-o``, at the same times."""
    import signal

    from live_helpers import LiveProcess, new_pty, raw_lines, send_until_rows

    port, out, rrd = tmp_path / "tty", tmp_path / "live.csv", tmp_path / "live.rrd"
    master = new_pty(port)
    live = LiveProcess(["--port", str(port), "--method", "ekf", "-o", str(out),
                        "--view", str(rrd), "--view-hz", "0"])  # fmt: skip
    lines = raw_lines(0, 30)
    code = send_until_rows(live, master, "".join(lines), out, len(lines), signal.SIGINT)
    assert code == 0, live.err
    est = read_state_table(out, ())
    rows = read_rrd(rrd)
    assert [t for t, _ in rows["/world/estimate/backbone"]] == _ns(est.t)
    tips = np.array([r["Points3D:positions"][0] for _, r in rows["/world/estimate/tip"]])
    np.testing.assert_allclose(tips, np.column_stack([est.column(c) for c in "xyz"]), atol=1e-6)


def test_blueprint_shows_the_trail_for_its_seconds(tmp_path: Path) -> None:
    """The recording's blueprint limits both tip trails to the last ``--trail`` seconds."""
    from rerun.chunk import RrdReader

    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    out = tmp_path / "v.rrd"
    assert main(["view", str(est), "--save", str(out), "--trail", "2.5"]) == 0
    reader = RrdReader(out)
    (blueprint,) = reader.blueprints()
    ranges = {}
    for chunk in reader.stream(store=blueprint).to_chunks():
        rb = chunk.to_record_batch()
        if "VisibleTimeRanges:ranges" in rb.schema.names:
            ranges[chunk.entity_path.split("/overrides/")[1]] = rb.column(
                "VisibleTimeRanges:ranges"
            ).to_pylist()[0]
    want = [{"timeline": "t", "range": {"start": -2_500_000_000, "end": 0}}]
    assert ranges == {
        "world/estimate/tip_trail/visualizers": want,
        "world/truth/tip_trail/visualizers": want,
    }


def _live_with_a_gyro_in_degrees(port: Path, out: Path, rrd: Path) -> tuple[Any, int, list[str]]:
    """``live --view rrd`` (EKF, raw readings, 30 s) on a new pty at ``port``, and 4 s of
    raw lines whose gyro is in deg/s: the process, the pty's master and the lines."""
    from live_helpers import LiveProcess, new_pty, raw_lines

    master = new_pty(port)
    lines = [ln.rstrip("\n") for ln in raw_lines(1000, 200, gyro_scale=180 / math.pi)]
    live = LiveProcess(["--port", str(port), "--method", "ekf", "--imu-model", "direct",
                        "-o", str(out), "--view", str(rrd), "--view-hz", "0",
                        "--duration", "30"])  # fmt: skip
    return live, master, lines


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_a_live_view_of_readings_in_the_wrong_units_says_it_holds_them(tmp_path: Path) -> None:
    """A gyro in deg/s stops ``live`` at its units check, and the estimates written to
    ``-o`` are removed; the view file cannot be cut back, and the line naming it says
    it holds the estimates from those readings."""
    from live_helpers import send_and_finish

    out, rrd = tmp_path / "live.csv", tmp_path / "live.rrd"
    live, master, lines = _live_with_a_gyro_in_degrees(tmp_path / "tty", out, rrd)
    code = send_and_finish(live, master, lines)  # kills it and closes master in any case
    assert code == 2 and not out.exists(), live.err
    said = f"live: the view in {rrd} (with the estimates made from readings in the wrong units)"
    assert said in live.err.splitlines(), live.err


def test_live_view_without_rerun_is_one_line_before_the_port(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "rerun", None)
    args = ["live", "--port", str(tmp_path / "no-such-port"), "--view", str(tmp_path / "v.rrd")]
    assert main(args) == 2
    assert "pip install 'continuum-mhe[view]'" in _one_error_line(capsys)


def test_live_view_without_rerun_nor_pyserial_names_both_extras_in_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """With neither extra of ``live --view`` installed, one line names both packages
    and the one install of both extras (not the view's alone, then the port's)."""
    monkeypatch.setitem(sys.modules, "rerun", None)
    monkeypatch.setitem(sys.modules, "serial", None)
    args = ["live", "--port", str(tmp_path / "no-such-port"), "--view", str(tmp_path / "v.rrd")]
    assert main(args) == 2
    assert _one_error_line(capsys) == (
        "continuum-mhe: error: live --view needs pyserial and rerun-sdk, which do not import "
        "here: pip install 'continuum-mhe[robot,view]'"
    )


def test_view_without_robot_draws_the_robot_the_estimate_names(
    tmp_path: Path, two_section: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """``view EST.csv --save V.rrd`` without --robot reads the robot the estimate's
    options line names, as evaluate does, with the same note, and draws the same view as
    with --robot; a file without the line still needs --robot (``pass --robot with the
    robot it was estimated on``)."""
    out = tmp_path / "v.rrd"
    capsys.readouterr()
    assert main(["view", str(two_section["est"]), "--truth", str(two_section["truth"]),
                 "--save", str(out), "--points", str(POINTS)]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert (
        f"note: {two_section['est']} was estimated with --robot two-section (its options "
        "line): drawn on that robot (pass --robot for another)"
    ) in err
    rows, given = read_rrd(out), two_section["rows"]
    assert set(rows) == set(given)
    for entity in ("/world/estimate/backbone", "/world/truth/backbone"):
        assert [t for t, _ in rows[entity]] == [t for t, _ in given[entity]]
        np.testing.assert_array_equal(
            rows[entity][-1][1]["LineStrips3D:strips"], given[entity][-1][1]["LineStrips3D:strips"]
        )
    bare = tmp_path / "bare.csv"  # the same rows without the comment lines
    text = two_section["est"].read_text().splitlines(True)
    bare.write_text("".join(ln for ln in text if ln[0] != "#"))
    assert main(["view", str(bare), "--save", str(tmp_path / "b.rrd")]) == 2
    assert "pass --robot with the robot it was estimated on" in _one_error_line(capsys)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="DISPLAY is Linux's")
def test_live_view_without_a_display_names_lives_choices_before_the_port(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``live --view`` without a display names live's own choices (``--view web``,
    ``--view FILE.rrd``), not view's options, which live does not have, before the port
    is opened."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    args = ["live", "--port", str(tmp_path / "no-such-port"), "--view"]
    assert main(args) == 2
    assert _one_error_line(capsys) == (
        "continuum-mhe: error: --view needs a display (DISPLAY is not set); use --view web "
        "or --view FILE.rrd"
    )
    assert list(tmp_path.iterdir()) == []


def test_truth_without_bends_draws_its_tip_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A truth CSV with only ``t, x, y, z`` (as ``evaluate`` accepts): its tip and trail,
    no backbone, and the summary line says so."""
    est, truth = tmp_path / "e.csv", tmp_path / "t.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    truth.write_text("t,x,y,z\n0,0.01,0,0.2\n0.05,0.02,0,0.2\n")
    out = tmp_path / "v.rrd"
    assert main(["view", str(est), "--truth", str(truth), "--save", str(out)]) == 0
    assert "tip and section ends only" in capsys.readouterr().err
    rows = read_rrd(out)
    assert "/world/truth/backbone" not in rows and "/world/truth/section_ends" not in rows
    tips = [r["Points3D:positions"][0] for _, r in rows["/world/truth/tip"]]
    np.testing.assert_allclose(tips, [[0.01, 0, 0.2], [0.02, 0, 0.2]], atol=1e-7)
    assert [t for t, _ in rows["/world/truth/tip_trail"]] == [50_000_000]


def _free_ports(count: int) -> list[int]:
    """``count`` distinct loopback ports that were free a moment ago (bound at once, so
    that they differ; another process may still take one before the test binds it)."""
    import socket

    sockets = [socket.socket() for _ in range(count)]
    try:
        for s in sockets:
            s.bind(("127.0.0.1", 0))
        return [int(s.getsockname()[1]) for s in sockets]
    finally:
        for s in sockets:
            s.close()


def test_serve_web_on_loopback_until_ctrl_c(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``view --serve-web``: the web viewer's page answers on 127.0.0.1 at the printed
    address, a second server on the same port is one line, and Ctrl-C stops both the
    command (exit 0) and the server (the port closes)."""
    import signal
    import socket
    import urllib.request

    from live_helpers import LiveProcess, wait_for

    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    for _ in range(5):  # a port another process took since it was free: other ports
        web, grpc = _free_ports(2)
        cmd = [sys.executable, "-m", "continuum_mhe.cli", "view", str(est), "--serve-web",
               "--web-port", str(web), "--grpc-port", str(grpc)]  # fmt: skip
        view = LiveProcess(cmd[4:], command="view")
        proc = view.proc
        wait_for(lambda v=view: "serving the view at" in v.err or v.proc.poll() is not None, "view")
        if proc.poll() is None:
            break
        view.finish()  # exited: its whole stderr
        if "is in use" not in view.err:
            break
    try:
        assert proc.poll() is None, f"view exited before serving: {view.err}"
        (line,) = [ln for ln in view.lines if "serving the view at" in ln]
        url = line.split(" at ")[1].split()[0]
        assert url.startswith(f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A")
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200
        # the port is taken: one line, before anything starts (in this process)
        assert main(cmd[3:]) == 2
        assert _one_error_line(capsys).endswith(
            f"port {web} on 127.0.0.1 is in use; pick another with --web-port"
        )
        code = view.finish(signal.SIGINT)
    finally:
        if proc.poll() is None:  # a failed assertion: Ctrl-C, so that view stops its
            view.finish(signal.SIGINT)  # server (killed, it would leave it serving)
    assert code == 0, view.err
    assert "stopped serving the view" in view.err
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", web)) != 0


def test_view_keeps_an_existing_file_unless_overwrite(
    tmp_path: Path, two_section: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """``view --save`` keeps an existing file and refuses in one line, as every command
    that writes; ``--overwrite`` replaces it."""
    rrd = tmp_path / "v.rrd"
    rrd.write_text("mine\n")
    argv = ["view", str(two_section["est"]), "--robot", "two-section", "--save", str(rrd),
            "--points", str(POINTS)]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 2
    assert "exists; give --overwrite" in _one_error_line(capsys)
    assert rrd.read_text() == "mine\n"
    assert main([*argv, "--overwrite"]) == 0
    assert rrd.stat().st_size > 1000


def test_evaluate_and_plot_read_an_estimate_mcap_as_its_csv(
    tmp_path: Path, two_section: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """evaluate scores an .mcap estimate as it scores the same run's CSV (not 'not UTF-8
    text'); plot draws it."""
    import json

    meas, truth, est_csv = (two_section[k] for k in ("meas", "truth", "est"))
    est_mcap = tmp_path / "e.mcap"
    robot = ["--robot", "two-section"]
    assert main(["estimate", str(meas), "-o", str(est_mcap), "--method", "ekf", *robot]) == 0
    scores = []
    capsys.readouterr()
    for est in (est_mcap, est_csv):
        assert main(["evaluate", str(est), str(truth), *robot, "--json"]) == 0
        scores.append(json.loads(capsys.readouterr().out))
    mcap, csv = scores
    assert mcap["tip_mean_mm"] > 0 and mcap.keys() == csv.keys()
    for key in ("tip_mean_mm", "tip_max_mm", "srmse"):  # the CSV holds 10 digits
        assert mcap[key] == pytest.approx(csv[key], rel=1e-6), key
    assert main(["plot", str(est_mcap), *robot, "-o", str(tmp_path / "p.png")]) == 0
    assert (tmp_path / "p.png").stat().st_size > 0
    capsys.readouterr()
    # without --robot: the robot file its options note names, as a CSV's options line
    assert main(["evaluate", str(est_mcap), str(truth), "--json"]) == 0
    got = capsys.readouterr()
    assert f"{est_mcap} was estimated with --robot two-section" in got.err
    assert json.loads(got.out)["tip_mean_mm"] == mcap["tip_mean_mm"]
    assert main(["evaluate", str(meas), str(truth), *robot]) == 2
    assert _one_error_line(capsys).endswith(
        f"-o EST.csv first, then continuum-mhe evaluate EST.csv {truth}"
    )


def test_view_reads_an_estimate_mcap_and_names_a_measurement_file(
    tmp_path: Path, two_section: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """view draws an .mcap estimate as it draws its CSV (not 'not UTF-8 text'), and a
    measurement file (tilt or raw) is one line saying to run estimate first (not a
    suggestion of --robot)."""
    meas, _, _ = _two_section_run(tmp_path)
    est_mcap = tmp_path / "e.mcap"
    robot = ["--robot", "two-section"]
    assert main(["estimate", str(meas), "-o", str(est_mcap), "--method", "ekf", *robot]) == 0
    rrd = tmp_path / "m.rrd"
    capsys.readouterr()
    assert main(["view", str(est_mcap), *robot, "--save", str(rrd), "--points", str(POINTS)]) == 0
    n = len(read_state_table(two_section["est"], ()).t)
    assert capsys.readouterr().err.strip() == (
        f"wrote {rrd}: {n} of {n} estimate(s) of {read_robot('two-section').describe()}"
    )
    from_csv = tmp_path / "c.rrd"
    assert main(["view", str(tmp_path / "e.csv"), *robot, "--save", str(from_csv),
                 "--points", str(POINTS)]) == 0  # fmt: skip
    a, b = read_rrd(rrd), read_rrd(from_csv)
    (backbone,) = [e for e in a if e.endswith("/backbone")]
    assert [t for t, _ in a[backbone]] == [t for t, _ in b[backbone]]
    compared = 0
    for (_, ra), (_, rb) in zip(a[backbone], b[backbone]):  # the CSV has 10 digits
        for k in (k for k in ra if k.endswith((":strips", ":positions"))):
            np.testing.assert_allclose(
                np.asarray(ra[k], float), np.asarray(rb[k], float), atol=1e-8
            )
            compared += 1
    assert compared >= len(a[backbone])
    capsys.readouterr()
    raw = tmp_path / "raw.csv"
    raw.write_text("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n")
    dropouts = tmp_path / "dropouts.csv"  # valid input: said before its rows are parsed
    dropouts.write_text("t,roll,pitch\n0,0.1,0.2\n0.05,,\n0.1,nan,0.2\n")
    for path in (meas, raw, dropouts):
        assert main(["view", str(path), "--save", str(tmp_path / "v.rrd")]) == 2
        said = _one_error_line(capsys)
        assert said.startswith(f"continuum-mhe: error: {path}: a measurement file (columns ")
        assert said.endswith(
            f"not an estimate: run continuum-mhe estimate {path} -o EST.csv first, then "
            "continuum-mhe view EST.csv"
        )
    assert not (tmp_path / "v.rrd").exists()


@pytest.fixture(scope="module")
def tendon_view(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The first 30 samples of the shipped twist-29 recording (a twisted, loaded tendon
    robot), estimated and viewed with its tensions and truth."""
    from importlib.resources import files

    data = files("continuum_mhe") / "data" / "tendon"
    tmp = tmp_path_factory.mktemp("tendon_view")
    meas, est, rrd = tmp / "m.csv", tmp / "e.csv", tmp / "v.rrd"
    meas.write_text("\n".join((data / "twist-29_raw.csv").read_text().splitlines()[:31]) + "\n")
    tensions, truth = str(data / "twist-29_tensions.csv"), str(data / "twist-29_truth.csv")
    robot = ["--robot", "tendon-two-section"]
    assert main(["estimate", str(meas), *robot, "--inputs", tensions, "-o", str(est)]) == 0
    assert main(["view", str(est), *robot, "--inputs", tensions, "--truth", truth,
                 "--save", str(rrd), "--points", str(POINTS)]) == 0  # fmt: skip
    return {"est": est, "rrd": rrd, "tensions": tensions, "tmp": tmp}


def test_a_tendon_robot_is_drawn_from_its_mechanics_model(tendon_view: dict[str, Any]) -> None:
    """``view --inputs``: each section's strip ends where the estimate puts its end,
    within a millimetre (the estimate's base curvature meets the tip condition to that
    condition's noise, 1e-4 rad/m, and its tension states their readings' noise; the
    drawing solves the statics at its tip force and the file's tensions exactly, with
    finer steps); each IMU frame sits at its section's end with z along the strip's
    last chord (to that chord's half angle); the truth is drawn by the same model."""
    rows, robot = read_rrd(tendon_view["rrd"]), read_robot("tendon-two-section")
    est = read_state_table(tendon_view["est"], ())
    strips = np.array([r["LineStrips3D:strips"] for _, r in rows["/world/estimate/backbone"]])
    assert strips.shape == (len(est.t), robot.n_sections, POINTS + 1, 3)
    for k in range(robot.n_sections):
        end = np.column_stack([est.column(f"{c}_{k + 1}") for c in "xyz"])
        np.testing.assert_allclose(strips[:, k, -1], end, atol=1e-3)
    for i, imu in enumerate(robot.imus):
        frames = rows[f"/world/estimate/imu_{i + 1}"]
        pos = np.array([r["Transform3D:translation"][0] for _, r in frames])
        mat = np.array([r["Transform3D:mat3x3"][0] for _, r in frames]).reshape(-1, 3, 3)
        mat = mat.transpose(0, 2, 1)  # column-major in the file
        np.testing.assert_allclose(pos, strips[:, imu.section, -1], atol=1e-7)
        chord = strips[:, imu.section, -1] - strips[:, imu.section, -2]
        chord /= np.linalg.norm(chord, axis=1, keepdims=True)
        assert np.all(np.sum(chord * mat[:, :, 2], axis=1) > math.cos(0.2 / POINTS))
    truth = np.array([r["LineStrips3D:strips"] for _, r in rows["/world/truth/backbone"]])
    assert truth.shape[1:] == (robot.n_sections, POINTS + 1, 3)


def test_view_says_when_the_models_backbone_misses_the_estimated_tip(
    tendon_view: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """A tendon estimate viewed with a robot file of a softer backbone (its tendons,
    sections and IMUs the estimate's): the mechanics model's backbone at the rows' tip
    forces and tensions ends far from the estimated tips, and a warning says by how
    much, as plot's does; with the estimate's own robot file none."""
    from importlib.resources import files

    text = (files("continuum_mhe") / "data" / "robots" / "tendon_two_section.toml").read_text()
    soft = tendon_view["tmp"] / "soft.toml"
    soft.write_text(text.replace("youngs_modulus = 54e9", "youngs_modulus = 30e9"))
    assert "youngs_modulus = 30e9" in soft.read_text()
    rrd = tendon_view["tmp"] / "soft.rrd"
    said = "backbone at the estimate's tip force and the tensions ends up to"
    capsys.readouterr()
    for action in ("error", "ignore"):  # the command's line, whatever -W says
        with warnings.catch_warnings():
            warnings.simplefilter(action)
            argv = ["view", str(tendon_view["est"]), "--robot", str(soft), "--inputs",
                    tendon_view["tensions"], "--save", str(rrd), "--overwrite"]  # fmt: skip
            assert main(argv) == 0
        err = capsys.readouterr().err
        assert f"continuum-mhe: warning: {rrd}" not in err  # the line names no file twice
        assert [line for line in err.splitlines() if said in line] == [
            line for line in err.splitlines() if line.startswith("continuum-mhe: warning: ")
        ] and said in err, err
    own = ["--robot", "tendon-two-section", "--inputs", tendon_view["tensions"]]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["view", str(tendon_view["est"]), *own, "--save", str(rrd), "--overwrite"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert not [w for w in seen if issubclass(w.category, ViewWarning)]


def test_a_tendon_robots_tip_force_is_an_arrow_from_its_tip(tendon_view: dict[str, Any]) -> None:
    """The estimated tip force, and the truth's, are arrows from their tips along the
    force, ``force_arrow_scale`` m per N (0.15 of the robot's length per E I / L^2),
    labelled with the force's magnitude; a robot without a backbone has no scale."""
    from importlib.resources import files

    from continuum_mhe.viewer.view import FORCE_ARROW_SHARE, force_arrow_scale

    rows, robot = read_rrd(tendon_view["rrd"]), read_robot("tendon-two-section")
    b = robot.backbone
    assert b is not None
    scale = force_arrow_scale(robot)
    ei = b.youngs_modulus * math.pi * b.radius**4 / 4
    assert scale == pytest.approx(FORCE_ARROW_SHARE * robot.length**3 / ei, rel=1e-12)
    assert force_arrow_scale(read_robot("two-section")) is None
    est = read_state_table(tendon_view["est"], ())
    arrows = rows["/world/estimate/tip_force"]
    assert [t for t, _ in arrows] == _ns(est.t)
    origins = np.array([r["Arrows3D:origins"][0] for _, r in arrows])
    vectors = np.array([r["Arrows3D:vectors"][0] for _, r in arrows])
    tip = np.column_stack([est.column(c) for c in "xyz"])
    force = np.column_stack([est.column(c) for c in ("fx", "fy", "fz")])
    np.testing.assert_allclose(origins, tip, atol=1e-6)  # float32 in the file
    np.testing.assert_allclose(vectors, force * scale, rtol=1e-5, atol=1e-6)
    labels = [r["Arrows3D:labels"][0] for _, r in arrows]
    assert labels == [f"{np.linalg.norm(f):.3f} N" for f in force]
    truth = read_state_table(files("continuum_mhe") / "data" / "tendon" / "twist-29_truth.csv", ())
    drawn = rows["/world/truth/tip_force"]
    truth_force = np.column_stack([truth.column(c) for c in ("fx", "fy", "fz")])
    got = np.array([r["Arrows3D:vectors"][0] for _, r in drawn])
    np.testing.assert_allclose(got, truth_force[: len(got)] * scale, rtol=1e-5, atol=1e-6)
    assert np.abs(truth_force[: len(got)]).max() > 0.01  # a load that draws an arrow


def test_a_tendon_robots_live_shapes_are_its_replayed_ones(tendon_view: dict[str, Any]) -> None:
    """The live hook draws a tendon robot from each estimate's state (base curvature,
    tip force, tensions), a replay from each row's tip force and the tensions file: at
    an equilibrium state the two agree; a replay without the tensions draws the tips
    alone and says so."""
    from continuum_mhe.io.tensions import read_tensions
    from continuum_mhe.model.tendon import tendon_outputs
    from continuum_mhe.model.tendon_statics import TendonStatics
    from continuum_mhe.viewer import TendonShapes

    robot = read_robot("tendon-two-section")
    outs = tendon_outputs(robot.n_sections)
    est = read_state_table(tendon_view["est"], ())
    values = np.column_stack([est.column(o.name) for o in outs])[:5]
    t = est.t[:5]
    tensions = read_tensions(tendon_view["tensions"], robot.n_tendons)
    statics = TendonStatics(robot)
    states = []
    for tk, row in zip(t, values):
        force, tau = row[-3:], tensions.at(float(tk))[0]
        states.append(np.concatenate([statics.solve(force, tau)[0], force, tau, np.zeros(4)]))
    live, replay = tendon_view["tmp"] / "live.rrd", tendon_view["tmp"] / "replay.rrd"
    view = BackboneView(robot, outs, ViewerSink("save", live), points_per_section=POINTS,
                        tendon=TendonShapes(robot, POINTS))  # fmt: skip
    for tk, row, x in zip(t, values, states):
        view.log_estimate(Estimate(float(tk), x, row, None, "ok", 1.0))  # type: ignore[arg-type]
    view.close()
    view = BackboneView(robot, outs, ViewerSink("save", replay), points_per_section=POINTS,
                        tendon=TendonShapes(robot, POINTS, tensions))  # fmt: skip
    view.log_rows(t, values, ["ok"] * len(t))
    view.close()
    a, b = read_rrd(live), read_rrd(replay)
    for entity in ("/world/estimate/backbone", "/world/estimate/imu_2"):
        for (ta, ra), (tb, rb) in zip(a[entity], b[entity]):
            assert ta == tb
            drawn = [c for c in ra if any(k in c for k in ("strips", "translation", "mat3x3"))]
            assert drawn
            for comp in drawn:
                np.testing.assert_allclose(
                    np.array(ra[comp], float), np.array(rb[comp], float), atol=1e-6
                )
    # without --inputs: the tensions its options line names, as plot takes them
    recorded = tendon_view["tmp"] / "recorded.rrd"
    assert main(["view", str(tendon_view["est"]), "--robot", "tendon-two-section",
                 "--save", str(recorded), "--points", str(POINTS)]) == 0  # fmt: skip
    drawn = read_rrd(recorded)["/world/estimate/backbone"]
    given = read_rrd(tendon_view["rrd"])["/world/estimate/backbone"]
    assert [r["LineStrips3D:strips"] for _, r in drawn] == [
        r["LineStrips3D:strips"] for _, r in given
    ]
    # where that file is not found: the tips alone, said in a note
    moved = tendon_view["tmp"] / "moved.csv"
    text = Path(tendon_view["est"]).read_text()
    assert tendon_view["tensions"] in text
    moved.write_text(text.replace(tendon_view["tensions"], "gone_tensions.csv"))
    bare = tendon_view["tmp"] / "bare.rrd"
    assert main(["view", str(moved), "--robot", "tendon-two-section",
                 "--save", str(bare)]) == 0  # fmt: skip
    rows = read_rrd(bare)
    assert "/world/estimate/backbone" not in rows and "/world/estimate/tip" in rows


def test_a_tendon_row_without_an_equilibrium_is_joined_through_its_section_ends(
    tendon_view: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """``view`` of a tendon estimate one of whose rows has a tip force the rod holds no
    equilibrium under (80 N): that row's backbone is drawn as ``plot`` draws it, from the
    base through the row's section ends, without IMU frames (no NaN in the file), and
    the summary counts it apart from the rows the mechanics model draws."""
    text = Path(tendon_view["est"]).read_text().splitlines(True)
    header = next(i for i, ln in enumerate(text) if not ln.startswith("#"))
    names = text[header].rstrip("\n").split(",")
    bad = header + 4  # the fourth row
    cells = text[bad].rstrip("\n").split(",")
    cells[names.index("fx")] = "80"
    text[bad] = ",".join(cells) + "\n"
    est = tendon_view["tmp"] / "unsolved.csv"
    est.write_text("".join(text))
    rrd = tendon_view["tmp"] / "unsolved.rrd"
    capsys.readouterr()
    first = (
        r"^continuum-mhe: warning: 1 of the backbones drawn joined through their section "
        r"ends: .* the row at t = "
    )
    argv = ["view", str(est), "--robot", "tendon-two-section", "--inputs",
            tendon_view["tensions"], "--save", str(rrd), "--points", str(POINTS)]  # fmt: skip
    assert main(argv) == 0
    robot, table = read_robot("tendon-two-section"), read_state_table(est, ())
    n = len(table.t)
    err = capsys.readouterr().err.strip().splitlines()
    assert [line for line in err if re.match(first, line)], err  # the command's warning
    said = err[-1]
    assert said == (
        f"wrote {rrd}: {n} of {n} estimate(s) of {robot.describe()} (1 of them joined "
        "through their section ends: no equilibrium under their loads)"
    )
    rows = read_rrd(rrd)
    backbone = rows["/world/estimate/backbone"]
    assert [t for t, _ in backbone] == _ns(table.t)
    strips = np.array([r["LineStrips3D:strips"] for _, r in backbone], float)
    assert np.all(np.isfinite(strips))
    k = bad - header - 1
    ends = np.array([[table.column(f"{c}_{s}")[k] for c in "xyz"] for s in (1, 2)])
    np.testing.assert_allclose(strips[k, 0, 0], 0.0, atol=1e-7)
    np.testing.assert_allclose(strips[k, 0, -1], ends[0], atol=1e-6)
    np.testing.assert_allclose(strips[k, 0, POINTS // 2], ends[0] / 2, atol=1e-6)
    np.testing.assert_allclose(strips[k, 1, 0], ends[0], atol=1e-6)
    np.testing.assert_allclose(strips[k, 1, -1], ends[1], atol=1e-6)
    np.testing.assert_allclose(strips[k, 1, POINTS // 2], (ends[0] + ends[1]) / 2, atol=1e-6)
    for i in range(robot.n_imus):  # no frame at that row: cleared, the others drawn
        frames = rows[f"/world/estimate/imu_{i + 1}"]
        posed = [t for t, r in frames if r.get("Transform3D:translation")]
        assert posed == [t for j, t in enumerate(_ns(table.t)) if j != k]
        for _, r in frames:
            if r.get("Transform3D:translation"):
                assert np.all(np.isfinite(np.array(r["Transform3D:translation"], float)))
        cleared = [t for t, r in frames if not r.get("Transform3D:translation")]
        assert cleared == [_ns(table.t)[k]]


# --- a folder or disk that cannot take the .rrd -----------------------------------------
def _fill_leaving(folder: Path, room: int) -> Path:
    """A file in ``folder`` that leaves ``room`` bytes free on its disk."""
    import shutil

    filler = folder / "filler"
    filler.write_bytes(b"\0" * max(shutil.disk_usage(folder).free - room, 0))
    return filler


@contextlib.contextmanager
def _tmpfs(folder: Path, options: str) -> Iterator[Path]:
    """A tmpfs mounted with ``options`` on ``folder`` for the block, or skip (not root)."""
    import subprocess

    folder.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                          capture_output=True, timeout=60)  # fmt: skip
    if done.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False, timeout=60)


def test_the_library_replay_prints_nothing_and_warns_its_notes(
    tendon_view: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """``viewer.replay`` and ``viewer.read_view_tensions`` called from Python write nothing
    to stdout or stderr: a tendon robot's tips drawn alone without its tensions and
    tensions taken on a robot log's clock are :class:`ViewNote` warnings (the text
    ``view`` says after ``continuum-mhe: note:``), tensions of another recording give
    the :class:`ViewWarning` that the backbone misses the tip, and the line of what was
    drawn goes to ``say``."""
    from continuum_mhe.viewer import ViewNote, read_view_tensions, replay

    robot, est = read_robot("tendon-two-section"), str(tendon_view["est"])
    n = len(read_state_table(est, ()).t)
    capsys.readouterr()
    rrd = tendon_view["tmp"] / "library.rrd"
    said: list[str] = []
    with pytest.warns(ViewNote) as notes:
        drawn = replay(est, robot, ViewerSink("save", rrd), points_per_section=POINTS,
                       say=said.append)  # fmt: skip
    assert [str(w.message) for w in notes] == [
        "a tendon robot's backbone is drawn from its mechanics model with its tensions "
        "(--inputs TENSIONS.csv; tensions=read_view_tensions(...) in Python); without "
        "them, the tips alone"
    ]
    assert drawn == n and said == [f"wrote {rrd}: {n} of {n} estimate(s) of {robot.describe()}"]
    # without say: the same file, and no line anywhere
    with pytest.warns(ViewNote):
        assert replay(est, robot, ViewerSink("save", rrd), points_per_section=POINTS) == n
    assert capsys.readouterr() == ("", "")
    # tensions stamped since 1970, read for an estimate of a log that starts at t0_ns
    t0_ns = 1_700_000_000_123_456_789
    stamped = tendon_view["tmp"] / "stamped.csv"
    header = "t," + ",".join(f"tension_{i + 1}" for i in range(robot.n_tendons))
    rows = [f"{1_700_000_000 + t:.3f}," + ",".join(["0.5"] * robot.n_tendons) for t in (0, 9)]
    stamped.write_text("\n".join([header, *rows]) + "\n")
    with pytest.warns(ViewNote, match="its times, since 1970, are taken on the log's clock"):
        table = read_view_tensions(str(stamped), robot, t0_ns)
    assert table.t[0] == pytest.approx(-0.123456789, abs=1e-6)
    # another recording's tensions: the backbone misses the estimated tip
    other = tendon_view["tmp"] / "other.csv"
    rows = [f"{t}," + ",".join(["2.0"] * robot.n_tendons) for t in (0, 9)]
    other.write_text("\n".join([header, *rows]) + "\n")
    with pytest.warns(ViewWarning, match="ends up to .* mm from the estimated tip"):
        replay(est, robot, ViewerSink("save", rrd), points_per_section=POINTS,
               tensions=read_view_tensions(str(other), robot))  # fmt: skip
    assert capsys.readouterr() == ("", "")


def test_view_into_a_folder_that_takes_no_file_is_one_line_before_the_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A folder that refuses a new file (here every file's creation fails, as in a
    read-only folder for a non-root user) is named in one line, exit 2, before the
    estimate is read."""
    import errno

    from continuum_mhe.io import output_files

    folder = tmp_path / "ro"
    folder.mkdir()

    def denied(*args: object, **kwargs: object) -> None:
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(output_files.tempfile, "mkstemp", denied)
    capsys.readouterr()
    missing = tmp_path / "no-such-estimate.csv"  # the folder is refused first
    assert main(["view", str(missing), "--save", str(folder / "p.rrd")]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"continuum-mhe: error: {folder / 'p.rrd'}: cannot write in folder {folder} "
        "(Permission denied)\n"
    )
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize(
    ("options", "seconds", "problem"),
    [
        ("ro,size=64k", 0, "cannot write in folder {folder} (Read-only file system)"),
        (
            "size=64k",
            0,
            "cannot write (its disk has 64 KiB free, a view needs 1 MiB) (nothing written)",
        ),
        ("size=1088k", 180, "cannot write (No space left on device) (nothing written)"),
    ],
    ids=["read-only", "nearly-full", "full"],
)
def test_view_onto_a_file_system_that_cannot_take_it_is_one_line(
    tmp_path: Path, options: str, seconds: int, problem: str
) -> None:
    """A read-only file system (which refuses even root) and a disk with too little
    room for a view before the work, and a disk that fills while the view is written:
    one line naming the file and why, exit 2, no .rrd and no temporary file (and no
    line of Rerun's own)."""
    est = tmp_path / "e.csv"
    if seconds:
        meas = tmp_path / "m.csv"
        assert main(["simulate", "paper3d", "-o", str(meas), "--duration", str(seconds)]) == 0
        assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    else:
        est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
    with _tmpfs(tmp_path / "fs", options) as folder:
        # a fresh process, as a user runs it: Rerun's log lines are set when it is first
        # imported, which another test in this one may have done
        done = subprocess.run(
            [sys.executable, "-m", "continuum_mhe.cli", "view", str(est), "--save",
             str(folder / "p.rrd")],
            capture_output=True, text=True, env=env, timeout=120,
        )  # fmt: skip
        assert done.returncode == 2, done.stderr
        said = problem.format(folder=folder)
        assert done.stderr == f"continuum-mhe: error: {folder / 'p.rrd'}: {said}\n"
        assert list(folder.iterdir()) == []


def test_a_killed_views_temporary_file_is_removed_by_the_next_write(tmp_path: Path) -> None:
    """The .rrd is written to a temporary file named as every output's, so a killed
    view's (its process gone) is removed by the next write into that folder."""
    import subprocess

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".p.rrd.{dead.pid}.k2j3h4g5.tmp"
    stale.write_bytes(b"partial")
    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    assert main(["view", str(est), "--save", str(tmp_path / "q.rrd")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.csv", "q.rrd"]
    # a view's own temporary file is one that pattern takes
    from continuum_mhe.io.output_files import _TEMPORARY

    robot = Robot.single(0.2)
    view = BackboneView(robot, pcc_outputs(1), ViewerSink("save", tmp_path / "r.rrd"))
    try:
        assert view._tmp is not None and _TEMPORARY.fullmatch(view._tmp.name), view._tmp
        assert view._tmp.parent == tmp_path
    finally:
        view.close(keep=False)
    assert not (tmp_path / "r.rrd").exists()


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_a_live_view_onto_a_full_disk_is_one_line_after_the_estimates_are_kept(
    tmp_path: Path,
) -> None:
    """``live --view`` onto a disk that fills: the estimates file is still written in
    full, then one line names the view file and the full disk, exit 2, and the small
    disk is left empty."""
    import signal

    from live_helpers import LiveProcess, data_rows, new_pty, raw_lines, send_until_rows

    with _tmpfs(tmp_path / "small", "size=2m") as small:
        port, out, rrd = tmp_path / "tty", tmp_path / "live.csv", small / "live.rrd"
        master = new_pty(port)
        lines = raw_lines(0, 400)
        live = LiveProcess(["--port", str(port), "--method", "ekf", "-o", str(out),
                            "--view", str(rrd), "--view-hz", "0"])  # fmt: skip
        live.wait_ready()
        filler = _fill_leaving(small, 16 << 10)
        code = send_until_rows(live, master, "".join(lines), out, len(lines), signal.SIGINT)
        assert code == 2, live.err
        assert data_rows(out) == len(lines), live.err
        last = live.err.splitlines()[-1]
        assert last == (
            f"continuum-mhe: error: {rrd}: cannot write (No space left on device) (nothing written)"
        ), live.err
        assert list(small.iterdir()) == [filler]


def _view_onto_an_unread_pipe(tmp_path: Path, patches: str, report: str) -> Any:
    """``view`` of a 2000-row estimate saved to ``tmp_path / "v.rrd"``, run in a new
    interpreter whose Rerun file writer writes into a pipe that nobody reads (it waits,
    as on a full disk), after ``patches`` (Python lines; ``view`` is the module); the
    finished process, whose stdout has ``report`` (a Python expression) printed."""
    import subprocess

    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n" + "".join(
        f"{0.05 * k:.2f},0,0,0.2,0.1,0.2,ok,0.1\n" for k in range(2000)))  # fmt: skip
    script = f"""
import os, sys
from pathlib import Path
pipe = Path({str(tmp_path / "pipe")!r})
os.mkfifo(pipe)
reader = os.open(pipe, os.O_RDONLY | os.O_NONBLOCK)  # open, never read: the writer waits
from continuum_mhe.viewer import view
view.temporary_beside = lambda path: pipe
{patches}
from continuum_mhe.cli import main
code = main(["view", {str(est)!r}, "--save", {str(tmp_path / "v.rrd")!r}])
print({report}, flush=True)
sys.exit(code)
"""
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)  # fmt: skip


def test_a_view_whose_writer_does_not_finish_is_one_line_and_the_process_ends(
    tmp_path: Path,
) -> None:
    """Rerun's file writer can wait forever (a full disk; here its file is a pipe that
    nobody reads): closing the view waits FLUSH_TIMEOUT_S, names the file in one line
    (nothing written), and the process ends (the recording, which would wait again
    when closed or freed, is left as it is); a second close() does nothing."""
    done = _view_onto_an_unread_pipe(
        tmp_path, "view.FLUSH_TIMEOUT_S = 1.0", '"main returned", code'
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr == (
        f"continuum-mhe: error: {tmp_path / 'v.rrd'}: cannot write (Rerun's file writer did "
        "not finish in 1 s) (nothing written)\n"
    )
    assert done.stdout == "main returned 2\n"
    assert not (tmp_path / "v.rrd").exists()


def test_a_writer_stuck_on_a_full_disk_is_given_up_after_one_slice(tmp_path: Path) -> None:
    """Rerun's file writer that stops on a full disk (here its file is a pipe nobody
    reads, and the disk reports no room): closing the view gives it up after one
    FLUSH_SLICE_S in which its file did not grow, not after FLUSH_TIMEOUT_S, and says
    the disk is full."""
    patches = """
import rerun
view.FLUSH_TIMEOUT_S = 600.0
flushes = []
flush = rerun.RecordingStream.flush
def counted(self, **kw):
    flushes.append(kw)
    return flush(self, **kw)
rerun.RecordingStream.flush = counted
free = view.free_bytes
calls = []
def filled(folder):  # room at the start, none once the view was begun
    calls.append(folder)
    return free(folder) if len(calls) == 1 else 0
view.free_bytes = filled
"""
    report = '"flushes", [kw.get("timeout_sec") for kw in flushes]'
    done = _view_onto_an_unread_pipe(tmp_path, patches, report)
    assert done.returncode == 2, done.stderr
    assert done.stderr == (
        f"continuum-mhe: error: {tmp_path / 'v.rrd'}: cannot write (No space left on device) "
        "(nothing written)\n"
    )
    assert done.stdout == "flushes [0.5]\n"
    assert not (tmp_path / "v.rrd").exists()


def test_free_bytes_counts_the_reserved_blocks_for_root_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file system keeps blocks for root (ext4's 5 %): root may write them, so the
    room a view needs is counted with them for root and without them for others."""
    import os
    from types import SimpleNamespace

    from continuum_mhe.viewer import view as view_module

    fake = SimpleNamespace(f_bfree=1000, f_bavail=10, f_frsize=4096)
    monkeypatch.setattr(os, "statvfs", lambda path: fake)
    for uid, want in ((0, 1000 * 4096), (1000, 10 * 4096)):
        monkeypatch.setattr(os, "geteuid", lambda uid=uid: uid)
        assert view_module.free_bytes(tmp_path) == want


def test_a_view_closed_twice_closes_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """close() after a failed close does nothing (no second flush that fails again)."""
    from continuum_mhe.errors import InputError

    view = BackboneView(Robot.single(0.2), pcc_outputs(1), ViewerSink("save", tmp_path / "v.rrd"))
    flushes: list[float] = []

    def failing(timeout_sec: float = 1e38) -> None:
        flushes.append(timeout_sec)
        raise RuntimeError("No space left on device")

    monkeypatch.setattr(view.rec, "flush", failing)
    with pytest.raises(InputError, match="cannot write"):
        view.close()
    view.close()
    assert len(flushes) == 1 and not view._stuck
    assert list(tmp_path.iterdir()) == []


def test_rerun_is_imported_quiet_and_the_users_rust_log_is_left_as_it_was() -> None:
    """Rerun's log lines are off for its import only: afterwards the process (and a
    viewer it starts) sees RUST_LOG as the user set it, or not at all."""
    import os
    import subprocess

    code = (
        "import os; from continuum_mhe.viewer import require_rerun; require_rerun(); "
        "print(os.environ.get('RUST_LOG'))"
    )
    env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
    for given, want in ((None, "None"), ("info", "info")):
        run_env = env if given is None else {**env, "RUST_LOG": given}
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              env=run_env, timeout=120)  # fmt: skip
        assert done.stdout.strip() == want, done.stderr


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_a_live_view_that_cannot_be_written_is_said_when_another_error_ends_live(
    tmp_path: Path,
) -> None:
    """A gyro in deg/s stops ``live`` (exit 2, its error the last line) while its view
    file's disk is full: the view's own error is said too, not dropped."""
    from live_helpers import send_and_finish

    with _tmpfs(tmp_path / "small", "size=2m") as small:
        out, rrd = tmp_path / "live.csv", small / "live.rrd"
        live, master, lines = _live_with_a_gyro_in_degrees(tmp_path / "tty", out, rrd)
        live.wait_ready()
        filler = _fill_leaving(small, 0)
        code = send_and_finish(live, master, lines)
        assert code == 2, live.err
        said = live.err.splitlines()
        view_line = f"live: {rrd}: cannot write (No space left on device) (nothing written)"
        assert view_line in said, live.err
        assert "deg/s" in said[-1], live.err
        assert list(small.iterdir()) == [filler]


def test_view_refuses_a_tendon_estimate_on_a_robot_without_tendons(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tendon robot's estimate (its tip force columns) with --robot of a robot without
    tendons, or --length: one line, exit 2, no view, as plot refuses it (the arcs drawn
    would miss the estimate's tip by up to 100 mm, with a warning about another thing)."""
    est = tmp_path / "e.csv"
    est.write_text(
        "t,x,y,z,theta_1,phi_1,x_1,y_1,z_1,theta_2,phi_2,fx,fy,fz,status\n"
        + "".join(f"{0.05 * i},0.01,0,0.39,0.1,0,0.005,0,0.2,0.1,0,0.01,0,0,ok\n" for i in range(5))
    )
    for extra in (["--robot", "two-section"], ["--length", "0.3"]):
        rrd = tmp_path / "v.rrd"
        assert main(["view", str(est), *extra, "--save", str(rrd)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1, err
        assert "the robot has no [[tendon]], but" in err and "tendon robot's estimate" in err
        assert not rrd.exists()


def test_view_times_are_the_estimates_to_the_nanosecond(tmp_path: Path) -> None:
    """Times whose seconds are not exact in binary (2.05 s is 2.0499999999999998): the
    view's times are the CSV's rounded to the nanosecond (not truncated, 1 ns early)."""
    t = [2.05, 4.1, 8.2, 8.45, 16.15]
    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi,status\n" + "".join(f"{v},0,0,0.2,0,0,ok\n" for v in t))
    rrd = tmp_path / "v.rrd"
    assert main(["view", str(est), "--save", str(rrd)]) == 0
    rows = read_rrd(rrd)
    timed = [v for v, _ in rows["/world/estimate/backbone"] if v is not None]
    assert timed == _ns(np.array(t)) == [2_050_000_000, 4_100_000_000, 8_200_000_000,
                                         8_450_000_000, 16_150_000_000]  # fmt: skip


def test_the_web_viewer_refuses_one_port_for_both_in_one_line() -> None:
    """--web-port equal to --grpc-port: one line naming both (not blamed on a port in
    use)."""
    from continuum_mhe.errors import InputError
    from continuum_mhe.viewer.sink import start_web_viewer

    sink = ViewerSink("web", web_port=9090, grpc_port=9090)
    with pytest.raises(InputError, match="--web-port and --grpc-port are both 9090"):
        start_web_viewer(sink)


def test_view_reads_a_robot_from_a_pipe_once(tmp_path: Path) -> None:
    """--robot from a pipe (<(...)): read once, where the robot is taken (the check of a
    tendon robot's estimate must not read it before)."""
    import os
    import threading

    est = tmp_path / "e.csv"
    est.write_text(
        "t,x,y,z,theta,phi,status\n" + "".join(f"{0.05 * i},0,0,0.2,0,0,ok\n" for i in range(3))
    )
    fifo = tmp_path / "robot.toml"
    os.mkfifo(fifo)

    def write() -> None:
        with open(fifo, "w") as fh:
            fh.write("[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n")

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    assert main(["view", str(est), "--robot", str(fifo), "--save", str(tmp_path / "v.rrd")]) == 0
    writer.join(10)


def test_view_warns_of_a_mounting_other_than_the_estimates(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--mounting z-down for an estimate made z-up (its options line): a warning that the
    given one turns the base over; the recorded one given: none."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "1"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    rrd = tmp_path / "v.rrd"
    assert main(["view", str(est), "--mounting", "z-down", "--save", str(rrd)]) == 0
    assert "was estimated with mounting z-up (its options line), not --mounting z-down" in (
        capsys.readouterr().err
    )
    assert main(["view", str(est), "--mounting", "z-up", "--save", str(rrd), "--overwrite"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_a_tendon_robots_live_tip_is_the_estimates(tendon_view: dict[str, Any]) -> None:
    """The live hook draws a tendon robot's tip, and its trail, at the estimate's ``x, y,
    z`` (to float32), as a replay does: not at the end of its drawing, whose finer steps
    end up to a tenth of a millimetre away."""
    from continuum_mhe.io.tensions import read_tensions
    from continuum_mhe.model.tendon import tendon_outputs
    from continuum_mhe.model.tendon_statics import TendonStatics
    from continuum_mhe.viewer import TendonShapes

    robot = read_robot("tendon-two-section")
    outs = tendon_outputs(robot.n_sections)
    est = read_state_table(tendon_view["est"], ())
    values = np.column_stack([est.column(o.name) for o in outs])
    tensions = read_tensions(tendon_view["tensions"], robot.n_tendons)
    statics = TendonStatics(robot)
    states = []
    for tk, row in zip(est.t, values):  # each row's equilibrium at its tip force
        force, tau = row[-3:], tensions.at(float(tk))[0]
        states.append(np.concatenate([statics.solve(force, tau)[0], force, tau, np.zeros(4)]))
    live = tendon_view["tmp"] / "live_tip.rrd"
    view = BackboneView(robot, outs, ViewerSink("save", live), points_per_section=POINTS,
                        tendon=TendonShapes(robot, POINTS))  # fmt: skip
    for tk, row, x in zip(est.t, values, states):
        view.log_estimate(Estimate(float(tk), x, row, None, "ok", 1.0))  # type: ignore[arg-type]
    view.close()
    rows = read_rrd(live)
    tips = np.array([r["Points3D:positions"][0] for _, r in rows["/world/estimate/tip"]])
    want = np.column_stack([est.column(c) for c in "xyz"])
    np.testing.assert_allclose(tips, want, atol=1e-6)
    trail = np.array([r["LineStrips3D:strips"][0] for _, r in rows["/world/estimate/tip_trail"]])
    np.testing.assert_allclose(trail[:, 0], want[:-1], atol=1e-6)
    np.testing.assert_allclose(trail[:, 1], want[1:], atol=1e-6)


def test_a_tendon_replay_draws_under_the_estimated_tension_gains(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An estimate made with --estimate-tension-gain on tensions given at 0.7 times the
    acting ones: the replay draws each section under the given tensions times the
    estimated gains, so its strips end within a millimetre of the estimate's section
    ends (under the given tensions alone they end 4.7 mm away), and the gains are
    outputs (``outputs/1``), as live --view shows them."""
    from importlib.resources import files

    data = files("continuum_mhe") / "data" / "tendon"
    meas, tensions = tmp_path / "m.csv", tmp_path / "tensions.csv"
    meas.write_text("\n".join((data / "force-29_raw.csv").read_text().splitlines()[:81]) + "\n")
    lines = (data / "force-29_tensions.csv").read_text().splitlines()
    scaled = [",".join([f[0], *(f"{0.7 * float(v):.9g}" for v in f[1:])])
              for f in (line.split(",") for line in lines[1:])]  # fmt: skip
    tensions.write_text("\n".join([lines[0], *scaled]) + "\n")
    est, rrd = tmp_path / "e.csv", tmp_path / "v.rrd"
    assert main(["estimate", str(meas), "--robot", "tendon-two-section", "--inputs",
                 str(tensions), "--estimate-tension-gain", "-o", str(est)]) == 0  # fmt: skip
    assert main(["view", str(est), "--save", str(rrd), "--points", str(POINTS)]) == 0
    capsys.readouterr()
    table = read_state_table(est, ())
    assert abs(table.column("tension_gain_2")[-1] - 1) > 0.2  # the gains were estimated
    rows = read_rrd(rrd)
    strips = np.array([r["LineStrips3D:strips"] for _, r in rows["/world/estimate/backbone"]])
    for k in range(2):
        end = np.column_stack([table.column(f"{c}_{k + 1}") for c in "xyz"])
        np.testing.assert_allclose(strips[:, k, -1], end, atol=1e-3)
    (names,) = [r["SeriesLines:names"] for t, r in rows["/outputs/1"] if t is None]
    assert names == ["tension_gain_1", "tension_gain_2"]
    gains = np.array([r["Scalars:scalars"] for t, r in rows["/outputs/1"] if t is not None])
    want = np.column_stack([table.column(n) for n in names])
    np.testing.assert_allclose(gains, want, rtol=1e-6)


def test_a_replay_shows_the_imu_twists_and_the_truths_backbone(tmp_path: Path) -> None:
    """An estimate made with --imu-twist (the first second of the shipped rod's spatial
    recording): its IMU twists are outputs of the replay (``outputs/rad``), as live
    --view shows them, and a truth, which has no twist column, is still drawn with its
    backbone."""
    from importlib.resources import files

    data = files("continuum_mhe") / "data" / "rod2"
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    for name, path in (("spatial_raw.csv", meas), ("spatial_truth.csv", truth)):
        path.write_text("\n".join((data / name).read_text().splitlines()[:51]) + "\n")
    est, rrd = tmp_path / "e.csv", tmp_path / "v.rrd"
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf",
                 "--robot", "two-section", "--imu-twist"]) == 0  # fmt: skip
    assert main(["view", str(est), "--truth", str(truth),
                 "--save", str(rrd), "--points", str(POINTS)]) == 0  # fmt: skip
    rows = read_rrd(rrd)
    (names,) = [r["SeriesLines:names"] for t, r in rows["/outputs/rad"] if t is None]
    assert names[-2:] == ["imu_twist_1", "imu_twist_2"]
    table = read_state_table(est, ())
    got = np.array([r["Scalars:scalars"] for t, r in rows["/outputs/rad"] if t is not None])
    np.testing.assert_allclose(got[:, -2:], np.column_stack([table.column(n) for n in names[-2:]]),
                               rtol=1e-6)  # fmt: skip
    assert [t for t, _ in rows["/world/truth/backbone"]] == _ns(read_state_table(truth, ()).t)
    # each IMU frame is the untwisted one turned about its z axis by the IMU's twist
    from scipy.spatial.transform import Rotation

    from continuum_mhe.viewer import backbone_geometry

    robot = read_robot("two-section")
    assert all(np.allclose(imu.mount_rpy, 0) for imu in robot.imus)
    theta = np.column_stack([table.column(f"theta_{k}") for k in (1, 2)])
    phi = np.column_stack([table.column(f"phi_{k}") for k in (1, 2)])
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=2)  # bend vectors
    untwisted = backbone_geometry(robot, bends, POINTS).imu_rotation
    for i in range(robot.n_imus):
        frames = rows[f"/world/estimate/imu_{i + 1}"]
        mat = np.array([r["Transform3D:mat3x3"][0] for _, r in frames]).reshape(-1, 3, 3)
        relative = np.einsum("nji,njk->nik", untwisted[:, i], mat.transpose(0, 2, 1))
        rotvec = Rotation.from_matrix(relative).as_rotvec()
        psi = table.column(f"imu_twist_{i + 1}")
        assert np.abs(psi).max() > 0.01  # twists that show
        np.testing.assert_allclose(rotvec[:, :2], 0.0, atol=1e-6)
        np.testing.assert_allclose(rotvec[:, 2], np.angle(np.exp(1j * psi)), atol=1e-6)


def test_view_takes_the_recorded_tensions_from_a_pipe_without_a_warning(
    tendon_view: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """--inputs from a pipe (<(cat TENSIONS.csv)) with the tensions the estimate's
    options line names: the same view as with the file, and no warning that other
    tensions were given (a pipe's text is compared, as a file's is)."""
    import os
    import threading

    text = Path(tendon_view["tensions"]).read_bytes()
    read_end, write_end = os.pipe()

    def write() -> None:
        with open(write_end, "wb") as fh:
            fh.write(text)

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    rrd = tendon_view["tmp"] / "piped.rrd"
    try:
        assert main(["view", str(tendon_view["est"]), "--inputs", f"/dev/fd/{read_end}",
                     "--save", str(rrd), "--points", str(POINTS)]) == 0  # fmt: skip
    finally:
        writer.join(10)
        os.close(read_end)
    assert "warning" not in capsys.readouterr().err
    drawn = read_rrd(rrd)["/world/estimate/backbone"]
    given = read_rrd(tendon_view["rrd"])["/world/estimate/backbone"]
    assert [r["LineStrips3D:strips"] for _, r in drawn] == [
        r["LineStrips3D:strips"] for _, r in given
    ]


def test_imu_twists_turn_a_mounted_imus_frame_about_the_backbone_before_its_mounting() -> None:
    """``with_imu_twists`` on an IMU with a ``mount_rpy``: the disk frame ``R``, then the
    twist about the backbone's tangent ``Rz(psi)``, then the mounting ``M`` (the model's
    order), against ``R`` from the same robot unmounted composed by hand."""
    from dataclasses import replace

    from scipy.spatial.transform import Rotation

    from continuum_mhe.io.raw_imu import mount_rotation
    from continuum_mhe.viewer import backbone_geometry
    from continuum_mhe.viewer.geometry import with_imu_twists

    plain = read_robot("two-section")
    rpy = ((10.0, -20.0, 35.0), (0.0, 90.0, -45.0))
    mounted = replace(
        plain, imus=tuple(replace(imu, mount_rpy=m) for imu, m in zip(plain.imus, rpy))
    )
    rng = np.random.default_rng(2)
    bends = rng.uniform(-1.0, 1.0, (6, 2, 2))
    psi = rng.uniform(-np.pi, np.pi, (6, 2))
    drawn = with_imu_twists(mounted, backbone_geometry(mounted, bends, POINTS), psi)
    disk = backbone_geometry(plain, bends, POINTS).imu_rotation
    for i, m in enumerate(rpy):
        turn = Rotation.from_rotvec(np.outer(psi[:, i], [0.0, 0.0, 1.0])).as_matrix()
        want = disk[:, i] @ turn @ mount_rotation(m)
        np.testing.assert_allclose(drawn.imu_rotation[:, i], want, atol=1e-12)
    assert not np.allclose(mount_rotation(rpy[0]) @ turn[0], turn[0] @ mount_rotation(rpy[0]))


def test_a_paper_formulation_estimate_is_drawn_at_its_own_tip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The paper formulation's ``x, y, z`` are states of their own, off the arc of its
    ``theta, phi``: the drawn tip and trail are the rows' own (as the time plot's), and
    no warning calls the robot the wrong one."""
    meas, est, rrd = tmp_path / "m.csv", tmp_path / "e.csv", tmp_path / "v.rrd"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "2"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--formulation", "paper",
                 "--method", "ekf"]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["view", str(est), "--save", str(rrd)]) == 0
    assert "warning" not in capsys.readouterr().err
    table = read_state_table(est)
    rows = read_rrd(rrd)
    tips = np.array([r["Points3D:positions"][0] for _, r in rows["/world/estimate/tip"]])
    xyz = np.column_stack([table.column(c) for c in "xyz"])
    assert np.max(np.abs(xyz - tips)) < 1e-7  # the file's float32
    arc = np.array([r["LineStrips3D:strips"][0][-1] for _, r in rows["/world/estimate/backbone"]])
    assert np.max(np.linalg.norm(arc - xyz, axis=1)) > 1e-3  # the states do drift apart


def test_view_with_mounting_alone_keeps_the_recorded_sections(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--mounting`` alone draws the robot the estimate records (here one 0.3 m
    section), turned as given, as ``--length`` alone keeps the recorded mounting."""
    meas, est, rrd = tmp_path / "m.csv", tmp_path / "e.csv", tmp_path / "v.rrd"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "1", "--length", "0.3"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", "--length", "0.3"]) == 0
    capsys.readouterr()
    assert main(["view", str(est), "--mounting", "z-up", "--save", str(rrd)]) == 0
    err = capsys.readouterr().err
    assert "1 section (0.3 m)" in err and "warning" not in err, err


def test_the_truths_trail_breaks_where_its_rows_have_no_tip(tmp_path: Path) -> None:
    """Truth rows without ``x, y, z`` (a motion-capture dropout) break the truth's trail,
    as the estimate's breaks at rows without an estimate: no chord across the gap."""
    est, truth, rrd = tmp_path / "e.csv", tmp_path / "t.csv", tmp_path / "v.rrd"
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    truth.write_text("t,x,y,z\n0,0.01,0,0.2\n0.05,0.02,0,0.2\n0.1,,,\n0.15,0.04,0,0.2\n"
                     "0.2,0.05,0,0.2\n")  # fmt: skip
    assert main(["view", str(est), "--truth", str(truth), "--save", str(rrd)]) == 0
    trail = [t for t, _ in read_rrd(rrd)["/world/truth/tip_trail"]]
    assert trail == [50_000_000, 200_000_000]


def test_a_file_without_statuses_is_drawn_without_a_status(tmp_path: Path) -> None:
    """A file with no ``status`` column (a truth, another tool's estimates) is drawn,
    and its rows are not logged as ``ok``: no status at all."""
    est, rrd = tmp_path / "other.csv", tmp_path / "v.rrd"
    est.write_text("t,x,y,z,theta,phi\n0,0,0,0.2,0,0\n0.05,0.01,0,0.2,0.1,0\n")
    assert main(["view", str(est), "--save", str(rrd)]) == 0
    rows = read_rrd(rrd)
    assert len(rows["/world/estimate/tip"]) == 2 and "/status" not in rows


def test_truth_shift_draws_the_truth_on_the_estimates_clock(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A truth whose clock runs 0.5 s ahead: without ``--truth-shift`` the view warns,
    naming the shift; with ``--truth-shift 0.5`` each truth row is drawn 0.5 s earlier
    (beside the estimate it belongs to) and nothing is said. The shift needs a truth."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--seed", "2"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    lines = truth.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("t,"))
    for i in range(head + 1, len(lines)):
        t, rest = lines[i].split(",", 1)
        lines[i] = f"{float(t) + 0.5!r},{rest}"
    late = tmp_path / "late.csv"
    late.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    plain, shifted = tmp_path / "plain.rrd", tmp_path / "shifted.rrd"
    assert main(["view", str(est), "--truth", str(late), "--save", str(plain)]) == 0
    warned = [ln for ln in capsys.readouterr().err.splitlines() if "clocks offset" in ln]
    assert len(warned) == 1 and warned[0].endswith("; --truth-shift 0.5 compares them so)")
    assert main(["view", str(est), "--truth", str(late), "--truth-shift", "0.5",
                 "--save", str(shifted)]) == 0  # fmt: skip
    assert "warning" not in capsys.readouterr().err
    tip = "/world/truth/tip"
    at_plain = [t for t, _ in read_rrd(plain)[tip]]
    at_shifted = [t for t, _ in read_rrd(shifted)[tip]]
    assert len(at_plain) == len(at_shifted) > 100
    assert [a - b for a, b in zip(at_plain, at_shifted)] == [500_000_000] * len(at_plain)
    assert main(["view", str(est), "--truth-shift", "0.5", "--save", str(shifted)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--truth-shift needs --truth" in err


def test_a_viewer_sink_of_an_unknown_kind_or_a_str_path_and_a_replay_of_no_robot(
    tmp_path: Path,
) -> None:
    """``ViewerSink('file', ...)`` is one ``UserError`` naming the kinds (it started a web
    viewer, then failed with a bare ``KeyError`` and left the server running); a path
    given as a ``str`` is taken as a ``Path``; ``replay`` of a robot's name instead of a
    ``Robot`` is a ``UserError`` naming the argument, before anything starts."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.viewer import ViewerSink, replay

    with pytest.raises(UserError, match=r"^ViewerSink kind must be one of save, spawn, web, "):
        ViewerSink("file", tmp_path / "v.rrd")  # type: ignore[arg-type]
    sink = ViewerSink("save", str(tmp_path / "v.rrd"))  # type: ignore[arg-type]
    assert sink.path == tmp_path / "v.rrd"
    with pytest.raises(UserError, match=r"robot"):
        replay(str(tmp_path / "e.csv"), "two-section", sink)  # type: ignore[arg-type]
    assert not (tmp_path / "v.rrd").exists()
