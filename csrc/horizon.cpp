// The fast MHE's per-sample step (horizon.hpp).
#include "horizon.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>


namespace cmhe {

namespace {

// rows [0, rows - 1) of a (rows, row) array take rows [1, rows): the window slides by one
void shift_up(std::vector<double>& a, Index rows, Index row) {
  if (rows > 1) std::memmove(a.data(), a.data() + row, (rows - 1) * row * sizeof(double));
}

// Tolerance of the bounds conditioned on in the covariance (covariance.hpp)
constexpr double kActiveTol = 1e-6;

}  // namespace

MovingHorizon::MovingHorizon(WindowSolver& solver_, NodeModel& node_, std::vector<double> R,
                             bool robust_, bool paper_start_, const SqpOptions& options_)
    : solver(solver_), node(node_), n(solver_.n), nx(solver_.nx), nz(solver_.nz),
      nu(solver_.nu), nblk(solver_.nblk), nb(solver_.nb), ny(node_.ny()), robust(robust_),
      paper_start(paper_start_), options(options_), R_(std::move(R)) {
  if (node.nx() != nx || node.nz() != nz)
    throw std::invalid_argument("the node model and the window solver differ in size");
  if (Index(R_.size()) != nz * nz) throw std::invalid_argument("R is not (nz, nz)");
  const Index bs = nx * nx;
  tw.assign(n, 0.0);
  zw.assign(n * nz, 0.0);
  zmask.assign(n * nz, 0.0);
  dt.assign(n - 1, 1.0);
  uw.assign((n - 1) * nu, 0.0);
  qw.assign(n - 1, bs, 0.0);
  qinvw.assign(n - 1, bs, 0.0);
  arrival.assign(n * bs, 0.0);
  xbar.assign(nx, 0.0);
  P.assign(bs, 0.0);
  Pinv.assign(bs, 0.0);
  X.assign(n * nx, 0.0);
  X_last.assign(n * nx, 0.0);
  X0.assign(n * nx, 0.0);
  lam0.assign(n * nb, 0.0);
  lam.assign(n * nb, 0.0);
  w_first.assign(nblk, 1.0);
  w_last.assign(nblk, 1.0);
  w_new_.assign(nblk, 1.0);
  X_sol.assign(n * nx, 0.0);
  X_last_sol.assign(n * nx, 0.0);
  D_sol.assign(n * bs, 0.0);
  E_sol.assign((n - 1) * bs, 0.0);
  state.assign(nx, 0.0);
  cov.assign(bs, 0.0);
  cov_free.assign(bs, 0.0);
  y.assign(ny, 0.0);
  ystd.assign(ny, 0.0);
  Rl_.assign(nz * nz, 0.0);
  zmask_nodes_.assign(n, 0.0);
  scale_.assign(nz, 1.0);
  block_of_.assign(nz, nblk);
  for (Index b = 0; b < nblk; ++b)
    for (Index a = 0; a < solver.blocks[2 * b + 1]; ++a) block_of_[solver.blocks[2 * b] + a] = b;
  restart();
}

void MovingHorizon::restart() {
  k = 0;
  cov_ok = cov_free_ok = false;
  std::fill(tw.begin(), tw.end(), 0.0);
  std::fill(zw.begin(), zw.end(), 0.0);
  std::fill(zmask.begin(), zmask.end(), 0.0);
  std::fill(dt.begin(), dt.end(), 1.0);
  std::fill(uw.begin(), uw.end(), 0.0);
  qw.fill(0.0);
  qinvw.fill(0.0);
  std::fill(arrival.begin(), arrival.end(), 0.0);
  has_prior = has_X = has_X_last = has_lam = solved = false;
  cost = 0.0;
  outputs_at_last = -1;
  iterations = 0;
  solve_seconds = step_seconds = 0.0;
  std::fill(w_first.begin(), w_first.end(), 1.0);
  std::fill(w_last.begin(), w_last.end(), 1.0);
  forget_past();
}

void MovingHorizon::set_prior(const double* xbar_, const double* P_, const double* Pinv_) {
  std::copy(xbar_, xbar_ + nx, xbar.begin());
  std::copy(P_, P_ + nx * nx, P.begin());
  std::copy(Pinv_, Pinv_ + nx * nx, Pinv.begin());
  has_prior = true;
}

void MovingHorizon::push(double t, const double* z, const double* mask, const double* u,
                         const double* Q, const double* Qinv) {
  const Index bs = nx * nx;
  if (k == n) slide();
  shift_up(tw, n, 1);
  shift_up(zw, n, nz);
  shift_up(zmask, n, nz);
  shift_up(dt, n - 1, 1);
  shift_up(uw, n - 1, nu);
  qw.slide();
  qinvw.slide();
  tw[n - 1] = t;
  for (Index j = 0; j < nz; ++j) {
    zmask[(n - 1) * nz + j] = mask[j];
    zw[(n - 1) * nz + j] = mask[j] > 0.0 ? z[j] : 0.0;
  }
  double* ul = uw.data() + (n - 2) * nu;
  double* ql = qw.data() + (n - 2) * bs;
  double* qil = qinvw.data() + (n - 2) * bs;
  if (k) {
    dt[n - 2] = t - tw[n - 2];
    std::copy(u, u + nu, ul);
    std::copy(Q, Q + bs, ql);
    std::copy(Qinv, Qinv + bs, qil);
  } else {
    dt[n - 2] = 1.0;
    std::fill(ul, ul + nu, 0.0);
    std::fill(ql, ql + bs, 0.0);
    std::fill(qil, qil + bs, 0.0);
  }
  k = std::min(k + 1, n);
}

// The arrival prior moves from window sample 0 to sample 1: an EKF update of (xbar, P)
// with the sample that leaves (at its weight in the last solve with a robust loss:
// R_b / w_b per block), then the prediction to the next sample; xbar projected.
void MovingHorizon::slide() {
  const double* R = R_.data();
  if (robust) {
    double* scale = scale_.data();  // per component: 1 / w of its block (1 outside blocks)
    for (Index a = 0; a < nz; ++a)
      scale[a] = block_of_[a] < nblk ? 1.0 / std::max(w_first[block_of_[a]], 1e-12) : 1.0;
    for (Index a = 0; a < nz; ++a)
      for (Index b = 0; b < nz; ++b)
        Rl_[a * nz + b] = R_[a * nz + b] * std::sqrt(scale[a] * scale[b]);
    R = Rl_.data();
  }
  if (!node.arrival_step(xbar.data(), P.data(), Pinv.data(), nu ? uw.data() : nullptr, dt[0],
                         zw.data(), zmask.data(), R, qw.data()))
    throw std::runtime_error("singular matrix in the arrival prior's step");
  project(1, nx, xbar.data(), solver.feasible());
}

void MovingHorizon::warm_start() {
  if (!has_X) {
    for (Index i = 0; i < n; ++i) std::copy(xbar.begin(), xbar.end(), X0.begin() + i * nx);
    return;
  }
  const double* prev = has_X_last ? X_last.data() : X.data();
  std::copy(prev + nx, prev + n * nx, X0.begin());
  const double step = k > 1 ? tw[n - 1] - tw[n - 2] : 0.0;
  node.predict(prev + (n - 1) * nx, nu ? uw.data() + (n - 2) * nu : nullptr, step);
  std::copy(node.node_out(), node.node_out() + nx, X0.begin() + (n - 1) * nx);
  project(1, nx, X0.data() + (n - 1) * nx, solver.feasible());
}

// pinned identity before the first active node, P^-1 on it, 0 after
void MovingHorizon::form_arrival() {
  const Index bs = nx * nx, off = n - k;
  for (Index i = 0; i < off; ++i) {
    double* a = arrival.data() + i * bs;
    std::fill(a, a + bs, 0.0);
    for (Index j = 0; j < nx; ++j) a[j * nx + j] = 1.0;
  }
  const Index stop = std::min(off + 2, n);
  std::fill(arrival.begin() + off * bs, arrival.begin() + stop * bs, 0.0);
  std::copy(Pinv.begin(), Pinv.end(), arrival.begin() + off * bs);
}

// the window's data and the iterate Xs into the solver's buffer 0; stage products anew,
// or (``slid``: the solver's stage products are those of the previous sample's window)
// shifted by one stage with the window's data
void MovingHorizon::load(const double* Xs, bool slid) {
  std::copy(zw.begin(), zw.end(), solver.z.begin());
  std::copy(zmask.begin(), zmask.end(), solver.m.begin());
  std::copy(uw.begin(), uw.end(), solver.u.begin());
  std::copy(dt.begin(), dt.end(), solver.dt.begin());
  std::copy(Xs, Xs + n * nx, solver.Xb.begin());
  if (slid)
    solver.shift_stages();
  else
    std::fill(solver.stage_done.begin(), solver.stage_done.end(), 0);
  solver.node_mask(zmask_nodes_.data());
}

namespace {
double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

int MovingHorizon::step(double t, const double* z, const double* mask, const double* u,
                        const double* Q, const double* Qinv, bool finish_) {
  const auto entered = std::chrono::steady_clock::now();
  step_seconds = 0.0;
  const int outcome = step_body(t, z, mask, u, Q, Qinv, finish_);
  step_seconds = seconds_since(entered);
  return outcome;
}

int MovingHorizon::step_body(double t, const double* z, const double* mask, const double* u,
                             const double* Q, const double* Qinv, bool finish_) {
  if (!has_prior) throw std::logic_error("the arrival prior is not set");
  solve_seconds = 0.0;
  solved = false;
  const int reusable = has_X && has_X_last ? outputs_at_last : -1;
  outputs_at_last = -1;
  push(t, z, mask, u, Q, Qinv);
  warm_start();
  has_X_last = false;
  if (paper_start && k < n) {
    X = X0;
    has_X = true;
    return STEP_NO_ESTIMATE;
  }
  form_arrival();
  // the previous sample's solve was this solver's, kept as it was (STEP_DONE): its stage
  // products, model outputs and assembly at its last iterate slide with the window
  load(X0.data(), reusable >= 0);
  if (has_lam) {  // the previous multipliers, shifted by one node
    std::memmove(lam.data(), lam.data() + nb, (n - 1) * nb * sizeof(double));
    std::fill(lam.begin() + (n - 1) * nb, lam.end(), 0.0);
  } else {
    std::fill(lam.begin(), lam.end(), 0.0);
  }
  std::copy(lam.begin(), lam.end(), lam0.begin());
  solved = true;
  const WindowData data{qinvw.data(), xbar.data(), arrival.data()};
  const auto start = std::chrono::steady_clock::now();
  // the warm start's nodes but the last are the last iterate's, shifted: so are their
  // model outputs (each node's depend on its own state and data only)
  const bool evaluated = reusable >= 0 && solver.tail != nullptr && solver.shift_outputs(reusable, 0);
  const SqpResult r = solver.solve(data, zmask_nodes_.data(), lam.data(), options, evaluated,
                                   evaluated ? reusable : -1);
  solve_seconds = seconds_since(start);
  iterations = r.iterations;
  cost = r.outcome == CONVERGED ? r.cost : std::numeric_limits<double>::quiet_NaN();
  if (r.outcome != CONVERGED) {
    has_lam = false;
    return STEP_UNCERTIFIED;
  }
  has_lam = true;
  const Index bs = nx * nx, last = 1 - r.buffer;
  const double* Xa = solver.Xb.data() + r.buffer * n * nx;
  const double* Xl = solver.Xb.data() + last * n * nx;
  const double* D = solver.Dgn.data() + last * n * bs;
  const double* E = solver.E.data() + last * (n - 1) * bs;
  if (!finish_ && !plausible_limit.empty()) {
    double dof = 0.0;
    for (double v : zmask) dof += v;
    const Index d = Index(dof);
    if (d >= 0 && d < Index(plausible_limit.size()) && 2.0 * r.cost <= plausible_limit[d]) {
      finish_ = true;
      ++plausible_kept;
    }
  }
  const double* w_new = nullptr;
  if (!finish_ && keep_unrejected && keeps_unrejected(Xa, w_new_.data())) {
    finish_ = true;
    if (k == n) w_new = w_new_.data();
  }
  if (!finish_) {
    solved_buffer = int(last);
    solved_generation = solver.generation;
    std::copy(Xa, Xa + n * nx, X_sol.begin());
    std::copy(Xl, Xl + n * nx, X_last_sol.begin());
    std::copy(D, D + n * bs, D_sol.begin());
    std::copy(E, E + (n - 1) * bs, E_sol.begin());
    return STEP_SOLVED;
  }
  std::copy(Xl, Xl + n * nx, X_last.begin());
  has_X_last = true;
  outputs_at_last = int(last);
  std::copy(Xa, Xa + n * nx, X.begin());
  has_X = true;
  keep_outputs(X.data(), D, E, false, w_new);
  return STEP_DONE;
}

// A window not yet full: the past answers are forgotten (the second start compares
// full windows only). A full one: the newest node's weights at the answer into w_new;
// true, remembering the answer, when none is below outlier_weight.
bool MovingHorizon::keeps_unrejected(const double* Xa, double* w_new) {
  if (k < n) {
    forget_past();
    return true;
  }
  node_weights(n - 1, Xa + (n - 1) * nx, w_new);
  for (Index b = 0; b < nblk; ++b)
    if (w_new[b] < outlier_weight) return false;
  remember(Xa);
  return true;
}

void MovingHorizon::set_past_lag(Index lag) {
  if (lag < 0 || lag > n) throw std::invalid_argument("past_lag must lie in [0, N]");
  past_lag = lag;
  past_.assign(lag * n * nx, 0.0);
  forget_past();
}

void MovingHorizon::remember(const double* Xk) {
  if (past_lag == 0) return;
  std::copy(Xk, Xk + n * nx, past_.begin() + past_next_ * n * nx);
  past_next_ = (past_next_ + 1) % past_lag;
  past_count = std::min(past_count + 1, past_lag);
}

const double* MovingHorizon::past_oldest() const {
  const Index slot = past_count < past_lag ? 0 : past_next_;
  return past_.data() + slot * n * nx;
}

void MovingHorizon::node_weights(Index i, const double* x, double* w) {
  node.evaluate(x, nu ? uw.data() : nullptr, 0.0, zw.data() + i * nz, zmask.data() + i * nz);
  const double* r = node.node_out() + nx + nx * nx + nz * nx;
  const double* rinv = solver.rinv.data();
  for (Index b = 0; b < nblk; ++b) {
    const Index b0 = solver.blocks[2 * b], size = solver.blocks[2 * b + 1];
    double s = 0.0;
    for (Index a = 0; a < size; ++a)
      for (Index c = 0; c < size; ++c) s += r[b0 + a] * rinv[(b0 + a) * nz + b0 + c] * r[b0 + c];
    double rho, rho1, rho2;
    rho_derivatives(solver.block_loss[b], solver.loss_scale, s, rho, rho1, rho2);
    w[b] = rho1;
  }
}

void MovingHorizon::finish(const double* Xk, bool solved, const double* w_new, bool failed) {
  const auto entered = std::chrono::steady_clock::now();
  if (Xk != X.data()) std::copy(Xk, Xk + n * nx, X.begin());
  has_X = true;
  if (solved) {
    std::copy(X_last_sol.begin(), X_last_sol.end(), X_last.begin());
    has_X_last = true;
    // nothing used the solver since this step's solve: its last iterate's model outputs
    // and assembly are still at hand for the next step
    if (solver.generation == solved_generation) outputs_at_last = solved_buffer;
  }
  keep_outputs(X.data(), solved ? D_sol.data() : nullptr, solved ? E_sol.data() : nullptr,
               failed, w_new);
  step_seconds += seconds_since(entered);
}

// the kept answer's robust weights (robust loss; the newest node's are w_new when
// known), last node, covariance (from the blocks D, E at hand, else evaluated at X with
// this sample's arrival weights) and outputs
void MovingHorizon::keep_outputs(const double* Xk, const double* D, const double* E,
                                 bool failed, const double* w_new) {
  if (robust) {
    node_weights(0, Xk, w_first.data());
    if (w_new)
      std::copy(w_new, w_new + nblk, w_last.begin());
    else
      node_weights(n - 1, Xk + (n - 1) * nx, w_last.data());
  }
  std::copy(Xk + (n - 1) * nx, Xk + n * nx, state.begin());
  cov_ok = cov_free_ok = false;
  if (!failed) {
    if (D == nullptr) {
      load(Xk, false);
      const WindowData data{qinvw.data(), xbar.data(), arrival.data()};
      if (std::isfinite(solver.evaluate(0, data, zmask_nodes_.data()))) {
        D = solver.Dgn.data();
        E = solver.E.data();
      }
    }
    if (D != nullptr)
      cov_ok = last_block_covariance(n, nx, Xk, D, E, solver.feasible(), kActiveTol, cov.data(),
                                     cov_scratch_);
    if (cov_ok && last_node_on_a_ball(n, nx, Xk, solver.feasible(), kActiveTol))
      cov_free_ok = last_block_covariance(n, nx, Xk, D, E, solver.feasible(), kActiveTol,
                                          cov_free.data(), cov_scratch_, false);
  }
  node.output(state.data(), y.data());
  if (cov_ok) node.output_std(state.data(), cov.data(), ystd.data());
}

}  // namespace cmhe
