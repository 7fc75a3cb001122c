"""``continuum-mhe plot``: the reproduction's figures, rendered again from its saved data."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def run(args: argparse.Namespace) -> int:
    from continuum_mhe.io.csv_files import new_files
    from continuum_mhe.reproduce.figures import render_all
    from continuum_mhe.reproduce.pipeline import load_results

    results = load_results(args.results)
    out = Path(args.out) if args.out else Path(args.results)
    with new_files(out) as files:  # Ctrl-C: none of the new figures, no new folder
        render_all(results, out, files)
    print(f"rendered {len(files)} figure files into {out}", file=sys.stderr)
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("results", help="folder written by 'continuum-mhe reproduce'")
    p.add_argument("--out", default=None, help="folder for the figures (default: RESULTS)")
