"""The ``continuum-mhe`` command line; no library module imports it.

:mod:`.program` holds the table of commands (each command's name and one-line help,
written once) and :mod:`.entry` the light entry point that answers ``--help`` and
``--version`` from it; :mod:`.app` builds the full parser from the same table and runs a
command (one line and exit status 2 for a user's mistake, 70 for a bug); each command
lives in its own module (:mod:`.estimate`, :mod:`.live`, ...) with ``add_arguments`` and
``run``; the options several commands share are in :mod:`.options`,
:mod:`.model_options`, :mod:`.method_options`, :mod:`.recovery_options` and
:mod:`.input_options`.

``main`` and ``build_parser`` are imported from :mod:`.app` on first use, so that
importing the entry point stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__all__ = ["build_parser", "main"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        return getattr(importlib.import_module("continuum_mhe.cli.app"), name)
    raise AttributeError(f"module 'continuum_mhe.cli' has no attribute {name!r}")


if TYPE_CHECKING:
    from continuum_mhe.cli.app import build_parser, main
