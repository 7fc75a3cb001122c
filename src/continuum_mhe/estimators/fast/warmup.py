"""The first run: compiling the fast backend's numba kernels, in the background.

numba compiles the fast MHE's and the compiled EKF's kernels on their first call and
caches them on disk; on 2 cores that takes one to two minutes (108 s measured on the
development machine in session 27, `python -m continuum_mhe.estimators` with an empty
cache), once per install. A command that
finds them not yet compiled can

* compile them now, in this process (``"foreground"``, the library's way: it says
  ``compiling ... (first run only)`` once and then waits), or
* start a background process that compiles them and run this command on the paths that
  need no compiling: IPOPT for the MHE (the same window problem; rows flagged
  ``fallback-ipopt``) and the CasADi EKF (the same equations) (``"background"``, the
  command line's way for short recordings). The next run finds the kernels compiled.

"Compiled" is a marker file written after every kernel was compiled by
:func:`warm_up`. Its name carries a key of the kernels' source, numba's and Python's
versions and the package's place; it lies in numba's cache folder, so a changed kernel,
a new numba or a removed cache compiles again; writing it removes this install's
markers of other sources, so going back to one (a checkout, a downgrade) compiles again
too (:func:`write_marker`). ``CONTINUUM_MHE_FIRST_RUN=foreground``
makes the command line wait too.

The process compiling (in the background or the foreground) holds a pid file beside the
marker. A foreground compile that finds another process compiling waits for it (said
once) instead of compiling beside it and flushing the cache it writes; if that process
ends without the marker, the foreground compiles after all.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from continuum_mhe.numba_cache import writable

if TYPE_CHECKING:
    from continuum_mhe.estimators.base import FloatArray
    from continuum_mhe.model.formulations import Formulation

FirstRun = Literal["foreground", "background"]

_FAST = Path(__file__).resolve().parent
#: the modules with numba kernels, callees before their callers
_KERNEL_MODULES = (
    "continuum_mhe.estimators.loss",
    *(f"continuum_mhe.estimators.fast.{m}"
      for m in ("ccall", "memory", "linalg", "qp", "outputs", "arrival", "sqp", "covariance",
                "step")),
)  # fmt: skip


def _source(module: str) -> Path:
    return Path(__file__).resolve().parents[2].joinpath(*module.split(".")[1:]).with_suffix(".py")


_announced: set[str] = set()
#: the background compile this process started (its pid stays alive as a zombie until
#: reaped, so this process asks the Popen whether it ended)
_child: subprocess.Popen[bytes] | None = None
#: seconds between checks while waiting for another process's compile
_POLL_S = 0.5
#: the longest wait for another process's compile (a recycled pid is not a compile)
_WAIT_LIMIT_S = 900.0


class CompileNotice(UserWarning):
    """The fast backend is compiling its kernels (first run only), or another path runs
    while it does; one line under the command line, said once per process."""


def kernels_key() -> str:
    """A key of everything that decides whether numba's cached kernels can be used."""
    h = hashlib.sha256()
    for name in _KERNEL_MODULES:
        h.update(_source(name).read_bytes())
    try:
        h.update(metadata.version("numba").encode())
    except metadata.PackageNotFoundError:  # pragma: no cover - numba is a dependency
        pass
    h.update(sys.version.encode())
    h.update(str(_FAST).encode())
    return h.hexdigest()[:20]


def _numba_cache_folder() -> Path:
    """Where numba caches these kernels: ``$NUMBA_CACHE_DIR``, else the package's
    ``__pycache__`` when writable, else the user's numba cache (as numba does, and as
    :mod:`continuum_mhe.numba_cache` arranges)."""
    own = os.environ.get("NUMBA_CACHE_DIR")
    if own:
        return Path(own)
    source = _FAST / "__pycache__"
    if writable(source):
        return source
    home = os.environ.get("HOME") or "/nonexistent"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path(home) / ".cache") / "numba"


def marker_path() -> Path:
    """The file whose existence says that the kernels are compiled and cached (beside
    numba's cache, so that removing that cache removes the marker too)."""
    return _numba_cache_folder() / f"continuum-mhe-kernels-{kernels_key()}.ready"


def pid_path() -> Path:
    """The background compiler's pid file (removed when it ends)."""
    return marker_path().with_suffix(".pid")


def log_path() -> Path:
    """The background compiler's error output (kept where it failed: removed by a
    compile that succeeds)."""
    return marker_path().with_suffix(".log")


def _last_failure() -> str | None:
    """The last line of a background compile's error output, where one failed (its log
    is not empty, no compile is running and the kernels are not compiled); else None."""
    if kernels_ready() or _running(pid_path()):
        return None
    try:
        lines = [ln.strip() for ln in log_path().read_text(errors="replace").splitlines()]
    except OSError:
        return None
    lines = [ln for ln in lines if ln]
    return lines[-1] if lines else None


def kernels_ready() -> bool:
    """True when :func:`warm_up` has compiled and cached every kernel of this install."""
    return marker_path().is_file()


def first_run_mode(default: FirstRun) -> FirstRun:
    """``$CONTINUUM_MHE_FIRST_RUN`` (``foreground`` or ``background``), else ``default``;
    another value is said once (a :class:`CompileNotice`) and ``default`` used."""
    mode = os.environ.get("CONTINUUM_MHE_FIRST_RUN", "")
    if mode in ("foreground", "background"):
        return mode  # type: ignore[return-value]
    if mode:
        say_once(
            f"CONTINUUM_MHE_FIRST_RUN={mode!r} is neither 'foreground' nor 'background': "
            "ignored"
        )
    return default


def say_once(
    message: str, category: type[Warning] = CompileNotice, stacklevel: int = 3
) -> None:
    """Warn ``message`` as a ``category`` (default :class:`CompileNotice`; one line under
    the command line), once per process."""
    if message not in _announced:
        _announced.add(message)
        warnings.warn(message, category, stacklevel=stacklevel)


def flush_kernel_caches() -> None:
    """Empty numba's cache index of every kernel of this package, and compile again any
    kernel already loaded in this process (callees first).

    numba checks a cached kernel only against its own source file, so a kernel whose
    callee in another file changed (an edited checkout, an upgrade that keeps a file's
    time stamp) would load stale machine code. :func:`kernels_key` hashes every kernel
    module, so a new key means: forget them all."""
    import importlib

    from numba.core.dispatcher import Dispatcher

    for name in _KERNEL_MODULES:  # in dependency order: callees first
        module = importlib.import_module(name)
        for obj in vars(module).values():
            if isinstance(obj, Dispatcher) and obj.__module__ == module.__name__:
                try:
                    obj._cache.flush()  # type: ignore[attr-defined]
                except OSError:  # an unwritable cache: numba then compiles in memory
                    pass
                if obj.overloads:
                    obj.recompile()


#: How to compile one estimator's kernels: a function of a formulation of the 0.2 m
#: robot, the sample times (s) of a short ``paper3d`` recording, its measurements and the
#: same with a spike on the last sample (rejected by a robust loss), that runs the
#: estimator on them. Registered by the estimator's own module (:func:`register_recipe`),
#: so that this module, below the estimators, imports none of them.
Recipe = Callable[["Formulation", "FloatArray", "FloatArray", "FloatArray"], None]
_RECIPES: dict[str, Recipe] = {}
#: the recipes :func:`warm_up` needs: every estimator with kernels
RECIPE_NAMES = ("mhe", "ekf")


def register_recipe(name: str, recipe: Recipe) -> None:
    """Register how to compile the kernels of the estimator ``name`` (one of
    :data:`RECIPE_NAMES`; its module does this on import)."""
    _RECIPES[name] = recipe


def warm_up() -> None:
    """Compile every kernel (by running each estimator's :data:`Recipe` on a short
    recording: the fast MHE with the quadratic and a robust loss, the default settings
    too, whose C model of the 0.2 m robot is then cached, and the compiled EKF), then
    write the marker. The cached kernels of an earlier source are flushed first
    (:func:`flush_kernel_caches`)."""
    import numpy as np

    missing = [name for name in RECIPE_NAMES if name not in _RECIPES]
    if missing:  # a caller that imported this module alone: continuum_mhe.estimators registers them
        raise RuntimeError(
            f"no kernel recipe registered for {', '.join(missing)}: import "
            "continuum_mhe.estimators before compiling"
        )
    flush_kernel_caches()

    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import Robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot.single(0.2)
    rec = simulate_robot("paper3d", robot, duration=0.5, dt=0.05, noise_deg=2.0, seed=0)
    f = make_formulation("bend", robot)
    z = np.asarray(rec.z)
    spiked = z.copy()
    spiked[-1] += 0.8  # rejected by a robust loss: its second start and two-call step

    # what is silenced here (a compile, a VM fallback) is still said, once, later
    announced = set(_announced)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # said, where it matters, by the estimators
        for name in RECIPE_NAMES:
            _RECIPES[name](f, rec.t, z, spiked)
    _announced.clear()
    _announced.update(announced)
    write_marker()


def write_marker() -> None:
    """Write this source's marker (its second line: the package's place), and remove the
    markers of this install's other sources (and those without a place): numba's cache
    now holds this source's kernels, so a marker of an earlier source, found again after
    going back to it (a checkout, a downgrade), would load callers compiled against
    this source's callees without a flush (numba checks a kernel only against its own
    file). Markers of other installs sharing the cache folder are kept."""
    path = marker_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    place = str(_FAST)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(f"compiled\n{place}\n")
    os.replace(tmp, path)
    for other in path.parent.glob("continuum-mhe-kernels-*.ready"):
        if other != path and _marker_place(other) in (place, None):
            other.unlink(missing_ok=True)


def _marker_place(marker: Path) -> str | None:
    """The package place a marker was written for (None: not recorded, or unreadable)."""
    try:
        lines = marker.read_text(errors="replace").splitlines()
    except OSError:
        return None
    return lines[1] if len(lines) > 1 and lines[1] else None


def ensure_compiled() -> None:
    """Compile the kernels now if they are not cached, saying so once (library use); if
    another process is compiling them, wait for it instead."""
    pid_file = pid_path()
    for _ in range(2):  # a compile that starts between the wait and the claim: wait again
        if kernels_ready() or _wait_for_other_compile():
            return
        if _claim(pid_file):  # a background compile started from now on waits for this one
            break
    say_once("compiling the fast solver's kernels (first run only; 1 to 2 minutes on 2 cores)")
    try:
        warm_up()
    finally:
        _release(pid_file)


def _wait_for_other_compile() -> bool:
    """Wait while another process compiles the kernels; True if they are compiled now."""
    pid_file = pid_path()
    if not _running(pid_file):
        return False
    say_once("waiting for the background compile of the fast solver's kernels (first run only)")
    give_up = time.monotonic() + _WAIT_LIMIT_S
    while _running(pid_file) and not kernels_ready() and time.monotonic() < give_up:
        time.sleep(_POLL_S)
    return kernels_ready()


def _running(pid_file: Path) -> bool:
    """True if the process named in ``pid_file`` is alive."""
    try:
        pid = int(pid_file.read_text().strip())
    except (OSError, ValueError):
        return False
    if _child is not None and _child.pid == pid:
        return _child.poll() is None
    try:
        os.kill(pid, 0)
    except OSError:
        return False
    return True


def _claim(pid_file: Path) -> bool:
    """Create ``pid_file`` holding this process's pid, atomically, unless a live process
    holds it (False); a stale one is replaced. True too when it cannot be written (a
    read-only cache folder: nothing to coordinate with)."""
    for _ in range(2):
        try:
            pid_file.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(pid_file, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            if _running(pid_file):
                return False
            try:  # stale: its process ended without removing it
                pid_file.unlink()
            except OSError:
                pass
            continue
        except OSError:
            return True
        with os.fdopen(fd, "w") as fh:
            fh.write(f"{os.getpid()}\n")
        return True
    return False


def _release(pid_file: Path) -> None:
    """Remove ``pid_file`` if it names this process."""
    try:
        if pid_file.read_text().strip() == str(os.getpid()):
            pid_file.unlink()
    except OSError:
        pass


def start_background_warmup() -> bool:
    """Start :func:`warm_up` in a detached process unless one is running already;
    returns True if one is running now."""
    global _child
    pid_file = pid_path()
    if not _claim(pid_file):  # held by a live compile, here or in the foreground
        return True
    try:
        with open(log_path(), "wb") as log:  # the child's traceback, if it fails
            proc = subprocess.Popen(  # noqa: S603 - our own module, same interpreter
                [sys.executable, "-m", "continuum_mhe.estimators"],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=log,
                start_new_session=True,  # survives this command and its Ctrl-C
            )
        pid_file.write_text(f"{proc.pid}\n")  # the claim passes to the child
        _child = proc
    except OSError:
        _release(pid_file)
        return False
    return True


def defer_compiling(what: str) -> str:
    """Start the background compile and say once what this run does meanwhile; returns
    the note (for the estimator's ``backend_note``)."""
    failed = _last_failure()
    if failed is not None:  # said before this run tries again, with where to read why
        say_once(f"the last background compile of the kernels failed ({failed}); see {log_path()}")
    started = start_background_warmup()
    where = "in the background" if started else "on the next run"
    note = (
        f"the fast solver's kernels are not compiled yet: compiling them {where} "
        f"(first run only); this run uses {what}"
    )
    say_once(note)
    return note


def main() -> int:
    """The background compile's process (``python -m continuum_mhe.estimators``, which
    registers the recipes first): :func:`warm_up`, then release the pid file."""
    try:
        warm_up()
    finally:
        _release(pid_path())
    try:  # compiled: no failure to report
        log_path().unlink()
    except OSError:
        pass
    return 0
