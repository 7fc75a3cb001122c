"""The files the commands write, atomically: an output in a missing folder, a folder, a
link or another format's name, the umask, an existing file kept on error, simulate's two
files or neither, demo's and reproduce's folders (what an interrupted or failed demo
leaves), and main giving the caller its warnings and signal handlers back."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import figures_drawn_small, good_rows, meas_csv, write_file

from continuum_mhe.cli import main


def test_output_folder_missing_is_an_error(tmp_path, capsys):
    meas = meas_csv(tmp_path, good_rows(5))
    assert main(["estimate", str(meas), "-o", str(tmp_path / "no" / "e.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_existing_output_is_kept_on_error(tmp_path):
    meas = write_file(tmp_path / "meas.csv", "t,roll,pitch\n0,0.1,0.1\n0.05,abc,0.1\n")
    est = write_file(tmp_path / "est.csv", "previous result\n")
    assert main(["estimate", str(meas), "-o", str(est)]) == 2
    assert est.read_text() == "previous result\n"


@pytest.mark.parametrize("suffix", [".bag", ".png", ".rrd", ".toml"])
def test_estimate_refuses_an_output_another_reader_would_misread(tmp_path, capsys, suffix):
    meas = meas_csv(tmp_path, good_rows(5))
    out = tmp_path / f"e{suffix}"
    assert main(["estimate", str(meas), "-o", str(out)]) == 2
    assert "an estimate is written as CSV" in capsys.readouterr().err
    assert not out.exists()
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.txt")]) == 0


@pytest.mark.parametrize("target", ["-", "DIR"])
def test_output_must_be_a_regular_file_name(tmp_path, capsys, target):
    meas = meas_csv(tmp_path, good_rows(5))
    out = str(tmp_path) if target == "DIR" else target
    assert main(["estimate", str(meas), "-o", out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert ("standard output" if target == "-" else "is a directory") in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["meas.csv"]


def test_an_output_link_is_written_through(tmp_path):
    """``-o LINK`` writes the file the link points to and keeps the link (a link such as
    ``/dev/stdout`` is not replaced by a file); a link to a folder or a device is
    refused as they are."""
    meas = meas_csv(tmp_path, good_rows(5))
    real, link = tmp_path / "real.csv", tmp_path / "link.csv"
    real.write_text("old\n")
    link.symlink_to(real.name)
    assert main(["estimate", str(meas), "-o", str(link), "--overwrite"]) == 0
    assert link.is_symlink() and link.readlink() == Path("real.csv")
    assert real.read_text().startswith("# continuum-mhe = ")
    dangling = tmp_path / "new-link.csv"
    dangling.symlink_to("made.csv")
    assert main(["estimate", str(meas), "-o", str(dangling)]) == 0
    assert dangling.is_symlink() and (tmp_path / "made.csv").is_file()
    to_folder, to_device = tmp_path / "to-folder.csv", tmp_path / "to-device.csv"
    to_folder.symlink_to(tmp_path)
    to_device.symlink_to("/dev/null")
    assert main(["estimate", str(meas), "-o", str(to_folder), "--overwrite"]) == 2
    assert main(["estimate", str(meas), "-o", str(to_device), "--overwrite"]) == 2
    assert to_folder.is_symlink() and to_device.is_symlink()


@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_follow_the_umask_at_write_time(tmp_path, umask, mode):
    """The umask in force when the file is written (set here after the import), not
    the one at import: a 0o077 caller gets a private file."""
    import os
    import stat

    meas, est = meas_csv(tmp_path, good_rows(5)), tmp_path / "est.csv"
    old = os.umask(umask)
    try:
        assert main(["estimate", str(meas), "-o", str(est)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(est.stat().st_mode) == mode


def test_simulate_writes_both_files_or_neither(tmp_path, capsys):
    """simulate writes both files or neither: a --truth path in a missing folder, or
    --truth naming -o's file, is one line, exit 2, and no measurement file is written."""
    meas, lost = tmp_path / "g.csv", tmp_path / "no" / "t.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(lost)]) == 2
    assert "folder" in capsys.readouterr().err and not meas.exists()
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(meas)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("--truth names the measurement file -o too; give two files")
    assert len(err.splitlines()) == 1 and not meas.exists()
    # a figure's name for either CSV is refused (not written as CSV under that name)
    for argv in (
        ["-o", str(tmp_path / "m.png")],
        ["-o", str(meas), "--truth", str(tmp_path / "t.pdf")],
    ):
        assert main(["simulate", "paper3d", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert (
            len(err.splitlines()) == 1 and "is written as CSV (.csv or .txt, or no suffix)" in err
        )
        assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_benchmark_checks_its_json_path_before_the_run(tmp_path, capsys, monkeypatch):
    from continuum_mhe.cli import benchmark

    def no_run(*args, **kwargs):
        raise AssertionError("the benchmark ran before its --json path was checked")

    monkeypatch.setattr(benchmark, "run_benchmark", no_run)
    monkeypatch.setattr(benchmark, "run_robot_benchmark", no_run)
    json_path = str(tmp_path / "no" / "b.json")
    assert main(["benchmark", "--skip", "do-mpc", "--json", json_path]) == 2
    assert capsys.readouterr().err.strip().endswith("does not exist")


def test_demo_refuses_a_file_as_its_folder(tmp_path, capsys):
    target = tmp_path / "afile"
    target.write_text("mine\n")
    assert main(["demo", "--out", str(target)]) == 2
    assert capsys.readouterr().err.strip().endswith("afile: exists and is not a folder")
    assert target.read_text() == "mine\n"


@pytest.fixture
def short_demo(monkeypatch):
    """``demo`` on a 2 s recording (its default is 20 s): the tests that use it check
    the files the demo writes and removes, which the recording's length does not
    change (the README's numbers are checked on the full demo in test_hygiene)."""
    from continuum_mhe.cli import demo

    short = functools.partial(demo.simulate_robot, duration=2.0)
    monkeypatch.setattr(demo, "simulate_robot", short)


def test_a_demo_s_estimates_are_evaluated_on_its_robot(
    tmp_path, capsys, monkeypatch, short_demo
) -> None:
    """The demo's estimate files record their method and --robot, as estimate's do:
    evaluate of a two-section demo's file against its truth takes the two-section robot
    without --robot (not the default 0.2 m section, refused)."""
    figures_drawn_small(monkeypatch)  # its estimate files, not its figures
    out = tmp_path / "d"
    assert main(["demo", "--robot", "two-section", "--out", str(out)]) == 0
    assert (
        (out / "estimates_ekf.csv")
        .read_text()
        .startswith('# options = {method = "ekf", robot = "two-section"}\n')
    )
    capsys.readouterr()
    assert main(["evaluate", str(out / "estimates_mhe.csv"), str(out / "truth.csv")]) == 0
    assert "estimated with --robot two-section (its options line)" in capsys.readouterr().err


def test_a_demo_of_one_section_with_its_imu_midway_runs_paper3d(
    tmp_path, capsys, monkeypatch, short_demo
) -> None:
    """A one-section robot whose IMU is not at the tip gets the one-section scenario
    (paper3d), not refused as a robot of too few sections for the spatial one."""
    figures_drawn_small(monkeypatch)  # its scenario and estimates, not its figures
    robot = tmp_path / "mid.toml"
    robot.write_text("[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\nat = 0.5\n")
    out = tmp_path / "d"
    assert main(["demo", "--robot", str(robot), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "paper3d, 1 section (0.2 m), IMUs at 1@0.5" in said
    assert main(["evaluate", str(out / "estimates_mhe.csv"), str(out / "truth.csv")]) == 0


@pytest.mark.parametrize("existing", [False, True], ids=["new-folder", "existing-folder"])
def test_an_interrupted_demo_leaves_nothing_it_wrote(
    tmp_path, capsys, monkeypatch, existing, short_demo
):
    """Ctrl-C during ``demo`` leaves nothing it wrote: the files are written after the
    estimates, and an interruption while writing (here: while saving the second figure)
    removes the files it created, and the folder it created; a user's own files in an
    existing folder stay."""
    from continuum_mhe.evaluation import plotting

    out = tmp_path / "demo"
    if existing:
        out.mkdir(parents=True)
        (out / "mine.txt").write_text("mine\n")
    saved = []
    real_save = plotting.save

    def save_then_interrupt(fig, path, formats=("png",)):
        saved.append(path)
        if len(saved) == 2:
            raise KeyboardInterrupt
        return real_save(fig, path, formats)

    monkeypatch.setattr(plotting, "save", save_then_interrupt)
    assert main(["demo", "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip().endswith("interrupted")
    assert len(saved) == 2
    if existing:
        assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]
    else:
        assert not out.exists()  # the folder it made too


def test_a_failed_demo_keeps_the_files_that_were_there(tmp_path, capsys, short_demo):
    """A demo that fails writing (a read-only truth.csv) removes only what it created:
    the read-only file, never replaced, stays as it was (the clean-up does not delete
    it), and so does a replaced estimates file."""
    out = tmp_path / "demo"
    out.mkdir()
    (out / "estimates_mhe.csv").write_text("old\n")
    (out / "truth.csv").write_text("mine\n")
    (out / "truth.csv").chmod(0o444)
    assert main(["demo", "--out", str(out), "--overwrite"]) == 2
    assert "truth.csv: the file is read-only; not replaced" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["estimates_mhe.csv", "truth.csv"]
    assert (out / "truth.csv").read_text() == "mine\n"
    assert (out / "estimates_mhe.csv").read_text().startswith("# options = ")  # replaced, kept


def test_demo_checks_its_folder_before_estimating(tmp_path, capsys, monkeypatch):
    from continuum_mhe.cli import demo

    def no_run(*args, **kwargs):
        raise AssertionError("the demo simulated before checking its --out")

    monkeypatch.setattr(demo, "simulate_robot", no_run)
    (tmp_path / "afile").write_text("x\n")
    assert main(["demo", "--out", str(tmp_path / "afile" / "sub")]) == 2
    assert capsys.readouterr().err.strip().endswith("afile is not a folder")


def test_demo_and_reproduce_keep_their_files_in_their_folder_without_overwrite(
    tmp_path, capsys, monkeypatch
):
    """``demo`` does not replace a ``truth.csv`` already in its folder, nor ``reproduce``
    its experiments' data, without ``--overwrite``: one line naming the file and
    ``--overwrite``, exit 2, before any work, the file kept. A file of another name does
    not stop the demo, nor another part's data ``reproduce --only`` (the report covers
    every part in the folder)."""
    from continuum_mhe.cli import demo
    from continuum_mhe.reproduce import pipeline

    def no_run(*args, **kwargs):
        raise RuntimeError("ran")

    monkeypatch.setattr(demo, "simulate_robot", no_run)
    monkeypatch.setattr(pipeline, "reproduce", no_run)
    out = tmp_path / "out"
    out.mkdir()
    for name, command in (("truth.csv", ["demo"]), ("exp1_synthetic3d.json",
                          ["reproduce", "--quick"])):  # fmt: skip
        (out / name).write_text("mine\n")
        assert main([*command, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err == (
            f"continuum-mhe: error: {out / name}: exists; give --overwrite to replace it, or "
            "another --out\n"
        )
        assert (out / name).read_text() == "mine\n"
        assert main([*command, "--out", str(out), "--overwrite"]) == 70  # the stand-in ran
        assert "RuntimeError: ran" in capsys.readouterr().err
    (out / "truth.csv").rename(out / "notes.txt")
    assert main(["demo", "--out", str(out)]) == 70
    assert main(["reproduce", "--quick", "--only", "beyond", "--out", str(out)]) == 70
    assert main(["reproduce", "--quick", "--only", "paper", "--out", str(out)]) == 2
    capsys.readouterr()


def test_main_gives_the_caller_its_warnings_and_signal_handlers_back(tmp_path):
    """A script or test that calls ``main`` keeps numpy's warnings, its warning format
    and its Ctrl-C handler: the command's settings do not outlive the call."""
    import signal
    import warnings

    meas, est = meas_csv(tmp_path, good_rows(5)), tmp_path / "est.csv"
    fmt, filters = warnings.formatwarning, list(warnings.filters)
    handlers = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    assert warnings.formatwarning is fmt
    assert warnings.filters == filters
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers
    with pytest.warns(RuntimeWarning, match="divide by zero"):
        np.float64(1.0) / np.float64(0.0)


def test_a_second_demo_in_its_own_folder_replaces_its_files(tmp_path, monkeypatch, short_demo):
    """The README's main command runs twice: without ``--out`` the demo writes into its
    own folder and replaces the files of the demo before (with ``--out`` a folder that
    holds them needs ``--overwrite``: the test above)."""
    from continuum_mhe.cli.demo import DEFAULT_OUT

    monkeypatch.chdir(tmp_path)
    figures_drawn_small(monkeypatch)  # which files it replaces, not what they show
    assert main(["demo"]) == 0
    for name in ("truth.csv", "estimates_mhe.csv"):
        (tmp_path / DEFAULT_OUT / name).write_text("old\n")
    assert main(["demo"]) == 0
    assert (tmp_path / DEFAULT_OUT / "truth.csv").read_text().startswith("t,")
    assert (tmp_path / DEFAULT_OUT / "estimates_mhe.csv").read_text().startswith("# options")


def test_plot_of_a_folder_without_results_says_so_before_its_options(tmp_path, capsys) -> None:
    """``plot FOLDER -o P.png`` on a folder that ``reproduce`` did not write: the folder
    holds no results (not that the folder is a reproduce folder and -o the fault)."""
    from continuum_mhe.cli import main

    folder = tmp_path / "empty"
    folder.mkdir()
    assert main(["plot", str(folder), "-o", str(tmp_path / "p.png")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"continuum-mhe: error: {folder}: no experiment data (expected "), line
    assert not (tmp_path / "p.png").exists()
