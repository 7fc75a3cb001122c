// Forward-mode derivatives of a tape, and the EKF's node function built on them.
//
// A model whose symbolic Jacobian is too large to form (a tendon robot's shooting: its
// measurement residual has tens of thousands of instructions, its symbolic Jacobian
// over a million) is read as the tape of its residual alone; the Jacobian is then
// propagated with the values, one tangent per state, instruction by instruction
// (forward-mode automatic differentiation, with CasADi's derivative of each operation).
#pragma once

#include <cstdint>
#include <vector>

#include "forward_plan.hpp"
#include "model_function.hpp"
#include "tape.hpp"

namespace cmhe {

// Evaluate ``tape`` and the derivatives of its outputs with respect to every nonzero of
// input ``plan.seed``: ``out[j]`` as Tape::evaluate writes it, ``dout[j]`` (when not
// null) the output's Jacobian, row-major (its ``output_sizes[j]`` rows, one column per
// nonzero of the seed input). The plan must be ``plan_forward(tape, seed)``. Throws
// std::invalid_argument for an operation without a derivative here (FMOD, REMAINDER)
// when the tape is checked (check_forward).
void evaluate_forward(const Tape& tape, const ForwardPlan& plan, const double* const* in,
                      double* const* out, double* const* dout);
// Throws std::invalid_argument if the tape holds an operation evaluate_forward cannot
// differentiate.
void check_forward(const Tape& tape);

// ``(x, u, dt, z, m) -> (f, F, H, r)`` (the layout of
// continuum_mhe.estimators.fast.window_functions.node_function) from the transition's tape
// ``(x, u, dt) -> (f, F)`` and the measurement residual's tape ``(x, z) -> r``:
// ``r_masked = m r`` and ``H = -d r_masked / dx`` (row-major) by forward mode. Without
// the transition (``with_transition`` false) the outputs are ``(H, r)`` alone (the
// measurement function of the EKF's node and of the consistency check).
class ResidualNodeFunction : public ModelFunction {
 public:
  ResidualNodeFunction(const Tape& transition, const Tape& residual, bool with_transition);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override;

 private:
  Tape transition_, residual_;
  ForwardPlan plan_;
  bool with_transition_;
  int64_t nx_, nz_;
};

// ``x -> dy/dx`` (ny, nx), column-major, for the tape ``x -> y`` of one dense input and
// one output (the formulation's outputs), by forward mode.
class ForwardJacobianFunction : public ModelFunction {
 public:
  explicit ForwardJacobianFunction(const Tape& tape);
  int evaluate(const double* const* in, double* out) const override;
  int64_t output_size() const override { return ny_ * nx_; }

 private:
  Tape tape_;
  ForwardPlan plan_;
  int64_t nx_, ny_;
};

}  // namespace cmhe
