// The MHE window solve: Newton-type SQP with a projected line search (sqp.cpp).
//
// Each iteration evaluates the whole window's model in one call of its window function
// (residuals, Jacobians and the measurement residuals' second-order term; layout of
// continuum_mhe.estimators.fast.window_functions.window_function), assembles the block-tridiagonal
// Hessian of the Lagrangian (Gauss-Newton J^T W J, plus the exact second-order term
// where that keeps it positive definite, plus 2 lam_b I on the coordinates of each ball
// b with a positive multiplier), and solves the QP subproblem (qp.hpp). Iterates stay
// exactly feasible (projection). See docs/fast-solver.md.
#pragma once

#include <cstdint>
#include <vector>

#include "model_function.hpp"
#include "qp.hpp"
#include "sliding_rows.hpp"

namespace cmhe {

// Robust losses (continuum_mhe.estimators.loss.LOSS_CODES): (rho, rho', rho'') at s
void rho_derivatives(int code, double scale, double s, double& rho, double& rho1,
                     double& rho2);

struct SqpOptions {
  Index max_iter = 30;
  double step_tol = 1e-8;
  double err_tol = 1e-8;
  Index max_qp_iter = 500;
  bool newton = true;     // add the measurement residuals' second-order term
  bool quadratic = false; // certify by Newton's quadratic rate (sqp.py's quadratic_rate)
};

struct SqpResult {
  int outcome;
  Index iterations;
  double step, cost;
  int buffer;  // the buffer holding the answer
};

// The per-window problem data: the process weights, the arrival prior
struct WindowData {
  const double* qinv;     // (n-1, nx, nx)
  const double* xbar;     // (nx,)
  const double* arrival;  // (n, nx, nx)
};

// Buffers and fixed data of the window solve of one window model. Two iterate buffers
// (current and trial): Xb (2, n, nx), the model outputs ``out`` (2, window_size; the
// window function's layout), the Gauss-Newton diagonal blocks Dgn and the QP's D (Dgn
// with the balls' curvature and the exact Newton term), the off-diagonal blocks E and
// gradient g, the
// robust-loss weights (wgt, extra, gb; see assemble) and node costs of each.
class WindowSolver {
 public:
  // ``window`` and ``tail`` must outlive the solver; a null ``window``: only assembly from
  // outputs written by the caller (evaluate returns an infinite cost)
  WindowSolver(Index horizon, Index nx, Index nz, Index nu, const ModelFunction* window,
               const ModelFunction* tail, std::vector<double> lo, std::vector<double> hi,
               std::vector<int64_t> ball, Index ball_size, std::vector<double> ball_r2,
               std::vector<double> rinv, std::vector<int64_t> blocks, int loss_code,
               double loss_scale, bool linear_transition, std::vector<int64_t> block_cols = {},
               std::vector<int64_t> block_robust = {});

  // The SQP from Xb[0] on the two buffers (current, trial); lam (n, nb) in: the
  // multipliers of the ball curvature, out: at the answer. Dgn[b] keeps the Gauss-Newton
  // diagonal blocks of buffer b's iterate (E[b] are its off-diagonal ones): on
  // certification the other buffer holds the last evaluated iterate X_k, whose blocks
  // give the answer's covariance.
  //
  // Steps and errors are measured in the max-norm weighted by step_scale.
  // Certified when the QP step d is below step_tol, or, with no constraint active, when
  // the observed contraction rho = |d_k| / |d_k-1| <= 1/2 of two full steps bounds the
  // error of X_k + d_k by rho / (1 - rho) |d_k| <= err_tol; when both steps were exact
  // Newton steps, by the smaller quadratic-rate estimate safety |d_k|^3 / |d_k-1|^2 (the
  // error K |d_k|^2 with the rate K = |d_k| / |d_k-1|^2 observed on the previous step),
  // if ``quadratic`` and neither QP had an active constraint. The answer is then the
  // projection of X_k + d_k (not evaluated again); the cost is at X_k. ``evaluated``: out[0] already holds the model's outputs at Xb[0]
  // (shift_outputs); ``shifted >= 0`` (with ``evaluated``): Xb[0] is buffer
  // ``shifted``'s iterate of the previous window shifted by one node, whose assembly
  // shifts with it. ``zmask`` (n,): 0 where a node has no measurement.
  SqpResult solve(const WindowData& data, const double* zmask, double* lam,
                  const SqpOptions& opt, bool evaluated, int shifted);
  // Evaluate the model at Xb[buf] and assemble (its Gauss-Newton blocks Dgn[buf], E[buf],
  // gradient g[buf], ...); the cost (inf if the model failed)
  double evaluate(int buf, const WindowData& data, const double* zmask);
  // Assemble buffer buf's blocks from out[buf] at Xb[buf] (shifted from buffer ``prev``'s
  // assembly where prev >= 0, see sqp.cpp's assemble); the cost
  double assemble(int buf, const WindowData& data, const double* zmask, int prev);
  // out[dst]: the outputs at Xb[0]'s iterate shifted by one node from out[src] (the
  // previous window's, may be dst) and the tail function at Xb[0]'s last stage
  bool shift_outputs(int src, int dst);
  // The stage products (affine transition) moved by one stage, as the window's data
  // slide by one sample: stage i takes stage i + 1's, the new last stage is formed anew
  void shift_stages();
  // 1 where the node's measurement mask m has a nonzero entry
  void node_mask(double* zmask) const;

  Index n, nx, nz, nu, nblk, nb, bk, window_size;
  // counts the calls that write the model outputs or the assembly (solve, evaluate,
  // assemble, shift_outputs): a caller that kept a buffer's outputs knows whether they
  // are still there
  uint64_t generation = 0;
  const ModelFunction* window;  // the whole window's outputs (WindowFunction)
  const ModelFunction* tail;    // one new last node's (TailFunction), or null
  std::vector<double> lo, hi, ball_r2, rinv;
  std::vector<int64_t> ball, blocks;
  // per measurement block (nblk): its residual depends on the first block_cols[b] state
  // coordinates at most, so that its Jacobian rows are zero beyond them and its
  // second-order term outside its leading block_cols[b] x block_cols[b] block, which is
  // all the model's outputs hold of it (a node's blocks one after the other from
  // sr_start[b], sr_size in all); the assembly's and the curvature's products run over
  // those (nx each where not given)
  std::vector<int64_t> block_cols, sr_start;
  Index sr_size;
  int loss_code;
  // per measurement block (nblk): the loss code its cost takes, loss_code where the
  // block is robust (a sensor's reading), the quadratic loss (0) where it is not (a
  // model's pseudo-measurement, an input given with the sample)
  std::vector<int> block_loss;
  // Gauss-Newton steps on stiff rows (a model without the second-order term, whose
  // weighted rows are far more nonlinear than the rest): a full step that the line
  // search rejects gets one more Gauss-Newton step from its trial point, and their sum
  // is tried against the same sufficient decrease before the step is shortened (a
  // watchdog: the full step overshoots such rows to second order, which the next step
  // corrects; shortening it instead creeps)
  bool watchdog = false;
  // (nx,) what a unit of each state counts for in the certificate's max-norm (the QP
  // step and the error bound): 1 for an angle (rad); a rate's error (rad/s) counts as
  // the angle it moves over a time (s) its model gives. Ones by default.
  std::vector<double> step_scale;
  double loss_scale;
  bool linear;

  // window data and the solve's buffers (shapes in bind_solver.cpp)
  std::vector<double> z, m, u, dt, Xb, out, D, E, g, d, lam_qp, wgt, extra, gb, Dgn, ncost;
  std::vector<int64_t> stage_done;  // (n-1,) for an affine transition, else empty
  SlidingRows stage_eq, stage_fqf;  // (n-1, nx, nx) each, as stage_done
  std::vector<double> tail_out;
  std::vector<const double*> ptrs, tail_ptrs;  // the model's argument pointers

  Feasible feasible() const {
    return {lo.data(), hi.data(), ball.data(), ball_r2.data(), nb, bk};
  }

  // scratch
  QPScratch qp;
  std::vector<double> wr, wj, qw, qf, e, acc, eql, fqfl, d_kept, lam_kept;
};

}  // namespace cmhe
