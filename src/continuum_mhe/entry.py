"""The entry point under its former name, for a ``continuum-mhe`` script written by an
install that predates :mod:`continuum_mhe.cli.entry` (``pip install`` again writes the
new one, and this module can then go)."""

from continuum_mhe.cli.entry import main

__all__ = ["main"]
