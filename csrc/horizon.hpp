// The fast MHE's per-sample step (continuum_mhe.estimators.mhe): the window's buffers
// and the sample's push, the arrival prior's slide (an EKF step on the prior), the warm
// start (the previous answer shifted, its last node predicted), the window solve
// (sqp.hpp), the covariance of the last node (covariance.hpp) and the outputs with their
// standard deviations (filter.hpp), in one call per sample.
//
// The window is aligned at its end: sample i of n, stage i joins samples i and i+1.
// Before n samples exist the active nodes are the last k; the leading inactive nodes
// are pinned to the prior (arrival weight I) and carry no other cost.
#pragma once

#include <cstdint>
#include <vector>

#include "covariance.hpp"
#include "filter.hpp"
#include "sliding_rows.hpp"
#include "sqp.hpp"

namespace cmhe {

// Outcomes of MovingHorizon::step
enum StepOutcome : int {
  STEP_NO_ESTIMATE = 0,  // the window is not full yet and paper_start holds the estimate
  STEP_DONE = 1,         // solved, certified, kept: state, covariance and outputs are set
  STEP_SOLVED = 2,       // solved and certified, not kept (finish follows)
  STEP_UNCERTIFIED = 3,  // the SQP did not certify its answer (the caller solves again)
};

class MovingHorizon {
 public:
  // ``solver`` and ``node`` of one window model (kept by the caller); ``R`` (nz, nz) the
  // measurement covariance; ``robust``: a robust loss (weights kept per solve, the
  // leaving sample's update at its weight); ``paper_start``: no estimate before n samples
  MovingHorizon(WindowSolver& solver, NodeModel& node, std::vector<double> R, bool robust,
                bool paper_start, const SqpOptions& options);

  // forget the window, the prior and the previous answer
  void restart();
  // the arrival prior (xbar, P, P^-1), as at a start or a re-anchoring
  void set_prior(const double* xbar, const double* P, const double* Pinv);

  // One sample: push (t, z, mask; the stage's input u and process noise Q, Q^-1), slide
  // the prior when the window was full, form the warm start, then (unless paper_start
  // holds the estimate) solve; when certified and ``finish``, keep the answer with its
  // covariance and outputs (STEP_DONE). Throws std::runtime_error if the prior's step
  // meets a singular matrix.
  int step(double t, const double* z, const double* mask, const double* u, const double* Q,
           const double* Qinv, bool finish);
  // Keep ``X`` (n, nx) as the answer: ``solved`` when it is the last step's certified
  // answer (its last iterate becomes the next warm start and its Gauss-Newton blocks
  // give the covariance), ``w_new`` (nblk) the newest node's robust weights when known
  // (else nullptr), ``failed``: no covariance. Sets state, covariance and outputs.
  void finish(const double* X, bool solved, const double* w_new, bool failed);
  // robust weights rho'(s_b) (nblk) of window node i at state x
  void node_weights(Index i, const double* x, double* w);

  WindowSolver& solver;
  NodeModel& node;
  Index n, nx, nz, nu, nblk, nb, ny;
  bool robust, paper_start;
  SqpOptions options;

  // the window (aligned at the end), with its arrival weights and the prior
  Index k = 0;
  std::vector<double> tw, zw, zmask, dt, uw, arrival, xbar, P, Pinv;
  SlidingRows qw, qinvw;  // (n-1, nx, nx) each
  bool has_prior = false;
  // the previous answer, the SQP's last iterate when that answer was its certified one
  // (the next warm start), the ball multipliers, and this sample's warm start
  // (and the multipliers it started from)
  std::vector<double> X, X_last, lam, X0, lam0;
  bool has_X = false, has_X_last = false, has_lam = false;
  // the solver's buffer whose model outputs are those at X_last and the window's data
  // (the next step's warm start shifts them and evaluates only the new node: the
  // window's tail function), -1 when none is
  int outputs_at_last = -1;
  // the buffer of the last step's last iterate when it stopped before finish
  // (STEP_SOLVED), and the solver's generation then (finish keeps that buffer's outputs
  // for the next step if the solver was not used in between)
  int solved_buffer = -1;
  uint64_t solved_generation = 0;
  // robust weights of the first and last node of the last answer
  std::vector<double> w_first, w_last;
  // the last solve: SQP iterations; when certified, its answer, last iterate and that
  // iterate's Gauss-Newton blocks
  bool solved = false;  // the last step solved the window
  Index iterations = 0;
  double solve_seconds = 0.0;  // the last solve's wall time, s
  // the last sample's wall time in step and finish (the prior's slide, the warm start,
  // the step's own window solve, the covariance and the outputs with their standard
  // deviations; not the solves of Python hooks between the two), s
  double step_seconds = 0.0;
  // the window cost at the last solve's last evaluated iterate when it was certified
  // (NaN otherwise): the branch check's measure of the window's fit
  double cost = 0.0;
  std::vector<double> X_sol, X_last_sol, D_sol, E_sol;
  // The branch check's first test (continuum_mhe.estimators.branch), empty when none
  // applies: a certified answer whose twice window cost is at most
  // plausible_limit[dof] (dof: the window's valid measurement components, entries 0 to
  // n nz) is kept by the step itself (STEP_DONE) although ``finish`` is false, and
  // counted in plausible_kept (zeroed by its owner, not by restart)
  std::vector<double> plausible_limit;
  uint64_t plausible_kept = 0;
  // The robust loss's second start (continuum_mhe.estimators.second_start) keeps the
  // answers of the last ``past_lag`` full windows (0: none kept) in ``past``; a window not
  // yet full forgets them. With ``keep_unrejected`` the step keeps a certified answer
  // itself (STEP_DONE, although ``finish`` is false) when the window is not yet full, or
  // when every robust weight of its newest node is at least ``outlier_weight`` (nothing
  // for the second start to try), remembering it; other answers are the caller's, who
  // remembers the one it keeps (remember).
  Index past_lag = 0;
  bool keep_unrejected = false;
  double outlier_weight = 0.0;
  void set_past_lag(Index lag);
  void remember(const double* Xk);
  void forget_past() { past_count = past_next_ = 0; }
  Index past_count = 0;
  // the oldest answer kept (n, nx); valid while past_count > 0
  const double* past_oldest() const;
  // the kept answer's last node, its covariance and outputs
  std::vector<double> state, cov, y, ystd;
  bool cov_ok = false;
  // where the last node sits on a bending bound: the covariance not conditioned on it
  // (for the standard deviations written; cov, conditioned, is the checks')
  std::vector<double> cov_free;
  bool cov_free_ok = false;

 private:
  // step without its timing
  int step_body(double t, const double* z, const double* mask, const double* u,
                const double* Q, const double* Qinv, bool finish);
  void push(double t, const double* z, const double* mask, const double* u, const double* Q,
            const double* Qinv);
  void slide();
  void warm_start();
  void form_arrival();
  void load(const double* Xs, bool slid);
  void keep_outputs(const double* X, const double* D, const double* E, bool failed,
                    const double* w_new);
  bool keeps_unrejected(const double* Xa, double* w_new);
  std::vector<double> R_, Rl_, scale_, zmask_nodes_, past_, w_new_;
  Index past_next_ = 0;
  std::vector<int64_t> block_of_;
  CovarianceScratch cov_scratch_;
};

}  // namespace cmhe
