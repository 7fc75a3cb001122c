// Model functions with a plain C entry point, ``int f(const double** in, double* out)``
// (0 on success), so that compiled kernels call every model the same way: one SX
// function (TapeFunction), or the whole MHE window built from a node's two pieces
// (WindowFunction, TailFunction; layouts in continuum_mhe.estimators.fast.codegen).
#pragma once

#include <cstdint>

#include "tape.hpp"

namespace cmhe {

using Entry = int (*)(const double* const*, double*);

class ModelFunction {
 public:
  ModelFunction();
  virtual ~ModelFunction();
  ModelFunction(const ModelFunction&) = delete;
  ModelFunction& operator=(const ModelFunction&) = delete;

  virtual int evaluate(const double* const* in, double* out) const = 0;
  virtual int64_t output_size() const = 0;
  // address of a C function that calls ``evaluate`` on this object
  std::uintptr_t address() const;

 private:
  int slot_;
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

// ``(X, Z, M, U, DT) -> (R, JR, W, FJ, SR)`` over a window of ``horizon`` nodes from
// ``meas: (x, z, m) -> (r, jr, sr)`` per node and ``proc: (x, xn, u, dt) -> (w, fj)``
// per stage; inputs and outputs column-major, one column per node or stage.
class WindowFunction : public ModelFunction {
 public:
  WindowFunction(const Tape& meas, const Tape& proc, int64_t horizon);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override;

 private:
  Tape meas_, proc_;
  int64_t n_, nx_, nz_, nu_, nr_, njr_, nsr_, nw_, nfj_;
};

// ``(x_prev, x, z, m, u, dt) -> (r, JR, W, FJ, SR)``: the window's outputs of one last
// node and of the stage into it.
class TailFunction : public ModelFunction {
 public:
  TailFunction(const Tape& meas, const Tape& proc);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override;

 private:
  Tape meas_, proc_;
  int64_t nr_, njr_, nsr_, nw_, nfj_;
};

}  // namespace cmhe
