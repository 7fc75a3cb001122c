"""Optional parts of continuum-mhe and the one-line error when one is missing.

The core install (``pip install continuum-mhe``) runs the main path: simulate,
estimate, evaluate, demo, reproduce, benchmark against IPOPT and the EKFs. The extras:

========  ===========================================  =================================
extra     packages                                     for
========  ===========================================  =================================
robot     pyserial, rosbags, mcap                      ``live`` on a serial port, ROS bags
                                                       and MCAP in and out
peers     filterpy, do-mpc                             do-mpc in ``benchmark``; the peer
                                                       tests
dask      dask[distributed]                            ``reproduce --scheduler``
rod       pyelastica                                   the Cosserat-rod generators
view      rerun-sdk                                    ``view`` and ``live --view`` (3D)
test      all of the above, pytest, hypothesis,        the test suite
          ruff, mypy
========  ===========================================  =================================
"""

from __future__ import annotations

import importlib
import importlib.util
import warnings
from types import ModuleType

from continuum_mhe.errors import UserError

#: extra name -> what it holds (for messages and docs)
EXTRAS: dict[str, str] = {
    "robot": "pyserial, rosbags, mcap",
    "peers": "filterpy, do-mpc",
    "dask": "dask[distributed]",
    "rod": "pyelastica",
    "view": "rerun-sdk",
}


class MissingExtraError(UserError):
    """An optional dependency is not installed; the message names the ``pip install``.

    A :class:`~continuum_mhe.errors.UserError`: the command line shows it as one line
    and exits 2.
    """


def install_hint(extra: str) -> str:
    """``pip install 'continuum-mhe[EXTRA]'``."""
    return f"pip install 'continuum-mhe[{extra}]'"


def install_advice(extra: str, why: str) -> str:
    """The ``pip install`` that mends ``why`` (as :func:`import_problem` says it): the
    extra, with ``--upgrade`` where the package is installed but does not import."""
    return install_hint(extra) + (" --upgrade" if why.startswith(INSTALLED_BROKEN) else "")


def missing(
    package: str, extra: str, feature: str, why: str = "which is not installed"
) -> MissingExtraError:
    """The error for ``feature`` needing ``package`` from ``extra`` (``why``: as
    :func:`import_problem` says it)."""
    return MissingExtraError(f"{feature} needs {package}, {why}: {install_advice(extra, why)}")


def require(module: str, extra: str, feature: str, package: str | None = None) -> ModuleType:
    """Import ``module`` or raise :class:`MissingExtraError` naming the extra to install.

    Args:
        module: the module to import (``serial``, ``do_mpc``...).
        extra: the extra that provides it (a key of :data:`EXTRAS`).
        feature: what needs it, for the message (``live``, ``benchmark's do-mpc row``).
        package: the package's name on PyPI when it differs from ``module``.
    """
    why = import_problem(module)
    if why is not None:
        raise missing(package or module, extra, feature, why)
    return _quiet_import(module)


def require_together(needs: list[tuple[str, str, str]], feature: str) -> None:
    """One :class:`MissingExtraError` naming every package of ``needs`` (``(module,
    extra, package on PyPI)``) that does not import, and the one ``pip install`` of
    all their extras (``continuum-mhe[robot,view]``), so that a feature needing several
    extras is not refused once for each; nothing where each imports."""
    lacking = [(package, extra, why) for m, extra, package in needs if (why := import_problem(m))]
    if len(lacking) < 2:
        if lacking:
            package, extra, why = lacking[0]
            raise missing(package, extra, feature, why)
        return
    packages = " and ".join(p for p, _, _ in lacking)
    extras = ",".join(dict.fromkeys(e for _, e, _ in lacking))
    upgrade = any(why.startswith(INSTALLED_BROKEN) for _, _, why in lacking)
    raise MissingExtraError(
        f"{feature} needs {packages}, which do not import here: "
        f"pip install 'continuum-mhe[{extras}]'{' --upgrade' if upgrade else ''}"
    )


def available(module: str) -> bool:
    """True if ``module`` can be imported (the import is attempted)."""
    return import_problem(module) is None


#: How :func:`import_problem` begins where the package is there but its import fails.
INSTALLED_BROKEN = "which is installed but does not import here"


def import_problem(module: str) -> str | None:
    """None if ``module`` imports, else why not, as the end of a sentence on what needs
    it: ``"which is not installed"``, or, where its package is installed but its import
    fails (a version older than the extra asks for, or one that does not fit the other
    packages), ``"which is installed but does not import here (ImportError: ...)"``."""
    try:
        _quiet_import(module)
    except Exception as exc:  # an old package may fail otherwise (np.Inf: AttributeError)
        if importlib.util.find_spec(module.split(".")[0]) is None:
            return "which is not installed"
        text = " ".join(f"{type(exc).__name__}: {exc}".split())
        shown = text if len(text) <= 120 else text[:120] + "..."
        return f"{INSTALLED_BROKEN} ({shown}): a version too old?"
    return None


def _quiet_import(module: str) -> ModuleType:
    """Import ``module`` without the warnings some packages print on import (do-mpc
    announces each of its own optional features it lacks)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return importlib.import_module(module)
