// The sensor-health policy of every estimator (continuum_mhe.estimators.sensor_health,
// whose Estimator.step docstring states it): around each inference step it checks the
// input, marks frozen sensors as dropouts, restarts the inference after a gap, a bad
// start, a robust MHE's run of rejected readings or a divergence, judges the readings
// against the estimate (consistency.hpp) and decides the status; ``run`` steps a whole
// recording into preallocated arrays without leaving compiled code.
//
// The inference (the MHE's window, the EKF, the UKF) and the model's checks of a state
// come through the interface ``PolicyInference``; the binding implements it for the
// fast MHE's compiled step (horizon.hpp) and for a Python inference object.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "consistency.hpp"
#include "model_function.hpp"

namespace cmhe {

// The statuses, in the order of continuum_mhe.results.Status (STATUS_NAMES)
enum StatusCode : int {
  ST_OK = 0,
  ST_DROPOUT,
  ST_NOT_CONVERGED,
  ST_SOLVER_FAILED,
  ST_NO_ESTIMATE,
  ST_FALLBACK_IPOPT,
  ST_BRANCH_RESTART,
  ST_RESET,
  ST_UNCERTAIN,
  ST_DRIFTED,
  ST_AT_BOUND,
  ST_INCONSISTENT,
  ST_COUNT
};
extern const char* const STATUS_NAMES[ST_COUNT];

// A sample the policy refuses (the caller's one-line error names it)
enum InputError : int {
  INPUT_OK = 0,
  INPUT_TIME = 1,      // t not finite, or not later than the previous sample's
  INPUT_DEGREES = 2,   // a tilt reading beyond degrees_like (just over pi): degrees for radians
  INPUT_INFINITE = 3,  // an infinite tilt reading
};

// A numerical failure of an inference step (the policy restarts from the sample)
struct InferenceFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// What the policy needs of an inference object and of the model's checks of a state.
class PolicyInference {
 public:
  virtual ~PolicyInference() = default;
  // forget the state: the next infer starts from its sample. ``kept_x`` (nx) and
  // ``kept_P`` (nx x nx), or null: the last confirmed (ok) estimate before the restart,
  // at ``kept_t`` s, and its covariance, whose sensor states (the formulation's
  // ``sensor_states``: biases, misalignments, gains) the start keeps
  virtual void restart(const double* kept_x, const double* kept_P, double kept_t) = 0;
  // one sample (``mask`` (nz) its valid readings): the status; ``x`` (nx) and ``P``
  // (nx x nx) written when ``has_state`` / ``has_cov`` are set. Throws InferenceFailure
  // (or std::runtime_error) on a numerical failure.
  virtual int infer(double t, const double* z, const double* mask, double* x, double* P,
                    bool& has_state, bool& has_cov) = 0;
  // the outputs (ny) of the state the last infer returned, and standard deviations (ny)
  // of a state with covariance P
  virtual void output(const double* x, double* y) = 0;
  virtual void output_std(const double* x, const double* P, double* s) = 0;
  // where the last infer's estimate sits on a bending bound that its covariance P is
  // conditioned on: the covariance not conditioned on it into ``P`` (nx x nx), true;
  // else false (an estimator that does not hold its bounds)
  virtual bool bound_free_covariance(double* /*P*/) { return false; }
  // whether the last infer down-weighted a reading (robust MHE); whether it rejected
  // every valid reading: 1, 0, or -1 when the sample had none
  virtual bool outlier() { return false; }
  virtual int rejected_every_reading() { return 0; }
  // the same for the blocks that hold any of ``rows`` (reading rows): 1 when every such
  // block of the newest sample with a valid reading was rejected, 0 when not, -1 when
  // none had a reading
  virtual int rejected_readings(const std::vector<int>& /*rows*/) { return 0; }
  // the model's checks of a state (P may be nullptr)
  virtual bool is_diverged(const double* x, const double* P) = 0;
  virtual bool drifted(const double* x) = 0;
  virtual bool at_bound(const double* x) = 0;
  // whether the current start (since the last restart) is one that no later reading
  // confirms: its formulation cannot tell what the reading ``z`` (nz) at ``t`` s, its
  // first with an IMU's reading, shows from the sensors' own errors (a tendon robot's
  // tip load at a start that knows nothing of the IMUs). Asked once per start; every
  // estimate of that start until the next restart is then not trusted.
  virtual bool start_untrusted(double /*t*/, const double* /*z*/) { return false; }
};

// The process noise ``Q(dt)`` (nx x nx) and its inverse, cached per time step rounded to
// 1e-9 s (at most 4096 steps), computed by ``compute`` on a miss; and the model's inputs
// ``u(z_prev, z, dt)`` (nu), by ``inputs`` (none when nu is 0).
class ProcessModel {
 public:
  using QFunction = std::function<void(double dt, double* Q, double* Qinv)>;
  using InputFunction =
      std::function<void(const double* z_prev, const double* z, double dt, double* u)>;
  ProcessModel(int nx, int nu, int nz, QFunction compute, InputFunction inputs);
  // (Q, Q^-1) of ``dt``: pointers valid until the next call
  std::pair<const double*, const double*> noise(double dt);
  // u from the previous valid reading ``z_prev`` (nullptr: none) to ``z``
  const double* inputs(const double* z_prev, const double* z, double dt);
  int nx, nu, nz;

 private:
  QFunction compute_;
  InputFunction inputs_;
  std::map<int64_t, std::vector<double>> cache_;  // Q then Q^-1
  std::vector<double> scratch_, u_;
};

// A model's inputs in compiled code: ``fn(z_prev, z, dt) -> u`` (inputs of nz, nz and 1
// values, nu outputs); u is zero where there is no previous reading or either reading
// has a value that is not finite (a dropout)
struct CompiledInputs {
  std::shared_ptr<const TapeFunction> fn;
  int nz = 0, nu = 0;
  void operator()(const double* z_prev, const double* z, double dt, double* u) const;
};

// A formulation's checks of a state as data (continuum_mhe.model.formulations:
// ``is_diverged``, ``at_bound``): not finite; a pair of bend coordinates (i, j) with
// ``x_i^2 + x_j^2`` beyond its ``diverged_r2``, or a rate row beyond ``rate_limit`` in
// magnitude; a covariance not finite or with a ``std_rows`` variance beyond
// ``std_limit2``. At its bound: ``hypot(x_i, x_j) >= at_bound_r`` of a pair. Beside
// these, a formulation's own rules as a model function ``flags(x) -> (diverged,
// at_bound, drifted)``, each nonzero where it holds (``drifted``: ``ok`` becomes
// ``drifted``); without it nothing drifts.
struct StateChecks {
  int nx = 0;
  std::vector<std::pair<int, int>> pairs;
  std::vector<double> diverged_r2, at_bound_r;
  std::vector<int> rate_rows;
  double rate_limit = INFINITY;
  std::vector<int> std_rows;
  double std_limit2 = INFINITY;
  std::shared_ptr<const TapeFunction> flags;  // none: no rules of its own
  bool is_diverged(const double* x, const double* P) const;  // P may be nullptr
  bool at_bound(const double* x) const;
  bool drifted(const double* x) const;

 private:
  bool flag(const double* x, int k) const;  // flags(x)[k] nonzero (false without flags)
};

// The policy's fixed data (recovery settings: NaN where off)
struct PolicySettings {
  int nx, nz, ny;
  std::vector<std::pair<int, int>> blocks;      // every measurement block: (start, size)
  std::vector<std::pair<int, int>> imu_blocks;  // the IMUs' blocks
  std::vector<int> tilt_rows;                   // rows checked for degrees
  std::vector<int> tip_rows;                    // outputs of the tip position (m)
  double freeze = NAN;                          // s
  int freeze_samples = 1;
  double gap_reset = NAN;     // s
  double bad_start = NAN;     // s
  double reject_reset = NAN;  // s
  double uncertain_fraction = 0.0;
  double length = 0.0;         // the robot's length, m
  bool checks_start = false;   // a calibrated covariance: start and consistency checks
  bool shape_observable = true;
  std::vector<double> start_limit;  // the start check's NIS limit by dof (index 0 unused)
  int start_samples = 2;            // consecutive readings beyond it that restart
  // bad-start restarts in a row (each within the probation time of the one before, no
  // other restart between) after which the check stops restarting until the probation
  // time passes, another restart or an IMU's return: readings that no restart fits
  // (0: no limit)
  int start_chain = 0;
  double unobserved_after = 1.0;    // s, an IMU's silence that unobserves it (gap reset off)
  double degrees_like = 0.0;        // rad, a tilt reading beyond it is in degrees
  // the formulation's checks of a state, when it states them as data (else the
  // inference's is_diverged, drifted and at_bound; with them a state drifts by their flags)
  std::optional<StateChecks> checks;
  // rows without which a sample is a dropout as a whole (a tendon robot's tensions and
  // their derivatives: its IMUs' model needs them)
  std::vector<int> whole_rows;
  // The estimate-change test of slowly varying states (a tendon robot's IMU errors,
  // random walks): their rows, prior standard deviations (the test's units) and
  // white-noise densities (per s), the lag (s), and the chi-square limit by degrees of
  // freedom (index 0 unused). No rows: off.
  std::vector<int> change_rows;
  std::vector<double> change_scale, change_psd, change_limit;
  double change_lag = 0.0;
  // readings that must agree with an unconfirmed start (the first estimate, a forced
  // restart) once one of them disagreed with it, before it is trusted
  int confirm_samples = 5;
  // ny, or empty: the largest standard deviation of each output, half the width of the
  // range its value has on the robot (inf: no range); a written one is held to it
  std::vector<double> std_limit;
  // ny, or empty (std_limit): the same for an estimate held on a bending bound, whose
  // standard deviations are not conditioned on it: a section's bend within 0 and pi
  std::vector<double> bound_std_limit;
  // The bend pairs (state rows) of the sections whose bend the IMUs leave free, each
  // with its section's reach (theta_max, rad), and the wrapped outputs: each written
  // standard deviation carries the root mean square of how far the output moves from
  // the estimate's when those bends take shapes spread evenly over their reach (no
  // reading pins them, so the estimate may be any of them). Empty: none.
  std::vector<std::pair<int, int>> free_pairs;
  std::vector<double> free_reach;
  std::vector<int> wrapped_outputs;
  // rows within the unobserved window of a reading beyond one sample's limit against
  // the prediction are uncertain (IMUs without gyros: a burst of wrong readings agrees
  // with the estimate that moved onto it)
  bool jump_hold = false;
  // nz: how far a reading may move from a freeze's first one and still repeat it (a stuck
  // IMU whose value jitters far below its noise is frozen too; the binding fills 0s)
  std::vector<double> freeze_tolerance;
  // s: an IMU silent for longer than this (or than the unobserved window, where shorter)
  // no longer observes its part of the shape (observed_now)
  double silent_after = INFINITY;
  // an IMU's reading whose NIS against the prediction from the previous estimate, where
  // that was ok, exceeds this many times the one-sample limit (chi-square 99.99 %, times
  // the model error the readings showed; given the sample's readings that are not an
  // IMU's, such as a tendon robot's tensions) is skipped as a glitch (a dropout of that
  // IMU for the sample, its row not ok); so the next reading is taken whatever it is (a
  // second such reading in a row: the robot may have moved so). A reading whose whitened
  // residual alone is beyond the limit is judged with the Jacobian at the IMU's reading
  // before as well (a tilt reading near the opposite gravity direction); 0: off
  double glitch_factor = 0.0;
  // s: rows drifted (the model's slowly varying error states gone from their prior) for
  // longer than this since the last ok row restart the estimate from the sensors' states
  // of that ok row (a fault that has passed: a frozen IMU, wrong tensions for a while)
  double drift_reset = NAN;
  // s: a valid sample after samples without the whole rows (a tendon robot's tensions
  // missing: no reading was used, and the prediction has no tensions) for longer than
  // this restarts as after a gap (the gap reset on; NaN: only gap_reset's)
  double whole_gap_reset = NAN;
  // a covariance that is no noise model (the paper's weight W): an ok row whose written tip
  // standard deviation passes the robot's length is uncertain, the tip anywhere in its reach
  bool judges_reach = false;
};

// What the policy did since its reset (continuum_mhe.results.Diagnostics)
struct PolicyDiagnostics {
  int64_t restarts = 0, gap_resets = 0, frozen_samples = 0, bad_starts = 0,
          reject_resets = 0, bound_samples = 0,
          bad_start_chains = 0,  // chains in which the check held a restart back
          untrusted_start_samples = 0,  // estimates of a start the inference did not trust
          glitches = 0,  // IMU readings skipped as glitches (glitch_factor)
          drift_resets = 0,  // restarts after rows drifted for drift_reset
          late_imu_starts = 0,  // restarts at the first reading of an IMU the start lacked
          // restarts after a step shorter than the gap reset but many times the usual one
          // (a clock that stepped forward, samples lost) whose readings the glitch test
          // would have skipped
          jump_resets = 0;
  // the first such step: the time (s) of the sample after it, and its length (s)
  double first_jump_t = NAN, first_jump_step = NAN;
  std::vector<std::pair<int, double>> first_freezes;  // (IMU, t), in order
  bool has_failure = false;
  std::string last_failure;
  double max_noise_scale = 1.0, model_error = 0.0;
};

// One sample's answer (the arrays are the caller's)
struct SampleResult {
  int status = ST_NO_ESTIMATE;
  bool has_state = false, has_cov = false, has_std = false, outlier = false, frozen = false;
  double ms = 0.0;
};

// The bends that no reading pins (PolicySettings::free_pairs, free_reach): their state
// rows and reach (rad)
struct FreeBends {
  std::vector<std::pair<int, int>> pairs;
  std::vector<double> reach;
};

class SensorHealth {
 public:
  // ``observable(imus)``: whether those IMUs (0-based, ascending) determine the shape;
  // ``free_of(imus)`` (may be empty): the bends those IMUs alone leave free, for the
  // standard deviations while the others are silent
  SensorHealth(PolicySettings settings, PolicyInference& inference, ProcessModel& process,
               ConsistencyCheck& consistency,
               std::function<bool(const std::vector<int>&)> observable,
               std::function<FreeBends(const std::vector<int>&)> free_of = {});

  // a new recording: forget every sample (and zero the diagnostics unless keep_counts)
  // a new recording, or (keep_counts) a restart within one; ``keep_sensors`` (with
  // keep_counts): the next start keeps the last estimate's sensor states
  void reset(bool keep_counts, bool keep_sensors);
  // One sample: INPUT_OK and the answer (state nx, cov nx*nx, y ny, ystd ny), or the input
  // error (nothing changed)
  int step(double t, const double* z, double* x, double* P, double* y, double* ystd,
           SampleResult& out);
  // ``n`` samples (t n, z n x nz) into the arrays (status n, ms n, outlier n, frozen n, y
  // n x ny, ystd n x ny, NaN where none); stops at the first refused sample: returns
  // (its index, its error), or (n, INPUT_OK); ``interrupted()`` is asked before the first
  // sample and between samples at most every kInterruptCheck (true: stop there)
  std::pair<int64_t, int> run(int64_t n, const double* t, const double* z, int32_t* status,
                              double* ms, uint8_t* outlier, uint8_t* frozen, double* y,
                              double* ystd, const std::function<bool()>& interrupted);

  static constexpr std::chrono::milliseconds kInterruptCheck{10};

  const PolicySettings& settings() const { return s_; }
  PolicyDiagnostics diagnostics;
  double last_t() const { return last_t_; }
  bool unconfirmed() const { return !returned_.empty(); }

 private:
  // ``keep_sensors``: hand the inference the last estimate (a restart within a
  // recording that does not doubt it: a gap, a live reconnect), else nothing
  void restart(bool keep_sensors);
  const double* unfreeze(double t, const double* z, bool& frozen);
  void measurement_mask(const double* z);
  bool note_imus(double t);  // fills back_rows_
  bool observed_now(double t);
  bool imu_reading() const;  // whether an IMU's reading is valid at this sample (mask_)
  // whether an IMU whose reading came after a silence (late_pending_) and that has not
  // read since the last (re)start reads at this sample beside every IMU that has, and
  // one has: the start was made without its part of the shape
  bool imu_joins() const;
  // the IMUs read at this sample enter imu_seen_, but a late one while others were seen
  void note_imus_seen();
  double unobserved_window() const;
  // the tip position's standard deviation, m, from an estimate's output stds
  double tip_std(const double* ystd) const;
  // the bad-start check (start_check.py's doc)
  void start_clear();
  void start_reopen(double hold);
  bool start_watching(double t) const;
  bool start_inconsistent(double t, const double* z);
  void start_remember(double t, const double* z, const double* x, const double* P,
                      bool has_state, bool has_cov);
  bool consistency_check(double t, const double* z, const double* judged, const double* x,
                         const double* P, bool has_state, bool has_cov);
  bool diverged(const double* x, const double* P);
  bool state_drifted(const double* x);  // the checks' drifted, else the inference's
  // Whether the change-test states moved between the estimate ``change_lag`` ago and
  // this one (x, P) beyond what their model allows: the change d against the covariance
  // the information gained and their random walk give it, ``P_then + Q(dt) - P_now``;
  // remembers this estimate
  bool changed_too_fast(double t, const double* x, const double* P);
  struct ChangeEntry {
    double t;
    std::vector<double> x, P;  // the change-test states and their covariance block
  };
  std::deque<ChangeEntry> change_past_;
  double changed_until_ = -INFINITY;  // the change test holds rows drifted until then
  int infer_once(double t, const double* z, double* x, double* P, bool& has_state,
                 bool& has_cov, bool& failed);
  // ``z`` with the IMU readings that glitch_factor skips as glitches made missing (their
  // rows zeroed in gated_mask_, a copy of mask_; counted in ``gated``): z itself where
  // none is
  const double* gate_glitches(double t, const double* z, int& gated);
  // the previous sample's estimate where it was ok, its readings and time (gate_glitches)
  std::vector<double> gate_x_, gate_P_, gate_z_, gated_z_, gated_mask_;
  double gate_t_ = -INFINITY;
  bool gate_has_ = false;
  // the gate's estimate is a start's first (not ok): only a reading near the opposite
  // gravity direction, judged again with the Jacobian at the reading before, is gated
  bool gate_from_start_ = false;
  std::vector<std::vector<int>> gate_sets_;  // scratch: the IMUs' judged rows, their NIS
  std::vector<int> gate_imus_, gate_given_;
  std::vector<char> imu_row_;  // 1 on the rows of an IMU's block
  std::vector<double> gate_nis_, gate_whitened_, gate_limit_;

  PolicySettings s_;
  PolicyInference& inference_;
  ProcessModel& process_;
  ConsistencyCheck& consistency_;
  std::function<bool(const std::vector<int>&)> observable_;
  std::map<std::vector<int>, bool> observable_cache_;
  std::function<FreeBends(const std::vector<int>&)> free_of_;
  std::map<std::vector<int>, FreeBends> free_cache_;
  FreeBends static_free_;  // the robot's own (every IMU reporting)
  // the bends free at ``t``: the robot's own, or, while some IMUs are silent (no valid
  // reading within the unobserved window, or frozen), those the others leave free
  const FreeBends& free_now(double t);
  // the IMUs with a valid reading within ``window`` s of ``t`` and not frozen, into
  // reporting_ (ascending); whether some, not all, are
  bool reporting_imus(double t, double window);
  std::vector<int> reporting_;
  double last_t_ = -INFINITY, last_valid_t_ = -INFINITY, first_valid_t_ = -INFINITY;
  // the average step between valid samples, the jumps left out (NaN before the second)
  double step_avg_ = NAN;
  // the last sample whose tip standard deviation exceeded the uncertain fraction (the
  // estimate's belief spanned shapes far apart); -inf since the (re)start when none
  double wide_t_ = -INFINITY;
  // the last row whose tip standard deviation, its own or the one written, was beyond
  // the uncertain fraction, until a row with an IMU reading follows it (-inf: none)
  double wide_row_t_ = -INFINITY;
  // the time of the restart the last sample with an IMU reading forced (the consistency
  // check's; the restart's own sample included), -inf where that sample forced none
  double forced_before_t_ = -INFINITY;
  // the last reading beyond one sample's limit that the estimate moved onto
  double jumped_t_ = -INFINITY;
  // how many more samples' readings must agree with the estimate of a start before it
  // is trusted: start_samples after a restart that the readings forced (the estimate
  // before it contradicted them, or failed), 1 after the first estimate of a recording
  // (or after a gap), confirm_after_ once a reading disagreed with either; 0 otherwise
  int unconfirmed_ = 0;
  // what a disagreeing reading sets unconfirmed_ to while it is positive: start_samples
  // after a forced restart, confirm_samples after the first estimate of a recording, and
  // after a restart forced at the sample right after another confirm_samples or the
  // readings the unobserved window holds, whichever is fewer (at least start_samples)
  int confirm_after_ = 0;
  // an estimate has been made since the last (re)start: the next one is a start from
  // one reading (the first, or the first after a gap), which a later reading confirms
  bool started_ = false;
  bool start_untrusted_ = false;  // the inference did not trust the current start
  bool start_judged_ = false;     // ... asked, at the start's first IMU reading
  // the last drifted row's time (-inf: none), kept across restarts, and whether the
  // estimator restarted after it or after a drifted row within the probation time before
  // it (rows drifted again soon after a restart keep the hold on the rows after them)
  double drifted_t_ = -INFINITY;
  // the samples since the last valid one that lacked the whole rows, and whether one
  // lacked every reading otherwise (a plain gap)
  int whole_missing_ = 0;
  bool other_missing_ = false;
  // the first drifted row since the last ok row or restart (NaN: none; restart clears
  // it), and whether a drift reset may restart (once after each ok row)
  double drift_since_ = NAN;
  bool drift_armed_ = true;
  bool restarted_since_drift_ = false;
  std::vector<double> freeze_value_, freeze_since_, freeze_last_t_, imu_last_valid_;
  std::vector<int64_t> freeze_count_;
  std::vector<char> has_freeze_value_;
  // per IMU: its readings of the last sample were a freeze's (set by unfreeze): it
  // observes nothing from the freeze's discovery on (observed_now)
  std::vector<char> frozen_now_;
  // per IMU: it has read since the last (re)start (imu_joins), it reads at this sample
  // (before the glitch gate), and its reading came after a silence longer than the
  // unobserved window (its first one too) and has not yet entered a start
  std::vector<char> imu_seen_, reads_now_, late_pending_;
  std::vector<double> z_, mask_, zero_mask_, bias_, std_b_, P_free_;
  // the free bends' spread: the shapes' bends in units of their reach (FREE_SHAPES x
  // free sections x 2, grown to the most sections free at once), a state and its outputs
  static constexpr size_t FREE_SHAPES = 64;
  std::vector<double> free_unit_, free_x_, free_y_, free_msd_;
  size_t free_slots_ = 0;
  std::vector<char> free_wrapped_;
  void widen_by_free_bends(const double* x, const double* y, double* ystd,
                           const FreeBends& free);
  // The constant reading errors' term of the standard deviations counts each reading
  // the estimate still holds: a reading missing now (a dropout) at its last value while
  // it was valid within the unobserved window since the last (re)start, since its
  // constant error entered the state through the estimates before (held_t_: -inf where
  // none); held_z_ and held_mask_ the readings and mask the term is computed on
  std::vector<double> held_z_, held_t_, held_mask_;
  // the last ok estimate with a covariance since the last restart that kept nothing
  // (has_last_), for a restart that keeps the sensors' states
  std::vector<double> last_x_, last_P_;
  double last_state_t_ = 0.0;  // its time, s
  bool has_last_ = false;
  // whether last_x_ holds an ok estimate of this recording, which a restart that keeps
  // nothing leaves there: a drift reset takes it (a restart the readings forced at a
  // fault's samples forgets what the fault did not change)
  bool has_ok_ = false;
  std::vector<int> back_rows_;
  // scratch: the start check's judged rows (one set), the rows they are conditioned
  // on, and their NIS (the vectors keep their storage from one sample to the next)
  std::vector<std::vector<int>> start_sets_;
  std::vector<int> start_given_;
  std::vector<double> start_nis_;
  std::optional<double> rejecting_since_;
  // the bad-start check's state
  double since_ = NAN, agreed_since_ = NAN, hold_ = 0.0, prev_t_ = 0.0;
  int run_ = 0;
  bool has_prev_ = false;
  // bad-start restarts in a row (PolicySettings::start_chain), and whether the check
  // has held back a restart since the chain began
  int chain_ = 0;
  bool chain_held_ = false;
  // bad starts in a row from which the rows are uncertain until the chain ends
  static constexpr int kChainUntrusted = 2;
  void end_chain() {
    chain_ = 0;
    chain_held_ = false;
  }
  // the times of the restarts the readings forced (bad start, reject reset, a diverged
  // or failed estimate) within the bad-start probation time or the unobserved window,
  // the longer; kRestartRun of them make every estimate meanwhile uncertain
  std::deque<double> forced_t_;
  static constexpr int kRestartRun = 4;
  // the estimate-change test's least eigenvalue of the change's covariance (the
  // information gained plus the random walk over the lag), in the states' prior
  // variances: below it a direction is not tested (the defaults' random walks of the
  // IMU errors reach at most a tenth of it over the lag)
  static constexpr double kChangeFloor = 1e-3;
  std::vector<double> prev_x_, prev_P_, prev_z_;
  std::vector<int> returned_;  // rows of the IMUs back from a silence, sorted
  // the consistency check's previous sample
  bool cons_has_prev_ = false;
  double cons_t_ = 0.0;
  std::vector<double> cons_z_;
};

}  // namespace cmhe
