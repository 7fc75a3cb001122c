"""``python -m continuum_mhe.cli``: the full command line (without the light entry point)."""

import sys

from continuum_mhe.cli.app import main

sys.exit(main())
