"""The statics of a tendon-driven robot: a Cosserat-rod backbone loaded by its tendons
and a tip force, shot from the base (:class:`TendonStatics`), used by the estimators'
formulation (:mod:`continuum_mhe.model.tendon`), the viewer and the figures.

The backbone is a Cosserat rod that bends and twists; it is taken as inextensible and
unshearable (``p' = R e3``): a 0.7 mm nitinol rod under a few newtons stretches by
about ``T / (E A) = 5e-5`` and shears less, far below the IMUs' resolution. Its
material law is ``m = R K u`` with ``K = diag(EI, EI, GJ)`` and ``u`` the curvature and
twist rate in the body frame (straight and untwisted at rest).

Tendon loads follow Rucker and Webster (2011) for frictionless tendons routed parallel
to the backbone at a fixed place ``r_i = (x_i, y_i, 0)`` in the disk frame (the disks
are taken as continuous: a tendon follows the backbone between disks instead of
running straight from disk to disk). Rather than the distributed tendon loads and the
point force and moment at each anchor, the equations are written for the *total*
internal wrench of a cross-section, backbone plus the tendons it cuts::

    N = n + sum_i tau_i t_i,            M = m + sum_i (R r_i) x (tau_i t_i)

with ``t_i`` the unit tangent of tendon ``i``'s path and the sums over the tendons
anchored beyond the cut. The distal part's equilibrium gives ``N(s) = F + w (L - s)``
(``F`` the tip force, ``w`` the weight per length when a density is given) and
``M' = -p' x N``, with ``M(L) = 0`` at the tip: the anchors' point loads are
internal to this balance and need no special step. This is Rucker and Webster's model
integrated once; it is exact for their assumptions. At each arc length ``u`` solves
``K u + sum_i tau_i r_i x t_i(u) = R^T M`` with ``t_i = (e3 + u x r_i)/|e3 + u x r_i|``
in the body frame. Its exact solution differs from the one with ``t_i = e3`` (closed
form, :meth:`TendonStatics.curvature_sym`) by a relative ``(u_z |r_i|)^2 / 2`` in the
tendon moments (a twisted backbone makes a tendon a helix): 2.4e-4 at 50 degrees of
twist over 0.4 m with tendons at 10 mm, so the closed form is used; the tendons'
stiffening of the twist, ``sum tau |r_i|^2``, is kept.

Tendons drawn straight from disk to disk (``Robot.tendon_route = "disks"``) run along
the chords of a bent section: a chord between disks ``d`` apart lies off the continuous
tendon's arc, towards the bend's centre, by ``kappa x (d - x) / 2`` at ``x`` into the
span, ``kappa d^2 / 12`` on average. Its tension's moment about the backbone grows by
that lever in the bend's own direction, ``-tau d^2 / 12 (u_x, u_y, 0)`` in the body
frame, so each section bends as if its bending stiffness were ``EI - sum tau d^2 / 12``
over the tendons it holds (the moment averaged over each span; the disks' point loads
are internal to the total wrench as the anchors' are). That is the first order of the
span as a beam-column under the tensions' compression ``P = sum tau``, whose mean
curvature under end moments is ``M / (EI x / tan x)``, ``x = (d / 2) sqrt(P / EI)``,
which the model takes (a span buckles at ``x = pi / 2``), with a first-order correction
for each tendon's place across the bend (:meth:`TendonStatics._curvature`), checked
against the recording generator's discrete rod with its tendons drawn so
(:mod:`continuum_mhe.simulation.cosserat_tendon`, ``route="disks"``).

Statics are solved by shooting: the rod ODE in ``(p, R, M)`` is integrated from the
base on a fixed number of steps per section (:data:`STEPS_PER_SECTION`, plus a step
boundary at every IMU), symbolically in CasADi SX, from the unknown base moment; the tip
condition ``M(L) = 0`` is a residual (:meth:`TendonStatics.shoot`). Each step is a
fourth-order commutator-free Lie-group step (CF4): the frame moves along helical arcs
of constant body curvature and twist (the exponential of SE(3)), which a bent, twisting
rod follows closely, so that two steps per section do what RK4 on ``R`` needed six for
(and ``R`` stays a rotation). Slack tendons: every tension is clipped at zero (a tendon
cannot push).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import NamedTuple

import casadi as ca
import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, time_text
from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.model.kinematics import Sym
from continuum_mhe.model.pcc import up_vector
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.tape import tape_function

#: Steps per section of the shooting (more where an IMU splits one): with the
#: fourth-order Lie-group steps of :meth:`TendonStatics.shoot`, two per section put every
#: station of the shipped recordings within 0.07 mm of a converged shooting.
STEPS_PER_SECTION = 2
#: The tip condition's residual norm (N m) below which :meth:`TendonStatics.solve`
#: takes the base curvature as the equilibrium.
TIP_CONDITION_TOL = 1e-12
#: Newton iterations of one :meth:`TendonStatics.solve` stage.
NEWTON_ITERATIONS = 50
#: The stages of :meth:`TendonStatics.solve`'s continuation in the loads.
LOAD_STAGES = 10


def _one_line(v: FloatArray) -> str:
    """A vector's values on one line, four significant digits."""
    return np.array2string(np.asarray(v, dtype=float), precision=4, max_line_width=10**6)


def no_equilibrium_at(t: float, exc: ArithmeticError) -> UserError:
    """The one-line error of a row at ``t`` s whose loads have no equilibrium
    (:meth:`TendonStatics.solve`'s ``exc``), for the drawings of estimates and truths."""
    return UserError(
        f"the row at t = {time_text(t)} s: {exc} (a force in mN, or a backbone too soft for "
        "its loads?)"
    )


def hat_sym(v: Sym) -> Sym:
    """The cross-product matrix of ``v`` (3,): ``hat_sym(v) w = v x w``."""
    return ca.vertcat(
        ca.horzcat(0, -v[2], v[1]), ca.horzcat(v[2], 0, -v[0]), ca.horzcat(-v[1], v[0], 0)
    )


#: The rod's state along the backbone: ``(p, R, M)``, position (m, base frame), frame
#: (3x3, body to base) and total internal moment (N m, base frame).
_RodState = tuple[Sym, Sym, Sym]
#: The series branch of :func:`_arc` below this squared angle, rad^2 (its error there is
#: under 1e-17).
_ARC_SERIES_BELOW = 1e-2


def _arc(omega: Sym, length: float) -> tuple[Sym, Sym]:
    """``(exp(hat(omega)), V(omega) e3 length)``: the rotation and the displacement (m,
    in the starting frame) of a helical arc of ``length`` whose frame turns by the body
    rotation vector ``omega`` (rad), the exponential of SE(3). Its coefficients
    ``sin t / t``, ``(1 - cos t) / t^2``, ``(t - sin t) / t^3`` come from their series
    near ``t = 0``, with a safe argument on the other branch so that neither branch nor
    its derivative meets ``0 / 0`` (jaxlie's pattern)."""
    t2 = ca.dot(omega, omega)
    small = t2 < _ARC_SERIES_BELOW
    t2s = ca.if_else(small, 1.0, t2)
    t = ca.sqrt(t2s)
    sin, cos = ca.sin(t), ca.cos(t)
    a = ca.if_else(small, 1 - t2 / 6 * (1 - t2 / 20 * (1 - t2 / 42 * (1 - t2 / 72))), sin / t)
    b = ca.if_else(small, (1 - t2 / 12 * (1 - t2 / 30 * (1 - t2 / 56 * (1 - t2 / 90)))) / 2,
                   (1 - cos) / t2s)  # fmt: skip
    c = ca.if_else(small, (1 - t2 / 20 * (1 - t2 / 42 * (1 - t2 / 72 * (1 - t2 / 110)))) / 6,
                   (t - sin) / (t2s * t))  # fmt: skip
    H: Sym = hat_sym(omega)
    H2: Sym = ca.mtimes(H, H)
    # V e3 = e3 + b hat(omega) e3 + c hat(omega)^2 e3: the third columns
    return ca.SX.eye(3) + a * H + b * H2, length * (ca.DM([0, 0, 1]) + b * H[:, 2] + c * H2[:, 2])


def _move(
    y: _RodState, weighted: list[tuple[float, tuple[Sym, Sym]]], h: float, n0: Sym
) -> _RodState:
    """``y`` moved by ``h`` (m) times the weighted sum of rod fields ``(u, g)``
    (:meth:`TendonStatics._field`): the frame along the helical arc of body rotation
    ``h sum w u`` and length ``h sum w``, the moment by ``-dp x n0`` for the arc's
    displacement ``dp`` and the step's starting section force ``n0`` (N), and by ``h sum
    w g``."""
    p, R, M = y
    rot, disp = _arc(h * sum(w * f[0] for w, f in weighted), h * sum(w for w, _ in weighted))
    dp = ca.mtimes(R, disp)
    return p + dp, ca.mtimes(R, rot), M - ca.cross(dp, n0) + h * sum(w * f[1] for w, f in weighted)


class _TendonSums(NamedTuple):
    """What the tendons that a cross-section cuts do to it (:func:`_tendon_sums`)."""

    #: ``sum tau y``, N m: their moment's body ``-x`` part
    tau_y: Sym
    #: ``sum tau x``, N m: their moment's body ``y`` part
    tau_x: Sym
    #: ``sum tau |r|^2``, N m^2: their stiffening of the twist
    tau_r2: Sym
    #: ``sum tau``, N: their pull, the compression of a span between two disks
    tau: Sym
    #: ``d^2 / 12``, m^2, for disks ``d`` apart where the tendons run from disk to disk;
    #: 0 for continuous tendons (see the module docstring)
    chord_share: float


def _tendon_sums(tensions: list[tuple[Sym, float, float]], chord_share: float = 0.0) -> _TendonSums:
    """The sums of the tendons ``(tau, x, y)`` (N, m, m) that a cross-section cuts, with
    the ``chord_share`` of its section's disks (0: continuous tendons)."""
    return _TendonSums(sum(tau * y for tau, _, y in tensions),
                       sum(tau * x for tau, x, _ in tensions),
                       sum(tau * (x**2 + y**2) for tau, x, y in tensions),
                       sum(tau for tau, _, _ in tensions), chord_share)  # fmt: skip


#: The least share of its bending stiffness a section keeps under its tendons' chords
#: (tendons from disk to disk: ``EI x / tan x``, ``x = (d / 2) sqrt(sum tau / EI)``),
#: reached at 0.96 of the load that buckles the backbone between two disks,
#: ``pi^2 EI / d^2`` (254 N for the shipped robot, 40 N for disks 5 cm apart).
CHORD_STIFFNESS_FLOOR = 0.1


@dataclass(frozen=True)
class Station:
    """A place on the backbone where the statics report a pose.

    Attributes:
        section: 0-based section.
        at: fraction of that section's length from its base, in ``(0, 1]``.
    """

    section: int
    at: float


@dataclass(frozen=True)
class TendonStatics:
    """The symbolic statics of one robot (needs ``robot.backbone``).

    :meth:`shoot` integrates from the base curvature ``k0`` (rad/m, 3), the tip force
    ``F`` (N, 3, base frame) and the tensions ``tau`` (N, clipped at zero) and returns
    the poses at the requested stations and the tip residual.
    """

    robot: Robot
    steps_per_section: int = STEPS_PER_SECTION
    #: the width of the tensions' clip at zero, N (0: ``max(tension, 0)``;
    #: :attr:`~continuum_mhe.model.tendon.TendonFormulation.slack_smoothing`)
    slack_smoothing: float = 0.0

    def __post_init__(self) -> None:
        if self.robot.backbone is None:
            raise UserError("the tendon model needs the backbone's material ([backbone])")

    @property
    def stiffness(self) -> tuple[float, float]:
        """``(EI, GJ)``, N m^2."""
        bb = self.robot.backbone
        assert bb is not None
        return bb.bending_stiffness, bb.torsional_stiffness

    def _weight_per_length(self) -> FloatArray:
        """The backbone's weight per length in the base frame, N/m (zero without a
        density)."""
        bb = self.robot.backbone
        assert bb is not None
        if bb.density is None:
            return np.zeros(3)
        return -bb.density * bb.area * STANDARD_GRAVITY * up_vector(self.robot.mounting)

    def curvature_sym(self, m_body: Sym, tensions: list[tuple[Sym, float, float]]) -> Sym:
        """Body curvature and twist rate ``u`` (rad/m) from the body-frame total moment
        (N m) and the active tendons ``(tau, x, y)`` (N, m, m), with the tendons taken
        along ``e3`` (see the module docstring): ``EI u_x = m_x - sum tau y``,
        ``EI u_y = m_y + sum tau x``, ``(GJ + sum tau |r|^2) u_z = m_z``."""
        return self._curvature(m_body, _tendon_sums(tensions))

    def _curvature(self, m_body: Sym, sums: _TendonSums) -> Sym:
        """:meth:`curvature_sym` from the tendons' sums (:func:`_tendon_sums`; tendons
        from disk to disk lower the bending stiffness, to at most
        :data:`CHORD_STIFFNESS_FLOOR` of it)."""
        ei, gj = self.stiffness
        bx, by = m_body[0] - sums.tau_y, m_body[1] + sums.tau_x
        twist = m_body[2] / (gj + sums.tau_r2)
        if sums.chord_share == 0.0:
            return ca.vertcat(bx / ei, by / ei, twist)
        floor = CHORD_STIFFNESS_FLOOR * ei

        # the span between two disks is a beam-column under the tensions' compression P:
        # its mean curvature under end moments is (M / EI) tan(x) / x, x = (d / 2)
        # sqrt(P / EI) (to first order EI - P d^2 / 12); it buckles at x = pi / 2
        def column(share: Sym) -> Sym:  # EI x / tan x for share = P d^2 / 12
            x = ca.sqrt(ca.fmax(3.0 * share / ei, 1e-12))
            return ca.fmax(ei * x / ca.tan(ca.fmin(x, 1.5)), floor)

        share = sums.chord_share
        chords = share * sums.tau
        bend = column(chords)
        # a tendon nearer the bend's centre by r . n runs a shorter arc between the disks,
        # (1 - kappa r . n) d, whose chord lies off it by kappa (1 - kappa r . n) d^2 / 12
        # on average: it counts as a tension tau (1 - kappa r . n), kappa r . n = u_y x
        # - u_x y at the curvature without it
        ux, uy = bx / bend, by / bend
        bend = column(chords - share * (uy * sums.tau_x - ux * sums.tau_y))
        return ca.vertcat(bx / bend, by / bend, twist)

    def chord_share(self, section: int) -> float:
        """``d^2 / 12`` (m^2) for section ``section``'s disks ``d`` apart where the
        robot's tendons run from disk to disk, else 0 (continuous tendons)."""
        sec = self.robot.sections[section]
        if self.robot.tendon_route != "disks" or sec.disks < 1:
            return 0.0
        return (sec.length / sec.disks) ** 2 / 12

    def _field(self, y: _RodState, ds: float, sums: _TendonSums) -> tuple[Sym, Sym]:
        """The rod equation ``ds`` (m) into a step as ``(u, g)``: the body curvature and
        twist rate (rad/m) that turn the frame (``R' = R hat(u)``, ``p' = R e3``), with
        the tendon sums ``sums`` of the section, and the weight's part of the moment's
        rate, ``g = p' x w ds`` (N; ``M' = -p' x N(s)`` with ``N(s) = N(s0) - w ds``)."""
        _, R, M = y
        weight = ca.cross(R[:, 2], ca.DM(self._weight_per_length())) * ds
        return self._curvature(ca.mtimes(R.T, M), sums), weight

    def stations(self) -> tuple[Station, ...]:
        """Every section's end and every IMU's place, base to tip."""
        places = {Station(k, 1.0) for k in range(self.robot.n_sections)}
        places |= {Station(i.section, i.at) for i in self.robot.imus}
        return tuple(sorted(places, key=lambda s: (s.section, s.at)))

    def _step(self, y: _RodState, s: float, h: float, force: Sym, sums: _TendonSums) -> _RodState:
        """One step of length ``h`` (m) from arc length ``s``: the commutator-free
        Lie-group method of order four (Celledoni, Marthinsen and Owren 2003, "CF4") on
        the frame ``(R, p)`` in SE(3) and the moment ``M`` in R^3. Each of its five
        moves is exact for a constant field: a helical arc of constant body curvature
        and twist (:func:`_arc`); the moment follows the arc's displacement ``dp`` as
        ``-dp x N(s)`` (exact for the tip force: the base then carries exactly
        ``p_tip x F``) plus the weight's part (:meth:`_field`)."""
        n0 = force + self._weight_per_length() * (self.robot.length - s)
        f1 = self._field(y, 0.0, sums)
        y2 = _move(y, [(0.5, f1)], h, n0)
        f2 = self._field(y2, h / 2, sums)
        y3 = _move(y, [(0.5, f2)], h, n0)
        f3 = self._field(y3, h / 2, sums)
        y4 = _move(y2, [(1.0, f3), (-0.5, f1)], h, n0)
        f4 = self._field(y4, h, sums)
        fs = (f1, f2, f3, f4)
        half = _move(y, list(zip((3 / 12, 2 / 12, 2 / 12, -1 / 12), fs)), h, n0)
        return _move(half, list(zip((-1 / 12, 2 / 12, 2 / 12, 3 / 12), fs)), h, n0)

    def acting(self, tension: Sym) -> Sym:
        """The tension a tendon pulls with, N, for a tension state ``tension``: clipped
        at zero, exactly or smoothly over :attr:`slack_smoothing`."""
        e = self.slack_smoothing
        if e > 0:
            return 0.5 * (tension + ca.sqrt(tension * tension + e * e))
        return ca.fmax(tension, 0.0)

    def shoot(
        self, k0: Sym, force: Sym, tension: Sym, stations: tuple[Station, ...] | None = None
    ) -> tuple[dict[Station, tuple[Sym, Sym]], Sym]:
        """``({station: (R, p)}, residual)``: the pose (3x3 body-to-base rotation, m) at
        every one of ``stations`` (default :meth:`stations`; in any order; each also ends
        a step) and the tip residual ``R(L)^T M(L) / EI`` (rad/m)."""
        robot = self.robot
        ei, _ = self.stiffness
        taus = [self.acting(tension[i]) for i in range(robot.n_tendons)]
        # R(0) = I: body and base frames agree
        y: _RodState = (ca.SX.zeros(3), ca.SX.eye(3), ei * k0)
        s0 = 0.0
        poses: dict[Station, tuple[Sym, Sym]] = {}
        stations = self.stations() if stations is None else stations
        for k, sec in enumerate(robot.sections):
            sums = _tendon_sums(
                [(taus[i], *td.offset) for i, td in enumerate(robot.tendons) if td.section >= k],
                self.chord_share(k),
            )
            cuts = sorted(
                {j / self.steps_per_section for j in range(1, self.steps_per_section + 1)}
                | {st.at for st in stations if st.section == k}
            )
            prev = 0.0
            for at in cuts:
                y = self._step(y, s0 + prev * sec.length, (at - prev) * sec.length, force, sums)
                st = Station(k, at)
                if st in stations:
                    poses[st] = (y[1], y[0])
                prev = at
            s0 += sec.length
        return poses, ca.mtimes(y[1].T, y[2]) / ei

    @cached_property
    def function(self) -> ca.Function:
        """``(k0, F, tau) -> (residual, [vec R, p] per station)`` as a CasADi Function
        (built once for all equal statics: :func:`_statics_functions`)."""
        return _statics_functions(self)[0]

    def _build_function(self) -> ca.Function:
        """A new :attr:`function` (its symbolic shooting built again)."""
        k0, force = ca.SX.sym("k0", 3), ca.SX.sym("F", 3)
        tau = ca.SX.sym("tau", self.robot.n_tendons)
        poses, res = self.shoot(k0, force, tau)
        outs = [ca.vertcat(ca.vec(R), p) for R, p in (poses[s] for s in self.stations())]
        return ca.Function("tendon_statics", [k0, force, tau], [res, ca.horzcat(*outs)])

    def solve(
        self, force: FloatArray, tension: FloatArray, k0: FloatArray | None = None
    ) -> tuple[FloatArray, dict[Station, tuple[FloatArray, FloatArray]]]:
        """Numeric statics under the tip force ``force`` (N, base frame) and the
        tensions ``tension`` (N): the base curvature ``k0`` (rad/m) that meets the tip
        condition and the poses ``{station: (R, p)}``.

        Damped Newton on the tip condition from ``k0`` (else the straight rod); where it
        stalls, from the straight rod, and then along the loads scaled from a tenth to
        all of them, each stage from the one before (the equilibrium of a large bend is
        out of a plain Newton's reach from the straight rod).

        Raises:
            ArithmeticError: if no equilibrium is found (loads beyond what the rod
                holds, or not finite).
        """
        force = np.asarray(force, dtype=float)
        tension = np.asarray(tension, dtype=float)
        x = None if k0 is None else self._newton(force, tension, np.asarray(k0, dtype=float))
        if x is None:
            x = self._newton(force, tension, np.zeros(3))
        if x is None:
            x = np.zeros(3)
            for scale in np.linspace(0.1, 1.0, LOAD_STAGES):
                x = self._newton(scale * force, scale * tension, x)
                if x is None:
                    raise ArithmeticError(
                        f"no equilibrium of the tendon robot under the tip force "
                        f"{_one_line(force)} N and the tensions {_one_line(tension)} N"
                    )
        _, arr = _compiled_statics(self)[0](x, force, tension)
        poses = {
            st: (arr[:9, j].reshape(3, 3, order="F"), arr[9:, j])
            for j, st in enumerate(self.stations())
        }
        return x, poses

    def _newton(self, force: FloatArray, tension: FloatArray, k0: FloatArray) -> FloatArray | None:
        """The base curvature (rad/m) meeting the tip condition, by Newton steps from
        ``k0`` halved until the residual's norm falls; None where a step cannot lower
        it or the iterations run out before it is below :data:`TIP_CONDITION_TOL`."""
        fn = _compiled_statics(self)[1]  # the tip condition
        x = k0.copy()
        r, J = fn(x, force, tension)
        norm = float(np.linalg.norm(r))
        for _ in range(NEWTON_ITERATIONS):
            if not np.isfinite(norm):
                return None
            if norm < TIP_CONDITION_TOL:
                return x
            step = np.linalg.lstsq(J, r.ravel(), rcond=None)[0]
            alpha = 1.0
            while alpha > 1e-6:
                trial = x - alpha * step
                rt, Jt = fn(trial, force, tension)
                nt = float(np.linalg.norm(rt))
                if nt < (1.0 - 1e-4 * alpha) * norm:
                    x, r, J, norm = trial, rt, Jt, nt
                    break
                alpha *= 0.5
            else:
                return None
        return x if norm < TIP_CONDITION_TOL else None

    def backbone_points(
        self,
        force: FloatArray,
        tension: FloatArray,
        points_per_section: int = 16,
        k0: FloatArray | None = None,
    ) -> FloatArray:
        """The backbone at equilibrium under the tip force ``force`` (N, base frame) and
        the tensions ``tension`` (N): ``(n_sections * points_per_section + 1, 3)`` m,
        from the base (the origin) to the tip, evenly spaced along each section (for
        drawing; the points also end the integration's steps, so the curve is at least
        as fine as the estimators' model). ``k0``: where :meth:`solve` starts (the
        equilibrium nearest a neighbouring row's, where the loads hold more than one)."""
        k0, _ = self.solve(force, tension, k0)
        points, _, _ = _compiled_drawing(self, points_per_section)(k0, force, tension)
        return np.vstack([np.zeros(3), points.T])

    @lru_cache(maxsize=4)  # noqa: B019 (a frozen dataclass: the cache keeps it alive)
    def drawing_function(self, points_per_section: int) -> ca.Function:
        """``(k0, F, tau) -> (points, imu_rotations, imu_positions)``: the backbone at
        ``points_per_section`` evenly spaced points a section after the base, (3,
        n_sections * points_per_section) m, and each IMU's disk frame (9, n_imus; a
        column-major body-to-base rotation, the twist included) and place (3, n_imus) m,
        from the base curvature ``k0`` (rad/m), the tip force ``F`` (N) and the tensions
        ``tau`` (N)."""
        dense = tuple(
            Station(k, j / points_per_section)
            for k in range(self.robot.n_sections)
            for j in range(1, points_per_section + 1)
        )
        imus = tuple(Station(i.section, i.at) for i in self.robot.imus)
        k0, force = ca.SX.sym("k0", 3), ca.SX.sym("F", 3)
        tau = ca.SX.sym("tau", self.robot.n_tendons)
        poses, _ = self.shoot(k0, force, tau, dense + imus)
        points = ca.horzcat(*(poses[st][1] for st in dense))
        rotations = ca.horzcat(*(ca.vec(poses[st][0]) for st in imus))
        places = ca.horzcat(*(poses[st][1] for st in imus))
        return ca.Function("tendon_drawing", [k0, force, tau], [points, rotations, places])


def swing_twist_sym(Q: Sym) -> tuple[Sym, Sym, Sym]:
    """``(theta, phi, psi)`` of a relative rotation ``Q``: the bend (the tangent
    ``Q e3 = (-cos phi sin theta, -sin phi sin theta, cos theta)``, the PCC
    convention) and the twist ``psi`` about the tangent, rad (``Q = R(theta, phi)
    Rz(psi)`` with ``R(theta, phi)`` the twist-free PCC rotation); ``phi`` is 0 where
    the section is straight (its tangent along ``e3``), as the PCC formulations write it."""
    t = Q[:, 2]
    theta = ca.atan2(ca.sqrt(t[0] ** 2 + t[1] ** 2), t[2])
    straight = ca.logic_and(t[0] == 0, t[1] == 0)  # atan2(-0, -0) would give -pi
    phi = ca.atan2(ca.if_else(straight, 0.0, -t[1]), ca.if_else(straight, 1.0, -t[0]))
    psi = 2 * ca.atan2(Q[1, 0] - Q[0, 1], 1 + Q[0, 0] + Q[1, 1] + Q[2, 2])
    return theta, phi, psi


class _CompiledFunction:
    """A CasADi SX function evaluated by the compiled core (CasADi's values to the last
    bit, without its per-call overhead): called with numeric arguments, it returns
    its outputs as dense float arrays of their shapes."""

    def __init__(self, fn: ca.Function) -> None:
        self._core = tape_function(fn)
        self._name = fn.name()
        self._sizes = [int(fn.nnz_in(i)) for i in range(fn.n_in())]
        self._shapes = [fn.size_out(i) for i in range(fn.n_out())]
        self._ends = np.cumsum([0] + [r * c for r, c in self._shapes])

    def __call__(self, *args: FloatArray) -> list[FloatArray]:
        """The outputs at ``args`` (one array per input, of its size).

        Raises:
            ValueError: if the arguments are not one per input, each of its size."""
        flat = [np.ascontiguousarray(np.asarray(a, dtype=float).ravel(order="F")) for a in args]
        if [len(a) for a in flat] != self._sizes:
            raise ValueError(
                f"{self._name}: arguments of sizes {[len(a) for a in flat]}, not {self._sizes}"
            )
        out = np.empty(int(self._ends[-1]))
        self._core.evaluate(flat, out)
        return [
            out[a:b].reshape(shape, order="F")
            for a, b, shape in zip(self._ends[:-1], self._ends[1:], self._shapes)
        ]


@lru_cache(maxsize=8)
def _compiled_statics(statics: TendonStatics) -> tuple[_CompiledFunction, _CompiledFunction]:
    """:attr:`TendonStatics.function` and its tip condition, evaluated by the core."""
    function, tip_condition = _statics_functions(statics)
    return _CompiledFunction(function), _CompiledFunction(tip_condition)


@lru_cache(maxsize=8)
def _compiled_drawing(statics: TendonStatics, points_per_section: int) -> _CompiledFunction:
    """:meth:`TendonStatics.drawing_function`, evaluated by the core."""
    return _CompiledFunction(statics.drawing_function(points_per_section))


@lru_cache(maxsize=8)
def _statics_functions(statics: TendonStatics) -> tuple[ca.Function, ca.Function]:
    """``(function, tip condition)`` of :class:`TendonStatics`, one pair for all statics
    equal to ``statics`` (frozen dataclasses compared by value)."""
    function = statics._build_function()
    k0, force = ca.SX.sym("k0", 3), ca.SX.sym("F", 3)
    tau = ca.SX.sym("tau", statics.robot.n_tendons)
    res, _ = function(k0, force, tau)
    return function, ca.Function("tip_condition", [k0, force, tau], [res, ca.jacobian(res, k0)])
