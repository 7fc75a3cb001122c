"""The process noise Q(dt) and its inverse in compiled code (csrc/process_noise.hpp)
against CasADi's covariance and LAPACK's inverse, and the estimators' runs taking it
without a call into Python per time step."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import continuum_mhe._core as _core
import continuum_mhe.estimators.process_noise as process_noise_module
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.process_noise import (
    ProcessNoiseCache,
    compiled_process_noise,
    process_noise,
)
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.formulations import MIN_NOISE_STEP_S
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.tape import tape_function
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate

STEPS_S = (1e-9, 0.5 * MIN_NOISE_STEP_S, 0.001, 0.0199, 0.05, 1.0, 40.0)


def formulations() -> list[object]:
    """One section (tilt, the paper's), two sections raw with gyro biases, a tendon robot
    (tilt, raw)."""
    return [
        make_formulation("bend"),
        make_formulation("paper"),
        make_formulation("direct", read_robot("two-section")),
        make_formulation("tendon", read_robot("tendon-two-section")),
        make_formulation("tendon", read_robot("tendon-two-section"), imu_model="direct"),
    ]


@pytest.mark.parametrize("f", formulations(), ids=lambda f: f"{f.name}-{f.nx}")
def test_the_compiled_process_noise_is_casadis_covariance_and_its_inverse(f: object) -> None:
    compiled = compiled_process_noise(f)  # type: ignore[arg-type]
    for dt in STEPS_S:
        Q, Qinv = process_noise(f, dt)  # type: ignore[arg-type]
        Qc, Qinv_c = compiled(dt)
        assert np.array_equal(Qc, Q), dt  # the same instructions
        assert np.abs(Qinv_c - Qinv).max() <= 1e-12 * np.abs(Qinv).max(), dt


def test_held_states_have_zero_rows_and_columns_and_the_whole_covariances_inverse() -> None:
    f = make_formulation("tendon", read_robot("tendon-two-section"))
    held = tuple(f.load_states)
    Q, Qinv = process_noise(f, 0.02)
    Qc, Qinv_c = compiled_process_noise(f, held)(0.02)
    Qp, Qinv_p = ProcessNoiseCache(f, held=held)(0.02)  # the steps in Python take
    assert np.array_equal(Qp, Qc) and np.allclose(Qinv_p, Qinv_c, rtol=1e-12, atol=0)
    free = np.setdiff1d(np.arange(f.nx), held)
    assert not Qc[held, :].any() and not Qc[:, held].any()
    assert not Qinv_c[held, :].any() and not Qinv_c[:, held].any()
    assert np.array_equal(Qc[np.ix_(free, free)], Q[np.ix_(free, free)])
    assert np.allclose(Qinv_c[np.ix_(free, free)], Qinv[np.ix_(free, free)], rtol=1e-12, atol=0)


def test_a_covariance_that_is_not_positive_definite_is_the_fallbacks() -> None:
    dt = ca.SX.sym("dt")
    singular = tape_function(ca.Function("q", [dt], [ca.diag(ca.vertcat(dt, 0.0))]))
    answer = (np.eye(2), 2 * np.eye(2))
    calls: list[float] = []

    def fallback(step: float) -> tuple[np.ndarray, np.ndarray]:
        calls.append(step)
        return answer

    noise = _core.ProcessNoise(singular, 2, [], fallback)
    Q, Qinv = noise(0.5)
    assert calls == [0.5] and noise.python_calls == 1
    assert np.array_equal(Q, answer[0]) and np.array_equal(Qinv, answer[1])
    positive = tape_function(ca.Function("q", [dt], [ca.diag(ca.vertcat(dt, 2 * dt))]))
    Q, Qinv = _core.ProcessNoise(positive, 2, [], fallback)(0.5)
    assert calls == [0.5]  # not called again
    assert np.allclose(Qinv, np.diag([2.0, 1.0]))
    two = tape_function(ca.Function("q", [ca.SX.sym("dt", 2)], [ca.SX.eye(2)]))
    with pytest.raises(ValueError, match="one input, dt"):  # it would read past dt
        _core.ProcessNoise(two, 2, [], fallback)


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_a_run_over_jittered_times_computes_the_process_noise_in_compiled_code(
    method: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # every step of a real logger's times differs a little, so that a per-step cache
    # misses at every sample: the core computes Q(dt) itself, never through Python
    rec = simulate("paper3d", duration=4, seed=0)
    t = rec.t + np.random.default_rng(0).uniform(-2e-4, 2e-4, len(rec.t))
    est = make_estimator(method, make_formulation("bend"), MHESettings(horizon=10))
    calls: list[float] = []
    reference = process_noise

    def counted(f: object, dt: float) -> tuple[np.ndarray, np.ndarray]:
        calls.append(dt)
        return reference(f, dt)  # type: ignore[arg-type]

    monkeypatch.setattr(process_noise_module, "process_noise", counted)
    series = est.run(t, rec.z)
    assert len(series.t) == len(t) and np.sum(series.status == "ok") > len(t) // 2
    assert calls == []  # no fallback
    inference = est.inference
    steps = getattr(inference, "_q", None) or inference._process_weight  # type: ignore[attr-defined]
    for compiled in (est.process_noise, steps.compiled):  # not called from Python either
        assert compiled.python_calls == 0
