"""``python -m continuum_mhe``: the ``continuum-mhe`` command."""

import sys

from continuum_mhe.cli.entry import main

sys.exit(main())
