"""Observability of a robot's shape from its IMUs: rank of the measurement Jacobian.

For random shapes over the workspace (each section's bend uniform in its disk of radius
``theta_max``, random rates), three Jacobians are computed from the same model the
estimators use:

* ``tilt``: ``d h / d u`` of the tilt measurements (roll, pitch of every IMU) with
  respect to the bend vectors ``u`` (``2 m x 2 n``): can one sample fix the shape?
* ``tilt, 2 samples``: the stacked ``[h(x); h(f(x, dt))]`` of the ``bend`` formulation
  with respect to the whole state (bends and rates): what a short window sees.
* ``with gyros``: the same two-sample Jacobian of the ``direct`` formulation (gravity
  direction and gyro of every IMU).

A tendon robot (a ``[backbone]``) is estimated with its mechanics model, whose shape
follows from the tensions, which are given, and the tip force, which is estimated: its
report (:func:`tendon_force_summary`) is the rank of the IMUs' gravity directions with
respect to the tip force, at equilibria of random tensions and tip forces; its verdict
follows from that.

A Jacobian has full rank at a shape when its rank equals its number of columns (the
unknowns it should determine), counting the singular values above ``RANK_TOL`` times
the largest: a Jacobian with fewer rows than columns (one IMU on two sections) never
has. The verdict (:func:`verdict`) follows from the one-sample tilt Jacobian. Tilt
cannot see a rotation about the vertical, so a section whose bending only turns the IMU
about the vertical (for example section 2 bending in the horizontal plane while section
1 points sideways) is unobservable from tilt at that instant.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Literal

import casadi as ca
import numpy as np

from continuum_mhe.errors import UserError
from continuum_mhe.model.pcc import FREE_AVERAGED_READINGS, free_sections, up_vector
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.model.tendon_statics import Station, TendonStatics
from continuum_mhe.settings import RecoverySettings

#: Relative singular-value threshold for "rank-deficient".
RANK_TOL = 1e-6
#: Time step of the two-sample Jacobians, s.
DT = 0.02


@dataclass(frozen=True)
class JacobianSummary:
    """Rank statistics of one Jacobian over the sampled shapes."""

    rows: int
    cols: int
    full_rank_fraction: float  # rank == cols: the unknowns are determined
    min_rank: int
    max_rank: int
    sigma_min_percentiles: dict[str, float]  # relative smallest singular value
    #: the median over the shapes of the smallest singular value itself (the Jacobian's
    #: unit: for tilt, rad of reading per rad of bend coordinate; 0 with fewer readings
    #: than unknowns)
    sigma_min_median: float = math.nan


@dataclass(frozen=True)
class ObservabilityReport:
    """The PCC model's Jacobians (``tilt``, ``tilt_window``, ``gyro_window``) and, for a
    tendon robot, its mechanics model's (``tendon_force``: the IMUs' gravity directions
    with respect to the tip force, the tensions of its ``n_tendons`` tendons given, at
    ``tendon_samples`` random equilibria; a backbone without tendons has none)."""

    samples: int
    tilt: JacobianSummary
    tilt_window: JacobianSummary
    gyro_window: JacobianSummary
    deficient_examples: list[dict[str, list[float]]] = field(default_factory=list)
    known_case: dict[str, float] = field(default_factory=dict)
    tendon_force: JacobianSummary | None = None
    tendon_samples: int = 0
    #: the sampled loads whose equilibrium the mechanics model did not find (left out)
    tendon_unsolved: int = 0
    #: the robot's tendons (0: a backbone without tendons, given no tensions)
    n_tendons: int = 0
    #: the robot's IMUs
    n_imus: int = 1
    #: the tip position's standard deviation, m, that one sample of tilt readings with
    #: :data:`VERDICT_NOISE` gives (:func:`tip_noise_std`), at the median sampled shape
    tip_noise_std: float = math.nan
    #: the share of the sampled shapes at which that standard deviation exceeds
    #: :data:`WEAK_TIP_FRACTION` of the robot's length (rows ``estimate`` marks
    #: ``uncertain`` there)
    tip_wide_share: float = math.nan
    #: the robot's length, m
    length: float = math.nan
    #: the sections (1-based) whose bend the IMUs leave free, or see by less than the
    #: noise of a mean of readings of :data:`VERDICT_NOISE` across their reach
    #: (:func:`~continuum_mhe.model.pcc.free_sections`): the estimates' standard
    #: deviations carry their reach
    free_sections: tuple[int, ...] = ()

    def as_dict(self) -> dict[str, object]:
        own = asdict(self)
        # JSON has no infinity: a tip the readings do not place (rank-deficient) is null
        own["tip_noise_std"] = self.tip_noise_std if math.isfinite(self.tip_noise_std) else None
        # the sections' lengths summed: 0.1 + 0.1 + 0.1 written as 0.3
        own["length"] = round(self.length, 12) if math.isfinite(self.length) else None
        own["tip_wide_share"] = self.tip_wide_share if math.isfinite(self.tip_wide_share) else None
        return {
            **own,
            "model_check": model_check(self),
            "observable": observability(self),
            "weakly": weakly(self),
            "verdict": verdict(self),
        }


#: Fraction of sampled shapes at which the one-sample tilt Jacobian must have full rank
#: for the verdict "observable".
OBSERVABLE_FRACTION = 0.99
#: The readings' noise the report converts into the tip's standard deviation, rad (the
#: command line's default ``--noise-deg``).
VERDICT_NOISE = math.radians(2.0)
#: A robot whose tip one sample of tilt readings places within more than this fraction
#: of its length (:attr:`ObservabilityReport.tip_noise_std`, the median over the sampled
#: shapes) is observable only weakly: the fraction beyond which ``estimate`` marks a row
#: ``uncertain`` (:attr:`~continuum_mhe.settings.RecoverySettings.uncertain_fraction`).
#: An IMU at a section's end gives 0.03 of the length on one section, 0.05 to 0.06 on
#: three or four sections; one at 0.05 of its section 0.38.
WEAK_TIP_FRACTION = RecoverySettings.uncertain_fraction


def observability(r: ObservabilityReport) -> Literal["yes", "except-near-some", "no"]:
    """The verdict as a word for scripts: ``yes`` where one sample determines the
    shape (a tendon robot's: its tip force) at :data:`OBSERVABLE_FRACTION` of the
    sampled shapes (loads) or more, ``no`` where at none, else ``except-near-some``."""
    t = r.tendon_force if r.tendon_force is not None else r.tilt
    if t.full_rank_fraction >= OBSERVABLE_FRACTION:
        return "yes"
    return "no" if t.full_rank_fraction == 0.0 else "except-near-some"


def weakly(r: ObservabilityReport) -> bool:
    """Whether the IMUs determine the shape only weakly: one sample of tilt readings
    places the tip within more than :data:`WEAK_TIP_FRACTION` of the robot's length at
    the median sampled shape, or leaves a section's bend free
    (:attr:`ObservabilityReport.free_sections`). Not judged for a tendon robot, whose
    verdict is its tip force's."""
    if r.tendon_force is not None or r.tilt.full_rank_fraction == 0.0:
        return False
    return bool(r.tip_noise_std > WEAK_TIP_FRACTION * r.length or r.free_sections)


def verdict(r: ObservabilityReport) -> str:
    """One line from the one-sample tilt Jacobian (a tendon robot's: from the gravity
    directions' Jacobian in its tip force): ``observable`` when it has full rank at
    ``OBSERVABLE_FRACTION`` of the sampled shapes or more, ``not observable`` when at
    none, else ``observable except near some shapes``."""
    if r.tendon_force is not None:
        return _tendon_verdict(r.tendon_force, r.n_tendons, r.n_imus)
    t = r.tilt
    weak = ""
    if t.full_rank_fraction > 0.0 and r.tip_noise_std > WEAK_TIP_FRACTION * r.length:
        weak = (
            f"; but weakly: one sample of tilt readings with {math.degrees(VERDICT_NOISE):g} "
            f"degrees of noise places the tip within about {_mm(r.tip_noise_std)} (a "
            f"standard deviation, {100 * r.tip_noise_std / r.length:.0f} % of the robot's "
            f"length, the median over the sampled shapes; beyond {100 * WEAK_TIP_FRACTION:.0f} "
            f"% at {_percent(r.tip_wide_share)} % of them, where estimate marks its rows "
            "uncertain): an IMU near its section's base barely turns with the bend (put "
            "each section's IMU at its end, at = 1)"
        )
    if r.free_sections:
        weak += (
            f"; the IMUs leave the bend of section(s) "
            f"{', '.join(map(str, r.free_sections))} free (or turn by less than the noise "
            f"of a mean of {FREE_AVERAGED_READINGS} readings of {math.degrees(VERDICT_NOISE):g} "
            "degrees across its reach): the estimates' standard deviations carry that reach"
        )
    if t.full_rank_fraction >= OBSERVABLE_FRACTION:
        return (
            f"observable: one sample of tilt determines all {t.cols} bend coordinates at "
            f"{_percent(t.full_rank_fraction)} % of the sampled shapes (not near the least "
            f"observable shapes of the report, where the estimate follows its motion model){weak}"
        )
    if t.full_rank_fraction == 0.0:
        g = r.gyro_window
        gyros = (
            "the gyros' two-sample rank of the report needs motion and is ill-conditioned: "
            "with them the tip is tens to hundreds of mm off (108 to 243 mm on average "
            "with one IMU at a two-section robot's tip), docs/uncertainty.md"
            if g.full_rank_fraction > 0.0
            else f"the gyros do not determine it either: with them, at most {g.max_rank} of "
            f"the {g.cols} unknowns of two samples at every sampled shape"
        )
        return (
            f"NOT observable: tilt determines at most {t.max_rank} of the {t.cols} bend "
            "coordinates at every sampled shape; estimates of this robot are all marked "
            f"uncertain (put an IMU on every section; {gyros}){weak}"
        )
    return (
        f"observable except near some shapes: full rank at {_percent(t.full_rank_fraction)} % "
        f"of shapes (the least observable are the report's){weak}"
    )


def _mm(length: float) -> str:
    """A length, m, in mm as the verdict says it."""
    return f"{1e3 * length:.0f} mm" if length < 1e3 else "kilometres"


def model_check(r: ObservabilityReport) -> str | None:
    """What in the tilt readings can check the constant-curvature model, for a robot
    without a mechanics model (None for a tendon robot, and where tilt does not determine
    the shape): the readings a sample beyond its bend coordinates. Where there are none,
    the one-sample tilt Jacobian is square and of full rank, so the readings of a nearby
    shape off constant curvature (a twist, a bend that is not an arc under a load) are
    fitted exactly by another constant-curvature shape."""
    t = r.tilt
    if r.tendon_force is not None or t.full_rank_fraction == 0.0:
        return None
    spare = t.rows - t.cols
    if spare > 0:
        return (
            f"tilt gives {t.rows} readings a sample for {t.cols} bend coordinates: {spare} "
            "left over check the constant-curvature model at every sample"
        )
    return (
        f"tilt gives {t.rows} readings a sample for {t.cols} bend coordinates, none left "
        "over: the readings of a robot off constant curvature (a twist, a load) are fitted "
        "exactly by another constant-curvature shape, and its rows read ok unless the "
        "motion between samples gives it away (docs/uncertainty.md); raw IMUs' gyros (3 "
        "readings each a sample) check the shape"
    )


def _tendon_verdict(t: JacobianSummary, n_tendons: int, n_imus: int) -> str:
    given = "with the tensions given, " if n_tendons else ""
    if t.full_rank_fraction >= OBSERVABLE_FRACTION:
        return (
            f"observable: {given}one sample of the IMUs' tilt determines "
            f"the tip force (all {t.cols} components), and so the shape, at "
            f"{_percent(t.full_rank_fraction)} % of the sampled loads with an equilibrium"
        )
    if t.full_rank_fraction == 0.0:
        return (
            f"NOT observable from one sample: the IMUs' tilt determines at most "
            f"{t.max_rank} of the tip force's {t.cols} components at every sampled load; "
            + (
                "estimates of this robot are all marked uncertain (raw IMUs' gyros determine "
                "it over time, loosely; a second IMU makes it observable; docs/tendon.md)"
                if n_imus == 1
                else "its estimates rest on the motion model and raw IMUs' gyros between "
                "samples (docs/tendon.md)"
            )
        )
    return (
        f"observable except near some loads: full rank at {_percent(t.full_rank_fraction)} % "
        "of the sampled loads"
    )


def _summary(jacs: np.ndarray) -> tuple[JacobianSummary, np.ndarray]:
    sv = np.linalg.svd(jacs, compute_uv=False)
    rel = sv[:, -1] / np.maximum(sv[:, 0], 1e-300)
    if jacs.shape[1] < jacs.shape[2]:  # fewer rows than unknowns: a zero singular value
        rel = np.zeros(len(jacs))
    # relative to the largest, and at least RANK_TOL absolute: the tilt Jacobian is in rad
    # per rad (about 1 for an IMU at a section's end), so an IMU that barely moves with
    # the bend (at = 1e-300) sees nothing, whatever the ratio of its singular values
    ranks = np.sum(sv > RANK_TOL * np.maximum(sv[:, :1], 1.0), axis=1)
    full = jacs.shape[2]  # the unknowns: full column rank
    pct = {f"p{q}": float(np.percentile(rel, q)) for q in (0, 1, 5, 50)}
    absolute = 0.0 if jacs.shape[1] < jacs.shape[2] else float(np.median(sv[:, -1]))
    return (
        JacobianSummary(
            rows=jacs.shape[1],
            cols=jacs.shape[2],
            full_rank_fraction=float(np.mean(ranks == full)),
            min_rank=int(ranks.min()),
            max_rank=int(ranks.max()),
            sigma_min_percentiles=pct,
            sigma_min_median=absolute,
        ),
        rel,
    )


def tip_noise_std(j_tilt: np.ndarray, j_tip: np.ndarray, noise: float) -> np.ndarray:
    """The tip position's standard deviation, m (the root of its covariance's trace),
    that one sample of tilt readings of independent noise ``noise`` (rad) gives through
    the bend coordinates, per shape: ``J_tip (J_tilt^T J_tilt)^-1 J_tip^T noise^2`` from
    the Jacobians ``j_tilt`` (shapes, readings, bends) and ``j_tip`` (shapes, 3, bends);
    infinite where the tilt Jacobian is singular."""
    out = np.full(len(j_tilt), np.inf)
    for i, (a, t) in enumerate(zip(j_tilt, j_tip)):
        sv = np.linalg.svd(a, compute_uv=False)
        if a.shape[0] < a.shape[1] or sv[-1] <= RANK_TOL * max(sv[0], 1.0):
            continue  # the rank _summary counts: tilt does not determine the bends
        cov = t @ np.linalg.solve(a.T @ a, t.T) * noise**2
        out[i] = math.sqrt(max(float(np.trace(cov)), 0.0))
    return out


def _jacobian_functions(
    robot: Robot,
) -> tuple[ca.Function, ca.Function, ca.Function, ca.Function]:
    """The one-sample tilt, two-sample tilt and two-sample raw Jacobians, and the tip
    position's (m) Jacobian in the bend coordinates."""
    bend = make_formulation("bend", robot)
    direct = make_formulation("direct", robot, estimate_gyro_bias=False)
    n2 = 2 * robot.n_sections
    x = ca.SX.sym("x", bend.nx)
    x_next = bend.transition_sym(x, ca.SX(0, 1), ca.SX(DT))
    h_tilt, h_dir = (ca.Function("h", [x], [f.measurement_sym(x)]) for f in (bend, direct))
    j_tilt = ca.Function("j_tilt", [x], [ca.jacobian(h_tilt(x), x[:n2])])
    two = ca.vertcat(h_tilt(x), h_tilt(x_next))
    j_tilt2 = ca.Function("j_tilt2", [x], [ca.jacobian(two, x)])
    two_d = ca.vertcat(h_dir(x), h_dir(x_next))
    j_dir2 = ca.Function("j_dir2", [x], [ca.jacobian(two_d, x)])
    j_tip = ca.Function("j_tip", [x], [ca.jacobian(bend.output_sym(x)[:3], x[:n2])])
    return j_tilt, j_tilt2, j_dir2, j_tip


def _sample_states(robot: Robot, samples: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = robot.n_sections
    x = np.zeros((samples, 4 * n))
    for k, sec in enumerate(robot.sections):
        r = sec.theta_max * np.sqrt(rng.uniform(0, 1, samples))
        ang = rng.uniform(-np.pi, np.pi, samples)
        x[:, 2 * k], x[:, 2 * k + 1] = r * np.cos(ang), r * np.sin(ang)
    x[:, 2 * n :] = rng.normal(scale=0.5, size=(samples, 2 * n))
    return x


def _eval(fn: ca.Function, x: np.ndarray) -> np.ndarray:
    out = np.asarray(fn.map(len(x))(x.T), dtype=float)
    rows, cols = fn.size1_out(0), fn.size2_out(0)
    return out.reshape(rows, len(x), cols).transpose(1, 0, 2)  # [J_1 J_2 ...] side by side


#: at most this many random equilibria for a tendon robot's report (a statics solve each)
TENDON_SAMPLES = 200


def _tendon_gravity_jacobian(robot: Robot) -> ca.Function:
    """``(k0, F, tau) -> (residual, d g / d F, d g / d k0, d residual / d k0, d residual
    / d F)`` of the statics, ``g`` every IMU's gravity direction ``R^T up`` stacked."""
    statics = TendonStatics(robot)
    k0, force = ca.SX.sym("k0", 3), ca.SX.sym("F", 3)
    tau = ca.SX.sym("tau", robot.n_tendons)
    stations = tuple(Station(i.section, i.at) for i in robot.imus)
    poses, res = statics.shoot(k0, force, tau, stations)
    up = ca.DM(up_vector(robot.mounting))
    g = ca.vertcat(*(ca.mtimes(poses[st][0].T, up) for st in stations))
    return ca.Function(
        "tendon_gravity",
        [k0, force, tau],
        [res, ca.jacobian(g, force), ca.jacobian(g, k0), ca.jacobian(res, k0),
         ca.jacobian(res, force)],
    )  # fmt: skip


def tendon_force_summary(robot: Robot, samples: int, seed: int = 0) -> tuple[JacobianSummary, int]:
    """The rank of the IMUs' gravity directions with respect to the tip force, the base
    curvature following it through the tip condition (implicit differentiation), at
    ``samples`` equilibria: each section bent by one of its tendons to a random angle up
    to ``min(theta_max, 2)`` rad, under a random tip force within twice the tendon
    formulation's force prior; and how many of those loads had no equilibrium the model
    finds (left out: a backbone too soft for its weight sags beyond them).

    Raises:
        UserError: if none of the loads has an equilibrium.
    """
    rng = np.random.default_rng(seed)
    statics = TendonStatics(robot)
    fn = _tendon_gravity_jacobian(robot)
    ei, _ = statics.stiffness
    reach = 2 * TendonFormulation(robot=robot).force_prior_std
    by_section = [[i for i, td in enumerate(robot.tendons) if td.section == k]
                  for k in range(robot.n_sections)]  # fmt: skip
    jacs = []
    unsolved = 0
    for _ in range(samples):
        tau = np.zeros(robot.n_tendons)
        for k, sec in enumerate(robot.sections):
            if by_section[k]:
                i = int(rng.choice(by_section[k]))
                bend = rng.uniform(0.0, min(sec.theta_max, 2.0))
                tau[i] = bend * ei / (robot.tendons[i].radius * sec.length)
        d = rng.normal(size=3)
        force = reach * rng.uniform() ** (1 / 3) * d / np.linalg.norm(d)
        try:
            k0, _ = statics.solve(force, tau)
        except ArithmeticError:
            unsolved += 1
            continue
        _, g_f, g_k, r_k, r_f = (np.asarray(v, dtype=float) for v in fn(k0, force, tau))
        jacs.append(g_f - g_k @ np.linalg.solve(r_k, r_f))
    if not jacs:
        b = robot.backbone
        stiffness = "" if b is None else f" (youngs_modulus {b.youngs_modulus:g} Pa)"
        raise UserError(
            f"the mechanics model finds no equilibrium of this robot at any of {samples} "
            f"loads (its tendons bending each section up to 2 rad, tip forces up to "
            f"{reach:.3g} N): is its backbone this soft{stiffness}, or this heavy (density)?"
        )
    summary, _ = _summary(np.array(jacs))
    return summary, unsolved


def observability_report(robot: Robot, samples: int = 2000, seed: int = 0) -> ObservabilityReport:
    """Rank of the measurement Jacobians over ``samples`` random shapes of ``robot``."""
    if not (isinstance(samples, int) and 10 <= samples <= 1_000_000):
        raise UserError(f"samples must be an integer in [10, 1000000], got {samples!r}")
    j_tilt, j_tilt2, j_dir2, j_tip = _jacobian_functions(robot)
    x = _sample_states(robot, samples, seed)
    tilt_jacs = _eval(j_tilt, x)
    tilt, rel = _summary(tilt_jacs)
    tip_stds = tip_noise_std(tilt_jacs, _eval(j_tip, x), VERDICT_NOISE)
    tip_std = float(np.median(tip_stds))
    tip_wide = float(np.mean(tip_stds > WEAK_TIP_FRACTION * sum(robot.lengths)))
    tilt2, _ = _summary(_eval(j_tilt2, x))
    gyro2, _ = _summary(_eval(j_dir2, x))
    worst = np.argsort(rel)[:3]
    n = robot.n_sections
    examples = [
        {
            "theta_deg": [math.degrees(math.hypot(x[i, 2 * k], x[i, 2 * k + 1])) for k in range(n)],
            "phi_deg": [math.degrees(math.atan2(x[i, 2 * k + 1], x[i, 2 * k])) for k in range(n)],
            "relative_sigma_min": [float(rel[i])],
        }
        for i in worst
    ]
    known: dict[str, float] = {}
    if n >= 2 and all(s.theta_max > math.pi / 2 for s in robot.sections[:1]):
        # section 1 bent 90 deg sideways (its end points horizontally), section 2 bending
        # in the horizontal plane: tilt cannot see section 2's bend there
        xk = np.zeros((1, 4 * n))
        xk[0, 0] = math.pi / 2
        xk[0, 3] = 0.5
        xk[0, 2 * n :] = 0.3  # moving: the gyros see the rates
        for name, fn in (("tilt", j_tilt), ("tilt_window", j_tilt2), ("gyro_window", j_dir2)):
            sv = np.linalg.svd(_eval(fn, xk)[0], compute_uv=False)
            known[name] = float(sv[-1] / sv[0])
    if robot.backbone is None:
        free = tuple(k + 1 for k in free_sections(robot, VERDICT_NOISE))
        return ObservabilityReport(
            samples, tilt, tilt2, gyro2, examples, known, n_imus=robot.n_imus,
            tip_noise_std=tip_std, tip_wide_share=tip_wide, length=sum(robot.lengths),
            free_sections=free,
        )  # fmt: skip
    m = min(samples, TENDON_SAMPLES)
    tendon, unsolved = tendon_force_summary(robot, m, seed)
    return ObservabilityReport(
        samples, tilt, tilt2, gyro2, examples, known, tendon, m, unsolved, robot.n_tendons,
        robot.n_imus, tip_std, tip_wide, sum(robot.lengths),
    )  # fmt: skip


def unsolved_warning(r: ObservabilityReport) -> str | None:
    """One line for the sampled loads of a tendon robot's report that have no
    equilibrium (left out of it), or None when every load has one."""
    if not r.tendon_unsolved:
        return None
    return (
        f"{r.tendon_unsolved} of the {r.tendon_samples} loads have no equilibrium the "
        "mechanics model finds (left out of the report): the backbone sags beyond them; "
        "is it this soft (youngs_modulus), or this heavy (density)?"
    )


def _percent(fraction: float) -> str:
    """``fraction`` (0 to 1) as a percentage to one decimal, or to as many more as keep a
    fraction under 1 from showing 100 and one over 0 from showing 0 (a rank drop at 1 of
    2000 shapes is 99.95 %, not 100.0 %)."""
    for digits in range(1, 7):
        text = f"{100 * fraction:.{digits}f}"
        if not ((fraction < 1 and float(text) >= 100) or (fraction > 0 and float(text) == 0)):
            break
    return text


def format_report(robot: Robot, r: ObservabilityReport) -> str:
    """Human-readable report (a tendon robot's: its mechanics model's first, with the
    verdict, which is that model's, right after it). The loads without an equilibrium
    are counted in it; :func:`unsolved_warning` says so."""
    lines = [f"robot: {robot.describe()} (an IMU as section@fraction of its length)"]
    if r.tendon_force is not None:
        s, p = r.tendon_force, r.tendon_force.sigma_min_percentiles
        given = "tensions given" if robot.n_tendons else "no tendons: a rod under its tip force"
        solved = r.tendon_samples - r.tendon_unsolved
        of = "" if not r.tendon_unsolved else f", {solved} of them with an equilibrium"
        lines.append(
            f"tendon model, {given}, one sample (d gravity directions / d tip force, "
            f"{r.tendon_samples} loads{of}): {s.rows}x{s.cols}, of full rank ({s.cols}) at "
            f"{_percent(s.full_rank_fraction)} % of those (min rank {s.min_rank}); relative "
            f"smallest singular value p1 {p['p1']:.2e}, p5 {p['p5']:.2e}, median {p['p50']:.2e}"
        )
        lines.append(f"verdict: {verdict(r)}")
        lines.append(
            "for comparison, the constant-curvature model of the same geometry (not the "
            "model that estimates this robot):"
        )
    lines.append(f"shapes sampled: {r.samples}")
    for label, s in (
        ("tilt, one sample (d roll,pitch / d bends)", r.tilt),
        ("tilt, two samples (whole state)", r.tilt_window),
        ("with gyros, two samples (whole state)", r.gyro_window),
    ):
        p = s.sigma_min_percentiles
        absolute = (
            f" (itself: median {s.sigma_min_median:.2e} rad of reading per rad of bend; "
            f"the tip's std from one sample at {math.degrees(VERDICT_NOISE):g} degrees of "
            f"noise: median {1e3 * r.tip_noise_std:.3g} mm)"
            if s is r.tilt and math.isfinite(r.tip_noise_std) and s.full_rank_fraction > 0.0
            else ""
        )
        lines.append(
            f"{label}: {s.rows}x{s.cols}, of full rank ({s.cols}, every unknown) at "
            f"{_percent(s.full_rank_fraction)} % of shapes (min rank {s.min_rank}); "
            "relative smallest singular value "
            f"p1 {p['p1']:.2e}, p5 {p['p5']:.2e}, median {p['p50']:.2e}{absolute}"
        )
    if r.tilt.full_rank_fraction > 0.0:
        lines.append("least observable shapes (tilt, one sample):")
    for e in r.deficient_examples if r.tilt.full_rank_fraction > 0.0 else []:
        th = ", ".join(f"{v:.0f}" for v in e["theta_deg"])
        ph = ", ".join(f"{v:.0f}" for v in e["phi_deg"])
        lines.append(f"  theta = [{th}] deg, phi = [{ph}] deg: {e['relative_sigma_min'][0]:.1e}")
    if r.known_case:
        k = r.known_case
        lines.append(
            "section 1 at 90 deg, section 2 bending in the horizontal plane"
            f"{', the others straight' if robot.n_sections > 2 else ''} (a shape "
            "that tilt alone cannot see): relative "
            f"smallest singular value tilt {k['tilt']:.1e}, tilt window {k['tilt_window']:.1e}, "
            f"with gyros {k['gyro_window']:.1e}"
        )
    check = model_check(r)
    if check is not None:
        lines.append(f"model check: {check}")
    if r.tendon_force is None:
        lines.append(f"verdict: {verdict(r)}")
    return "\n".join(lines)
