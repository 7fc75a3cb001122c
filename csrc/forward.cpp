#include "forward.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace cmhe {

namespace {
inline double sign(double v) { return v < 0 ? -1.0 : (v > 0 ? 1.0 : v); }

// dr over [lo, hi): p * d on [l, h) (inside it), zero elsewhere. ``kChecked``: a zero
// entry of d gives a zero term even against an infinite or undefined p.
template <bool kChecked>
inline void scaled_tangent(double* dr, int64_t lo, int64_t hi, int64_t l, int64_t h,
                           double p, const double* d) {
  for (int64_t k = lo; k < l; ++k) dr[k] = 0.0;
  for (int64_t k = l; k < h; ++k) dr[k] = kChecked && d[k] == 0.0 ? 0.0 : p * d[k];
  for (int64_t k = h; k < hi; ++k) dr[k] = 0.0;
}

// zero the slot's entries that its previous value may have left nonzero ([rg[6],
// rg[7]), ForwardPlan) outside its new range [rg[0], rg[1])
inline void clear_outside(double* dr, const int32_t* rg) {
  const int32_t lo = rg[0], hi = rg[1], old_lo = rg[6], old_hi = rg[7];
  if (old_lo < lo) std::fill(dr + old_lo, dr + std::min(lo, old_hi), 0.0);
  if (old_hi > hi) std::fill(dr + std::max(hi, old_lo), dr + old_hi, 0.0);
}
}  // namespace

void check_forward(const Tape& tape) {
  for (const Instruction& I : tape.code())
    if (I.op == OP_FMOD || I.op == OP_REMAINDER)
      throw std::invalid_argument("forward derivatives: no derivative of FMOD or REMAINDER");
}

namespace {
// Whether an operation's derivative reads its first (a) or second (b) operand's tangent
// (evaluate_forward's px, py may be nonzero)
bool derivative_uses_a(int32_t op) {
  switch (op) {
    case OP_LT: case OP_LE: case OP_EQ: case OP_NE: case OP_NOT: case OP_AND: case OP_OR:
    case OP_FLOOR: case OP_CEIL: case OP_SIGN: case OP_IF_ELSE_ZERO:
      return false;
    default:
      return true;
  }
}
bool derivative_uses_b(int32_t op) {
  switch (op) {
    case OP_ADD: case OP_SUB: case OP_MUL: case OP_DIV: case OP_POW: case OP_IF_ELSE_ZERO:
    case OP_FMIN: case OP_FMAX: case OP_ATAN2: case OP_HYPOT:
      return true;
    default:
      return false;
  }
}
}  // namespace

ForwardPlan plan_forward(const Tape& tape, int seed) {
  constexpr int kS = ForwardPlan::kStride;
  ForwardPlan plan;
  plan.seed = seed;
  const auto& code = tape.code();
  const int32_t d = static_cast<int32_t>(tape.input_sizes().at(static_cast<size_t>(seed)));
  plan.ranges.assign(code.size() * kS, 0);
  // the instructions a GUARD may skip
  std::vector<char> skippable(code.size(), 0);
  for (size_t i = 0; i < code.size(); ++i)
    if (code[i].op == OP_GUARD)
      for (size_t k = i + 1; k <= i + static_cast<size_t>(code[i].res) && k < code.size(); ++k)
        skippable[k] = 1;
  // each work slot's current range (its latest value's), and whether its content is
  // known to be zero outside that range (written in this evaluation, by an instruction
  // that always runs)
  const size_t nw = static_cast<size_t>(tape.work_size());
  std::vector<int32_t> lo(nw, 0), hi(nw, 0);
  std::vector<char> known(nw, 0);
  for (size_t i = 0; i < code.size(); ++i) {
    const Instruction& I = code[i];
    int32_t* r = plan.ranges.data() + kS * i;
    if (I.op == OP_GUARD) continue;  // res: a count, not a slot
    if (I.op == OP_OUTPUT) {  // res: the output's entry, b: the output; a: the slot read
      r[0] = r[2] = lo[static_cast<size_t>(I.a)];
      r[1] = r[3] = hi[static_cast<size_t>(I.a)];
      continue;
    }
    int32_t l = 0, h = 0;  // empty
    if (I.op == OP_INPUT) {
      if (I.a == seed) l = I.b, h = I.b + 1;
    } else if (I.op != OP_CONST) {
      if (derivative_uses_a(I.op)) {
        r[2] = lo[static_cast<size_t>(I.a)];
        r[3] = hi[static_cast<size_t>(I.a)];
      }
      if (derivative_uses_b(I.op)) {
        r[4] = lo[static_cast<size_t>(I.b)];
        r[5] = hi[static_cast<size_t>(I.b)];
      }
      const bool ea = r[2] >= r[3], eb = r[4] >= r[5];
      if (!ea || !eb) {
        l = ea ? r[4] : (eb ? r[2] : std::min(r[2], r[4]));
        h = ea ? r[5] : (eb ? r[3] : std::max(r[3], r[5]));
      }
    }
    const size_t s = static_cast<size_t>(I.res);
    r[0] = l;
    r[1] = h;
    r[6] = known[s] ? lo[s] : 0;
    r[7] = known[s] ? hi[s] : d;
    lo[s] = l;
    hi[s] = h;
    known[s] = !skippable[i];
  }
  return plan;
}

void evaluate_forward(const Tape& tape, const ForwardPlan& plan, const double* const* in,
                      double* const* out, double* const* dout) {
  const int seed = plan.seed;
  const int64_t d = tape.input_sizes().at(static_cast<size_t>(seed));
  const int64_t nw = tape.work_size();
  thread_local std::vector<double> work, tangents;
  if (static_cast<int64_t>(work.size()) < nw) work.resize(static_cast<size_t>(nw));
  if (static_cast<int64_t>(tangents.size()) < nw * d)
    tangents.resize(static_cast<size_t>(nw * d));
  double* w = work.data();
  double* t = tangents.data();
  const double* c = tape.constants().data();
  const auto& sizes = tape.output_sizes();
  for (size_t j = 0; j < sizes.size(); ++j) {  // structural zeros are never written
    if (out[j]) std::fill(out[j], out[j] + sizes[j], 0.0);
    if (dout[j]) std::fill(dout[j], dout[j] + sizes[j] * d, 0.0);
  }
  // A slot's tangent is written over its value's range and kept zero outside it (the
  // previous value's entries outside the new range are cleared): an operation reads
  // its operands' tangents over the result's range.
  const auto& code = tape.code();
  constexpr int kS = ForwardPlan::kStride;
  for (size_t pc = 0; pc < code.size(); ++pc) {
    const Instruction& I = code[pc];
    const int32_t* rg = plan.ranges.data() + kS * pc;
    if (I.op == OP_GUARD) {  // the values skipped are read only as IF_ELSE_ZERO(0, .)
      if (w[I.a] == 0.0) pc += static_cast<size_t>(I.res);
      continue;
    }
    double* dr = t + static_cast<int64_t>(I.res) * d;
    if (I.op == OP_INPUT) {
      w[I.res] = in[I.a] ? in[I.a][I.b] : 0.0;
      if (I.a == seed) dr[I.b] = 1.0;
      clear_outside(dr, rg);
      continue;
    }
    if (I.op == OP_OUTPUT) {
      if (out[I.b]) out[I.b][I.res] = w[I.a];
      if (dout[I.b]) {
        const double* src = t + static_cast<int64_t>(I.a) * d;
        std::copy(src + rg[0], src + rg[1], dout[I.b] + static_cast<int64_t>(I.res) * d + rg[0]);
      }
      continue;
    }
    if (I.op == OP_CONST) {
      w[I.res] = c[I.a];
      clear_outside(dr, rg);
      continue;
    }
    const double x = w[I.a], y = w[I.b];
    const double* dx = t + static_cast<int64_t>(I.a) * d;
    const double* dy = t + static_cast<int64_t>(I.b) * d;
    // the value r and its partial derivatives px = dr/dx, py = dr/dy (CasADi's)
    double r = 0.0, px = 0.0, py = 0.0;
    switch (I.op) {
      case OP_ASSIGN: r = x; px = 1; break;
      case OP_ADD: r = x + y; px = 1; py = 1; break;
      case OP_SUB: r = x - y; px = 1; py = -1; break;
      case OP_MUL: r = x * y; px = y; py = x; break;
      case OP_DIV: r = x / y; px = 1 / y; py = -r / y; break;
      case OP_NEG: r = -x; px = -1; break;
      case OP_EXP: r = std::exp(x); px = r; break;
      case OP_LOG: r = std::log(x); px = 1 / x; break;
      case OP_POW:
        r = std::pow(x, y);
        px = y * std::pow(x, y - 1);
        py = x > 0 ? std::log(x) * r : 0.0;  // a constant exponent of a negative base
        break;
      case OP_CONSTPOW: r = std::pow(x, y); px = y * std::pow(x, y - 1); break;
      case OP_SQRT: r = std::sqrt(x); px = 1 / (2 * r); break;
      case OP_SQ: r = x * x; px = 2 * x; break;
      case OP_TWICE: r = 2 * x; px = 2; break;
      case OP_SIN: r = std::sin(x); px = std::cos(x); break;
      case OP_COS: r = std::cos(x); px = -std::sin(x); break;
      case OP_TAN: r = std::tan(x); px = 1 + r * r; break;
      case OP_ASIN: r = std::asin(x); px = 1 / std::sqrt(1 - x * x); break;
      case OP_ACOS: r = std::acos(x); px = -1 / std::sqrt(1 - x * x); break;
      case OP_ATAN: r = std::atan(x); px = 1 / (1 + x * x); break;
      case OP_LT: r = x < y; break;
      case OP_LE: r = x <= y; break;
      case OP_EQ: r = x == y; break;
      case OP_NE: r = x != y; break;
      case OP_NOT: r = !x; break;
      case OP_AND: r = x && y; break;
      case OP_OR: r = x || y; break;
      case OP_FLOOR: r = std::floor(x); break;
      case OP_CEIL: r = std::ceil(x); break;
      case OP_FABS: r = std::fabs(x); px = sign(x); break;
      case OP_SIGN: r = sign(x); break;
      case OP_COPYSIGN:
        r = std::copysign(x, y);
        px = sign(x) * std::copysign(1.0, y);
        break;
      case OP_IF_ELSE_ZERO: r = x == 0 ? 0.0 : y; py = x == 0 ? 0.0 : 1.0; break;
      case OP_ERF: r = std::erf(x); px = 2 / std::sqrt(M_PI) * std::exp(-x * x); break;
      case OP_FMIN: {  // a tie splits the derivative in halves, as CasADi's
        const double a = x <= y, b = y <= x;
        r = std::fmin(x, y);
        px = a / (a + b);
        py = b / (a + b);
        break;
      }
      case OP_FMAX: {
        const double a = x >= y, b = y >= x;
        r = std::fmax(x, y);
        px = a / (a + b);
        py = b / (a + b);
        break;
      }
      case OP_INV: r = 1 / x; px = -r * r; break;
      case OP_SINH: r = std::sinh(x); px = std::cosh(x); break;
      case OP_COSH: r = std::cosh(x); px = std::sinh(x); break;
      case OP_TANH: r = std::tanh(x); px = 1 - r * r; break;
      case OP_ASINH: r = std::asinh(x); px = 1 / std::sqrt(1 + x * x); break;
      case OP_ACOSH: r = std::acosh(x); px = 1 / std::sqrt((x - 1) * (x + 1)); break;
      case OP_ATANH: r = std::atanh(x); px = 1 / (1 - x * x); break;
      case OP_ATAN2: {
        const double s = x * x + y * y;
        r = std::atan2(x, y);
        px = y / s;
        py = -x / s;
        break;
      }
      case OP_HYPOT: r = std::hypot(x, y); px = x / r; py = y / r; break;
      case OP_LOG1P: r = std::log1p(x); px = 1 / (1 + x); break;
      case OP_EXPM1: r = std::expm1(x); px = r + 1; break;
      default: break;  // FMOD, REMAINDER: refused by check_forward
    }
    w[I.res] = r;
    // a zero partial or a zero tangent contributes nothing, even against an infinite
    // or undefined factor (a symbolic Jacobian has no term there: a structural zero).
    // Over the result's range [lo, hi): x's tangent counts on [xl, xh), y's on
    // [yl, yh) (both inside it; the result's slot may be an operand's), and is zero
    // elsewhere in that range.
    const int64_t lo = rg[0], hi = rg[1];
    const int64_t xl = px == 0.0 ? 0 : rg[2], xh = px == 0.0 ? 0 : rg[3];
    const int64_t yl = py == 0.0 ? 0 : rg[4], yh = py == 0.0 ? 0 : rg[5];
    const bool has_x = xl < xh, has_y = yl < yh;
    if (std::isfinite(px) && std::isfinite(py)) {
      // finite partials: a zero tangent entry gives a zero term (its sign aside), so
      // the loops run over the whole range without branches
      if (has_x && has_y)
        for (int64_t k = lo; k < hi; ++k) dr[k] = px * dx[k] + py * dy[k];
      else if (has_x)
        for (int64_t k = lo; k < hi; ++k) dr[k] = px * dx[k];
      else if (has_y)
        for (int64_t k = lo; k < hi; ++k) dr[k] = py * dy[k];
      else
        std::fill(dr + lo, dr + hi, 0.0);
    } else if (!has_x && !has_y) {
      std::fill(dr + lo, dr + hi, 0.0);
    } else if (!has_y) {
      scaled_tangent<true>(dr, lo, hi, xl, xh, px, dx);
    } else if (!has_x) {
      scaled_tangent<true>(dr, lo, hi, yl, yh, py, dy);
    } else {
      for (int64_t k = lo; k < hi; ++k) {
        const double vx = (k >= xl && k < xh && dx[k] != 0.0) ? px * dx[k] : 0.0;
        const double vy = (k >= yl && k < yh && dy[k] != 0.0) ? py * dy[k] : 0.0;
        dr[k] = vx + vy;
      }
    }
    clear_outside(dr, rg);
  }
}

ResidualNodeFunction::ResidualNodeFunction(const Tape& transition, const Tape& residual,
                                           bool with_transition)
    : transition_(transition), residual_(residual), with_transition_(with_transition) {
  if (residual.input_sizes().size() != 2 || residual.output_sizes().size() != 1)
    throw std::invalid_argument("the residual must map (x, z) to r");
  nx_ = residual.input_sizes()[0];
  nz_ = residual.input_sizes()[1];
  if (residual.output_sizes()[0] != nz_)
    throw std::invalid_argument("the residual must have one entry per measurement");
  if (transition.input_sizes().size() != 3 || transition.output_sizes().size() != 2 ||
      transition.input_sizes()[0] != nx_ || transition.output_sizes()[0] != nx_ ||
      transition.output_sizes()[1] != nx_ * nx_)
    throw std::invalid_argument("the transition must map (x, u, dt) to (f, F)");
  check_forward(residual);
  plan_ = plan_forward(residual, 0);
}

int64_t ResidualNodeFunction::output_size() const {
  return (with_transition_ ? nx_ + nx_ * nx_ : 0) + nz_ * nx_ + nz_;
}

int ResidualNodeFunction::evaluate(const double* const* in, double* out) const {
  // inputs (x, u, dt, z, m)
  if (with_transition_) {
    double* fout[2] = {out, out + nx_};
    transition_.evaluate(in, fout);
    out += nx_ + nx_ * nx_;
  }
  double* H = out;
  double* r = out + nz_ * nx_;
  const double* args[2] = {in[0], in[3]};
  double* vals[1] = {r};
  double* jac[1] = {H};
  evaluate_forward(residual_, plan_, args, vals, jac);
  const double* m = in[4];
  for (int64_t i = 0; i < nz_; ++i) {
    const double mi = m ? m[i] : 0.0;
    r[i] *= mi;
    for (int64_t j = 0; j < nx_; ++j) H[i * nx_ + j] *= -mi;
  }
  return 0;
}

ForwardJacobianFunction::ForwardJacobianFunction(const Tape& tape) : tape_(tape) {
  if (tape.input_sizes().size() != 1 || tape.output_sizes().size() != 1)
    throw std::invalid_argument("the function must map x to y");
  nx_ = tape.input_sizes()[0];
  ny_ = tape.output_sizes()[0];
  check_forward(tape);
  plan_ = plan_forward(tape, 0);
}

int ForwardJacobianFunction::evaluate(const double* const* in, double* out) const {
  thread_local std::vector<double> value, rows;
  value.resize(static_cast<size_t>(ny_));
  rows.resize(static_cast<size_t>(ny_ * nx_));
  double* vals[1] = {value.data()};
  double* jac[1] = {rows.data()};
  evaluate_forward(tape_, plan_, in, vals, jac);
  for (int64_t i = 0; i < ny_; ++i)
    for (int64_t j = 0; j < nx_; ++j) out[i + j * ny_] = rows[static_cast<size_t>(i * nx_ + j)];
  return 0;
}

}  // namespace cmhe
