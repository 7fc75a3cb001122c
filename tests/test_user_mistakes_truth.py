"""User mistakes in scoring and drawing an estimate against a truth (evaluate, plot and
view, and the library's compute_metrics and aligned_truth): positions in mm or cm,
angles in degrees, a truth of another robot (other sections, lengths or mounting), on
another clock or in a motion capture's frame, partial or with gaps, an estimate given
as the truth: refused in one line, or warned of with the likely cause."""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import figures_drawn_small, notes_and_rows, simulated
from numpy.testing import assert_allclose

from continuum_mhe import (
    compute_metrics,
    make_estimator,
    make_formulation,
    simulate,
)
from continuum_mhe.cli import main
from continuum_mhe.errors import UserError
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.simulation.scenarios import simulate_robot

DATA_ROBOTS = Path(__file__).resolve().parents[1] / "src" / "continuum_mhe" / "data" / "robots"


def test_evaluate_of_a_cut_estimate_warns_that_it_scores_a_part(tmp_path, capsys) -> None:
    """An estimate of the first 30 % of a recording (interrupted, cut with head) is
    scored on that part with a warning giving the span it covers; a truth sampled twice
    as densely as the estimate is no mistake and gets none."""
    m, t = simulated(tmp_path, "a")
    est, cut = tmp_path / "e.csv", tmp_path / "cut.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    notes, rows = notes_and_rows(est)
    cut.write_text("".join(notes + rows[:31]))  # the column line and 30 rows
    capsys.readouterr()
    assert main(["evaluate", str(cut), str(t)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"continuum-mhe: warning: {cut}: its rows cover t = 0 to 1.45 s of {t}'s 0 to 5 s "
        "(29 %): the scores are of that part only (an interrupted or cut estimate?)"
    ]
    dense_m, dense_t = simulated(tmp_path, "d", "--dt", "0.025")
    sparse = tmp_path / "sparse.csv"  # every second row of a 0.025 s estimate
    assert main(["estimate", str(dense_m), "-o", str(sparse), "--method", "ekf"]) == 0
    notes, rows = notes_and_rows(sparse)
    sparse.write_text("".join(notes + rows[:1] + rows[1::2]))
    capsys.readouterr()
    assert main(["evaluate", str(sparse), str(dense_t)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_evaluate_scores_every_section_end_the_truth_has_and_names_a_typo(tmp_path, capsys) -> None:
    """Every section end and bend both files have is scored: a three-section truth
    without section 2's end scores sections 1 and 3 (the count does not stop at the
    gap); a header typo (``xx_3``, ``x-3``) is named in a warning; a truth with
    ``theta_2`` and no ``phi_2``, or without section 2's bend, is scored by ``evaluate``
    and drawn by ``plot``."""
    m, t, robot = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "three.toml"
    robot.write_text(
        "".join("[[section]]\nlength = 0.1\ntheta_max = 3.0\n" for _ in range(3))
        + "".join(f"[[imu]]\nsection = {k}\n" for k in (1, 2, 3))
    )
    assert main(["simulate", "spatial", "--robot", str(robot), "--duration", "2",
                 "-o", str(m), "--truth", str(t)]) == 0  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "--robot", str(robot), "--method", "ekf",
                 "-o", str(est)]) == 0  # fmt: skip
    header, *rows = t.read_text().splitlines(keepends=True)
    names = header.strip().split(",")
    keep = [i for i, c in enumerate(names) if c in "t x y z x_1 y_1 z_1 x_3 y_3 z_3".split()]
    gap = tmp_path / "gap.csv"
    gap.write_text("".join(",".join(r.strip().split(",")[i] for i in keep) + "\n"
                           for r in [header, *rows]))  # fmt: skip
    capsys.readouterr()
    assert main(["evaluate", str(est), str(gap), "--robot", str(robot), "--json"]) == 0
    assert sorted(json.loads(capsys.readouterr().out)["section_end_mean_mm"]) == ["1", "3"]
    typo = tmp_path / "typo.csv"
    typo.write_text(header.replace("x_3", "xx_3") + "".join(rows))
    assert main(["evaluate", str(est), str(typo), "--robot", str(robot), "--json"]) == 0
    out = capsys.readouterr()
    assert sorted(json.loads(out.out)["section_end_mean_mm"]) == ["1", "2"]
    assert out.err == (
        f"continuum-mhe: warning: {typo}: column(s) xx_3 for x_3? (a typo: such a column "
        "is left out)\n"
    )
    substituted = tmp_path / "substituted.csv"
    substituted.write_text(header.replace("x_3", "x-3") + "".join(rows))
    assert main(["evaluate", str(est), str(substituted), "--robot", str(robot)]) == 0
    assert "column(s) x-3 for x_3?" in capsys.readouterr().err
    # a bend without its phi, and a section's bend left out: each bend column there is
    # scored, none stops the command
    for drop in (("phi_2",), ("theta_2", "phi_2")):
        keep = [i for i, c in enumerate(names) if c not in drop]
        partial = tmp_path / f"partial{len(drop)}.csv"
        partial.write_text("".join(",".join(r.strip().split(",")[i] for i in keep) + "\n"
                                   for r in [header, *rows]))  # fmt: skip
        assert main(["evaluate", str(est), str(partial), "--robot", str(robot)]) == 0
        out = capsys.readouterr().out
        assert "RMSE theta_3, phi_3" in out
        assert ("RMSE theta_2 " in out) == (len(drop) == 1)
        fig = tmp_path / f"partial{len(drop)}.png"
        assert main(["plot", str(est), "--truth", str(partial), "--robot", str(robot),
                     "-o", str(fig)]) == 0  # fmt: skip
        assert fig.read_bytes()[:4] == b"\x89PNG"
    assert main(["evaluate", str(est), str(t), "--robot", str(robot)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_evaluate_with_times_that_do_not_match_is_an_error(tmp_path, capsys) -> None:
    """A truth at another rate is interpolated at the estimate's times (a note); one in
    milliseconds matches nowhere: one line naming the truth file and its unit, exit 2
    (``evaluate`` and ``plot`` alike, no figure); with its column named ``t_ms`` it is
    scored as the one in seconds."""
    m, _ = simulated(tmp_path, "a")
    _, t2 = simulated(tmp_path, "b", "--dt", "0.0493")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t2)]) == 0
    assert "the truth is interpolated linearly at them (100 of 101 rows)" in (
        capsys.readouterr().err
    )
    rows = t2.read_text().splitlines()
    ms = tmp_path / "b_ms.csv"
    ms.write_text(
        "\n".join([rows[0], *(f"{1000 * float(r.split(',')[0])!r},{r.split(',', 1)[1]}"
                             for r in rows[1:])]) + "\n"
    )  # fmt: skip
    said = (
        f"continuum-mhe: error: {ms}: t advances by a median of 49.3 s per sample, the "
        "estimate's by 0.05 s (986 times as long): is the truth's t in milliseconds? name "
        "its column t_ms (read in milliseconds), or give seconds\n"
    )
    assert main(["evaluate", str(est), str(ms)]) == 2
    assert capsys.readouterr().err == said
    fig = tmp_path / "fig.png"
    assert main(["plot", str(est), "--truth", str(ms), "-o", str(fig)]) == 2
    assert capsys.readouterr().err == said and not fig.exists()
    assert main(["evaluate", str(est), str(t2)]) == 0
    in_seconds = capsys.readouterr().out
    ms.write_text(ms.read_text().replace("t,", "t_ms,", 1))
    assert main(["evaluate", str(est), str(ms)]) == 0
    assert capsys.readouterr().out == in_seconds
    # a sparse truth in seconds on another clock (every 50th row, 40 s late): its steps
    # are long, but read in milliseconds its times would not meet the estimate's: the
    # clock's hint, not milliseconds
    late = tmp_path / "b_late.csv"
    late.write_text(
        "\n".join([rows[0], *(f"{40 + float(r.split(',')[0])!r},{r.split(',', 1)[1]}"
                             for r in rows[1::50])]) + "\n"
    )  # fmt: skip
    assert main(["evaluate", str(est), str(late)]) == 2
    err = capsys.readouterr().err
    assert "is the truth's t in milliseconds" not in err and "--truth-shift 40 " in err, err


def test_evaluate_of_another_length_gets_a_hint(tmp_path, capsys) -> None:
    m, t = simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf", "--length", "0.5"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 0
    out, err = capsys.readouterr()
    # evaluated on the length the estimate records (a note says so); one warning (not a
    # second, est against truth, for the same mistake), naming the truth and the length
    # it was made for
    assert err.count("warning") == 1, err
    assert f"note: {est} was estimated on 1 section (0.5 m), IMUs at 1@1, z-up" in err
    assert f"warning: {t}: its tip is 0.40 times as far from the base" in err
    # not "pass the --length": the estimate would then misfit it, the other way round
    assert "made for a robot of about 0.2 m; the estimate's robot (its options line) is" in err
    assert "SRMSE                not given" in out and not re.search(r"SRMSE\s+\d", out)
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf", "--overwrite"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 0
    out, err = capsys.readouterr()
    assert "warning" not in err  # same length: no hint
    summed = r"SRMSE\s+\d\.\d{4} \(sum of the RMSEs of x, y, z, theta, phi, m \+ rad\)"
    assert re.search(summed, out)


@pytest.mark.parametrize(
    ("unit", "factor", "angles"), [("mm", 1000.0, True), ("cm", 100.0, True), ("mm", 1000.0, False)]
)
def test_evaluate_refuses_a_truth_whose_positions_are_in_mm_or_cm(
    tmp_path, capsys, unit: str, factor: float, angles: bool
) -> None:
    """A truth file whose x, y, z are in mm (or cm), with or without its bend angles:
    one line naming the file and the likely unit, exit 2, no figures (not a warning about
    a robot 1000 times as long and a tip error of hundreds of metres)."""
    m, t = simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    lines = t.read_text().splitlines()
    header = lines[0].split(",")
    xyz = [header.index(c) for c in ("x", "y", "z")]
    keep = [i for i, c in enumerate(header) if angles or c not in ("theta", "phi")]
    rows = []
    for line in lines[1:]:
        v = line.split(",")
        for i in xyz:
            v[i] = repr(float(v[i]) * factor)
        rows.append(",".join(v[i] for i in keep))
    scaled = tmp_path / "truth_scaled.csv"
    scaled.write_text(",".join(header[i] for i in keep) + "\n" + "\n".join(rows) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(scaled)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert err.startswith(f"continuum-mhe: error: {scaled}: its tip is ")
    assert err.rstrip().endswith(
        "times as far from the base as a robot of 0.2 m reaches: "
        f"positions in {unit}? give x, y, z in m"
    )


def test_position_units_without_angles_known_answers() -> None:
    """A file of tip positions alone (no angles): a straight robot's tip 100.5 times as
    far as the robot's length is in cm (not mm, though over 100); 150 times, beyond any
    shape in cm, is mm; 1.0 times is metres."""
    from continuum_mhe.io.position_units import position_unit_problem

    names = ("x", "y", "z")
    for factor, unit in ((100.5, "cm"), (150.0, "mm"), (1.0, None)):
        rows = np.tile([0.0, 0.0, 0.2 * factor], (5, 1))
        said = position_unit_problem(names, rows, (0.2,))
        assert said.endswith(f"positions in {unit}? give x, y, z in m") if unit else said == ""


def test_evaluate_with_another_robot_than_the_estimate_records_warns(tmp_path, capsys) -> None:
    """An estimate made with one robot file, evaluated with ``--robot`` naming another of
    other section lengths: a warning naming both and their lengths (the figures, in %
    of the length, are the given robot's); the recorded robot itself, or ``--robot``
    left out, gives none."""
    robot = tmp_path / "mine.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.15\ntheta_max = 2.5\n'
        "[[section]]\nlength = 0.12\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    m, t, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    argv = ["simulate", "spatial", "--robot", str(robot), "-o", str(m), "--truth", str(t)]
    assert main([*argv, "--duration", "2"]) == 0
    assert main(["estimate", str(m), "-o", str(est), "--robot", str(robot), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t), "--robot", "two-section"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning") == 1, err
    assert (
        f"warning: {est} was estimated with --robot {robot} (its options line: sections of "
        "0.15, 0.12 m), not with --robot two-section (sections of 0.16, 0.14 m); the given "
        "one is used: leave --robot out to use the recorded one"
    ) in err
    for extra in (["--robot", str(robot)], []):
        assert main(["evaluate", str(est), str(t), *extra]) == 0
        assert "warning" not in capsys.readouterr().err


def test_evaluate_of_drifting_positions_names_no_other_length(tmp_path, capsys) -> None:
    """The paper formulation's positions drift from its angles (rows ``drifted``), by a
    factor that changes from row to row: no warning that the file was made for a robot
    of another length, which a constant factor alone means."""
    from continuum_mhe.io.position_units import steady_ratio

    m, t = simulated(tmp_path, "p", "--duration", "20")
    est = tmp_path / "e.csv"
    argv = ["estimate", str(m), "-o", str(est), "--formulation", "paper", "--paper-start"]
    assert main(argv) == 0
    assert "drifted" in capsys.readouterr().err
    assert main(["evaluate", str(est), str(t)]) == 0
    assert "warning" not in capsys.readouterr().err
    assert steady_ratio(np.array([2.5, 2.51, 2.49, np.nan])) == pytest.approx(2.5)
    assert steady_ratio(np.array([1.0, 1.07, 1.19, 1.49, 1.64])) is None


def test_evaluate_of_an_unknown_status_is_an_error(tmp_path, capsys) -> None:
    # a status outside the vocabulary (edited by hand, another tool's "OK") is not read
    # as a row like any other, to which evaluate and view would give no meaning
    m, t = simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    lines = est.read_text().splitlines(keepends=True)
    row = next(i for i, line in enumerate(lines) if ",ok," in line)
    lines[row] = lines[row].replace(",ok,", ",OK,")
    est.write_text("".join(lines))
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"line {row + 1}: status 'OK' is not one of ok, dropout," in err


def test_evaluate_against_another_robots_truth_gives_no_srmse(tmp_path, capsys) -> None:
    """A two-section truth for a one-section estimate: the warning, and no SRMSE summed
    over the x, y, z they share that would read as a score."""
    m, _ = simulated(tmp_path, "a")
    two = tmp_path / "two.csv"
    args = ["simulate", "spatial", "--robot", "two-section", "--duration", "5"]
    assert main([*args, "-o", str(tmp_path / "m2.csv"), "--truth", str(two)]) == 0
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(two)]) == 0
    out, err = capsys.readouterr()
    assert "warning" in err and "SRMSE                not given" in out
    # one warning: the truth's length is not checked against a robot it is not of
    assert err.count("warning") == 1 and "another robot" in err, err


def test_evaluate_of_a_partial_truth_warns(tmp_path, capsys) -> None:
    m, t = simulated(tmp_path, "a")  # 101 rows
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    t.write_text("\n".join(t.read_text().splitlines()[:31]) + "\n")  # 30 of 101 rows
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("continuum-mhe: warning: ")
    assert "30 of the estimate's 101 rows compared (a truth of part of the run?)" in err


THREE_SECTIONS = "".join(
    f"[[section]]\nlength = {v}\ntheta_max = 2.0\n" for v in (0.12, 0.1, 0.08)
) + "".join(f"[[imu]]\nsection = {k}\n" for k in (1, 2, 3))


@pytest.fixture(scope="module")
def two_and_three(tmp_path_factory) -> dict[str, Path]:
    """A two-section EKF estimate, its truth, and a three-section truth at the same t."""
    tmp = tmp_path_factory.mktemp("robots")
    (tmp / "robot3.toml").write_text(THREE_SECTIONS)
    paths = {k: tmp / f"{k}.csv" for k in ("m2", "t2", "e2", "m3", "t3")}
    sim = ["simulate", "spatial", "--duration", "2"]
    assert main([*sim, "--robot", "two-section", "-o", str(paths["m2"]),
                 "--truth", str(paths["t2"])]) == 0  # fmt: skip
    assert main([*sim, "--robot", str(tmp / "robot3.toml"), "-o", str(paths["m3"]),
                 "--truth", str(paths["t3"])]) == 0  # fmt: skip
    argv = ["estimate", str(paths["m2"]), "-o", str(paths["e2"]), "--robot", "two-section"]
    assert main([*argv, "--method", "ekf"]) == 0
    return paths


def test_evaluate_against_a_truth_of_more_sections_warns_and_gives_no_srmse(
    two_and_three, capsys
) -> None:
    """A two-section estimate against a three-section truth: a warning that the truth is
    of another robot, and no SRMSE (None in the JSON)."""
    e2, t2, t3 = two_and_three["e2"], two_and_three["t2"], two_and_three["t3"]
    capsys.readouterr()
    assert main(["evaluate", str(e2), str(t2), "--robot", "two-section"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and re.search(r"SRMSE\s+\d", out)
    assert main(["evaluate", str(e2), str(t3), "--robot", "two-section"]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"continuum-mhe: warning: {t3}: its columns (theta_1, theta_2, theta_3) do not fit the "
        "robot (2 sections (0.16 m, 0.14 m), IMUs at 1@1, 2@1, z-up): extra theta_3: the truth "
        "is of another robot (pass --robot with its robot)\n"
    )
    assert "SRMSE                not given" in out and not re.search(r"SRMSE\s+\d", out)
    assert main(["evaluate", str(e2), str(t3), "--robot", "two-section", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["srmse"] is None


def test_a_truth_of_fewer_sections_is_said_in_evaluate_and_refused_in_plot(
    two_and_three, tmp_path, capsys
) -> None:
    """A three-section estimate against a two-section truth: its columns are a subset of
    the three-section robot's, but its section 2 ends at its tip in every row. evaluate
    warns that it is of another robot and gives no SRMSE; plot refuses it in one line;
    the three-section truth passes both."""
    robot3 = two_and_three["m3"].parent / "robot3.toml"
    e3 = tmp_path / "e3.csv"
    assert main(["estimate", str(two_and_three["m3"]), "--robot", str(robot3), "--method",
                 "ekf", "-o", str(e3)]) == 0  # fmt: skip
    t2, t3 = two_and_three["t2"], two_and_three["t3"]
    capsys.readouterr()
    assert main(["evaluate", str(e3), str(t2), "--robot", str(robot3)]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"continuum-mhe: warning: {t2}: section 2's end is its tip in every row: a robot of "
        "2 section(s), not 3: the truth is of another robot (pass --robot with its robot)\n"
    )
    assert "SRMSE                not given" in out
    assert main(["plot", str(e3), "--truth", str(t2), "-o", str(tmp_path / "p.png")]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {t2}: the truth's section 2 ends at its tip in every row: a "
        "truth of a robot of 2 section(s), not of this estimate's 3?\n"
    )
    assert not (tmp_path / "p.png").exists()
    # without section 1's columns (a truth may have some sections' and not others')
    table = read_state_table(t2)
    keep = [i for i, n in enumerate(table.names) if not n.endswith("_1")]
    gapped = tmp_path / "t2_gapped.csv"
    write_table(gapped, ["t", *(table.names[i] for i in keep)],
                np.column_stack([table.t, table.values[:, keep]]).tolist())  # fmt: skip
    assert main(["evaluate", str(e3), str(gapped), "--robot", str(robot3)]) == 0
    assert "section 2's end is its tip in every row" in capsys.readouterr().err
    assert main(["evaluate", str(e3), str(t3), "--robot", str(robot3)]) == 0
    out, err = capsys.readouterr()
    assert err == "" and re.search(r"SRMSE\s+\d", out)


def _on_the_device_clock(src: Path, dst: Path, t0: float) -> list[str]:
    """``src`` with ``t0`` s added to every row's t (the first column), as a device
    clock that has run for days gives it; the new t cells, in order."""
    lines, cells = src.read_text().splitlines(keepends=True), []
    with dst.open("w") as fh:
        for ln in lines:
            if ln.startswith("#") or not ln[0].isdigit():
                fh.write(ln)
                continue
            t, rest = ln.split(",", 1)
            cells.append(repr(t0 + float(t)))
            fh.write(f"{cells[-1]},{rest}")
    return cells


def test_evaluate_says_device_clock_times_that_differ_differently(tmp_path, capsys) -> None:
    """Times of a device clock past 4.3e6 s are said as they read back, so times 0.05 s
    apart differ in the messages (%g would print both as ``4.29496e+06``, in ``its rows
    cover t = ...`` and ``t=... does not increase (previous t=...)``)."""
    m, t = simulated(tmp_path, "a")
    est, cut = tmp_path / "e.csv", tmp_path / "cut.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    notes, rows = notes_and_rows(est)
    cut.write_text("".join(notes + rows[:31]))
    t0 = 4294960.0
    cut_dev, t_dev = tmp_path / "cut_dev.csv", tmp_path / "t_dev.csv"
    te, tt = _on_the_device_clock(cut, cut_dev, t0), _on_the_device_clock(t, t_dev, t0)
    capsys.readouterr()
    assert main(["evaluate", str(cut_dev), str(t_dev)]) == 0
    assert capsys.readouterr().err.splitlines() == [
        f"continuum-mhe: warning: {cut_dev}: its rows cover t = 4294960 to 4294961.45 s of "
        f"{t_dev}'s 4294960 to 4294965 s (29 %): the scores are of that part only (an "
        "interrupted or cut estimate?)"
    ]
    assert (te[-1], tt[-1]) == ("4294961.45", "4294965.0")
    notes, rows = notes_and_rows(cut_dev)
    back = tmp_path / "back.csv"  # the fourth row again after the fifth: 0.05 s back
    back.write_text("".join(notes + rows[:6] + rows[4:5]))
    assert main(["evaluate", str(back), str(t_dev)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {back}: line {len(notes) + 7}: t={te[3]} does not increase "
        f"(previous t={te[4]})\n"
    )
    assert te[3] != te[4]


def test_evaluate_of_a_multi_section_estimate_without_its_robot_is_an_error(
    two_and_three, tmp_path, capsys
) -> None:
    """evaluate e2.csv t2.csv of a multi-section estimate without --robot takes the
    robot file the estimate's options line names (said in a note), not the one-section
    0.2 m robot; without that line (an estimate from elsewhere), an error naming --robot."""
    e2, t2 = two_and_three["e2"], two_and_three["t2"]
    capsys.readouterr()
    assert main(["evaluate", str(e2), str(t2)]) == 0
    out, err = capsys.readouterr()
    assert "evaluated on that robot (pass --robot for another)" in err and "tip error mean" in out
    bare = tmp_path / "bare.csv"  # the same rows without the comment lines
    bare.write_text("".join(ln for ln in e2.read_text().splitlines(True) if ln[0] != "#"))
    assert main(["evaluate", str(bare), str(t2)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {bare}: its columns (theta_1, theta_2) do not fit the robot "
        "(1 section (0.2 m), IMUs at 1@1, z-up): missing theta; extra theta_1, theta_2; pass "
        "--robot with the robot it was estimated on\n"
    )
    robot3 = two_and_three["m2"].parent / "robot3.toml"
    assert main(["evaluate", str(e2), str(two_and_three["t3"]), "--robot", str(robot3)]) == 2
    assert "missing theta_3; pass --robot" in capsys.readouterr().err
    tip = tmp_path / "tip.csv"  # an estimate of the tip only: no robot to check against
    rows = e2.read_text().splitlines()
    tip.write_text("\n".join(",".join(r.split(",")[:4]) for r in rows) + "\n")
    assert main(["evaluate", str(tip), str(t2), "--robot", "two-section"]) == 0
    assert "tip error mean" in capsys.readouterr().out


def test_compute_metrics_refuses_what_does_not_fit_in_one_user_error() -> None:
    """``compute_metrics`` names each mistake in a UserError: an estimate series given
    for its array, arrays of different lengths or with another column count than their
    names, a length that is not a number, a string for the names; a length or positions
    in mm (as ``evaluate`` refuses them)."""
    rec = simulate("paper3d", duration=2.0, seed=1)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    in_mm = rec.truth.copy()
    in_mm[:, :3] *= 1000.0
    cases = [
        ((s, rec.truth, 0.2), "not an EstimateSeries: pass its .output"),
        ((s.output[:-1], rec.truth, 0.2), "estimate has 40 rows but truth has 41"),
        ((s.output, rec.truth, "0.2"), "length must be a number"),
        ((s.output, rec.truth, -0.2), "length must be a positive number"),
        ((s.output, rec.truth, math.inf), "length must be a positive number"),
        ((s.output, rec.truth[:, :3], 0.2), r"truth has 3 columns, but names gives 5"),
        ((s.output, rec.truth, 0.2, ["x", "y", "z"]), "estimate has 5 columns, but names gives 3"),
        ((s.output, rec.truth, 0.2, "xyz"), "names must be a sequence of column names"),
        ((s.output[:, :1], rec.truth[:, :1], 0.2, ["x"]), "both sides need the tip column 'y'"),
        ((s.output, rec.truth, 200), r"length 200 m is over 5 m: .*millimetres"),
        ((s.output, in_mm, 0.2), r"^truth: its tip is 1000 times as far .* positions in mm\?"),
        ((in_mm, in_mm, 0.2), r"^estimate: its tip is 1000 times as far .* positions in mm\?"),
    ]
    for args, match in cases:
        with pytest.raises(UserError, match=match):
            compute_metrics(*args)


def test_compute_metrics_refuses_positions_in_mm_of_a_robot_of_several_sections() -> None:
    """Positions in mm on a two-section robot, whose bend columns (theta_1, theta_2, ...)
    the one ``length`` cannot check: the tip's distance from the base alone says it (a
    2,000 mm tip error without it), on either side and on both."""
    robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    rec = simulate_robot("s-curve", robot, duration=1.0, seed=1)
    s = make_estimator("ekf", make_formulation("bend", robot)).run(rec.t, rec.z)
    names = list(s.names)
    metres = [i for i, o in enumerate(s.outputs) if o.unit == "m"]
    est_mm, truth_mm = s.output.copy(), rec.truth.copy()
    est_mm[:, metres] *= 1000.0
    truth_mm[:, metres] *= 1000.0
    assert compute_metrics(s.output, rec.truth, 0.3, names).tip_mean_mm < 50.0
    for args, side in (((est_mm, rec.truth), "estimate"), ((s.output, truth_mm), "truth"),
                       ((est_mm, truth_mm), "estimate")):  # fmt: skip
        with pytest.raises(UserError, match=rf"^{side}: its tip is .* positions in mm\?"):
            compute_metrics(*args, 0.3, names)


def test_aligned_truth_refuses_a_truth_whose_rows_and_times_differ() -> None:
    """``aligned_truth`` with times of another length than the truth's rows (rows paired
    five samples apart, 16 mm of error added, without it), or values of another column
    count than their names: a UserError naming both; the same arrays aligned run."""
    from continuum_mhe.evaluation.metrics import aligned_truth

    rec = simulate("paper3d", duration=2.0, seed=1)
    names = [o.name for o in rec.outputs]
    with pytest.raises(UserError, match=r"^values has 41 rows but t_truth has 36"):
        aligned_truth(rec.t, rec.t[5:], rec.truth, names)
    with pytest.raises(UserError, match=r"^values has 5 columns, but names gives 3"):
        aligned_truth(rec.t, rec.t, rec.truth, names[:3])
    for args, needle in (
        (("abc", rec.t), "t_est must be an array of times (s), got 'abc'"),
        ((rec.t, [None, "x"]), "t_truth must be an array of times (s), got [None, 'x']"),
    ):  # a ValueError or TypeError from numpy
        with pytest.raises(UserError, match="^" + re.escape(needle)):
            aligned_truth(*args, rec.truth, names)
    i_est, rows, interpolated = aligned_truth(rec.t, rec.t, rec.truth, names)
    assert len(i_est) == len(rec.t) and not interpolated
    np.testing.assert_array_equal(rows, rec.truth)


def test_aligned_truth_refuses_times_that_do_not_increase() -> None:
    """A truth whose rows are out of time order: times that do not increase are a
    UserError naming the row (not aligned on 1 of 61 rows, with a warning that blames
    milliseconds); the same truth sorted aligns every row."""
    from continuum_mhe.evaluation.metrics import aligned_truth

    rec = simulate("paper3d", duration=3.0, seed=1)
    names = [o.name for o in rec.outputs]
    order = np.random.default_rng(0).permutation(len(rec.t))
    with pytest.raises(UserError, match=r"^t_truth must increase: row \d+ is at"):
        aligned_truth(rec.t, rec.t[order], rec.truth[order], names)
    with pytest.raises(UserError, match=r"^t_est must increase: row 1 is at 0 s after 0.05 s"):
        aligned_truth(rec.t[[1, 0, 2]], rec.t, rec.truth, names)
    i_est, _, _ = aligned_truth(rec.t, rec.t, rec.truth, names)
    assert len(i_est) == len(rec.t)


def test_compute_metrics_refuses_angles_in_degrees() -> None:
    """Bend angles in degrees (a theta RMSE of 54 "rad"): beyond a turn, they are a
    UserError naming the side, row and column, as read_state_table refuses them."""
    rec = simulate("paper3d", duration=2.0, seed=1)
    degrees = rec.truth * [1.0, 1.0, 1.0, 180 / math.pi, 180 / math.pi]
    for est, truth, side in ((rec.truth, degrees, "truth"), (degrees, rec.truth, "estimate")):
        with pytest.raises(UserError, match=rf"^{side}: row \d+: (theta|phi)=[\d.]+ beyond 2 pi"):
            compute_metrics(est, truth, 0.2)
    assert compute_metrics(rec.truth, rec.truth, 0.2).tip_mean_mm == 0.0


def test_compute_metrics_skips_rows_without_a_finite_truth_and_counts_them() -> None:
    """Rows whose truth is NaN (a gap in a motion capture) are left out of the metrics
    and counted, as rows without an estimate are: the metrics are those of the other
    rows alone."""
    rec = simulate("paper3d", duration=2.0, seed=1)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    truth = rec.truth.copy()
    truth[5:10] = np.nan
    keep = np.ones(len(truth), dtype=bool)
    keep[5:10] = False
    m = compute_metrics(s.output, truth, 0.2)
    want = compute_metrics(s.output[keep], rec.truth[keep], 0.2)
    assert (m.n, m.n_without_truth, m.n_without_estimate) == (36, 5, 0)
    assert m.tip_mean_mm == want.tip_mean_mm and m.rmse == want.rmse
    truth[:] = np.nan
    with pytest.raises(UserError, match="no estimated sample has a finite truth"):
        compute_metrics(s.output, truth, 0.2)


def _scaled_truth(t: Path, out: Path, columns: tuple[str, ...], factor: float) -> Path:
    """The truth ``t`` with ``columns`` multiplied by ``factor``, as ``out``."""
    lines = t.read_text().splitlines()
    header = lines[0].split(",")
    at = [header.index(c) for c in columns]
    rows = []
    for line in lines[1:]:
        v = line.split(",")
        for i in at:
            v[i] = repr(float(v[i]) * factor)
        rows.append(",".join(v))
    out.write_text(lines[0] + "\n" + "\n".join(rows) + "\n")
    return out


def test_bend_angles_in_degrees_are_refused_on_their_line(tmp_path, capsys) -> None:
    """A truth whose theta is in degrees (read as rad, a theta RMSE of thousands of degrees):
    one line naming the file, the first row beyond 2 pi and its value, exit 2."""
    m, t = simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    degrees = _scaled_truth(t, tmp_path / "deg.csv", ("theta",), math.degrees(1.0))
    theta = read_state_table(t).column("theta")
    first = int(np.argmax(np.degrees(theta) > 2 * math.pi))
    capsys.readouterr()
    assert main(["evaluate", str(est), str(degrees)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert err.startswith(f"continuum-mhe: error: {degrees}: line {first + 2}: theta=")
    assert "beyond 2 pi: degrees? angles are in rad" in err


def test_plot_refuses_a_truth_in_mm_without_the_robot(tmp_path, capsys) -> None:
    """``plot --truth`` in mm, no --robot: the truth's tip 1000 times as far from the
    base as the estimate's, one line, nothing drawn; the same truth in m is drawn."""
    from continuum_mhe.io.position_units import position_unit_against

    m, t = simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    mm = _scaled_truth(t, tmp_path / "mm.csv", ("x", "y", "z"), 1000.0)
    figure = tmp_path / "p.png"
    capsys.readouterr()
    assert main(["plot", str(est), "--truth", str(mm), "-o", str(figure)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {mm}: its tip is ")
    assert "times as far from the base as the estimate's: positions in mm?" in err
    assert not figure.exists()
    truth, e = read_state_table(t), read_state_table(est)
    assert position_unit_against(truth.names, truth.values, e.names, e.values) == ""
    cm = read_state_table(_scaled_truth(t, tmp_path / "cm.csv", ("x", "y", "z"), 100.0))
    assert "positions in cm?" in position_unit_against(cm.names, cm.values, e.names, e.values)
    assert main(["plot", str(est), "--truth", str(t), "-o", str(figure)]) == 0


def test_a_tip_truth_in_cm_is_refused_naming_it(tmp_path, capsys) -> None:
    """Tip positions alone in cm (a motion capture's): 100 times the robot's reach is a
    shape of no unit but cm, so only the estimate tells. ``evaluate`` and ``plot
    --robot`` refuse it in one line naming the truth (not the estimate, and not drawn as
    another robot's truth)."""
    m, t = simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    truth = read_state_table(t)
    cm = tmp_path / "tip_cm.csv"
    write_table(cm, ["t", "x", "y", "z"],
                np.column_stack([truth.t, *(100 * truth.column(c) for c in "xyz")]))  # fmt: skip
    robot = tmp_path / "r.toml"
    robot.write_text("[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n")
    figure = tmp_path / "p.png"
    capsys.readouterr()
    for argv in (
        ["evaluate", str(est), str(cm)],
        ["plot", str(est), "--truth", str(cm), "--robot", str(robot), "-o", str(figure)],
    ):
        assert main(argv) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()[-1:]
        assert line.startswith(f"continuum-mhe: error: {cm}: its tip is "), line
        assert line.endswith("positions in cm? give x, y, z in m"), line
    assert not figure.exists()


def test_evaluate_refuses_the_same_file_as_estimate_and_truth(tmp_path, capsys) -> None:
    """``evaluate truth.csv truth.csv`` (or the same file spelt another way) would score
    0 mm: refused."""
    _, t = simulated(tmp_path, "a")
    capsys.readouterr()
    assert main(["evaluate", str(t), str(tmp_path / "." / t.name)]) == 2
    assert "the truth is the estimate file itself" in capsys.readouterr().err


@pytest.fixture(scope="module")
def paper3d_pair(tmp_path_factory) -> dict[str, Path]:
    """A paper3d EKF estimate (6 s), its truth, and three mistaken copies: the estimate's
    positions in mm, the truth on a clock 0.5 s late, and the truth with t in ms."""
    tmp = tmp_path_factory.mktemp("pair")
    paths = {k: tmp / f"{k}.csv" for k in ("m", "t", "e", "e_mm", "t_late", "t_ms")}
    assert main(["simulate", "paper3d", "--duration", "6", "-o", str(paths["m"]),
                 "--truth", str(paths["t"])]) == 0  # fmt: skip
    assert main(["estimate", str(paths["m"]), "-o", str(paths["e"]), "--method", "ekf"]) == 0

    def rewrite(src: Path, dst: Path, change) -> None:
        lines = src.read_text().splitlines()
        body = [ln for ln in lines if not ln.startswith("#")]
        header = body[0].split(",")
        out = [ln for ln in lines if ln.startswith("#")] + [body[0]]
        for ln in body[1:]:
            fields = ln.split(",")
            out.append(",".join(change(header, fields)))
        dst.write_text("\n".join(out) + "\n")

    def in_mm(header, f):
        return [repr(float(v) * 1e3) if h in ("x", "y", "z") and v else v
                for h, v in zip(header, f)]  # fmt: skip

    rewrite(paths["e"], paths["e_mm"], in_mm)
    rewrite(paths["t"], paths["t_late"], lambda h, f: [repr(float(f[0]) + 0.5), *f[1:]])
    rewrite(paths["t"], paths["t_ms"], lambda h, f: [repr(float(f[0]) * 1e3), *f[1:]])
    return paths


def test_plot_refuses_positions_in_mm_without_a_robot(paper3d_pair, tmp_path, capsys) -> None:
    """plot of an estimate whose positions are in mm drew a 200 m robot without a word
    (evaluate and view refused it): its rows' own sections, beyond any robot's, refuse it."""
    fig = tmp_path / "f.png"
    assert main(["plot", str(paper3d_pair["e_mm"]), "-o", str(fig)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not fig.exists()
    assert "its rows give sections of 200 m (its positions against its own bend angles)" in err
    assert err.endswith("positions in mm? give x, y, z in m\n")


def test_plot_and_view_warn_of_a_truth_on_an_offset_clock(
    paper3d_pair, tmp_path, capsys, monkeypatch
) -> None:
    """A truth 0.5 s late: evaluate, plot and view each say it (plot and view do not draw
    the offset as an error of the estimate without a word), naming the --truth-shift that
    compares them (each command's own)."""
    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    e, late = str(paper3d_pair["e"]), str(paper3d_pair["t_late"])
    said = "the truth fits the estimate best +0.5 s later"
    assert main(["evaluate", e, late]) == 0
    assert said in capsys.readouterr().err
    assert main(["plot", e, "--truth", late, "-o", str(tmp_path / "f.png")]) == 0
    err = capsys.readouterr().err
    assert said in err and "; --truth-shift 0.5 compares them so" in err
    assert main(["view", e, "--truth", late, "--save", str(tmp_path / "v.rrd")]) == 0
    err = capsys.readouterr().err
    assert said in err and "; --truth-shift 0.5 compares them so" in err


def _truth_with_gaps(src: Path, dst: Path, rows: range, columns: set[str] | None) -> None:
    """``src``'s truth with the ``columns`` (None: every one but ``t``) of data rows
    ``rows`` (0-based) empty: a motion capture's lost marker."""
    header, *body = src.read_text().splitlines()
    names = header.split(",")
    out = [header]
    for i, line in enumerate(body):
        f = line.split(",")
        if i in rows:
            f = [v if c == "t" or (columns and c not in columns) else "" for c, v in zip(names, f)]
        out.append(",".join(f))
    dst.write_text("\n".join(out) + "\n")


def test_plot_view_and_evaluate_read_a_truth_with_gaps(paper3d_pair, tmp_path, capsys) -> None:
    """A truth with lost markers (empty cells): evaluate compares the other rows, and plot
    and view take the file too (not refused naming the line). A column empty in every
    row (an angle the capture does not give) is left out (not every row without a finite
    truth, none compared and the coverage nan, nor a traceback in view). A truth without
    any tip value is refused in one line."""
    e, t = paper3d_pair["e"], paper3d_pair["t"]
    gaps, theta, empty = tmp_path / "gaps.csv", tmp_path / "theta.csv", tmp_path / "none.csv"
    _truth_with_gaps(t, gaps, range(40, 50), None)
    _truth_with_gaps(t, theta, range(0, 10**6), {"theta"})
    _truth_with_gaps(t, empty, range(0, 10**6), None)
    n = len(t.read_text().splitlines()) - 1
    assert main(["evaluate", str(e), str(gaps)]) == 0
    assert "without a finite truth)" in capsys.readouterr().out
    assert main(["plot", str(e), "--truth", str(gaps), "-o", str(tmp_path / "f.png")]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(e), str(theta)]) == 0
    out = capsys.readouterr().out
    assert f"samples compared     {n} (0 without estimate)" in out, out
    assert "RMSE theta" not in out and "nan" not in out and "phi 1.000" in out, out
    refused = f"continuum-mhe: error: {empty}: no row has a value in each of x, y, z "
    figure = str(tmp_path / "g.png")
    for argv in (
        ["evaluate", str(e), str(empty)],
        ["plot", str(e), "--truth", str(empty), "-o", figure],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err == refused + "(every row a gap)\n", err
    assert not (tmp_path / "g.png").exists()
    # a truth in mm with an empty angle column: refused by each, naming the truth (its
    # empty angles would say nothing, and view would draw it 1000 times too large)
    header, *rows = t.read_text().splitlines()
    names = header.split(",")
    in_mm = tmp_path / "mm.csv"
    in_mm.write_text("\n".join([header, *(
        ",".join(repr(float(v) * 1e3) if c in "xyz" else "" if c == "theta" else v
                 for c, v in zip(names, r.split(",")))
        for r in rows)]) + "\n")  # fmt: skip
    rrd, png = str(tmp_path / "mm.rrd"), str(tmp_path / "mm.png")
    for argv in (["evaluate", str(e), str(in_mm)],
                 ["view", str(e), "--truth", str(in_mm), "--save", rrd],
                 ["plot", str(e), "--truth", str(in_mm), "-o", png]):  # fmt: skip
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"continuum-mhe: error: {in_mm}: its tip is ") and "in mm?" in err, (
            err
        )
    # theta and phi empty in alternate rows: no row has both
    alternate = tmp_path / "alternate.csv"
    alternate.write_text("\n".join([header, *(
        ",".join("" if c == ("theta", "phi")[i % 2] else v for c, v in zip(names, r.split(",")))
        for i, r in enumerate(rows))]) + "\n")  # fmt: skip
    assert main(["plot", str(e), "--truth", str(alternate), "-o", str(tmp_path / "a.png")]) == 0
    for truth in (gaps, theta, alternate):
        out_rrd = tmp_path / f"{truth.stem}.rrd"
        assert main(["view", str(e), "--truth", str(truth), "--save", str(out_rrd)]) == 0
        assert out_rrd.stat().st_size > 0
    assert "(tip and section ends only: no theta/phi" in capsys.readouterr().err


def test_view_refuses_a_truth_with_t_in_milliseconds(paper3d_pair, tmp_path, capsys) -> None:
    """view wrote a recording "with truth" of a truth whose t is in ms (evaluate and plot
    refused it): refused in one line, nothing written."""
    out = tmp_path / "v.rrd"
    argv = ["view", str(paper3d_pair["e"]), "--truth", str(paper3d_pair["t_ms"])]
    assert main([*argv, "--save", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not out.exists()
    assert f"{paper3d_pair['t_ms']}: t advances by a median of 50 s per sample" in err
    assert "is the truth's t in milliseconds? name its column t_ms" in err


def test_aligned_truth_warns_where_few_rows_are_scored() -> None:
    """The library's scoring path (aligned_truth, then compute_metrics) scored an
    estimate against a truth whose t is in ms on the one row they shared (a tip error of
    0.64 mm) without a word, where evaluate refuses it: a TruthCoverageWarning says how
    few rows are compared; a matching truth says nothing."""
    from continuum_mhe.evaluation.metrics import TruthCoverageWarning, aligned_truth

    rec = simulate("paper3d", duration=4.0)
    names = [o.name for o in rec.outputs]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rows, _, _ = aligned_truth(rec.t, rec.t, rec.truth, names)
    assert len(rows) == len(rec.t)
    with pytest.warns(TruthCoverageWarning, match=r"only 1 of the estimate's 81 rows have a"):
        rows, _, _ = aligned_truth(rec.t, rec.t * 1e3, rec.truth, names)
    assert len(rows) == 1


def test_evaluate_json_carries_what_the_text_says(paper3d_pair, capsys) -> None:
    """evaluate --json carries the warnings the text run says, the truth shift used,
    whether the truth is interpolated and which columns the SRMSE sums, so that a script
    sees a problem a person would."""
    e, late = str(paper3d_pair["e"]), str(paper3d_pair["t_late"])
    assert main(["evaluate", e, late, "--json"]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out)
    said = [ln.removeprefix("continuum-mhe: warning: ") for ln in err.splitlines()]
    assert report["warnings"] == said and len(said) == 1 and "+0.5 s later" in said[0]
    assert report["srmse_columns"] == ["x", "y", "z", "theta", "phi"]
    assert (report["truth_shift_s"], report["interpolated"]) == (0.0, False)
    assert main(["evaluate", e, late, "--json", "--truth-shift", "0.5"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["truth_shift_s"] == 0.5 and report["warnings"] == []
    typo = paper3d_pair["t"].with_name("t_typo.csv")
    typo.write_text(paper3d_pair["t"].read_text().replace(",theta,", ",thetaa,", 1))
    assert main(["evaluate", e, str(typo), "--json"]) == 0
    out, err = capsys.readouterr()
    said = [ln.removeprefix("continuum-mhe: warning: ") for ln in err.splitlines()]
    assert json.loads(out)["warnings"] == said and "thetaa" in said[0]


def test_a_full_disk_on_standard_output_says_what_failed(paper3d_pair) -> None:
    """evaluate > /dev/full says what failed ("writing the output"), not 'error: : No
    space left on device'."""
    import subprocess
    import sys

    if not Path("/dev/full").exists():
        pytest.skip("needs /dev/full")
    with open("/dev/full", "w") as full:
        done = subprocess.run(
            [sys.executable, "-m", "continuum_mhe", "evaluate", str(paper3d_pair["e"]),
             str(paper3d_pair["t"])],
            stdout=full, stderr=subprocess.PIPE, text=True, timeout=120,
        )  # fmt: skip
    assert done.returncode == 2
    assert done.stderr == "continuum-mhe: error: writing the output: No space left on device\n"


def test_an_empty_estimate_names_an_estimate_s_header(tmp_path, capsys) -> None:
    """evaluate of an empty estimate file names an estimate's header, not a measurement
    header (t,roll,pitch)."""
    empty = tmp_path / "e.csv"
    empty.write_text("")
    assert main(["evaluate", str(empty), str(empty)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {empty}: line 1: file is empty, expected a header such as "
        "t,x,y,z,theta,phi (an estimate's or a truth's)\n"
    )


def test_evaluate_plot_and_view_refuse_a_truth_of_two_rows_alike(paper3d_pair, tmp_path, capsys):
    """A truth of the estimate's first two rows: evaluate refused it (under 10 % of the
    rows compare), plot and view drew it without a word; all three refuse it in the
    same line."""
    lines = paper3d_pair["t"].read_text().splitlines()
    body = [i for i, ln in enumerate(lines) if not ln.startswith("#")]
    two = tmp_path / "t2.csv"
    two.write_text("\n".join(lines[: body[0] + 3]) + "\n")
    e = str(paper3d_pair["e"])
    said = f"{e}: only 2 of 121 rows have a row at the same t (within 1 us) in {two}"
    assert main(["evaluate", e, str(two)]) == 2
    assert said in capsys.readouterr().err
    assert main(["plot", e, "--truth", str(two), "-o", str(tmp_path / "f.png")]) == 2
    assert said in capsys.readouterr().err
    assert main(["view", e, "--truth", str(two), "--save", str(tmp_path / "v.rrd")]) == 2
    assert said in capsys.readouterr().err


def test_evaluate_warns_of_a_truth_whose_x_and_y_are_swapped(
    paper3d_pair, tmp_path, capsys, monkeypatch
):
    """A truth with x and y swapped (scored 129 mm beside a theta RMSE of 1.15 deg) is not
    scored without a word: its tip points far from where its own angles put it, said in
    a warning; the right truth, and the shipped rods' and tendon robots' truths, say
    nothing of it (their median angle is under 3 degrees)."""
    from continuum_mhe.io.position_units import tip_direction_problem
    from continuum_mhe.io.state_tables import read_state_table

    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    lines = paper3d_pair["t"].read_text().splitlines()
    header = next(ln for ln in lines if not ln.startswith("#")).split(",")
    ix, iy = header.index("x"), header.index("y")
    swapped = tmp_path / "t_xy.csv"
    out = []
    for ln in lines:
        f = ln.split(",")
        if not ln.startswith("#") and f != header:  # the values, not the names
            f[ix], f[iy] = f[iy], f[ix]
        out.append(",".join(f))
    swapped.write_text("\n".join(out) + "\n")
    e = str(paper3d_pair["e"])
    assert main(["evaluate", e, str(swapped)]) == 0
    err = capsys.readouterr().err
    assert f"warning: {swapped}: its tip points " in err and "x and y swapped" in err
    assert main(["evaluate", e, str(paper3d_pair["t"])]) == 0
    assert "tip points" not in capsys.readouterr().err
    assert main(["plot", e, "--truth", str(swapped), "-o", str(tmp_path / "f.png")]) == 0
    assert f"warning: {swapped}: its tip points " in capsys.readouterr().err  # as evaluate
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data"
    for folder, lengths in (("rod2", (0.16, 0.14)), ("tendon", (0.2, 0.2))):
        for path in sorted((data / folder).glob("*_truth.csv")):
            table = read_state_table(path)
            assert tip_direction_problem(table.names, table.values, lengths) == "", path


def test_the_srmse_counts_the_tip_once_on_several_sections() -> None:
    """A two-section table has the tip twice (x, y, z and the second section's end
    x_2, y_2, z_2): a tip 10 mm off in x sums 10 mm into the SRMSE, not 20 mm. One
    section's SRMSE (the paper's) sums all of its columns."""
    from continuum_mhe.evaluation.metrics import srmse_columns

    names = ["x", "y", "z", "theta_1", "phi_1", "x_1", "y_1", "z_1",
             "theta_2", "phi_2", "x_2", "y_2", "z_2"]  # fmt: skip
    truth = np.zeros((20, len(names)))
    truth[:, names.index("z")] = truth[:, names.index("z_2")] = 0.3
    truth[:, names.index("z_1")] = 0.16
    est = truth.copy()
    est[:, names.index("x")] += 0.01
    est[:, names.index("x_2")] += 0.01
    m = compute_metrics(est, truth, 0.3, names)
    assert m.rmse["x"] == pytest.approx(0.01) and m.rmse["x_2"] == pytest.approx(0.01)
    assert m.srmse == pytest.approx(0.01)
    assert "x_2" not in srmse_columns(names) and "x_1" in srmse_columns(names)
    assert srmse_columns(["x", "y", "z", "theta", "phi"]) == ["x", "y", "z", "theta", "phi"]


def test_plot_refuses_an_estimate_given_as_the_truth(tmp_path, capsys) -> None:
    """As ``evaluate`` does: an estimate's status and std_ columns in the truth's place."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(a)]) == 0
    assert main(["estimate", str(meas), "--method", "ukf", "-o", str(b)]) == 0
    capsys.readouterr()
    png = tmp_path / "p.png"
    assert main(["plot", str(a), "--truth", str(b), "-o", str(png)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {b}: has an estimate's status or std_ columns: an estimate, "
        "not a truth (plot EST.csv --truth TRUTH.csv)\n"
    )
    assert not png.exists()


def test_evaluate_says_when_the_truths_sections_are_the_robot_files_in_another_order(
    tmp_path, capsys
) -> None:
    """Two sections of 0.16 and 0.14 m described as 0.14 and 0.16 m: the whole length
    agrees, so only the truth's own sections (their chords and bends) show that the
    robot file is not the truth's robot."""
    meas, truth = tmp_path / "m.csv", tmp_path / "truth.csv"
    argv = ["simulate", "spatial", "--robot", "two-section", "--duration", "2"]
    assert main([*argv, "-o", str(meas), "--truth", str(truth)]) == 0
    swapped = tmp_path / "swapped.toml"
    text = (DATA_ROBOTS / "two_section.toml").read_text()
    swapped.write_text(text.replace("length = 0.16", "length = X").replace(
        "length = 0.14", "length = 0.16").replace("length = X", "length = 0.14"))  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", str(swapped), "--method", "ekf",
                 "-o", str(est)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--robot", str(swapped)]) == 0
    warned = [ln for ln in capsys.readouterr().err.splitlines() if "its rows fit" in ln]
    assert warned == [
        f"continuum-mhe: warning: {truth}: its rows fit sections of 0.16, 0.14 m, not the "
        "given robot's 0.14, 0.16 m: check the robot's section lengths and their order"
    ]
    est_right = tmp_path / "e2.csv"
    argv = ["estimate", str(meas), "--robot", "two-section", "--method", "ekf"]
    assert main([*argv, "-o", str(est_right)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est_right), str(truth), "--robot", "two-section"]) == 0
    assert "its rows fit" not in capsys.readouterr().err


def test_plot_and_view_say_a_truth_of_a_robot_of_other_lengths(
    tmp_path, capsys, monkeypatch
) -> None:
    """As ``evaluate`` says it: a truth made for sections twice as long, drawn beside the
    estimate's backbone; the right truth gives no such line."""
    long_robot = tmp_path / "long.toml"
    text = (DATA_ROBOTS / "two_section.toml").read_text()
    long_robot.write_text(text.replace("length = 0.16", "length = 0.3").replace(
        "length = 0.14", "length = 0.3"))  # fmt: skip
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    long_truth = tmp_path / "tl.csv"
    argv = ["simulate", "spatial", "--duration", "2"]
    assert main([*argv, "--robot", "two-section", "-o", str(meas), "--truth", str(truth)]) == 0
    assert main([*argv, "--robot", str(long_robot), "-o", str(tmp_path / "ml.csv"),
                 "--truth", str(long_truth)]) == 0  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", "two-section", "--method", "ekf",
                 "-o", str(est)]) == 0  # fmt: skip
    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    for command in (["plot", str(est), "-o", str(tmp_path / "p.png")],
                    ["view", str(est), "--save", str(tmp_path / "v.rrd")]):  # fmt: skip
        capsys.readouterr()
        assert main([*command, "--truth", str(long_truth)]) == 0
        err = capsys.readouterr().err
        assert (
            f"warning: {long_truth}: its tip is 2.00 times as far from the base as its own "
            "angles put it on a robot of 0.3 m: it was made for a robot of about 0.6 m; it is "
            "drawn beside the estimate of a robot of 0.16, 0.14 m (the truth of another "
            "robot?)"
        ) in err, err
        assert main([*command, "--truth", str(truth), "--overwrite"]) == 0
        assert "another robot" not in capsys.readouterr().err


def test_the_tip_direction_warning_names_bends_past_180_degrees() -> None:
    """A section bent past 180 degrees (a soft robot curled by the tensions sized for
    another) has a bend angle, the swing of its end's frame, that cannot describe it:
    its positions then disagree with its angles as swapped axes would. The warning names
    that cause where the file's bends reach over 170 degrees, and only there."""
    from continuum_mhe.io.position_units import tip_direction_problem
    from continuum_mhe.model.pcc import pose_at

    names = ["t", "x", "y", "z", "theta_1", "phi_1", "theta_2", "phi_2"]
    lengths = (0.15, 0.15)

    def table(theta_1: float) -> np.ndarray:
        theta = np.column_stack([np.full(40, theta_1), np.linspace(0.1, 0.6, 40)])
        phi = np.column_stack([np.linspace(0.0, 1.0, 40), np.linspace(0.0, 1.0, 40)])
        bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=-1)
        tip = -np.asarray(pose_at(bends, lengths, 1)[1], dtype=float)  # x and y flipped
        tip[:, 2] *= -1.0
        return np.column_stack([np.arange(40) * 0.02, tip, theta[:, 0], phi[:, 0],
                                theta[:, 1], phi[:, 1]])  # fmt: skip

    said = tip_direction_problem(names, table(math.radians(175.0)), lengths)
    assert "x and y swapped" in said and "bent past 180 degrees (its bends reach 175" in said
    said = tip_direction_problem(names, table(math.radians(120.0)), lengths)
    assert "x and y swapped" in said and "bent past" not in said


def _tip_truth_turned(
    src: Path, dst: Path, turn: np.ndarray, move: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> None:
    """``src``'s truth as a motion capture gives it, ``t, x, y, z`` of the tip alone, each
    position turned by the matrix ``turn`` (3, 3), then moved by ``move`` (m)."""
    from continuum_mhe.io.state_tables import read_state_table

    table = read_state_table(src)
    tip = table.values[:, [table.names.index(c) for c in ("x", "y", "z")]] @ turn.T + move
    np.savetxt(dst, np.c_[table.t, tip], delimiter=",", header="t,x,y,z", comments="", fmt="%.9g")


def test_evaluate_and_plot_warn_of_a_truth_in_a_y_up_motion_capture_frame(
    paper3d_pair, tmp_path, capsys, monkeypatch
) -> None:
    """A motion capture's tip positions in its y-up frame (x, z, -y of the robot's base
    frame), hundreds of mm off as given, are warned of: the truth turned about the base
    fits far better, and the warning names where its axes lie; the same tip positions in
    the base frame, and turned by 10 degrees only, say nothing."""
    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    e = str(paper3d_pair["e"])
    y_up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # base frame -> y-up frame
    cases = {"yup": y_up, "base": np.eye(3)}
    small = math.radians(10)
    cases["small"] = np.array(
        [[math.cos(small), -math.sin(small), 0], [math.sin(small), math.cos(small), 0], [0, 0, 1]]
    )
    paths = {k: tmp_path / f"{k}.csv" for k in cases}
    for k, turn in cases.items():
        _tip_truth_turned(paper3d_pair["t"], paths[k], turn)
    said = "the truth's tip fits the estimate far better turned by 90 degrees about the base"
    assert main(["evaluate", e, str(paths["yup"])]) == 0
    err = capsys.readouterr().err
    assert f"warning: {paths['yup']}: {said}" in err
    assert "its x, y and z lie along the estimate's x, z, -y" in err
    assert "an IMU's yaw" not in err  # a turn about x: no yaw of an IMU's does that
    assert main(["plot", e, "--truth", str(paths["yup"]), "-o", str(tmp_path / "f.png")]) == 0
    assert said in capsys.readouterr().err  # as evaluate
    # turned about z: the frame, or an IMU's yaw that a rest calibration kept
    about_z = tmp_path / "about_z.csv"
    _tip_truth_turned(paper3d_pair["t"], about_z, np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]))
    assert main(["evaluate", e, str(about_z)]) == 0
    err = capsys.readouterr().err
    (line,) = [ln for ln in err.splitlines() if said in ln]
    assert line.endswith(
        "; or, turned about z, is an IMU's yaw in the robot file wrong (its mount_rpy: a "
        "calibration at rest keeps the file's yaw, calibrate --bend measures it)?"
    )
    for k in ("base", "small"):
        assert main(["evaluate", e, str(paths[k])]) == 0
        assert "fits the estimate far better" not in capsys.readouterr().err, k
    # about a motion capture's origin 1.5 m away: said, with the move, and not taken for
    # a truth of a longer robot; an offset of 2 cm (as likely the estimate's) is not
    far, near = tmp_path / "far.csv", tmp_path / "near.csv"
    _tip_truth_turned(paper3d_pair["t"], far, y_up, (0.9, 1.2, -0.05))
    _tip_truth_turned(paper3d_pair["t"], near, np.eye(3), (0.02, 0.0, 0.0))
    assert main(["evaluate", e, str(far)]) == 0
    err = capsys.readouterr().err
    moved = re.search(r"far better turned by 90 degrees and moved by \((.*?)\) mm", err)
    assert moved is not None  # by about the move back, within the estimate's own errors
    assert_allclose([float(v) for v in moved.group(1).split(",")], [-900, -50, -1200], atol=20)
    assert "its x, y and z lie along the estimate's x, z, -y" in err
    assert "longer robot" not in err and "another --length" not in err
    assert err.count("warning:") == 1
    assert main(["evaluate", e, str(near)]) == 0
    assert "fits the estimate far better" not in capsys.readouterr().err


def test_best_rotation_recovers_a_known_turn_of_the_positions() -> None:
    """The rotation that takes the truth's positions back to the estimate's: a known
    turn of 40 degrees about a tilted axis is found to 1e-9, with its error 0 against the
    unturned one; positions as they are give 0 degrees; too few rows give None."""
    from scipy.spatial.transform import Rotation

    from continuum_mhe.evaluation.metrics import ROTATION_MIN_ROWS, best_rotation

    rng = np.random.default_rng(3)
    est = rng.normal(size=(50, 3)) * 0.1
    turn = Rotation.from_rotvec(math.radians(40) * np.array([1.0, 2.0, 2.0]) / 3.0)
    found = best_rotation(est, turn.inv().apply(est))
    assert found is not None
    assert found.angle_deg == pytest.approx(40.0, abs=1e-9)
    np.testing.assert_allclose(found.matrix, turn.as_matrix(), atol=1e-9)
    assert found.error < 1e-12 and found.unturned > 0.01
    same = best_rotation(est, est)
    assert same is not None and same.angle_deg < 1e-6 and same.unturned == 0.0
    assert best_rotation(est[: ROTATION_MIN_ROWS - 1], est[: ROTATION_MIN_ROWS - 1]) is None
    # moved as well: the turn and the move are found
    move = np.array([0.7, -1.1, 0.4])
    moved = best_rotation(est, turn.inv().apply(est - move), moved=True)
    assert moved is not None
    np.testing.assert_allclose(moved.matrix, turn.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(moved.offset, move, atol=1e-9)
    assert moved.error < 1e-12
    np.testing.assert_allclose(found.offset, 0.0)


def test_no_frame_is_claimed_for_a_truth_along_a_line() -> None:
    """A truth whose tip stays along a line (a still or straight robot, a motion along
    one axis) leaves the turn about that line undetermined: a still truth 5 to 50 mm off
    the estimate fits turned by 50 to 175 degrees about it, and a wobble along x
    mirrored by 180; no frame is claimed for them (a bent, moving truth turned by 90
    degrees is)."""
    from scipy.spatial.transform import Rotation

    from continuum_mhe.evaluation.truth_checks import frame_fit

    rng = np.random.default_rng(0)
    n, length = 500, 0.35
    for offset in (0.005, 0.01, 0.05):  # the estimate off the still truth in x
        still_truth = np.array([0.0, 0.0, length]) + rng.normal(0.0, 5e-4, (n, 3))
        still_est = np.array([offset, 0.0, length - 5e-4]) + rng.normal(0.0, 5e-5, (n, 3))
        assert frame_fit(still_est, still_truth, length) is None, offset
    wobble = np.column_stack(
        [0.01 * np.sin(np.linspace(0, 20, n)), np.zeros(n), np.full(n, length)]
    ) + rng.normal(0.0, 3e-4, (n, 3))
    assert frame_fit(wobble * [-1.0, 1.0, 1.0], wobble, length) is None  # mirrored in x
    theta = np.linspace(0.0, 1.2, n)
    bent = np.column_stack([length * np.sin(theta) * np.cos(3 * theta), length * np.sin(theta)
                            * np.sin(3 * theta), length * np.cos(theta)])  # fmt: skip
    turned = Rotation.from_euler("x", 90, degrees=True).apply(bent)
    fit = frame_fit(bent, turned, length)
    assert fit is not None and abs(fit.angle_deg - 90.0) < 1e-6


def test_an_estimate_s_recorded_mounting_holds_with_length_and_is_warned_with_a_robot(
    tmp_path, capsys
) -> None:
    """A hanging robot's estimate (its options line records ``z-down``) read with
    ``--length`` alone keeps that mounting; with a robot file that says ``z-up`` the
    turn is warned of, as ``--mounting z-up`` is."""
    import argparse

    from continuum_mhe.cli.robot_options import estimate_robot

    m, t, e = (str(tmp_path / n) for n in ("m.csv", "t.csv", "e.csv"))
    assert main(["simulate", "paper3d", "-o", m, "--truth", t, "--duration", "1",
                 "--mounting", "z-down"]) == 0  # fmt: skip
    assert main(["estimate", m, "-o", e, "--mounting", "z-down", "--method", "ekf"]) == 0
    capsys.readouterr()
    args = argparse.Namespace(robot=None, length=0.2, mounting=None)
    assert estimate_robot(args, e, "drawn").mounting == "z-down"
    up = tmp_path / "up.toml"
    up.write_text('mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    said: list[str] = []
    robot = estimate_robot(argparse.Namespace(robot=str(up)), e, "drawn", said)
    assert robot.mounting == "z-up" and len(said) == 1
    assert "was estimated with mounting z-down (its options line), but" in said[0]


def test_view_of_a_tendon_estimate_whose_tensions_file_is_gone_names_it(tmp_path, capsys) -> None:
    """A tendon robot's estimate whose options line names a tensions file that is not
    there: ``view`` draws the tips alone and says which file it looked for."""
    from continuum_mhe.cli.view import _recorded_tensions
    from continuum_mhe.io.robot_file import read_robot

    est = tmp_path / "e.csv"
    est.write_text(
        '# options = {robot = "tendon-two-section", inputs = "gone_tensions.csv"}\n'
        "t,x,y,z,status\n0,0,0,0.4,ok\n"
    )
    assert _recorded_tensions(str(est), read_robot("tendon-two-section")) is None
    err = capsys.readouterr().err
    assert "was estimated with --inputs gone_tensions.csv (its options line), which is not" in err


def test_evaluate_of_a_truth_that_ends_early_says_so_after_skip_start(
    paper3d_pair, tmp_path, capsys
) -> None:
    """A truth that ends at 3.6 s of a 6 s run, scored with --skip-start: what is left of
    it decides whether it covers part of the run (from 2.6 s: that part's warning, not
    'the files' times do not match'); where no rows are left, the message says the truth
    ends there, not only that the times do not match."""
    lines = Path(paper3d_pair["t"]).read_text().splitlines()
    head = [ln for ln in lines if not ln[:1].isdigit()]
    rows = [ln for ln in lines if ln[:1].isdigit() and float(ln.split(",")[0]) <= 3.6]
    early = tmp_path / "early.csv"
    early.write_text("\n".join([*head, *rows]) + "\n")
    e = str(paper3d_pair["e"])
    assert main(["evaluate", e, str(early), "--skip-start", "2.6"]) == 0
    err = capsys.readouterr().err
    assert "(a truth of part of the run?)" in err and "do not match" not in err
    assert main(["evaluate", e, str(early), "--skip-start", "4.5"]) == 2
    err = capsys.readouterr().err
    assert "or the truth ends at t = 3.6 s and --skip-start scores from t = 4.5 s" in err


def test_plot_of_a_paper_formulation_estimate_draws_the_recorded_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The paper formulation's x, y, z are states of their own, off the end of the arc
    of its bend: plot takes the robot its options line records (0.2 m), as evaluate and
    view do, without a warning that the truth or the given robot file is another
    robot's."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth)]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--formulation", "paper"]) == 0
    robot = tmp_path / "one.toml"
    robot.write_text('mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    capsys.readouterr()
    fig = tmp_path / "f.png"
    for extra in ([], ["--robot", str(robot)]):
        assert main(["plot", str(est), "--truth", str(truth), "-o", str(fig), "--overwrite",
                     *extra]) == 0  # fmt: skip
        err = capsys.readouterr().err
        assert "warning" not in err, (extra, err)
    figures_drawn_small(monkeypatch)  # the rest: what plot says, not what it draws
    # a robot file of another length: its states give no lengths, its options line does
    robot.write_text(robot.read_text().replace("length = 0.2", "length = 0.3"))
    assert main(["plot", str(est), "-o", str(fig), "--overwrite", "--robot", str(robot)]) == 0
    assert "it was estimated with --length 0.2 (its options line), not the given robot's 0.3 m" in (
        capsys.readouterr().err
    )


def test_plot_warns_of_a_robot_file_of_another_mounting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """plot --robot with the estimate's sections but the other mounting draws the robot
    turned over: a warning, as evaluate and view give; the same file with the estimate's
    mounting, none."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    fig = tmp_path / "f.png"
    figures_drawn_small(monkeypatch)  # what plot says, not what it draws
    for mounting, warned in (("z-down", True), ("z-up", False)):
        robot = tmp_path / f"{mounting}.toml"
        robot.write_text(
            f'mounting = "{mounting}"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n'
        )
        capsys.readouterr()
        assert main(["plot", str(est), "--robot", str(robot), "-o", str(fig), "--overwrite"]) == 0
        err = capsys.readouterr().err
        assert (f"says {mounting}: the robot file's is used, which turns the estimate's "
                "base over" in err) is warned, err  # fmt: skip


@pytest.mark.parametrize("bend_names", [("theta", "phi"), ("theta_1", "phi_1")])
def test_one_sections_checks_read_either_models_bend_columns(bend_names) -> None:
    """A one-section table names its bend ``theta, phi`` (the constant-curvature model's
    outputs) or ``theta_1, phi_1`` (the tendon model's): either way its tip's unit, its
    robot's length and its axes are checked against its own angles (known answers: x and
    y swapped, positions in cm, a robot twice as long)."""
    from continuum_mhe.evaluation.metrics import length_misfit
    from continuum_mhe.io.position_units import position_unit_problem, tip_direction_problem
    from continuum_mhe.model.pcc import pose_at

    lengths = (0.2,)
    theta, phi = np.linspace(0.2, 1.2, 40), np.linspace(-1.0, 1.0, 40)
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=-1)[:, None, :]
    tip = np.asarray(pose_at(bends, lengths, 0)[1], dtype=float)
    names = ("x", "y", "z", *bend_names)

    def table(positions: np.ndarray) -> np.ndarray:
        return np.column_stack([positions, theta, phi])

    assert tip_direction_problem(names, table(tip), lengths) == ""
    assert position_unit_problem(names, table(tip), lengths) == ""
    assert length_misfit(names, table(tip), lengths) == ""
    swapped = tip[:, [1, 0, 2]]
    assert "x and y swapped" in tip_direction_problem(names, table(swapped), lengths)
    said = position_unit_problem(names, table(100.0 * tip), lengths)
    assert said.endswith("positions in cm? give x, y, z in m"), said
    said = length_misfit(names, table(2.0 * tip), lengths)
    assert "made for a robot of about 0.4 m" in said, said
