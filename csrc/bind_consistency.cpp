// Python bindings of the consistency check (continuum_mhe.estimators.consistency).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>

#include "bind_arrays.hpp"
#include "bindings.hpp"
#include "consistency.hpp"

namespace nb = nanobind;
using namespace cmhe;

namespace {

using In = InArray;
using Out = NewArray;

}  // namespace

void cmhe::bind_consistency(nb::module_& m) {
  nb::class_<ConsistencyCheck>(
      m, "ConsistencyCheck",
      "The consistency of one estimator's estimates with its readings, every sample "
      "(continuum_mhe.estimators.consistency). Matrices row-major.")
      .def(
          "__init__",
          [](ConsistencyCheck* self, const ModelFunction& transition,
             const ModelFunction& measurement, const ModelFunction& residual, int nx, int nu,
             int nz, std::vector<double> R, std::vector<double> judged, std::vector<double> limit,
             std::vector<double> run_limit, std::vector<double> avg_limit,
             std::vector<double> shift_limit, std::vector<double> bias, std::vector<double> gravity_r, int memory,
             int quiet_memory, double rcond, double model_error_floor,
             std::vector<double> range_info) {
            new (self) ConsistencyCheck(
                transition, measurement, residual,
                ConsistencySettings{nx, nu, nz, std::move(R), std::move(judged),
                                    std::move(limit), std::move(run_limit),
                                    std::move(avg_limit), std::move(shift_limit),
                                    std::move(bias),
                                    std::move(gravity_r), memory, quiet_memory, rcond,
                                    model_error_floor, std::move(range_info)});
          },
          nb::arg("transition"), nb::arg("measurement"), nb::arg("residual"), nb::arg("nx"),
          nb::arg("nu"), nb::arg("nz"), nb::arg("R"), nb::arg("judged"), nb::arg("limit"), nb::arg("run_limit"), nb::arg("avg_limit"),
          nb::arg("shift_limit"), nb::arg("bias"), nb::arg("gravity_r"), nb::arg("memory"), nb::arg("quiet_memory"), nb::arg("rcond"),
          nb::arg("model_error_floor"), nb::arg("range_info") = std::vector<double>{},
          nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>(), nb::keep_alive<1, 4>(),
          "Functions of ``(x, u, dt, z, m)``: ``transition -> (f, F = df/dx)``, "
          "``measurement -> (H = -dr/dx, r)``, ``residual -> r``; ``R`` (nz x nz, "
          "row-major); ``judged`` (nz): 1 for a reading, 0 for a pseudo-measurement; "
          "``limit``, ``run_limit``, ``avg_limit`` (nz + 1): the chi-square limits by the "
          "number of judged readings; ``shift_limit`` (nx + 1): the chi-square limits of "
          "the shift to the readings' shape by its degrees of freedom; ``bias`` (nz): the readings' constant-error "
          "variances; ``gravity_r`` (nz): R's diagonal on the gravity directions, else 0; "
          "``memory``: samples the average remembers; ``quiet_memory``: samples the "
          "average while no model error shows remembers; ``rcond``: the pseudo-inverse's "
          "cut-off; ``model_error_floor``: each gravity-direction reading's model-error "
          "variance (rad^2) assumed until the one learned exceeds it; ``range_info`` (nx, "
          "or empty: none): each state's range as information 1 / std^2 (0: unbounded), "
          "added to ``H^T R^-1 H`` in the constant errors' sensitivity.")
      .def("set_own_acceleration", &ConsistencyCheck::set_own_acceleration,
           nb::arg("velocity"), nb::arg("error"), nb::arg("span"), nb::keep_alive<1, 2>(),
           nb::keep_alive<1, 3>(),
           "The IMUs' own acceleration as a model error of the gravity-direction readings "
           "(continuum_mhe.model.imu_motion): ``velocity(x)`` 3 values per IMU, "
           "``error(x, a)`` nz values; the velocities differenced over ``span`` s.")
      .def(
          "note_motion",
          [](ConsistencyCheck& c, double t, In x) {
            check_size(x, c.settings().nx, "x");
            c.note_motion(t, x.data());
          },
          nb::arg("t"), nb::arg("x"),
          "This sample's estimate: the IMUs' acceleration and its reading errors, which "
          "constant_error_cov then carries.")
      .def("forget_motion", &ConsistencyCheck::forget_motion,
           "The IMUs' motion starts again at the next note_motion.")
      .def("reset", &ConsistencyCheck::reset,
           "Forget the previous estimate, the average and the model error.")
      .def("forget", &ConsistencyCheck::forget,
           "A sample without an estimate: forget the previous estimate.")
      .def(
          "check",
          [](ConsistencyCheck& c, double t, In z, In mask, In x, In P, In u, In Q) {
            const ConsistencySettings& s = c.settings();
            const size_t nx = s.nx, nz = s.nz;
            check_size(z, nz, "z");
            check_size(mask, nz, "mask");
            check_size(x, nx, "x");
            check_size(P, nx * nx, "P");
            if (u.size()) check_size(u, s.nu, "u");
            if (Q.size()) check_size(Q, nx * nx, "Q");
            return c.check(t, z.data(), mask.data(), x.data(), P.data(),
                           u.size() ? u.data() : nullptr, Q.size() ? Q.data() : nullptr);
          },
          nb::arg("t"), nb::arg("z"), nb::arg("mask"), nb::arg("x"), nb::arg("P"),
          nb::arg("u"), nb::arg("Q"),
          "Whether this sample's estimate disagrees with its readings; remembers it. ``u`` "
          "(nu) and ``Q`` (nx x nx): the inputs and process noise from the previous "
          "sample, read only when there is one (else empty).")
      .def(
          "constant_error_cov",
          [](ConsistencyCheck& c, In z, In mask, In x) {
            const size_t nx = c.settings().nx, nz = c.settings().nz;
            check_size(z, nz, "z");
            check_size(mask, nz, "mask");
            check_size(x, nx, "x");
            Out out = new_array({nx, nx});
            c.constant_error_cov(z.data(), mask.data(), x.data(), out.data());
            return out;
          },
          nb::arg("z"), nb::arg("mask"), nb::arg("x"),
          "``A B A^T`` (nx, nx) at ``x``: the covariance from the readings' constant errors "
          "and the model error learned so far.")
      .def_prop_ro("noise_scale", &ConsistencyCheck::noise_scale,
                   "The exponentially weighted mean of NIS / dof (1 before any).")
      .def_prop_ro("quiet_scale", &ConsistencyCheck::quiet_scale,
                   "The slower mean of NIS / dof while no model error showed (1 before "
                   "any): the level a model error that showed must fall back to.")
      .def_prop_rw("model_error", &ConsistencyCheck::model_error,
                   &ConsistencyCheck::set_model_error,
                   "The largest noise_scale - 1 beyond its limit since the reset, in "
                   "units of R (settable: a model error known beforehand).")
      .def_prop_ro("nis", &ConsistencyCheck::nis, "The last sample's NIS (0 if none).")
      .def_prop_ro("fit", &ConsistencyCheck::fit, "The last sample's fit (0 if not judged).")
      .def_prop_ro("fit_nis", &ConsistencyCheck::fit_nis,
                   "The NIS of the innovation the last sample's fit implies, "
                   "(R^-1 r)^T S (R^-1 r) (0 without a previous estimate).")
      .def_prop_ro("shift", &ConsistencyCheck::shift,
                   "The shift that fits the last sample's readings in its covariance, "
                   "d^T P^+ d (computed only where fit_nis is beyond its limit and the shift "
                   "test is on, some shift_limit finite; else 0).")
      .def_prop_ro("dof", &ConsistencyCheck::dof, "The last sample's judged readings.");

  m.def(
      "pinv_symmetric",
      [](In a, double rcond) {
        if (a.ndim() != 2 || a.shape(0) != a.shape(1))
          throw std::invalid_argument("a must be a square matrix");
        const Eigen::Index n = static_cast<Eigen::Index>(a.shape(0));
        const RowMatrix p = pinv_symmetric(Eigen::Map<const RowMatrix>(a.data(), n, n), rcond);
        return copy_of(p.data(), {size_t(n), size_t(n)});
      },
      nb::arg("a"), nb::arg("rcond"),
      "The pseudo-inverse of the symmetric matrix ``a`` from its eigendecomposition, "
      "eigenvalues at most ``rcond`` times the largest in magnitude taken as zero.");
}
