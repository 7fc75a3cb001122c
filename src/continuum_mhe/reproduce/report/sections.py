"""The per-experiment sections of ``report.md`` (tables made from saved numbers)."""

from __future__ import annotations

import math
from typing import Any

from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.reproduce.report.format import (
    _METRIC_HEADER,
    _ci,
    _f,
    _g,
    _median_total_ms,
    _metric_row,
    _noise_deg,
    _table,
    _total_time_peak,
    verdict,
)
from continuum_mhe.simulation.cosserat import GENERATOR


def _range_deg(example: dict[str, Any], column: int) -> str:
    """``lo..hi`` of a truth column of an example run, in degrees."""
    v = [math.degrees(row[column]) for row in example["series"]["truth"]]
    return f"{min(v):.0f}..{max(v):.0f}"


def _exp1(d: dict[str, Any]) -> list[str]:
    ex = d["example"]
    sp = ex["spec"]
    lines = [
        "## 1. Synthetic 3D data (paper Sec. 3.1, Fig. 4)",
        "",
        f"Scenario `{sp['scenario']}` (true theta {_range_deg(ex, 3)} deg, phi "
        f"{_range_deg(ex, 4)} deg), {sp['duration']} s at "
        f"T = {sp['dt']} s, noise {math.degrees(sp['noise_std'][0]):.1f} deg std, "
        f"N = {sp['horizon']}, seed {sp['seed']}. "
        "Figures: `exp1_synthetic3d_trajectory`, `exp1_synthetic3d_states`.",
        "",
    ]
    rows = [
        _metric_row(m.upper(), r["all"], r["solve_ms_median"]) for m, r in ex["methods"].items()
    ]
    status = ", ".join(f"{k}: {v}" for k, v in ex["methods"]["mhe"]["status"].items())
    lines += _table(_METRIC_HEADER, rows) + [f"MHE solver status counts: {status}.", ""]
    pf = d.get("paper_formulation")
    if pf:
        r = pf["methods"]
        w = pf["noise_settings"]["paper_process_weight"]
        lines += [
            f"The paper's own 5-state formulation (`paper`: state [x, y, z, theta, phi], "
            f"u from consecutive readings, W = {w:g} I), same scenario and seed, "
            f"{pf['spec']['duration']} s:",
            "",
            *_table(
                (*_METRIC_HEADER, "RMSE x, y, z (mm)"),
                [
                    [
                        *_metric_row(m.upper(), r[m]["all"], r[m]["solve_ms_median"]),
                        ", ".join(_f(r[m]["all"]["rmse"][k] * 1e3, 1) for k in ("x", "y", "z")),
                    ]
                    for m in r
                ],
            ),
        ]
    return lines


def _exp2(d: dict[str, Any]) -> list[str]:
    ex = d["example"]
    c = ex["constraints"]
    any_c = next(iter(c.values()))
    bound = f"theta_max = {math.degrees(ex['theta_max']):.1f} deg"
    lines = [
        "## 2. Constraint handling (paper Sec. 3.2, Fig. 5)",
        "",
        f"Scenario `{ex['spec']['scenario']}`: the true theta passes {bound} at sample "
        f"{any_c['first_t_truth_over_bound_index']} "
        f"(t = {any_c['first_t_truth_over_bound_index'] * ex['spec']['dt']:.2f} s); "
        f"{any_c['n_inside']} samples inside the feasible region, {any_c['n_outside']} "
        "outside. Outside, errors are given against the truth and against the closest "
        f"feasible state (theta clipped to {bound}), the best any bounded estimate can do. "
        "Figure: `exp2_constraints`.",
        "",
    ]
    rows = []
    for m, s in c.items():
        rows.append(
            [
                m.upper(),
                _f(s["inside"]["tip_mean_mm"]) if s["inside"] else "–",
                _f(s["outside_vs_truth"]["tip_mean_mm"]) if s["outside_vs_truth"] else "–",
                _f(s["outside_vs_feasible"]["tip_mean_mm"]) if s["outside_vs_feasible"] else "–",
                _f(math.degrees(s["theta_max_estimate"]), 1),
                str(s["n_estimates_over_bound"]),
            ]
        )
    return lines + _table(
        (
            "method",
            "tip mean inside (mm)",
            "tip mean outside vs truth (mm)",
            "tip mean outside vs feasible (mm)",
            "max theta estimate (deg)",
            "estimates over the bound",
        ),
        rows,
    )


def _rod_description(gen: dict[str, Any] | None) -> str:
    """The rod and its sensor, from the generator settings saved beside the recording,
    and the command that makes it again (the command line's, whatever the settings
    record as their generator)."""
    if gen is None:
        return "was given with --rod-csv, with no generator settings beside it."
    rod, imu = gen["rod"], gen["imu"]
    g = STANDARD_GRAVITY
    return (
        f"comes from a PyElastica Cosserat rod ({rod['length']:g} m, radius "
        f"{rod['radius'] * 1e3:g} mm, E = {rod['youngs_modulus'] / 1e6:g} MPa, "
        f"{rod['n_elements']} elements, tip IMU mass {rod['tip_mass'] * 1e3:g} g, clamped "
        f"base, gravity) bent in one plane by a cable moment of up to {rod['max_moment']:g} "
        f"N m (pull, hold, release, rest every {rod['period']:g} s), with an MPU9250-like "
        f"accelerometer read every {imu['sample_dt']:g} s (tip acceleration included, "
        f"noise {imu['accel_noise']:g} m/s^2, bias {imu['accel_bias']:g} m/s^2 and "
        f"misalignment {imu['misalignment_deg']:g} deg (1 sigma, drawn once), "
        f"{imu['bits']}-bit +-{imu['accel_range'] / g:.0f} g) giving roll and pitch; seed "
        f"{gen['seed']}, {gen['duration']:g} s. Regenerate it with `{GENERATOR} -o rod.csv "
        f"--seed {gen['seed']} --duration {gen['duration']:g}`."
    )


def _exp3(d: dict[str, Any]) -> list[str]:
    lines = [
        "## 3. Hardware-like recording (paper Sec. 3.3, Fig. 7)",
        "",
        f"The paper's recordings are not public. `{d['source']}` ({d['n']} samples at "
        f"{d['dt']:.3f} s) {_rod_description(d.get('generator'))} The estimators assume "
        f"{_f(math.degrees(d['assumed_std']), 1)} deg noise and a {d['length']:g} m section. "
        "'Truth' is the rod's tip position; theta is compared with the best constant-"
        "curvature (CC) fit of the rod's centreline. Figure: `exp3_rod`.",
        "",
    ]
    rows = []
    for m, r in d["methods"].items():
        t, fk = r["vs_truth"]["all"], r["vs_fk_of_measurements"]["all"]
        rows.append(
            [
                m.upper(),
                _f(t["tip_mean_mm"]),
                _f(t["tip_max_mm"]),
                _f(fk["tip_mean_mm"]),
                _f(math.degrees(t["rmse"]["theta"])),
            ]
        )
    lines += _table(
        (
            "method",
            "tip mean vs rod (mm)",
            "tip max vs rod (mm)",
            "tip mean vs FK of measurements (mm)",
            "theta RMSE vs CC fit (deg)",
        ),
        rows,
    )
    lines += ["Where the error comes from (tip position against the rod's true tip):", ""]
    lines += _table(
        ("reference", "mean (mm)", "max (mm)"),
        [
            [
                "best CC arc through the whole centreline (CC assumption alone)",
                _f(d["cc_fit_vs_truth"]["mean_mm"]),
                _f(d["cc_fit_vs_truth"]["max_mm"]),
            ],
            [
                "CC arc from the true tip tangent (a perfect tilt sensor + CC)",
                _f(d["cc_from_tip_tangent_vs_truth"]["mean_mm"]),
                _f(d["cc_from_tip_tangent_vs_truth"]["max_mm"]),
            ],
            [
                "forward kinematics of the raw measurements (no estimator)",
                _f(d["fk_of_measurements_vs_truth"]["mean_mm"]),
                _f(d["fk_of_measurements_vs_truth"]["max_mm"]),
            ],
        ],
    )
    dth = d["theta_tangent_minus_fit_deg"]
    lines += [
        f"The tip tangent's bend differs from the CC fit's theta by {_f(dth['mean_abs'])} deg "
        f"on average (max {_f(dth['max_abs'])} deg): gravity and the rod's dynamics make the "
        "shape depart from an arc.",
        "",
    ]
    return lines


def _table1_scenario(table1: list[list[float]], spec: dict[str, Any]) -> str:
    """`` (Table 1 scenario i)`` if the spec's noise is scenario i's, else nothing."""
    for i, (sb, sg) in enumerate(table1, start=1):
        if list(spec["noise_std"]) == [abs(sg), abs(sb)]:
            return f" (Table 1 scenario {i})"
    return ""


def _exp4(d: dict[str, Any]) -> list[str]:
    ex = d["example"]
    sp = ex["spec"]
    mc = d["monte_carlo"]
    keys = sorted(mc, key=lambda g: int(g.split("-")[1]))
    n = mc[keys[0]]["n_trials"]
    t1 = d["table1"]
    lines = [
        "## 4. Comparison with the EKF (paper Sec. 3.4, Figs. 6 and 8, Table 1)",
        "",
        f"Example run (figure `exp4_trajectory_3d`): {sp['scenario']}, roll/pitch noise "
        f"{sp['noise_std'][0]:.3f}/{sp['noise_std'][1]:.3f} rad{_table1_scenario(t1, sp)}, "
        f"{sp['duration']} s.",
        "",
    ]
    lines += _table(
        _METRIC_HEADER,
        [_metric_row(m.upper(), r["all"], r["solve_ms_median"]) for m, r in ex["methods"].items()],
    )
    mcsp = d["trials"][0]["spec"]
    lines += [
        f"Monte Carlo (figure `exp4_monte_carlo`): {n} seeds per Table 1 scenario, "
        f"{mcsp['duration']} s each, {mcsp['scenario']}. Table 1's sigma is read as a standard "
        "deviation in rad, |sigma| (some printed values are negative, so they cannot be "
        "variances). All estimators use the same model, Q and R (R: "
        f"{_f(_noise_deg(mcsp), 1)} deg std, the paper's V). Mean SRMSE with its 95 % "
        "bootstrap interval; the last columns are the paired difference MHE - EKF over the "
        "same seeds and its verdict (rules in the header).",
        "",
    ]
    rows = []
    for k in keys:
        i = int(k.split("-")[1])
        e = mc[k]
        rows.append(
            [
                str(i),
                _f(abs(t1[i - 1][0]), 3),
                _f(abs(t1[i - 1][1]), 3),
                _ci(e["mhe"]["srmse"]),
                _ci(e["ekf"]["srmse"]),
                _ci(e["ukf"]["srmse"]) if "ukf" in e else "–",
                _ci(e["mhe_minus_ekf"]["srmse"], 4),
                verdict(e["mhe_minus_ekf"]["srmse"], e["ekf"]["srmse"]),
            ]
        )
    lines += _table(
        (
            "scenario",
            "|sigma_beta| (rad)",
            "|sigma_gamma| (rad)",
            "MHE SRMSE",
            "EKF SRMSE",
            "UKF SRMSE",
            "MHE - EKF",
            "verdict",
        ),
        rows,
    )
    cond, early = d["conditions"], d["conditions_early"]
    cfg = d["config"]
    lines += [
        f"Conditions the claim depends on (figure `exp4_conditions`; {cfg['noise_deg']:g} deg "
        f"noise unless stated): `bad-init` offsets the first sample by {cfg['bad_init_deg']:g} "
        "deg on roll and pitch (every estimator initialises from it); `outliers` adds "
        f"+-{cfg['outlier_deg']:g} deg spikes to {cfg['outlier_fraction']:.0%} of the samples; "
        f"`straight` passes through theta = 0; `large-noise` uses {cfg['large_noise_deg']:g} "
        f"deg noise with a matched R. {cfg['condition_seeds']} seeds each; tip error in mm, "
        f"whole run and over the first N = {cfg['horizon']} samples.",
        "",
    ]
    rows = []
    for k in cond:
        c, e = cond[k], early[k]
        rows.append(
            [
                k.removeprefix("condition-"),
                _ci(c["mhe"]["tip_mean_mm"], 2),
                _ci(c["ekf"]["tip_mean_mm"], 2),
                _ci(c["mhe_minus_ekf"]["tip_mean_mm"], 2),
                verdict(c["mhe_minus_ekf"]["tip_mean_mm"], c["ekf"]["tip_mean_mm"]),
                _ci(e["mhe"]["tip_mean_mm"], 2),
                _ci(e["ekf"]["tip_mean_mm"], 2),
                verdict(e["mhe_minus_ekf"]["tip_mean_mm"], e["ekf"]["tip_mean_mm"]),
            ]
        )
    lines += _table(
        (
            "condition",
            "MHE tip (mm)",
            "EKF tip (mm)",
            "MHE - EKF",
            "verdict",
            "MHE tip, first N",
            "EKF tip, first N",
            "verdict, first N",
        ),
        rows,
    )
    return lines


def _ipopt(entry: dict[str, Any], key: str) -> float:
    block = (entry.get("ipopt") or {}).get(key)
    if isinstance(block, dict):
        block = block.get("mean")
    return math.nan if block is None else float(block)


def _ipopt_seeds(s: dict[str, Any], ns: list[int]) -> str:
    counts = sorted({(s[str(n)].get("ipopt") or {}).get("n_seeds", 0) for n in ns})
    text = " or ".join(str(c) for c in counts)
    return f"{text} seed{'s' if counts != [1] else ''} per N"


def _exp5(d: dict[str, Any]) -> list[str]:
    s = d["summary"]
    ns = sorted(int(k) for k in s)
    sp = d["trials"][0]["spec"]
    k0 = s[str(ns[0])].get("score_from", 0)
    rows = [
        [
            str(n),
            _ci(s[str(n)]["srmse"], 4),
            _ci(s[str(n)].get("srmse_common"), 4),
            _ci(s[str(n)].get("tip_mm_common"), 2),
            _f(s[str(n)]["solve_ms_mean"]["mean"], 2),
            _f(s[str(n)].get("solve_ms_median", {}).get("mean"), 2),
            _g(s[str(n)]["solve_ms_total"]["mean"]),
            _g(_median_total_ms(s[str(n)])),
            _f(_ipopt(s[str(n)], "solve_ms_median"), 2),
            _g(_ipopt(s[str(n)], "solve_ms_total")),
            str(s[str(n)]["n_estimates"]),
        ]
        for n in ns
    ]
    med = [s[str(n)].get("solve_ms_median", s[str(n)]["solve_ms_mean"])["mean"] for n in ns]
    peak = _total_time_peak(s, ns)
    grows = med[-1] > 1.5 * med[0]
    m = s[str(ns[0])]["n_samples"]
    n_seeds = sum(1 for t in d["trials"] if not t["spec"].get("mhe_solver")) // len(ns)
    lines = [
        "## 5. Horizon sweep (paper Sec. 3.5, Fig. 9)",
        "",
        f"{sp['scenario']}, {sp['duration']} s (M = {m} samples), {n_seeds} seeds "
        "per N, the paper's start (no estimate before N samples). SRMSE is given over each "
        f"run's own estimates (as the paper) and over the same samples for every N (from "
        f"sample {k0} on), which is the fair comparison. Time is wall time per estimate "
        "in the worker process (trials run in parallel, one per core; the median is robust "
        "to other load on the machine). The default backend is timed on every seed; the "
        f"paper's solver, IPOPT, on {_ipopt_seeds(s, ns)}. Figure: `exp5_horizon`.",
        "",
    ]
    lines += _table(
        (
            "N",
            "SRMSE, own estimates",
            "SRMSE, common samples",
            "tip mm, common samples",
            "mean ms/estimate",
            "median ms/estimate",
            "total ms, sum of the M - N + 1 solves",
            "total ms, (M - N + 1) x median (judged)",
            "IPOPT median ms/estimate",
            "IPOPT total ms (sum)",
            "estimates",
        ),
        rows,
    )
    lines += [
        f"Median time per estimate {'grows' if grows else 'barely changes'} with N (from "
        f"{_f(med[0])} ms at N = {ns[0]} to {_f(med[-1])} ms at N = {ns[-1]}): each solve "
        "has N nodes (a banded KKT system, so roughly linear in N). The total time over "
        f"the recording, (M - N + 1) solves at the median time, peaks at N = {peak} in "
        "this sweep"
        + (
            ", so a fall in a 'time' curve at larger N is the M - N effect of counting "
            "fewer estimates, not a faster solver."
            if peak < ns[-1]
            else "; it does not fall within the sweep because M is much larger than N here."
        ),
        "",
    ]
    return lines


def _exp6(d: dict[str, Any]) -> list[str]:
    s = d["summary"]
    sp = d["trials"][0]["spec"]
    rows = []
    for key, name in (
        ("growing", "MHE, growing window (default)"),
        ("paper-start", "MHE, paper start (Algorithm 1)"),
        ("ekf", "EKF"),
    ):
        b = s[key]
        rows.append(
            [
                name,
                _ci(b["first_estimate_s"], 2),
                _ci(b["early_tip_mm"], 2),
                f"{b['early_estimates']['mean']:.0f}" if "early_estimates" in b else "",
                _ci(b["late_tip_mm"], 2),
            ]
        )
    n = len([t for t in d["trials"] if t["spec"]["group"] == "growing"])
    return [
        "## 6. Beyond the paper: growing window vs the paper's start",
        "",
        f"{sp['scenario']}, {sp['duration']} s, N = {sp['horizon']}, {n} seeds. Time to first "
        "estimate is the sample time of the first estimate. "
        "Figure: `exp6_window`.",
        "",
        *_table(
            (
                "estimator",
                "first estimate (s)",
                "tip error, first N samples (mm)",
                f"estimates in the first N = {sp['horizon']} (the error's samples)",
                "tip error after N (mm)",
            ),
            rows,
        ),
    ]
