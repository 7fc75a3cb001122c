// The consistency check of an estimator's estimates with its readings, every sample
// (continuum_mhe.estimators.consistency, whose module doc states the tests): the
// prediction of the previous estimate, the NIS of this reading against it, the fit of
// this reading to this estimate and the NIS of the innovation that fit implies, the
// exponential average of NIS / dof and the model error it shows, and the estimate's
// covariance from the readings' constant errors.
//
// Matrices are row-major (numpy's C order). The model comes as three functions of the
// node's inputs ``(x, u, dt, z, m)`` (continuum_mhe.estimators.fast.window_functions.
// node_function's outputs, each evaluated only where it is needed): the transition
// ``(f, F)``, the measurement ``(H, r)`` and the residual ``r``, with ``F = df/dx``,
// ``H = -dr/dx``; they are evaluated with every reading's mask 1 and the invalid
// readings zero.
#pragma once

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <deque>
#include <vector>

#include "model_function.hpp"

namespace cmhe {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// The storage of pinv_symmetric's eigendecomposition, kept between calls.
struct PinvScratch {
  Eigen::SelfAdjointEigenSolver<RowMatrix> eig;
  Eigen::VectorXd inv_s;
};

// The pseudo-inverse of the symmetric matrix ``a`` from its eigendecomposition, the
// eigenvalues at most ``rcond`` times the largest in magnitude taken as zero (what
// ``numpy.linalg.pinv(a, rcond, hermitian=True)`` computes).
RowMatrix pinv_symmetric(const RowMatrix& a, double rcond);
// The same into ``out``, in the storage of ``scratch``.
void pinv_symmetric(const RowMatrix& a, double rcond, PinvScratch& scratch, RowMatrix& out);

// The fixed data of one formulation's check (sizes nz, or nz + 1 for a limit by the
// number of judged readings, index 0 unused).
struct ConsistencySettings {
  int nx, nu, nz;
  std::vector<double> R;          // nz x nz: the readings' noise covariance
  // nz: 1 for a reading, 0 for a model's pseudo-measurement or a row it reads as an input
  std::vector<double> judged;
  std::vector<double> limit;      // a reading beyond it is inconsistent on its own
  std::vector<double> run_limit;  // two readings in a row beyond it are inconsistent
  // the average of NIS / dof beyond it times the quiet level (the slower average while
  // no model error showed, at most 1) is inconsistent
  std::vector<double> avg_limit;
  // nx + 1, by the shift's degrees of freedom: a fit not explained by a linear update
  // whose shift to the readings' own shape is beyond it is inconsistent
  std::vector<double> shift_limit;
  std::vector<double> bias;       // nz: the readings' constant-error variances (B's diagonal)
  std::vector<double> gravity_r;  // nz: R's diagonal on the gravity directions, 0 elsewhere
  int memory;                     // samples the average of NIS / dof remembers
  int quiet_memory;               // samples the average while no model error shows remembers
  double rcond;                   // the pseudo-inverse's relative eigenvalue cut-off
  // the variance (rad^2) of each gravity-direction reading's model error assumed
  // before the readings show one: the floor under the model error learned
  double model_error_floor = 0.0;
  // nx, or empty (all 0): the information 1 / std^2 of each state's range (the bend
  // bound's), added to H^T R^-1 H in the constant errors' sensitivity, so that a shape
  // the readings barely pin is not shifted beyond the range by them
  std::vector<double> range_info;
};

class ConsistencyCheck {
 public:
  ConsistencyCheck(const ModelFunction& transition, const ModelFunction& measurement,
                   const ModelFunction& residual, ConsistencySettings settings);

  // forget the previous estimate, the average and the model error (a new recording)
  void reset();
  // a sample without an estimate, or a restart: the next one has no previous estimate
  // to predict (the average and the model error stay); the IMUs' motion starts again
  void forget() {
    has_prev_ = false;
    clear_motion();
  }
  // The IMUs' own acceleration as a model error of the gravity-direction readings
  // (continuum_mhe.model.imu_motion): ``velocity(x)`` each IMU's velocity (3 per IMU)
  // and ``error(x, a)`` the residual's change (nz) when the IMUs accelerate at ``a``;
  // the velocities are differenced over ``span`` s. Kept by reference
  void set_own_acceleration(const ModelFunction& velocity, const ModelFunction& error,
                            double span);
  // This sample's estimate ``x`` at ``t``: the IMUs' acceleration from their velocity
  // ``span`` s before (the oldest kept that far back; none before the estimates noted
  // span a span), and the error it puts into each reading, for constant_error_cov
  // (nothing without set_own_acceleration)
  void note_motion(double t, const double* x);
  // the motion starts again at the next note_motion, and no reading carries an error
  // from it until then
  void forget_motion() { clear_motion(); }
  // Whether this sample's estimate ``x`` (nx), ``P`` (nx x nx) disagrees with its
  // readings ``z``, ``mask`` (nz); remembers the estimate for the next sample. ``u``
  // (nu) and ``Q`` (nx x nx): the inputs and process noise from the previous sample to
  // this one, read only when there is a previous estimate and a judged reading.
  bool check(double t, const double* z, const double* mask, const double* x, const double* P,
             const double* u, const double* Q);
  // The NIS of the readings ``z`` in ``rows`` (``mask`` > 0 on each) against the estimate
  // ``x0`` (nx), ``P0`` (nx x nx) predicted over ``dt`` s with inputs ``u`` (nu) and
  // process noise ``Q`` (nx x nx): ``r^T (H P+ H^T + R)^-1 r`` at ``x+ = f(x0, u, dt)``,
  // ``P+ = F P0 F^T + Q``; ``rows`` not empty. The innovation covariance over ``rows``
  // stays in ``S_`` until the next call
  double predicted_nis(const double* x0, const double* P0, double dt, const double* z,
                       const double* mask, const double* u, const double* Q,
                       const std::vector<int>& rows);
  // The NIS of each set of readings in ``sets`` (rows with ``mask`` > 0, none empty)
  // against the prediction of ``x0``, ``P0`` as predicted_nis, each given the readings
  // ``given`` of the same sample (the innovation's distribution conditioned on theirs: a
  // tendon robot's tensions and tip condition, which pin states the motion model leaves
  // free); into ``out`` (one per set). One evaluation of the model for all of them.
  // ``whitened`` (or null): each set's ``r^T R^-1 r`` at the prediction, without its
  // covariance. ``z_jac`` (or null): the readings at which the Jacobian is taken (the
  // residual stays ``z``'s): a residual whose linearisation widens with it, as the tilt
  // residual's near the opposite gravity direction, is judged with the Jacobian at the
  // readings before (another evaluation of the model).
  void predicted_nis_given(const double* x0, const double* P0, double dt, const double* z,
                           const double* mask, const double* u, const double* Q,
                           const std::vector<std::vector<int>>& sets,
                           const std::vector<int>& given, std::vector<double>& out,
                           std::vector<double>* whitened = nullptr,
                           const double* z_jac = nullptr);
  // ``A B A^T`` (nx x nx, into ``out``) at ``x``: the covariance from the readings'
  // constant errors and the model error (the one learned so far, at least the floor, at
  // least the square of the error the IMUs' own acceleration puts into the reading at
  // the last note_motion), ``A = (H^T R^-1 H + diag(range_info))^+ H^T R^-1``
  void constant_error_cov(const double* z, const double* mask, const double* x, double* out);

  const ConsistencySettings& settings() const { return s_; }
  double noise_scale() const { return noise_scale_; }
  // the slower average of NIS / dof over the samples while no model error showed (1
  // before any): the level a model error that showed must fall back to
  double quiet_scale() const { return quiet_scale_; }
  double model_error() const { return model_error_; }
  // the model error carried from here on (the largest since a (re)start is kept); >= 0
  void set_model_error(double value);
  double nis() const { return nis_; }  // this sample's NIS (0 when not computed)
  double fit() const { return fit_; }  // this sample's fit (0 when not judged)
  // the NIS of the innovation this sample's fit implies, ``(R^-1 r)^T S (R^-1 r)`` with
  // ``S`` the predicted innovation covariance (0 without a previous estimate)
  double fit_nis() const { return fit_nis_; }
  // the shift that fits the readings, in this estimate's covariance: ``d^T P^+ d`` with
  // ``d = (H^T R^-1 H)^+ H^T R^-1 r`` over the states the readings depend on; computed
  // only where the fit's NIS is beyond its limit and some shift_limit is finite (a
  // model whose shift test is off has none), else 0
  double shift() const { return shift_; }
  // how many times this estimate's covariance must grow for the shift that fits the
  // readings to lie at its quantile (``shift() / shift_limit``); 1 where the shift is
  // within it, or was not computed
  double shift_inflation() const {
    if (!(shift_ > 0.0) || shift_dof_ <= 0) return 1.0;
    return std::max(1.0, shift_ / s_.shift_limit[shift_dof_]);
  }
  // shift_inflation() for the last check's readings at the estimate ``x`` with the
  // covariance ``P`` instead (a covariance the check did not judge with: an estimate on
  // a bound, its covariance not conditioned on it); 1 where the last check compared no
  // prediction, or the model's shift test is off
  double shift_inflation_at(const double* x, const double* P);
  int dof() const { return dof_; }     // this sample's judged readings

 private:
  // ``fn`` at (x, u, dt, zv) with every mask 1 into ``out``
  void evaluate(const ModelFunction& fn, const double* x, const double* u, double dt,
                double* out);
  void set_readings(const double* z, const double* mask);
  void clear_motion();
  // the own-acceleration model (set_own_acceleration; null: none), its velocities kept
  // (their times, and 3 per IMU each, oldest first; deques: no allocation a sample once
  // they have grown) and the squared reading errors of the last note_motion (nz)
  const ModelFunction* velocity_ = nullptr;
  const ModelFunction* accel_error_ = nullptr;
  double span_ = 0.0;
  std::deque<double> motion_t_, motion_v_;
  std::vector<double> accel_err2_, vel_, acc_, err_;
  // the states the readings rows_ depend on (into cols_), and H (in Hr_) and R^-1 H
  // over those readings and states
  void weighted_jacobian(RowMatrix& Hs, RowMatrix& wh);
  // shift() at this estimate ``x``, ``P`` over the judged readings (rows_)
  double shift_to_fit(const double* x, const double* P, const double* u, double dt);
  // the estimate's move from the previous one's prediction in the predicted covariance,
  // ``d^T Pn^+ d`` with ``d = x - f(x0)``, from what predict() left in fF_ and Pn_: a
  // linear update by readings whose NIS is within the limit moves it at most as far
  double predicted_jump(const double* x);
  // the prediction of ``x0``, ``P0`` over ``dt`` with ``u``, ``Q`` and the readings
  // ``z``, ``mask``: fF_ (x+, F), pred_Hr_ (H, r at x+) and Pn_ (F P0 F^T + Q); kept,
  // and not computed again for the same inputs bit for bit (the glitch test and the
  // check predict from the same estimate)
  void predict(const double* x0, const double* P0, double dt, const double* z,
               const double* mask, const double* u, const double* Q);
  std::vector<double> pred_key_, key_;  // x0, P0, dt, u, Q, zv of the prediction kept
  std::vector<double> pred_Hr_;         // H and r at the prediction kept
  std::vector<double> jac_Hr_;          // H at the prediction and other readings
  bool has_pred_ = false;
  RowMatrix Pn_;

  const ModelFunction &transition_, &measurement_, &residual_;
  ConsistencySettings s_;
  std::vector<double> r_inv_;
  std::vector<double> zv_, ones_, zeros_u_, dt_;
  std::vector<double> fF_, Hr_, r_;  // the transition's, measurement's, residual's outputs
  std::vector<int> rows_, cols_;
  std::vector<double> x0_, P0_;
  RowMatrix S_;  // the last predicted_nis's innovation covariance (its rows)
  // constant_error_cov's storage: B's diagonal, H and R^-1 H over the readings and
  // states, H^T R^-1 H with the range information and its pseudo-inverse, A and A B A^T
  struct ConstantErrorScratch {
    std::vector<double> bias;
    RowMatrix Hs, wh, info, info_pinv, A, C;
    Eigen::VectorXd b;
    PinvScratch pinv;
  } cov_;
  double t0_ = 0.0;
  bool has_prev_ = false;
  bool shift_judged_ = false;  // some shift_limit is finite: the shift can matter
  // the last check's inputs and time step to its prediction (shift_inflation_at)
  std::vector<double> last_u_;
  double last_dt_ = 0.0;
  bool shift_ready_ = false;
  double noise_scale_ = 1.0, model_error_ = 0.0, nis_ = 0.0, fit_ = 0.0, fit_nis_ = 0.0;
  double shift_ = 0.0, quiet_scale_ = 1.0, jump_ = 0.0;
  // predicted_jump()'s factorisation and vectors (kept: no allocation a sample)
  Eigen::LDLT<Eigen::MatrixXd> jump_ldlt_;
  Eigen::VectorXd jump_y_;
  int avg_dof_ = 0, dof_ = 0, shift_dof_ = 0;
  int quiet_run_ = 0;  // samples in a row the average has been at the quiet level
  // the most readings judged at one sample so far: the quiet level learns only from
  // samples with as many, and starts again from 1 when a sample has more (an IMU's first
  // reading): a sample without some IMU's readings scatters otherwise
  int max_dof_ = 0;
  bool high_ = false, persists_ = false;
};

}  // namespace cmhe
