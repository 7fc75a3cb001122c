// Python bindings of the sensor-health policy (sensor_health.hpp): the policy object over
// an inference object, the compiled fast MHE's step or a Python one.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <optional>
#include <utility>
#include <tuple>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bind_arrays.hpp"
#include "bindings.hpp"
#include "horizon.hpp"
#include "process_noise.hpp"
#include "sensor_health.hpp"
#include "unscented.hpp"

namespace nb = nanobind;
using namespace cmhe;

namespace {

using In = InArray;
using Array = NewArray;
template <typename T>
using OutArray = nb::ndarray<T, nb::c_contig, nb::device::cpu>;

// What the counts of the policy's diagnostics are at a moment: a sample that changes
// none of them leaves Python's copy as it is (a failure restarts, so it changes a count)
auto counts_of(const PolicyDiagnostics& d) {
  return std::make_tuple(d.restarts, d.gap_resets, d.frozen_samples, d.bad_starts,
                         d.reject_resets, d.bound_samples, d.bad_start_chains,
                         d.untrusted_start_samples, d.glitches, d.drift_resets, d.late_imu_starts,
                         d.jump_resets,
                         d.first_freezes.size(), d.has_failure, d.max_noise_scale,
                         d.model_error);
}

// One sample's answer as Python reads it (SensorHealth.step); None where there is none. The
// arrays are held as the Python objects they were converted to once, so that reading
// them costs no conversion.
struct PolicyStep {
  InputError input_error;  // INPUT_OK when the sample was accepted
  int status;       // a STATUS_NAMES index
  nb::object state, covariance, output, output_std;  // NumPy arrays, or None
  bool outlier, frozen;
  bool diagnostics_changed;  // the sample changed the policy's counts
  double solve_ms;
};

// a float64 array of ``n`` values read from a Python result into ``out``
void read_into(const nb::handle& value, size_t n, double* out, const char* what) {
  In a = nb::cast<In>(value);
  if (a.size() != n)
    throw std::invalid_argument(std::string(what) + " has " + std::to_string(a.size()) +
                                " values, expected " + std::to_string(n));
  std::memcpy(out, a.data(), n * sizeof(double));
}

// ``run`` steps a recording without the GIL, so that other Python threads (the reading
// of the next block, the writing of the last) go on meanwhile: every call into Python
// below holds it (nb::gil_scoped_acquire; it nests where the caller holds it already),
// and so does every Python object's lifetime.

// A restart's kept estimate for Python: ``(x (nx,), P (nx, nx))`` arrays, or (None, None)
inline std::pair<nb::object, nb::object> kept_arrays(const double* x, const double* P, int nx) {
  if (!x || !P) return {nb::none(), nb::none()};
  return {nb::cast(copy_of(x, {size_t(nx)})), nb::cast(copy_of(P, {size_t(nx), size_t(nx)}))};
}

// The policy's interface implemented by a Python object with the methods
// ``restart(kept_x | None, kept_P | None, kept_t)``,
// ``infer(t, z, mask) -> (state | None, cov | None, status code, failure | None)``,
// ``output(x)``, ``output_std(x, P)``, ``outlier()``, ``rejected() -> 1, 0 or -1``,
// ``is_diverged(x, P | None)``, ``drifted(x)``, ``at_bound(x)``, ``start_untrusted(t, z)``
// (continuum_mhe.estimators.sensor_health.PythonInference).
class PythonInference final : public PolicyInference {
 public:
  PythonInference(nb::object obj, int nx, int nz, int ny) : obj_(std::move(obj)), nx_(nx), nz_(nz), ny_(ny) {}
  void restart(const double* kept_x, const double* kept_P, double kept_t) override {
    nb::gil_scoped_acquire gil;
    auto [x, P] = kept_arrays(kept_x, kept_P, nx_);
    obj_.attr("restart")(x, P, kept_t);
  }
  int infer(double t, const double* z, const double* mask, double* x, double* P,
            bool& has_state, bool& has_cov) override {
    nb::gil_scoped_acquire gil;
    nb::tuple r = nb::cast<nb::tuple>(
        obj_.attr("infer")(t, copy_of(z, {size_t(nz_)}), copy_of(mask, {size_t(nz_)})));
    if (!r[3].is_none()) throw InferenceFailure(nb::cast<std::string>(r[3]));
    cov_ = P;
    has_state = !r[0].is_none();
    has_cov = !r[1].is_none();
    if (has_state) read_into(r[0], nx_, x, "state");
    if (has_cov) read_into(r[1], size_t(nx_) * nx_, P, "covariance");
    return nb::cast<int>(r[2]);
  }
  void output(const double* x, double* y) override {
    nb::gil_scoped_acquire gil;
    read_into(obj_.attr("output")(state(x)), ny_, y, "output");
  }
  void output_std(const double* x, const double* P, double* s) override {
    nb::gil_scoped_acquire gil;
    // ``answer``: P is the last infer's own covariance (the inference may hold its std)
    read_into(obj_.attr("output_std")(state(x), cov(P), P == cov_), ny_, s, "output_std");
  }
  bool outlier() override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(obj_.attr("outlier")());
  }
  bool bound_free_covariance(double* P) override {
    nb::gil_scoped_acquire gil;
    nb::object r = obj_.attr("bound_free_covariance")();
    if (r.is_none()) return false;
    read_into(r, size_t(nx_) * nx_, P, "bound_free_covariance");
    return true;
  }
  int rejected_every_reading() override {
    nb::gil_scoped_acquire gil;
    return nb::cast<int>(obj_.attr("rejected")());
  }
  int rejected_readings(const std::vector<int>& rows) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<int>(obj_.attr("rejected")(nb::cast(rows)));
  }
  bool is_diverged(const double* x, const double* P) override {
    nb::gil_scoped_acquire gil;
    nb::object p = P ? nb::cast(cov(P)) : nb::none();
    return nb::cast<bool>(obj_.attr("is_diverged")(state(x), p));
  }
  bool drifted(const double* x) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(obj_.attr("drifted")(state(x)));
  }
  bool at_bound(const double* x) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(obj_.attr("at_bound")(state(x)));
  }
  bool start_untrusted(double t, const double* z) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(obj_.attr("start_untrusted")(t, copy_of(z, {size_t(nz_)})));
  }

 private:
  Array state(const double* x) const { return copy_of(x, {size_t(nx_)}); }
  Array cov(const double* P) const { return copy_of(P, {size_t(nx_), size_t(nx_)}); }
  nb::object obj_;
  int nx_, nz_, ny_;
  const double* cov_ = nullptr;  // where the last infer wrote its covariance
};

// The fast MHE's inference in compiled code: the window's process noise, inputs and
// step (horizon.hpp) each sample; the Python inference object
// (continuum_mhe.estimators.mhe.MovingHorizonInference) only where it is needed: its
// ``restart(kept_x, kept_P, kept_t)``, ``start(z) -> failure | None`` (the arrival prior from the first
// reading), ``after_step(outcome, valid) -> (status code, failure | None)`` when the compiled
// step did not keep its answer (IPOPT's fallback, the branch check, the second start),
// ``start_untrusted(t, z)`` once per start, and the formulation's checks of a state.
class HorizonInference final : public PolicyInference {
 public:
  HorizonInference(MovingHorizon& h, nb::object py, bool finish, bool robust,
                   ProcessModel::QFunction q, ProcessModel::InputFunction inputs)
      : h_(h),
        py_(std::move(py)),
        formulation_(py_.attr("formulation")),
        finish_(finish),
        robust_(robust),
        process_(int(h.nx), int(h.nu), int(h.nz), std::move(q), std::move(inputs)) {
    u0_.assign(h.nu, 0.0);
    zero_.assign(size_t(h.nx) * h.nx, 0.0);
    z_prev_.resize(h.nz);
  }
  MovingHorizon& horizon() { return h_; }
  void restart(const double* kept_x, const double* kept_P, double kept_t) override {
    {
      nb::gil_scoped_acquire gil;
      auto [x, P] = kept_arrays(kept_x, kept_P, int(h_.nx));
      py_.attr("restart")(x, P, kept_t);
    }
    t_last_ = 0.0;
    has_z_prev_ = false;
  }
  int infer(double t, const double* z, const double* mask, double* x, double* P,
            bool& has_state, bool& has_cov) override {
    const size_t nx = h_.nx, nz = h_.nz;
    h_.step_seconds = 0.0;  // a sample that does not step the window times nothing
    bool valid = false;
    for (size_t i = 0; i < nz && !valid; ++i) valid = mask[i] > 0.0;
    if (!h_.has_prior) {
      if (!valid) return ST_NO_ESTIMATE;
      nb::gil_scoped_acquire gil;
      nb::object failure = py_.attr("start")(copy_of(z, {nz}));
      if (!failure.is_none()) throw InferenceFailure(nb::cast<std::string>(failure));
    }
    const double* u = u0_.data();
    const double *Q = zero_.data(), *Qinv = zero_.data();
    if (h_.k) {
      const double dt = t - t_last_;
      std::tie(Q, Qinv) = process_.noise(dt);
      if (h_.nu) u = process_.inputs(has_z_prev_ ? z_prev_.data() : nullptr, z, dt);
    }
    t_last_ = t;
    if (valid) {
      std::copy(z, z + nz, z_prev_.begin());
      has_z_prev_ = true;
    }
    const int outcome = h_.step(t, z, mask, u, Q, Qinv, finish_);
    if (outcome == STEP_NO_ESTIMATE) return ST_NO_ESTIMATE;
    int status = ST_OK;
    if (outcome != STEP_DONE) {  // the Python hooks, or IPOPT on the window
      nb::gil_scoped_acquire gil;
      nb::tuple r = nb::cast<nb::tuple>(
          py_.attr("after_step")(static_cast<StepOutcome>(outcome), valid));
      if (!r[1].is_none()) throw InferenceFailure(nb::cast<std::string>(r[1]));
      status = nb::cast<int>(r[0]);
    } else if (!valid) {
      status = ST_DROPOUT;
    }
    std::copy(h_.state.begin(), h_.state.end(), x);
    has_state = true;
    has_cov = h_.cov_ok;
    if (has_cov) std::copy(h_.cov.begin(), h_.cov.end(), P);
    cov_ = P;
    (void)nx;
    return status;
  }
  void output(const double* x, double* y) override {
    if (std::equal(h_.state.begin(), h_.state.end(), x))  // the answer's, kept
      std::copy(h_.y.begin(), h_.y.end(), y);
    else
      h_.node.output(x, y);
  }
  void output_std(const double* x, const double* P, double* s) override {
    if (P == cov_ && h_.cov_ok)
      std::copy(h_.ystd.begin(), h_.ystd.end(), s);
    else
      h_.node.output_std(x, P, s);
  }
  bool bound_free_covariance(double* P) override {
    if (!h_.cov_free_ok) return false;
    std::copy(h_.cov_free.begin(), h_.cov_free.end(), P);
    return true;
  }
  bool outlier() override {
    if (!robust_) return false;
    for (double w : h_.w_last)
      if (w < outlier_weight) return true;
    return false;
  }
  // 1 when every block of the newest sample with a valid reading was weighted below
  // outlier_weight in the last answer, 0 when not, -1 when no block had a reading
  int rejected_every_reading() override { return rejected(nullptr); }
  int rejected_readings(const std::vector<int>& rows) override { return rejected(&rows); }
  // rejected_every_reading over the blocks that hold any of ``rows`` (all: nullptr)
  int rejected(const std::vector<int>* rows) const {
    if (!robust_) return 0;
    const Index last = (h_.n - 1) * h_.nz;
    bool any = false, every = true;
    for (Index b = 0; b < h_.nblk; ++b) {
      // a block the loss does not act on (not an IMU's: a tendon robot's tip condition,
      // its tensions) is never rejected, and says nothing of the readings
      const int64_t start = h_.solver.blocks[2 * b], size = h_.solver.blocks[2 * b + 1];
      if (h_.solver.block_loss[b] == 0 || h_.zmask[last + start] <= 0.0) continue;
      if (rows && std::none_of(rows->begin(), rows->end(),
                               [&](int r) { return start <= r && r < start + size; }))
        continue;
      any = true;
      every = every && h_.w_last[b] < outlier_weight;
    }
    return any ? int(every) : -1;
  }
  bool is_diverged(const double* x, const double* P) override {
    nb::gil_scoped_acquire gil;
    nb::object p = P ? nb::cast(copy_of(P, {size_t(h_.nx), size_t(h_.nx)})) : nb::none();
    return nb::cast<bool>(formulation_.attr("is_diverged")(copy_of(x, {size_t(h_.nx)}), p));
  }
  bool drifted(const double* x) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(formulation_.attr("drifted")(copy_of(x, {size_t(h_.nx)})));
  }
  bool at_bound(const double* x) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(formulation_.attr("at_bound")(copy_of(x, {size_t(h_.nx)})));
  }
  bool start_untrusted(double t, const double* z) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(py_.attr("start_untrusted")(t, copy_of(z, {size_t(h_.nz)})));
  }
  double outlier_weight = 0.0;

 private:
  MovingHorizon& h_;
  nb::object py_, formulation_;
  bool finish_, robust_;
  ProcessModel process_;
  std::vector<double> u0_, zero_, z_prev_;
  double t_last_ = 0.0;
  bool has_z_prev_ = false;
  const double* cov_ = nullptr;
};

// The compiled EKF's or UKF's inference for the policy: each sample's step (the node
// model's EKF step, filter.hpp, or an UnscentedFilter's, unscented.hpp), outputs and
// standard deviations on the node model; the Python inference object
// (continuum_mhe.estimators.kalman.CompiledExtendedKalmanInference or
// UnscentedKalmanInference) only for its
// ``restart(kept_x, kept_P, kept_t)`` and the first sample, ``first(t, z) -> (x | None, P | None, status
// code, failure | None)`` (the prior from the reading, updated with it), and
// ``start_untrusted(t, z)`` once per start.
class KalmanInference final : public PolicyInference {
 public:
  KalmanInference(NodeModel& node, nb::object py, std::vector<double> R,
                  ProcessModel::QFunction q, ProcessModel::InputFunction inputs,
                  UnscentedFilter* unscented = nullptr)
      : node_(node),
        unscented_(unscented),
        py_(std::move(py)),
        R_(std::move(R)),
        process_(node.nx(), int(nb::cast<int>(py_.attr("nu"))), node.nz(), std::move(q),
                 std::move(inputs)) {
    x_.resize(node.nx());
    P_.resize(size_t(node.nx()) * node.nx());
    z_prev_.resize(node.nz());
  }
  void restart(const double* kept_x, const double* kept_P, double kept_t) override {
    {
      nb::gil_scoped_acquire gil;
      auto [x, P] = kept_arrays(kept_x, kept_P, node_.nx());
      py_.attr("restart")(x, P, kept_t);
    }
    has_x_ = false;
  }
  int infer(double t, const double* z, const double* mask, double* x, double* P,
            bool& has_state, bool& has_cov) override {
    const int nx = node_.nx(), nz = node_.nz();
    bool valid = false;
    for (int i = 0; i < nz && !valid; ++i) valid = mask[i] > 0.0;
    int status = ST_OK;
    if (!has_x_) {
      nb::gil_scoped_acquire gil;
      nb::tuple r = nb::cast<nb::tuple>(py_.attr("first")(t, copy_of(z, {size_t(nz)})));
      if (!r[3].is_none()) throw InferenceFailure(nb::cast<std::string>(r[3]));
      if (r[0].is_none()) return nb::cast<int>(r[2]);
      read_into(r[0], nx, x_.data(), "state");
      read_into(r[1], size_t(nx) * nx, P_.data(), "covariance");
      std::copy(z, z + nz, z_prev_.begin());
      has_x_ = true;
      status = nb::cast<int>(r[2]);
    } else {
      const double dt = t - t_prev_;
      const double* u = process_.inputs(z_prev_.data(), z, dt);
      const double* Q = process_.noise(dt).first;
      if (unscented_ != nullptr) {
        unscented_step(process_.nu ? u : nullptr, dt, z, mask, Q, valid);
      } else if (!node_.ekf_step(x_.data(), P_.data(), process_.nu ? u : nullptr, dt, z, mask,
                                 R_.data(), Q)) {
        throw std::runtime_error("singular innovation covariance in the EKF update");
      }
      status = valid ? ST_OK : ST_DROPOUT;
      if (valid) std::copy(z, z + nz, z_prev_.begin());
    }
    t_prev_ = t;
    std::copy(x_.begin(), x_.end(), x);
    std::copy(P_.begin(), P_.end(), P);
    has_state = has_cov = true;
    return status;
  }
  void output(const double* x, double* y) override { node_.output(x, y); }
  void output_std(const double* x, const double* P, double* s) override {
    node_.output_std(x, P, s);
  }
  int nz() const { return node_.nz(); }
  bool is_diverged(const double* x, const double* P) override {
    return check("is_diverged", x, P);
  }
  bool drifted(const double* x) override { return check("drifted", x, nullptr); }
  bool at_bound(const double* x) override { return check("at_bound", x, nullptr); }
  bool start_untrusted(double t, const double* z) override {
    nb::gil_scoped_acquire gil;
    return nb::cast<bool>(py_.attr("start_untrusted")(t, copy_of(z, {size_t(node_.nz())})));
  }
  // Each of the ``n`` samples' innovation log-density (the node's ``log_likelihood``)
  // into ``ll``, the filter stepped over the readings ``z`` (n, nz) at ``t`` (n,) with
  // the validity ``mask`` (n, nz) and no policy: NaN for a start, a sample without a
  // valid reading, and one whose step failed or left a non-finite state, after which
  // the filter starts again from the next sample. The EKF's step only (an unscented
  // inference is refused). Called without the GIL (the Python hooks of a start and a
  // restart take it), which it takes every 1,024 samples for a signal's handler: one
  // that raises ends the call with its exception (Python runs handlers on its main
  // thread alone: a call on another thread runs to its end).
  void log_likelihoods(size_t n, const double* t, const double* z, const double* mask,
                       double* ll) {
    if (unscented_ != nullptr)
      throw std::invalid_argument("log_likelihoods steps the EKF: this inference is the UKF's");
    const int nx = node_.nx(), nz = node_.nz();
    std::vector<double> x(nx), P(size_t(nx) * nx);
    for (size_t i = 0; i < n; ++i) {
      if (i % 1024 == 0) {
        nb::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() != 0) throw nb::python_error();
      }
      ll[i] = NAN;
      const bool started = has_x_;
      bool has_state = false, has_cov = false;
      try {
        infer(t[i], z + i * nz, mask + i * nz, x.data(), P.data(), has_state, has_cov);
      } catch (const nb::python_error&) {
        throw;  // not a numerical failure: the caller's to see
      } catch (const std::runtime_error&) {  // a failed step: start again
        restart(nullptr, nullptr, NAN);
        continue;
      }
      if (!has_state) continue;
      if (!std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); })) {
        restart(nullptr, nullptr, NAN);  // diverged: start again
        continue;
      }
      if (started) ll[i] = node_.log_likelihood;
    }
  }

 private:
  // the UKF's step (predict, then update with the valid components), in place; a failure
  // as the Python UKF's would be named (numpy's LinAlgError, or the tilt chart's
  // ArithmeticError)
  void unscented_step(const double* u, double dt, const double* z, const double* mask,
                      const double* Q, bool valid) {
    UnscentedFilter& f = *unscented_;
    if (f.predict(x_.data(), P_.data(), u, dt, Q) &&
        (!valid || f.update(x_.data(), P_.data(), z, mask, R_.data(), true)))
      return;
    const char* kind =
        f.failure == UnscentedFailure::TILT_CHART ? "ArithmeticError: " : "LinAlgError: ";
    throw InferenceFailure(kind + f.message);
  }
  // the formulation's check ``name`` of a state, in Python (a formulation without
  // StateChecks)
  bool check(const char* name, const double* x, const double* P) {
    const size_t nx = node_.nx();
    nb::gil_scoped_acquire gil;
    nb::object f = py_.attr("formulation");
    if (std::string(name) == "is_diverged") {
      nb::object p = P ? nb::cast(copy_of(P, {nx, nx})) : nb::none();
      return nb::cast<bool>(f.attr(name)(copy_of(x, {nx}), p));
    }
    return nb::cast<bool>(f.attr(name)(copy_of(x, {nx})));
  }
  NodeModel& node_;
  UnscentedFilter* unscented_;  // the UKF's step, else the EKF's
  nb::object py_;
  std::vector<double> R_;
  ProcessModel process_;
  std::vector<double> x_, P_, z_prev_;
  double t_prev_ = 0.0;
  bool has_x_ = false;
};

// The policy with what it owns: its inference adapter and process model
struct Policy {
  std::unique_ptr<PolicyInference> inference;  // a PythonInference, or none
  PolicyInference* used = nullptr;             // the inference the policy steps
  std::unique_ptr<ProcessModel> process;
  std::unique_ptr<SensorHealth> health;
  // the thread whose ``run`` or ``step`` steps samples now (``run`` without the GIL; a
  // ``step`` or ``run`` whose inference calls into Python lets other threads in there):
  // another thread's call is refused (set and read with the GIL held)
  std::optional<std::thread::id> running_in;

  // a RuntimeError where another thread's ``run`` or ``step`` is stepping this policy
  void check_idle() const {
    if (running_in && *running_in != std::this_thread::get_id())
      throw std::runtime_error(
          "this estimator is stepping samples in another thread (step, run, "
          "continue_run): an estimator is used from one thread at a time");
  }
};

// ``running_in`` for the scope of a ``run`` or ``step``
class Running {
 public:
  explicit Running(Policy& p) : p_(p), outer_(p.running_in) {
    p.check_idle();
    p.running_in = std::this_thread::get_id();
  }
  ~Running() { p_.running_in = outer_; }  // a call nested in the same thread keeps it
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;

 private:
  Policy& p_;
  std::optional<std::thread::id> outer_;
};

// The compiled process noise, and the Python function that answers where its Q is not
// positive definite (its one-line error names the step)
struct BoundProcessNoise {
  ProcessNoise core;
  nb::object fallback;
  int64_t python_calls = 0;  // calls of __call__ (from Python, or a caller's callable)
};

// ``process_noise(dt) -> (Q, Q^-1)``: a ProcessNoise in compiled code (Python only for its
// fallback), or any Python callable
ProcessModel::QFunction q_function(nb::object fn, int nx) {
  if (nb::isinstance<BoundProcessNoise>(fn)) {
    BoundProcessNoise* p = nb::cast<BoundProcessNoise*>(fn);
    if (p->core.nx != nx)
      throw std::invalid_argument("the process noise has " + std::to_string(p->core.nx) +
                                  " states, expected " + std::to_string(nx));
    return [fn, p, nx](double dt, double* Q, double* Qinv) {
      if (p->core.compute(dt, Q, Qinv)) return;
      nb::gil_scoped_acquire gil;
      nb::tuple r = nb::cast<nb::tuple>(p->fallback(dt));
      read_into(r[0], size_t(nx) * nx, Q, "Q");
      read_into(r[1], size_t(nx) * nx, Qinv, "Q^-1");
    };
  }
  return [fn, nx](double dt, double* Q, double* Qinv) {
    nb::gil_scoped_acquire gil;
    nb::tuple r = nb::cast<nb::tuple>(fn(dt));
    read_into(r[0], size_t(nx) * nx, Q, "Q");
    read_into(r[1], size_t(nx) * nx, Qinv, "Q^-1");
  };
}

ProcessModel::InputFunction input_function(nb::object fn, int nz, int nu) {
  if (nb::isinstance<CompiledInputs>(fn)) {
    const CompiledInputs c = nb::cast<const CompiledInputs&>(fn);
    if (c.nz != nz || c.nu != nu)
      throw std::invalid_argument("the compiled inputs take " + std::to_string(c.nz) +
                                  " readings and give " + std::to_string(c.nu) +
                                  " inputs; expected " + std::to_string(nz) + " and " +
                                  std::to_string(nu));
    return c;
  }
  return [fn, nz, nu](const double* z_prev, const double* z, double dt, double* u) {
    nb::gil_scoped_acquire gil;
    nb::object prev = z_prev ? nb::cast(copy_of(z_prev, {size_t(nz)})) : nb::none();
    read_into(fn(prev, copy_of(z, {size_t(nz)}), dt), nu, u, "u");
  };
}

}  // namespace

void cmhe::bind_sensor_health(nb::module_& m) {
  nb::list names;
  for (const char* s : STATUS_NAMES) names.append(nb::str(s));
  m.attr("STATUS_NAMES") = nb::tuple(names);

  nb::enum_<InputError>(m, "InputProblem", nb::is_arithmetic(),
                        "A sample the policy refuses (csrc/sensor_health.hpp's InputError).")
      .value("OK", INPUT_OK, "Accepted.")
      .value("TIME", INPUT_TIME, "t not finite, or not later than the previous sample's.")
      .value("DEGREES", INPUT_DEGREES,
             "A tilt reading beyond degrees_like (just over pi): degrees given for radians.")
      .value("INFINITE", INPUT_INFINITE, "An infinite reading.");

  nb::class_<PolicyStep>(m, "PolicyStep", "One sample's answer of SensorHealth.step.")
      .def_ro("input_error", &PolicyStep::input_error,
              "InputProblem.OK (0) when the sample was accepted, else its problem.")
      .def_ro("status", &PolicyStep::status, "The status, an index into STATUS_NAMES.")
      .def_prop_ro(
          "state", [](const PolicyStep& r) { return r.state; },
          nb::for_getter(nb::sig("def state(self, /) -> NDArray[numpy.float64] | None")),
          "The state (nx,), or None.")
      .def_prop_ro(
          "covariance", [](const PolicyStep& r) { return r.covariance; },
          nb::for_getter(nb::sig("def covariance(self, /) -> NDArray[numpy.float64] | None")),
          "The state covariance (nx, nx), or None.")
      .def_prop_ro(
          "output", [](const PolicyStep& r) { return r.output; },
          nb::for_getter(nb::sig("def output(self, /) -> NDArray[numpy.float64] | None")),
          "The outputs (ny,), or None.")
      .def_prop_ro(
          "output_std", [](const PolicyStep& r) { return r.output_std; },
          nb::for_getter(nb::sig("def output_std(self, /) -> NDArray[numpy.float64] | None")),
          "The outputs' standard deviations (ny,), or None.")
      .def_ro("outlier", &PolicyStep::outlier, "The robust MHE down-weighted this sample.")
      .def_ro("frozen", &PolicyStep::frozen, "A sensor counts as frozen at this sample.")
      .def_ro("diagnostics_changed", &PolicyStep::diagnostics_changed,
              "The sample changed a count of SensorHealth.diagnostics.")
      .def_ro("solve_ms", &PolicyStep::solve_ms, "Wall time spent on this sample, ms.");

  nb::class_<PolicyDiagnostics>(
      m, "PolicyDiagnostics",
      "What the policy did since its last reset (continuum_mhe.results.Diagnostics).")
      .def_ro("restarts", &PolicyDiagnostics::restarts,
              "Restarts after a divergence or numerical failure.")
      .def_ro("gap_resets", &PolicyDiagnostics::gap_resets, "Restarts after a gap.")
      .def_ro("frozen_samples", &PolicyDiagnostics::frozen_samples,
              "Samples with at least one IMU counted as frozen.")
      .def_ro("first_freezes", &PolicyDiagnostics::first_freezes,
              "Each IMU's first freeze, [(its block index among the IMUs, t s)], in order.")
      .def_ro("bad_starts", &PolicyDiagnostics::bad_starts,
              "Restarts after a bad start (an IMU back from a silence included).")
      .def_ro("reject_resets", &PolicyDiagnostics::reject_resets,
              "Restarts after the robust MHE rejected every reading for too long.")
      .def_ro("drift_resets", &PolicyDiagnostics::drift_resets,
              "Restarts from the last ok estimate's sensor states after rows drifted "
              "for drift_reset s.")
      .def_ro("late_imu_starts", &PolicyDiagnostics::late_imu_starts,
              "Restarts at the first reading of an IMU that had not read since the last "
              "(re)start, beside every IMU that had.")
      .def_ro("jump_resets", &PolicyDiagnostics::jump_resets,
              "Restarts after a jump in t shorter than the gap reset whose readings "
              "disagreed with the prediction across it.")
      .def_ro("first_jump_t", &PolicyDiagnostics::first_jump_t,
              "t (s) of the sample after the first such jump (NaN: none).")
      .def_ro("first_jump_step", &PolicyDiagnostics::first_jump_step,
              "The first such jump's length, s (NaN: none).")
      .def_prop_ro(
          "last_failure",
          [](const PolicyDiagnostics& d) {
            return d.has_failure ? std::optional<std::string>(d.last_failure) : std::nullopt;
          },
          "The last numerical failure's description, or None.")
      .def_ro("bound_samples", &PolicyDiagnostics::bound_samples,
              "Estimates of status at-bound.")
      .def_ro("max_noise_scale", &PolicyDiagnostics::max_noise_scale,
              "The largest model-error factor seen (the innovations' variance over the "
              "noise model's; 1 when the readings fit their noise).")
      .def_ro("model_error", &PolicyDiagnostics::model_error,
              "The largest model error learned, in units of R (0 when none showed).")
      .def_ro("bad_start_chains", &PolicyDiagnostics::bad_start_chains,
              "Times the bad-start check stopped restarting after a chain of restarts.")
      .def_ro("untrusted_start_samples", &PolicyDiagnostics::untrusted_start_samples,
              "Estimates of a start the inference did not trust (none of them ok).")
      .def_ro("glitches", &PolicyDiagnostics::glitches,
              "IMU readings skipped as glitches (far beyond the prediction from an ok "
              "estimate).");

  nb::class_<StateChecks>(
      m, "StateChecks",
      "A formulation's checks of a state as data (csrc/sensor_health.hpp): diverged, at "
      "its bound, drifted.")
      .def(
          "__init__",
          [](StateChecks* self, int nx, std::vector<std::pair<int, int>> pairs,
             std::vector<double> diverged_r2, std::vector<double> at_bound_r,
             std::vector<int> rate_rows, double rate_limit, std::vector<int> std_rows,
             double std_limit2, std::shared_ptr<TapeFunction> flags) {
            if (diverged_r2.size() != pairs.size() || at_bound_r.size() != pairs.size())
              throw std::invalid_argument("one diverged_r2 and at_bound_r per pair");
            for (const auto& [i, j] : pairs)
              if (i < 0 || j < 0 || i >= nx || j >= nx)
                throw std::invalid_argument("a pair's row is outside the state");
            for (const auto* rows : {&rate_rows, &std_rows})
              for (int r : *rows)
                if (r < 0 || r >= nx) throw std::invalid_argument("a row is outside the state");
            if (flags && (flags->tape().input_sizes() != std::vector<int64_t>{nx} ||
                          flags->output_size() != 3))
              throw std::invalid_argument("flags takes the state (nx) and gives 3 values");
            new (self) StateChecks{nx, std::move(pairs), std::move(diverged_r2),
                                   std::move(at_bound_r), std::move(rate_rows), rate_limit,
                                   std::move(std_rows), std_limit2, std::move(flags)};
          },
          nb::arg("nx"), nb::arg("pairs"), nb::arg("diverged_r2"), nb::arg("at_bound_r"),
          nb::arg("rate_rows"), nb::arg("rate_limit"), nb::arg("std_rows"),
          nb::arg("std_limit2"), nb::arg("flags").none() = nb::none(),
          "``pairs``: the bend coordinates (i, j) of each section, with the squared radius "
          "beyond which it diverged and the radius at which it is at its bound; "
          "``rate_rows`` held to ``rate_limit`` in magnitude; ``std_rows`` whose variance "
          "beyond ``std_limit2`` is a divergence; ``flags(x) -> (diverged, at_bound, "
          "drifted)``, a TapeFunction of the state whose nonzero values say so (none: "
          "nothing drifts).")
      .def(
          "is_diverged",
          [](const StateChecks& c, In x, std::optional<In> P) {
            check_size(x, c.nx, "x");
            if (P) check_size(*P, size_t(c.nx) * c.nx, "P");
            return c.is_diverged(x.data(), P ? P->data() : nullptr);
          },
          nb::arg("x"), nb::arg("P").none(), "Whether the state (and covariance) diverged.")
      .def(
          "at_bound",
          [](const StateChecks& c, In x) {
            check_size(x, c.nx, "x");
            return c.at_bound(x.data());
          },
          nb::arg("x"), "Whether a section's bend is at its bound.")
      .def(
          "drifted",
          [](const StateChecks& c, In x) {
            check_size(x, c.nx, "x");
            return c.drifted(x.data());
          },
          nb::arg("x"), "Whether the state is not one the model holds (``flags``).");

  nb::class_<CompiledInputs>(
      m, "CompiledInputs",
      "A model's inputs u(z_prev, z, dt) in compiled code (csrc/sensor_health.hpp): zero "
      "where there is no previous reading or either reading has a value not finite.")
      .def(
          "__init__",
          [](CompiledInputs* self, std::shared_ptr<TapeFunction> fn, int nz, int nu) {
            if (!fn || fn->tape().input_sizes() != std::vector<int64_t>{nz, nz, 1} ||
                fn->output_size() != nu)
              throw std::invalid_argument("fn takes (z_prev (nz), z (nz), dt) and gives nu");
            new (self) CompiledInputs{std::move(fn), nz, nu};
          },
          nb::arg("fn"), nb::arg("nz"), nb::arg("nu"),
          "``fn(z_prev, z, dt) -> u``, a TapeFunction.")
      .def_ro("nz", &CompiledInputs::nz, "Readings per sample.")
      .def_ro("nu", &CompiledInputs::nu, "Inputs.")
      .def(
          "__call__",
          [](const CompiledInputs& c, std::optional<In> z_prev, In z, double dt) {
            check_size(z, c.nz, "z");
            if (z_prev) check_size(*z_prev, c.nz, "z_prev");
            std::vector<double> u(c.nu);
            c(z_prev ? z_prev->data() : nullptr, z.data(), dt, u.data());
            return u;
          },
          nb::arg("z_prev").none(), nb::arg("z"), nb::arg("dt"),
          "u (nu,) from the previous reading ``z_prev`` (None: none) to ``z``, ``dt`` s "
          "apart.");

  nb::class_<BoundProcessNoise>(
      m, "ProcessNoise",
      "A formulation's process noise Q(dt) and its inverse, from the tape of its covariance "
      "(csrc/process_noise.hpp); the policy and the inferences take it without Python.")
      .def(
          "__init__",
          [](BoundProcessNoise* self, const TapeFunction& q, int nx, std::vector<int> held,
             nb::object fallback) {
            new (self) BoundProcessNoise{ProcessNoise(q, nx, std::move(held)), fallback};
          },
          nb::arg("q"), nb::arg("nx"), nb::arg("held"), nb::arg("fallback"),
          nb::keep_alive<1, 2>(),
          "``q``: dt (s) -> Q (nx, nx); ``held``: states whose rows and columns of Q and Q^-1 "
          "are zero; ``fallback(dt) -> (Q, Q^-1)`` where Q is not positive definite (it "
          "must not refer back to this object: the garbage collector does not see it).")
      .def(
          "__call__",
          [](BoundProcessNoise& p, double dt) -> nb::tuple {
            ++p.python_calls;
            const size_t nx = size_t(p.core.nx);
            Array Q = new_array({nx, nx}), Qinv = new_array({nx, nx});
            if (p.core.compute(dt, Q.data(), Qinv.data())) return nb::make_tuple(Q, Qinv);
            return nb::cast<nb::tuple>(p.fallback(dt));
          },
          nb::arg("dt"), "``(Q, Q^-1)`` (nx, nx each) of a step of ``dt`` s.")
      .def_prop_ro("nx", [](const BoundProcessNoise& p) { return p.core.nx; })
      .def_prop_ro(
          "python_calls", [](const BoundProcessNoise& p) { return p.python_calls; },
          "Calls of this object from Python (the compiled steps compute without them).");

  nb::class_<HorizonInference>(
      m, "HorizonInference",
      "The fast MHE's inference for the compiled policy: the window step in compiled code, "
      "the Python inference only for its hooks (csrc/bind_sensor_health.cpp).")
      .def(
          "__init__",
          [](HorizonInference* self, MovingHorizon& h, nb::object inference, bool finish,
             bool robust, double outlier_weight, nb::object process_noise, nb::object inputs) {
            new (self) HorizonInference(h, inference, finish, robust,
                                        q_function(process_noise, int(h.nx)),
                                        input_function(inputs, int(h.nz), int(h.nu)));
            self->outlier_weight = outlier_weight;
          },
          nb::arg("horizon"), nb::arg("inference"), nb::arg("finish"), nb::arg("robust"),
          nb::arg("outlier_weight"), nb::arg("process_noise"), nb::arg("inputs"),
          nb::keep_alive<1, 2>(),
          "``horizon``: the inference's MovingHorizon; ``finish``: keep certified answers in "
          "the step (no Python hooks); ``robust``: outlier flags below ``outlier_weight``; "
          "``process_noise(dt) -> (Q, Q^-1)``, ``inputs(z_prev | None, z, dt) -> u``.");

  nb::class_<KalmanInference>(
      m, "KalmanInference",
      "The compiled EKF's or UKF's inference for the compiled policy: each step, its outputs and "
      "standard deviations in compiled code, the Python inference only for the first "
      "sample and restarts (csrc/bind_sensor_health.cpp).")
      .def(
          "__init__",
          [](KalmanInference* self, NodeModel& node, nb::object inference, In R,
             nb::object process_noise, nb::object inputs, UnscentedFilter* unscented) {
            check_size(R, size_t(node.nz()) * node.nz(), "R");
            if (unscented && (unscented->nx() != node.nx() || unscented->nz() != node.nz()))
              throw std::invalid_argument("the unscented filter's sizes differ from the node's");
            new (self) KalmanInference(node, inference,
                                       std::vector<double>(R.data(), R.data() + R.size()),
                                       q_function(process_noise, node.nx()),
                                       input_function(inputs, node.nz(),
                                                      nb::cast<int>(inference.attr("nu"))),
                                       unscented);
          },
          nb::arg("node"), nb::arg("inference"), nb::arg("R"), nb::arg("process_noise"),
          nb::arg("inputs"), nb::arg("unscented").none() = nb::none(), nb::keep_alive<1, 2>(),
          nb::keep_alive<1, 7>(),
          "``node``: the filter's NodeModel (its outputs, and the EKF's step); "
          "``inference``: its hooks (``restart(kept_x, kept_P, kept_t)``, "
          "``first(t, z)``, ``formulation``, ``nu``); ``R`` (nz, nz); "
          "``process_noise(dt) -> (Q, Q^-1)``, ``inputs(z_prev | None, z, dt) -> u``; "
          "``unscented``: the UKF's steps (an UnscentedFilter) instead of the EKF's.")
      .def(
          "log_likelihoods",
          [](KalmanInference& self, In t, In z, In mask, OutArray<double> ll) {
            const size_t n = t.size(), nz = size_t(self.nz());
            for (const auto& [a, name] : {std::pair{&z, "z"}, std::pair{&mask, "mask"}})
              if (a->ndim() != 2 || a->shape(0) != n || a->shape(1) != nz)
                throw std::invalid_argument(std::string(name) + " must be (n, nz): " +
                                            std::to_string(n) + " x " + std::to_string(nz));
            if (ll.ndim() != 1 || ll.size() != n)
              throw std::invalid_argument("ll must be (n,): " + std::to_string(n));
            nb::gil_scoped_release released;  // two filters may step side by side
            self.log_likelihoods(n, t.data(), z.data(), mask.data(), ll.data());
          },
          nb::arg("t"), nb::arg("z"), nb::arg("mask"), nb::arg("ll").noconvert(),
          "Step the EKF, without the policy, over the readings ``z`` (n, nz) at ``t`` "
          "(n,) s with the validity ``mask`` (n, nz: 1 where a component is valid), writing "
          "each sample's innovation log-density ``-(r^T S^-1 r + log|S|) / 2`` into ``ll`` "
          "(n,): NaN for a start, a sample without a valid reading, and one whose step "
          "failed or left a non-finite state, after which the filter starts again from the "
          "next sample (``ll`` a C-contiguous float64 array, written in place). Runs without "
          "the GIL but for the filter's Python hooks (a start, a restart); on the main "
          "thread a signal whose handler raises ends it.");

  nb::class_<Policy>(
      m, "SensorHealth",
      "The sensor-health policy of an estimator (continuum_mhe.estimators.sensor_health): "
      "step one sample, or run a recording into arrays, in compiled code "
      "(csrc/sensor_health.hpp).")
      .def(
          "__init__",
          [](Policy* self, nb::object inference, ConsistencyCheck& consistency, int nx, int nu,
             int nz, int ny, std::vector<std::pair<int, int>> blocks,
             std::vector<std::pair<int, int>> imu_blocks, std::vector<int> tilt_rows,
             std::vector<int> tip_rows, double freeze, int freeze_samples, double gap_reset,
             double bad_start, double reject_reset, double uncertain_fraction, double length,
             bool checks_start, bool shape_observable, std::vector<double> start_limit,
             int start_samples, int start_chain, double unobserved_after, double degrees_like,
             std::vector<int> whole_rows, nb::object process_noise, nb::object inputs,
             nb::object observable, const StateChecks* checks, std::vector<int> change_rows,
             std::vector<double> change_scale, std::vector<double> change_psd,
             std::vector<double> change_limit, double change_lag, int confirm_samples,
             std::vector<double> std_limit, bool jump_hold,
             std::vector<double> freeze_tolerance, double silent_after, double glitch_factor,
             double drift_reset, double whole_gap_reset,
             std::vector<std::pair<int, int>> free_pairs, std::vector<double> free_reach,
             std::vector<int> wrapped_outputs, std::vector<double> bound_std_limit,
             bool judges_reach, nb::object free_of) {
            PolicySettings s{nx, nz, ny, std::move(blocks), std::move(imu_blocks),
                             std::move(tilt_rows), std::move(tip_rows), freeze,
                             freeze_samples, gap_reset, bad_start, reject_reset,
                             uncertain_fraction, length, checks_start, shape_observable,
                             std::move(start_limit), start_samples, start_chain, unobserved_after,
                             degrees_like, std::nullopt, std::move(whole_rows), {}, {}, {},
                             {}, 0.0};
            if (checks) s.checks = *checks;
            const size_t m = change_rows.size();
            if (change_scale.size() != m || change_psd.size() != m ||
                (m > 0 && change_limit.size() < m + 1))
              throw std::invalid_argument(
                  "change_scale and change_psd need one value per change row, change_limit "
                  "one per degree of freedom after index 0");
            for (size_t i = 0; i < m; ++i) {
              const int r = change_rows[i];
              if (r < 0 || r >= nx) throw std::invalid_argument("a change row is not a state");
              for (size_t j = 0; j < i; ++j)
                if (change_rows[j] == r) throw std::invalid_argument("a change row repeats");
              if (!(std::isfinite(change_scale[i]) && change_scale[i] > 0.0) ||
                  !(std::isfinite(change_psd[i]) && change_psd[i] >= 0.0))
                throw std::invalid_argument(
                    "change_scale must be finite and positive, change_psd finite and >= 0");
            }
            if (m > 0 && !(std::isfinite(change_lag) && change_lag > 0.0))
              throw std::invalid_argument("change_lag must be finite and positive");
            s.change_rows = std::move(change_rows);
            s.change_scale = std::move(change_scale);
            s.change_psd = std::move(change_psd);
            s.change_limit = std::move(change_limit);
            s.change_lag = change_lag;
            if (confirm_samples < 1) throw std::invalid_argument("confirm_samples must be >= 1");
            s.confirm_samples = confirm_samples;
            if (!std_limit.empty()) {
              if (std_limit.size() != static_cast<size_t>(ny))
                throw std::invalid_argument("std_limit needs one value per output (ny)");
              for (double v : std_limit)
                if (!(v > 0.0)) throw std::invalid_argument("std_limit must be positive");
            }
            s.std_limit = std::move(std_limit);
            if (!bound_std_limit.empty() && bound_std_limit.size() != static_cast<size_t>(ny))
              throw std::invalid_argument("bound_std_limit needs one value per output (ny)");
            s.bound_std_limit = std::move(bound_std_limit);
            s.jump_hold = jump_hold;
            if (freeze_tolerance.empty()) freeze_tolerance.assign(static_cast<size_t>(nz), 0.0);
            if (freeze_tolerance.size() != static_cast<size_t>(nz))
              throw std::invalid_argument("freeze_tolerance needs one value per reading (nz)");
            for (double v : freeze_tolerance)
              if (!(std::isfinite(v) && v >= 0.0))
                throw std::invalid_argument("freeze_tolerance must be finite and >= 0");
            s.freeze_tolerance = std::move(freeze_tolerance);
            if (!(silent_after > 0.0)) throw std::invalid_argument("silent_after must be > 0");
            s.silent_after = silent_after;
            if (!(std::isfinite(glitch_factor) && glitch_factor >= 0.0))
              throw std::invalid_argument("glitch_factor must be finite and >= 0");
            s.glitch_factor = glitch_factor;
            if (!(std::isnan(drift_reset) || drift_reset > 0.0))
              throw std::invalid_argument("drift_reset must be > 0 s, or NaN (off)");
            s.drift_reset = drift_reset;
            if (!(std::isnan(whole_gap_reset) || whole_gap_reset > 0.0))
              throw std::invalid_argument("whole_gap_reset must be > 0 s, or NaN (off)");
            s.whole_gap_reset = whole_gap_reset;
            if (free_reach.size() != free_pairs.size())
              throw std::invalid_argument("free_reach needs one value per free pair");
            for (size_t p = 0; p < free_pairs.size(); ++p) {
              const auto [i, j] = free_pairs[p];
              if (i < 0 || i >= nx || j < 0 || j >= nx)
                throw std::invalid_argument("a free pair's row is not a state");
              if (!(std::isfinite(free_reach[p]) && free_reach[p] > 0.0))
                throw std::invalid_argument("free_reach must be finite and positive");
            }
            for (int i : wrapped_outputs)
              if (i < 0 || i >= ny) throw std::invalid_argument("a wrapped output is not an output");
            s.free_pairs = std::move(free_pairs);
            s.free_reach = std::move(free_reach);
            s.wrapped_outputs = std::move(wrapped_outputs);
            s.judges_reach = judges_reach;
            new (self) Policy();
            if (nb::isinstance<HorizonInference>(inference)) {
              self->used = nb::cast<HorizonInference*>(inference);
            } else if (nb::isinstance<KalmanInference>(inference)) {
              self->used = nb::cast<KalmanInference*>(inference);
            } else {
              self->inference = std::make_unique<PythonInference>(inference, nx, nz, ny);
              self->used = self->inference.get();
            }
            self->process = std::make_unique<ProcessModel>(
                nx, nu, nz, q_function(process_noise, nx), input_function(inputs, nz, nu));
            auto obs = [observable](const std::vector<int>& imus) {
              nb::gil_scoped_acquire gil;
              return nb::cast<bool>(observable(nb::cast(imus)));
            };
            std::function<FreeBends(const std::vector<int>&)> free;
            if (!free_of.is_none())
              free = [free_of, nx](const std::vector<int>& imus) {
                nb::gil_scoped_acquire gil;
                FreeBends out;
                for (nb::handle item : free_of(nb::cast(imus))) {
                  const auto [i, j, reach] = nb::cast<std::tuple<int, int, double>>(item);
                  if (i < 0 || i >= nx || j < 0 || j >= nx || !(std::isfinite(reach) && reach > 0.0))
                    throw std::invalid_argument(
                        "free_of: each free bend is (row, row, reach > 0) of the state");
                  out.pairs.emplace_back(i, j);
                  out.reach.push_back(reach);
                }
                return out;
              };
            self->health = std::make_unique<SensorHealth>(
                std::move(s), *self->used, *self->process, consistency, obs, std::move(free));
          },
          nb::arg("inference"), nb::arg("consistency"), nb::arg("nx"), nb::arg("nu"),
          nb::arg("nz"), nb::arg("ny"), nb::arg("blocks"), nb::arg("imu_blocks"),
          nb::arg("tilt_rows"), nb::arg("tip_rows"), nb::arg("freeze"),
          nb::arg("freeze_samples"), nb::arg("gap_reset"), nb::arg("bad_start"),
          nb::arg("reject_reset"), nb::arg("uncertain_fraction"), nb::arg("length"),
          nb::arg("checks_start"), nb::arg("shape_observable"), nb::arg("start_limit"),
          nb::arg("start_samples"), nb::arg("start_chain"), nb::arg("unobserved_after"),
          nb::arg("degrees_like"),
          nb::arg("whole_rows"), nb::arg("process_noise"),
          nb::arg("inputs"), nb::arg("observable"), nb::arg("checks").none(),
          nb::arg("change_rows") = std::vector<int>(),
          nb::arg("change_scale") = std::vector<double>(),
          nb::arg("change_psd") = std::vector<double>(),
          nb::arg("change_limit") = std::vector<double>(), nb::arg("change_lag") = 0.0,
          nb::arg("confirm_samples") = 5, nb::arg("std_limit") = std::vector<double>(),
          nb::arg("jump_hold") = false, nb::arg("freeze_tolerance") = std::vector<double>(),
          nb::arg("silent_after") = INFINITY, nb::arg("glitch_factor") = 0.0,
          nb::arg("drift_reset") = NAN, nb::arg("whole_gap_reset") = NAN,
          nb::arg("free_pairs") = std::vector<std::pair<int, int>>(),
          nb::arg("free_reach") = std::vector<double>(),
          nb::arg("wrapped_outputs") = std::vector<int>(),
          nb::arg("bound_std_limit") = std::vector<double>(),
          nb::arg("judges_reach") = false, nb::arg("free_of").none() = nb::none(),
          nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>(),
          "``inference``: a HorizonInference, or a Python inference adapter; ``consistency``: the estimator's "
          "ConsistencyCheck; ``blocks``, ``imu_blocks``: (start, size) of every measurement "
          "block and of the IMUs'; ``whole_rows``: rows without which a sample is a dropout "
          "as a whole; settings in s and rad, NaN where off; "
          "``process_noise(dt) -> (Q, Q^-1)``, ``inputs(z_prev | None, z, dt) -> u``, "
          "``observable(imus) -> bool``; ``free_of(imus) -> [(row, row, reach)]`` (None: "
          "none): the bends those IMUs alone leave free, while the others are silent; ``checks``: the formulation's StateChecks (None: the "
          "inference's is_diverged, drifted and at_bound); ``change_rows``, ``change_scale``, "
          "``change_psd``, ``change_limit``, ``change_lag``: the estimate-change test of "
          "slowly varying states (rows, prior std, white-noise density per s, chi-square "
          "limit by dof from index 1, lag s; no rows: off); ``confirm_samples``: readings "
          "that must agree with an unconfirmed start once one disagreed with it; "
          "``std_limit`` (ny, or empty: none): each output's largest standard deviation, "
          "half the width of its range (inf: no range); ``bound_std_limit``: the same for an "
          "estimate held on a bending bound (empty: std_limit); ``jump_hold``: rows within the "
          "unobserved window of a reading beyond one sample's limit are uncertain; "
          "``freeze_tolerance`` (nz, or empty: 0): how far a reading may move from a "
          "freeze's first one and still repeat it; ``silent_after`` (s): an IMU silent for "
          "longer no longer observes its part of the shape (inf: the unobserved window); "
          "``glitch_factor``: an IMU's reading beyond this many times the one-sample limit "
          "against the prediction from an ok estimate is skipped as a glitch (0: off); "
          "``drift_reset`` (s, NaN: off): rows drifted for longer since the last ok one "
          "restart the estimate from that one's sensor states; ``whole_gap_reset`` (s, "
          "NaN: off): a valid sample after samples without the whole rows for longer "
          "restarts as after a gap; ``free_pairs`` (bend pairs of state rows), "
          "``free_reach`` (rad, one per pair), ``wrapped_outputs``: the sections whose bend "
          "the IMUs leave free; each written standard deviation carries the rms of the "
          "outputs' moves over shapes of those bends spread evenly over their reach "
          "(empty: none).")
      .def(
          "reset",
          [](Policy& p, bool keep_counts, bool keep_sensors) {
            p.check_idle();
            p.health->reset(keep_counts, keep_sensors);
          },
          nb::arg("keep_counts"), nb::arg("keep_sensors"),
          "A new recording (diagnostics zeroed unless keep_counts; the last estimate's sensor "
          "states kept for the next start with keep_sensors and keep_counts).")
      .def(
          "step",
          [](Policy& p, double t, In z) {
            Running running(p);
            SensorHealth& h = *p.health;
            const auto& s = h.settings();
            check_size(z, s.nz, "z");
            Array x = new_array({size_t(s.nx)}), P = new_array({size_t(s.nx), size_t(s.nx)});
            Array y = new_array({size_t(s.ny)}), ystd = new_array({size_t(s.ny)});
            SampleResult r;
            const auto before = counts_of(h.diagnostics);
            const int err = h.step(t, z.data(), x.data(), P.data(), y.data(), ystd.data(), r);
            auto when = [](bool has, Array a) { return has ? nb::cast(a) : nb::none(); };
            return PolicyStep{static_cast<InputError>(err),
                              r.status,
                              when(r.has_state, x),
                              when(r.has_cov, P),
                              when(r.has_state, y),
                              when(r.has_std, ystd),
                              r.outlier,
                              r.frozen,
                              counts_of(h.diagnostics) != before,
                              r.ms};
          },
          nb::arg("t"), nb::arg("z"), "One sample: a PolicyStep.")
      .def(
          "run",
          [](Policy& p, In t, In z, OutArray<int32_t> status, OutArray<double> ms,
             OutArray<uint8_t> outlier, OutArray<uint8_t> frozen, OutArray<double> y,
             OutArray<double> ystd, nb::object should_stop) {
            Running running(p);  // destroyed last: after the GIL is taken back
            SensorHealth& h = *p.health;
            const auto& s = h.settings();
            const size_t n = t.size();
            check_size(z, n * s.nz, "z");
            for (size_t size : {status.size(), ms.size(), outlier.size(), frozen.size()})
              if (size != n) throw std::invalid_argument("every result array needs n values");
            if (y.size() != n * s.ny || ystd.size() != n * s.ny)
              throw std::invalid_argument("y and ystd need n x ny values");
            // a signal's handler that raises ends the run with its exception; one that
            // defers it (the command line) leaves should_stop() to say so
            const auto interrupted = [&should_stop]() {
              nb::gil_scoped_acquire gil;
              if (PyErr_CheckSignals() != 0) throw nb::python_error();
              if (should_stop.is_none()) return false;
              const int yes = PyObject_IsTrue(should_stop().ptr());  // any truth value
              if (yes < 0) throw nb::python_error();
              return yes == 1;
            };
            nb::gil_scoped_release released;  // see the note above PythonInference
            const auto [stop, err] =
                h.run(static_cast<int64_t>(n), t.data(), z.data(), status.data(), ms.data(),
                      outlier.data(), frozen.data(), y.data(), ystd.data(), interrupted);
            return std::make_pair(stop, static_cast<InputError>(err));
          },
          nb::arg("t"), nb::arg("z"), nb::arg("status"), nb::arg("ms"), nb::arg("outlier"),
          nb::arg("frozen"), nb::arg("y"), nb::arg("ystd"), nb::arg("should_stop").none() = nb::none(),
          "Step the samples ``t`` (n), ``z`` (n, nz) into the arrays (status codes, ms, "
          "outlier and frozen flags, outputs and their std, NaN where none); stops at the "
          "first refused sample: (its index, its InputProblem), or where ``should_stop()`` "
          "(asked before the first sample and then about every 10 ms) says True: (the "
          "samples stepped, InputProblem.OK); else (n, InputProblem.OK).")
      .def("check_idle", &Policy::check_idle,
           "A RuntimeError where another thread steps this policy now (before a change "
           "of its settings).")
      .def_prop_ro("last_t",
                   [](const Policy& p) {
                     p.check_idle();
                     return p.health->last_t();
                   },
                   "The last accepted sample's time, s (-inf after a reset).")
      .def_prop_ro(
          "diagnostics",
          [](const Policy& p) {
            p.check_idle();
            return p.health->diagnostics;  // a copy
          },
          "The counts since the last reset, a PolicyDiagnostics (a copy).");
}
