"""The compiled core of continuum-mhe: model evaluation from CasADi instruction lists,
the fast MHE's window solver, and the EKF and arrival-prior steps (C++ in ``csrc/``,
built by ``pip install``; docs/compiled-core.md). Its names come from the extension
module ``_ext``; ``_ext.pyi`` types them."""

from continuum_mhe._core._ext import *  # noqa: F403
