"""
The compiled core of continuum-mhe: model evaluation, MHE solver, filters.
"""

from collections.abc import Sequence
import enum
from typing import Annotated, overload

import numpy
from numpy.typing import NDArray


class ModelFunction:
    """
    A model evaluation of the compiled core: flat column-major inputs to all outputs concatenated.
    """

    @property
    def output_size(self) -> int:
        """Number of values written (all outputs concatenated)."""

    def evaluate(self, inputs: Sequence[Annotated[NDArray[numpy.float64], dict(shape=(None,), order='C', device='cpu', writable=False)]], out: Annotated[NDArray[numpy.float64], dict(shape=(None,), order='C', device='cpu')]) -> None:
        """Evaluate on flat column-major ``inputs``; all outputs into ``out``."""

def share_tape(code: Annotated[NDArray[numpy.int32], dict(shape=(None, 4), order='C', device='cpu', writable=False)], constants: Annotated[NDArray[numpy.float64], dict(shape=(None,), order='C', device='cpu', writable=False)]) -> tuple[Annotated[NDArray[numpy.int32], dict(shape=(None, 4))], int]:
    """
    ``(code, work_size)``: the tape ``code`` (rows ``(op, res, a, b)``) with every value computed once and only the values an output needs, its work slots reassigned (csrc/tape.hpp); the constants are unchanged.
    """

class TapeFunction(ModelFunction):
    """One CasADi SX function read as a tape."""

    def __init__(self, code: Annotated[NDArray[numpy.int32], dict(shape=(None, 4), order='C', device='cpu', writable=False)], constants: Annotated[NDArray[numpy.float64], dict(shape=(None,), order='C', device='cpu', writable=False)], input_sizes: Sequence[int], output_sizes: Sequence[int], work_size: int) -> None: ...

    @property
    def instructions(self) -> int: ...

class WindowFunction(ModelFunction):
    """The MHE window's residuals and Jacobians."""

    @overload
    def __init__(self, meas: TapeFunction, proc: TapeFunction, horizon: int) -> None: ...

    @overload
    def __init__(self, residual: TapeFunction, sr_size: int, proc: TapeFunction, horizon: int) -> None:
        """
        From the residual's tape ``(x, z) -> r`` alone: its Jacobian by forward-mode derivatives, the second-order term zero (``sr_size`` entries per node).
        """

class TailFunction(ModelFunction):
    """A window's last node and its incoming stage."""

    @overload
    def __init__(self, meas: TapeFunction, proc: TapeFunction) -> None: ...

    @overload
    def __init__(self, residual: TapeFunction, sr_size: int, proc: TapeFunction) -> None:
        """From the residual's tape alone, as WindowFunction's."""

class ResidualNodeFunction(ModelFunction):
    """
    ``(x, u, dt, z, m) -> (f, F, H, r)`` (or ``(H, r)`` without the transition) from the transition's tape and the residual's, ``H`` by forward-mode derivatives (csrc/forward.hpp).
    """

    def __init__(self, transition: TapeFunction, residual: TapeFunction, with_transition: bool) -> None: ...

class RememberedFunction(ModelFunction):
    """
    A model function with its last evaluations remembered, per thread (the last two of any such function on that thread): an evaluation at the same inputs, bit for bit, copies the outputs kept. ``input_sizes``: the number of values of each input.
    """

    def __init__(self, function: ModelFunction, input_sizes: Sequence[int]) -> None: ...

    @property
    def hits(self) -> int:
        """The evaluations answered from those kept, on every thread."""

class MaskedResidualFunction(ModelFunction):
    """
    ``(x, u, dt, z, m) -> m * r(x, z)`` from the residual's tape ``(x, z) -> r``.
    """

    def __init__(self, residual: TapeFunction) -> None: ...

class ForwardJacobianFunction(ModelFunction):
    """
    ``x -> dy/dx`` (ny, nx), column-major, of a tape ``x -> y``, by forward-mode derivatives (csrc/forward.hpp).
    """

    def __init__(self, function: TapeFunction) -> None: ...

def uses_vector_sin_cos() -> bool:
    """
    Whether the batched model evaluations take sin and cos four at a time from glibc's vector math library (within 4 ulp of the C library's; csrc/vector_math.hpp).
    """

def sin_cos_rows(x: Annotated[NDArray[numpy.float64], dict(shape=(None,), order='C', device='cpu', writable=False)]) -> tuple[list[float], list[float]]:
    """
    ``(sin(x), cos(x))`` as the batched model evaluations compute them (``x`` 1-D).
    """

OPERATIONS: tuple = ...

class SqpResult:
    """The outcome of one window solve (WindowSolver.solve)."""

    @property
    def outcome(self) -> int:
        """
        0 converged (certified), else the failure (continuum_mhe's OUTCOMES order).
        """

    @property
    def iterations(self) -> int:
        """SQP iterations taken."""

    @property
    def step(self) -> float:
        """
        The last QP step's largest entry, each state's weighted by its step_scale.
        """

    @property
    def cost(self) -> float:
        """The window cost at the last evaluated iterate."""

    @property
    def buffer(self) -> int:
        """The buffer (0 or 1) of Xb holding the answer."""

class WindowSolver:
    """
    The fast MHE's window solve for one window model: its buffers (NumPy views, row-major) and the SQP over them (continuum_mhe.estimators.fast.sqp).
    """

    def __init__(self, horizon: int, nx: int, nz: int, nu: int, window: ModelFunction | None, tail: ModelFunction | None, lo: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], hi: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ball_idx: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], ball_r2: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rinv: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], blocks: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], loss_code: int, loss_scale: float, linear_transition: bool, block_cols: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)] | None = None, block_robust: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)] | None = None) -> None:
        """
        ``block_cols`` (nblocks,): the number of leading state coordinates each measurement block's residual depends on at most (its Jacobian rows are zero beyond them, and its second-order term outside that leading square, which is all the window's outputs hold of it); nx each where None. ``block_robust`` (nblocks,): 1 where the loss acts on the block, 0 where the block's cost is quadratic whatever the loss; 1 each where None. ``window`` and ``tail`` (a WindowFunction and a TailFunction; None: the caller writes the outputs ``out`` itself) are kept alive with the solver.
        """

    def solve(self, qinv: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], xbar: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], arrival: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], lam: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], max_iter: int, step_tol: float, err_tol: float, max_qp_iter: int, newton: bool, quadratic: bool, evaluated: bool = False, shifted: int = -1) -> SqpResult:
        """
        The SQP from Xb[0] with the window data in z, m, u, dt: an SqpResult; lam (N, nb) in and out.
        """

    def evaluate(self, buf: int, qinv: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], xbar: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], arrival: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> float:
        """
        Evaluate the model at Xb[buf] and assemble its blocks (Gauss-Newton Dgn, E, g, ...): the window cost (inf if the model failed).
        """

    def assemble(self, buf: int, qinv: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], xbar: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], arrival: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], shifted_from: int = -1) -> float:
        """
        Assemble buffer buf's Gauss-Newton blocks, gradient, robust weights and node costs from out[buf] at Xb[buf]; with shifted_from >= 0, from that buffer's assembly shifted by one node (Dgn, E, g, ...) where the shift applies. The cost.
        """

    def shift_outputs(self, src: int, dst: int) -> bool:
        """
        out[dst]: out[src] without its first node and stage, then the tail function's outputs at Xb[0]'s last stage; False if the tail function failed.
        """

    @property
    def z(self) -> NDArray[numpy.float64]: ...

    @property
    def m(self) -> NDArray[numpy.float64]: ...

    @property
    def u(self) -> NDArray[numpy.float64]: ...

    @property
    def dt(self) -> NDArray[numpy.float64]: ...

    @property
    def step_scale(self) -> NDArray[numpy.float64]:
        """
        (nx,) what a unit of each state counts for in the certificate's max-norm (the QP step and its error bound): ones unless set (a rate's, the time over which its error moves the angle it is the rate of)
        """

    @property
    def Xb(self) -> NDArray[numpy.float64]: ...

    @property
    def out(self) -> NDArray[numpy.float64]: ...

    @property
    def D(self) -> NDArray[numpy.float64]: ...

    @property
    def E(self) -> NDArray[numpy.float64]: ...

    @property
    def Dgn(self) -> NDArray[numpy.float64]: ...

    @property
    def g(self) -> NDArray[numpy.float64]: ...

    @property
    def d(self) -> NDArray[numpy.float64]: ...

    @property
    def lam_qp(self) -> NDArray[numpy.float64]: ...

    @property
    def wgt(self) -> NDArray[numpy.float64]: ...

    @property
    def extra(self) -> NDArray[numpy.float64]: ...

    @property
    def gb(self) -> NDArray[numpy.float64]: ...

    @property
    def ncost(self) -> NDArray[numpy.float64]: ...

    @property
    def stage_done(self) -> NDArray[numpy.int64]: ...

    @property
    def stage_eq(self) -> NDArray[numpy.float64]: ...

    @property
    def stage_fqf(self) -> NDArray[numpy.float64]: ...

    @property
    def tail_out(self) -> NDArray[numpy.float64]: ...

    @property
    def window_size(self) -> int: ...

    @property
    def watchdog(self) -> bool:
        """
        A rejected full step gets one more Gauss-Newton step from its trial point before it is shortened (for models without the second-order term).
        """

    @watchdog.setter
    def watchdog(self, arg: bool, /) -> None: ...

def last_block_covariance(X: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], D: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], E: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], lo: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], hi: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ball_idx: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], ball_r2: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], tol: float, out: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], condition_balls: bool = True) -> bool:
    """
    Into out (nx, nx): the last diagonal block of H^-1 for H = (D, E), conditioned on the bounds active at X (n, nx) within tol (the balls only where condition_balls); False if the reduced Hessian is not positive definite.
    """

def btd_solve(D: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], E: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], b: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], y: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> bool:
    """
    Solve H y = b for the symmetric block-tridiagonal H = (D, E) (diagonal blocks D (n, nx, nx), super-diagonal E (n-1, nx, nx)) by block Cholesky; False if H is not positive definite.
    """

def btd_solve_two_ended(D: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], E: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], b: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], y: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], generic: bool = False) -> bool:
    """
    As btd_solve, eliminating from both ends towards the middle node (the QP's Newton system without active constraints); False if H is not positive definite. ``generic``: the kernel for a block size read at run time, not the one specialised for nx (the same operations in the same order: the same bits).
    """

def householder(nrm: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], idx: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], T: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> int:
    """
    Symmetric orthogonal T with T nrm = -+e_c for a unit normal on the coordinates idx; returns the pivot c.
    """

def solve_qp(X: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], D: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], E: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], g: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], lo: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], hi: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ball_idx: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], ball_r2: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], max_it: int, d: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], lam: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> tuple[int, int, int]:
    """
    Active-set solution d of min 1/2 d^T H d + g^T d s.t. lo <= X + d <= hi and the balls linearised at X: (status, iterations, active constraints); lam (n, nb) the ball multipliers.
    """

def project(X: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], lo: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], hi: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ball_idx: Annotated[NDArray[numpy.int64], dict(order='C', device='cpu', writable=False)], ball_r2: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> None:
    """
    Project each row of X onto the box and the balls, in place (the bounds hold exactly).
    """

def rho_derivatives(code: int, scale: float, s: float) -> tuple[float, float, float]:
    """
    (rho(s), rho'(s), rho''(s)) of the robust loss ``code`` (loss.LOSS_CODES).
    """

def dense_mul(A: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], B: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], out: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> None:
    """out = A B, written out."""

def dense_cholesky(A: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], L: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> bool:
    """
    Lower Cholesky factor L of a symmetric A; False if A is not positive definite.
    """

def dense_inverse_gram(L: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], out: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> None:
    """out = (L L^T)^-1 for a lower-triangular L."""

class NodeModel:
    """
    One node of a model: its EKF step, the arrival prior's step, and the outputs with their standard deviations. Matrices row-major.
    """

    def __init__(self, transition: ModelFunction, measurement: ModelFunction, output: ModelFunction, output_jacobian: ModelFunction, nx: int, nu: int, nz: int, ny: int, wrapped: Sequence[int], sigma_states: Sequence[int] = []) -> None: ...

    def evaluate(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], u: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], dt: float, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
        """
        ``(f, F, H, r)`` at one node: the transition, its Jacobian, ``H = -dr/dx`` and the masked residual.
        """

    def arrival_step(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], u: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], dt: float, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], R: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], Q: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
        """The arrival prior's EKF step: ``(x+, P+, P+^-1)``."""

    def ekf_step_outputs(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], u: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], dt: float, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], R: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], Q: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
        """
        One EKF step, then the outputs and their standard deviations: ``(x+, P+, y, std)``.
        """

    @property
    def log_likelihood(self) -> float:
        """
        The last EKF step's innovation log-density, ``-(r^T S^-1 r + log|S|) / 2`` (its constant left out); NaN where the step had no valid reading. With ``likelihood_given`` rows: the other components' density given those (the whole density less theirs), NaN where theirs has no Cholesky factor.
        """

    @property
    def likelihood_given(self) -> list[int]:
        """
        The measurement components (0-based rows) on which ``log_likelihood`` is conditioned; empty (the default): the whole innovation's density.
        """

    @likelihood_given.setter
    def likelihood_given(self, arg: Sequence[int], /) -> None: ...

    @property
    def step_seconds(self) -> float:
        """
        Wall time of the last ``ekf_step_outputs`` call's arithmetic (the step, the outputs and their standard deviations; not its arrays' conversion), s.
        """

    def output(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """The outputs of state ``x`` (wrapped angles in [-pi, pi))."""

    def output_std(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """
        One standard deviation of each output for state ``x`` with covariance ``P``: the root mean square of the outputs' change over the sigma points on ``sigma_states`` (given), else ``sqrt(diag(J P J^T))``, J the output Jacobian at x.
        """

def ekf_update(x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], r: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], H: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], R: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
    """EKF measurement update, Joseph form: ``(x+, P+)`` with ``H = -dr/dx``."""

class UnscentedFilter:
    """
    The UKF's predict and update with Van der Merwe's scaled sigma points, on a node model's transition ``(x, u, dt, z, m) -> (f, F)`` and masked residual ``(x, u, dt, z, m) -> m r(z, x)``. Matrices row-major. Each call returns ``(x, P, failure, message)``: ``failure`` 0, or 1 (no Cholesky factor, a singular innovation covariance) or 2 (a tilt reading about a half turn from the sigma points' tilts), with ``x`` and ``P`` then unchanged.
    """

    def __init__(self, transition: ModelFunction, residual: ModelFunction, nx: int, nu: int, nz: int, alpha: float, beta: float, kappa: float, chart_rows: Sequence[int], names: Sequence[str]) -> None: ...

    def predict(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], u: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], dt: float, Q: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> tuple:
        """The prediction with ``(u, dt)`` and process noise ``Q``."""

    def update(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], R: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], check_chart: bool) -> tuple:
        """
        The update with the valid components of ``z`` (``mask`` > 0), noise ``R``; ``check_chart``: refuse a valid tilt reading whose residuals differ by more than pi across the sigma points.
        """

class ConsistencyCheck:
    """
    The consistency of one estimator's estimates with its readings, every sample (continuum_mhe.estimators.consistency). Matrices row-major.
    """

    def __init__(self, transition: ModelFunction, measurement: ModelFunction, residual: ModelFunction, nx: int, nu: int, nz: int, R: Sequence[float], judged: Sequence[float], limit: Sequence[float], run_limit: Sequence[float], avg_limit: Sequence[float], shift_limit: Sequence[float], bias: Sequence[float], gravity_r: Sequence[float], memory: int, quiet_memory: int, rcond: float, model_error_floor: float, range_info: Sequence[float] = []) -> None:
        """
        Functions of ``(x, u, dt, z, m)``: ``transition -> (f, F = df/dx)``, ``measurement -> (H = -dr/dx, r)``, ``residual -> r``; ``R`` (nz x nz, row-major); ``judged`` (nz): 1 for a reading, 0 for a pseudo-measurement; ``limit``, ``run_limit``, ``avg_limit`` (nz + 1): the chi-square limits by the number of judged readings; ``shift_limit`` (nx + 1): the chi-square limits of the shift to the readings' shape by its degrees of freedom; ``bias`` (nz): the readings' constant-error variances; ``gravity_r`` (nz): R's diagonal on the gravity directions, else 0; ``memory``: samples the average remembers; ``quiet_memory``: samples the average while no model error shows remembers; ``rcond``: the pseudo-inverse's cut-off; ``model_error_floor``: each gravity-direction reading's model-error variance (rad^2) assumed until the one learned exceeds it; ``range_info`` (nx, or empty: none): each state's range as information 1 / std^2 (0: unbounded), added to ``H^T R^-1 H`` in the constant errors' sensitivity.
        """

    def set_own_acceleration(self, velocity: ModelFunction, error: ModelFunction, span: float) -> None:
        """
        The IMUs' own acceleration as a model error of the gravity-direction readings (continuum_mhe.model.imu_motion): ``velocity(x)`` 3 values per IMU, ``error(x, a)`` nz values; the velocities differenced over ``span`` s.
        """

    def note_motion(self, t: float, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> None:
        """
        This sample's estimate: the IMUs' acceleration and its reading errors, which constant_error_cov then carries.
        """

    def forget_motion(self) -> None:
        """The IMUs' motion starts again at the next note_motion."""

    def reset(self) -> None:
        """Forget the previous estimate, the average and the model error."""

    def forget(self) -> None:
        """A sample without an estimate: forget the previous estimate."""

    def check(self, t: float, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], u: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], Q: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> bool:
        """
        Whether this sample's estimate disagrees with its readings; remembers it. ``u`` (nu) and ``Q`` (nx x nx): the inputs and process noise from the previous sample, read only when there is one (else empty).
        """

    def constant_error_cov(self, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """
        ``A B A^T`` (nx, nx) at ``x``: the covariance from the readings' constant errors and the model error learned so far.
        """

    @property
    def noise_scale(self) -> float:
        """The exponentially weighted mean of NIS / dof (1 before any)."""

    @property
    def quiet_scale(self) -> float:
        """
        The slower mean of NIS / dof while no model error showed (1 before any): the level a model error that showed must fall back to.
        """

    @property
    def model_error(self) -> float:
        """
        The largest noise_scale - 1 beyond its limit since the reset, in units of R (settable: a model error known beforehand).
        """

    @model_error.setter
    def model_error(self, arg: float, /) -> None: ...

    @property
    def nis(self) -> float:
        """The last sample's NIS (0 if none)."""

    @property
    def fit(self) -> float:
        """The last sample's fit (0 if not judged)."""

    @property
    def fit_nis(self) -> float:
        """
        The NIS of the innovation the last sample's fit implies, (R^-1 r)^T S (R^-1 r) (0 without a previous estimate).
        """

    @property
    def shift(self) -> float:
        """
        The shift that fits the last sample's readings in its covariance, d^T P^+ d (computed only where fit_nis is beyond its limit and the shift test is on, some shift_limit finite; else 0).
        """

    @property
    def dof(self) -> int:
        """The last sample's judged readings."""

def pinv_symmetric(a: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], rcond: float) -> NDArray[numpy.float64]:
    """
    The pseudo-inverse of the symmetric matrix ``a`` from its eigendecomposition, eigenvalues at most ``rcond`` times the largest in magnitude taken as zero.
    """

class StepOutcome(enum.IntEnum):
    """Outcomes of MovingHorizon.step (csrc/horizon.hpp)."""

    NO_ESTIMATE = 0
    """The window is not full yet and paper_start holds the estimate."""

    DONE = 1
    """Solved, certified and kept: the answer is returned."""

    SOLVED = 2
    """Solved and certified, not kept: finish follows."""

    UNCERTIFIED = 3
    """The SQP did not certify its answer: the caller solves the window."""

class MovingHorizon:
    """
    The fast MHE's per-sample step over one WindowSolver and NodeModel: the window's buffers (NumPy views, row-major, aligned at the end), the arrival prior's slide, the warm start, the SQP, the last node's covariance and the outputs (csrc/horizon.hpp).
    """

    def __init__(self, solver: WindowSolver, node: NodeModel, R: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], robust: bool, paper_start: bool, max_iter: int, step_tol: float, err_tol: float, max_qp_iter: int, newton: bool, quadratic: bool) -> None: ...

    def restart(self) -> None:
        """Forget the window, prior and answers."""

    def set_prior(self, xbar: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], Pinv: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> None:
        """Set the arrival prior (xbar, P, P^-1)."""

    def step(self, t: float, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], u: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], Q: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], Qinv: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], finish: bool) -> tuple:
        """
        One sample (push, slide, warm start, solve; keep when certified and finish): (a StepOutcome, (state, cov, y, std) when the answer was kept (DONE), else None).
        """

    def finish(self, X: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], solved: bool, w_new: object | None, failed: bool) -> tuple:
        """
        Keep X (N, nx) as the answer (solved: the last step's certified one): (state, cov, y, std), cov and std None when failed or not positive definite.
        """

    def node_weights(self, i: int, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]:
        """Robust weights rho'(s_b) of window node i at state x."""

    @property
    def k(self) -> int:
        """Samples in the window."""

    @property
    def iterations(self) -> int:
        """SQP iterations of the last solve."""

    @property
    def solve_seconds(self) -> float:
        """
        Wall time of the last step's window solve, s (0 when it solved none; the Python hooks add their solves' to it).
        """

    @solve_seconds.setter
    def solve_seconds(self, arg: float, /) -> None: ...

    @property
    def step_seconds(self) -> float:
        """
        Wall time of the last sample's step and finish, s: the prior's slide, the warm start, the step's own window solve, the covariance and the outputs with their standard deviations (not the solves of Python hooks between the two; 0 for a sample that stepped no window).
        """

    @property
    def cost(self) -> float:
        """Window cost at the last certified solve's last iterate (NaN if none)."""

    @property
    def solved(self) -> bool:
        """Whether the last step solved the window (from X0 and lam0)."""

    @property
    def plausible_limit(self) -> NDArray[numpy.float64]:
        """
        The branch check's first test in the step ((n nz + 1,) or empty: none): a certified answer whose twice window cost is at most entry [dof] (the window's valid measurement components) is kept by the step although finish is false.
        """

    @plausible_limit.setter
    def plausible_limit(self, arg: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], /) -> None: ...

    @property
    def past_lag(self) -> int:
        """
        Answers of full windows the robust loss's second start keeps (0: none); setting it forgets them.
        """

    @past_lag.setter
    def past_lag(self, arg: int, /) -> None: ...

    @property
    def keep_unrejected(self) -> bool:
        """
        Whether the step keeps a certified answer itself when the window is not yet full or no weight of its newest node is below outlier_weight (remembering it); other answers are the caller's.
        """

    @keep_unrejected.setter
    def keep_unrejected(self, arg: bool, /) -> None: ...

    @property
    def outlier_weight(self) -> float:
        """The robust weight below which a block counts as rejected."""

    @outlier_weight.setter
    def outlier_weight(self, arg: float, /) -> None: ...

    @property
    def past_count(self) -> int:
        """Answers of full windows kept, at most past_lag."""

    def remember(self, X: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> None:
        """Keep X (N, nx) as the newest past answer (dropping the oldest)."""

    def forget_past(self) -> None:
        """Forget the past answers."""

    def past_oldest(self) -> NDArray[numpy.float64]:
        """A copy of the oldest past answer kept (N, nx)."""

    @property
    def plausible_kept(self) -> int:
        """Answers kept by plausible_limit since the owner last zeroed it."""

    @plausible_kept.setter
    def plausible_kept(self, arg: int, /) -> None: ...

    @property
    def has_prior(self) -> bool: ...

    @has_prior.setter
    def has_prior(self, arg: bool, /) -> None: ...

    @property
    def has_X(self) -> bool: ...

    @has_X.setter
    def has_X(self, arg: bool, /) -> None: ...

    @property
    def outputs_at_last(self) -> int: ...

    @outputs_at_last.setter
    def outputs_at_last(self, arg: int, /) -> None: ...

    @property
    def has_X_last(self) -> bool: ...

    @has_X_last.setter
    def has_X_last(self, arg: bool, /) -> None: ...

    @property
    def has_lam(self) -> bool: ...

    @has_lam.setter
    def has_lam(self, arg: bool, /) -> None: ...

    @property
    def tw(self) -> NDArray[numpy.float64]: ...

    @property
    def zw(self) -> NDArray[numpy.float64]: ...

    @property
    def zmask(self) -> NDArray[numpy.float64]: ...

    @property
    def dt(self) -> NDArray[numpy.float64]: ...

    @property
    def uw(self) -> NDArray[numpy.float64]: ...

    @property
    def qw(self) -> NDArray[numpy.float64]: ...

    @property
    def qinvw(self) -> NDArray[numpy.float64]: ...

    @property
    def arrival(self) -> NDArray[numpy.float64]: ...

    @property
    def xbar(self) -> NDArray[numpy.float64]: ...

    @property
    def P(self) -> NDArray[numpy.float64]: ...

    @property
    def Pinv(self) -> NDArray[numpy.float64]: ...

    @property
    def X(self) -> NDArray[numpy.float64]: ...

    @property
    def X_last(self) -> NDArray[numpy.float64]: ...

    @property
    def X0(self) -> NDArray[numpy.float64]: ...

    @property
    def X_sol(self) -> NDArray[numpy.float64]: ...

    @property
    def lam(self) -> NDArray[numpy.float64]: ...

    @property
    def lam0(self) -> NDArray[numpy.float64]: ...

    @property
    def w_first(self) -> NDArray[numpy.float64]: ...

    @property
    def w_last(self) -> NDArray[numpy.float64]: ...

    @property
    def cov_free(self) -> NDArray[numpy.float64]: ...

    @property
    def cov_free_ok(self) -> bool:
        """
        Whether the last answer's node sits on a bending bound: cov_free (nx, nx) is then its covariance not conditioned on that bound.
        """

STATUS_NAMES: tuple = ...

class InputProblem(enum.IntEnum):
    """A sample the policy refuses (csrc/sensor_health.hpp's InputError)."""

    OK = 0
    """Accepted."""

    TIME = 1
    """t not finite, or not later than the previous sample's."""

    DEGREES = 2
    """
    A tilt reading beyond degrees_like (just over pi): degrees given for radians.
    """

    INFINITE = 3
    """An infinite reading."""

class PolicyStep:
    """One sample's answer of SensorHealth.step."""

    @property
    def input_error(self) -> InputProblem:
        """InputProblem.OK (0) when the sample was accepted, else its problem."""

    @property
    def status(self) -> int:
        """The status, an index into STATUS_NAMES."""

    @property
    def state(self, /) -> NDArray[numpy.float64] | None:
        """The state (nx,), or None."""

    @property
    def covariance(self, /) -> NDArray[numpy.float64] | None:
        """The state covariance (nx, nx), or None."""

    @property
    def output(self, /) -> NDArray[numpy.float64] | None:
        """The outputs (ny,), or None."""

    @property
    def output_std(self, /) -> NDArray[numpy.float64] | None:
        """The outputs' standard deviations (ny,), or None."""

    @property
    def outlier(self) -> bool:
        """The robust MHE down-weighted this sample."""

    @property
    def frozen(self) -> bool:
        """A sensor counts as frozen at this sample."""

    @property
    def diagnostics_changed(self) -> bool:
        """The sample changed a count of SensorHealth.diagnostics."""

    @property
    def solve_ms(self) -> float:
        """Wall time spent on this sample, ms."""

class PolicyDiagnostics:
    """
    What the policy did since its last reset (continuum_mhe.results.Diagnostics).
    """

    @property
    def restarts(self) -> int:
        """Restarts after a divergence or numerical failure."""

    @property
    def gap_resets(self) -> int:
        """Restarts after a gap."""

    @property
    def frozen_samples(self) -> int:
        """Samples with at least one IMU counted as frozen."""

    @property
    def first_freezes(self) -> list[tuple[int, float]]:
        """
        Each IMU's first freeze, [(its block index among the IMUs, t s)], in order.
        """

    @property
    def bad_starts(self) -> int:
        """Restarts after a bad start (an IMU back from a silence included)."""

    @property
    def reject_resets(self) -> int:
        """Restarts after the robust MHE rejected every reading for too long."""

    @property
    def drift_resets(self) -> int:
        """
        Restarts from the last ok estimate's sensor states after rows drifted for drift_reset s.
        """

    @property
    def late_imu_starts(self) -> int:
        """
        Restarts at the first reading of an IMU that had not read since the last (re)start, beside every IMU that had.
        """

    @property
    def jump_resets(self) -> int:
        """
        Restarts after a jump in t shorter than the gap reset whose readings disagreed with the prediction across it.
        """

    @property
    def first_jump_t(self) -> float:
        """t (s) of the sample after the first such jump (NaN: none)."""

    @property
    def first_jump_step(self) -> float:
        """The first such jump's length, s (NaN: none)."""

    @property
    def last_failure(self) -> str | None:
        """The last numerical failure's description, or None."""

    @property
    def bound_samples(self) -> int:
        """Estimates of status at-bound."""

    @property
    def max_noise_scale(self) -> float:
        """
        The largest model-error factor seen (the innovations' variance over the noise model's; 1 when the readings fit their noise).
        """

    @property
    def model_error(self) -> float:
        """The largest model error learned, in units of R (0 when none showed)."""

    @property
    def bad_start_chains(self) -> int:
        """
        Times the bad-start check stopped restarting after a chain of restarts.
        """

    @property
    def untrusted_start_samples(self) -> int:
        """Estimates of a start the inference did not trust (none of them ok)."""

    @property
    def glitches(self) -> int:
        """
        IMU readings skipped as glitches (far beyond the prediction from an ok estimate).
        """

class StateChecks:
    """
    A formulation's checks of a state as data (csrc/sensor_health.hpp): diverged, at its bound, drifted.
    """

    def __init__(self, nx: int, pairs: Sequence[tuple[int, int]], diverged_r2: Sequence[float], at_bound_r: Sequence[float], rate_rows: Sequence[int], rate_limit: float, std_rows: Sequence[int], std_limit2: float, flags: TapeFunction | None = None) -> None:
        """
        ``pairs``: the bend coordinates (i, j) of each section, with the squared radius beyond which it diverged and the radius at which it is at its bound; ``rate_rows`` held to ``rate_limit`` in magnitude; ``std_rows`` whose variance beyond ``std_limit2`` is a divergence; ``flags(x) -> (diverged, at_bound, drifted)``, a TapeFunction of the state whose nonzero values say so (none: nothing drifts).
        """

    def is_diverged(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], P: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)] | None) -> bool:
        """Whether the state (and covariance) diverged."""

    def at_bound(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> bool:
        """Whether a section's bend is at its bound."""

    def drifted(self, x: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> bool:
        """Whether the state is not one the model holds (``flags``)."""

class CompiledInputs:
    """
    A model's inputs u(z_prev, z, dt) in compiled code (csrc/sensor_health.hpp): zero where there is no previous reading or either reading has a value not finite.
    """

    def __init__(self, fn: TapeFunction, nz: int, nu: int) -> None:
        """``fn(z_prev, z, dt) -> u``, a TapeFunction."""

    @property
    def nz(self) -> int:
        """Readings per sample."""

    @property
    def nu(self) -> int:
        """Inputs."""

    def __call__(self, z_prev: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)] | None, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], dt: float) -> list[float]:
        """
        u (nu,) from the previous reading ``z_prev`` (None: none) to ``z``, ``dt`` s apart.
        """

class ProcessNoise:
    """
    A formulation's process noise Q(dt) and its inverse, from the tape of its covariance (csrc/process_noise.hpp); the policy and the inferences take it without Python.
    """

    def __init__(self, q: TapeFunction, nx: int, held: Sequence[int], fallback: object) -> None:
        """
        ``q``: dt (s) -> Q (nx, nx); ``held``: states whose rows and columns of Q and Q^-1 are zero; ``fallback(dt) -> (Q, Q^-1)`` where Q is not positive definite (it must not refer back to this object: the garbage collector does not see it).
        """

    def __call__(self, dt: float) -> tuple:
        """``(Q, Q^-1)`` (nx, nx each) of a step of ``dt`` s."""

    @property
    def nx(self) -> int: ...

    @property
    def python_calls(self) -> int:
        """
        Calls of this object from Python (the compiled steps compute without them).
        """

class HorizonInference:
    """
    The fast MHE's inference for the compiled policy: the window step in compiled code, the Python inference only for its hooks (csrc/bind_sensor_health.cpp).
    """

    def __init__(self, horizon: MovingHorizon, inference: object, finish: bool, robust: bool, outlier_weight: float, process_noise: object, inputs: object) -> None:
        """
        ``horizon``: the inference's MovingHorizon; ``finish``: keep certified answers in the step (no Python hooks); ``robust``: outlier flags below ``outlier_weight``; ``process_noise(dt) -> (Q, Q^-1)``, ``inputs(z_prev | None, z, dt) -> u``.
        """

class KalmanInference:
    """
    The compiled EKF's or UKF's inference for the compiled policy: each step, its outputs and standard deviations in compiled code, the Python inference only for the first sample and restarts (csrc/bind_sensor_health.cpp).
    """

    def __init__(self, node: NodeModel, inference: object, R: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], process_noise: object, inputs: object, unscented: UnscentedFilter | None = None) -> None:
        """
        ``node``: the filter's NodeModel (its outputs, and the EKF's step); ``inference``: its hooks (``restart(kept_x, kept_P, kept_t)``, ``first(t, z)``, ``formulation``, ``nu``); ``R`` (nz, nz); ``process_noise(dt) -> (Q, Q^-1)``, ``inputs(z_prev | None, z, dt) -> u``; ``unscented``: the UKF's steps (an UnscentedFilter) instead of the EKF's.
        """

    def log_likelihoods(self, t: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], mask: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], ll: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')]) -> None:
        """
        Step the EKF, without the policy, over the readings ``z`` (n, nz) at ``t`` (n,) s with the validity ``mask`` (n, nz: 1 where a component is valid), writing each sample's innovation log-density ``-(r^T S^-1 r + log|S|) / 2`` into ``ll`` (n,): NaN for a start, a sample without a valid reading, and one whose step failed or left a non-finite state, after which the filter starts again from the next sample (``ll`` a C-contiguous float64 array, written in place). Runs without the GIL but for the filter's Python hooks (a start, a restart); on the main thread a signal whose handler raises ends it.
        """

class SensorHealth:
    """
    The sensor-health policy of an estimator (continuum_mhe.estimators.sensor_health): step one sample, or run a recording into arrays, in compiled code (csrc/sensor_health.hpp).
    """

    def __init__(self, inference: object, consistency: ConsistencyCheck, nx: int, nu: int, nz: int, ny: int, blocks: Sequence[tuple[int, int]], imu_blocks: Sequence[tuple[int, int]], tilt_rows: Sequence[int], tip_rows: Sequence[int], freeze: float, freeze_samples: int, gap_reset: float, bad_start: float, reject_reset: float, uncertain_fraction: float, length: float, checks_start: bool, shape_observable: bool, start_limit: Sequence[float], start_samples: int, start_chain: int, unobserved_after: float, degrees_like: float, whole_rows: Sequence[int], process_noise: object, inputs: object, observable: object, checks: StateChecks | None, change_rows: Sequence[int] = [], change_scale: Sequence[float] = [], change_psd: Sequence[float] = [], change_limit: Sequence[float] = [], change_lag: float = 0.0, confirm_samples: int = 5, std_limit: Sequence[float] = [], jump_hold: bool = False, freeze_tolerance: Sequence[float] = [], silent_after: float = float('inf'), glitch_factor: float = 0.0, drift_reset: float = float('nan'), whole_gap_reset: float = float('nan'), free_pairs: Sequence[tuple[int, int]] = [], free_reach: Sequence[float] = [], wrapped_outputs: Sequence[int] = [], bound_std_limit: Sequence[float] = [], judges_reach: bool = False, free_of: object | None = None) -> None:
        """
        ``inference``: a HorizonInference, or a Python inference adapter; ``consistency``: the estimator's ConsistencyCheck; ``blocks``, ``imu_blocks``: (start, size) of every measurement block and of the IMUs'; ``whole_rows``: rows without which a sample is a dropout as a whole; settings in s and rad, NaN where off; ``process_noise(dt) -> (Q, Q^-1)``, ``inputs(z_prev | None, z, dt) -> u``, ``observable(imus) -> bool``; ``free_of(imus) -> [(row, row, reach)]`` (None: none): the bends those IMUs alone leave free, while the others are silent; ``checks``: the formulation's StateChecks (None: the inference's is_diverged, drifted and at_bound); ``change_rows``, ``change_scale``, ``change_psd``, ``change_limit``, ``change_lag``: the estimate-change test of slowly varying states (rows, prior std, white-noise density per s, chi-square limit by dof from index 1, lag s; no rows: off); ``confirm_samples``: readings that must agree with an unconfirmed start once one disagreed with it; ``std_limit`` (ny, or empty: none): each output's largest standard deviation, half the width of its range (inf: no range); ``bound_std_limit``: the same for an estimate held on a bending bound (empty: std_limit); ``jump_hold``: rows within the unobserved window of a reading beyond one sample's limit are uncertain; ``freeze_tolerance`` (nz, or empty: 0): how far a reading may move from a freeze's first one and still repeat it; ``silent_after`` (s): an IMU silent for longer no longer observes its part of the shape (inf: the unobserved window); ``glitch_factor``: an IMU's reading beyond this many times the one-sample limit against the prediction from an ok estimate is skipped as a glitch (0: off); ``drift_reset`` (s, NaN: off): rows drifted for longer since the last ok one restart the estimate from that one's sensor states; ``whole_gap_reset`` (s, NaN: off): a valid sample after samples without the whole rows for longer restarts as after a gap; ``free_pairs`` (bend pairs of state rows), ``free_reach`` (rad, one per pair), ``wrapped_outputs``: the sections whose bend the IMUs leave free; each written standard deviation carries the rms of the outputs' moves over shapes of those bends spread evenly over their reach (empty: none).
        """

    def reset(self, keep_counts: bool, keep_sensors: bool) -> None:
        """
        A new recording (diagnostics zeroed unless keep_counts; the last estimate's sensor states kept for the next start with keep_sensors and keep_counts).
        """

    def step(self, t: float, z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> PolicyStep:
        """One sample: a PolicyStep."""

    def run(self, t: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], z: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], status: Annotated[NDArray[numpy.int32], dict(order='C', device='cpu')], ms: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], outlier: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu')], frozen: Annotated[NDArray[numpy.uint8], dict(order='C', device='cpu')], y: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], ystd: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu')], should_stop: object | None = None) -> tuple[int, InputProblem]:
        """
        Step the samples ``t`` (n), ``z`` (n, nz) into the arrays (status codes, ms, outlier and frozen flags, outputs and their std, NaN where none); stops at the first refused sample: (its index, its InputProblem), or where ``should_stop()`` (asked before the first sample and then about every 10 ms) says True: (the samples stepped, InputProblem.OK); else (n, InputProblem.OK).
        """

    def check_idle(self) -> None:
        """
        A RuntimeError where another thread steps this policy now (before a change of its settings).
        """

    @property
    def last_t(self) -> float:
        """The last accepted sample's time, s (-inf after a reset)."""

    @property
    def diagnostics(self) -> PolicyDiagnostics:
        """The counts since the last reset, a PolicyDiagnostics (a copy)."""

def estimate_lines(t: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], output: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], output_std: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)], estimated: Annotated[NDArray[numpy.uint8], dict(shape=(None,), order='C', device='cpu', writable=False)], outlier: Annotated[NDArray[numpy.uint8], dict(shape=(None,), order='C', device='cpu', writable=False)] | None, status: Sequence[str], solve_ms: Annotated[NDArray[numpy.float64], dict(order='C', device='cpu', writable=False)]) -> str:
    """
    The estimate CSV lines of ``n`` samples: ``t`` (n) s, ``output`` and ``output_std`` (n, ny), ``estimated`` (n, uint8: 0 leaves the row's outputs and standard deviations empty), ``outlier`` (n, uint8; None: no such column), ``status`` (n names), ``solve_ms`` (n); numbers as ``%.10g``, a non-finite standard deviation empty. ValueError for a non-finite time, solve time or estimated output.
    """
