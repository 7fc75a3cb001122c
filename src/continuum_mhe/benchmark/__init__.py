"""Timing of the estimators beside their peers: the harness of ``continuum-mhe
benchmark`` (:mod:`.harness`), the peers on the same windows (:mod:`.peers`) and
do-mpc's MHE (:mod:`.dompc`), the bare compiled kernels (:mod:`.kernels`), the
measurement losses (:mod:`.losses`) and where the numbers come from
(:mod:`.environment`)."""
