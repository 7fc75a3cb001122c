"""``report.md``: the head, the claims, the sections and the settings of every run."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from continuum_mhe.io.output_files import atomic_writer
from continuum_mhe.reproduce.bootstrap import BOOTSTRAP_RESAMPLES
from continuum_mhe.reproduce.report.beyond import beyond_section
from continuum_mhe.reproduce.report.claims import PAPER, _claims
from continuum_mhe.reproduce.report.format import (
    EQUIVALENCE,
    Results,
    _f,
    _rerun,
    _seed_range,
)
from continuum_mhe.reproduce.report.sections import _exp1, _exp2, _exp3, _exp4, _exp5, _exp6
from continuum_mhe.simulation.cosserat import default_data_path


def _settings(r: Results) -> list[str]:
    lines = [
        "## Settings of every run",
        "",
        "Each synthetic run is one `TrialSpec`; its exact dict is stored with its result in "
        "the experiment's JSON (`trials[*].spec`). One template per group, with its seeds:",
        "",
    ]
    for name in ("exp1_synthetic3d", "exp2_constraints"):
        if name in r:
            lines += [f"### {name}", "", *_rerun(r[name]["example"]["spec"])]
    for name in ("exp4_ekf_comparison", "exp5_horizon", "exp6_window"):
        if name not in r:
            continue
        d = r[name]
        lines += [f"### {name}", ""]
        if "example" in d:
            lines += ["example run:", "", *_rerun(d["example"]["spec"])]
        groups: dict[str, list[dict[str, Any]]] = {}
        for t in d["trials"]:
            groups.setdefault(t["spec"]["group"], []).append(t)
        for g, trs in groups.items():
            lines += [f"group `{g}`:", "", *_rerun(trs[0]["spec"], _seed_range(trs))]
    if "exp3_rod" in r:
        d = r["exp3_rod"]
        cfg = d["config"]
        shipped = d["source"] == default_data_path().name
        lines += [
            "### exp3_rod",
            "",
            f"`{d['source']}`{' from the package data' if shipped else ''}; MHE "
            f"({d['mhe_settings']}) and EKF on the `bend` formulation, R = "
            f"{math.degrees(d['assumed_std']):.1f} deg std, length {d['length']:g} m:",
            "",
            "```python",
            "from continuum_mhe.reproduce.experiments import ReproduceConfig, run_rod",
            "from continuum_mhe.simulation.cosserat import default_data_path"
            if shipped
            else "from pathlib import Path",
            f"cfg = ReproduceConfig(length={cfg['length']!r}, noise_deg={cfg['noise_deg']!r}, "
            f"horizon={cfg['horizon']!r})",
            "result = run_rod("
            + ("default_data_path()" if shipped else f"Path({d['source']!r})")
            + ", cfg)",
            "```",
            "",
        ]
    return lines


#: Fewer seeds than this in any group: the report opens by saying so.
FEW_SEEDS = 10


def _config(r: Results) -> dict[str, Any]:
    for key in r:
        if key != "manifest" and "config" in r[key]:
            return dict(r[key]["config"])
    return dict(r.get("manifest", {}).get("config", {}))


def _few_seeds_line(cfg: dict[str, Any], command: str) -> list[str]:
    """The warning of a run of few seeds per group, naming ``--quick`` where the run's
    ``command`` has it (else asking whether the seeds were set low by hand)."""
    keys = tuple(
        k
        for k in ("mc_seeds", "condition_seeds", "sweep_seeds", "window_seeds", "beyond_seeds")
        if k in cfg
    )
    if not cfg or min(int(cfg[k]) for k in keys) >= FEW_SEEDS:
        return []
    counts = ", ".join(f"{k.removesuffix('_seeds')} {cfg[k]}" for k in keys)
    quick = "--quick" in command.split()
    how = "`--quick`" if quick else "seeds set low"
    again = "without `--quick`" if quick else "with more seeds"
    return [
        f"**Few seeds ({counts} per group, {how}): the intervals below are rough and the "
        f"verdicts come from few seeds. Rerun {again} before citing them.**",
        "",
    ]


def _counts(man: dict[str, Any]) -> str:
    """What the run ran, from its manifest."""
    parts = []
    if man.get("n_trials", 1):
        parts.append(f"{man.get('n_trials', '?')} synthetic trials + 1 rod run")
    if man.get("n_beyond_trials"):
        parts.append(f"{man['n_beyond_trials']} runs beyond the paper")
    return " + ".join(parts)


def render_report(r: Results) -> str:
    """The report's Markdown text."""
    man = r.get("manifest", {})
    cfg = _config(r)
    head = [
        "# Reproduction of 'State Estimation of Continuum Robots: A Nonlinear Constrained "
        "Moving Horizon Approach' (Sec. 3)",
        "",
        *_few_seeds_line(cfg, str(man.get("command", ""))),
        f"Command: `{man.get('command', 'continuum-mhe reproduce')}`; " + _counts(man) + " run in "
        f"{_f(man.get('wall_s_trials'), 0)} s of wall time (the trials alone) "
        + (
            f"(Dask scheduler {man['scheduler']})."
            if man.get("scheduler")
            else f"(local processes: {man.get('jobs') or 'all CPUs'})."
        ),
        *(
            "Also in this folder, from an earlier run: "
            f"`{run.get('command') or 'continuum-mhe reproduce'}` "
            f"({', '.join(run.get('parts', []))})."
            for run in man.get("earlier_runs", [])
        ),
        f"Versions: {json.dumps(man.get('versions', {}))}; machine: {man.get('machine', '?')}.",
        f"MHE settings (defaults except N and paper_start): `{man.get('mhe_settings_default')}`;"
        f" noise settings (except measurement_std): `{man.get('noise_settings_default')}`.",
        "",
        "How to read: every estimator runs the default `bend` formulation (bend vector and "
        "its rate, constant-velocity model) with the same Q and R; the paper's "
        f"V = diag({PAPER['V_deg']:g}, {PAPER['V_deg']:g}) 'degrees' is read as a standard "
        f"deviation (R = V^2); this run uses {_f(cfg.get('noise_deg'), 1)} deg. SRMSE is the "
        "paper's sum of the five state RMSEs (m and rad mixed, so it is dominated by the "
        "angles; phi is ill-defined near straight). Tip errors are in mm on a "
        f"{_f(cfg.get('length'), 3)} m section. Intervals are 95 % percentile-bootstrap "
        f"intervals of the mean over seeds ({BOOTSTRAP_RESAMPLES} resamples, fixed seed): "
        "they stay within the range of the per-seed values, so errors and times never get "
        "a negative bound. Verdicts on the paired difference MHE - EKF "
        f"(same seeds): 'equivalent' if its whole interval lies within +-{EQUIVALENCE:.0%} of "
        "the EKF's mean, else 'MHE lower' / 'EKF lower' if the interval excludes 0, else 'no "
        "significant difference'. Each claim's verdict is computed from the saved numbers by "
        "the rule printed beside it.",
        "",
    ]
    body: list[str] = []
    for key, fn in (
        ("exp1_synthetic3d", _exp1),
        ("exp2_constraints", _exp2),
        ("exp3_rod", _exp3),
        ("exp4_ekf_comparison", _exp4),
        ("exp5_horizon", _exp5),
        ("exp6_window", _exp6),
    ):
        if key in r:
            body += fn(r[key])
    if "exp7_beyond" in r:
        body += beyond_section(r["exp7_beyond"])
    return "\n".join(head + _claims(r) + body + _settings(r)) + "\n"


def write_report(results: Results, folder: str | Path) -> Path:
    """Write ``report.md`` into ``folder`` and return its path."""
    p = Path(folder) / "report.md"
    with atomic_writer(p) as fh:
        fh.write(render_report(results))
    return p
