// Evaluation of CasADi SX functions from their instruction list (a "tape").
//
// The model of a robot is written once, symbolically, in CasADi (continuum_mhe.model);
// Python reads each SX function's algorithm (casadi.Function.instruction_*) into a
// Tape, and this file evaluates it. A new robot or option set is new data, never new
// code: nothing is compiled at run time.
#pragma once

#include <cstdint>
#include <vector>

namespace cmhe {

// Operation codes of a tape, independent of CasADi's own numbering (Python maps
// CasADi's OP_* names onto these; an operation missing here is refused there).
enum Op : int32_t {
  OP_INPUT = 0,   // w[res] = in[a][b]        (a: input index, b: nonzero offset)
  OP_OUTPUT,      // out[b][res] = w[a]       (b: output index, res: dense offset)
  OP_CONST,       // w[res] = constants[a]
  OP_ASSIGN,      // w[res] = w[a]
  OP_ADD, OP_SUB, OP_MUL, OP_DIV, OP_NEG, OP_EXP, OP_LOG, OP_POW, OP_CONSTPOW,
  OP_SQRT, OP_SQ, OP_TWICE, OP_SIN, OP_COS, OP_TAN, OP_ASIN, OP_ACOS, OP_ATAN,
  OP_LT, OP_LE, OP_EQ, OP_NE, OP_NOT, OP_AND, OP_OR, OP_FLOOR, OP_CEIL, OP_FMOD,
  OP_FABS, OP_SIGN, OP_COPYSIGN, OP_IF_ELSE_ZERO, OP_ERF, OP_FMIN, OP_FMAX, OP_INV,
  OP_SINH, OP_COSH, OP_TANH, OP_ASINH, OP_ACOSH, OP_ATANH, OP_ATAN2, OP_HYPOT,
  OP_LOG1P, OP_EXPM1, OP_REMAINDER,
  OP_GUARD,       // where w[a] is zero (in every evaluation of a batch), skip the next res
                  // instructions: values only IF_ELSE_ZERO(w[a], .) reads (share_tape)
  OP_COUNT
};

struct Instruction {
  int32_t op, res, a, b;
};

// One SX function: inputs and outputs are dense column-major arrays (an output's
// structural zeros are written too). A null input
// pointer reads as zeros, a null output pointer is not written (CasADi's convention).
class Tape {
 public:
  Tape(std::vector<Instruction> code, std::vector<double> constants,
       std::vector<int64_t> input_sizes, std::vector<int64_t> output_sizes,
       int64_t work_size);

  // ``out[k]``: where output k goes. Always succeeds once constructed (the callers
  // check the values).
  void evaluate(const double* const* in, double* const* out) const;
  // all outputs concatenated into ``out``
  void evaluate_flat(const double* const* in, double* out) const;
  // ``count`` evaluations at once, instruction by instruction over all of them (the
  // dispatch of each instruction is paid once per batch, and its loop vectorises):
  // evaluation ``k`` reads input ``i`` at ``in[i] + k * in_stride[i]`` and writes output
  // ``j`` at ``out[j] + k * out_stride[j]``.
  void evaluate_batch(const double* const* in, const int64_t* in_stride, double* const* out,
                      const int64_t* out_stride, int64_t count) const;

  const std::vector<int64_t>& input_sizes() const { return input_sizes_; }
  const std::vector<int64_t>& output_sizes() const { return output_sizes_; }
  int64_t output_size() const { return output_size_; }
  int64_t instructions() const { return static_cast<int64_t>(code_.size()); }
  const std::vector<Instruction>& code() const { return code_; }
  const std::vector<double>& constants() const { return constants_; }
  int64_t work_size() const { return work_size_; }

 private:
  std::vector<Instruction> code_;
  std::vector<double> constants_;
  std::vector<int64_t> input_sizes_, output_sizes_;
  int64_t output_size_ = 0;
  int64_t work_size_ = 0;
  std::vector<int64_t> sparse_outputs_;  // outputs with structural zeros
  // per instruction: the pair index p * kPairOps + q where it and the next run as a
  // pair in evaluate_batch, else -1
  std::vector<int16_t> pair_;
  static constexpr int kPairOps = 9;
  static int pair_index(int32_t op);  // its index among the paired operations, or -1
  static constexpr int64_t kLanes = 8;   // a batch's rows are padded to a multiple
};

// ``code`` (a tape as Python reads it from CasADi) with every value computed once and
// only the values an output needs: an instruction that applies the same operation to
// the same inputs, constant (the same bits) or values as an earlier one is the earlier
// value (value numbering; ADD and MUL operands in either order), instructions no output
// needs are dropped, and work slots are reassigned (a slot is free after its value's
// last use). The values that only one side of a branch needs (``if_else(c, a, b)`` is
// ``IF_ELSE_ZERO(c, a) + IF_ELSE_ZERO(!c, b)``: every use of such a value is an
// ``IF_ELSE_ZERO(c, .)``, directly or through other such values) are moved together
// behind an OP_GUARD on ``c``, so that an evaluation skips the side not taken. The
// arithmetic of every value used is unchanged. ``work_size``: the slots used.
std::vector<Instruction> share_tape(const std::vector<Instruction>& code,
                                    const std::vector<double>& constants,
                                    int64_t& work_size);

}  // namespace cmhe
