"""``python -m continuum_mhe.estimators``: compile the fast kernels (the background
compile of the first run; :mod:`continuum_mhe.estimators.fast.warmup`). Importing
this package registers every estimator's kernel recipe first."""

import sys

import continuum_mhe.estimators  # noqa: F401 - registers the kernel recipes
from continuum_mhe.estimators.fast.warmup import main

sys.exit(main())
