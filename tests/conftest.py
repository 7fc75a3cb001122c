"""Suite-wide settings.

The command line's first run (fast kernels not compiled yet) runs short recordings on
IPOPT while the kernels compile in the background (``estimators/fast/warmup.py``); the
suite makes every command compile in the foreground instead, so that the statuses and
timings of the CLI tests do not depend on which test ran first. ``test_first_run.py``
tests the background path itself.
"""

import os

os.environ.setdefault("CONTINUUM_MHE_FIRST_RUN", "foreground")
