#include "unscented.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "filter.hpp"

namespace cmhe {

namespace {
constexpr double kPi = 3.14159265358979323846;

// The weighted mean (weights ``wm``) of ``points`` rows of ``dim`` values into ``mean``,
// the rows made their deviations from it in place, and ``cov`` (dim x dim) the
// deviations' weighted outer products (weights ``wc``)
void weighted_moments(double* rows, int points, int dim, const double* wm, const double* wc,
                      double* mean, double* cov) {
  for (int c = 0; c < dim; ++c) {
    double s = 0.0;
    for (int k = 0; k < points; ++k) s += wm[k] * rows[k * dim + c];
    mean[c] = s;
  }
  for (int k = 0; k < points; ++k)
    for (int c = 0; c < dim; ++c) rows[k * dim + c] -= mean[c];
  for (int a = 0; a < dim; ++a)
    for (int b = 0; b < dim; ++b) {
      double s = 0.0;
      for (int k = 0; k < points; ++k) s += wc[k] * rows[k * dim + a] * rows[k * dim + b];
      cov[a * dim + b] = s;
    }
}
}  // namespace

UnscentedFilter::UnscentedFilter(const ModelFunction& transition, const ModelFunction& residual,
                                 int nx, int nu, int nz, double alpha, double beta,
                                 double kappa, std::vector<int64_t> chart_rows,
                                 std::vector<std::string> names)
    : transition_(transition),
      residual_(residual),
      nx_(nx),
      nu_(nu),
      nz_(nz),
      chart_(nz, 0),
      names_(std::move(names)) {
  if (nx < 1 || nz < 1 || nu < 0) throw std::invalid_argument("nx, nz >= 1 and nu >= 0");
  if (!(alpha > 0.0 && alpha <= 1.0)) throw std::invalid_argument("alpha must lie in (0, 1]");
  if (transition.output_size() != nx + int64_t(nx) * nx)
    throw std::invalid_argument("the transition must write f and F (nx + nx^2 values)");
  if (residual.output_size() != nz)
    throw std::invalid_argument("the residual must write nz values");
  if (int(names_.size()) != nz) throw std::invalid_argument("names needs one name per row");
  for (int64_t i : chart_rows) {
    if (i < 0 || i >= nz) throw std::invalid_argument("a chart row is out of range");
    chart_[i] = 1;
  }
  const int points = 2 * nx + 1;
  lambda_ = alpha * alpha * (nx + kappa) - nx;
  wm_.assign(points, 0.5 / (nx + lambda_));
  wc_ = wm_;
  wm_[0] = lambda_ / (nx + lambda_);
  wc_[0] = wm_[0] + 1.0 - alpha * alpha + beta;
  pts_.resize(size_t(points) * nx);
  prop_.resize(size_t(points) * nx);
  L_.resize(size_t(nx) * nx);
  scaled_.resize(size_t(nx) * nx);
  out_.resize(nx + size_t(nx) * nx);
  dt_.resize(1);
  zv_.resize(nz);
  mask_.resize(nz);
  r_.resize(nz);
  rs_.resize(size_t(points) * nz);
}

bool UnscentedFilter::fail(UnscentedFailure kind, std::string text) {
  failure = kind;
  message = std::move(text);
  return false;
}

bool UnscentedFilter::sigma_points(const double* x, const double* P) {
  const int n = nx_;
  for (int i = 0; i < n * n; ++i) scaled_[i] = (n + lambda_) * P[i];
  if (!small::cholesky(scaled_.data(), L_.data(), n))
    return fail(UnscentedFailure::LINEAR_ALGEBRA, "Matrix is not positive definite");
  // x, then x + L e_j and x - L e_j (the columns of the lower factor)
  for (int c = 0; c < n; ++c) pts_[c] = x[c];
  for (int j = 0; j < n; ++j)
    for (int c = 0; c < n; ++c) {
      pts_[(1 + j) * n + c] = x[c] + L_[c * n + j];
      pts_[(1 + n + j) * n + c] = x[c] - L_[c * n + j];
    }
  return true;
}

bool UnscentedFilter::predict(double* x, double* P, const double* u, double dt,
                              const double* Q) {
  failure = UnscentedFailure::NONE;
  const int n = nx_, points = 2 * n + 1;
  if (!sigma_points(x, P)) return false;
  dt_[0] = dt;
  for (int i = 0; i < nz_; ++i) zv_[i] = mask_[i] = 0.0;
  for (int k = 0; k < points; ++k) {
    const double* in[5] = {pts_.data() + k * n, nu_ ? u : nullptr, dt_.data(), zv_.data(),
                           mask_.data()};
    if (transition_.evaluate(in, out_.data()) != 0)
      throw std::runtime_error("the transition's evaluation failed");
    std::copy(out_.begin(), out_.begin() + n, prop_.begin() + k * n);
  }
  weighted_moments(prop_.data(), points, n, wm_.data(), wc_.data(), x, P);
  for (int i = 0; i < n * n; ++i) P[i] += Q[i];
  return true;
}

bool UnscentedFilter::update(double* x, double* P, const double* z, const double* mask,
                             const double* R, bool check_chart) {
  failure = UnscentedFailure::NONE;
  const int n = nx_, nz = nz_, points = 2 * n + 1;
  rows_.clear();
  for (int i = 0; i < nz; ++i)
    if (mask[i] > 0.0) rows_.push_back(i);
  const int m = int(rows_.size());
  if (m == 0) return true;
  if (!sigma_points(x, P)) return false;
  for (int i = 0; i < nz; ++i) {
    mask_[i] = mask[i] > 0.0 ? 1.0 : 0.0;
    zv_[i] = mask[i] > 0.0 && std::isfinite(z[i]) ? z[i] : 0.0;
  }
  dt_[0] = 0.0;
  for (int k = 0; k < points; ++k) {
    const double* in[5] = {pts_.data() + k * n, nullptr, dt_.data(), zv_.data(), mask_.data()};
    if (residual_.evaluate(in, r_.data()) != 0)
      throw std::runtime_error("the residual's evaluation failed");
    for (int a = 0; a < m; ++a) rs_[k * m + a] = r_[rows_[a]];
  }
  if (check_chart) {  // the valid tilt component whose residuals spread the most
    double worst = 0.0;
    int at = -1;
    for (int a = 0; a < m; ++a) {
      if (!chart_[rows_[a]]) continue;
      double jump = 0.0;
      for (int k = 0; k < points; ++k)
        jump = std::max(jump, std::fabs(rs_[k * m + a] - rs_[a]));
      if (at < 0 || jump > worst) worst = jump, at = a;
    }
    if (at >= 0 && worst > kPi) {
      double lo = rs_[at], hi = rs_[at];
      for (int k = 0; k < points; ++k) {
        lo = std::min(lo, rs_[k * m + at]);
        hi = std::max(hi, rs_[k * m + at]);
      }
      char span[32];
      std::snprintf(span, sizeof span, "%.3g", hi - lo);
      return fail(UnscentedFailure::TILT_CHART,
                  "the unscented transform's " + names_[rows_[at]] + " residuals span " +
                      span +
                      " across the sigma points: the reading is about a half turn from "
                      "the predicted tilt");
    }
  }
  rm_.resize(m);
  S_.resize(size_t(m) * m);
  Ct_.resize(size_t(m) * n);
  Kt_.resize(size_t(m) * n);
  SK_.resize(size_t(m) * n);
  weighted_moments(rs_.data(), points, m, wm_.data(), wc_.data(), rm_.data(), S_.data());
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) S_[a * m + b] += R[rows_[a] * nz + rows_[b]];
  // C^T (m x n), C = -sum_k wc_k (X_k - x) dr_k^T: the state's cross-covariance with the
  // predicted measurement, whose deviations are -dr
  for (int a = 0; a < m; ++a)
    for (int c = 0; c < n; ++c) {
      double s = 0.0;
      for (int k = 0; k < points; ++k) s += wc_[k] * (pts_[k * n + c] - x[c]) * rs_[k * m + a];
      Ct_[a * n + c] = -s;
    }
  // K^T = S^-1 C^T (S symmetric)
  if (!small::solve(S_.data(), Ct_.data(), Kt_.data(), m, n))
    return fail(UnscentedFailure::LINEAR_ALGEBRA, "Singular matrix");
  for (int c = 0; c < n; ++c) {
    double s = 0.0;
    for (int a = 0; a < m; ++a) s += Kt_[a * n + c] * rm_[a];
    x[c] += s;
  }
  // P -= K S K^T
  small::mul(S_.data(), Kt_.data(), SK_.data(), m, m, n);
  for (int c = 0; c < n; ++c)
    for (int d = 0; d < n; ++d) {
      double s = 0.0;
      for (int a = 0; a < m; ++a) s += Kt_[a * n + c] * SK_[a * n + d];
      P[c * n + d] -= s;
    }
  return true;
}

}  // namespace cmhe
