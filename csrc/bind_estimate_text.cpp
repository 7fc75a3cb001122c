// Python binding of the estimate CSV's lines (continuum_mhe.io.estimate_csv.estimate_lines).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bind_arrays.hpp"
#include "bindings.hpp"
#include "estimate_text.hpp"

namespace nb = nanobind;
using namespace cmhe;

namespace {

using Flags = nb::ndarray<const uint8_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

}  // namespace

void cmhe::bind_estimate_text(nb::module_& m) {
  m.def(
      "estimate_lines",
      [](const InArray& t, const InArray& output, const InArray& output_std,
         const Flags& estimated, std::optional<Flags> outlier,
         const std::vector<std::string>& status, const InArray& solve_ms) {
        const size_t n = t.size();
        const size_t ny = n > 0 ? output.size() / n : 0;
        check_size(output, n * ny, "output");
        check_size(output_std, n * ny, "output_std");
        check_size(solve_ms, n, "solve_ms");
        if (estimated.size() != n || (outlier && outlier->size() != n))
          throw std::invalid_argument("one flag per sample needed");
        EstimateRows rows{n, ny, t.data(), output.data(), output_std.data(), estimated.data(),
                          outlier ? outlier->data() : nullptr, &status, solve_ms.data()};
        std::string text;
        {
          nb::gil_scoped_release released;
          append_estimate_lines(rows, text);
        }
        return nb::str(text.data(), text.size());
      },
      nb::arg("t"), nb::arg("output"), nb::arg("output_std"), nb::arg("estimated"),
      nb::arg("outlier").none(), nb::arg("status"), nb::arg("solve_ms"),
      "The estimate CSV lines of ``n`` samples: ``t`` (n) s, ``output`` and ``output_std`` "
      "(n, ny), ``estimated`` (n, uint8: 0 leaves the row's outputs and standard deviations "
      "empty), ``outlier`` (n, uint8; None: no such column), ``status`` (n names), "
      "``solve_ms`` (n); numbers as ``%.10g``, a non-finite standard deviation empty. "
      "ValueError for a non-finite time, solve time or estimated output.");
}
