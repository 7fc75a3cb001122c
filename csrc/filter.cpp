#include "filter.hpp"

#include "btd.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace cmhe {

namespace small {

void mul_t(const double* A, const double* B, double* C, int m, int k, int n) {
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < n; ++j) {
      double s = 0.0;
      for (int a = 0; a < k; ++a) s += A[i * k + a] * B[j * k + a];
      C[i * n + j] = s;
    }
}

void mul(const double* A, const double* B, double* C, int m, int k, int n) {
  dense_mul(m, k, n, A, B, C);
}

bool cholesky(const double* A, double* L, int n) { return dense_cholesky(n, A, L); }

void inverse_gram(const double* L, double* out, int n) {
  std::vector<double> Li(static_cast<size_t>(n) * n);
  dense_inverse_gram(n, L, out, Li.data());
}

bool solve(const double* A, const double* B, double* X, int n, int m) {
  std::vector<double> a(A, A + static_cast<size_t>(n) * n);
  for (int i = 0; i < n * m; ++i) X[i] = B[i];
  for (int c = 0; c < n; ++c) {
    int p = c;
    for (int i = c + 1; i < n; ++i)
      if (std::fabs(a[i * n + c]) > std::fabs(a[p * n + c])) p = i;
    if (a[p * n + c] == 0.0) return false;
    if (p != c) {
      for (int k = 0; k < n; ++k) std::swap(a[p * n + k], a[c * n + k]);
      for (int k = 0; k < m; ++k) std::swap(X[p * m + k], X[c * m + k]);
    }
    for (int i = c + 1; i < n; ++i) {
      const double f = a[i * n + c] / a[c * n + c];
      for (int k = c; k < n; ++k) a[i * n + k] -= f * a[c * n + k];
      for (int k = 0; k < m; ++k) X[i * m + k] -= f * X[c * m + k];
    }
  }
  for (int c = n - 1; c >= 0; --c)
    for (int k = 0; k < m; ++k) {
      double t = X[c * m + k];
      for (int j = c + 1; j < n; ++j) t -= a[c * n + j] * X[j * m + k];
      X[c * m + k] = t / a[c * n + c];
    }
  return true;
}

}  // namespace small

bool ekf_update(double* x, double* P, const double* r, const double* H, const double* R,
                int nx, int nz, double* log_likelihood) {
  std::vector<double> HP(nz * nx), S(nz * nz), Ls(nz * nz), Si(nz * nz), Kt(nz * nx);
  small::mul(H, P, HP.data(), nz, nx, nx);
  small::mul_t(HP.data(), H, S.data(), nz, nx, nz);
  for (int i = 0; i < nz * nz; ++i) S[i] += R[i];
  if (log_likelihood) *log_likelihood = NAN;
  if (small::cholesky(S.data(), Ls.data(), nz)) {
    small::inverse_gram(Ls.data(), Si.data(), nz);
    small::mul(Si.data(), HP.data(), Kt.data(), nz, nz, nx);  // S^-1 H P
    if (log_likelihood) {  // log N(r; 0, S) without its constant: -(r^T S^-1 r)/2 - log|S|/2
      double q = 0.0, half_log_det = 0.0;
      for (int a = 0; a < nz; ++a) {
        double s = 0.0;
        for (int b = 0; b < nz; ++b) s += Si[a * nz + b] * r[b];
        q += r[a] * s;
        half_log_det += std::log(Ls[a * nz + a]);
      }
      *log_likelihood = -0.5 * q - half_log_det;
    }
  } else if (!small::solve(S.data(), HP.data(), Kt.data(), nz, nx)) {
    return false;
  }
  std::vector<double> ikh(nx * nx), K(nx * nz), A(nx * nx), B(nx * nx), KR(nx * nz);
  for (int j = 0; j < nx; ++j) {
    for (int a = 0; a < nz; ++a) x[j] += Kt[a * nx + j] * r[a];
    for (int k = 0; k < nx; ++k) {
      double s = j == k ? 1.0 : 0.0;
      for (int a = 0; a < nz; ++a) s -= Kt[a * nx + j] * H[a * nx + k];
      ikh[j * nx + k] = s;
    }
  }
  for (int j = 0; j < nx; ++j)
    for (int a = 0; a < nz; ++a) K[j * nz + a] = Kt[a * nx + j];
  small::mul(ikh.data(), P, A.data(), nx, nx, nx);
  small::mul_t(A.data(), ikh.data(), B.data(), nx, nx, nx);  // (I - KH) P (I - KH)^T
  small::mul(K.data(), R, KR.data(), nx, nz, nz);
  small::mul_t(KR.data(), K.data(), A.data(), nx, nz, nx);  // K R K^T
  for (int i = 0; i < nx * nx; ++i) P[i] = B[i] + A[i];
  return true;
}

void predict_covariance(double* P, const double* F, const double* Q, int nx) {
  std::vector<double> FP(nx * nx);
  small::mul(F, P, FP.data(), nx, nx, nx);
  small::mul_t(FP.data(), F, P, nx, nx, nx);
  for (int i = 0; i < nx * nx; ++i) P[i] += Q[i];
}

NodeModel::NodeModel(const ModelFunction& transition, const ModelFunction& measurement,
                     const ModelFunction& output, const ModelFunction& output_jacobian, int nx,
                     int nu, int nz, int ny, std::vector<int64_t> wrapped,
                     std::vector<int64_t> sigma_states)
    : transition_(transition),
      measurement_(measurement),
      output_(output),
      jacobian_(output_jacobian),
      nx_(nx),
      nu_(nu),
      nz_(nz),
      ny_(ny),
      wrapped_(std::move(wrapped)),
      x_(nx),
      u_(nu),
      dt_(1),
      z_(nz),
      m_(nz),
      out_(nx + nx * nx + nz * nx + nz),
      oout_(ny),
      jout_(static_cast<size_t>(ny) * nx),
      r_(nz),
      H_(nz * nx),
      jx_(nx),
      sigma_states_(std::move(sigma_states)),
      is_wrapped_(ny, 0),
      yx_(ny),
      Ps_(sigma_states_.size() * sigma_states_.size()),
      Ls_(sigma_states_.size() * sigma_states_.size()),
      acc_(ny) {
  for (int64_t i : wrapped_) {
    if (i < 0 || i >= ny) throw std::invalid_argument("a wrapped output index out of range");
    is_wrapped_[i] = 1;
  }
  for (int64_t j : sigma_states_)
    if (j < 0 || j >= nx) throw std::invalid_argument("a sigma state index out of range");
  if (const auto* tf = dynamic_cast<const TapeFunction*>(&output)) {
    const Tape& tape = tf->tape();
    if (tape.input_sizes().size() == 1 && tape.output_sizes().size() == 1 &&
        tape.input_sizes()[0] == nx && tape.output_sizes()[0] == ny)
      output_tape_ = &tape;
  }
  const size_t points = 2 * sigma_states_.size();
  xs_.resize(points * nx);
  ys_.resize(points * ny);
  if (transition.output_size() != nx + nx * nx)
    throw std::invalid_argument("the transition must write f and F (nx + nx^2 values)");
  if (measurement.output_size() != nz * nx + nz)
    throw std::invalid_argument("the measurement must write H and r (nz nx + nz values)");
}

void NodeModel::set_sample(const double* u, double dt, const double* z, const double* mask) {
  for (int i = 0; i < nu_; ++i) u_[i] = u[i];
  dt_[0] = dt;
  for (int i = 0; i < nz_; ++i) {
    m_[i] = mask ? mask[i] : 1.0;
    z_[i] = z && m_[i] > 0.0 ? z[i] : 0.0;
  }
}

void NodeModel::evaluate(const double* x, const double* u, double dt, const double* z,
                         const double* mask) {
  set_sample(u, dt, z, mask);
  const auto in = inputs(x);
  transition_.evaluate(in.data(), out_.data());
  measurement_.evaluate(in.data(), out_.data() + nx_ + nx_ * nx_);
}

void NodeModel::predict(const double* x, const double* u, double dt) {
  set_sample(u, dt, nullptr, nullptr);
  transition_.evaluate(inputs(x).data(), out_.data());
}

std::array<const double*, 5> NodeModel::inputs(const double* x) {
  for (int i = 0; i < nx_; ++i) x_[i] = x[i];
  return {x_.data(), nu_ ? u_.data() : nullptr, dt_.data(), z_.data(), m_.data()};
}

namespace {
bool any_valid(const double* mask, int nz) {
  for (int i = 0; i < nz; ++i)
    if (mask[i] > 0.0) return true;
  return false;
}
}  // namespace

bool NodeModel::arrival_step(double* x, double* P, double* Pinv, const double* u, double dt,
                             const double* z, const double* mask, const double* R,
                             const double* Q) {
  const int nx = nx_, nz = nz_, k = nx + nx * nx;
  if (any_valid(mask, nz)) {
    evaluate(x, u, dt, z, mask);
    if (!ekf_update(x, P, out_.data() + k + nz * nx, out_.data() + k, R, nx, nz)) return false;
  }
  predict(x, u, dt);
  for (int i = 0; i < nx; ++i) x[i] = out_[i];
  predict_covariance(P, out_.data() + nx, Q, nx);
  for (int j = 0; j < nx; ++j)
    for (int c = 0; c < j; ++c) {
      const double m = 0.5 * (P[j * nx + c] + P[c * nx + j]);
      P[j * nx + c] = m;
      P[c * nx + j] = m;
    }
  std::vector<double> L(nx * nx);
  if (small::cholesky(P, L.data(), nx)) {
    small::inverse_gram(L.data(), Pinv, nx);
    return true;
  }
  std::vector<double> I(nx * nx, 0.0);
  for (int i = 0; i < nx; ++i) I[i * nx + i] = 1.0;
  return small::solve(P, I.data(), Pinv, nx, nx);
}

bool NodeModel::ekf_step(double* x, double* P, const double* u, double dt, const double* z,
                         const double* mask, const double* R, const double* Q) {
  const int nx = nx_, nz = nz_, k = nx + nx * nx;
  predict(x, u, dt);
  for (int i = 0; i < nx; ++i) x[i] = out_[i];
  predict_covariance(P, out_.data() + nx, Q, nx);
  log_likelihood = NAN;
  if (!any_valid(mask, nz)) return true;
  evaluate(x, u, dt, z, mask);
  const double *H = out_.data() + k, *r = H + nz * nx;
  double given = 0.0;
  const bool conditioned = likelihood_given.empty() || given_log_density(P, r, H, R, &given);
  const bool updated = ekf_update(x, P, r, H, R, nx, nz, &log_likelihood);
  log_likelihood = conditioned ? log_likelihood - given : NAN;
  return updated;
}

bool NodeModel::given_log_density(const double* P, const double* r, const double* H,
                                  const double* R, double* out) const {
  const int nx = nx_, nz = nz_, nb = static_cast<int>(likelihood_given.size());
  std::vector<double> Hb(nb * nx), HP(nb * nx), S(nb * nb), L(nb * nb);
  for (int a = 0; a < nb; ++a)
    for (int j = 0; j < nx; ++j) Hb[a * nx + j] = H[likelihood_given[a] * nx + j];
  small::mul(Hb.data(), P, HP.data(), nb, nx, nx);
  small::mul_t(HP.data(), Hb.data(), S.data(), nb, nx, nb);
  for (int a = 0; a < nb; ++a)
    for (int b = 0; b < nb; ++b) S[a * nb + b] += R[likelihood_given[a] * nz + likelihood_given[b]];
  if (!small::cholesky(S.data(), L.data(), nb)) return false;
  // -(r_b^T S_bb^-1 r_b + log|S_bb|) / 2 by forward substitution, w = L^-1 r_b
  double q = 0.0, half_log_det = 0.0;
  std::vector<double> w(nb);
  for (int a = 0; a < nb; ++a) {
    double t = r[likelihood_given[a]];
    for (int b = 0; b < a; ++b) t -= L[a * nb + b] * w[b];
    w[a] = t / L[a * nb + a];
    q += w[a] * w[a];
    half_log_det += std::log(L[a * nb + a]);
  }
  *out = -0.5 * q - half_log_det;
  return true;
}

void NodeModel::output(const double* x, double* y) {
  const double* in[1] = {x};
  output_.evaluate(in, y);
  const double period = 2.0 * M_PI;
  for (int64_t i : wrapped_) {  // Python's (y + pi) % (2 pi) - pi
    double m = std::fmod(y[i] + M_PI, period);
    if (m != 0.0) {
      if (m < 0.0) m += period;
    } else {
      m = 0.0;
    }
    y[i] = m - M_PI;
  }
}

void NodeModel::output_std(const double* x, const double* P, double* std) {
  if (!sigma_states_.empty()) {
    sigma_point_std(x, P, std);
    return;
  }
  const int ny = ny_, nx = nx_;
  // the policy asks for two covariances at one state (the estimate's, then the
  // readings' constant errors): the Jacobian of the last state asked for is kept
  if (!has_jx_ || std::memcmp(x, jx_.data(), sizeof(double) * nx) != 0) {
    const double* in[1] = {x};
    jacobian_.evaluate(in, jout_.data());
    std::copy(x, x + nx, jx_.begin());
    has_jx_ = true;
  }
  for (int i = 0; i < ny; ++i) {
    double s = 0.0;
    for (int j = 0; j < nx; ++j)
      for (int k = 0; k < nx; ++k) s += jout_[i + ny * j] * P[j * nx + k] * jout_[i + ny * k];
    std[i] = std::sqrt(s > 0.0 ? s : 0.0);
  }
}

namespace {
// Lower L with L L^T = A (n x n, symmetric positive semidefinite, row-major): Cholesky,
// with a zero column where the pivot is below 1e-14 of the largest diagonal entry (a
// direction without variance: a state held at a bound, or rounding)
void psd_cholesky(const double* A, double* L, int n) {
  double top = 0.0;
  for (int i = 0; i < n; ++i) top = std::max(top, A[i * n + i]);
  const double floor = 1e-14 * top;
  std::fill(L, L + n * n, 0.0);
  for (int j = 0; j < n; ++j) {
    double d = A[j * n + j];
    for (int k = 0; k < j; ++k) d -= L[j * n + k] * L[j * n + k];
    if (!(d > floor)) {
      if (std::isnan(d)) L[j * n + j] = d;  // NaN in, NaN out
      continue;
    }
    const double ljj = std::sqrt(d);
    L[j * n + j] = ljj;
    for (int i = j + 1; i < n; ++i) {
      double v = A[i * n + j];
      for (int k = 0; k < j; ++k) v -= L[i * n + k] * L[j * n + k];
      L[i * n + j] = v / ljj;
    }
  }
}

// Python's (d + pi) % (2 pi) - pi
double wrap(double d) {
  const double period = 2.0 * M_PI;
  double m = std::fmod(d + M_PI, period);
  if (m < 0.0) m += period;
  return m - M_PI;
}
}  // namespace

void NodeModel::sigma_point_std(const double* x, const double* P, double* std) {
  const int ny = ny_, nx = nx_, s = static_cast<int>(sigma_states_.size());
  const int64_t* S = sigma_states_.data();
  if (!has_jx_ || std::memcmp(x, jx_.data(), sizeof(double) * nx) != 0) {
    output(x, yx_.data());
    std::copy(x, x + nx, jx_.begin());
    has_jx_ = true;
  }
  for (int a = 0; a < s; ++a)
    for (int b = 0; b < s; ++b) Ps_[a * s + b] = P[S[a] * nx + S[b]];
  psd_cholesky(Ps_.data(), Ls_.data(), s);
  // the points x + sqrt(s) L e_j, then x - sqrt(s) L e_j, row by row in xs_
  const double spread = std::sqrt(static_cast<double>(s));
  for (int p = 0; p < 2 * s; ++p) {
    const int j = p % s;
    const double sign = p < s ? spread : -spread;
    double* xp = xs_.data() + static_cast<size_t>(p) * nx;
    std::copy(x, x + nx, xp);
    for (int a = j; a < s; ++a) xp[S[a]] += sign * Ls_[a * s + j];
  }
  if (output_tape_) {  // unwrapped outputs: their differences are wrapped below
    const double* in[1] = {xs_.data()};
    double* out[1] = {ys_.data()};
    const int64_t in_stride[1] = {nx}, out_stride[1] = {ny};
    output_tape_->evaluate_batch(in, in_stride, out, out_stride, 2 * s);
  } else {
    for (int p = 0; p < 2 * s; ++p)
      output(xs_.data() + static_cast<size_t>(p) * nx, ys_.data() + static_cast<size_t>(p) * ny);
  }
  std::fill(acc_.begin(), acc_.end(), 0.0);
  for (int p = 0; p < 2 * s; ++p) {
    const double* yp = ys_.data() + static_cast<size_t>(p) * ny;
    for (int i = 0; i < ny; ++i) {
      const double d = is_wrapped_[i] ? wrap(yp[i] - yx_[i]) : yp[i] - yx_[i];
      acc_[i] += d * d;
    }
  }
  for (int i = 0; i < ny; ++i) std[i] = std::sqrt(acc_[i] / (2.0 * s));
}

}  // namespace cmhe
