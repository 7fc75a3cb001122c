"""Analyses of a robot description (observability)."""
