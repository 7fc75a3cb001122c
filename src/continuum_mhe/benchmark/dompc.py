"""do-mpc's MHE as a peer of ``continuum-mhe benchmark``, given our window cost through
its own API: the tangent-plane tilt residual as its measurement (the window's
measurements enter as time-varying parameters, the measured value is 0, so its
measurement noise ``v`` is the residual),
the same ``Q^-1`` and ``R^-1``, the disk bound, and our arrival prior (the EKF's
filtered state and covariance of the sample before the window) as a parameter of its
arrival cost. The transition is linear, so its extra arrival node is exactly our prior
propagated one step. From sample ``N`` on it solves the same problem as our IPOPT
backend (agreement to the solvers' tolerance); before, do-mpc has no growing window and
pads the missing samples, so its first ``N`` estimates differ. Its bound covers its
nodes 0 to N-1 (do-mpc's rule): its extra arrival node and every node of our window but
the newest; the disk is not reached in this recording.
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.signals import between_samples
from continuum_mhe.simulation.scenarios import (
    Recording,
)


def _dompc_mhe(formulation: Formulation, horizon: int, dt: float) -> tuple[Any, Any, Any]:
    """do-mpc's MHE with our window cost (see the module docstring); returns the MHE
    and its time-varying-parameter and parameter templates, which the caller fills
    before each ``make_step``."""
    import casadi as ca

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import do_mpc

    f = formulation
    nx, nz = f.nx, f.nz
    model = do_mpc.model.Model("discrete", "SX")
    x = model.set_variable("_x", "x", shape=(nx, 1))
    z = model.set_variable("_tvp", "z", shape=(nz, 1))  # the stage's measurement
    m = model.set_variable("_tvp", "m", shape=(nz, 1))  # its sensor mask
    xbar = model.set_variable("_p", "xbar", shape=(nx, 1))  # arrival prior
    pinv = model.set_variable("_p", "pinv", shape=(nx * nx, 1))
    model.set_rhs("x", f.transition_sym(x, ca.SX(0, 1), dt), process_noise=True)
    # measured value 0, so v = -m * r(z, x): the stage cost v' R^-1 v is our residual term
    model.set_meas("r", m * f.measurement_residual_sym(z, x), meas_noise=True)
    model.setup()
    mhe = do_mpc.estimator.MHE(model, p_est_list=[])
    mhe.settings.n_horizon = horizon
    mhe.settings.t_step = dt
    mhe.settings.store_full_solution = False
    mhe.settings.meas_from_data = True
    mhe.settings.nlpsol_opts = {
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "print_time": False,
        "ipopt.tol": MHESettings().tol,
    }
    g, _, hi = f.constraint_sym(x)
    mhe.set_nl_cons("disk", g, ub=hi)
    Q = np.asarray(f.functions.predict(np.zeros(nx), np.zeros(f.nu), dt)[2], float)
    v, w = mhe._v.cat, mhe._w.cat
    stage = v.T @ np.linalg.inv(f.meas_cov()) @ v + w.T @ np.linalg.inv(Q.reshape(nx, nx)) @ w
    dx = mhe._x.cat - xbar
    mhe.set_objective(stage, dx.T @ ca.reshape(pinv, nx, nx) @ dx)
    tvp, par = mhe.get_tvp_template(), mhe.get_p_template()
    mhe.set_tvp_fun(lambda t: tvp)
    mhe.set_p_fun(lambda t: par)
    mhe.setup()
    return mhe, tvp, par


def run_dompc(
    formulation: Formulation, horizon: int, rec: Recording
) -> tuple[FloatArray, FloatArray]:
    """do-mpc's MHE over the recording: ``(output (n, ny), seconds per sample (n,))``.

    Before each ``make_step`` the window's measurements and masks go into the
    time-varying parameters and the arrival prior into the parameters: from sample
    ``N`` on, the EKF's filtered state and covariance at sample ``k - N`` (one EKF step
    per sample, timed with do-mpc's step, as our MHE's arrival update is); before,
    the first sample's prior (``Formulation.start_prior``). The time per sample is the
    EKF step and ``make_step``; copying the window's data and the prior into do-mpc's
    templates is not timed, as the peers' data are not
    (:func:`~continuum_mhe.benchmark.peers.run_peer`)."""
    from continuum_mhe.estimators import make_estimator

    f = formulation
    n, nz = len(rec.t), f.nz
    dt = float(rec.t[1] - rec.t[0])
    out = np.full((n, f.ny), np.nan)
    sec = np.empty(n)
    x0, P0 = f.start_prior(rec.z[0])
    x0, pinv0 = f.project(x0), np.linalg.inv(P0).ravel()
    ekf = make_estimator("ekf", f)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # do-mpc calls numpy functions on CasADi values
        mhe, tvp, par = _dompc_mhe(f, horizon, dt)
        mhe.x0 = x0
        mhe.set_initial_guess()
        zero = np.zeros((nz, 1))
        for j in between_samples(range(n)):  # (as the harness's timed runs)
            # the window's data are handed over before the clock starts, as the peers'
            # (CasADi's structure assignments cost tens of us a node)
            for k in range(horizon):
                s = j - horizon + 1 + k
                tvp["_tvp", k, "z"] = rec.z[max(s, 0)]
                tvp["_tvp", k, "m"] = f.measurement_mask(rec.z[s]) if s >= 0 else np.zeros(nz)
            t0 = time.perf_counter()
            if j >= horizon:
                prior = ekf.step(Measurement(float(rec.t[j - horizon]), rec.z[j - horizon]))
                if prior.state is None or prior.covariance is None:
                    raise RuntimeError(f"the EKF gave no arrival prior at sample {j - horizon}")
                xbar, pinv = prior.state, np.linalg.inv(prior.covariance).ravel()
            else:
                xbar, pinv = x0, pinv0
            arrival = time.perf_counter() - t0
            par["xbar"], par["pinv"] = xbar, pinv
            t0 = time.perf_counter()
            x = np.asarray(mhe.make_step(zero), float).ravel()
            sec[j] = arrival + time.perf_counter() - t0
            out[j] = f.output(x)
    return out, sec
