#include "consistency.hpp"

#include <cstring>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace cmhe {

using ConstRowMap = Eigen::Map<const RowMatrix>;
using ConstVectorMap = Eigen::Map<const Eigen::VectorXd>;

void pinv_symmetric(const RowMatrix& a, double rcond, PinvScratch& scratch, RowMatrix& out) {
  Eigen::SelfAdjointEigenSolver<RowMatrix>& eig = scratch.eig;
  eig.compute(a);
  const Eigen::VectorXd& s = eig.eigenvalues();
  const double cut = rcond * (s.size() ? s.cwiseAbs().maxCoeff() : 0.0);
  Eigen::VectorXd& inv_s = scratch.inv_s;
  inv_s.resize(s.size());
  for (Eigen::Index i = 0; i < s.size(); ++i)
    inv_s[i] = std::fabs(s[i]) > cut ? 1.0 / s[i] : 0.0;
  const RowMatrix& u = eig.eigenvectors();
  out.noalias() = u * inv_s.asDiagonal() * u.transpose();
}

RowMatrix pinv_symmetric(const RowMatrix& a, double rcond) {
  PinvScratch scratch;
  RowMatrix out;
  pinv_symmetric(a, rcond, scratch, out);
  return out;
}

ConsistencyCheck::ConsistencyCheck(const ModelFunction& transition,
                                   const ModelFunction& measurement,
                                   const ModelFunction& residual, ConsistencySettings settings)
    : transition_(transition),
      measurement_(measurement),
      residual_(residual),
      s_(std::move(settings)) {
  const size_t nx = s_.nx, nz = s_.nz;
  const auto need = [](const std::vector<double>& v, size_t n, const char* name) {
    if (v.size() != n)
      throw std::invalid_argument(std::string(name) + " has " + std::to_string(v.size()) +
                                  " values, expected " + std::to_string(n));
  };
  need(s_.R, nz * nz, "R");
  need(s_.judged, nz, "judged");
  need(s_.limit, nz + 1, "limit");
  need(s_.run_limit, nz + 1, "run_limit");
  need(s_.avg_limit, nz + 1, "avg_limit");
  need(s_.shift_limit, nx + 1, "shift_limit");
  need(s_.bias, nz, "bias");
  need(s_.gravity_r, nz, "gravity_r");
  if (!s_.range_info.empty()) {
    need(s_.range_info, nx, "range_info");
    for (double v : s_.range_info)
      if (!(v >= 0.0) || !std::isfinite(v))
        throw std::invalid_argument("range_info must be finite and >= 0");
  }
  if (s_.memory < 1 || s_.quiet_memory < 1)
    throw std::invalid_argument("memory and quiet_memory must be at least 1");
  if (!(s_.model_error_floor >= 0.0) || !std::isfinite(s_.model_error_floor))
    throw std::invalid_argument("model_error_floor must be finite and >= 0");
  const auto writes = [](const ModelFunction& fn, size_t n, const char* name) {
    if (fn.output_size() != static_cast<int64_t>(n))
      throw std::invalid_argument(std::string("the ") + name + " function writes " +
                                  std::to_string(fn.output_size()) + " values, expected " +
                                  std::to_string(n));
  };
  writes(transition_, nx + nx * nx, "transition (f, F)");
  writes(measurement_, nz * nx + nz, "measurement (H, r)");
  writes(residual_, nz, "residual (r)");
  r_inv_.resize(nz);
  for (size_t i = 0; i < nz; ++i) r_inv_[i] = 1.0 / s_.R[i * nz + i];
  for (double v : s_.shift_limit) shift_judged_ = shift_judged_ || std::isfinite(v);
  zv_.resize(nz);
  ones_.assign(nz, 1.0);
  zeros_u_.assign(s_.nu, 0.0);
  dt_.resize(1);
  fF_.resize(nx + nx * nx);
  Hr_.resize(nz * nx + nz);
  pred_Hr_.resize(nz * nx + nz);
  r_.resize(nz);
  x0_.resize(nx);
  P0_.resize(nx * nx);
  rows_.reserve(nz);
  cols_.reserve(nx);
  reset();
}

void ConsistencyCheck::reset() {
  has_prev_ = false;
  clear_motion();
  noise_scale_ = quiet_scale_ = 1.0;
  model_error_ = 0.0;
  avg_dof_ = 0;
  high_ = false;
  persists_ = false;
  quiet_run_ = 0;
  max_dof_ = 0;
  nis_ = fit_ = fit_nis_ = shift_ = 0.0;
  dof_ = 0;
}

void ConsistencyCheck::set_model_error(double value) {
  if (!(value >= 0.0) || !std::isfinite(value))
    throw std::invalid_argument("model_error must be finite and >= 0, got " +
                                std::to_string(value));
  model_error_ = value;
}

void ConsistencyCheck::set_own_acceleration(const ModelFunction& velocity,
                                            const ModelFunction& error, double span) {
  if (error.output_size() != s_.nz)
    throw std::invalid_argument("the acceleration's reading error must have nz values");
  if (velocity.output_size() <= 0 || velocity.output_size() % 3 != 0)
    throw std::invalid_argument("the IMUs' velocities must have 3 values per IMU");
  if (!(span > 0.0) || !std::isfinite(span))
    throw std::invalid_argument("span must be finite and > 0");
  velocity_ = &velocity;
  accel_error_ = &error;
  span_ = span;
  vel_.assign(velocity.output_size(), 0.0);
  acc_.assign(velocity.output_size(), 0.0);
  err_.assign(s_.nz, 0.0);
  clear_motion();
}

void ConsistencyCheck::clear_motion() {
  motion_t_.clear();
  motion_v_.clear();
  accel_err2_.assign(s_.nz, 0.0);
}

void ConsistencyCheck::note_motion(double t, const double* x) {
  if (velocity_ == nullptr) return;
  const double* in[1] = {x};
  if (velocity_->evaluate(in, vel_.data()) != 0)
    throw std::runtime_error("the model's evaluation failed");
  if (!motion_t_.empty() && !(t > motion_t_.back())) clear_motion();  // not after the last
  const size_t n = vel_.size();
  motion_t_.push_back(t);
  motion_v_.insert(motion_v_.end(), vel_.begin(), vel_.end());
  // the oldest kept at least span before t (the one after it is not that far back)
  while (motion_t_.size() > 2 && t - motion_t_[1] >= span_ - 1e-9) {
    motion_t_.pop_front();
    motion_v_.erase(motion_v_.begin(), motion_v_.begin() + static_cast<std::ptrdiff_t>(n));
  }
  const double dt = t - motion_t_.front();
  std::fill(accel_err2_.begin(), accel_err2_.end(), 0.0);
  if (!(dt >= span_ - 1e-9)) return;  // not yet a span of confirmed estimates
  for (size_t i = 0; i < n; ++i) acc_[i] = (vel_[i] - motion_v_[i]) / dt;
  const double* ein[2] = {x, acc_.data()};
  if (accel_error_->evaluate(ein, err_.data()) != 0)
    throw std::runtime_error("the model's evaluation failed");
  for (int i = 0; i < s_.nz; ++i)
    accel_err2_[i] = std::isfinite(err_[i]) ? err_[i] * err_[i] : 0.0;
}

void ConsistencyCheck::set_readings(const double* z, const double* mask) {
  for (int i = 0; i < s_.nz; ++i) zv_[i] = mask[i] > 0.0 ? z[i] : 0.0;
}

void ConsistencyCheck::evaluate(const ModelFunction& fn, const double* x, const double* u,
                                double dt, double* out) {
  dt_[0] = dt;
  const double* in[5] = {x, s_.nu ? u : nullptr, dt_.data(), zv_.data(), ones_.data()};
  if (fn.evaluate(in, out) != 0) throw std::runtime_error("the model's evaluation failed");
}

bool ConsistencyCheck::check(double t, const double* z, const double* mask, const double* x,
                             const double* P, const double* u, const double* Q) {
  const int nx = s_.nx, nz = s_.nz;
  rows_.clear();
  for (int i = 0; i < nz; ++i)
    if (s_.judged[i] != 0.0 && mask[i] != 0.0) rows_.push_back(i);
  const int dof = static_cast<int>(rows_.size());
  nis_ = fit_ = fit_nis_ = shift_ = jump_ = 0.0;
  dof_ = dof;
  shift_ready_ = false;
  if (dof > max_dof_) {  // more readings than any sample before: learn their level anew
    max_dof_ = dof;
    quiet_scale_ = 1.0;
  }
  if (dof > 0) {
    set_readings(z, mask);
    if (has_prev_) {
      if (!Q || (s_.nu && !u))
        throw std::invalid_argument("the prediction from the previous estimate needs u and Q");
      const double dt = t - t0_;
      last_dt_ = dt;
      if (s_.nu) last_u_.assign(u, u + s_.nu);
      shift_ready_ = shift_judged_;
      nis_ = predicted_nis(x0_.data(), P0_.data(), dt, z, mask, u, Q, rows_);
      // covariance matching: the average factor of the innovations over their predicted
      // size; a reading flagged on its own (an outlier) stays out of it
      if (nis_ <= s_.limit[dof]) {
        noise_scale_ += (nis_ / dof - noise_scale_) / s_.memory;
        avg_dof_ = dof;
        // the level the readings scatter at while the model follows them, all of them:
        // with an IMU silent (a dropout, a freeze) the others' innovations scatter less,
        // and a level learned from them would flag every sample after its return
        if (!persists_ && dof == max_dof_)
          quiet_scale_ += (nis_ / dof - quiet_scale_) / s_.quiet_memory;
      }
      jump_ = predicted_jump(x);
      evaluate(residual_, x, u, dt, r_.data());  // r at this estimate
      // the innovation this estimate's residual implies, S R^-1 r (an exact update of a
      // linear model leaves r = R S^-1 nu), and its NIS: (R^-1 r)^T S (R^-1 r)
      Eigen::VectorXd w(dof);
      for (int a = 0; a < dof; ++a) w[a] = r_[rows_[a]] * r_inv_[rows_[a]];
      fit_nis_ = w.dot(S_ * w);
      // an update that was not a linear one: is the shift to the readings' own shape
      // within this estimate's covariance? (not asked where no shift limit is finite:
      // a model with pseudo-measurements, whose update is not a linear one of the
      // readings alone)
      if (shift_judged_ && fit_nis_ > s_.limit[dof]) shift_ = shift_to_fit(x, P, u, dt);
    } else {
      evaluate(residual_, x, zeros_u_.data(), 0.0, r_.data());
      last_dt_ = 0.0;  // shift_inflation_at: the readings at this estimate alone
      if (s_.nu) last_u_.assign(zeros_u_.begin(), zeros_u_.end());
      shift_ready_ = shift_judged_;
    }
    const double* r = r_.data();
    for (int i : rows_) fit_ += r[i] * r[i] * r_inv_[i];
  }
  t0_ = t;
  std::copy(x, x + nx, x0_.begin());
  std::copy(P, P + nx * nx, P0_.begin());
  has_prev_ = true;
  if (dof == 0) return false;
  const double worst = std::max(fit_, nis_);
  const bool high = high_;
  high_ = worst > s_.run_limit[dof];
  // the level the readings scattered at while the model followed them (never above R's):
  // the average is judged against it, as readings less noisy than R says make a model
  // error show only against their own level
  const double level = std::min(1.0, quiet_scale_);
  if (avg_dof_ > 0 && noise_scale_ > s_.avg_limit[avg_dof_] * level) {
    persists_ = true;
    quiet_run_ = 0;
    model_error_ = std::max(model_error_, noise_scale_ - level);
  } else if (persists_ && noise_scale_ <= level) {
    // a model error ends once the average has stayed at the quiet level for as many
    // samples as it remembers: a motion that shows the error only in some of its
    // phases leaves the average low for a few samples between them
    if (++quiet_run_ >= s_.memory) persists_ = false;
  } else {
    quiet_run_ = 0;
  }
  const bool unexplained = fit_nis_ > s_.limit[dof] && shift_ > s_.shift_limit[shift_dof_];
  // an estimate that moved from the prediction farther than readings within the limit
  // could move a linear update: a nonlinear update (an MHE's window, a UKF's sigma
  // points) onto a shape its linearised prediction called near (a reading half a turn
  // off, which the wide prediction of a low rate does not rule out)
  const bool jumped = jump_ > s_.limit[dof];
  return worst > s_.limit[dof] || (high && high_) || persists_ || unexplained || jumped;
}

double ConsistencyCheck::shift_inflation_at(const double* x, const double* P) {
  if (!shift_ready_ || rows_.empty()) return 1.0;
  const int kept = shift_dof_;
  const double shift = shift_to_fit(x, P, s_.nu ? last_u_.data() : nullptr, last_dt_);
  const int dof = shift_dof_;
  shift_dof_ = kept;  // shift_inflation() stays the check's
  if (!(shift > 0.0) || dof <= 0) return 1.0;
  return std::max(1.0, shift / s_.shift_limit[dof]);
}

void ConsistencyCheck::weighted_jacobian(RowMatrix& Hs, RowMatrix& wh) {
  const int nx = s_.nx, nz = s_.nz, nr = static_cast<int>(rows_.size());
  ConstRowMap H(Hr_.data(), nz, nx);
  cols_.clear();  // the states the readings depend on
  for (int c = 0; c < nx; ++c)
    for (int i : rows_)
      if (H(i, c) != 0.0) {
        cols_.push_back(c);
        break;
      }
  const int nc = static_cast<int>(cols_.size());
  Hs.resize(nr, nc);
  wh.resize(nr, nc);
  for (int a = 0; a < nr; ++a)
    for (int c = 0; c < nc; ++c) {
      Hs(a, c) = H(rows_[a], cols_[c]);
      wh(a, c) = Hs(a, c) * r_inv_[rows_[a]];  // R^-1 H
    }
}

double ConsistencyCheck::shift_to_fit(const double* x, const double* P, const double* u,
                                      double dt) {
  const int nx = s_.nx, nz = s_.nz, dof = static_cast<int>(rows_.size());
  evaluate(measurement_, x, u, dt, Hr_.data());  // H and r at this estimate
  ConstRowMap Pm(P, nx, nx);
  const double* r = Hr_.data() + nz * nx;
  RowMatrix Hs, wh;
  weighted_jacobian(Hs, wh);
  const int nc = static_cast<int>(cols_.size());
  shift_dof_ = std::min(nc, dof);
  if (nc == 0) return 0.0;
  RowMatrix Pc(nc, nc);
  Eigen::VectorXd wr(dof);
  for (int a = 0; a < dof; ++a) wr[a] = r[rows_[a]] * r_inv_[rows_[a]];  // R^-1 r
  for (int i = 0; i < nc; ++i)
    for (int j = 0; j < nc; ++j) Pc(i, j) = Pm(cols_[i], cols_[j]);
  // the weighted least-squares shift that fits the readings: (H^T R^-1 H)^+ H^T R^-1 r
  const Eigen::VectorXd d = pinv_symmetric(Hs.transpose() * wh, s_.rcond) * (Hs.transpose() * wr);
  return d.dot(pinv_symmetric(Pc, s_.rcond) * d);
}

void ConsistencyCheck::predict(const double* x0, const double* P0, double dt, const double* z,
                               const double* mask, const double* u, const double* Q) {
  const int nx = s_.nx, nz = s_.nz, nu = s_.nu;
  set_readings(z, mask);
  const size_t size = static_cast<size_t>(nx) * (1 + 2 * nx) + 1 + nu + nz;
  key_.resize(size);
  double* k = key_.data();
  k = std::copy(x0, x0 + nx, k);
  k = std::copy(P0, P0 + nx * nx, k);
  *k++ = dt;
  if (nu) k = std::copy(u, u + nu, k);
  k = std::copy(Q, Q + nx * nx, k);
  std::copy(zv_.begin(), zv_.end(), k);
  if (has_pred_ && pred_key_.size() == size &&
      std::memcmp(pred_key_.data(), key_.data(), size * sizeof(double)) == 0)
    return;
  evaluate(transition_, x0, u, dt, fF_.data());                // x+ = f(x0, u, dt), F
  evaluate(measurement_, fF_.data(), u, dt, pred_Hr_.data());  // H and r at x+
  ConstRowMap F(fF_.data() + nx, nx, nx), P(P0, nx, nx), Qm(Q, nx, nx);
  Pn_.noalias() = F * P * F.transpose();
  Pn_ += Qm;
  pred_key_.swap(key_);
  has_pred_ = true;
}

double ConsistencyCheck::predicted_jump(const double* x) {
  const int nx = s_.nx;
  jump_y_.resize(nx);
  for (int i = 0; i < nx; ++i) jump_y_[i] = x[i] - fF_[i];  // fF_ holds f(x0) first
  // Pn = T^T L D L^T T (pivoted, from its lower triangle): d^T Pn^+ d = sum y_i^2 / D_i
  // with y = L^-1 T d, over the pivots above the rounding of the largest (directions the
  // prediction holds below it say nothing)
  jump_ldlt_.compute(Pn_);
  jump_y_ = jump_ldlt_.transpositionsP() * jump_y_;
  jump_ldlt_.matrixL().solveInPlace(jump_y_);
  const auto D = jump_ldlt_.vectorD();
  const double floor = 1e-12 * std::max(D.maxCoeff(), 0.0);
  double stat = 0.0;
  for (int i = 0; i < nx; ++i)
    if (D[i] > floor) stat += jump_y_[i] * jump_y_[i] / D[i];
  return stat;
}

double ConsistencyCheck::predicted_nis(const double* x0, const double* P0, double dt,
                                       const double* z, const double* mask, const double* u,
                                       const double* Q, const std::vector<int>& rows) {
  const int nx = s_.nx, nz = s_.nz, dof = static_cast<int>(rows.size());
  predict(x0, P0, dt, z, mask, u, Q);
  ConstRowMap H(pred_Hr_.data(), nz, nx);
  const double* r_pred = pred_Hr_.data() + nz * nx;
  const RowMatrix& Pn = Pn_;
  RowMatrix Hj(dof, nx);
  Eigen::VectorXd rp(dof);
  for (int a = 0; a < dof; ++a) {
    Hj.row(a) = H.row(rows[a]);
    rp[a] = r_pred[rows[a]];
  }
  S_.resize(dof, dof);
  S_.noalias() = Hj * Pn * Hj.transpose();
  for (int a = 0; a < dof; ++a)
    for (int b = 0; b < dof; ++b) S_(a, b) += s_.R[rows[a] * nz + rows[b]];
  return rp.dot(S_.partialPivLu().solve(rp));
}

void ConsistencyCheck::predicted_nis_given(const double* x0, const double* P0, double dt,
                                           const double* z, const double* mask, const double* u,
                                           const double* Q,
                                           const std::vector<std::vector<int>>& sets,
                                           const std::vector<int>& given,
                                           std::vector<double>& out,
                                           std::vector<double>* whitened,
                                           const double* z_jac) {
  const int nx = s_.nx, nz = s_.nz;
  out.assign(sets.size(), 0.0);
  if (whitened) whitened->assign(sets.size(), 0.0);
  if (sets.empty()) return;
  predict(x0, P0, dt, z, mask, u, Q);
  const double* r_pred = pred_Hr_.data() + nz * nx;
  const double* jac = pred_Hr_.data();
  if (z_jac) {
    set_readings(z_jac, mask);
    jac_Hr_.resize(pred_Hr_.size());
    evaluate(measurement_, fF_.data(), u, dt, jac_Hr_.data());
    jac = jac_Hr_.data();
  }
  ConstRowMap H(jac, nz, nx);
  const RowMatrix& Pn = Pn_;
  // the innovation covariance and residual over rows ``a`` (rows) against rows ``b``
  auto block = [&](const std::vector<int>& a, const std::vector<int>& b) {
    RowMatrix Ha(a.size(), nx), Hb(b.size(), nx);
    for (size_t i = 0; i < a.size(); ++i) Ha.row(i) = H.row(a[i]);
    for (size_t i = 0; i < b.size(); ++i) Hb.row(i) = H.row(b[i]);
    RowMatrix S = Ha * Pn * Hb.transpose();
    for (size_t i = 0; i < a.size(); ++i)
      for (size_t j = 0; j < b.size(); ++j) S(i, j) += s_.R[a[i] * nz + b[j]];
    return S;
  };
  auto residual = [&](const std::vector<int>& a) {
    Eigen::VectorXd r(a.size());
    for (size_t i = 0; i < a.size(); ++i) r[i] = r_pred[a[i]];
    return r;
  };
  const bool conditioned = !given.empty();
  Eigen::PartialPivLU<RowMatrix> lu_g;
  Eigen::VectorXd rg;
  if (conditioned) {
    lu_g.compute(block(given, given));
    rg = residual(given);
  }
  for (size_t k = 0; k < sets.size(); ++k) {
    const std::vector<int>& a = sets[k];
    RowMatrix Saa = block(a, a);
    Eigen::VectorXd ra = residual(a);
    if (whitened) {
      RowMatrix Ra(a.size(), a.size());
      for (size_t i = 0; i < a.size(); ++i)
        for (size_t j = 0; j < a.size(); ++j) Ra(i, j) = s_.R[a[i] * nz + a[j]];
      (*whitened)[k] = ra.dot(Ra.partialPivLu().solve(ra));
    }
    if (conditioned) {  // the innovation of a given that of ``given``
      const RowMatrix Sag = block(a, given);
      ra -= Sag * lu_g.solve(rg);
      Saa -= Sag * lu_g.solve(RowMatrix(Sag.transpose()));
    }
    out[k] = ra.dot(Saa.partialPivLu().solve(ra));
  }
}

void ConsistencyCheck::constant_error_cov(const double* z, const double* mask, const double* x,
                                          double* out) {
  const int nx = s_.nx, nz = s_.nz;
  std::fill(out, out + nx * nx, 0.0);
  // the model error learned, or the floor assumed before the readings show one
  std::vector<double>& bias = cov_.bias;
  bias.assign(s_.bias.begin(), s_.bias.end());
  for (int i = 0; i < nz; ++i)  // (accel_err2_ is zero without the own-acceleration model)
    if (s_.gravity_r[i] > 0.0)
      bias[i] += std::max({model_error_ * s_.gravity_r[i], s_.model_error_floor, accel_err2_[i]});
  rows_.clear();
  for (int i = 0; i < nz; ++i)
    if (mask[i] > 0.0 && bias[i] > 0.0) rows_.push_back(i);
  const int nr = static_cast<int>(rows_.size());
  if (nr == 0) return;
  set_readings(z, mask);
  evaluate(measurement_, x, zeros_u_.data(), 0.0, Hr_.data());
  // every sample: the matrices keep their storage from one sample to the next
  RowMatrix &Hs = cov_.Hs, &wh = cov_.wh, &A = cov_.A, &C = cov_.C;
  weighted_jacobian(Hs, wh);
  const int nc = static_cast<int>(cols_.size());
  Eigen::VectorXd& b = cov_.b;
  b.resize(nr);
  for (int a = 0; a < nr; ++a) b[a] = bias[rows_[a]];
  cov_.info.noalias() = Hs.transpose() * wh;
  if (!s_.range_info.empty())
    for (int i = 0; i < nc; ++i) cov_.info(i, i) += s_.range_info[cols_[i]];
  pinv_symmetric(cov_.info, s_.rcond, cov_.pinv, cov_.info_pinv);
  A.noalias() = cov_.info_pinv * wh.transpose();
  C.noalias() = A * b.asDiagonal() * A.transpose();
  for (int i = 0; i < nc; ++i)
    for (int j = 0; j < nc; ++j) out[cols_[i] * nx + cols_[j]] = C(i, j);
}

}  // namespace cmhe
