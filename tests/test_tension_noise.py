"""Noisy tensions: a tensions file whose rows scatter (a load cell's noise) is smoothed
by a local cubic before the estimators take its values, rates and second derivatives
(``continuum_mhe.io.tension_derivatives.tension_derivatives``), and this is said; a smooth file is
taken row by row as it is."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import savgol_coeffs

from continuum_mhe.cli import main
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.tension_derivatives import (
    MAX_SMOOTHING_S,
    TENSION_ACCELERATION_NOISE,
    TENSION_RATE_NOISE,
    central_differences,
    hold_knots,
    line_knots,
    smoothing_rows,
    tension_derivatives,
    tension_noise_std,
)
from continuum_mhe.io.tensions import Tensions, TensionStream, TensionsWarning, read_tensions

DATA = Path(__file__).resolve().parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


@pytest.mark.parametrize("noise", [0.003, 0.01, 0.03])
def test_the_noise_of_tensions_is_read_from_their_rows(noise: float) -> None:
    """White noise of a known standard deviation added to smooth tensions (the shipped
    ``force-29``'s, 401 rows at 50 Hz, slack tendons included) is read back within 20 %;
    the smooth rows alone read as under a thousandth of the smallest."""
    smooth = read_tensions(DATA / "force-29_tensions.csv", 6)
    assert tension_noise_std(smooth.values) < 3e-6
    rng = np.random.default_rng(3)
    noisy = smooth.values + rng.normal(0.0, noise, smooth.values.shape)
    assert tension_noise_std(noisy) == pytest.approx(noise, rel=0.2)


@pytest.mark.parametrize("noise", [0.003, 0.01, 0.1])
def test_the_smoothing_is_the_shortest_that_meets_the_derivatives_noise(noise: float) -> None:
    """At 50 Hz: the chosen local cubic's rates and second derivatives are within their
    noise tolerances (its weights' norm times the noise), and two rows fewer are not,
    unless the longest span is reached; a noise that central differences take as it is
    gives no smoothing. 0.1 N gets the longest span, 75 rows, where the rates are still
    noisier than their tolerance."""
    step = 0.02
    rows = smoothing_rows(noise, step)
    assert rows >= 5 and rows % 2 == 1

    def gains(n: int) -> tuple[float, float]:
        g1 = float(np.linalg.norm(savgol_coeffs(n, 3, deriv=1, delta=step)))
        g2 = float(np.linalg.norm(savgol_coeffs(n, 3, deriv=2, delta=step)))
        return g1 * noise, g2 * noise

    def meets(n: int) -> bool:
        rate, acc = gains(n)
        return rate <= TENSION_RATE_NOISE and acc <= TENSION_ACCELERATION_NOISE

    longest = 2 * int(MAX_SMOOTHING_S / step / 2) + 1
    assert rows <= longest
    assert meets(rows) or rows == longest
    if rows > 5:
        assert not meets(rows - 2)
    if noise == 0.1:
        assert rows == longest == 75 and not meets(rows)
    assert smoothing_rows(1e-6, step) == 0


def test_tensions_too_noisy_for_the_longest_span_are_said() -> None:
    """0.1 N of noise at 50 Hz: smoothed over the longest span (1.48 s), and the warning
    says that the rates stay noisier than the estimators take (0.067 against 0.04 N/s);
    0.01 N: no such clause."""
    t = np.arange(0.0, 8.0, 0.02)
    rng = np.random.default_rng(2)
    loud = Tensions.from_rows("loud.csv", t, 3.0 + rng.normal(0.0, 0.1, (len(t), 2)))
    assert loud.smoothing is not None and loud.smoothing.span_s == pytest.approx(1.48)
    assert loud.smoothing.rate_noise > TENSION_RATE_NOISE
    with pytest.warns(TensionsWarning, match=r"even so their rates keep a noise of about 0\.0"):
        loud.warn_smoothed()
    quiet = Tensions.from_rows("quiet.csv", t, 3.0 + rng.normal(0.0, 0.01, (len(t), 2)))
    with pytest.warns(TensionsWarning) as said:
        quiet.warn_smoothed()
    assert "even so" not in str(said[0].message)


def test_smooth_tensions_are_taken_row_by_row() -> None:
    """The shipped tensions (noiseless) are the file's rows, their central differences
    and those of the rates, with no smoothing and no warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", TensionsWarning)
        table = read_tensions(DATA / "unloaded_tensions.csv", 6)
        table.warn_smoothed()
    assert table.smoothing is None
    raw = np.loadtxt(DATA / "unloaded_tensions.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table.values, raw[:, 1:])
    np.testing.assert_allclose(table.rates, np.gradient(raw[:, 1:], raw[:, 0], axis=0), atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_smooth_tensions_at_irregular_times_are_not_read_as_noise(seed: int) -> None:
    """The shipped noiseless tensions taken at 240 random times over their 8 s (a
    controller that logs when it can): the noise read between the rows needs no
    smoothing at their median step (the rows' divided differences, each over its
    weights' norm, read the noise without resampling: a line between them reads its
    own error, under 0.5 mN, as noise), while 5 mN of white noise on the same rows does,
    and is read as 5 mN."""
    from scipy.interpolate import CubicSpline

    raw = np.loadtxt(DATA / "unloaded_tensions.csv", delimiter=",", skiprows=1)
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(raw[0, 0], raw[-1, 0], 240))
    t[[0, -1]] = raw[0, 0], raw[-1, 0]
    values = CubicSpline(raw[:, 0], raw[:, 1:], axis=0)(t)
    step = float(np.median(np.diff(t)))
    assert smoothing_rows(tension_noise_std(values, t), step) == 0
    noisy = values + rng.normal(0.0, 5e-3, values.shape)
    assert smoothing_rows(tension_noise_std(noisy, t), step) > 0
    assert tension_noise_std(noisy, t) == pytest.approx(5e-3, rel=0.25)  # read as itself


def test_a_cubic_in_time_keeps_its_derivatives_through_the_smoothing() -> None:
    """Tensions that are a cubic in time plus noise: the local cubic's rates and second
    derivatives are the cubic's within a few times their noise tolerances (exact for the
    cubic itself), where the rows' central differences are off by far more."""
    t = np.arange(0.0, 8.0, 0.02)
    exact = np.column_stack([1.0 + 0.5 * t - 0.08 * t**2 + 0.004 * t**3, 2.0 + 0.1 * t])
    rate = np.column_stack([0.5 - 0.16 * t + 0.012 * t**2, 0.1 + 0 * t])
    acc = np.column_stack([-0.16 + 0.024 * t, 0 * t])
    noisy = exact + np.random.default_rng(5).normal(0.0, 0.01, exact.shape)
    table = Tensions.from_rows("cubic.csv", t, noisy)
    assert table.smoothing is not None
    inner = slice(50, -50)  # away from the ends' one-sided fits
    assert np.abs(table.rates - rate)[inner].max() < 4 * TENSION_RATE_NOISE
    assert np.abs(table.accelerations - acc)[inner].max() < 4 * TENSION_ACCELERATION_NOISE
    plain = central_differences(t, noisy)
    assert np.abs(central_differences(t, plain) - acc)[inner].max() > 20.0


def test_noisy_tensions_do_not_throw_the_estimate_off(tmp_path: Path) -> None:
    """The first 200 samples (4 s) of ``unloaded`` (raw IMUs, the command line's
    defaults) with 0.01 N of white noise on its tensions: the tip is within 3 mm of the
    truth on average after the first second, and ``estimate`` says the tensions were
    smoothed. (Differenced row by row, the whole file is 55 mm off:
    ``python tools/tension_noise_study.py unloaded``.)"""
    raw = np.loadtxt(DATA / "unloaded_tensions.csv", delimiter=",", skiprows=1)
    rng = np.random.default_rng(0)
    raw[:, 1:] = np.maximum(raw[:, 1:] + rng.normal(0.0, 0.01, raw[:, 1:].shape), 0.0)
    given = tmp_path / "noisy.csv"
    header = "t," + ",".join(f"tension_{j}" for j in range(1, 7))
    np.savetxt(given, raw, delimiter=",", header=header, comments="", fmt="%.6f")
    meas = tmp_path / "meas.csv"
    meas.write_text("\n".join((DATA / "unloaded_raw.csv").read_text().splitlines()[:201]) + "\n")
    out = tmp_path / "est.csv"
    argv = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(given),
            "-o", str(out)]  # fmt: skip
    said = r"noisy\.csv: the tensions scatter by about 0\.01\d* N .* local cubic over 0\.52 s"
    with pytest.warns(TensionsWarning, match=said):
        assert main(argv) == 0
    est, truth = read_state_table(out), read_state_table(DATA / "unloaded_truth.csv")
    tip = np.stack([est.column(c) for c in ("x", "y", "z")], axis=1)
    true_tip = np.stack([truth.column(c) for c in ("x", "y", "z")], axis=1)[: len(tip)]
    after = est.t >= 1.0
    assert float(np.mean(np.linalg.norm(tip - true_tip, axis=1)[after])) < 3e-3


def test_a_stream_of_noisy_tensions_is_said_once() -> None:
    """``live``'s stream differences its samples as they come (no smoothing, so that a
    recording replays to the same estimates): 0.01 N of noise at 50 Hz is said once,
    after the first 50 samples, with the noise its rates then carry (about 0.35 N/s,
    read from 50 samples); the
    shipped smooth tensions are not."""
    smooth = read_tensions(DATA / "force-29_tensions.csv", 6)
    rng = np.random.default_rng(4)
    noisy = smooth.values + rng.normal(0.0, 0.01, smooth.values.shape)
    stream = TensionStream("port")
    with pytest.warns(TensionsWarning) as said:
        for i in range(len(smooth.t)):
            stream.push(float(smooth.t[i]), noisy[i])
    relevant = [w for w in said if issubclass(w.category, TensionsWarning)]
    relevant = [w for w in relevant if "below 0" not in str(w.message)]  # slack readings
    assert len(relevant) == 1
    assert re.match(r"port: the tensions scatter by about 0\.01\d* N .* about 0\.[34]\d* N/s",
                    str(relevant[0].message))  # fmt: skip
    quiet = TensionStream("port")
    with warnings.catch_warnings():
        warnings.simplefilter("error", TensionsWarning)
        for i in range(len(smooth.t)):
            quiet.push(float(smooth.t[i]), smooth.values[i])


@pytest.mark.parametrize("hz", [1.0, 2.0, 3.0])
def test_a_fast_smooth_swing_is_not_read_as_noise(hz: float) -> None:
    """Two newtons swinging at up to 3 Hz, sampled at 50 Hz without noise: its high
    differences are far below the noise a 50 Hz file is smoothed for, so it is taken row
    by row (its second derivatives those of the central differences)."""
    t = np.arange(0.0, 8.0, 0.02)
    v = np.column_stack([3.0 + 2.0 * np.sin(2 * np.pi * hz * t), 1.0 + 0 * t])
    table = Tensions.from_rows("swing.csv", t, v)
    assert table.smoothing is None
    rates = central_differences(t, v)
    np.testing.assert_array_equal(table.accelerations, central_differences(t, rates))


def test_a_fast_smooth_log_and_a_hold_keep_every_row() -> None:
    """A smooth log at 1 kHz (the shipped ``force-29`` tensions through a cubic spline,
    six decimals), whose rows lie on the line through their neighbours within the
    rounding here and there, keeps every row (no resampling's pattern) and is not
    smoothed; a tension held for 2 s in a 50 Hz file has rates and second derivatives
    of exactly 0 there."""
    from scipy.interpolate import CubicSpline

    d = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)
    t = np.arange(0.0, 8.0005, 0.001)
    v = np.maximum(np.round(CubicSpline(d[:, 0], d[:, 1:])(t), 6), 0.0)
    assert line_knots(t, v).all()
    assert Tensions.from_rows("fast.csv", t, v).smoothing is None
    t50 = np.arange(0.0, 6.0, 0.02)
    held = np.column_stack([np.where(t50 < 2.0, 2.0, 2.0 + 0.3 * np.sin(t50 - 2.0) ** 2)])
    table = Tensions.from_rows("held.csv", t50, held)
    inside = t50 < 1.9
    assert np.abs(table.rates[inside]).max() < 1e-9
    assert np.abs(table.accelerations[inside]).max() < 1e-9


def test_a_slower_log_resampled_linearly_is_differenced_at_its_corners() -> None:
    """The shipped ``force-29`` tensions kept every fifth row (10 Hz) and interpolated
    linearly back to 50 Hz: the rows between the corners are left out of the
    differences, so the second derivatives are those of the 10 Hz rows interpolated to
    the 50 Hz ones (no spikes at the corners: within 0.06 N/s^2 rms of the 50 Hz
    file's, where row by row they are 0.7 off), and the values are the file's."""
    d = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)
    t, keep = d[:, 0], np.arange(0, len(d), 5)
    lin = np.column_stack([np.interp(t, t[keep], d[keep, j]) for j in range(1, 7)])
    lin = np.round(lin, 6)
    table = Tensions.from_rows("lin.csv", t, lin)
    assert table.smoothing is None
    np.testing.assert_array_equal(table.values, lin)
    slow = Tensions.from_rows("slow.csv", t[keep], lin[keep])
    at = np.column_stack([np.interp(t, t[keep], slow.accelerations[:, j]) for j in range(6)])
    np.testing.assert_allclose(table.accelerations, at, atol=1e-6)
    row_by_row = central_differences(t, central_differences(t, lin))
    fifty = read_tensions(DATA / "force-29_tensions.csv", 6).accelerations

    def rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean((a - fifty) ** 2)))

    assert rms(table.accelerations) < 0.06 and rms(row_by_row) > 0.7


def test_the_checks_read_the_rows_as_given() -> None:
    """A noisy file (smoothed) whose logger froze for 1.2 s: the freeze is said from the
    rows as given (the smoothed values repeat for less than the second that is said),
    and ``rows`` are those rows."""
    t = np.arange(0.0, 8.0, 0.02)
    rng = np.random.default_rng(7)
    v = 3.0 + 0.5 * np.sin(t)[:, None] + rng.normal(0.0, 0.01, (len(t), 2))
    frozen = (t >= 3.0) & (t < 4.2)
    v[frozen] = v[np.flatnonzero(frozen)[0]]
    table = Tensions.from_rows("frozen.csv", t, v)
    assert table.smoothing is not None
    np.testing.assert_array_equal(table.rows, v)
    with pytest.warns(TensionsWarning, match=r"repeat exactly from t = 3 to 4\.18 s"):
        table.warn_suspect()


def test_no_smoothing_span_beyond_the_longest() -> None:
    """Rows 0.5 s apart: five of them span 2 s, more than the longest local cubic
    (1.5 s), so even a noisy file is differenced row by row."""
    assert smoothing_rows(0.1, 0.5) == 0
    assert smoothing_rows(0.1, 0.3) == 5


def test_holds_and_ramps_keep_their_rates() -> None:
    """A controller's hold, ramp and hold written at 50 Hz (three straight stretches, no
    resampling's pattern) keeps every row: 0 N/s in the holds, the ramp's 0.5 N/s on
    it. A smooth 10 Hz log with a 1.4 s hold, resampled linearly to 50 Hz, keeps a knot
    every fifth row of the hold, whose rates stay 0 there."""
    t = np.arange(0.0, 8.0, 0.02)
    v = np.column_stack([np.clip(1.0 + 0.5 * (t - 2.0), 1.0, 3.0)])
    table = Tensions.from_rows("command.csv", t, v)
    assert line_knots(t, v).all()
    ramp = (t > 2.1) & (t < 5.9)
    np.testing.assert_allclose(table.rates[ramp], 0.5, atol=1e-9)
    assert np.abs(table.rates[t < 1.9]).max() < 1e-9
    slow_t = np.arange(0.0, 8.0001, 0.1)
    slow = 2.0 + np.sin(slow_t)
    hold = (slow_t >= 3.0) & (slow_t <= 4.4)
    slow[hold] = slow[hold][0]
    fast = np.round(np.column_stack([np.interp(t, slow_t, slow)]), 6)
    knots = line_knots(t, fast)
    assert knots.sum() < len(t) / 3  # the resampling's pattern is found
    resampled = Tensions.from_rows("resampled.csv", t, fast)
    inside = (t > 3.15) & (t < 4.25)
    assert np.abs(resampled.rates[inside]).max() < 1e-9


def test_jittered_times_and_slack_zeros_read_no_false_noise() -> None:
    """Exact tensions at times jittered by up to 2 ms (a logger's stamps) read as no
    noise (they are interpolated onto an even grid first); a tendon at exactly 0 for
    most of the file does not hide the noise of the rows where it pulls."""
    rng = np.random.default_rng(9)
    t = np.arange(0.0, 8.0, 0.02) + rng.uniform(-0.002, 0.002, 400)
    smooth = np.column_stack([2.0 + np.sin(t), 1.0 + 0.5 * np.cos(0.7 * t)])
    assert tension_noise_std(smooth, t) < 1e-4
    assert Tensions.from_rows("jitter.csv", t, smooth).smoothing is None
    t = np.arange(0.0, 8.0, 0.02)
    slack = np.zeros((len(t), 2))
    pulls = t > 5.0
    slack[pulls] = 1.0 + rng.normal(0.0, 0.03, (int(pulls.sum()), 2))
    assert tension_noise_std(slack, t) == pytest.approx(0.03, rel=0.3)


def _slower_log(every: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The shipped ``force-29`` tensions (50 Hz) kept every ``every``-th row, written back
    at every row two ways: ``(t, held, linear, kept rows)``, each kept value repeated
    until the next (a logger's zero-order hold) and linear between them."""
    d = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)
    t, keep = d[:, 0], np.arange(0, len(d), every)
    held = d[(np.arange(len(d)) // every) * every, 1:]
    lin = np.column_stack([np.interp(t, t[keep], d[keep, j]) for j in range(1, 7)])
    return t, held, lin, keep


def test_a_slower_log_held_at_every_row_is_taken_between_its_samples() -> None:
    """The 10 Hz tensions held over the 50 Hz rows: the rows where they change are that
    log's samples, so that the tensions, rates and second derivatives are those of the
    same log resampled linearly (to 1e-9), not the steps and spikes of the held rows
    (second derivatives 1.4 N/s^2 rms off the 50 Hz file's, row by row); the rows as
    given stay what the checks read, and it is said."""
    t, held, lin, keep = _slower_log()
    found = hold_knots(t, held)
    assert found is not None
    knots, period = found
    np.testing.assert_array_equal(np.flatnonzero(knots), keep)
    assert period == pytest.approx(0.1)
    table = Tensions.from_rows("held.csv", t, held)
    linear = Tensions.from_rows("lin.csv", t, lin)
    assert table.hold_period_s == pytest.approx(0.1) and linear.hold_period_s == 0.0
    np.testing.assert_allclose(table.values, linear.values, atol=1e-9)
    np.testing.assert_allclose(table.rates, linear.rates, atol=1e-9)
    np.testing.assert_allclose(table.accelerations, linear.accelerations, atol=1e-9)
    np.testing.assert_array_equal(table.rows, held)
    fifty = read_tensions(DATA / "force-29_tensions.csv", 6).accelerations
    row_by_row = central_differences(t, central_differences(t, held))
    assert np.sqrt(np.mean((row_by_row - fifty) ** 2)) > 1.0
    with pytest.warns(TensionsWarning, match=r"held\.csv: the tensions hold each value for "
                      r"about 0\.1 s \(a log at 10 Hz"):  # fmt: skip
        table.warn_held()


def test_a_quantised_ramp_is_read_as_its_slope() -> None:
    """A load cell's 0.01 N steps on a 0.1 N/s ramp sampled at 50 Hz change every fifth
    row: taken between its changes, the ramp's rate is 0.1 N/s on every inner row (row
    by row it is 0 or 0.25 N/s); a value that changes on every row, or a hold of 2 s
    in a smooth swing, is no held log."""
    t = np.arange(0.0, 6.0, 0.02)
    steps = np.column_stack([np.floor(np.round((1.0 + 0.1 * t) / 0.01, 9)) * 0.01])
    table = Tensions.from_rows("cell.csv", t, steps)
    assert table.hold_period_s == pytest.approx(0.1)
    inner = (t > 0.2) & (t < 5.7)
    np.testing.assert_allclose(table.rates[inner], 0.1, atol=1e-9)
    assert hold_knots(t, np.column_stack([1.0 + 0.1 * t])) is None
    swing = np.column_stack([np.where(t < 2.0, 2.0, 2.0 + 0.3 * np.sin(t - 2.0) ** 2)])
    assert hold_knots(t, swing) is None


def test_a_recordings_held_tension_columns_and_a_held_stream_are_said(tmp_path: Path) -> None:
    """A recording whose own tension columns hold a 10 Hz log's values (differenced row
    by row, as ``live`` takes them) is told to give them as a tensions file; so is one
    whose columns are resampled linearly; ``live``'s stream of held tensions says it
    once, instead of reading the steps as a load cell's noise."""
    t, held, lin, _ = _slower_log()
    raw = (DATA / "force-29_raw.csv").read_text().splitlines()
    names = ",".join(f"tension_{j}" for j in range(1, 7))
    for kind, values in (("hold each value of", held), ("are resampled linearly from", lin)):
        rec = tmp_path / "rec.csv"
        rows = [f"{r},{','.join(f'{v:.6f}' for v in values[i])}" for i, r in enumerate(raw[1:])]
        rec.write_text("\n".join([f"{raw[0]},{names}", *rows]) + "\n")
        table = read_tensions(rec, 6, other_columns=True)
        with pytest.warns(TensionsWarning, match=f"rec.csv: the tension columns {kind} a "
                          r"slower log \(every 0\.1 s, 10 Hz\).*--inputs"):  # fmt: skip
            table.warn_slower_log()
    quiet = read_tensions(DATA / "force-29_tensions.csv", 6)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TensionsWarning)
        quiet.warn_slower_log()
    stream = TensionStream("port")
    with pytest.warns(TensionsWarning) as said:
        for i in range(len(t)):
            stream.push(float(t[i]), held[i])
    relevant = [str(w.message) for w in said if issubclass(w.category, TensionsWarning)]
    assert len(relevant) == 1
    assert relevant[0].startswith("port: the tensions hold each value of a slower log")


def test_a_held_tensions_file_estimates_as_its_linear_resampling(tmp_path: Path) -> None:
    """``estimate`` with the 10 Hz tensions held over the 50 Hz rows of the first 2 s of
    ``force-29`` (a tip force growing from the start, 0.22 N at 2 s; the files end on a
    sample of the 10 Hz log) gives the estimates of the same log resampled linearly (to
    1e-6: the files keep nine digits; a bend angle of a nearly straight section moves
    most), and says the hold."""
    rows = 101
    t, held, lin, keep = _slower_log()
    assert rows - 1 in keep
    raw = tmp_path / "raw.csv"
    raw.write_text("".join((DATA / "force-29_raw.csv").read_text().splitlines(True)[: rows + 1]))
    header = "t," + ",".join(f"tension_{j}" for j in range(1, 7))
    outs = []
    for name, values in (("held", held), ("lin", lin)):
        f = tmp_path / f"{name}.csv"
        np.savetxt(f, np.column_stack([t, values])[:rows], delimiter=",", fmt="%.9g",
                   header=header, comments="")  # fmt: skip
        out = tmp_path / f"est_{name}.csv"
        argv = ["estimate", str(raw), "--robot", "tendon-two-section", "--inputs", str(f),
                "-o", str(out)]  # fmt: skip
        if name == "held":
            with pytest.warns(TensionsWarning, match="hold each value for about 0.1 s"):
                assert main(argv) == 0
        else:
            assert main(argv) == 0
        outs.append(read_state_table(out))
    np.testing.assert_allclose(outs[0].values, outs[1].values, rtol=0, atol=1e-6)
    assert list(outs[0].status) == list(outs[1].status)


@pytest.mark.parametrize("hz", [9.5, 9.9, 8.0])
def test_a_log_held_at_a_period_of_no_whole_number_of_rows_is_found(hz: float) -> None:
    """The ``force-29`` tensions sampled at a rate that is no divisor of 50 Hz and held:
    changes every 5 or 6 rows (9.5 Hz), mostly 5 with a 6 now and then (9.9 Hz), 6 or
    7 (8 Hz). The hold is found at its rate, and the tensions, linear between the
    changes, are within 0.01 N rms of the 50 Hz file's (a change is taken at the row
    where it appears, up to a row late), where the held rows as given lag them by half a
    period: 0.03 N rms or more."""
    d = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)
    t = d[:, 0]
    ts = np.arange(0.0, t[-1] + 1e-9, 1.0 / hz)
    slow = np.column_stack([np.interp(ts, t, d[:, j]) for j in range(1, 7)])
    held = slow[np.searchsorted(ts, t + 1e-9, side="right") - 1]
    found = hold_knots(t, held)
    assert found is not None and 1.0 / found[1] == pytest.approx(hz, rel=0.02)
    fifty = read_tensions(DATA / "force-29_tensions.csv", 6).values

    def rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean((a - fifty) ** 2)))

    assert rms(Tensions.from_rows("held.csv", t, held).values) < 0.01
    assert rms(tension_derivatives(t, held, hold=False).values) > 0.03


def test_a_held_log_that_holds_to_the_end_keeps_its_rate_zero_there() -> None:
    """A 10 Hz ramp from 1 N at 0.5 N/s, held at 3.5 N from 5 s to the end of an 8 s
    file: 0.5 N/s on the ramp, 0 over the held end (not the ramp's slope carried on)."""
    t = np.arange(0.0, 8.0, 0.02)
    slow_t = np.arange(0.0, 8.0001, 0.1)
    slow = np.minimum(1.0 + 0.5 * slow_t, 3.5)
    rows = slow[np.searchsorted(slow_t, t + 1e-9, side="right") - 1][:, None]
    table = Tensions.from_rows("tail.csv", t, rows)
    assert table.hold_period_s == pytest.approx(0.1)
    np.testing.assert_allclose(table.rates[(t > 1.0) & (t < 4.0)], 0.5, atol=1e-9)
    assert np.abs(table.rates[t > 5.2]).max() < 1e-9


@pytest.mark.parametrize("resampled", [False, True])
def test_a_slower_logs_ends_take_second_order_differences(resampled: bool) -> None:
    """Tensions ``a t^2`` from rest at 10 Hz (the file's own rows, or resampled linearly
    to 50 Hz): at the first row the rate is 0 and the second derivative ``2 a``, exact
    for a quadratic, where the chord to the next sample gives ``a h`` and half of
    ``2 a``; at the last row too. A file at the IMUs' 50 Hz keeps the chord at its ends,
    as a recording's own columns and ``live`` difference them."""
    a = 3.0
    slow_t = np.arange(0.0, 2.0001, 0.1)
    t = np.arange(0.0, 2.0001, 0.02) if resampled else slow_t
    rows = (a * np.interp(t, slow_t, slow_t**2))[:, None]
    table = Tensions.from_rows("slow.csv", t, rows)
    assert table.rates[0, 0] == pytest.approx(0.0, abs=1e-9)
    assert table.accelerations[0, 0] == pytest.approx(2 * a, rel=1e-9)
    assert table.rates[-1, 0] == pytest.approx(2 * a * t[-1], rel=1e-9)
    assert table.accelerations[-1, 0] == pytest.approx(2 * a, rel=1e-9)
    fast_t = np.arange(0.0, 2.0001, 0.02)
    fast = Tensions.from_rows("fast.csv", fast_t, (a * fast_t**2)[:, None])
    assert fast.rates[0, 0] == pytest.approx(a * 0.02, rel=1e-9)  # the chord


def test_the_start_of_a_10_hz_tensions_file_is_not_thrown_off(tmp_path: Path) -> None:
    """``unloaded``'s tensions kept at every fifth row (a 10 Hz log, from rest): the
    first estimates are as close as the 50 Hz file's (within 1 mm over the first
    second), and the start is not taken as under load (the chord to the next sample
    at the first row puts the first estimate 28.9 mm off and every row ``uncertain``)."""
    d = np.loadtxt(DATA / "unloaded_tensions.csv", delimiter=",", skiprows=1)
    slow = tmp_path / "slow.csv"
    header = "t," + ",".join(f"tension_{j}" for j in range(1, 7))
    np.savetxt(slow, d[::5], delimiter=",", fmt="%.9g", header=header, comments="")
    lines = (DATA / "unloaded_raw.csv").read_text().splitlines()
    first = tmp_path / "first.csv"
    first.write_text("\n".join(lines[: 1 + 51]) + "\n")  # the first second
    out = tmp_path / "e.csv"
    argv = ["estimate", str(first), "--robot", "tendon-two-section", "--inputs", str(slow),
            "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    est, truth = read_state_table(out), read_state_table(DATA / "unloaded_truth.csv")
    tip = np.column_stack([est.column(c) for c in "xyz"])
    true_tip = np.column_stack([truth.column(c)[: len(tip)] for c in "xyz"])
    err = np.linalg.norm(tip - true_tip, axis=1)
    assert err.max() < 1e-3, err.max()
    assert list(est.status).count("ok") >= len(tip) - 2


def test_a_recordings_own_noisy_tension_columns_are_said_as_live_says_them(tmp_path) -> None:
    """A recording whose own tension columns carry a load cell's noise (as ``live
    --record`` writes them) is differenced row by row, as ``live`` takes it, and
    ``estimate`` says so as ``live`` does, naming a tensions file of their own (smoothed);
    the shipped smooth tensions in the same columns are not said."""
    smooth = read_tensions(DATA / "force-29_tensions.csv", 6)
    rng = np.random.default_rng(5)
    cols = ",".join(f"tension_{j}" for j in range(1, 7))
    for noise, said in ((0.0, False), (0.001, True)):
        values = smooth.values + rng.normal(0.0, noise, smooth.values.shape)
        values = np.maximum(values, 0.0)
        rows = [
            f"{tk:.2f},0,0,9.81,0,0,0," + ",".join(f"{x:.6f}" for x in vk)
            for tk, vk in zip(smooth.t, values)
        ]
        path = tmp_path / f"rec{noise}.csv"
        path.write_text("\n".join([f"t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,{cols}", *rows]) + "\n")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            read_tensions(path, 6, other_columns=True).warn_slower_log()
        notes = [str(w.message) for w in caught if "scatter" in str(w.message)]
        assert bool(notes) == said
        if said:
            assert re.search(r"scatter by about 0\.00\d+ N .*--inputs TENSIONS\.csv", notes[0])


def test_a_logger_hole_keeps_the_smoothed_rates_of_the_rows_beside_it() -> None:
    """Noisy tensions of a slow swing at 50 Hz with jittered times and a 0.5 s hole (a
    logger that paused): the smoothed rates beside the hole follow the swing's as they
    do without the hole (the even grid fills the hole; rows either side are not taken
    as one step apart)."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 6.0, 0.02) + rng.uniform(-2e-3, 2e-3, 300)
    t.sort()
    keep = (t < 3.0) | (t > 3.5)  # the hole
    swing = lambda tt: 2.0 + np.sin(2 * np.pi * 0.3 * tt)  # noqa: E731
    rate = lambda tt: 2 * np.pi * 0.3 * np.cos(2 * np.pi * 0.3 * tt)  # noqa: E731
    values = (swing(t) + rng.normal(0.0, 0.02, len(t)))[:, None]
    whole = tension_derivatives(t, values)
    holed = tension_derivatives(t[keep], values[keep])
    near = (np.abs(t[keep] - 3.0) < 0.2) | (np.abs(t[keep] - 3.5) < 0.2)
    err_whole = np.max(np.abs(whole.rates[keep][near, 0] - rate(t[keep][near])))
    err_holed = np.max(np.abs(holed.rates[near, 0] - rate(t[keep][near])))
    assert err_holed < 2.0 * err_whole + 0.3, (err_holed, err_whole)


@pytest.mark.parametrize("second", ["same", "noisy"])
def test_a_row_written_twice_a_hair_apart_keeps_the_rates_around_it(second: str) -> None:
    """A row written again 1 us later (the same tensions, or 1 mN off): its differences
    would lean on that microsecond (a rate of 0, or 1000 N/s); it is left out of the
    differences, so that every row's rate and second derivative are those of the file
    without it, to the interpolation of the rates onto it. Every row keeps its value."""
    d = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)[:200]
    t, values = d[:, 0], d[:, 1:]
    at = 100
    twice = values[at] + (1e-3 if second == "noisy" else 0.0)
    t2 = np.insert(t, at + 1, t[at] + 1e-6)
    v2 = np.insert(values, at + 1, twice, axis=0)
    alone = tension_derivatives(t, values)
    both = tension_derivatives(t2, v2)
    others = np.delete(np.arange(len(t2)), at + 1)
    assert np.array_equal(both.values, v2)
    assert_allclose(both.rates[others], alone.rates, rtol=0, atol=1e-12)
    assert_allclose(both.accelerations[others], alone.accelerations, rtol=0, atol=1e-9)
    assert_allclose(both.rates[at + 1], alone.rates[at], rtol=0, atol=1e-3)


def test_a_file_of_every_row_written_twice_keeps_its_rates() -> None:
    """Every row of the shipped tensions written again 1 us later, 1 mN off (more than
    half the steps a microsecond: their median one): the rates and second derivatives
    are those of the file written once, not zero."""
    from continuum_mhe.arrays import typical_step

    d = np.loadtxt(DATA / "force-29_tensions.csv", delimiter=",", skiprows=1)[:200]
    t, values = d[:, 0], d[:, 1:]
    t2 = np.sort(np.concatenate([t, t + 1e-6]))
    v2 = np.repeat(values, 2, axis=0)
    v2[1::2] += 1e-3  # each copy 1 mN off (a load cell read twice): no held log
    assert typical_step(t2) == pytest.approx(0.02 - 1e-6, rel=1e-9)
    alone, both = tension_derivatives(t, values), tension_derivatives(t2, v2)
    # (the last rows: the file's last row is the copy, 1 us later, and is kept)
    assert_allclose(both.rates[:-4:2], alone.rates[:-2], rtol=0, atol=1e-9)
    assert_allclose(both.accelerations[:-6:2], alone.accelerations[:-3], rtol=0, atol=1e-6)
