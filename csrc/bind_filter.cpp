// Python bindings of the node model's EKF step, arrival prior and outputs, and of the
// UKF's predict and update.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <chrono>
#include <cstring>
#include <initializer_list>
#include <stdexcept>
#include <string>

#include "bind_arrays.hpp"
#include "bindings.hpp"
#include "filter.hpp"
#include "unscented.hpp"

namespace nb = nanobind;
using namespace cmhe;

namespace {

using In = InArray;
using Out = NewArray;

struct Sample {
  const double* u;
  const double* z;
  const double* mask;
};

Sample sample(const NodeModel& m, const In& u, const In& z, const In& mask, size_t nu) {
  check_size(u, nu, "u");
  check_size(z, m.nz(), "z");
  check_size(mask, m.nz(), "mask");
  return {u.size() ? u.data() : nullptr, z.data(), mask.data()};
}

}  // namespace

void cmhe::bind_filter(nb::module_& m) {
  nb::class_<NodeModel>(m, "NodeModel",
                        "One node of a model: its EKF step, the arrival prior's step, and "
                        "the outputs with their standard deviations. Matrices row-major.")
      .def(
          "__init__",
          [](NodeModel* self, const ModelFunction& transition, const ModelFunction& measurement,
             const ModelFunction& output, const ModelFunction& jacobian, int nx, int nu, int nz,
             int ny, std::vector<int64_t> wrapped, std::vector<int64_t> sigma_states) {
            new (self) NodeModel(transition, measurement, output, jacobian, nx, nu, nz, ny,
                                 std::move(wrapped), std::move(sigma_states));
          },
          nb::arg("transition"), nb::arg("measurement"), nb::arg("output"),
          nb::arg("output_jacobian"),
          nb::arg("nx"), nb::arg("nu"), nb::arg("nz"), nb::arg("ny"), nb::arg("wrapped"),
          nb::arg("sigma_states") = std::vector<int64_t>{},
          nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>(), nb::keep_alive<1, 4>(),
          nb::keep_alive<1, 5>())
      .def(
          "evaluate",
          [](NodeModel& n, In x, In u, double dt, In z, In mask) {
            const int nx = n.nx(), nz = n.nz();
            check_size(x, nx, "x");
            Sample s = sample(n, u, z, mask, u.size());
            n.evaluate(x.data(), s.u, dt, s.z, s.mask);
            const double* o = n.node_out();
            const size_t k = nx + nx * nx;
            return nb::make_tuple(copy_of(o, {size_t(nx)}), copy_of(o + nx, {size_t(nx), size_t(nx)}),
                                  copy_of(o + k, {size_t(nz), size_t(nx)}),
                                  copy_of(o + k + nz * nx, {size_t(nz)}));
          },
          nb::arg("x"), nb::arg("u"), nb::arg("dt"), nb::arg("z"), nb::arg("mask"),
          "``(f, F, H, r)`` at one node: the transition, its Jacobian, ``H = -dr/dx`` and "
          "the masked residual.")
      .def(
          "arrival_step",
          [](NodeModel& n, In x, In P, In u, double dt, In z, In mask, In R, In Q) {
            const size_t nx = n.nx(), nz = n.nz();
            check_size(x, nx, "x");
            check_size(P, nx * nx, "P");
            check_size(R, nz * nz, "R");
            check_size(Q, nx * nx, "Q");
            Sample s = sample(n, u, z, mask, u.size());
            Out xn = copy_of(x.data(), {nx}), Pn = copy_of(P.data(), {nx, nx});
            Out Pinv = new_array({nx, nx});
            if (!n.arrival_step(xn.data(), Pn.data(), Pinv.data(), s.u, dt, s.z, s.mask,
                                R.data(), Q.data()))
              throw std::runtime_error("singular matrix in the arrival prior's step");
            return nb::make_tuple(xn, Pn, Pinv);
          },
          nb::arg("x"), nb::arg("P"), nb::arg("u"), nb::arg("dt"), nb::arg("z"),
          nb::arg("mask"), nb::arg("R"), nb::arg("Q"),
          "The arrival prior's EKF step: ``(x+, P+, P+^-1)``.")
      .def(
          "ekf_step_outputs",
          [](NodeModel& n, In x, In P, In u, double dt, In z, In mask, In R, In Q) {
            const size_t nx = n.nx(), nz = n.nz(), ny = n.ny();
            check_size(x, nx, "x");
            check_size(P, nx * nx, "P");
            check_size(R, nz * nz, "R");
            check_size(Q, nx * nx, "Q");
            Sample s = sample(n, u, z, mask, u.size());
            Out xn = copy_of(x.data(), {nx}), Pn = copy_of(P.data(), {nx, nx});
            Out y = new_array({ny}), sd = new_array({ny});
            const auto start = std::chrono::steady_clock::now();
            if (!n.ekf_step(xn.data(), Pn.data(), s.u, dt, s.z, s.mask, R.data(), Q.data()))
              throw std::runtime_error("singular innovation covariance in the EKF update");
            n.output(xn.data(), y.data());
            n.output_std(xn.data(), Pn.data(), sd.data());
            n.step_seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            return nb::make_tuple(xn, Pn, y, sd);
          },
          nb::arg("x"), nb::arg("P"), nb::arg("u"), nb::arg("dt"), nb::arg("z"),
          nb::arg("mask"), nb::arg("R"), nb::arg("Q"),
          "One EKF step, then the outputs and their standard deviations: "
          "``(x+, P+, y, std)``.")
      .def_prop_ro("log_likelihood", [](NodeModel& n) { return n.log_likelihood; },
                   "The last EKF step's innovation log-density, ``-(r^T S^-1 r + log|S|) / 2`` "
                   "(its constant left out); NaN where the step had no valid reading. With "
                   "``likelihood_given`` rows: the other components' density given those "
                   "(the whole density less theirs), NaN where theirs has no Cholesky factor.")
      .def_prop_rw(
          "likelihood_given", [](NodeModel& n) { return n.likelihood_given; },
          [](NodeModel& n, std::vector<int64_t> rows) {
            for (int64_t i : rows)
              if (i < 0 || i >= n.nz())
                throw std::out_of_range("likelihood_given: a row outside the measurement");
            n.likelihood_given = std::move(rows);
          },
          "The measurement components (0-based rows) on which ``log_likelihood`` is "
          "conditioned; empty (the default): the whole innovation's density.")
      .def_prop_ro("step_seconds", [](NodeModel& n) { return n.step_seconds; },
                   "Wall time of the last ``ekf_step_outputs`` call's arithmetic (the "
                   "step, the outputs and their standard deviations; not its arrays' "
                   "conversion), s.")
      .def(
          "output",
          [](NodeModel& n, In x) {
            check_size(x, n.nx(), "x");
            Out y = new_array({size_t(n.ny())});
            n.output(x.data(), y.data());
            return y;
          },
          nb::arg("x"), "The outputs of state ``x`` (wrapped angles in [-pi, pi)).")
      .def(
          "output_std",
          [](NodeModel& n, In x, In P) {
            check_size(x, n.nx(), "x");
            check_size(P, size_t(n.nx()) * n.nx(), "P");
            Out sd = new_array({size_t(n.ny())});
            n.output_std(x.data(), P.data(), sd.data());
            return sd;
          },
          nb::arg("x"), nb::arg("P"),
          "One standard deviation of each output for state ``x`` with covariance ``P``: the "
          "root mean square of the outputs' change over the sigma points on "
          "``sigma_states`` (given), else ``sqrt(diag(J P J^T))``, J the output Jacobian at x.");

  m.def(
      "ekf_update",
      [](In x, In P, In r, In H, In R) {
        const size_t nx = x.size(), nz = r.size();
        check_size(P, nx * nx, "P");
        check_size(H, nz * nx, "H");
        check_size(R, nz * nz, "R");
        Out xn = copy_of(x.data(), {nx}), Pn = copy_of(P.data(), {nx, nx});
        if (!ekf_update(xn.data(), Pn.data(), r.data(), H.data(), R.data(), int(nx), int(nz)))
          throw std::runtime_error("singular innovation covariance in the EKF update");
        return nb::make_tuple(xn, Pn);
      },
      nb::arg("x"), nb::arg("P"), nb::arg("r"), nb::arg("H"), nb::arg("R"),
      "EKF measurement update, Joseph form: ``(x+, P+)`` with ``H = -dr/dx``.");

  nb::class_<UnscentedFilter>(
      m, "UnscentedFilter",
      "The UKF's predict and update with Van der Merwe's scaled sigma points, on a node "
      "model's transition ``(x, u, dt, z, m) -> (f, F)`` and masked residual "
      "``(x, u, dt, z, m) -> m r(z, x)``. Matrices row-major. Each call returns "
      "``(x, P, failure, message)``: ``failure`` 0, or 1 (no Cholesky factor, a singular "
      "innovation covariance) or 2 (a tilt reading about a half turn from the sigma "
      "points' tilts), with ``x`` and ``P`` then unchanged.")
      .def(
          "__init__",
          [](UnscentedFilter* self, const ModelFunction& transition,
             const ModelFunction& residual, int nx, int nu, int nz, double alpha, double beta,
             double kappa, std::vector<int64_t> chart_rows, std::vector<std::string> names) {
            new (self) UnscentedFilter(transition, residual, nx, nu, nz, alpha, beta, kappa,
                                       std::move(chart_rows), std::move(names));
          },
          nb::arg("transition"), nb::arg("residual"), nb::arg("nx"), nb::arg("nu"),
          nb::arg("nz"), nb::arg("alpha"), nb::arg("beta"), nb::arg("kappa"),
          nb::arg("chart_rows"), nb::arg("names"), nb::keep_alive<1, 2>(),
          nb::keep_alive<1, 3>())
      .def(
          "predict",
          [](UnscentedFilter& f, In x, In P, In u, double dt, In Q) {
            const size_t nx = f.nx();
            check_size(x, nx, "x");
            check_size(P, nx * nx, "P");
            check_size(Q, nx * nx, "Q");
            check_size(u, size_t(f.nu()), "u");
            Out xn = copy_of(x.data(), {nx}), Pn = copy_of(P.data(), {nx, nx});
            f.predict(xn.data(), Pn.data(), f.nu() ? u.data() : nullptr, dt, Q.data());
            return nb::make_tuple(xn, Pn, int(f.failure), f.message);
          },
          nb::arg("x"), nb::arg("P"), nb::arg("u"), nb::arg("dt"), nb::arg("Q"),
          "The prediction with ``(u, dt)`` and process noise ``Q``.")
      .def(
          "update",
          [](UnscentedFilter& f, In x, In P, In z, In mask, In R, bool check_chart) {
            const size_t nx = f.nx(), nz = f.nz();
            check_size(x, nx, "x");
            check_size(P, nx * nx, "P");
            check_size(z, nz, "z");
            check_size(mask, nz, "mask");
            check_size(R, nz * nz, "R");
            Out xn = copy_of(x.data(), {nx}), Pn = copy_of(P.data(), {nx, nx});
            f.update(xn.data(), Pn.data(), z.data(), mask.data(), R.data(), check_chart);
            return nb::make_tuple(xn, Pn, int(f.failure), f.message);
          },
          nb::arg("x"), nb::arg("P"), nb::arg("z"), nb::arg("mask"), nb::arg("R"),
          nb::arg("check_chart"),
          "The update with the valid components of ``z`` (``mask`` > 0), noise ``R``; "
          "``check_chart``: refuse a valid tilt reading whose residuals differ by more than "
          "pi across the sigma points.");
}
