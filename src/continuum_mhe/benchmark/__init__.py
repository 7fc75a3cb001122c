"""Timing of the estimators beside their peers: the harness of ``continuum-mhe
benchmark`` (:mod:`.harness`), the bare compiled kernels (:mod:`.kernels`) and the
measurement losses (:mod:`.losses`)."""
