// The UKF's predict and update on one node model, with Van der Merwe's scaled sigma
// points (continuum_mhe.estimators.kalman.UnscentedKalmanInference steps it).
//
// Matrices are row-major (numpy's C order). The transition is the node model's
// ``(x, u, dt, z, m) -> (f, F)`` (F is not used), the residual its masked
// ``(x, u, dt, z, m) -> m r(z, x)``: the innovation is the residual's weighted mean over
// the sigma points, and the predicted measurement's deviations are ``-(r_i - mean)``.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "model_function.hpp"

namespace cmhe {

// Why an unscented step failed (``UnscentedFilter::failure``): a matrix without a
// Cholesky factor or a singular innovation covariance (numpy's LinAlgError in the
// Python terms of the policy), or a tilt reading about a half turn from the sigma
// points' tilts, where the transform means nothing (an ArithmeticError)
enum class UnscentedFailure { NONE = 0, LINEAR_ALGEBRA = 1, TILT_CHART = 2 };

class UnscentedFilter {
 public:
  // ``chart_rows``: the tilt rows whose residual does not wrap (the bend formulation's
  // tangent plane), checked in an update (``check_chart``); ``names``: the measurement
  // rows' names, for the failure's message. ``alpha`` in (0, 1].
  UnscentedFilter(const ModelFunction& transition, const ModelFunction& residual, int nx,
                  int nu, int nz, double alpha, double beta, double kappa,
                  std::vector<int64_t> chart_rows, std::vector<std::string> names);

  int nx() const { return nx_; }
  int nu() const { return nu_; }
  int nz() const { return nz_; }

  // ``x`` (nx) and ``P`` (nx x nx) through the transition with ``(u, dt)``, plus ``Q``,
  // in place; false (``failure`` set, x and P unchanged) where ``P`` has no Cholesky
  // factor
  bool predict(double* x, double* P, const double* u, double dt, const double* Q);
  // the update with the valid components (``mask`` > 0) of ``z`` (a missing one is NaN),
  // ``R`` (nz x nz), in place (nothing without a valid component); false (``failure``
  // set, x and P unchanged) where ``P`` has no Cholesky factor, the innovation
  // covariance is singular, or (``check_chart``) a valid tilt component's residuals
  // differ by more than pi across the sigma points
  bool update(double* x, double* P, const double* z, const double* mask, const double* R,
              bool check_chart);

  UnscentedFailure failure = UnscentedFailure::NONE;
  // the last failure's message, as numpy or the Python UKF words it
  std::string message;

 private:
  // sigma points of (x, P) into pts_ ((2n + 1) x n); false where P has no factor
  bool sigma_points(const double* x, const double* P);
  bool fail(UnscentedFailure kind, std::string text);
  const ModelFunction& transition_;
  const ModelFunction& residual_;
  int nx_, nu_, nz_;
  double lambda_;
  std::vector<double> wm_, wc_;
  std::vector<char> chart_;
  std::vector<std::string> names_;
  std::vector<double> pts_, prop_, L_, scaled_, out_, dt_, zv_, mask_, r_, rs_;
  // the update's matrices over its valid rows (m of them): kept from sample to sample
  std::vector<double> rm_, S_, Kt_, Ct_, SK_;
  std::vector<int> rows_;
};

}  // namespace cmhe
