"""Glitches of the given tensions (:mod:`continuum_mhe.io.tension_glitches`): found
where one row alone, or two in a row, leave the curve through their neighbours, replaced by that
curve in a tensions file and in a stream, never found in smooth motions, steps, a slack
tendon that starts to pull or a slower log held at every row; and a glitch does not
send the tendon robot's estimate off for the rest of the recording."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tendon_helpers import DATA, default_ekf_run

from continuum_mhe.errors import InputError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import open_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tension_derivatives import tension_noise_std
from continuum_mhe.io.tension_glitches import tension_glitches
from continuum_mhe.io.tensions import Tensions, TensionStream, TensionsWarning, read_tensions
from continuum_mhe.model.registry import make_formulation

T = np.arange(0.0, 10.0, 0.02)  # 50 Hz


def _glitches(values: np.ndarray, t: np.ndarray = T) -> np.ndarray:
    """The (row, tendon) pairs found as glitches."""
    return np.argwhere(tension_glitches(t, values, tension_noise_std(values, t)).mask)


def _smooth(seed: int, tendons: int = 3, fastest: float = 3.0) -> np.ndarray:
    """Tensions of a controller's smooth motion: three sinusoids up to ``fastest`` Hz,
    up to 2 N."""
    rng = np.random.default_rng(seed)
    v = np.full((len(T), tendons), 2.5)
    for _ in range(3):
        amp, ph = rng.uniform(0.1, 0.7, tendons), rng.uniform(0, 6)
        f = rng.uniform(0.05, fastest)
        v += amp * np.sin(2 * math.pi * f * T[:, None] + ph)
    return v


def test_a_glitch_is_found_alone_and_replaced_by_the_curve_through_its_neighbours() -> None:
    """One tension 0.02 N off at one row of a smooth motion (up to 1 Hz): that tension
    alone is a glitch, and the curve it is replaced by lies within 0.05 mN of the
    motion."""
    clean = _smooth(0, fastest=1.0)
    v = clean.copy()
    v[200, 1] += 0.02
    found = tension_glitches(T, v, tension_noise_std(v, T))
    assert np.argwhere(found.mask).tolist() == [[200, 1]]
    assert abs(found.replaced(v)[200, 1] - clean[200, 1]) < 5e-5
    assert np.array_equal(found.replaced(v)[found.mask == 0], v[found.mask == 0])


@pytest.mark.parametrize(
    "case",
    ["steps", "slack-start", "fast-sine", "held-log", "noise", "uneven-times", "early-kink"],
)
def test_no_glitch_in_what_tensions_do(case: str) -> None:
    """A controller's steps, a slack tendon that starts to pull (a kink at zero), a 5 Hz
    swing of 2 N, a 10 Hz log held at every 50 Hz row, a load cell's white noise, rows
    at jittered times, and kinks and steps within a file's first and last rows: none is
    a glitch."""
    rng = np.random.default_rng(1)
    t = T
    if case == "steps":
        v = 1.0 + 0.5 * np.floor(T / 1.3)[:, None] * np.array([1.0, -0.3])
    elif case == "slack-start":
        v = np.maximum(0.0, (T - 2.01) * 0.8)[:, None] * np.array([1.0, 3.0])
    elif case == "fast-sine":
        v = 2.0 + 2.0 * np.sin(2 * math.pi * 5.0 * T)[:, None]
    elif case == "held-log":
        v = np.repeat(np.round(1 + 0.3 * np.sin(T[::5]), 3), 5)[:, None]
    elif case == "early-kink":  # a tendon that starts to pull, and a step, at rows 2 to 5
        k = np.arange(len(T))[:, None]
        v = np.hstack([np.maximum(0.0, (k - j) * 0.02) for j in (2, 3, 4, 5)])
        v = np.hstack([v, np.where(k >= 3, 1.0, 0.5), np.where(k >= len(T) - 3, 1.0, 0.5)])
    elif case == "noise":
        v = 1.0 + 0.01 * rng.normal(size=(len(T), 3))
    else:
        t = np.sort(T + 0.004 * rng.uniform(size=len(T)))
        v = 1.0 + 0.3 * np.sin(3.0 * t)[:, None]
    assert _glitches(v, t).size == 0


@pytest.mark.parametrize("seed", [5, 37, 39])
def test_a_noisy_step_is_no_two_row_glitch(seed: int) -> None:
    """A controller's step of 0.2 N read with 5 mN of noise: the two rows at the step
    nearly echo as a two-row glitch would, but the four rows each side lie on two
    levels, not one cubic; none is a glitch (these seeds' steps are not taken for one and
    smeared into a ramp)."""
    rng = np.random.default_rng(seed)
    v = (1.0 + 0.2 * (T >= 5.0) + 0.005 * rng.normal(size=len(T)))[:, None]
    assert _glitches(v).size == 0


def test_two_rows_off_are_found_together_and_replaced_by_the_curve_around_them() -> None:
    """Two rows in a row that a logger held at the row before's values (every tendon),
    or one tension 0.02 N off at both: those tensions alone are glitches, replaced
    within 0.2 mN of the motion (up to 1 Hz); the single-row test alone finds none of
    them."""
    clean = _smooth(3, fastest=1.0)
    held = clean.copy()
    held[200] = held[201] = clean[199]
    found = tension_glitches(T, held, tension_noise_std(held, T))
    assert np.argwhere(found.mask).tolist() == [[r, c] for r in (200, 201) for c in range(3)]
    assert np.max(np.abs(found.replaced(held) - clean)) < 2e-4
    off = clean.copy()
    off[300:302, 2] += 0.02
    found = tension_glitches(T, off, tension_noise_std(off, T))
    assert np.argwhere(found.mask).tolist() == [[300, 2], [301, 2]]
    assert np.max(np.abs(found.replaced(off) - clean)) < 2e-4


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 1000),
    row=st.integers(4, len(T) - 6),
    size=st.floats(0.005, 1.0),
    ratio=st.floats(0.5, 2.0),
    signs=st.sampled_from([(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]),
)
def test_two_rows_off_on_any_smooth_motion_are_found_and_only_they(
    seed: int, row: int, size: float, ratio: float, signs: tuple[float, float]
) -> None:
    """Across smooth motions up to 1 Hz, one tension off at two rows in a row (5 mN to
    2 N each, within a factor of two of each other, of either sign) at any row but the
    first and last four: exactly those two are found."""
    v = _smooth(seed, fastest=1.0)
    c = seed % 3
    for r, h in ((row, signs[0] * size), (row + 1, signs[1] * size * ratio)):
        v[r, c] += h
    v = np.maximum(v, 0.0)
    assert _glitches(v).tolist() == [[row, c], [row + 1, c]]


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    row=st.integers(2, len(T) - 3),
    size=st.floats(0.005, 1.0),
    sign=st.sampled_from([-1.0, 1.0]),
)
def test_a_glitch_on_any_smooth_motion_is_found_and_only_it(
    seed: int, row: int, size: float, sign: float
) -> None:
    """Across smooth motions, glitches of 5 mN to 1 N at any row but the first and last
    two: exactly that tension is found where the motion is up to 1 Hz; motions up to
    3 Hz alone have none. (A glitch is told from the motion by the same departure of
    the rows around: one under four times that is taken as the motion's.)"""
    assert _glitches(_smooth(seed)).size == 0
    v = _smooth(seed, fastest=1.0)
    assert _glitches(v).size == 0
    v[row, seed % 3] = max(0.0, v[row, seed % 3] + sign * size)
    assert _glitches(v).tolist() == [[row, seed % 3]]


def test_a_tensions_file_says_its_glitch_and_takes_the_curve() -> None:
    """:meth:`Tensions.from_rows` warns of a glitch, naming its line, tendon and value,
    and its tensions and rates there are those of the rows without the glitch."""
    clean = _smooth(2, fastest=1.0)
    v = clean.copy()
    v[100, 2] += 0.1
    lines = tuple(range(2, len(T) + 2))
    with pytest.warns(TensionsWarning, match=r"f.csv: 1 tension in 1 row leaves .* line 102"):
        table = Tensions.from_rows("f.csv", T, v, lines=lines)
    reference = Tensions.from_rows("f.csv", T, clean, lines=lines)
    assert np.max(np.abs(table.values - reference.values)) < 1e-4
    assert np.max(np.abs(table.rates - reference.rates)) < 0.01
    assert table.rows[100, 2] == v[100, 2]  # the file as given


def test_a_huge_glitch_is_replaced_not_refused_as_tensions_in_mn() -> None:
    """One tension of 1e9 N on one row of the shipped ``unloaded`` tensions is a glitch,
    replaced by the curve through its neighbours and said; the scale check (tensions in
    mN, a modulus far too low) judges the tensions the estimate takes, so it passes,
    as the warning says. The same tensions a thousand times too large throughout are
    refused."""
    robot = read_robot("tendon-two-section")
    table = read_tensions(DATA / "unloaded_tensions.csv", robot.n_tendons)
    v = table.values.copy()
    v[30, 0] = 1e9
    lines = tuple(range(2, len(table.t) + 2))
    with pytest.warns(TensionsWarning, match=r"line 32 \(tension_1 1e\+09 N where"):
        glitched = Tensions.from_rows("f.csv", table.t, v, lines=lines)
    glitched.check_scale(robot)
    assert glitched.values[30, 0] < 10.0 and glitched.rows[30, 0] == 1e9
    with pytest.raises(InputError, match=r"^f.csv: line \d+: .* full turns"):
        Tensions.from_rows("f.csv", table.t, 1000.0 * table.values, lines=lines).check_scale(robot)


def test_live_replaces_a_glitch_before_its_derivatives_are_given_and_a_replay_alike(
    tmp_path: Path,
) -> None:
    """``live``'s stream holds the samples a candidate glitch enters (two each side)
    until the two samples after it are in and judge it: the derivatives it gives are
    those of the tensions without the glitches (two on one tendon five samples apart
    among them), it counts and says them once, and a recording's own tension columns (a
    replay) give the same values and derivatives."""
    clean = np.round(_smooth(3, fastest=1.0), 6)  # as the recording below writes them
    v = clean.copy()
    v[150, 0] += 0.05
    v[155, 0] += 0.05  # judged after the one before it was replaced
    v[300, 2] -= 0.05
    given = {}
    for name, x in (("clean", clean), ("glitched", v)):
        stream = TensionStream("serial", 3)
        out = []
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            for tk, vk in zip(T, x):
                out.extend(stream.push(float(tk), vk))
            out.extend(stream.end())
        given[name] = out
    notes = [w for w in said if "glitch" in str(w.message)]
    assert len(notes) == 1 and "t = 3 s" in str(notes[0].message) and stream.glitches == 3
    for part in ("values", "rates", "accelerations"):
        a = np.array([getattr(s, part) for s in given["glitched"]])
        b = np.array([getattr(s, part) for s in given["clean"]])
        assert np.max(np.abs(a - b)) < {"values": 1e-4, "rates": 1e-2, "accelerations": 1.0}[part]
    header = "t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,tension_1,tension_2,tension_3"
    rows = [f"{tk:.2f},0,0,9.81,0,0,0," + ",".join(f"{x:.6f}" for x in vk) for tk, vk in zip(T, v)]
    recording = tmp_path / "rec.csv"
    recording.write_text("\n".join([header, *rows]) + "\n")
    with pytest.warns(TensionsWarning, match="3 tensions in 3 rows leave .* line 152"):
        own = read_tensions(recording, 3, other_columns=True)
    for part in ("values", "rates", "accelerations"):
        streamed = np.array([getattr(s, part) for s in given["glitched"]])
        assert np.max(np.abs(getattr(own, part) - streamed)) < 1e-9


@pytest.mark.parametrize("size", [1e9, 1e200])
def test_a_huge_glitch_in_a_stream_takes_the_curve_through_its_neighbours(size: float) -> None:
    """``live``'s stream (and a replay of a recording's own tension columns) replaces a
    glitch of any size by the curve through its neighbours, as a tensions file does:
    not by the glitch less its departure, which rounding takes to 0 N from 1e17 N on."""
    clean = np.round(_smooth(3, fastest=1.0), 6)
    v = clean.copy()
    v[150, 0] = size
    given = {}
    for name, x in (("clean", clean), ("glitched", v)):
        stream = TensionStream("serial", 3)
        out = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TensionsWarning)
            for tk, vk in zip(T, x):
                out.extend(stream.push(float(tk), vk))
            out.extend(stream.end())
        given[name] = np.array([s.values for s in out])
    assert stream.glitches == 1
    assert np.max(np.abs(given["glitched"] - given["clean"])) < 1e-4


def test_a_stream_of_noise_has_no_glitch_and_starts_afresh_after_its_end() -> None:
    """A slow motion with a load cell's white noise (2 mN at 50 Hz, 40 streams): no
    sample is taken as a glitch, from the first; after :meth:`TensionStream.end` the
    stream takes a new run from t = 0."""
    t = np.arange(0.0, 4.0, 0.02)
    stream = TensionStream("serial", 1)
    for seed in range(40):
        x = 1.0 + 0.3 * np.sin(np.pi * t) + 0.002 * np.random.default_rng(seed).normal(size=len(t))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TensionsWarning)  # the noise itself is said
            for tk, xk in zip(t, x):
                stream.push(float(tk), [xk])
            assert len(stream.end()) > 0
    assert stream.glitches == 0


@pytest.mark.parametrize("glitch", ["one-row", "held-two-rows", "two-rows"])
def test_a_tension_glitch_does_not_send_the_estimate_off(tmp_path: Path, glitch: str) -> None:
    """The shipped ``force-29`` (raw IMUs, EKF) with one tension 0.05 N off at one row
    (t = 1 s), a logger that held the row before for two rows (t = 1 and 1.02 s), or
    one tension 0.05 N off at those two rows: the glitch is replaced, and the tip stays
    within 0.1 mm of the clean file's estimate on average (55, 21 and 45 mm off, with
    the glitch taken as given)."""
    lines = (DATA / "force-29_tensions.csv").read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("t,"))
    rows = [ln.split(",") for ln in lines[head + 1 :]]
    assert float(rows[50][0]) == 1.0
    if glitch == "held-two-rows":
        rows[50][1:] = rows[51][1:] = rows[49][1:]
    for r in {"one-row": [50], "two-rows": [50, 51]}.get(glitch, []):
        rows[r][1] = f"{float(rows[r][1]) + 0.05:.6f}"
    glitched = tmp_path / "glitched.csv"
    glitched.write_text("\n".join([*lines[: head + 1], *(",".join(r) for r in rows)]))
    run = default_ekf_run("force-29", "raw")  # the clean file's, once a test process
    clean = _tips(run.f, run.series)
    assert np.mean(np.linalg.norm(_force29_ekf_tips(str(glitched)) - clean, axis=1)) < 1e-4


def _tips(f: object, series: object) -> np.ndarray:
    """The tip (x, y, z) of every estimate of ``series``."""
    cols = [o.name for o in f.outputs]  # type: ignore[attr-defined]
    return np.asarray(series.output, float)[:, [cols.index(c) for c in "xyz"]]  # type: ignore[attr-defined]


def _force29_ekf_tips(tensions: str) -> np.ndarray:
    """The EKF's tip (x, y, z) on the shipped ``force-29`` (raw IMUs) with ``tensions``."""
    base = make_formulation("bend", read_robot("tendon-two-section"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open_input(DATA / "force-29_raw.csv", InputOptions(tensions=tensions), base) as s:
            f = s.formulation
            blocks = list(s.blocks)
        t, z = np.concatenate([b[0] for b in blocks]), np.vstack([b[1] for b in blocks])
        series = make_estimator("ekf", f).run(t, z)
    return _tips(f, series)
