#include "tape.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "vector_math.hpp"

namespace cmhe {

Tape::Tape(std::vector<Instruction> code, std::vector<double> constants,
           std::vector<int64_t> input_sizes, std::vector<int64_t> output_sizes,
           int64_t work_size)
    : code_(std::move(code)),
      constants_(std::move(constants)),
      input_sizes_(std::move(input_sizes)),
      output_sizes_(std::move(output_sizes)),
      work_size_(work_size) {
  for (int64_t s : output_sizes_) output_size_ += s;
  const int64_t n_in = static_cast<int64_t>(input_sizes_.size());
  // every index is checked once here, so that evaluation needs no checks
  for (size_t k = 0; k < code_.size(); ++k) {
    const Instruction& I = code_[k];
    auto bad = [&](const char* what) {
      throw std::invalid_argument("tape instruction " + std::to_string(k) + ": " + what);
    };
    if (I.op < 0 || I.op >= OP_COUNT) bad("unknown operation");
    auto work = [&](int32_t i) { if (i < 0 || i >= work_size_) bad("work index out of range"); };
    switch (I.op) {
      case OP_INPUT:
        work(I.res);
        if (I.a < 0 || I.a >= n_in || I.b < 0 || I.b >= input_sizes_[I.a]) bad("input out of range");
        break;
      case OP_OUTPUT:
        work(I.a);
        if (I.b < 0 || I.b >= static_cast<int32_t>(output_sizes_.size()) || I.res < 0 ||
            I.res >= output_sizes_[I.b])
          bad("output out of range");
        break;
      case OP_CONST:
        work(I.res);
        if (I.a < 0 || I.a >= static_cast<int32_t>(constants_.size())) bad("constant out of range");
        break;
      case OP_GUARD:  // res: the instructions skipped, all of them after it
        work(I.a);
        if (I.res < 1 || static_cast<size_t>(I.res) >= code_.size() - k) bad("guard out of range");
        break;
      default:
        work(I.res);
        work(I.a);
        work(I.b);  // unary operations carry b = a
    }
  }
  // an output with fewer writes than entries has structural zeros, written by the
  // evaluation before the instructions run
  std::vector<int64_t> written(output_sizes_.size(), 0);
  for (const Instruction& I : code_)
    if (I.op == OP_OUTPUT) ++written[I.b];
  for (size_t j = 0; j < output_sizes_.size(); ++j)
    if (written[j] < output_sizes_[j]) sparse_outputs_.push_back(static_cast<int64_t>(j));
  // consecutive elementwise instructions run as pairs in the batched evaluation, never
  // the last one a guard may skip with the next
  std::vector<char> run_end(code_.size(), 0);
  for (size_t k = 0; k < code_.size(); ++k)
    if (code_[k].op == OP_GUARD) run_end[k + static_cast<size_t>(code_[k].res)] = 1;
  pair_.assign(code_.size(), -1);
  for (size_t k = 0; k + 1 < code_.size(); ++k) {
    const int p = pair_index(code_[k].op), q = pair_index(code_[k + 1].op);
    if (p >= 0 && q >= 0 && !run_end[k]) pair_[k++] = static_cast<int16_t>(p * kPairOps + q);
  }
}

#if defined(_OPENMP) || defined(__GNUC__) || defined(__clang__)
#define CMHE_SIMD _Pragma("omp simd")
#else
#define CMHE_SIMD
#endif

// The batched loops also in an AVX2 version where the compiler can choose at load time
// (a function with target clones; each operation rounds the same either way, but sin and
// cos, which vector_math.hpp takes from the vector library where it can)
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CMHE_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define CMHE_CLONES
#endif

namespace {
// the operations that run in pairs, in the order of their pair index
constexpr int32_t kPairOpcodes[] = {OP_ADD, OP_SUB, OP_MUL, OP_DIV, OP_NEG,
                                     OP_TWICE, OP_SQ, OP_IF_ELSE_ZERO, OP_ASSIGN};
}  // namespace

int Tape::pair_index(int32_t op) {
  for (int i = 0; i < kPairOps; ++i)
    if (kPairOpcodes[i] == op) return i;
  return -1;
}

namespace {
inline double sign(double x) { return x < 0 ? -1.0 : (x > 0 ? 1.0 : x); }
// x == 0 ? 0 : y without a branch (y is read either way), so that a loop of it vectorises
inline double if_else_zero(double x, double y) {
  uint64_t bits;
  std::memcpy(&bits, &y, sizeof bits);
  bits &= -static_cast<uint64_t>(x != 0.0);
  std::memcpy(&y, &bits, sizeof bits);
  return y;
}

// operation number P of kPairOpcodes
template <int P>
inline double pair_op(double x, double y) {
  if constexpr (P == 0) return x + y;
  if constexpr (P == 1) return x - y;
  if constexpr (P == 2) return x * y;
  if constexpr (P == 3) return x / y;
  if constexpr (P == 4) return -x;
  if constexpr (P == 5) return 2.0 * x;
  if constexpr (P == 6) return x * x;
  if constexpr (P == 7) return if_else_zero(x, y);
  return x;
}

// two consecutive instructions in one loop over the batch: each node's values are its
// own, so node k's second result may read its first
template <int P, int Q>
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
inline void run_pair(const Instruction& I, const Instruction& J, double* w, int64_t n) {
  double* r1 = w + static_cast<int64_t>(I.res) * n;
  const double* x1 = w + static_cast<int64_t>(I.a) * n;
  const double* y1 = w + static_cast<int64_t>(I.b) * n;
  double* r2 = w + static_cast<int64_t>(J.res) * n;
  const double* x2 = w + static_cast<int64_t>(J.a) * n;
  const double* y2 = w + static_cast<int64_t>(J.b) * n;
  CMHE_SIMD
  for (int64_t k = 0; k < n; ++k) {
    r1[k] = pair_op<P>(x1[k], y1[k]);
    r2[k] = pair_op<Q>(x2[k], y2[k]);
  }
}
}  // namespace

void Tape::evaluate_flat(const double* const* in, double* out) const {
  thread_local std::vector<double*> res;
  res.resize(output_sizes_.size());
  for (size_t k = 0; k < output_sizes_.size(); ++k) {
    res[k] = out;
    out += output_sizes_[k];
  }
  evaluate(in, res.data());
}

// The scalar operations as (name, value of r from x = w[a] and y = w[b]): one list for
// both dispatches of Tape::evaluate
#define CMHE_SCALAR_OPS(X)                                                                \
  X(ASSIGN, x) X(ADD, x + y) X(SUB, x - y) X(MUL, x * y) X(DIV, x / y) X(NEG, -x)          \
  X(EXP, std::exp(x)) X(LOG, std::log(x)) X(POW, std::pow(x, y))                           \
  X(CONSTPOW, std::pow(x, y)) X(SQRT, std::sqrt(x)) X(SQ, x * x) X(TWICE, 2.0 * x)         \
  X(SIN, std::sin(x)) X(COS, std::cos(x)) X(TAN, std::tan(x)) X(ASIN, std::asin(x))        \
  X(ACOS, std::acos(x)) X(ATAN, std::atan(x)) X(LT, x < y) X(LE, x <= y) X(EQ, x == y)     \
  X(NE, x != y) X(NOT, !x) X(AND, x && y) X(OR, x || y) X(FLOOR, std::floor(x))            \
  X(CEIL, std::ceil(x)) X(FMOD, std::fmod(x, y)) X(FABS, std::fabs(x)) X(SIGN, sign(x))    \
  X(COPYSIGN, std::copysign(x, y)) X(IF_ELSE_ZERO, x == 0 ? 0.0 : y) X(ERF, std::erf(x))   \
  X(FMIN, std::fmin(x, y)) X(FMAX, std::fmax(x, y)) X(INV, 1.0 / x)                        \
  X(SINH, std::sinh(x)) X(COSH, std::cosh(x)) X(TANH, std::tanh(x))                        \
  X(ASINH, std::asinh(x)) X(ACOSH, std::acosh(x)) X(ATANH, std::atanh(x))                  \
  X(ATAN2, std::atan2(x, y)) X(HYPOT, std::hypot(x, y)) X(LOG1P, std::log1p(x))            \
  X(EXPM1, std::expm1(x)) X(REMAINDER, std::remainder(x, y))

void Tape::evaluate(const double* const* in, double* const* out) const {
  thread_local std::vector<double> work;
  if (static_cast<int64_t>(work.size()) < work_size_) work.resize(work_size_);
  double* w = work.data();
  const double* c = constants_.data();
  for (int64_t j : sparse_outputs_)
    if (out[j]) std::fill(out[j], out[j] + output_sizes_[j], 0.0);
  const Instruction* I = code_.data();
  const Instruction* const end = I + code_.size();
  if (I == end) return;
// operands are read inside each case: for INPUT, OUTPUT and CONST, a and res are not
// work indices
#define x (w[I->a])
#define y (w[I->b])
#define r (w[I->res])
#if defined(__GNUC__) || defined(__clang__)
  // threaded dispatch (GNU labels as values): each operation jumps to the next one's
  // code itself, so the processor predicts each jump from its own history, where one
  // shared switch mispredicts at almost every instruction
  const void* labels[OP_COUNT];
  for (const void*& l : labels) l = &&done;  // the constructor refused any other code
  labels[OP_INPUT] = &&op_INPUT;
  labels[OP_OUTPUT] = &&op_OUTPUT;
  labels[OP_CONST] = &&op_CONST;
  labels[OP_GUARD] = &&op_GUARD;
#define CMHE_LABEL(NAME, VALUE) labels[OP_##NAME] = &&op_##NAME;
  CMHE_SCALAR_OPS(CMHE_LABEL)
#undef CMHE_LABEL
#define CMHE_NEXT             \
  if (++I == end) goto done;  \
  goto* labels[I->op]
  goto* labels[I->op];
op_INPUT:
  r = in[I->a] ? in[I->a][I->b] : 0.0;
  CMHE_NEXT;
op_OUTPUT:
  if (out[I->b]) out[I->b][I->res] = x;
  CMHE_NEXT;
op_CONST:
  r = c[I->a];
  CMHE_NEXT;
op_GUARD:
  if (x == 0.0) I += I->res;
  CMHE_NEXT;
#define CMHE_CASE(NAME, VALUE) \
  op_##NAME : r = (VALUE);     \
  CMHE_NEXT;
  CMHE_SCALAR_OPS(CMHE_CASE)
#undef CMHE_CASE
#undef CMHE_NEXT
done:
  return;
#else
  for (; I != end; ++I) {
    switch (I->op) {
      case OP_INPUT: r = in[I->a] ? in[I->a][I->b] : 0.0; break;
      case OP_OUTPUT: if (out[I->b]) out[I->b][I->res] = x; break;
      case OP_CONST: r = c[I->a]; break;
      case OP_GUARD: if (x == 0.0) I += I->res; break;
#define CMHE_CASE(NAME, VALUE) case OP_##NAME: r = (VALUE); break;
      CMHE_SCALAR_OPS(CMHE_CASE)
#undef CMHE_CASE
      default: break;
    }
  }
#endif
#undef x
#undef y
#undef r
}

CMHE_CLONES void Tape::evaluate_batch(const double* const* in, const int64_t* in_stride, double* const* out,
                          const int64_t* out_stride, int64_t count) const {
  // work slot i of evaluation k at w[i * n + k]: the row of each slot padded to whole
  // vectors, so that every instruction is one loop over n contiguous values. Rows are
  // disjoint or the same (an instruction may overwrite its operand), never partly
  // overlapping, so the loops carry no dependence (the simd pragmas say so).
  const int64_t n = (count + kLanes - 1) / kLanes * kLanes;
  thread_local std::vector<double> work;
  const size_t need = static_cast<size_t>(work_size_ * n);
  if (work.size() < need) work.resize(need);
  double* w = work.data();
  const double* c = constants_.data();
  for (int64_t j : sparse_outputs_)
    if (out[j])
      for (int64_t k = 0; k < count; ++k)
        std::fill(out[j] + k * out_stride[j], out[j] + k * out_stride[j] + output_sizes_[j], 0.0);
  const size_t size = code_.size();
  for (size_t pc = 0; pc < size; ++pc) {
    const Instruction& I = code_[pc];
    if (pair_[pc] >= 0) {
      const Instruction& J = code_[++pc];
      switch (pair_[pc - 1]) {
#define CMHE_PAIR(P, Q) case P * kPairOps + Q: run_pair<P, Q>(I, J, w, n); break;
#define CMHE_ROW(P) CMHE_PAIR(P, 0) CMHE_PAIR(P, 1) CMHE_PAIR(P, 2) CMHE_PAIR(P, 3) \
  CMHE_PAIR(P, 4) CMHE_PAIR(P, 5) CMHE_PAIR(P, 6) CMHE_PAIR(P, 7) CMHE_PAIR(P, 8)
        CMHE_ROW(0) CMHE_ROW(1) CMHE_ROW(2) CMHE_ROW(3) CMHE_ROW(4) CMHE_ROW(5) CMHE_ROW(6)
        CMHE_ROW(7) CMHE_ROW(8)
#undef CMHE_ROW
#undef CMHE_PAIR
        default: break;
      }
      continue;
    }
    if (I.op == OP_GUARD) {  // res: a count, not a slot
      const double* cond = w + static_cast<int64_t>(I.a) * n;
      bool zero = true;
      for (int64_t k = 0; k < count; ++k) zero = zero && cond[k] == 0.0;
      if (zero) pc += static_cast<size_t>(I.res);
      continue;
    }
    double* r = w + static_cast<int64_t>(I.res) * n;
    const double* x = w + static_cast<int64_t>(I.a) * n;
    const double* y = w + static_cast<int64_t>(I.b) * n;
#define EACH(expr)                   \
  CMHE_SIMD                          \
  for (int64_t k = 0; k < n; ++k) r[k] = (expr); \
  break
    switch (I.op) {
      case OP_INPUT: {
        const double* src = in[I.a];
        const int64_t s = in_stride[I.a];
        if (src) {
          src += I.b;
          for (int64_t k = 0; k < count; ++k) r[k] = src[k * s];
          for (int64_t k = count; k < n; ++k) r[k] = r[count - 1];  // padding: a valid point
        } else {
          for (int64_t k = 0; k < n; ++k) r[k] = 0.0;
        }
        break;
      }
      case OP_OUTPUT: {
        double* dst = out[I.b];
        if (dst) {
          const int64_t s = out_stride[I.b];
          dst += I.res;
          const double* v = w + static_cast<int64_t>(I.a) * n;
          for (int64_t k = 0; k < count; ++k) dst[k * s] = v[k];
        }
        break;
      }
      case OP_CONST: {
        const double v = c[I.a];
        EACH(v);
      }

      case OP_ASSIGN: EACH(x[k]);
      case OP_ADD: EACH(x[k] + y[k]);
      case OP_SUB: EACH(x[k] - y[k]);
      case OP_MUL: EACH(x[k] * y[k]);
      case OP_DIV: EACH(x[k] / y[k]);
      case OP_NEG: EACH(-x[k]);
      case OP_EXP: EACH(std::exp(x[k]));
      case OP_LOG: EACH(std::log(x[k]));
      case OP_POW: case OP_CONSTPOW: EACH(std::pow(x[k], y[k]));
      case OP_SQRT: EACH(std::sqrt(x[k]));
      case OP_SQ: EACH(x[k] * x[k]);
      case OP_TWICE: EACH(2.0 * x[k]);
      case OP_SIN: sin_row(x, r, n); break;
      case OP_COS: cos_row(x, r, n); break;
      case OP_TAN: EACH(std::tan(x[k]));
      case OP_ASIN: EACH(std::asin(x[k]));
      case OP_ACOS: EACH(std::acos(x[k]));
      case OP_ATAN: EACH(std::atan(x[k]));
      case OP_LT: EACH(x[k] < y[k]);
      case OP_LE: EACH(x[k] <= y[k]);
      case OP_EQ: EACH(x[k] == y[k]);
      case OP_NE: EACH(x[k] != y[k]);
      case OP_NOT: EACH(!x[k]);
      case OP_AND: EACH(x[k] && y[k]);
      case OP_OR: EACH(x[k] || y[k]);
      case OP_FLOOR: EACH(std::floor(x[k]));
      case OP_CEIL: EACH(std::ceil(x[k]));
      case OP_FMOD: EACH(std::fmod(x[k], y[k]));
      case OP_FABS: EACH(std::fabs(x[k]));
      case OP_SIGN: EACH(sign(x[k]));
      case OP_COPYSIGN: EACH(std::copysign(x[k], y[k]));
      case OP_IF_ELSE_ZERO: EACH(if_else_zero(x[k], y[k]));
      case OP_ERF: EACH(std::erf(x[k]));
      case OP_FMIN: EACH(std::fmin(x[k], y[k]));
      case OP_FMAX: EACH(std::fmax(x[k], y[k]));
      case OP_INV: EACH(1.0 / x[k]);
      case OP_SINH: EACH(std::sinh(x[k]));
      case OP_COSH: EACH(std::cosh(x[k]));
      case OP_TANH: EACH(std::tanh(x[k]));
      case OP_ASINH: EACH(std::asinh(x[k]));
      case OP_ACOSH: EACH(std::acosh(x[k]));
      case OP_ATANH: EACH(std::atanh(x[k]));
      case OP_ATAN2: EACH(std::atan2(x[k], y[k]));
      case OP_HYPOT: EACH(std::hypot(x[k], y[k]));
      case OP_LOG1P: EACH(std::log1p(x[k]));
      case OP_EXPM1: EACH(std::expm1(x[k]));
      case OP_REMAINDER: EACH(std::remainder(x[k], y[k]));
      default: break;
    }
#undef EACH
  }
}

namespace {

struct ValueKey {
  int32_t op;
  int64_t x, y;
  bool operator==(const ValueKey& o) const { return op == o.op && x == o.x && y == o.y; }
};

struct ValueKeyHash {
  size_t operator()(const ValueKey& k) const {
    uint64_t h = static_cast<uint64_t>(k.op) * 0x9E3779B97F4A7C15ULL;
    h ^= static_cast<uint64_t>(k.x) + 0x632BE59BD9B4E019ULL + (h << 6) + (h >> 2);
    h ^= static_cast<uint64_t>(k.y) + 0x85EBCA77C2B2AE63ULL + (h << 6) + (h >> 2);
    return static_cast<size_t>(h ^ (h >> 31));
  }
};

}  // namespace

std::vector<Instruction> share_tape(const std::vector<Instruction>& code,
                                    const std::vector<double>& constants,
                                    int64_t& work_size) {
  int32_t slots = 0;  // the input tape's work slots
  for (const Instruction& in : code)
    if (in.op != OP_OUTPUT) slots = std::max(slots, in.res + 1);
  std::vector<int32_t> slot_value(static_cast<size_t>(slots), -1);  // value in each slot
  std::unordered_map<ValueKey, int32_t, ValueKeyHash> known;
  known.reserve(code.size());
  std::vector<Instruction> defs;  // per value: (op, res unused, a, b) over values or inputs
  std::vector<Instruction> outputs;  // (value, dense offset, output index)
  std::vector<int32_t> order;  // value v >= 0 defined, or output -(k + 1), in order
  defs.reserve(code.size());
  order.reserve(code.size());
  for (const Instruction& in : code) {
    if (in.op == OP_OUTPUT) {
      order.push_back(-static_cast<int32_t>(outputs.size()) - 1);
      outputs.push_back({slot_value.at(static_cast<size_t>(in.a)), in.res, in.b, 0});
      continue;
    }
    ValueKey key{in.op, in.a, in.b};
    Instruction row{in.op, 0, in.a, in.b};
    if (in.op == OP_CONST) {
      uint64_t bits;
      std::memcpy(&bits, &constants.at(static_cast<size_t>(in.a)), sizeof bits);
      key = {in.op, static_cast<int64_t>(bits), 0};
      row.b = 0;
    } else if (in.op != OP_INPUT) {
      int32_t x = slot_value.at(static_cast<size_t>(in.a));
      int32_t y = slot_value.at(static_cast<size_t>(in.b));
      if ((in.op == OP_ADD || in.op == OP_MUL) && y < x) std::swap(x, y);
      key = {in.op, x, y};
      row.a = x;
      row.b = y;
    }
    auto [it, added] = known.try_emplace(key, static_cast<int32_t>(defs.size()));
    if (added) {
      defs.push_back(row);
      order.push_back(it->second);
    }
    slot_value[static_cast<size_t>(in.res)] = it->second;
  }
  auto operands = [](const Instruction& d) { return d.op != OP_INPUT && d.op != OP_CONST; };
  // the values the outputs need, and each one's last use
  std::vector<char> needed(defs.size(), 0);
  for (const Instruction& o : outputs) needed[static_cast<size_t>(o.op)] = 1;
  for (size_t v = defs.size(); v-- > 0;)
    if (needed[v] && operands(defs[v]))
      needed[static_cast<size_t>(defs[v].a)] = needed[static_cast<size_t>(defs[v].b)] = 1;
  // Each needed value's guard: the condition value c such that every use of it is
  // IF_ELSE_ZERO(c, value) or a value with guard c (-1: none; a value an output reads
  // has none). The uses come later in the order of the values, so one backward sweep
  // meets them all first.
  constexpr int32_t kUnset = -2;
  std::vector<int32_t> guard(defs.size(), kUnset);
  auto meet = [&](int32_t v, int32_t g) {
    int32_t& m = guard[static_cast<size_t>(v)];
    m = m == kUnset ? g : (m == g ? m : -1);
  };
  for (const Instruction& o : outputs) meet(o.op, -1);
  for (size_t v = defs.size(); v-- > 0;) {
    if (!needed[v]) continue;
    int32_t& g = guard[v];
    if (g == kUnset) g = -1;
    const Instruction& d = defs[v];
    if (!operands(d)) continue;
    if (d.op == OP_IF_ELSE_ZERO && d.a != d.b) {
      meet(d.a, g);
      meet(d.b, d.a);
    } else {
      meet(d.a, g);
      if (d.b != d.a) meet(d.b, g);
    }
  }
  // The schedule: the order of the values, but each guarded value held back with the
  // others of its guard until a value outside them reads one; the held values then run
  // together behind a guard on their condition, if that is computed by then (else, or
  // if they are fewer than kMinRun, whose guard would cost as much as it saves, without
  // one). Where a guard's condition is zero its values are read by none of the values
  // that follow: IF_ELSE_ZERO(0, .) is 0 whatever its operand holds.
  constexpr size_t kMinRun = 4;
  struct Step {
    int32_t kind;  // 0: value, 1: output, 2: guard
    int32_t index; // the value, the output, or the guard's condition value
    int32_t count; // a guard's values
  };
  std::vector<Step> steps;
  steps.reserve(order.size() + 16);
  std::vector<std::vector<int32_t>> held(defs.size());
  std::vector<char> is_held(defs.size(), 0), scheduled(defs.size(), 0);
  auto release = [&](int32_t c) {
    std::vector<int32_t>& run = held[static_cast<size_t>(c)];
    if (run.size() >= kMinRun && scheduled[static_cast<size_t>(c)])
      steps.push_back({2, c, static_cast<int32_t>(run.size())});
    for (int32_t v : run) {
      steps.push_back({0, v, 0});
      is_held[static_cast<size_t>(v)] = 0;
      scheduled[static_cast<size_t>(v)] = 1;
    }
    run.clear();
  };
  for (int32_t k : order) {
    if (k < 0) {
      steps.push_back({1, -k - 1, 0});
      continue;
    }
    const auto v = static_cast<size_t>(k);
    if (!needed[v]) continue;
    const Instruction& d = defs[v];
    if (operands(d))
      for (int32_t op : {d.a, d.b})
        if (is_held[static_cast<size_t>(op)] && guard[static_cast<size_t>(op)] != guard[v])
          release(guard[static_cast<size_t>(op)]);
    if (guard[v] >= 0) {
      held[static_cast<size_t>(guard[v])].push_back(k);
      is_held[v] = 1;
    } else {
      steps.push_back({0, k, 0});
      scheduled[v] = 1;
    }
  }
  for (size_t c = 0; c < held.size(); ++c)
    if (!held[c].empty()) release(static_cast<int32_t>(c));
  // each value's last use (a guard reads its condition)
  std::vector<int64_t> last(defs.size(), -1);
  for (size_t step = 0; step < steps.size(); ++step) {
    const Step& st = steps[step];
    const auto now = static_cast<int64_t>(step);
    if (st.kind == 1) {
      last[static_cast<size_t>(outputs[static_cast<size_t>(st.index)].op)] = now;
    } else if (st.kind == 2) {
      last[static_cast<size_t>(st.index)] = now;
    } else if (operands(defs[static_cast<size_t>(st.index)])) {
      const Instruction& d = defs[static_cast<size_t>(st.index)];
      last[static_cast<size_t>(d.a)] = last[static_cast<size_t>(d.b)] = now;
    }
  }
  std::vector<int32_t> slot(defs.size(), -1);
  std::vector<int32_t> free;
  int32_t size = 0;
  std::vector<Instruction> rows;
  rows.reserve(steps.size());
  for (size_t step = 0; step < steps.size(); ++step) {
    const auto now = static_cast<int64_t>(step);
    const Step& st = steps[step];
    if (st.kind == 1) {
      const Instruction& o = outputs[static_cast<size_t>(st.index)];
      const auto value = static_cast<size_t>(o.op);
      rows.push_back({OP_OUTPUT, o.res, slot[value], o.a});
      if (last[value] == now) free.push_back(slot[value]);
      continue;
    }
    if (st.kind == 2) {
      const int32_t cs = slot[static_cast<size_t>(st.index)];
      rows.push_back({OP_GUARD, st.count, cs, cs});
      if (last[static_cast<size_t>(st.index)] == now) free.push_back(cs);
      continue;
    }
    const int32_t k = st.index;
    const Instruction& d = defs[static_cast<size_t>(k)];
    int32_t a = d.a, b = d.b;
    if (operands(d)) {
      a = slot[static_cast<size_t>(d.a)];
      b = slot[static_cast<size_t>(d.b)];
      // an operand used here for the last time frees its slot
      if (last[static_cast<size_t>(d.a)] == now) free.push_back(a);
      if (d.b != d.a && last[static_cast<size_t>(d.b)] == now) free.push_back(b);
    }
    int32_t r;
    if (!free.empty()) {
      r = free.back();
      free.pop_back();
    } else {
      r = size++;
    }
    slot[static_cast<size_t>(k)] = r;
    rows.push_back({d.op, r, a, b});
  }
  work_size = std::max<int64_t>(size, 1);
  return rows;
}

}  // namespace cmhe
