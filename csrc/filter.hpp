// The EKF step of one node model: the compiled EKF's step and the MHE's arrival prior.
//
// Matrices are row-major (numpy's C order). The node function is
// ``(x, u, dt, z, m) -> (f, F, H, r)``: the transition, its Jacobian (row-major), the
// measurement Jacobian ``H = -dr/dx`` (nz x nx, row-major) and the masked residual
// (continuum_mhe.estimators.fast.window_functions.node_function).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "model_function.hpp"

namespace cmhe {

// Small dense kernels on row-major matrices (btd.hpp's, in this file's argument order,
// and the two it lacks): for the few-by-few matrices of one node a BLAS or LAPACK call
// costs more than its arithmetic.
namespace small {
// C (m x n) = A (m x k) B (k x n)
void mul(const double* A, const double* B, double* C, int m, int k, int n);
// C (m x n) = A (m x k) B^T, B (n x k)
void mul_t(const double* A, const double* B, double* C, int m, int k, int n);
// lower Cholesky factor of A (n x n); false if A is not positive definite
bool cholesky(const double* A, double* L, int n);
// (L L^T)^-1 for a lower-triangular L with a nonzero diagonal
void inverse_gram(const double* L, double* out, int n);
// X (n x m) = A^-1 B by Gaussian elimination with partial pivoting; false if singular
bool solve(const double* A, const double* B, double* X, int n, int m);
}  // namespace small

// EKF measurement update, Joseph form, in place: ``x`` (nx), ``P`` (nx x nx) with the
// residual ``r`` (nz) and ``H = -dr/dx`` (nz x nx); false if ``S`` is singular. With
// ``log_likelihood``: the innovation's log-density ``-(r^T S^-1 r + log|S|) / 2`` (the
// constant left out; NaN where ``S`` has no Cholesky factor).
bool ekf_update(double* x, double* P, const double* r, const double* H, const double* R,
                int nx, int nz, double* log_likelihood = nullptr);
// ``P = F P F^T + Q``, in place
void predict_covariance(double* P, const double* F, const double* Q, int nx);

class NodeModel {
 public:
  // The node function ``(x, u, dt, z, mask) -> (f, F, H, r)`` as two functions of its
  // inputs: ``transition`` its first two outputs ``(f, F)`` (a prediction evaluates no
  // measurement terms), ``measurement`` its last two ``(H, r)``.
  NodeModel(const ModelFunction& transition, const ModelFunction& measurement,
            const ModelFunction& output, const ModelFunction& output_jacobian, int nx, int nu,
            int nz, int ny, std::vector<int64_t> wrapped,
            std::vector<int64_t> sigma_states = {});

  int nx() const { return nx_; }
  int nz() const { return nz_; }
  int ny() const { return ny_; }

  // the node function at (x, u, dt, z, mask); its outputs stay in ``node_out()``
  void evaluate(const double* x, const double* u, double dt, const double* z,
                const double* mask);
  const double* node_out() const { return out_.data(); }
  // the transition alone at (x, u, dt): ``node_out()``'s first nx + nx * nx values
  // (f, F) are set, the rest are left as they were
  void predict(const double* x, const double* u, double dt);

  // the arrival prior's EKF step: update with the valid components of z (none:
  // prediction only), then predict; ``P`` symmetrised, ``Pinv`` its inverse.
  bool arrival_step(double* x, double* P, double* Pinv, const double* u, double dt,
                    const double* z, const double* mask, const double* R, const double* Q);
  // the EKF's step: predict, then update with the valid components of z
  bool ekf_step(double* x, double* P, const double* u, double dt, const double* z,
                const double* mask, const double* R, const double* Q);
  // outputs of x (wrapped angles in [-pi, pi))
  void output(const double* x, double* y);
  // One standard deviation of each output for a state with mean x and covariance P: with
  // ``sigma_states`` (the states the outputs depend on, S), the root mean square of
  // y(X) - y(x) over the 2 s sigma points X = x +- sqrt(s) L e_j, L L^T = P[S, S]
  // (the unscented transform with weights 1 / (2 s); wrapped outputs' differences
  // wrapped): it carries the outputs' curvature, which a straight section's z needs
  // (its first derivative vanishes there). Without them sqrt(diag(J P J^T)) with the
  // output Jacobian J at x. Either evaluates the outputs (or J) at x once for
  // consecutive calls at the same x.
  void output_std(const double* x, const double* P, double* std);

  // wall time of the last ``ekf_step_outputs`` binding call's arithmetic (the step, the
  // outputs and their standard deviations; not its arrays' conversion), s
  double step_seconds = 0.0;
  // the last ``ekf_step``'s innovation log-density (``ekf_update``); NaN where it had no
  // valid reading. With ``likelihood_given`` rows: the density of the other components
  // given those rows (the whole density less the given rows' own), NaN where the given
  // rows' innovation covariance has no Cholesky factor
  double log_likelihood = NAN;
  // the rows (measurement components) on which ``log_likelihood`` is conditioned; none:
  // the whole innovation's density
  std::vector<int64_t> likelihood_given;

 private:
  // the innovation log-density of the ``likelihood_given`` rows alone, with the residual
  // ``r`` and ``H`` at the predicted state and its covariance ``P``; false where their
  // innovation covariance has no Cholesky factor
  bool given_log_density(const double* P, const double* r, const double* H, const double* R,
                         double* out) const;
  void set_sample(const double* u, double dt, const double* z, const double* mask);
  // x into x_, then the node functions' inputs (x, u, dt, z, mask) of the sample set
  std::array<const double*, 5> inputs(const double* x);
  const ModelFunction& transition_;
  const ModelFunction& measurement_;
  const ModelFunction& output_;
  const ModelFunction& jacobian_;
  int nx_, nu_, nz_, ny_;
  std::vector<int64_t> wrapped_;
  std::vector<double> x_, u_, dt_, z_, m_, out_, oout_, jout_, r_, H_;
  void sigma_point_std(const double* x, const double* P, double* std);
  std::vector<double> jx_;  // the state of the output Jacobian in jout_ (or outputs in yx_)
  bool has_jx_ = false;
  std::vector<int64_t> sigma_states_;
  std::vector<char> is_wrapped_;
  // the outputs' tape where ``output`` is one with a single input and output: the sigma
  // points are then evaluated as one batch
  const Tape* output_tape_ = nullptr;
  std::vector<double> yx_, ys_, xs_, Ps_, Ls_, acc_;
};

}  // namespace cmhe
