#include "sensor_health.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cmhe {

const char* const STATUS_NAMES[ST_COUNT] = {
    "ok",          "dropout",        "not-converged", "solver-failed",
    "no-estimate", "fallback-ipopt", "branch-restart", "reset",
    "uncertain",   "drifted",        "at-bound",      "inconsistent"};

namespace {

// Whether the time ``span`` (s) between two samples, the later at ``t`` (s), is longer
// than ``limit`` (s) by more than the times' rounding: steps of exactly the limit (0.05 s
// at 20 Hz, 0.050000000000000044 as the times subtract; a file's times kept to the
// microsecond) are not longer. The rounding of a difference of two times is a few units
// in the last place of ``t`` (2e-7 s at a Unix time of 1.7e9 s), not a share of ``t``
// (1e-9 of it would be 1.7 s there, hiding every gap shorter than that)
bool longer(double span, double limit, double t) {
  return span > limit + 1e-6 + 8.0 * std::numeric_limits<double>::epsilon() * std::fabs(t);
}
// A step between valid samples more than this many times their average step is a jump
// (a clock that stepped forward, a block of samples lost), and the average's weight
constexpr double kJumpSteps = 5.0;
constexpr double kStepWeight = 0.1;
bool trusted(int status) {
  return status == ST_OK || status == ST_FALLBACK_IPOPT || status == ST_BRANCH_RESTART;
}
bool any_positive(const std::vector<double>& v) {
  return std::any_of(v.begin(), v.end(), [](double m) { return m > 0.0; });
}
}  // namespace

// --- StateChecks ------------------------------------------------------------------------

bool StateChecks::flag(const double* x, int k) const {
  if (!flags) return false;
  double out[3];
  const double* in[1] = {x};
  flags->evaluate(in, out);
  return out[k] != 0.0;
}

bool StateChecks::is_diverged(const double* x, const double* P) const {
  for (int i = 0; i < nx; ++i)
    if (!std::isfinite(x[i])) return true;
  if (flag(x, 0)) return true;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const double a = x[pairs[k].first], b = x[pairs[k].second];
    if (a * a + b * b > diverged_r2[k]) return true;
  }
  for (int r : rate_rows)
    if (std::fabs(x[r]) > rate_limit) return true;
  if (!P) return false;
  for (int i = 0; i < nx * nx; ++i)
    if (!std::isfinite(P[i])) return true;
  for (int r : std_rows)
    if (P[r * nx + r] > std_limit2) return true;
  return false;
}

bool StateChecks::at_bound(const double* x) const {
  for (size_t k = 0; k < pairs.size(); ++k)
    if (std::hypot(x[pairs[k].first], x[pairs[k].second]) >= at_bound_r[k]) return true;
  return flag(x, 1);
}

bool StateChecks::drifted(const double* x) const { return flag(x, 2); }

// --- CompiledInputs ---------------------------------------------------------------------

void CompiledInputs::operator()(const double* z_prev, const double* z, double dt,
                                double* u) const {
  bool finite = z_prev != nullptr;
  for (int i = 0; finite && i < nz; ++i) finite = std::isfinite(z_prev[i]) && std::isfinite(z[i]);
  if (!finite) {
    std::fill(u, u + nu, 0.0);
    return;
  }
  const double* in[3] = {z_prev, z, &dt};
  fn->evaluate(in, u);
}

// --- ProcessModel -----------------------------------------------------------------------

ProcessModel::ProcessModel(int nx_, int nu_, int nz_, QFunction compute, InputFunction inputs)
    : nx(nx_), nu(nu_), nz(nz_), compute_(std::move(compute)), inputs_(std::move(inputs)) {
  scratch_.resize(2 * nx * nx);
  u_.assign(nu, 0.0);
}

std::pair<const double*, const double*> ProcessModel::noise(double dt) {
  const double key_d = std::nearbyint(dt * 1e9);  // Python's round(dt, 9), as a count
  const bool cacheable = std::isfinite(key_d) && std::fabs(key_d) < 9e18;
  const size_t n2 = static_cast<size_t>(nx) * nx;
  if (cacheable) {
    auto it = cache_.find(static_cast<int64_t>(key_d));
    if (it != cache_.end()) return {it->second.data(), it->second.data() + n2};
  }
  compute_(dt, scratch_.data(), scratch_.data() + n2);
  if (cacheable && cache_.size() < 4096) {
    auto& v = cache_[static_cast<int64_t>(key_d)];
    v = scratch_;
    return {v.data(), v.data() + n2};
  }
  return {scratch_.data(), scratch_.data() + n2};
}

const double* ProcessModel::inputs(const double* z_prev, const double* z, double dt) {
  if (nu > 0) inputs_(z_prev, z, dt, u_.data());
  return u_.data();
}

// --- SensorHealth -----------------------------------------------------------------------

SensorHealth::SensorHealth(PolicySettings settings, PolicyInference& inference,
                           ProcessModel& process, ConsistencyCheck& consistency,
                           std::function<bool(const std::vector<int>&)> observable,
                           std::function<FreeBends(const std::vector<int>&)> free_of)
    : s_(std::move(settings)),
      inference_(inference),
      process_(process),
      consistency_(consistency),
      observable_(std::move(observable)),
      free_of_(std::move(free_of)) {
  const size_t nb = s_.imu_blocks.size();
  freeze_value_.assign(static_cast<size_t>(s_.nz), 0.0);
  freeze_since_.assign(nb, -INFINITY);
  freeze_last_t_.assign(nb, -INFINITY);
  imu_last_valid_.assign(nb, -INFINITY);
  freeze_count_.assign(nb, 0);
  has_freeze_value_.assign(nb, 0);
  frozen_now_.assign(nb, 0);
  imu_seen_.assign(nb, 0);
  reads_now_.assign(nb, 0);
  late_pending_.assign(nb, 0);
  gate_x_.resize(s_.nx);
  gate_P_.resize(static_cast<size_t>(s_.nx) * s_.nx);
  gate_z_.resize(s_.nz);
  gated_z_.resize(s_.nz);
  gated_mask_.resize(s_.nz);
  imu_row_.assign(static_cast<size_t>(s_.nz), 0);
  for (const auto& [start, size] : s_.imu_blocks)
    for (int i = start; i < start + size; ++i) imu_row_[i] = 1;
  z_.resize(s_.nz);
  mask_.resize(s_.nz);
  zero_mask_.assign(s_.nz, 0.0);
  bias_.resize(static_cast<size_t>(s_.nx) * s_.nx);
  P_free_.resize(static_cast<size_t>(s_.nx) * s_.nx);
  std_b_.resize(s_.ny);
  static_free_ = FreeBends{s_.free_pairs, s_.free_reach};
  free_x_.resize(s_.nx);
  free_y_.resize(s_.ny);
  free_msd_.resize(s_.ny);
  free_wrapped_.assign(s_.ny, 0);
  for (int i : s_.wrapped_outputs) free_wrapped_[i] = 1;
  prev_x_.resize(s_.nx);
  last_x_.resize(s_.nx);
  last_P_.resize(static_cast<size_t>(s_.nx) * s_.nx);
  prev_P_.resize(static_cast<size_t>(s_.nx) * s_.nx);
  prev_z_.resize(s_.nz);
  cons_z_.resize(s_.nz);
  held_z_.assign(s_.nz, 0.0);
  held_t_.assign(s_.nz, -INFINITY);
  held_mask_.assign(s_.nz, 0.0);
  if (static_cast<int>(s_.start_limit.size()) != s_.nz + 1)
    throw std::invalid_argument("start_limit must hold nz + 1 values");
  reset(false, false);
}

void SensorHealth::widen_by_free_bends(const double* x, const double* y, double* ystd,
                                       const FreeBends& free) {
  // the root mean square of the outputs' moves from the estimate's over the free bends'
  // shapes, in quadrature with the standard deviation: the estimate is one of them,
  // and where the readings do not pin them the robot may be any other
  const int ny = s_.ny;
  const size_t np = free.pairs.size();
  if (np > free_slots_) {
    // shapes spread evenly over each free section's reach (its disk of bend vectors,
    // uniform in area): a Kronecker sequence, one pair of irrational steps per section
    free_unit_.resize(FREE_SHAPES * np * 2);
    for (size_t j = 0; j < FREE_SHAPES; ++j)
      for (size_t p = 0; p < np; ++p) {
        const double u = std::fmod((j + 0.5) * std::sqrt(2.0 + 4.0 * p), 1.0);
        const double v = std::fmod((j + 0.5) * std::sqrt(3.0 + 4.0 * p), 1.0);
        const double r = std::sqrt(u), a = 2.0 * M_PI * v;
        free_unit_[(j * np + p) * 2] = r * std::cos(a);
        free_unit_[(j * np + p) * 2 + 1] = r * std::sin(a);
      }
    free_slots_ = np;
  }
  std::fill(free_msd_.begin(), free_msd_.end(), 0.0);
  for (size_t j = 0; j < FREE_SHAPES; ++j) {
    std::copy(x, x + s_.nx, free_x_.begin());
    for (size_t p = 0; p < np; ++p) {
      free_x_[free.pairs[p].first] = free.reach[p] * free_unit_[(j * free_slots_ + p) * 2];
      free_x_[free.pairs[p].second] = free.reach[p] * free_unit_[(j * free_slots_ + p) * 2 + 1];
    }
    inference_.output(free_x_.data(), free_y_.data());
    for (int i = 0; i < ny; ++i) {
      const double d = free_wrapped_[i] ? std::remainder(free_y_[i] - y[i], 2.0 * M_PI)
                                        : free_y_[i] - y[i];
      free_msd_[i] += d * d;
    }
  }
  for (int i = 0; i < ny; ++i)
    ystd[i] = std::sqrt(ystd[i] * ystd[i] + free_msd_[i] / static_cast<double>(FREE_SHAPES));
}

const FreeBends& SensorHealth::free_now(double t) {
  if (!free_of_ || s_.imu_blocks.size() < 2) return static_free_;
  // silent for the unobserved window: its covariance alone holds for a shorter dropout
  if (!reporting_imus(t, unobserved_window())) return static_free_;  // all, or a gap
  auto it = free_cache_.find(reporting_);
  if (it == free_cache_.end()) it = free_cache_.emplace(reporting_, free_of_(reporting_)).first;
  return it->second;
}

bool SensorHealth::reporting_imus(double t, double window) {
  const size_t n = s_.imu_blocks.size();
  reporting_.clear();
  for (size_t k = 0; k < n; ++k)  // a frozen IMU observes nothing, however recent
    if (!longer(t - imu_last_valid_[k], window, t) && !frozen_now_[k])
      reporting_.push_back(static_cast<int>(k));
  return !reporting_.empty() && reporting_.size() < n;
}

void SensorHealth::reset(bool keep_counts, bool keep_sensors) {
  if (!keep_counts) {  // a new recording (else a restart within one: its drift is kept)
    diagnostics = PolicyDiagnostics();
    drifted_t_ = -INFINITY;
  }
  drift_since_ = NAN;
  drift_armed_ = true;
  last_t_ = last_valid_t_ = first_valid_t_ = -INFINITY;
  step_avg_ = NAN;
  whole_missing_ = 0;
  other_missing_ = false;
  std::fill(has_freeze_value_.begin(), has_freeze_value_.end(), 0);
  std::fill(frozen_now_.begin(), frozen_now_.end(), 0);
  gate_has_ = false;
  std::fill(freeze_since_.begin(), freeze_since_.end(), -INFINITY);
  std::fill(freeze_last_t_.begin(), freeze_last_t_.end(), -INFINITY);
  std::fill(freeze_count_.begin(), freeze_count_.end(), 0);
  std::fill(imu_last_valid_.begin(), imu_last_valid_.end(), -INFINITY);
  std::fill(late_pending_.begin(), late_pending_.end(), 0);
  returned_.clear();
  forced_before_t_ = -INFINITY;
  hold_ = 0.0;
  end_chain();
  forced_t_.clear();
  // a restart within a recording keeps the model error learned, as a gap's does: the
  // model does not follow the robot better for it
  if (!keep_counts) consistency_.reset();
  if (!keep_counts) has_last_ = false;  // a new recording: another robot's sensors, maybe
  // a caller that keeps no sensor states (a new recording, a failure that may have come
  // from them) keeps none for a drift reset either
  if (!(keep_counts && keep_sensors)) has_ok_ = false;
  restart(keep_counts && keep_sensors);
}

void SensorHealth::restart(bool keep_sensors) {
  start_clear();
  // the previous estimate only: the average, its run and the model error learned are
  // the robot's, and a restart does not make the model follow
  consistency_.forget();
  cons_has_prev_ = false;
  gate_has_ = false;
  rejecting_since_.reset();
  wide_t_ = -INFINITY;
  wide_row_t_ = -INFINITY;
  jumped_t_ = -INFINITY;
  unconfirmed_ = 0;
  started_ = false;
  start_untrusted_ = start_judged_ = false;
  restarted_since_drift_ = true;  // drifted_t_ is kept: see step
  // the drift reset times the drifted rows since the last ok row or restart (a drift
  // reset after another restart would restart a start that has not drifted)
  drift_since_ = NAN;
  change_past_.clear();  // a restart's estimate jumps: its change says nothing
  changed_until_ = -INFINITY;
  std::fill(held_t_.begin(), held_t_.end(), -INFINITY);  // a start holds no past reading
  std::fill(imu_seen_.begin(), imu_seen_.end(), 0);
  if (!keep_sensors) has_last_ = false;
  inference_.restart(has_last_ ? last_x_.data() : nullptr, has_last_ ? last_P_.data() : nullptr,
                     last_state_t_);
}

double SensorHealth::unobserved_window() const {
  return std::isnan(s_.gap_reset) || s_.gap_reset == 0.0 ? s_.unobserved_after : s_.gap_reset;
}

double SensorHealth::tip_std(const double* ystd) const {
  double sum = 0.0;
  for (int i : s_.tip_rows) sum += ystd[i] * ystd[i];
  return std::sqrt(sum);
}

const double* SensorHealth::unfreeze(double t, const double* z, bool& frozen) {
  frozen = false;
  if (std::isnan(s_.freeze)) return z;
  const double freeze = s_.freeze;
  // a step longer than an IMU's silence (the gap reset, else 1 s), or than the freeze
  // where that is longer, is a gap in the data: the count starts again
  const double gap_step = std::max(freeze, unobserved_window());
  bool copied = false;
  for (size_t k = 0; k < s_.imu_blocks.size(); ++k) {
    const auto [start, size] = s_.imu_blocks[k];
    const double* zb = z + start;
    double* last = freeze_value_.data() + start;
    const bool gap = longer(t - freeze_last_t_[k], gap_step, t);
    freeze_last_t_[k] = t;
    bool same = has_freeze_value_[k] != 0;
    const double* tol = s_.freeze_tolerance.data() + start;
    for (int i = 0; same && i < size; ++i)  // NaN never repeats
      same = std::fabs(zb[i] - last[i]) <= tol[i];
    if (!has_freeze_value_[k] || gap || !same) {
      frozen_now_[k] = 0;
      std::copy(zb, zb + size, last);
      has_freeze_value_[k] = 1;
      freeze_since_[k] = t;
      freeze_count_[k] = 1;
      continue;
    }
    ++freeze_count_[k];
    // both: two equal readings with a long gap between them are not a freeze
    if (freeze_count_[k] >= s_.freeze_samples && longer(t - freeze_since_[k], freeze, t)) {
      if (!copied) {
        std::copy(z, z + s_.nz, z_.begin());
        copied = true;
      }
      std::fill(z_.begin() + start, z_.begin() + start + size, NAN);
      frozen_now_[k] = 1;
      // its last reading is that of the freeze's start: the repeated ones since then were
      // no readings, so its silence (which unobserves its part of the shape) dates from it
      imu_last_valid_[k] = std::min(imu_last_valid_[k], freeze_since_[k]);
      auto& first = diagnostics.first_freezes;
      const int kk = static_cast<int>(k);
      if (std::none_of(first.begin(), first.end(), [kk](const auto& f) { return f.first == kk; }))
        first.emplace_back(kk, freeze_since_[k]);
    }
  }
  if (!copied) return z;
  ++diagnostics.frozen_samples;
  frozen = true;
  return z_.data();
}

void SensorHealth::measurement_mask(const double* z) {
  std::fill(mask_.begin(), mask_.end(), 0.0);
  for (int i : s_.whole_rows)
    if (!std::isfinite(z[i])) return;
  for (const auto& [start, size] : s_.blocks) {
    bool finite = true;
    for (int i = start; finite && i < start + size; ++i) finite = std::isfinite(z[i]);
    if (finite) std::fill(mask_.begin() + start, mask_.begin() + start + size, 1.0);
  }
}

bool SensorHealth::note_imus(double t) {
  back_rows_.clear();
  if (first_valid_t_ == -INFINITY) {
    if (!any_positive(mask_)) return false;
    first_valid_t_ = t;
  }
  const double window = unobserved_window();
  const double silent = std::min(window, s_.silent_after);
  for (size_t k = 0; k < s_.imu_blocks.size(); ++k) {
    const auto [start, size] = s_.imu_blocks[k];
    if (mask_[start] > 0.0) {
      if (longer(t - imu_last_valid_[k], window, t) && longer(t - first_valid_t_, window, t))
        for (int i = start; i < start + size; ++i) back_rows_.push_back(i);
      if (longer(t - imu_last_valid_[k], silent, t)) late_pending_[k] = 1;  // first reading too
      imu_last_valid_[k] = t;
    }
  }
  return !back_rows_.empty();
}

bool SensorHealth::imu_reading() const {
  return std::any_of(s_.imu_blocks.begin(), s_.imu_blocks.end(),
                     [this](const auto& b) { return mask_[b.first] > 0.0; });
}

bool SensorHealth::imu_joins() const {
  bool joins = false, any_seen = false;
  for (size_t k = 0; k < s_.imu_blocks.size(); ++k) {
    const bool reads = reads_now_[k];
    // a partial sample (a seen or waiting IMU without its reading): wait for a whole one
    if ((imu_seen_[k] || late_pending_[k]) && !reads) return false;
    joins = joins || (reads && late_pending_[k] && !imu_seen_[k]);
    any_seen = any_seen || imu_seen_[k];
  }
  return joins && any_seen;  // (no IMU seen yet: this sample is the start's first reading)
}

void SensorHealth::note_imus_seen() {
  const bool any_seen = std::any_of(imu_seen_.begin(), imu_seen_.end(), [](char c) { return c; });
  for (size_t k = 0; k < s_.imu_blocks.size(); ++k)
    if (reads_now_[k] && (imu_seen_[k] || !late_pending_[k] || !any_seen)) {
      imu_seen_[k] = 1;  // in the estimate from here; a late one waits for its restart
      late_pending_[k] = 0;
    }
}

bool SensorHealth::observed_now(double t) {
  if (!s_.shape_observable) return false;
  if (s_.imu_blocks.size() == 1) return true;  // its silence is the whole robot's gap
  if (!reporting_imus(t, std::min(unobserved_window(), s_.silent_after)))
    return true;  // all reporting, or none
  auto it = observable_cache_.find(reporting_);
  if (it != observable_cache_.end()) return it->second;
  const bool known = observable_(reporting_);
  observable_cache_.emplace(reporting_, known);
  return known;
}

// --- the bad-start check ---------------------------------------------------------------

void SensorHealth::start_clear() {
  since_ = NAN;
  has_prev_ = false;
  run_ = 0;
  agreed_since_ = NAN;
}

void SensorHealth::start_reopen(double hold) {
  start_clear();
  end_chain();  // a returned IMU: its readings are new evidence
  for (int r : back_rows_) returned_.push_back(r);
  std::sort(returned_.begin(), returned_.end());
  returned_.erase(std::unique(returned_.begin(), returned_.end()), returned_.end());
  hold_ = hold;
}

bool SensorHealth::start_watching(double t) const {
  if (!returned_.empty()) return true;
  return !std::isnan(s_.bad_start) && (std::isnan(since_) || t - since_ <= s_.bad_start);
}

bool SensorHealth::start_inconsistent(double t, const double* z) {
  const bool in_window = !std::isnan(s_.bad_start) && t - since_ <= s_.bad_start;
  if (!has_prev_ || !(in_window || !returned_.empty())) return false;
  // the consistency check's judged rows (the readings: a tendon robot's IMUs and
  // tensions), their innovation given the sample's other valid rows: a tip condition (a
  // pseudo-measurement, met by a step only to its linearisation) says nothing of the
  // readings but pins states the motion model leaves free; the rows a model reads as
  // inputs (a tendon robot's tension rates) have a zero residual at every state, and
  // counted among the degrees of freedom they would loosen the limit (that of 25 rows
  // for 10 readings with tilt IMUs) without adding to the statistic
  const auto& judged = consistency_.settings().judged;
  start_sets_.resize(1);
  std::vector<int>& rows = start_sets_[0];
  rows.clear();
  start_given_.clear();
  for (int i = 0; i < s_.nz; ++i)
    if (mask_[i] != 0.0) (judged[i] != 0.0 ? rows : start_given_).push_back(i);
  if (rows.empty()) return false;
  const double dt = t - prev_t_;
  const double* u = process_.inputs(prev_z_.data(), z, dt);
  const double* Q = process_.noise(dt).first;
  double value;
  if (start_given_.empty()) {
    value =
        consistency_.predicted_nis(prev_x_.data(), prev_P_.data(), dt, z, mask_.data(), u, Q, rows);
  } else {
    consistency_.predicted_nis_given(prev_x_.data(), prev_P_.data(), dt, z, mask_.data(), u, Q,
                                     start_sets_, start_given_, start_nis_);
    value = start_nis_[0];
  }
  const bool consistent = value <= s_.start_limit[rows.size()];
  run_ = consistent ? 0 : run_ + 1;
  if (!returned_.empty() &&
      std::all_of(returned_.begin(), returned_.end(), [&](int r) { return mask_[r] > 0.0; })) {
    if (!consistent)
      agreed_since_ = NAN;
    else if (std::isnan(agreed_since_))
      agreed_since_ = prev_t_;  // the estimate this reading agrees with
    if (t - agreed_since_ >= hold_) returned_.clear();  // NaN compares false
  }
  const bool fires = in_window && run_ >= s_.start_samples;
  // the readings were inconsistent after every one of the last restarts: another
  // restart from them would not fit either (counted once a chain)
  if (fires && s_.start_chain > 0 && chain_ >= s_.start_chain) {
    if (!chain_held_) ++diagnostics.bad_start_chains;
    chain_held_ = true;
    return false;
  }
  return fires;
}

void SensorHealth::start_remember(double t, const double* z, const double* x, const double* P,
                                  bool has_state, bool has_cov) {
  if (!has_state) return;
  if (std::isnan(since_)) since_ = t;
  if (!has_cov) {
    has_prev_ = false;
    return;
  }
  prev_t_ = t;
  std::copy(x, x + s_.nx, prev_x_.begin());
  std::copy(P, P + s_.nx * s_.nx, prev_P_.begin());
  std::copy(z, z + s_.nz, prev_z_.begin());
  has_prev_ = true;
}

const double* SensorHealth::gate_glitches(double t, const double* z, int& gated) {
  gated = 0;
  if (!(s_.glitch_factor > 0.0) || !s_.checks_start || !gate_has_ ||
      !(t - gate_t_ <= unobserved_window()))
    return z;
  const auto& judged = consistency_.settings().judged;
  // each IMU's judged readings, and the sample's other readings (a tendon robot's
  // tensions and tip condition) that its prediction is conditioned on
  // (the sets keep their storage from one sample to the next)
  gate_sets_.resize(s_.imu_blocks.size());
  gate_imus_.clear();
  size_t n = 0;
  for (size_t b = 0; b < s_.imu_blocks.size(); ++b) {
    const auto [start, size] = s_.imu_blocks[b];
    std::vector<int>& rows = gate_sets_[n];
    rows.clear();
    for (int i = start; i < start + size; ++i)
      if (mask_[i] > 0.0 && judged[i] != 0.0) rows.push_back(i);
    if (!rows.empty()) {
      gate_imus_.push_back(static_cast<int>(b));
      ++n;
    }
  }
  gate_sets_.resize(n);
  if (n == 0) return z;
  gate_given_.clear();
  for (int i = 0; i < s_.nz; ++i)
    if (!imu_row_[i] && mask_[i] > 0.0) gate_given_.push_back(i);
  const double dt = t - gate_t_;
  const double* u = process_.inputs(gate_z_.data(), z, dt);
  const double* Q = process_.noise(dt).first;
  consistency_.predicted_nis_given(gate_x_.data(), gate_P_.data(), dt, z, mask_.data(), u, Q,
                                   gate_sets_, gate_given_, gate_nis_, &gate_whitened_);
  const double scale = std::max(1.0, consistency_.noise_scale());
  gate_limit_.resize(n);
  for (size_t k = 0; k < n; ++k)
    gate_limit_[k] =
        s_.glitch_factor * consistency_.settings().limit[gate_sets_[k].size()] * scale;
  // a reading far from the prediction by its noise alone whose linearised prediction
  // widens as far (the tilt residual near the opposite gravity direction, where both
  // grow without bound): judged again with the Jacobian at the IMU's readings before,
  // where it agreed with the estimate
  std::vector<int> again;
  for (size_t k = 0; k < n; ++k) {
    bool before = true;
    for (int i : gate_sets_[k]) before = before && std::isfinite(gate_z_[i]);
    if (gate_nis_[k] <= gate_limit_[k] && gate_whitened_[k] > gate_limit_[k] && before)
      again.push_back(static_cast<int>(k));
  }
  if (!again.empty()) {
    std::vector<std::vector<int>> sets;
    std::copy(z, z + s_.nz, gated_z_.begin());  // scratch: z with those IMUs' readings before
    for (int k : again) {
      sets.push_back(gate_sets_[k]);
      for (int i : gate_sets_[k]) gated_z_[i] = gate_z_[i];
    }
    std::vector<double> nis;
    consistency_.predicted_nis_given(gate_x_.data(), gate_P_.data(), dt, z, mask_.data(), u, Q,
                                     sets, gate_given_, nis, nullptr, gated_z_.data());
    for (size_t j = 0; j < again.size(); ++j)
      gate_nis_[again[j]] = std::max(gate_nis_[again[j]], nis[j]);
  }
  const double* out = z;
  for (size_t k = 0; k < n; ++k) {
    const int b = gate_imus_[k];
    // from a start's first estimate, only such a reading (near the opposite gravity
    // direction) is a glitch: one far from the start by its prediction as well says
    // that the start may be wrong, which the bad-start check judges
    if (gate_from_start_ &&
        std::find(again.begin(), again.end(), static_cast<int>(k)) == again.end())
      continue;
    // (a NIS that is not finite is beyond any limit)
    if (!(gate_nis_[k] <= gate_limit_[k])) {
      if (out == z) {
        std::copy(z, z + s_.nz, gated_z_.begin());
        std::copy(mask_.begin(), mask_.end(), gated_mask_.begin());
        out = gated_z_.data();
      }
      const auto [start, size] = s_.imu_blocks[b];
      for (int i = start; i < start + size; ++i) {
        gated_z_[i] = NAN;
        gated_mask_[i] = 0.0;
      }
      ++gated;
    }
  }
  return out;
}

bool SensorHealth::consistency_check(double t, const double* z, const double* judged,
                                     const double* x, const double* P, bool has_state,
                                     bool has_cov) {
  if (!has_state || !has_cov) {
    consistency_.forget();
    cons_has_prev_ = false;
    return false;
  }
  const double* u = nullptr;
  const double* Q = nullptr;
  if (cons_has_prev_) {
    const auto& judged_rows = consistency_.settings().judged;
    bool any = false;
    for (int i = 0; i < s_.nz && !any; ++i) any = judged_rows[i] != 0.0 && judged[i] != 0.0;
    if (any) {
      const double dt = t - cons_t_;
      u = process_.inputs(cons_z_.data(), z, dt);
      Q = process_.noise(dt).first;
    }
  }
  cons_t_ = t;
  std::copy(z, z + s_.nz, cons_z_.begin());
  cons_has_prev_ = true;
  return consistency_.check(t, z, judged, x, P, u, Q);
}

bool SensorHealth::diverged(const double* x, const double* P) {
  return s_.checks ? s_.checks->is_diverged(x, P) : inference_.is_diverged(x, P);
}

bool SensorHealth::state_drifted(const double* x) {
  return s_.checks ? s_.checks->drifted(x) : inference_.drifted(x);
}

bool SensorHealth::changed_too_fast(double t, const double* x, const double* P) {
  const auto& rows = s_.change_rows;
  const int m = static_cast<int>(rows.size()), nx = s_.nx;
  ChangeEntry now{t, std::vector<double>(m), std::vector<double>(static_cast<size_t>(m) * m)};
  for (int i = 0; i < m; ++i) {
    now.x[i] = x[rows[i]];
    for (int j = 0; j < m; ++j) now.P[i * m + j] = P[static_cast<size_t>(rows[i]) * nx + rows[j]];
  }
  // the latest remembered estimate at least the lag ago (the older ones are not needed)
  while (change_past_.size() >= 2 && change_past_[1].t <= t - s_.change_lag)
    change_past_.pop_front();
  bool beyond = false;
  if (!change_past_.empty() && change_past_.front().t <= t - s_.change_lag) {
    const ChangeEntry& then = change_past_.front();
    const double dt = t - then.t;
    Eigen::MatrixXd S(m, m);
    Eigen::VectorXd d(m);
    for (int i = 0; i < m; ++i) {
      const double si = s_.change_scale[i];
      d[i] = (now.x[i] - then.x[i]) / si;
      for (int j = 0; j < m; ++j)
        S(i, j) = (then.P[i * m + j] - now.P[i * m + j] + (i == j ? s_.change_psd[i] * dt : 0.0)) /
                  (si * s_.change_scale[j]);
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (S + S.transpose()));
    // directions with little information gained are left out: the estimate may not move
    // there, and a change below the rounding of P says nothing
    const Eigen::VectorXd w = eig.eigenvalues();
    const Eigen::VectorXd y = eig.eigenvectors().transpose() * d;
    double stat = 0.0;
    int dof = 0;
    for (int i = 0; i < m; ++i)
      if (w[i] > kChangeFloor) {
        stat += y[i] * y[i] / w[i];
        ++dof;
      }
    beyond = dof > 0 && std::isfinite(stat) && stat > s_.change_limit[dof];
  }
  change_past_.push_back(std::move(now));
  return beyond;
}

int SensorHealth::infer_once(double t, const double* z, double* x, double* P, bool& has_state,
                             bool& has_cov, bool& failed) {
  failed = false;
  has_state = has_cov = false;
  try {
    return inference_.infer(t, z, mask_.data(), x, P, has_state, has_cov);
  } catch (const InferenceFailure& e) {
    diagnostics.last_failure = e.what();
  } catch (const std::runtime_error& e) {
    diagnostics.last_failure = std::string("RuntimeError: ") + e.what();
  }
  diagnostics.has_failure = true;
  failed = true;
  has_state = has_cov = false;
  return ST_NO_ESTIMATE;
}

int SensorHealth::step(double t, const double* z_in, double* x, double* P, double* y,
                       double* ystd, SampleResult& out) {
  if (!(std::isfinite(t) && t > last_t_)) return INPUT_TIME;
  for (int j = 0; j < s_.nz; ++j)  // a missing reading is NaN; an infinite one is refused
    if (std::isinf(z_in[j])) return INPUT_INFINITE;
  for (int i : s_.tilt_rows)
    if (std::fabs(z_in[i]) > s_.degrees_like) return INPUT_DEGREES;  // NaN compares false
  last_t_ = t;
  const auto start = std::chrono::steady_clock::now();
  out = SampleResult();
  const double* z = unfreeze(t, z_in, out.frozen);
  measurement_mask(z);
  for (size_t k = 0; k < s_.imu_blocks.size(); ++k)
    reads_now_[k] = mask_[s_.imu_blocks[k].first] > 0.0;
  const bool valid = any_positive(mask_);
  if (!valid) {  // a sample without the whole rows, or one without any reading at all
    bool whole_gone = false;
    for (int i : s_.whole_rows) whole_gone = whole_gone || !std::isfinite(z[i]);
    if (whole_gone)
      ++whole_missing_;
    else
      other_missing_ = true;
  }
  bool gap_reset = false;
  bool jump = false;  // a step many times the usual one, shorter than the gap reset
  const double valid_step = t - last_valid_t_;
  if (!std::isnan(s_.gap_reset) && valid) {
    gap_reset = -INFINITY < last_valid_t_ && longer(valid_step, s_.gap_reset, t);
    // without the tensions the prediction leaves the robot within a fraction of a
    // second: their return is a gap sooner
    if (whole_missing_ > 0 && !other_missing_ && !std::isnan(s_.whole_gap_reset))
      gap_reset = gap_reset || (-INFINITY < last_valid_t_ &&
                                longer(valid_step, s_.whole_gap_reset, t));
    whole_missing_ = 0;
    other_missing_ = false;
    if (!gap_reset && -INFINITY < last_valid_t_) {
      jump = std::isfinite(step_avg_) && longer(valid_step, kJumpSteps * step_avg_, t);
      if (!jump)
        step_avg_ = std::isfinite(step_avg_) ? step_avg_ + kStepWeight * (valid_step - step_avg_)
                                             : valid_step;
    }
    last_valid_t_ = t;
  }
  const bool back = note_imus(t);
  const bool observed = observed_now(t);
  // the glitches are judged against the estimate before any restart below, and skipped
  // only where none happens (a restart starts from this sample's readings); the
  // bad-start check counts them among the readings that disagree with a start, and the
  // silence tracking above as readings (an IMU that sent one reported)
  int gated = 0;
  const double* z_read = z;
  const double* z_gated = gate_glitches(t, z, gated);
  // an IMU that had not read since the (re)start, and not for the silence before it,
  // joins the others (a log whose topics start apart): its part of the shape was never
  // observed, and the window or filter would move it at once, a jump that the gyros'
  // biases take up; start again with it, at the first sample every IMU reads
  const bool late_start = !gap_reset && !std::isnan(s_.gap_reset) && valid && started_ &&
                          imu_joins();
  // the readings after a jump in t (a clock that stepped forward, samples lost) that the
  // glitch test would skip: the prediction across the jump, not one reading, is what
  // failed (by the stamps alone the robot may have moved for all that time), so they
  // restart the estimate as after a gap, and the summary names the jump
  const bool jump_reset = jump && !gap_reset && !late_start && gated > 0;
  // a restart the data's timing called for (a gap, a late IMU, a jump whose readings
  // disagree with the prediction across it), not the readings' values alone
  const bool data_restart = gap_reset || late_start || jump_reset;
  if (data_restart) {  // restart from this sample instead of a blind prediction
    if (jump_reset) {
      if (diagnostics.jump_resets++ == 0) {
        diagnostics.first_jump_t = t;
        diagnostics.first_jump_step = valid_step;
      }
    } else {
      ++(late_start ? diagnostics.late_imu_starts : diagnostics.gap_resets);
    }
    end_chain();
    restart(true);  // the sensors are those of the estimate before
  } else if (back && s_.checks_start) {
    // their part of the shape was predicted blindly: check it as after a start
    start_reopen(unobserved_window());
  }
  if (chain_ > 0 && t - since_ > s_.bad_start) end_chain();  // the last restart held
  bool bad_start = false;
  const bool check_start = s_.checks_start && start_watching(t);
  if (check_start) {
    bad_start = start_inconsistent(t, z);
    if (bad_start) {  // the start was wrong: restart from this reading
      ++diagnostics.bad_starts;
      ++chain_;
      restart(false);  // what it kept may be why
    }
  }
  bool reject_reset = false;
  if (rejecting_since_ && !std::isnan(s_.reject_reset) &&
      t - *rejecting_since_ > s_.reject_reset && valid) {
    reject_reset = true;  // restart from this reading
    ++diagnostics.reject_resets;
    end_chain();
    restart(false);
  }
  // rows drifted since the last ok one for longer than drift_reset: a fault that has
  // passed left the error states off; restart from those of the last ok estimate
  bool drift_reset = false;
  if (!data_restart && !bad_start && !reject_reset && valid && has_ok_ && drift_armed_ &&
      !std::isnan(s_.drift_reset) && !std::isnan(drift_since_) &&
      t - drift_since_ > s_.drift_reset) {
    drift_reset = true;
    ++diagnostics.drift_resets;
    has_last_ = true;  // the last ok estimate's, as last_x_ holds it
    restart(true);
    drift_armed_ = false;  // once after each ok row
  }
  // (the bad-start chain goes on across it: a model that no restart fits stops the
  // restarts the readings force)
  // the restarts this sample's readings forced (its estimate starts from them)
  const bool forced_restart = bad_start || reject_reset || drift_reset;
  if (gated > 0 && (data_restart || forced_restart)) gated = 0;
  if (gated > 0) {
    z = z_gated;
    std::copy(gated_mask_.begin(), gated_mask_.end(), mask_.begin());
    diagnostics.glitches += gated;
  }
  note_imus_seen();  // after this sample's restarts, which forget what was seen
  bool has_state = false, has_cov = false, failed = false;
  int status = infer_once(t, z, x, P, has_state, has_cov, failed);
  bool healthy = !failed && (!has_state || !diverged(x, has_cov ? P : nullptr));
  if (!healthy) {  // flag it and restart from this sample's measurement
    ++diagnostics.restarts;
    end_chain();
    restart(false);
    note_imus_seen();
    if (gated > 0) {  // the restart starts from this sample's readings, all of them
      diagnostics.glitches -= gated;
      gated = 0;
      z = z_read;
      measurement_mask(z);
    }
    status = infer_once(t, z, x, P, has_state, has_cov, failed);
    if (has_state && diverged(x, has_cov ? P : nullptr)) {
      restart(false);
      has_state = has_cov = false;
      status = ST_NO_ESTIMATE;
    }
    if (has_state) status = ST_RESET;
  }
  if ((data_restart || forced_restart) && has_state) status = ST_RESET;
  const bool forced = (forced_restart || !healthy) && has_state;
  const bool branched = status == ST_BRANCH_RESTART;  // the window's answer, another branch
  // a sample without any IMU's reading is a dropout, whatever else it carried (a
  // tendon robot's tensions update the estimate, but nothing read the robot) and
  // whichever solve answered it (IPOPT's fallback, another branch)
  const bool imu_read = s_.imu_blocks.empty() || imu_reading();
  if (trusted(status) && has_state && !imu_read) status = ST_DROPOUT;
  // a sample whose IMU readings were all skipped as glitches: inconsistent (the estimate
  // is the prediction), as one with some of them skipped (below)
  if (status == ST_DROPOUT && has_state && gated > 0) status = ST_INCONSISTENT;
  // the first estimate since a (re)start fits its one reading alone
  const bool first = has_state && !started_;
  if (has_state) started_ = true;
  // whether the start can be trusted, judged on its first IMU reading (a start on a
  // sample without one, as live's before its IMUs report, is judged on the next that
  // has one). A restart that keeps the sensor states keeps those of the last ok
  // estimate, which an untrusted start never gives.
  if (has_state && !start_judged_ && imu_read) {
    start_judged_ = true;
    start_untrusted_ = inference_.start_untrusted(t, z);
  }
  if (start_untrusted_ && has_state) {
    // no estimate of that start is ok (drifted where the model's error states have left
    // their prior: that says more), until the next restart
    ++diagnostics.untrusted_start_samples;
    if (trusted(status)) status = state_drifted(x) ? ST_DRIFTED : ST_UNCERTAIN;
  }
  if (check_start) start_remember(t, z, x, P, has_state, has_cov);
  if (trusted(status) && has_state && state_drifted(x)) status = ST_DRIFTED;
  if (trusted(status) && !observed) {
    status = ST_UNCERTAIN;  // the data do not determine the shape
  } else if (trusted(status) && !returned_.empty()) {
    status = ST_UNCERTAIN;  // an IMU is back and no reading has confirmed the estimate
  } else if (trusted(status) && has_state &&
             (s_.checks ? s_.checks->at_bound(x) : inference_.at_bound(x))) {
    status = ST_AT_BOUND;  // the bound, not the data, may have set the shape
    ++diagnostics.bound_samples;
  }
  double factor = 1.0, shift_factor = 1.0;
  bool start_unconfirmed = false;  // uncertain for that alone: the first row of a start
  if (s_.checks_start) {  // the readings against the estimates (consistency.hpp)
    // a reading the robust MHE rejected as an outlier is flagged as one, and says
    // nothing about the estimate
    const bool rejected = has_state && inference_.outlier();
    const double* judged = rejected ? zero_mask_.data() : mask_.data();
    const bool disagree = consistency_check(t, z, judged, x, P, has_state, has_cov);
    // a row whose newest reading the robust MHE rejected is not one its readings agree
    // with, whichever was wrong (a reading's glitch, or an estimate that followed a
    // burst and now rejects the clean readings after it): as a skipped glitch's row
    if ((disagree || gated > 0 || rejected) && trusted(status)) status = ST_INCONSISTENT;
    // a reading beyond the limit of one sample against the prediction (IMUs without
    // gyros, jump_hold): the estimator moved onto readings its model called impossible,
    // and a burst of wrong readings then agrees with the moved estimate as the robot's
    // would, so the rows after it are not trusted for the unobserved window (gyros see
    // that such a burst turned nothing, and flag it)
    const int dof = consistency_.dof();
    if (s_.jump_hold && has_state && has_cov && dof > 0) {
      const double limit = consistency_.settings().limit[dof];
      if (consistency_.nis() > limit) jumped_t_ = t;
    }
    if (trusted(status) && t - jumped_t_ < unobserved_window()) status = ST_UNCERTAIN;
    // restarts the readings forced, within the bad-start check's probation time (the
    // unobserved window where longer, or without the check): a run of them says the
    // readings contradict every estimate the model makes of them, so none is trusted
    // while it lasts (a robot file that is not the robot's, a motion the model cannot
    // follow), even where the readings agree with one for a few samples
    const double run_window = std::isnan(s_.bad_start)
                                  ? unobserved_window()
                                  : std::max(s_.bad_start, unobserved_window());
    while (!forced_t_.empty() && t - forced_t_.front() > run_window) forced_t_.pop_front();
    if (forced) forced_t_.push_back(t);
    const bool storm = static_cast<int>(forced_t_.size()) >= kRestartRun;
    if (storm && trusted(status)) status = ST_UNCERTAIN;
    // a model whose restarts are limited (a chain, start_chain): a bad start that follows
    // another within its probation time says the readings contradicted the last start,
    // and the filter started again on them may narrow around a shape that its error
    // states bend to the readings; no row is trusted until a restart has held for the
    // probation time (the chain ends)
    if (s_.start_chain > 0 && chain_ >= kChainUntrusted && trusted(status))
      status = ST_UNCERTAIN;
    // a restart the readings forced fits this one reading; the next start_samples
    // readings the check compares with the estimate (judged rows, not an outlier's)
    // confirm it when they agree, and until then it is not trusted
    // (the first estimate of a recording, or after a gap, is as unconfirmed: one later
    // reading that agrees with it confirms it)
    // A reading that disagrees with the first estimate of a recording (or after a gap)
    // before another confirmed it says that the readings may contradict the model from
    // the start (an IMU upside down, columns swapped): a wrong shape can then agree
    // with a few readings in a row, so confirm_samples of them must agree before it is
    // trusted. (A restart the readings forced takes start_samples; one forced at the
    // sample right after another takes confirm_samples, or as many as the unobserved
    // window holds where fewer, at least start_samples: a restart that the very next
    // reading fails says that the readings contradict each other, one of them wrong
    // (a reading half a turn off), and a restart from the next reading alone may land
    // on another shape that those readings share, which readings close in time agree
    // with as well.)
    if (forced) {
      int confirm = s_.start_samples;
      if (std::isfinite(forced_before_t_)) {
        // confirm_samples, or the readings the unobserved window holds where fewer
        // (a step of 0.2 s read as 0.2000001: the window holds 5, not 4)
        const double within = std::floor(unobserved_window() / (t - forced_before_t_) + 1e-9);
        const int held = within < s_.confirm_samples ? static_cast<int>(within)
                                                      : s_.confirm_samples;
        confirm = std::max(s_.start_samples, held);
      }
      unconfirmed_ = confirm_after_ = confirm;
    } else if (first) {
      confirm_after_ = s_.confirm_samples;
      unconfirmed_ = disagree ? confirm_after_ : 1;
      start_unconfirmed = trusted(status);
      if (trusted(status)) status = ST_UNCERTAIN;
    } else if (unconfirmed_ > 0) {
      const auto& rows = consistency_.settings().judged;
      bool compared = has_state && has_cov;
      bool any = false;
      for (int i = 0; i < s_.nz && compared && !any; ++i) any = rows[i] != 0.0 && judged[i] > 0.0;
      if (compared && any) unconfirmed_ = disagree ? confirm_after_ : unconfirmed_ - 1;
      if (unconfirmed_ > 0 && trusted(status)) status = ST_UNCERTAIN;
    }
    // the last sample with an IMU reading forced a restart: a sample without one (a
    // dropout, a tension-only line) between the two does not part them
    if (forced)
      forced_before_t_ = t;
    else if (imu_read)
      forced_before_t_ = -INFINITY;
    const double scale = consistency_.noise_scale();
    factor = scale > 1.0 ? std::sqrt(scale) : 1.0;
    // a row whose readings this estimate cannot explain (inconsistent, or another
    // status that is not ok): its covariance grows until the shift that would fit them
    // lies within it, so that its standard deviation says how far off the readings put
    // it (after the statuses are decided: it changes no row's status)
    // (the shift is measured against the plain covariance: the model error's widening
    // already counts towards it)
    if (disagree)
      shift_factor = std::sqrt(std::max(1.0, consistency_.shift_inflation() / std::max(1.0, scale)));
    diagnostics.max_noise_scale = std::max(diagnostics.max_noise_scale, scale);
    diagnostics.model_error = std::max(diagnostics.model_error, consistency_.model_error());
  }
  if (has_state) inference_.output(x, y);
  if (has_state && has_cov) {
    const int ny = s_.ny;
    inference_.output_std(x, P, ystd);
    if (factor != 1.0)  // the model error the readings show (covariance matching)
      for (int i = 0; i < ny; ++i) ystd[i] *= factor;
    // the bends no reading pins (before the statuses that a wide tip makes uncertain)
    const FreeBends& free = free_now(t);
    if (!free.pairs.empty()) widen_by_free_bends(x, y, ystd, free);
    // whether this row's tip standard deviation, its own or the one written, is beyond
    // the uncertain fraction (below)
    bool wide_row = false;
    if (!s_.tip_rows.empty() && s_.checks_start) {
      // a tip standard deviation beyond the fraction: the estimate may be any of
      // shapes far apart. When it shrinks again the estimate stays uncertain for the
      // unobserved window: a filter linearised on one of those shapes narrows around
      // it whether or not it is the robot's, so only readings that go on agreeing
      // with it confirm it
      wide_row = tip_std(ystd) > s_.uncertain_fraction * s_.length;
      if (wide_row) wide_t_ = t;
      if (trusted(status) && t - wide_t_ < unobserved_window()) status = ST_UNCERTAIN;
    }
    // an estimate on a bending bound that the MHE held it to: the checks judged it with
    // its covariance conditioned on the bound (the estimate cannot leave it), and so do
    // the statuses above; its standard deviations are not, as the bound may not be the
    // robot's, and they grow until the shift that fits the readings, beyond the bound,
    // lies within them
    const bool held = status == ST_AT_BOUND ||
                      (status == ST_RESET &&  // a restart's row on the bound
                       (s_.checks ? s_.checks->at_bound(x) : inference_.at_bound(x)));
    const bool on_bound =
        held && s_.checks_start && inference_.bound_free_covariance(P_free_.data());
    if (on_bound) {
      inference_.output_std(x, P_free_.data(), ystd);
      if (factor != 1.0)
        for (int i = 0; i < ny; ++i) ystd[i] *= factor;
      if (!free.pairs.empty()) widen_by_free_bends(x, y, ystd, free);
      shift_factor = std::sqrt(std::max(1.0, consistency_.shift_inflation_at(x, P_free_.data()) /
                                                 std::max(1.0, consistency_.noise_scale())));
    }
    if (shift_factor != 1.0)
      for (int i = 0; i < ny; ++i) ystd[i] *= shift_factor;
    if (s_.checks_start) {  // constant reading errors, model error: no residual shows them
      for (int i = 0; i < s_.nz; ++i) {
        if (mask_[i] > 0.0) {
          held_z_[i] = z[i];
          held_t_[i] = t;
        }
        held_mask_[i] = t - held_t_[i] <= unobserved_window() ? 1.0 : 0.0;
      }
      // the IMUs' own acceleration, read as gravity, from the estimates of a run the
      // check confirmed: a start's or an unconfirmed estimate's rates are its prior's and
      // its first updates', whose differences are no motion of the robot (an estimate
      // judged inconsistent, on a bound or drifted goes on from the one before)
      if (status == ST_OK || status == ST_INCONSISTENT || status == ST_AT_BOUND ||
          status == ST_DRIFTED)
        consistency_.note_motion(t, x);
      else
        consistency_.forget_motion();
      consistency_.constant_error_cov(held_z_.data(), held_mask_.data(), x, bias_.data());
      inference_.output_std(x, bias_.data(), std_b_.data());
      for (int i = 0; i < ny; ++i) ystd[i] = std::hypot(ystd[i], std_b_[i]);
      // where the readings barely pin the shape, their constant errors alone may put
      // the tip far off: the standard deviation written (these errors in it) beyond
      // the fraction makes the row uncertain as the estimate's own does
      if (!s_.tip_rows.empty() && tip_std(ystd) > s_.uncertain_fraction * s_.length) {
        wide_row = true;
        if (trusted(status)) status = ST_UNCERTAIN;
      }
      // the first row with a reading after a wide one, where it comes the unobserved
      // window or more later (a low rate): the estimate narrowed onto that one
      // reading, which may be a wrong one (half a turn off) that the wide prediction
      // does not rule out; not trusted
      if (wide_row) {
        wide_row_t_ = t;
      } else if (imu_read && std::isfinite(wide_row_t_)) {
        if (trusted(status) && t - wide_row_t_ >= unobserved_window()) status = ST_UNCERTAIN;
        wide_row_t_ = -INFINITY;
      }
    }
    // no distribution within an output's range has a larger standard deviation than
    // half its width: beyond it (a covariance widened to the shift that fits readings
    // this estimate cannot explain), the estimate may lie anywhere in the range, and
    // that is what the limit says (after the statuses: it changes none)
    const std::vector<double>& limit =
        on_bound && !s_.bound_std_limit.empty() ? s_.bound_std_limit : s_.std_limit;
    if (!limit.empty())
      for (int i = 0; i < s_.ny; ++i) ystd[i] = std::min(ystd[i], limit[i]);
    out.has_std = true;
  }
  if (!s_.change_rows.empty() && s_.checks_start) {
    // the IMU errors moved faster than their model allows: the readings are followed
    // with errors that change, as a model that does not describe the robot needs. Only
    // between rows that are trusted (ok, fallback-ipopt, branch-restart), drifted or
    // inconsistent: after a restart, a gap or an unconfirmed estimate the filter's first
    // updates are not linear ones, and their change says nothing. A branch restart's
    // estimate jumps from the warm-started one: the change is measured from it on, and
    // one beyond the limit before it still holds (another branch of the window does not
    // make the model follow)
    const bool judged = trusted(status) || status == ST_DRIFTED ||
                        status == ST_INCONSISTENT || start_unconfirmed;
    if (judged && has_state && has_cov) {
      if (branched) change_past_.clear();
      // once beyond, for a lag after: a change that dips below the limit for a sample
      // does not make the model follow
      if (changed_too_fast(t, x, P)) changed_until_ = t + s_.change_lag;
      if (trusted(status) && t <= changed_until_) status = ST_DRIFTED;
    } else {
      change_past_.clear();
      changed_until_ = -INFINITY;
    }
  }
  // What later rows build on, here and below, comes from ok rows only: the drifted run
  // a drift reset times, the state a restart keeps, the gate's prediction. A
  // fallback-ipopt or branch-restart row answers a window the fast MHE could not answer
  // from its warm start; the rules above judge it as an ok row, but it is not built on.
  // A restart does not make a model that did not follow the robot follow it: the rows
  // after a restart within the probation time of the last drifted row are not trusted
  // (the restart cleared the IMU error states and their change, which showed it)
  if (status == ST_DRIFTED && std::isnan(drift_since_)) drift_since_ = t;
  if (status == ST_OK) {
    drift_since_ = NAN;
    drift_armed_ = true;
  }
  const double probation = std::isnan(s_.bad_start) ? unobserved_window()
                                                    : std::max(s_.bad_start, unobserved_window());
  if (status == ST_DRIFTED) {
    // rows drifted again within the probation time after such a restart: the model
    // still does not follow, and the rows after them are no more trusted than the
    // restart's (a drifted row ends the restart's hold only where it comes later)
    if (t - drifted_t_ > probation) restarted_since_drift_ = false;
    drifted_t_ = t;
  } else if (restarted_since_drift_ && trusted(status) && s_.checks_start) {
    if (0.0 <= t - drifted_t_ && t - drifted_t_ <= probation) status = ST_UNCERTAIN;
  }
  out.outlier = has_state && inference_.outlier();
  // the reject reset's run; a sample without readings neither ends nor extends it. An
  // IMU back from a silence whose readings the robust MHE rejects counts as every
  // reading rejected: its part of the shape went on without it, and the estimate that
  // rejects it is the lost one (the other IMUs' readings agree with any shape of it)
  int rejected = has_state ? inference_.rejected_every_reading() : 0;
  if (rejected == 0 && has_state && !returned_.empty() &&
      inference_.rejected_readings(returned_) == 1)
    rejected = 1;
  if (rejected == 0)
    rejecting_since_.reset();
  else if (rejected == 1 && !rejecting_since_)
    rejecting_since_ = t;
  if (status == ST_OK && has_state && has_cov && !failed) {
    // an estimate the readings confirmed: what a restart within the recording may keep
    const size_t nx = static_cast<size_t>(s_.nx);
    const bool finite = std::all_of(x, x + nx, [](double v) { return std::isfinite(v); }) &&
                        std::all_of(P, P + nx * nx, [](double v) { return std::isfinite(v); });
    if (finite) {
      std::copy(x, x + nx, last_x_.begin());
      std::copy(P, P + nx * nx, last_P_.begin());
      last_state_t_ = t;
      has_last_ = has_ok_ = true;
    }
  }
  // the gate predicts from an estimate the readings confirmed only: readings far from an
  // estimate that is not trusted may be right where it is wrong. And from the first
  // estimate of a start, uncertain for that alone, for a reading half a turn from it
  // alone (whose linearised prediction widens as far, so that the consistency check
  // passes it, and which would confirm a shape fitted to itself): gate_from_start_
  gate_has_ = has_state && has_cov && !failed && (status == ST_OK || start_unconfirmed);
  gate_from_start_ = gate_has_ && status != ST_OK;
  if (gate_has_) {
    std::copy(x, x + s_.nx, gate_x_.begin());
    std::copy(P, P + static_cast<size_t>(s_.nx) * s_.nx, gate_P_.begin());
    std::copy(z, z + s_.nz, gate_z_.begin());
    gate_t_ = t;
  }
  // a standard deviation past the robot's reach, where no other test judges one (a
  // covariance that is no noise model): the written row only, after the policy's own
  // use of its status
  if (s_.judges_reach && trusted(status) && out.has_std && !s_.tip_rows.empty() &&
      tip_std(ystd) > s_.length)
    status = ST_UNCERTAIN;
  out.status = status;
  out.has_state = has_state;
  out.has_cov = has_cov;
  // the whole step, its outputs and their standard deviations included
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
               .count();
  return INPUT_OK;
}

std::pair<int64_t, int> SensorHealth::run(int64_t n, const double* t, const double* z,
                                          int32_t* status, double* ms, uint8_t* outlier,
                                          uint8_t* frozen, double* y, double* ystd,
                                          const std::function<bool()>& interrupted) {
  const int nz = s_.nz, ny = s_.ny, nx = s_.nx;
  std::vector<double> x(nx), P(static_cast<size_t>(nx) * nx);
  SampleResult r;
  // asked before the first sample and then at most every kInterruptCheck: each asking
  // takes the GIL, which the reading of the next block may hold meanwhile
  auto asked = std::chrono::steady_clock::now();
  for (int64_t i = 0; i < n; ++i) {
    if (interrupted) {
      const auto now = std::chrono::steady_clock::now();
      if (i == 0 || now - asked >= kInterruptCheck) {
        asked = now;
        if (interrupted()) return {i, INPUT_OK};
      }
    }
    double* yi = y + i * ny;
    double* si = ystd + i * ny;
    const int err = step(t[i], z + i * nz, x.data(), P.data(), yi, si, r);
    if (err != INPUT_OK) return {i, err};
    if (!r.has_state) std::fill(yi, yi + ny, NAN);
    if (!r.has_std) std::fill(si, si + ny, NAN);
    status[i] = r.status;
    ms[i] = r.ms;
    outlier[i] = r.outlier;
    frozen[i] = r.frozen;
  }
  return {n, INPUT_OK};
}

}  // namespace cmhe
