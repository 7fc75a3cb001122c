"""A slack tendon's tension read a little below zero (a load cell's noise or offset) is
taken as 0, said once, in a tensions file, on the serial line, in a stream and in an
estimator's ``step`` and ``run``; a tension further below zero is refused."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from tendon_helpers import DATA

from continuum_mhe.cli import main
from continuum_mhe.errors import UserError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import open_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.slack_readings import slack_reading_limit, take_slack_readings
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.tensions import Tensions, TensionStream, TensionsWarning
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.results import Measurement
from continuum_mhe.stream.protocol import GarbledLine, parse_line

ROBOT = "tendon-two-section"


def test_the_limit_is_a_floor_or_a_share_of_the_rows_largest_tension() -> None:
    """Known answers: 10 mN, or 2 % of the row's largest tension where more."""
    rows = np.array([[1.0, -0.015, -0.03], [0.1, -0.009, -0.011], [np.nan, -0.005, 0.0]])
    np.testing.assert_allclose(slack_reading_limit(rows), [0.02, 0.01, 0.01])
    taken = take_slack_readings(rows)
    assert taken.slack.tolist() == [[False, True, False], [False, True, False],
                                    [False, True, False]]  # fmt: skip
    assert taken.too_negative.tolist() == [[False, False, True], [False, False, True],
                                           [False, False, False]]  # fmt: skip
    assert taken.values[0, 1] == 0.0 and taken.values[0, 2] == -0.03
    assert np.isnan(taken.values[2, 0]) and taken.count == 3 and taken.lowest == -0.015


def test_a_tensions_table_takes_slack_readings_as_zero_and_refuses_the_rest() -> None:
    """``Tensions.from_rows``: readings 4 mN below zero beside a 1 N tendon are 0, in a
    warning naming the first line; 50 mN below zero is refused naming its line and the
    limit there (20 mN)."""
    t = np.arange(10) * 0.02
    values = np.column_stack([np.ones(10), np.zeros(10)])
    noisy = values.copy()
    noisy[3:7:2, 1] = -0.004
    lines = tuple(range(2, 12))
    with pytest.warns(TensionsWarning, match=r"log.csv: 2 tensions below 0 \(down to -0.004 N, "
                      r"the first at line 5\): a slack tendon read"):  # fmt: skip
        table = Tensions.from_rows("log.csv", t, noisy, lines=lines)
    reference = Tensions.from_rows("log.csv", t, values, lines=lines)
    np.testing.assert_array_equal(table.values, reference.values)
    noisy[5, 1] = -0.05
    with pytest.raises(UserError, match=re.escape(
        "log.csv: line 7: tension_2 = -0.05 N is negative: a tendon cannot push (a slack "
        "tendon's tension is 0; its load cell may read down to -0.02 N there, taken as 0)"
    )):  # fmt: skip
        Tensions.from_rows("log.csv", t, noisy, lines=lines)


def test_the_serial_line_takes_a_slack_reading_and_refuses_a_negative_tension() -> None:
    """On the line: -20 mN beside 1.5 N (a limit of 30 mN) is read; -50 mN is garbled."""
    s = parse_line("20,0.1,-0.2,1.5,-0.02", "tilt", n_tensions=2)
    assert s is not None
    np.testing.assert_array_equal(s.tensions, [1.5, -0.02])
    with pytest.raises(GarbledLine, match="a negative tension"):
        parse_line("20,0.1,-0.2,1.5,-0.05", "tilt", n_tensions=2)


def test_a_stream_takes_a_slack_reading_as_zero_said_once() -> None:
    stream = TensionStream("line", 2)
    t = np.arange(8) * 0.02
    given = [[1.0, -0.004 * (k % 2)] for k in range(8)]
    with pytest.warns(TensionsWarning) as said:
        out = [a for tk, v in zip(t, given) for a in stream.push(float(tk), np.array(v))]
    out += stream.end()
    assert sum("below 0" in str(w.message) for w in said) == 1
    assert [a.values[1] for a in out] == [0.0] * 8


def _recording(n: int) -> tuple[object, np.ndarray, np.ndarray]:
    base = make_formulation("bend", read_robot(ROBOT))
    options = InputOptions(tensions=str(DATA / "force-29_tensions.csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open_input(DATA / "force-29_raw.csv", options, base) as stream:
            f = stream.formulation
            blocks = list(stream.blocks)
    t = np.concatenate([b[0] for b in blocks])[:n]
    z = np.vstack([b[1] for b in blocks])[:n]
    return f, t, z


def test_the_estimators_take_a_slack_reading_as_zero() -> None:
    """``run`` and ``step`` with tension_3 read 4 mN below zero at some samples give the
    estimates of 0 N there, with one warning; 50 mN below zero is refused."""
    f, t, z = _recording(12)
    row = f.measurement_names.index("tension_3")  # type: ignore[attr-defined]
    zero, noisy = z.copy(), z.copy()
    zero[4:10, row] = 0.0
    noisy[4:10, row] = -0.004
    reference = make_estimator("ekf", f).run(t, zero)  # type: ignore[arg-type]
    with pytest.warns(TensionsWarning) as said:
        batch = make_estimator("ekf", f).run(t, noisy)  # type: ignore[arg-type]
    assert sum("below 0" in str(w.message) for w in said) == 1
    np.testing.assert_array_equal(batch.output, reference.output)
    est = make_estimator("ekf", f)  # type: ignore[arg-type]
    with pytest.warns(TensionsWarning) as said:
        stepped = [est.step(Measurement(float(tk), zk)).output for tk, zk in zip(t, noisy)]
    assert sum("below 0" in str(w.message) for w in said) == 1
    np.testing.assert_array_equal(np.array(stepped), reference.output)
    assert noisy[5, row] == -0.004  # the caller's array as given
    noisy[6, row] = -0.05
    with pytest.raises(UserError, match="tension_3 = -0.05 N is negative"):
        make_estimator("ekf", f).run(t, noisy)  # type: ignore[arg-type]


def test_estimate_takes_a_tensions_files_slack_readings_as_zero(tmp_path: Path) -> None:
    """``estimate --inputs`` with a tendon read 3 mN below zero on some rows (0.4 to
    0.78 s): the estimate of those rows at 0 N (the first 2 s of ``force-29``'s IMUs,
    its whole tensions files), one warning naming the first line."""
    meas = tmp_path / "m.csv"
    meas.write_text("".join((DATA / "force-29_raw.csv").read_text().splitlines(True)[:102]))
    lines = (DATA / "force-29_tensions.csv").read_text().splitlines()
    zero, noisy = [lines[0]], [lines[0]]
    for k, ln in enumerate(lines[1:]):
        fields = ln.split(",")
        if 20 <= k < 40:
            fields[3] = "0"
        zero.append(",".join(fields))
        if 20 <= k < 40 and k % 3:
            fields[3] = "-0.003"
        noisy.append(",".join(fields))
    outs = []
    for name, text in (("zero", zero), ("noisy", noisy)):
        path = tmp_path / f"{name}.csv"
        path.write_text("\n".join(text) + "\n")
        out = tmp_path / f"e_{name}.csv"
        argv = ["estimate", str(meas), "--robot", ROBOT, "--inputs", str(path), "-o", str(out)]
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            assert main(argv) == 0
        slack = [str(w.message) for w in said if "below 0" in str(w.message)]
        assert slack == ([] if name == "zero" else [slack[0]])
        outs.append(read_state_table(out))
    assert "noisy.csv: 13 tensions below 0 (down to -0.003 N, the first at line 22)" in slack[0]
    np.testing.assert_array_equal(outs[0].values, outs[1].values)


def test_a_stream_takes_a_tension_further_below_zero_as_missing() -> None:
    """-0.5 N beside 1 N (a limit of 20 mN) in a stream: taken as missing, so that its
    sample and the two on each side have no tensions (dropouts as a whole; their rates
    would take it), said once; the samples further away keep theirs (the estimator's
    step does not refuse the sample alone, with its neighbours' rates taking -0.5 N)."""
    stream = TensionStream("line", 2)
    t = np.arange(12) * 0.02
    given = [[1.0 + 0.1 * k, -0.5 if k == 6 else 0.3] for k in range(12)]
    with pytest.warns(TensionsWarning, match="taken as missing") as said:
        out = [a for tk, v in zip(t, given) for a in stream.push(float(tk), np.array(v))]
        out += stream.end()
    assert sum("taken as missing" in str(w.message) for w in said) == 1
    gone = [k for k, a in enumerate(out) if not np.isfinite(a.values).all()]
    assert gone and min(gone) >= 4 and max(gone) <= 8 and 6 in gone
    assert all(np.isfinite(out[k].values).all() for k in (0, 1, 2, 3, 9, 10, 11))
