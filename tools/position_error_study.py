"""What a position-side model-error term would do to the two-section rods' coverage
(docs/uncertainty.md, "Honest ``ok``: the four targets", (a)): a study by
post-processing, the estimators unchanged.

Each rod recording (``NAME_raw.csv``, ``NAME_tilt.csv`` beside ``NAME_truth.csv`` in
the ``--rods`` folders) is estimated once per method with the command line's defaults
(``continuum-mhe estimate REC --robot two-section --method METHOD``, as
``tools/honesty_study.py`` does), the estimates kept in ``--scratch`` (reused when
there). Then, for each term and scale, every ``ok`` row's ``std_x, std_y, std_z`` get
``sigma_pos^2`` added in variance, with ``sigma_pos = c * f(theta_1, theta_2)`` from
the row's own estimated bends (rad) and the sections' lengths ``L_k`` (m):

* ``sq-total``: ``f = (L_1 + L_2) * (theta_1^2 + theta_2^2)``;
* ``sq-sum``: ``f = L_1 theta_1^2 + L_2 theta_2^2``;
* ``lin-sum``: ``f = L_1 theta_1 + L_2 theta_2``;
* ``product``: ``f = (L_1 + L_2) theta_1 theta_2`` (large only where both bend).

The scale is given as ``s100``, the term's ``sigma_pos`` in mm where both sections
bend 100 degrees (``c = s100 / f(100 deg, 100 deg)``, printed too), so the forms
compare at one size. A row whose widened tip standard deviation
``sqrt(std_x^2 + std_y^2 + std_z^2)`` then exceeds ``--uncertain-fraction`` (0.1) of
the robot's length turns ``uncertain`` and leaves ``ok`` (only that row: the policy's
holding of the status for the next rows is not replayed). Printed per method and
setting: the recordings (of those in ``--choose-on`` folders, and of the others) whose
``ok`` rows cover the truth 0.85 to 0.99 on x, y and z, the pooled coverage and the
share of rows ``ok`` of each group, the rows turned ``uncertain``, and the recordings
that move into or out of the band against no term.

::

    python tools/position_error_study.py --rods src/continuum_mhe/data/rod2 DIR \\
        --choose-on rod2 --methods mhe ekf --scratch /tmp/pos_est
    # DIR: python tools/rod_variants.py -o DIR
"""

from __future__ import annotations

import argparse
import csv
import tempfile
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from honesty_study import Z95, estimate, truth_tip

from continuum_mhe.io.robot_file import read_robot

BAND = (0.85, 0.99)
THETA100 = np.deg2rad(100.0)


def _forms(lengths: Sequence[float]) -> dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]]:
    l1, l2 = lengths
    return {
        "sq-total": lambda t1, t2: (l1 + l2) * (t1**2 + t2**2),
        "sq-sum": lambda t1, t2: l1 * t1**2 + l2 * t2**2,
        "lin-sum": lambda t1, t2: l1 * np.abs(t1) + l2 * np.abs(t2),
        "product": lambda t1, t2: (l1 + l2) * np.abs(t1 * t2),
    }


@dataclass
class Recording:
    """One estimate of one recording: what the study needs of it."""

    name: str  # "FOLDER/NAME CASE"
    group: str  # "choose" or "check"
    err: np.ndarray  # (n, 3) tip error, m
    std: np.ndarray  # (n, 3) written tip std, m
    ok: np.ndarray  # (n,)
    theta: np.ndarray  # (n, 2) estimated bends, rad


def load(scratch: Path, rec: Path, truth: Path, method: str, group: str) -> Recording:
    """Estimate ``rec`` (once: the CSV is kept in ``scratch`` and reused) and read it."""
    out = scratch / f"{rec.parent.name}_{rec.stem}_{method}.csv"
    if not out.exists():
        estimate(scratch, rec, method, "--robot", "two-section")
    with out.open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))

    def column(name: str) -> np.ndarray:
        return np.array([float(r[name] or "nan") for r in rows])

    tip = np.column_stack([column(c) for c in "xyz"])
    std = np.column_stack([column(f"std_{c}") for c in "xyz"])
    theta = np.column_stack([column("theta_1"), column("theta_2")])
    ok = np.array([r["status"] == "ok" for r in rows])
    name = f"{rec.parent.name}/{rec.stem.rsplit('_', 1)[0]} {rec.stem.rsplit('_', 1)[1]}"
    return Recording(name, group, tip - truth_tip(truth), std, ok, theta)


def apply(
    r: Recording, f: Callable[[np.ndarray, np.ndarray], np.ndarray], c: float, limit: float
) -> tuple[np.ndarray, np.ndarray, int]:
    """The ``ok`` rows left (n,), each row's per-axis coverage (n, 3) with the term
    ``c * f`` added, and the count of ``ok`` rows it turns ``uncertain``."""
    sigma = c * f(r.theta[:, 0], r.theta[:, 1])
    std = np.sqrt(r.std**2 + sigma[:, None] ** 2)
    wide = np.linalg.norm(std, axis=1) > limit
    ok = r.ok & ~wide
    return ok, np.abs(r.err) <= Z95 * std, int(np.sum(r.ok & wide))


def in_band(c: np.ndarray) -> bool:
    return bool(np.all((c >= BAND[0]) & (c <= BAND[1])))


def study(
    recs: Sequence[Recording],
    forms: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]],
    s100s: Sequence[float],
    limit: float,
    method: str,
    verbose: bool,
) -> None:
    settings: list[tuple[str, float]] = [("none", 0.0)]
    settings += [(form, s) for form in forms for s in s100s if s > 0]
    base: dict[str, bool] = {}
    for form, s100 in settings:
        f = forms.get(form, forms["sq-total"])
        c = 0.0 if form == "none" else s100 * 1e-3 / float(f(THETA100, THETA100))
        cells: dict[str, bool] = {}
        said: dict[str, str] = {}
        line = [f"  {method} {form:8s} s100 {s100:4.1f} mm (c {c:.5f}):"]
        for group in ("choose", "check"):
            members = [r for r in recs if r.group == group]
            if not members:
                continue
            n_in, n_ok, n_rows, turned, cov = 0, 0, 0, 0, []
            for r in members:
                ok, hit, t = apply(r, f, c, limit)
                turned += t
                n_ok += int(ok.sum())
                n_rows += len(ok)
                cov.append(hit[ok])
                cr = hit[ok].mean(axis=0) if ok.any() else np.full(3, np.nan)
                cells[r.name] = in_band(cr)
                said[r.name] = f"{r.name} ({cr[0]:.3f} / {cr[1]:.3f} / {cr[2]:.3f})"
                n_in += cells[r.name]
                if verbose:
                    print(
                        f"    {r.name}: ok {ok.mean():.2f}, {cr[0]:.3f} / {cr[1]:.3f} / {cr[2]:.3f}"
                    )
            p = np.concatenate(cov).mean(axis=0)
            line.append(
                f"{group} {n_in}/{len(members)} in band, pooled {p[0]:.3f} / {p[1]:.3f} / "
                f"{p[2]:.3f}, ok {n_ok / n_rows:.3f} ({turned} turned uncertain);"
            )
        if form == "none":
            base = cells
        moved_in = [said[k] for k, v in cells.items() if v and not base[k]]
        moved_out = [said[k] for k, v in cells.items() if not v and base[k]]
        if moved_in:
            line.append(f"in: {', '.join(moved_in)};")
        if moved_out:
            line.append(f"out: {', '.join(moved_out)};")
        print(" ".join(line), flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rods", nargs="+", type=Path, required=True,
                   help="folders of two-section rod recordings")  # fmt: skip
    p.add_argument("--choose-on", nargs="+", default=["rod2"],
                   help="folder names whose recordings the scale is chosen on; the "
                   "others are the check")  # fmt: skip
    p.add_argument("--methods", nargs="+", default=["mhe"])
    p.add_argument("--cases", nargs="+", default=["raw", "tilt"])
    p.add_argument("--s100", nargs="+", type=float, default=[1, 2, 3, 4, 6, 8],
                   help="the term's size in mm where both sections bend 100 degrees")  # fmt: skip
    p.add_argument("--uncertain-fraction", type=float, default=0.1)
    p.add_argument("--scratch", type=Path, help="folder for the estimates (kept, reused)")
    p.add_argument("--verbose", action="store_true", help="each recording's cell too")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    robot = read_robot("two-section")
    lengths = [s.length for s in robot.sections]
    limit = args.uncertain_fraction * sum(lengths)
    forms = _forms(lengths)
    with tempfile.TemporaryDirectory() as name:
        scratch = args.scratch or Path(name)
        scratch.mkdir(parents=True, exist_ok=True)
        for method in args.methods:
            recs = []
            for folder in args.rods:
                group = "choose" if folder.name in args.choose_on else "check"
                for truth in sorted(folder.glob("*_truth.csv")):
                    stem = truth.name[: -len("_truth.csv")]
                    for case in args.cases:
                        rec = folder / f"{stem}_{case}.csv"
                        if rec.exists():
                            recs.append(load(scratch, rec, truth, method, group))
            study(recs, forms, args.s100, limit, method, args.verbose)


if __name__ == "__main__":
    main()
