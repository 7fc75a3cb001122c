// Python bindings of the model functions (tapes, window, tail).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/vector.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "forward.hpp"
#include "model_function.hpp"
#include "tape.hpp"
#include "vector_math.hpp"

namespace nb = nanobind;
using namespace cmhe;

using CodeArray = nb::ndarray<const int32_t, nb::shape<-1, 4>, nb::c_contig, nb::device::cpu>;
using ConstArray = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using InArray = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using OutArray = nb::ndarray<double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

namespace {

Tape make_tape(CodeArray code, ConstArray constants, std::vector<int64_t> input_sizes,
               std::vector<int64_t> output_sizes, int64_t work_size) {
  std::vector<Instruction> instructions(code.shape(0));
  if (code.shape(0) > 0)
    std::memcpy(instructions.data(), code.data(), code.shape(0) * sizeof(Instruction));
  std::vector<double> c(constants.data(), constants.data() + constants.shape(0));
  return Tape(std::move(instructions), std::move(c), std::move(input_sizes),
              std::move(output_sizes), work_size);
}

// evaluate any model function from Python (tests, one-off calls): inputs flat,
// column-major; the outputs concatenated into ``out``
void evaluate(const ModelFunction& f, std::vector<InArray> inputs, OutArray out) {
  if (static_cast<int64_t>(out.shape(0)) != f.output_size())
    throw std::invalid_argument("out has " + std::to_string(out.shape(0)) +
                                " values; the function writes " +
                                std::to_string(f.output_size()));
  std::vector<const double*> ptrs;
  for (auto& a : inputs) ptrs.push_back(a.shape(0) ? a.data() : nullptr);
  int status;
  {
    nb::gil_scoped_release release;
    status = f.evaluate(ptrs.data(), out.data());
  }
  if (status != 0) throw std::runtime_error("model evaluation failed");
}

}  // namespace

static_assert(sizeof(Instruction) == 4 * sizeof(int32_t), "Instruction is four int32");

void cmhe::bind_model(nb::module_& m) {
  nb::class_<ModelFunction>(m, "ModelFunction",
                            "A model evaluation of the compiled core: flat column-major "
                            "inputs to all outputs concatenated.")
      .def_prop_ro("output_size", &ModelFunction::output_size,
                   "Number of values written (all outputs concatenated).")
      .def("evaluate", &evaluate, nb::arg("inputs"), nb::arg("out"),
           "Evaluate on flat column-major ``inputs``; all outputs into ``out``.");

  m.def(
      "share_tape",
      [](CodeArray code, ConstArray constants) {
        std::vector<Instruction> in(code.shape(0));
        if (code.shape(0) > 0)
          std::memcpy(in.data(), code.data(), code.shape(0) * sizeof(Instruction));
        std::vector<double> c(constants.data(), constants.data() + constants.shape(0));
        int64_t work_size = 1;
        std::vector<Instruction> rows;
        {
          nb::gil_scoped_release release;
          rows = share_tape(in, c, work_size);
        }
        auto* data = new int32_t[rows.size() * 4 + 4];  // never empty
        if (!rows.empty()) std::memcpy(data, rows.data(), rows.size() * sizeof(Instruction));
        nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<int32_t*>(p); });
        nb::ndarray<nb::numpy, int32_t, nb::shape<-1, 4>> out(data, {rows.size(), 4}, owner);
        return std::make_pair(out, work_size);
      },
      nb::arg("code"), nb::arg("constants"),
      "``(code, work_size)``: the tape ``code`` (rows ``(op, res, a, b)``) with every value "
      "computed once and only the values an output needs, its work slots reassigned "
      "(csrc/tape.hpp); the constants are unchanged.");

  nb::class_<TapeFunction, ModelFunction>(m, "TapeFunction",
                                          "One CasADi SX function read as a tape.")
      .def(
          "__init__",
          [](TapeFunction* self, CodeArray code, ConstArray constants,
             std::vector<int64_t> input_sizes, std::vector<int64_t> output_sizes,
             int64_t work_size) {
            new (self) TapeFunction(
                make_tape(code, constants, std::move(input_sizes), std::move(output_sizes),
                          work_size));
          },
          nb::arg("code"), nb::arg("constants"), nb::arg("input_sizes"),
          nb::arg("output_sizes"), nb::arg("work_size"))
      .def_prop_ro("instructions", [](const TapeFunction& f) { return f.tape().instructions(); });

  nb::class_<WindowFunction, ModelFunction>(m, "WindowFunction",
                                            "The MHE window's residuals and Jacobians.")
      .def(
          "__init__",
          [](WindowFunction* self, const TapeFunction& meas, const TapeFunction& proc,
             int64_t horizon) {
            new (self) WindowFunction(MeasurementPiece(meas.tape()), proc.tape(), horizon);
          },
          nb::arg("meas"), nb::arg("proc"), nb::arg("horizon"))
      .def(
          "__init__",
          [](WindowFunction* self, const TapeFunction& residual, int64_t sr_size,
             const TapeFunction& proc, int64_t horizon) {
            new (self)
                WindowFunction(MeasurementPiece(residual.tape(), sr_size), proc.tape(), horizon);
          },
          nb::arg("residual"), nb::arg("sr_size"), nb::arg("proc"), nb::arg("horizon"),
          "From the residual's tape ``(x, z) -> r`` alone: its Jacobian by forward-mode "
          "derivatives, the second-order term zero (``sr_size`` entries per node).");

  nb::class_<TailFunction, ModelFunction>(m, "TailFunction",
                                          "A window's last node and its incoming stage.")
      .def(
          "__init__",
          [](TailFunction* self, const TapeFunction& meas, const TapeFunction& proc) {
            new (self) TailFunction(MeasurementPiece(meas.tape()), proc.tape());
          },
          nb::arg("meas"), nb::arg("proc"))
      .def(
          "__init__",
          [](TailFunction* self, const TapeFunction& residual, int64_t sr_size,
             const TapeFunction& proc) {
            new (self) TailFunction(MeasurementPiece(residual.tape(), sr_size), proc.tape());
          },
          nb::arg("residual"), nb::arg("sr_size"), nb::arg("proc"),
          "From the residual's tape alone, as WindowFunction's.");

  nb::class_<ResidualNodeFunction, ModelFunction>(
      m, "ResidualNodeFunction",
      "``(x, u, dt, z, m) -> (f, F, H, r)`` (or ``(H, r)`` without the transition) from the "
      "transition's tape and the residual's, ``H`` by forward-mode derivatives "
      "(csrc/forward.hpp).")
      .def(
          "__init__",
          [](ResidualNodeFunction* self, const TapeFunction& transition,
             const TapeFunction& residual, bool with_transition) {
            new (self) ResidualNodeFunction(transition.tape(), residual.tape(), with_transition);
          },
          nb::arg("transition"), nb::arg("residual"), nb::arg("with_transition"));

  nb::class_<RememberedFunction, ModelFunction>(
      m, "RememberedFunction",
      "A model function with its last evaluations remembered, per thread (the last two of "
      "any such function on that thread): an evaluation at the same inputs, bit for bit, "
      "copies the outputs kept. ``input_sizes``: the number of values of each input.")
      .def(
          "__init__",
          [](RememberedFunction* self, const ModelFunction& inner,
             std::vector<int64_t> input_sizes) {
            new (self) RememberedFunction(inner, std::move(input_sizes));
          },
          nb::arg("function"), nb::arg("input_sizes"), nb::keep_alive<1, 2>())
      .def_prop_ro("hits", &RememberedFunction::hits,
                   "The evaluations answered from those kept, on every thread.");

  nb::class_<MaskedResidualFunction, ModelFunction>(
      m, "MaskedResidualFunction",
      "``(x, u, dt, z, m) -> m * r(x, z)`` from the residual's tape ``(x, z) -> r``.")
      .def(
          "__init__",
          [](MaskedResidualFunction* self, const TapeFunction& residual) {
            new (self) MaskedResidualFunction(residual.tape());
          },
          nb::arg("residual"));

  nb::class_<ForwardJacobianFunction, ModelFunction>(
      m, "ForwardJacobianFunction",
      "``x -> dy/dx`` (ny, nx), column-major, of a tape ``x -> y``, by forward-mode "
      "derivatives (csrc/forward.hpp).")
      .def(
          "__init__",
          [](ForwardJacobianFunction* self, const TapeFunction& fn) {
            new (self) ForwardJacobianFunction(fn.tape());
          },
          nb::arg("function"));

  m.def("uses_vector_sin_cos", &uses_vector_sin_cos,
        "Whether the batched model evaluations take sin and cos four at a time from glibc's "
        "vector math library (within 4 ulp of the C library's; csrc/vector_math.hpp).");
  m.def(
      "sin_cos_rows",
      [](ConstArray x) {
        const size_t n = x.shape(0);
        std::vector<double> s(n), c(n);
        sin_row(x.data(), s.data(), static_cast<int64_t>(n));
        cos_row(x.data(), c.data(), static_cast<int64_t>(n));
        return std::make_pair(s, c);
      },
      nb::arg("x"),
      "``(sin(x), cos(x))`` as the batched model evaluations compute them (``x`` 1-D).");

  m.attr("OPERATIONS") = nb::make_tuple(
      "INPUT", "OUTPUT", "CONST", "ASSIGN", "ADD", "SUB", "MUL", "DIV", "NEG", "EXP", "LOG",
      "POW", "CONSTPOW", "SQRT", "SQ", "TWICE", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN",
      "LT", "LE", "EQ", "NE", "NOT", "AND", "OR", "FLOOR", "CEIL", "FMOD", "FABS", "SIGN",
      "COPYSIGN", "IF_ELSE_ZERO", "ERF", "FMIN", "FMAX", "INV", "SINH", "COSH", "TANH",
      "ASINH", "ACOSH", "ATANH", "ATAN2", "HYPOT", "LOG1P", "EXPM1", "REMAINDER", "GUARD");
}
