// Model functions, all evaluated the same way, ``evaluate(const double** in, double* out)``
// (0 on success): one SX function (TapeFunction), or the whole MHE window built from a
// node's two pieces (WindowFunction, TailFunction; layouts in
// continuum_mhe.estimators.fast.window_functions).
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "forward_plan.hpp"
#include "tape.hpp"

namespace cmhe {

class ModelFunction {
 public:
  ModelFunction() = default;
  virtual ~ModelFunction() = default;
  ModelFunction(const ModelFunction&) = delete;
  ModelFunction& operator=(const ModelFunction&) = delete;

  virtual int evaluate(const double* const* in, double* out) const = 0;
  virtual int64_t output_size() const = 0;
};

class TapeFunction : public ModelFunction {
 public:
  explicit TapeFunction(Tape tape) : tape_(std::move(tape)) {}
  int evaluate(const double* const* in, double* out) const override {
    tape_.evaluate_flat(in, out);
    return 0;
  }
  int64_t output_size() const override { return tape_.output_size(); }
  const Tape& tape() const { return tape_; }

 private:
  Tape tape_;
};

// ``inner`` with its last evaluations remembered, per thread (the last two of any
// RememberedFunction on that thread): an evaluation at the same inputs, bit for bit (a
// null input pointer is an input of its own), copies the outputs kept instead of
// evaluating again. An EKF's update and the consistency check's prediction evaluate the
// measurement terms at the same state; two EKFs of one model side by side (a tendon
// robot's load hypotheses) step before the check evaluates at either's prediction.
// ``input_sizes``: the number of values of each input; ``inner`` must outlive this
// object.
class RememberedFunction : public ModelFunction {
 public:
  RememberedFunction(const ModelFunction& inner, std::vector<int64_t> input_sizes);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override { return inner_.output_size(); }
  // the evaluations answered from those kept, on every thread
  int64_t hits() const { return hits_.load(std::memory_order_relaxed); }

 private:
  // whether ``kept`` (presence and values of each input) holds the inputs ``in``
  bool same_inputs(const double* kept, const double* const* in) const;
  const ModelFunction& inner_;
  std::vector<int64_t> input_sizes_;
  mutable std::atomic<int64_t> hits_{0};
  int64_t inputs_ = 0;  // the values of all inputs together
  uint64_t id_;         // unique among these objects, also after one is freed
};

// ``(x, u, dt, z, m) -> m * r(x, z)`` (the masked residual, a function of a node's
// inputs) from the residual's tape ``(x, z) -> r``; a null ``m`` reads as zeros.
class MaskedResidualFunction : public ModelFunction {
 public:
  explicit MaskedResidualFunction(const Tape& residual);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override { return nz_; }

 private:
  Tape residual_;
  int64_t nz_;
};

// One node's measurement terms ``(x, z, m) -> (r, jr, sr)`` (layout of
// continuum_mhe.estimators.fast.window_functions.node_pieces): the tape of all three, or, for a
// model whose symbolic Jacobian is too large to form (``forward``), the residual's tape
// ``(x, z) -> r`` alone, with ``r`` masked by ``m``, ``jr = d(m r)/dx`` (row-major) by
// forward-mode derivatives (forward.hpp) and ``sr`` zero (Gauss-Newton steps).
class MeasurementPiece {
 public:
  explicit MeasurementPiece(const Tape& meas);
  // ``sr_size``: the second-order term's entries (``sr`` holds that many zeros)
  MeasurementPiece(const Tape& residual, int64_t sr_size);
  // one node
  void evaluate(const double* x, const double* z, const double* m, double* r, double* jr,
                double* sr) const;
  // ``count`` nodes, columns of ``X`` (nx), ``Z``, ``M`` (nz) into ``R``, ``JR``, ``SR``
  void evaluate_batch(const double* X, const double* Z, const double* M, double* R,
                      double* JR, double* SR, int64_t count) const;

  Tape tape;
  bool forward;
  ForwardPlan plan;  // with ``forward``: the residual's tangents over the state
  int64_t nx, nz, nr, njr, nsr;
};

// ``(X, Z, M, U, DT) -> (R, JR, W, FJ, SR)`` over a window of ``horizon`` nodes from
// ``meas: (x, z, m) -> (r, jr, sr)`` per node and ``proc: (x, xn, u, dt) -> (w, fj)``
// per stage; inputs and outputs column-major, one column per node or stage.
class WindowFunction : public ModelFunction {
 public:
  WindowFunction(const MeasurementPiece& meas, const Tape& proc, int64_t horizon);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override;

 private:
  MeasurementPiece meas_;
  Tape proc_;
  int64_t n_, nu_, nw_, nfj_;
};

// ``(x_prev, x, z, m, u, dt) -> (r, JR, W, FJ, SR)``: the window's outputs of one last
// node and of the stage into it.
class TailFunction : public ModelFunction {
 public:
  TailFunction(const MeasurementPiece& meas, const Tape& proc);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override;

 private:
  MeasurementPiece meas_;
  Tape proc_;
  int64_t nw_, nfj_;
};

}  // namespace cmhe
