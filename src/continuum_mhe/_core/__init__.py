"""The compiled core of continuum-mhe: model evaluation from CasADi instruction lists,
the fast MHE's window solver and per-sample step, the EKF and arrival-prior steps, the
estimators' sensor-health policy and consistency check, and the estimate files' writer
(C++ in ``csrc/``, built by ``pip install``; docs/compiled-core.md). Its names come
from the extension module ``_ext``; ``_ext.pyi`` types them."""

from continuum_mhe._core._ext import *  # noqa: F403
