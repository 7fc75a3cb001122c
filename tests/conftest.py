"""Fixtures shared by several test modules, and the session's bytecode: where it is
kept, and how the pytest-xdist workers share its making."""

from __future__ import annotations

import contextlib
import gc
import importlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

# Bytecode where PYTHONDONTWRITEBYTECODE is set: each interpreter the tests start (every
# command-line run, and each pytest-xdist worker) would compile the package's modules
# anew. Instead the session's interpreters share a
# bytecode folder of the session's own (PYTHONPYCACHEPREFIX), removed when the session
# ends; nothing is written beside the sources either way. Set by the first process only
# (the xdist controller, before it starts its workers), which the workers inherit.
_PYC_ENV = "CONTINUUM_MHE_TEST_PYCACHE"


def _link_installed_bytecode(folder: str) -> None:
    """Hard-link the bytecode that the standard library and the installed packages
    carry (each ``__pycache__`` folder's, which pip and Python's installer compiled)
    into ``folder`` where an interpreter with that prefix looks for it: otherwise each
    worker compiles every module it imports anew, numpy, SciPy and Matplotlib included
    (most of a worker's start). Python checks each file against its source as it would
    beside it (a stale one is compiled and replaced, the link alone). A file system
    that takes no hard link leaves the folder empty."""
    import sysconfig
    from importlib.util import cache_from_source

    paths = sysconfig.get_paths()
    tag = f".{sys.implementation.cache_tag}.pyc"
    skip = {"site-packages", "test"}  # the base interpreter's own packages, its test suite
    prefix, sys.pycache_prefix = sys.pycache_prefix, folder  # where cache_from_source looks
    try:
        for base in [paths["stdlib"], *sorted({paths["purelib"], paths["platlib"]})]:
            for root, dirs, files in os.walk(base):
                if root == base == paths["stdlib"]:
                    dirs[:] = [d for d in dirs if d not in skip]
                if os.path.basename(root) != "__pycache__":
                    continue
                made = False
                for name in files:
                    if not name.endswith(tag):
                        continue
                    source = os.path.join(os.path.dirname(root), name[: -len(tag)] + ".py")
                    into = cache_from_source(source)
                    if not made:
                        os.makedirs(os.path.dirname(into), exist_ok=True)
                        made = True
                    with contextlib.suppress(FileExistsError):  # a folder walked twice
                        os.link(os.path.join(root, name), into)
    except OSError:  # no hard links here (another file system): those left are compiled
        pass
    finally:
        sys.pycache_prefix = prefix


if os.environ.get("PYTHONDONTWRITEBYTECODE") and _PYC_ENV not in os.environ:
    _pycache = tempfile.mkdtemp(prefix="continuum-mhe-tests-pyc-")
    _link_installed_bytecode(_pycache)
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


def pytest_collection(session: pytest.Session) -> None:
    """In pytest-xdist worker ``i`` of ``n``, import this folder's test files that the
    session collects before it collects them, starting ``i / n`` of the way through
    them: each worker collects every file, and pytest rewrites each file's asserts
    (most of the collection's time) for the first worker to import it and keeps the
    result where the others find it (the session's bytecode folder, or beside the
    sources), so the workers share that work instead of each doing all of it. The
    collection then finds each file imported, as it would have imported it."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    options = session.config.option
    if not worker.startswith("gw") or count < 2 or options.importmode != "prepend":
        return
    here = Path(__file__).parent
    files: set[Path] = set()
    for arg in session.config.args:
        path = Path(session.config.invocation_params.dir, arg.split("::")[0]).resolve()
        if path == here:
            files.update(here.glob("test_*.py"))
        elif path.parent == here and path.name.startswith("test_") and path.suffix == ".py":
            files.add(path)
    ordered = sorted(files)
    start = len(ordered) * (int(worker[2:]) % count) // count
    for path in ordered[start:] + ordered[:start]:
        try:  # by its name alone, as pytest's default import mode imports a test file
            importlib.import_module(path.stem)
        except Exception:  # noqa: BLE001 - the collection says what is wrong with it
            sys.modules.pop(path.stem, None)


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
