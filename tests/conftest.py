"""Fixtures shared by several test modules, and the order in which the test files run."""

from __future__ import annotations

import gc
import os
import shutil
import sys
import tempfile

# Bytecode where PYTHONDONTWRITEBYTECODE is set: each interpreter the tests start (every
# command-line run, and each pytest-xdist worker) would compile the package's modules
# anew. Instead the session's interpreters share a
# bytecode folder of the session's own (PYTHONPYCACHEPREFIX), removed when the session
# ends; nothing is written beside the sources either way. Set by the first process only
# (the xdist controller, before it starts its workers), which the workers inherit.
_PYC_ENV = "CONTINUUM_MHE_TEST_PYCACHE"
if os.environ.get("PYTHONDONTWRITEBYTECODE") and _PYC_ENV not in os.environ:
    _pycache = tempfile.mkdtemp(prefix="continuum-mhe-tests-pyc-")
    os.environ[_PYC_ENV] = os.environ["PYTHONPYCACHEPREFIX"] = _pycache
    del os.environ["PYTHONDONTWRITEBYTECODE"]
    sys.pycache_prefix, sys.dont_write_bytecode = _pycache, False
else:
    _pycache = None


def pytest_unconfigure() -> None:
    """Remove the session's bytecode folder (the process that made it)."""
    if _pycache is not None:
        shutil.rmtree(_pycache, ignore_errors=True)


# One BLAS thread per test process (before numpy loads its BLAS): the estimators'
# matrices are small, and with a worker per core an idle BLAS thread's spinning takes
# the other worker's core.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

# PyElastica's numba kernels (the rod generators' tests) compiled at LLVM's level 1, not
# 3: in a fresh environment, whose numba cache is empty, the compile is most of those
# tests' time and level 1 takes about two thirds of it; the simulations run as fast,
# and the shipped rod recording is still regenerated to its CSV's digits
# (test_rod_generators.py). Set before numba is imported; an explicit setting is kept.
# PyElastica caches its kernels in its own folder, keyed without the level, so later
# runs in the same environment may load these: the same results, at about the speed.
os.environ.setdefault("NUMBA_OPT", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from estimator_helpers import (  # noqa: E402
    LIN_DT,
    LIN_H,
    LIN_N,
    LinearBend,
    bend_process_cov,
    lin_transition,
)


@pytest.fixture(scope="module")
def linear_recording() -> tuple[LinearBend, np.ndarray, np.ndarray]:
    f = LinearBend()
    rng = np.random.default_rng(7)
    F, Q, R = lin_transition(LIN_DT), bend_process_cov(f.noise.bend_accel_psd, LIN_DT), f.meas_cov()
    x = np.array([0.3, -0.2, 0.5, 0.4])
    z = []
    for _ in range(LIN_N):
        z.append(LIN_H @ x + rng.multivariate_normal(np.zeros(2), R))
        x = F @ x + rng.multivariate_normal(np.zeros(4), Q)
    return f, np.arange(LIN_N) * LIN_DT, np.array(z)


#: the test file whose first test froze the collector's objects (pytest_runtest_setup)
_frozen_for: list[object] = [None]


def pytest_runtest_setup(item: pytest.Item) -> None:
    """At each test file's first test, collect the cyclic garbage and move every object
    left (the compiled models and CasADi functions that earlier files cached) out of
    the garbage collector's passes (``gc.freeze``): otherwise each pass walks them
    again, and the estimators' per-sample loops in every later file pay for it."""
    module = getattr(item, "module", None)
    if module is not _frozen_for[0]:
        _frozen_for[0] = module
        gc.collect()
        gc.freeze()
