// Python bindings of the fast MHE's per-sample step (horizon.hpp).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/tuple.h>

#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

#include "bind_arrays.hpp"
#include "bindings.hpp"
#include "horizon.hpp"

namespace nb = nanobind;
using namespace cmhe;

namespace {

using In = InArray;
using Array = NewArray;

// a NumPy view of one of the step's buffers, keeping the step alive
Array view(MovingHorizon& h, std::vector<double>& v, std::initializer_list<size_t> shape) {
  return Array(v.data(), shape, nb::find(&h));
}

// ... of a sliding one: a view of its rows now, which the next sample's slide moves
Array view(MovingHorizon& h, SlidingRows& v, std::initializer_list<size_t> shape) {
  return Array(v.data(), shape, nb::find(&h));
}

// (state, covariance or None, outputs, their standard deviations or None): copies
nb::tuple answer(const MovingHorizon& h) {
  const size_t nx = h.nx, ny = h.ny;
  nb::object cov = nb::none(), std = nb::none();
  if (h.cov_ok) {
    cov = nb::cast(copy_of(h.cov.data(), {nx, nx}));
    std = nb::cast(copy_of(h.ystd.data(), {ny}));
  }
  return nb::make_tuple(copy_of(h.state.data(), {nx}), cov, copy_of(h.y.data(), {ny}), std);
}

}  // namespace

void cmhe::bind_horizon(nb::module_& m) {
  nb::enum_<StepOutcome>(m, "StepOutcome", nb::is_arithmetic(),
                         "Outcomes of MovingHorizon.step (csrc/horizon.hpp).")
      .value("NO_ESTIMATE", STEP_NO_ESTIMATE,
             "The window is not full yet and paper_start holds the estimate.")
      .value("DONE", STEP_DONE, "Solved, certified and kept: the answer is returned.")
      .value("SOLVED", STEP_SOLVED, "Solved and certified, not kept: finish follows.")
      .value("UNCERTIFIED", STEP_UNCERTIFIED,
             "The SQP did not certify its answer: the caller solves the window.");
  nb::class_<MovingHorizon>(
      m, "MovingHorizon",
      "The fast MHE's per-sample step over one WindowSolver and NodeModel: the window's "
      "buffers (NumPy views, row-major, aligned at the end), the arrival prior's slide, the "
      "warm start, the SQP, the last node's covariance and the outputs (csrc/horizon.hpp).")
      .def(
          "__init__",
          [](MovingHorizon* self, WindowSolver& solver, NodeModel& node, In R, bool robust,
             bool paper_start, Index max_iter, double step_tol, double err_tol,
             Index max_qp_iter, bool newton, bool quadratic) {
            const SqpOptions opt{max_iter, step_tol, err_tol, max_qp_iter, newton, quadratic};
            new (self) MovingHorizon(solver, node, std::vector<double>(R.data(), R.data() + R.size()),
                                     robust, paper_start, opt);
          },
          nb::arg("solver"), nb::arg("node"), nb::arg("R"), nb::arg("robust"),
          nb::arg("paper_start"), nb::arg("max_iter"), nb::arg("step_tol"), nb::arg("err_tol"),
          nb::arg("max_qp_iter"), nb::arg("newton"), nb::arg("quadratic"),
          nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>())
      .def("restart", &MovingHorizon::restart, "Forget the window, prior and answers.")
      .def(
          "set_prior",
          [](MovingHorizon& h, In xbar, In P, In Pinv) {
            check_size(xbar, h.nx, "xbar");
            check_size(P, h.nx * h.nx, "P");
            check_size(Pinv, h.nx * h.nx, "Pinv");
            h.set_prior(xbar.data(), P.data(), Pinv.data());
          },
          nb::arg("xbar"), nb::arg("P"), nb::arg("Pinv"),
          "Set the arrival prior (xbar, P, P^-1).")
      .def(
          "step",
          [](MovingHorizon& h, double t, In z, In mask, In u, In Q, In Qinv, bool finish) {
            check_size(z, h.nz, "z");
            check_size(mask, h.nz, "mask");
            check_size(u, h.nu, "u");
            check_size(Q, h.nx * h.nx, "Q");
            check_size(Qinv, h.nx * h.nx, "Qinv");
            const int outcome = h.step(t, z.data(), mask.data(), u.data(), Q.data(),
                                       Qinv.data(), finish);
            const auto code = static_cast<StepOutcome>(outcome);
            if (outcome != STEP_DONE) return nb::make_tuple(code, nb::none());
            return nb::make_tuple(code, answer(h));
          },
          nb::arg("t"), nb::arg("z"), nb::arg("mask"), nb::arg("u"), nb::arg("Q"),
          nb::arg("Qinv"), nb::arg("finish"),
          "One sample (push, slide, warm start, solve; keep when certified and finish): "
          "(a StepOutcome, (state, cov, y, std) when the answer was kept (DONE), else "
          "None).")
      .def(
          "finish",
          [](MovingHorizon& h, In X, bool solved, nb::object w_new, bool failed) {
            check_size(X, h.n * h.nx, "X");
            std::vector<double> w;
            if (!w_new.is_none()) {
              In wa = nb::cast<In>(w_new);
              check_size(wa, h.nblk, "w_new");
              w.assign(wa.data(), wa.data() + wa.size());
            }
            h.finish(X.data(), solved, w.empty() ? nullptr : w.data(), failed);
            return answer(h);
          },
          nb::arg("X"), nb::arg("solved"), nb::arg("w_new").none(), nb::arg("failed"),
          "Keep X (N, nx) as the answer (solved: the last step's certified one): (state, "
          "cov, y, std), cov and std None when failed or not positive definite.")
      .def(
          "node_weights",
          [](MovingHorizon& h, Index i, In x) {
            check_size(x, h.nx, "x");
            if (i < 0) i += h.n;
            if (i < 0 || i >= h.n) throw std::invalid_argument("node index out of range");
            std::vector<double> w(h.nblk);
            h.node_weights(i, x.data(), w.data());
            return copy_of(w.data(), {size_t(h.nblk)});
          },
          nb::arg("i"), nb::arg("x"), "Robust weights rho'(s_b) of window node i at state x.")
      .def_prop_ro("k", [](MovingHorizon& h) { return h.k; }, "Samples in the window.")
      .def_prop_ro("iterations", [](MovingHorizon& h) { return h.iterations; },
                   "SQP iterations of the last solve.")
      .def_rw("solve_seconds", &MovingHorizon::solve_seconds,
              "Wall time of the last step's window solve, s (0 when it solved none; the "
              "Python hooks add their solves' to it).")
      .def_prop_ro("step_seconds", [](MovingHorizon& h) { return h.step_seconds; },
                   "Wall time of the last sample's step and finish, s: the prior's slide, "
                   "the warm start, the step's own window solve, the covariance and the "
                   "outputs with their standard deviations (not the solves of Python hooks "
                   "between the two; 0 for a sample that stepped no window).")
      .def_prop_ro("cost", [](MovingHorizon& h) { return h.cost; },
                   "Window cost at the last certified solve's last iterate (NaN if none).")
      .def_prop_ro("solved", [](MovingHorizon& h) { return h.solved; },
                   "Whether the last step solved the window (from X0 and lam0).")
      .def_prop_rw(
          "plausible_limit",
          [](MovingHorizon& h) { return view(h, h.plausible_limit, {h.plausible_limit.size()}); },
          [](MovingHorizon& h, In limit) {
            if (limit.size() != 0) check_size(limit, h.n * h.nz + 1, "plausible_limit");
            h.plausible_limit.assign(limit.data(), limit.data() + limit.size());
          },
          "The branch check's first test in the step ((n nz + 1,) or empty: none): a "
          "certified answer whose twice window cost is at most entry [dof] (the window's "
          "valid measurement components) is kept by the step although finish is false.")
      .def_prop_rw(
          "past_lag", [](MovingHorizon& h) { return h.past_lag; },
          [](MovingHorizon& h, Index lag) { h.set_past_lag(lag); },
          "Answers of full windows the robust loss's second start keeps (0: none); "
          "setting it forgets them.")
      .def_rw("keep_unrejected", &MovingHorizon::keep_unrejected,
              "Whether the step keeps a certified answer itself when the window is not "
              "yet full or no weight of its newest node is below outlier_weight "
              "(remembering it); other answers are the caller's.")
      .def_rw("outlier_weight", &MovingHorizon::outlier_weight,
              "The robust weight below which a block counts as rejected.")
      .def_prop_ro("past_count", [](MovingHorizon& h) { return h.past_count; },
                   "Answers of full windows kept, at most past_lag.")
      .def(
          "remember",
          [](MovingHorizon& h, In X) {
            check_size(X, h.n * h.nx, "X");
            h.remember(X.data());
          },
          nb::arg("X"), "Keep X (N, nx) as the newest past answer (dropping the oldest).")
      .def("forget_past", &MovingHorizon::forget_past, "Forget the past answers.")
      .def(
          "past_oldest",
          [](MovingHorizon& h) {
            if (h.past_count == 0) throw std::invalid_argument("no past answer is kept");
            return copy_of(h.past_oldest(), {size_t(h.n), size_t(h.nx)});
          },
          "A copy of the oldest past answer kept (N, nx).")
      .def_rw("plausible_kept", &MovingHorizon::plausible_kept,
              "Answers kept by plausible_limit since the owner last zeroed it.")
      .def_rw("has_prior", &MovingHorizon::has_prior)
      .def_rw("has_X", &MovingHorizon::has_X)
      .def_rw("outputs_at_last", &MovingHorizon::outputs_at_last)
      .def_rw("has_X_last", &MovingHorizon::has_X_last)
      .def_rw("has_lam", &MovingHorizon::has_lam)
#define CMHE_VIEW(name, ...) \
  .def_prop_ro(#name, [](MovingHorizon& h) { return view(h, h.name, {__VA_ARGS__}); })
      CMHE_VIEW(tw, size_t(h.n))
      CMHE_VIEW(zw, size_t(h.n), size_t(h.nz))
      CMHE_VIEW(zmask, size_t(h.n), size_t(h.nz))
      CMHE_VIEW(dt, size_t(h.n - 1))
      CMHE_VIEW(uw, size_t(h.n - 1), size_t(h.nu))
      CMHE_VIEW(qw, size_t(h.n - 1), size_t(h.nx), size_t(h.nx))
      CMHE_VIEW(qinvw, size_t(h.n - 1), size_t(h.nx), size_t(h.nx))
      CMHE_VIEW(arrival, size_t(h.n), size_t(h.nx), size_t(h.nx))
      CMHE_VIEW(xbar, size_t(h.nx))
      CMHE_VIEW(P, size_t(h.nx), size_t(h.nx))
      CMHE_VIEW(Pinv, size_t(h.nx), size_t(h.nx))
      CMHE_VIEW(X, size_t(h.n), size_t(h.nx))
      CMHE_VIEW(X_last, size_t(h.n), size_t(h.nx))
      CMHE_VIEW(X0, size_t(h.n), size_t(h.nx))
      CMHE_VIEW(X_sol, size_t(h.n), size_t(h.nx))
      CMHE_VIEW(lam, size_t(h.n), size_t(h.nb))
      CMHE_VIEW(lam0, size_t(h.n), size_t(h.nb))
      CMHE_VIEW(w_first, size_t(h.nblk))
      CMHE_VIEW(w_last, size_t(h.nblk))
      CMHE_VIEW(cov_free, size_t(h.nx), size_t(h.nx))
      .def_ro("cov_free_ok", &MovingHorizon::cov_free_ok,
              "Whether the last answer's node sits on a bending bound: cov_free (nx, nx) is "
              "then its covariance not conditioned on that bound.");
#undef CMHE_VIEW
}
