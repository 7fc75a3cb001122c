"""The paper formulation's inputs and checks of a state run in compiled code, taped from
their symbolic form: they are the definitions (independent numpy versions here, near
the singular points: straight, gimbal lock, phi's wrap), and a run calls no Python for
them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from continuum_mhe.estimators import make_estimator
from continuum_mhe.model.formulations import AT_BOUND_TOL, DIVERGED_MARGIN
from continuum_mhe.model.paper import DRIFT_FRACTION, PHI_BOUND_THETA, PaperFormulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate

angles = st.floats(-math.pi, math.pi, allow_nan=False)
near = st.sampled_from([0.0, 1e-9, -1e-9, math.pi / 2, -math.pi / 2, math.pi, -math.pi])


def _shape(roll: float, pitch: float, up: float) -> tuple[float, float]:
    """(theta, phi) of a tilt reading: the gravity direction's angle from the base's z
    axis and its azimuth (0 where straight)."""
    g = up * np.array([-math.sin(pitch), math.cos(pitch) * math.sin(roll),
                       math.cos(pitch) * math.cos(roll)])  # fmt: skip
    theta = math.acos(min(max(g[2], -1.0), 1.0))
    return theta, 0.0 if theta == 0.0 else math.atan2(g[1], g[0])


def _paper(mounting: str = "z-up") -> PaperFormulation:
    f = make_formulation("paper", Robot.single(0.3, 3.0, mounting=mounting))
    assert isinstance(f, PaperFormulation)
    return f


@settings(max_examples=300, deadline=None)
@given(
    st.tuples(angles | near, angles | near),
    st.tuples(angles | near, angles | near),
    st.floats(1e-3, 2.0),
    st.sampled_from(["z-up", "z-down"]),
)
@example((0.0, 0.0), (0.0, 0.0), 0.05, "z-up")  # straight: phi 0
@example((0.0, 0.3), (1e-12, 0.3), 0.05, "z-up")  # phi crosses pi
@example((0.1, math.pi / 2), (0.2, -math.pi / 2), 0.05, "z-down")  # gimbal lock
def test_the_inputs_are_the_change_of_the_shape_the_readings_show(
    z_prev: tuple[float, float], z: tuple[float, float], dt: float, mounting: str
) -> None:
    f = _paper(mounting)
    up = 1.0 if mounting == "z-up" else -1.0
    theta0, phi0 = _shape(*z_prev, up)
    theta1, phi1 = _shape(*z, up)
    u = f.inputs(np.array(z_prev), np.array(z), dt)
    assert u.shape == (2,)
    assert u[0] == pytest.approx((theta1 - theta0) / dt, rel=1e-9, abs=1e-9)
    turn = (u[1] * dt - (phi1 - phi0)) / (2 * math.pi)  # phi's change, wrapped
    assert abs(turn - round(turn)) < 1e-9
    assert -math.pi - 1e-9 <= u[1] * dt < math.pi + 1e-9


def test_the_inputs_are_zero_without_a_previous_reading_or_with_a_dropout() -> None:
    f = _paper()
    z = np.array([0.3, -0.2])
    assert np.any(f.inputs(np.array([0.1, 0.1]), z, 0.05) != 0.0)
    for z_prev, now in [(None, z), (np.array([np.nan, 0.1]), z), (z, np.array([0.1, np.inf]))]:
        np.testing.assert_array_equal(f.inputs(z_prev, now, 0.05), [0.0, 0.0])


def _tip(theta: float, phi: float, length: float) -> np.ndarray:
    """The arc's tip: bent by ``theta`` towards ``-(cos phi, sin phi, 0)`` (the tip frame
    ``Rz(phi) Ry(-theta) Rz(-phi)``)."""
    if theta == 0.0:
        return np.array([0.0, 0.0, length])
    across = 2 * math.sin(theta / 2) ** 2 / theta  # (1 - cos theta) / theta
    return length * np.array([-across * math.cos(phi), -across * math.sin(phi),
                              math.sin(theta) / theta])  # fmt: skip


@settings(max_examples=400, deadline=None)
@given(
    st.tuples(*[st.floats(-1.2, 1.2)] * 3),
    st.floats(-1.5, 4.5) | st.sampled_from([0.0, 0.1, 3.0 - 1e-3, 3.0, 4.0]),
    angles | st.sampled_from([math.pi - 5e-4, -math.pi + 5e-4, math.pi - 2e-3]),
    st.booleans(),
    st.floats(0.0, 0.06),
)
def test_the_checks_are_the_paper_formulation_s_rules(
    position: tuple[float, float, float], theta: float, phi: float, on_arc: bool, off: float
) -> None:
    f = _paper()
    length, theta_max = f.length, f.robot.theta_max
    p = np.array(position) * length
    if on_arc:  # near the tip of its own angles, up to 0.06 lengths off along x
        p = _tip(theta, phi, length) + np.array([off * length, 0.0, 0.0])
    x = np.array([*p, theta, phi])
    drift = float(np.linalg.norm(p - _tip(theta, phi, length)))
    # (not on a threshold to rounding)
    for value, limit in [(drift, DRIFT_FRACTION * length), (float(np.linalg.norm(p)), 3 * length)]:
        if abs(value - limit) < 1e-9:
            return
    diverged = not -DIVERGED_MARGIN <= theta <= theta_max + DIVERGED_MARGIN
    diverged = diverged or float(np.linalg.norm(p)) > 3 * length
    at_bound = theta >= theta_max - AT_BOUND_TOL or (
        theta > PHI_BOUND_THETA and abs(abs(phi) - math.pi) <= AT_BOUND_TOL
    )
    assert f.is_diverged(x) == diverged
    assert f.at_bound(x) == at_bound
    assert f.drifted(x) == (drift > DRIFT_FRACTION * length)
    assert f.is_diverged(x, np.eye(5)) == diverged
    bad = np.eye(5)
    bad[4, 0] = np.nan
    assert f.is_diverged(x, bad)
    x[2] = np.inf
    assert f.is_diverged(x)


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_a_run_of_the_paper_formulation_calls_no_python_per_sample(
    method: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[str] = []
    for name in ("inputs", "is_diverged", "at_bound", "drifted"):
        original = getattr(PaperFormulation, name)

        def counted(self: PaperFormulation, *args: object, _f=original, _n=name) -> object:  # type: ignore[no-untyped-def]
            calls.append(_n)
            return _f(self, *args)

        monkeypatch.setattr(PaperFormulation, name, counted)
    rec = simulate("paper3d", duration=4, seed=0)
    series = make_estimator(method, _paper(), MHESettings(horizon=10)).run(rec.t, rec.z)
    assert len(series.t) == len(rec.t)
    assert calls == []
