"""Reproduce the paper's experiments: ``continuum-mhe reproduce`` and ``plot``."""
