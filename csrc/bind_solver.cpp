// Python bindings of the MHE window solve (sqp.hpp) and its kernels (btd.hpp, qp.hpp).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

#include <initializer_list>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "bindings.hpp"
#include "btd.hpp"
#include "covariance.hpp"
#include "qp.hpp"
#include "sqp.hpp"

namespace nb = nanobind;
using namespace cmhe;

namespace {

using In = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Out = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using IndexIn = nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu>;
template <class T>
using View = nb::ndarray<nb::numpy, T>;

template <class A>
void check_shape(const A& a, std::initializer_list<Index> shape, const char* name) {
  bool ok = a.ndim() == shape.size();
  size_t k = 0;
  for (Index s : shape) ok = ok && k < a.ndim() && Index(a.shape(k++)) == s;
  if (!ok) {
    std::string want, got;
    for (Index s : shape) want += (want.empty() ? "" : ", ") + std::to_string(s);
    for (size_t j = 0; j < a.ndim(); ++j) got += (j ? ", " : "") + std::to_string(a.shape(j));
    throw std::invalid_argument(std::string(name) + " has shape (" + got + "); expected (" +
                                want + ")");
  }
}

// (n, nx) of the block-tridiagonal system H y = b with H = (D, E), its arrays' shapes
// checked
std::pair<Index, Index> btd_system_size(const In& D, const In& E, const In& b, const Out& y) {
  if (D.ndim() != 3) throw std::invalid_argument("D must be (n, nx, nx)");
  const Index n = D.shape(0), nx = D.shape(1);
  check_shape(D, {n, nx, nx}, "D");
  check_shape(E, {n - 1, nx, nx}, "E");
  check_shape(b, {n, nx}, "b");
  check_shape(y, {n, nx}, "y");
  return {n, nx};
}

template <class T>
std::vector<T> copy_of(const nb::ndarray<const T, nb::c_contig, nb::device::cpu>& a) {
  return std::vector<T>(a.data(), a.data() + a.size());
}

// a NumPy view of one of the solver's buffers, keeping the solver alive
template <class T>
View<T> view(WindowSolver& s, std::vector<T>& v, std::initializer_list<size_t> shape) {
  return View<T>(v.data(), shape, nb::find(&s));
}

// ... of a sliding one: a view of its rows now, which the next shift_stages moves
View<double> view(WindowSolver& s, SlidingRows& v, std::initializer_list<size_t> shape) {
  return View<double>(v.data(), shape, nb::find(&s));
}

Feasible feasible_of(const In& lo, const In& hi, const IndexIn& ball, const In& r2, Index nx) {
  check_shape(lo, {nx}, "lo");
  check_shape(hi, {nx}, "hi");
  if (ball.ndim() != 2 || Index(ball.shape(0)) != Index(r2.size()))
    throw std::invalid_argument("ball_idx must be (nb, k) with nb = len(ball_r2)");
  for (size_t i = 0; i < ball.size(); ++i)
    if (ball.data()[i] < 0 || ball.data()[i] >= nx)
      throw std::invalid_argument("a ball coordinate is out of range");
  return {lo.data(), hi.data(), ball.data(), r2.data(), Index(ball.shape(0)),
          Index(ball.shape(1))};
}

WindowData window_data(const WindowSolver& s, const In& qinv, const In& xbar, const In& arrival) {
  check_shape(qinv, {s.n - 1, s.nx, s.nx}, "qinv");
  check_shape(xbar, {s.nx}, "xbar");
  check_shape(arrival, {s.n, s.nx, s.nx}, "arrival");
  return {qinv.data(), xbar.data(), arrival.data()};
}

SqpResult solve(WindowSolver& s, In qinv, In xbar, In arrival, Out lam, Index max_iter,
                double step_tol, double err_tol, Index max_qp_iter, bool newton, bool quadratic,
                bool evaluated, int shifted) {
  const WindowData data = window_data(s, qinv, xbar, arrival);
  check_shape(lam, {s.n, s.nb}, "lam");
  if (shifted >= 2 || shifted < -1) throw std::invalid_argument("shifted must be -1, 0 or 1");
  const SqpOptions opt{max_iter, step_tol, err_tol, max_qp_iter, newton, quadratic};
  std::vector<double> zmask(s.n);
  s.node_mask(zmask.data());
  SqpResult r;
  {
    nb::gil_scoped_release release;
    r = s.solve(data, zmask.data(), lam.data(), opt, evaluated, shifted);
  }
  return r;
}

}  // namespace

void cmhe::bind_solver(nb::module_& m) {
  nb::class_<SqpResult>(m, "SqpResult", "The outcome of one window solve (WindowSolver.solve).")
      .def_ro("outcome", &SqpResult::outcome,
              "0 converged (certified), else the failure (continuum_mhe's OUTCOMES order).")
      .def_ro("iterations", &SqpResult::iterations, "SQP iterations taken.")
      .def_ro("step", &SqpResult::step, "The last QP step's largest entry, each state's weighted by its step_scale.")
      .def_ro("cost", &SqpResult::cost, "The window cost at the last evaluated iterate.")
      .def_ro("buffer", &SqpResult::buffer, "The buffer (0 or 1) of Xb holding the answer.");
  nb::class_<WindowSolver>(
      m, "WindowSolver",
      "The fast MHE's window solve for one window model: its buffers (NumPy views, "
      "row-major) and the SQP over them (continuum_mhe.estimators.fast.sqp).")
      .def(
          "__init__",
          [](WindowSolver* self, Index horizon, Index nx, Index nz, Index nu,
             const ModelFunction* window, const ModelFunction* tail, In lo, In hi,
             IndexIn ball_idx,
             In ball_r2, In rinv, IndexIn blocks, int loss_code, double loss_scale,
             bool linear_transition, std::optional<IndexIn> block_cols,
             std::optional<IndexIn> block_robust) {
            if (ball_idx.ndim() != 2) throw std::invalid_argument("ball_idx must be 2-D");
            new (self) WindowSolver(horizon, nx, nz, nu, window, tail, copy_of(lo), copy_of(hi),
                                    copy_of(ball_idx), Index(ball_idx.shape(1)),
                                    copy_of(ball_r2), copy_of(rinv), copy_of(blocks), loss_code,
                                    loss_scale, linear_transition,
                                    block_cols ? copy_of(*block_cols) : std::vector<int64_t>{},
                                    block_robust ? copy_of(*block_robust) : std::vector<int64_t>{});
          },
          nb::arg("horizon"), nb::arg("nx"), nb::arg("nz"), nb::arg("nu"),
          nb::arg("window").none(), nb::arg("tail").none(), nb::arg("lo"), nb::arg("hi"), nb::arg("ball_idx"), nb::arg("ball_r2"),
          nb::arg("rinv"), nb::arg("blocks"), nb::arg("loss_code"), nb::arg("loss_scale"),
          nb::arg("linear_transition"), nb::arg("block_cols") = nb::none(),
          nb::arg("block_robust") = nb::none(),
          "``block_cols`` (nblocks,): the number of leading state coordinates each "
          "measurement block's residual depends on at most (its Jacobian rows are zero "
          "beyond them, and its second-order term outside that leading square, which is "
          "all the window's outputs hold of it); nx each where None. ``block_robust`` "
          "(nblocks,): 1 where the loss acts on the block, 0 where the block's cost is "
          "quadratic whatever the loss; 1 each where None. ``window`` and "
          "``tail`` (a WindowFunction and a TailFunction; None: the caller writes the "
          "outputs ``out`` itself) are kept alive with the solver.",
          nb::keep_alive<1, 6>(), nb::keep_alive<1, 7>())
      .def("solve", &solve, nb::arg("qinv"), nb::arg("xbar"), nb::arg("arrival"),
           nb::arg("lam"), nb::arg("max_iter"), nb::arg("step_tol"), nb::arg("err_tol"),
           nb::arg("max_qp_iter"), nb::arg("newton"), nb::arg("quadratic"),
           nb::arg("evaluated") = false, nb::arg("shifted") = -1,
           "The SQP from Xb[0] with the window data in z, m, u, dt: an SqpResult; lam (N, nb) "
           "in and out.")
      .def(
          "evaluate",
          [](WindowSolver& s, int buf, In qinv, In xbar, In arrival) {
            if (buf != 0 && buf != 1) throw std::invalid_argument("buf must be 0 or 1");
            const WindowData data = window_data(s, qinv, xbar, arrival);
            std::vector<double> zmask(s.n);
            s.node_mask(zmask.data());
            return s.evaluate(buf, data, zmask.data());
          },
          nb::arg("buf"), nb::arg("qinv"), nb::arg("xbar"), nb::arg("arrival"),
          "Evaluate the model at Xb[buf] and assemble its blocks (Gauss-Newton Dgn, E, g, "
          "...): the window cost (inf if the model failed).")
      .def(
          "assemble",
          [](WindowSolver& s, int buf, In qinv, In xbar, In arrival, int shifted_from) {
            if (buf != 0 && buf != 1) throw std::invalid_argument("buf must be 0 or 1");
            if (shifted_from < -1 || shifted_from > 1)
              throw std::invalid_argument("shifted_from must be -1, 0 or 1");
            const WindowData data = window_data(s, qinv, xbar, arrival);
            std::vector<double> zmask(s.n);
            s.node_mask(zmask.data());
            return s.assemble(buf, data, zmask.data(), shifted_from);
          },
          nb::arg("buf"), nb::arg("qinv"), nb::arg("xbar"), nb::arg("arrival"),
          nb::arg("shifted_from") = -1,
          "Assemble buffer buf's Gauss-Newton blocks, gradient, robust weights and node "
          "costs from out[buf] at Xb[buf]; with shifted_from >= 0, from that buffer's "
          "assembly shifted by one node (Dgn, E, g, ...) where the shift applies. The cost.")
      .def(
          "shift_outputs",
          [](WindowSolver& s, int src, int dst) {
            if ((src != 0 && src != 1) || (dst != 0 && dst != 1))
              throw std::invalid_argument("src and dst must be 0 or 1");
            return s.shift_outputs(src, dst);
          },
          nb::arg("src"), nb::arg("dst"),
          "out[dst]: out[src] without its first node and stage, then the tail function's "
          "outputs at Xb[0]'s last stage; False if the tail function failed.")
      .def_prop_ro("z", [](WindowSolver& s) { return view(s, s.z, {size_t(s.n), size_t(s.nz)}); })
      .def_prop_ro("m", [](WindowSolver& s) { return view(s, s.m, {size_t(s.n), size_t(s.nz)}); })
      .def_prop_ro("u",
                   [](WindowSolver& s) { return view(s, s.u, {size_t(s.n - 1), size_t(s.nu)}); })
      .def_prop_ro("dt", [](WindowSolver& s) { return view(s, s.dt, {size_t(s.n - 1)}); })
      .def_prop_ro(
          "step_scale", [](WindowSolver& s) { return view(s, s.step_scale, {size_t(s.nx)}); },
          "(nx,) what a unit of each state counts for in the certificate's max-norm (the QP "
          "step and its error bound): ones unless set (a rate's, the time over which its "
          "error moves the angle it is the rate of)")
      .def_prop_ro("Xb",
                   [](WindowSolver& s) { return view(s, s.Xb, {2, size_t(s.n), size_t(s.nx)}); })
      .def_prop_ro("out", [](WindowSolver& s) { return view(s, s.out, {2, size_t(s.window_size)}); })
      .def_prop_ro("D",
                   [](WindowSolver& s) {
                     return view(s, s.D, {2, size_t(s.n), size_t(s.nx), size_t(s.nx)});
                   })
      .def_prop_ro("E",
                   [](WindowSolver& s) {
                     return view(s, s.E, {2, size_t(s.n - 1), size_t(s.nx), size_t(s.nx)});
                   })
      .def_prop_ro("Dgn",
                   [](WindowSolver& s) {
                     return view(s, s.Dgn, {2, size_t(s.n), size_t(s.nx), size_t(s.nx)});
                   })
      .def_prop_ro("g",
                   [](WindowSolver& s) { return view(s, s.g, {2, size_t(s.n), size_t(s.nx)}); })
      .def_prop_ro("d", [](WindowSolver& s) { return view(s, s.d, {size_t(s.n), size_t(s.nx)}); })
      .def_prop_ro("lam_qp",
                   [](WindowSolver& s) { return view(s, s.lam_qp, {size_t(s.n), size_t(s.nb)}); })
      .def_prop_ro("wgt",
                   [](WindowSolver& s) { return view(s, s.wgt, {2, size_t(s.n), size_t(s.nblk)}); })
      .def_prop_ro(
          "extra", [](WindowSolver& s) { return view(s, s.extra, {2, size_t(s.n), size_t(s.nblk)}); })
      .def_prop_ro("gb",
                   [](WindowSolver& s) {
                     return view(s, s.gb, {2, size_t(s.n), size_t(s.nblk), size_t(s.nx)});
                   })
      .def_prop_ro("ncost", [](WindowSolver& s) { return view(s, s.ncost, {2, size_t(s.n)}); })
      .def_prop_ro("stage_done",
                   [](WindowSolver& s) { return view(s, s.stage_done, {s.stage_done.size()}); })
      .def_prop_ro("stage_eq",
                   [](WindowSolver& s) {
                     return view(s, s.stage_eq,
                                 {s.stage_done.size(), size_t(s.nx), size_t(s.nx)});
                   })
      .def_prop_ro("stage_fqf",
                   [](WindowSolver& s) {
                     return view(s, s.stage_fqf,
                                 {s.stage_done.size(), size_t(s.nx), size_t(s.nx)});
                   })
      .def_prop_ro("tail_out",
                   [](WindowSolver& s) { return view(s, s.tail_out, {s.tail_out.size()}); })
      .def_ro("window_size", &WindowSolver::window_size)
      .def_rw("watchdog", &WindowSolver::watchdog,
              "A rejected full step gets one more Gauss-Newton step from its trial point "
              "before it is shortened (for models without the second-order term).");

  m.def(
      "last_block_covariance",
      [](In X, In D, In E, In lo, In hi, IndexIn ball_idx, In ball_r2, double tol, Out out,
         bool condition_balls) {
        if (X.ndim() != 2) throw std::invalid_argument("X must be (n, nx)");
        const Index n = X.shape(0), nx = X.shape(1);
        check_shape(D, {n, nx, nx}, "D");
        check_shape(E, {n - 1, nx, nx}, "E");
        check_shape(out, {nx, nx}, "out");
        const Feasible fs = feasible_of(lo, hi, ball_idx, ball_r2, nx);
        CovarianceScratch scratch;
        return last_block_covariance(n, nx, X.data(), D.data(), E.data(), fs, tol, out.data(),
                                     scratch, condition_balls);
      },
      nb::arg("X"), nb::arg("D"), nb::arg("E"), nb::arg("lo"), nb::arg("hi"),
      nb::arg("ball_idx"), nb::arg("ball_r2"), nb::arg("tol"), nb::arg("out"),
      nb::arg("condition_balls") = true,
      "Into out (nx, nx): the last diagonal block of H^-1 for H = (D, E), conditioned on "
      "the bounds active at X (n, nx) within tol (the balls only where condition_balls); "
      "False if the reduced Hessian is not positive definite.");
  m.def(
      "btd_solve",
      [](In D, In E, In b, Out y) {
        const auto [n, nx] = btd_system_size(D, E, b, y);
        std::vector<double> L(n * nx * nx), M((n - 1) * nx * nx), rd(n * nx);
        return with_block_size(nx, [&](auto k) {
          return btd_solve<decltype(k)::value>(n, nx, D.data(), E.data(), b.data(), L.data(),
                                               M.data(), rd.data(), y.data());
        });
      },
      nb::arg("D"), nb::arg("E"), nb::arg("b"), nb::arg("y"),
      "Solve H y = b for the symmetric block-tridiagonal H = (D, E) (diagonal blocks D "
      "(n, nx, nx), super-diagonal E (n-1, nx, nx)) by block Cholesky; False if H is not "
      "positive definite.");
  m.def(
      "btd_solve_two_ended",
      [](In D, In E, In b, Out y, bool generic) {
        const auto [n, nx] = btd_system_size(D, E, b, y);
        std::vector<double> V(n * nx * nx), G((n - 1) * nx * nx), p(n * nx), rows(2 * nx);
        auto solve = [&](auto k) {
          return btd_solve_two_ended<decltype(k)::value>(n, nx, D.data(), E.data(), b.data(),
                                                         V.data(), G.data(), p.data(),
                                                         rows.data(), y.data());
        };
        return generic ? solve(std::integral_constant<int, 0>{}) : with_block_size(nx, solve);
      },
      nb::arg("D"), nb::arg("E"), nb::arg("b"), nb::arg("y"), nb::arg("generic") = false,
      "As btd_solve, eliminating from both ends towards the middle node (the QP's Newton "
      "system without active constraints); False if H is not positive definite. "
      "``generic``: the kernel for a block size read at run time, not the one specialised "
      "for nx (the same operations in the same order: the same bits).");
  m.def(
      "householder",
      [](In nrm, IndexIn idx, Out T) {
        const Index nx = nrm.size();
        check_shape(T, {nx, nx}, "T");
        if (idx.size() == 0) throw std::invalid_argument("idx is empty");
        for (size_t a = 0; a < idx.size(); ++a)
          if (idx.data()[a] < 0 || idx.data()[a] >= nx)
            throw std::invalid_argument("idx out of range");
        std::vector<double> v(nx);
        return householder(nx, nrm.data(), idx.data(), idx.size(), T.data(), v.data());
      },
      nb::arg("nrm"), nb::arg("idx"), nb::arg("T"),
      "Symmetric orthogonal T with T nrm = -+e_c for a unit normal on the coordinates idx; "
      "returns the pivot c.");
  m.def(
      "solve_qp",
      [](In X, In D, In E, In g, In lo, In hi, IndexIn ball_idx, In ball_r2, Index max_it,
         Out d, Out lam) {
        if (X.ndim() != 2) throw std::invalid_argument("X must be (n, nx)");
        const Index n = X.shape(0), nx = X.shape(1);
        check_shape(D, {n, nx, nx}, "D");
        check_shape(E, {n - 1, nx, nx}, "E");
        check_shape(g, {n, nx}, "g");
        check_shape(d, {n, nx}, "d");
        const Feasible fs = feasible_of(lo, hi, ball_idx, ball_r2, nx);
        check_shape(lam, {n, fs.nb}, "lam");
        QPScratch s;
        QPResult r = with_block_size(nx, [&](auto k) {
          return solve_qp<decltype(k)::value>(n, nx, X.data(), D.data(), E.data(), g.data(), fs,
                                              max_it, d.data(), lam.data(), s);
        });
        return std::make_tuple(r.status, r.iterations, r.active);
      },
      nb::arg("X"), nb::arg("D"), nb::arg("E"), nb::arg("g"), nb::arg("lo"), nb::arg("hi"),
      nb::arg("ball_idx"), nb::arg("ball_r2"), nb::arg("max_it"), nb::arg("d"), nb::arg("lam"),
      "Active-set solution d of min 1/2 d^T H d + g^T d s.t. lo <= X + d <= hi and the "
      "balls linearised at X: (status, iterations, active constraints); lam (n, nb) the "
      "ball multipliers.");
  m.def(
      "project",
      [](Out X, In lo, In hi, IndexIn ball_idx, In ball_r2) {
        if (X.ndim() != 2) throw std::invalid_argument("X must be (n, nx)");
        const Index n = X.shape(0), nx = X.shape(1);
        project(n, nx, X.data(), feasible_of(lo, hi, ball_idx, ball_r2, nx));
      },
      nb::arg("X"), nb::arg("lo"), nb::arg("hi"), nb::arg("ball_idx"), nb::arg("ball_r2"),
      "Project each row of X onto the box and the balls, in place (the bounds hold exactly).");
  m.def(
      "rho_derivatives",
      [](int code, double scale, double s) {
        double r, r1, r2;
        rho_derivatives(code, scale, s, r, r1, r2);
        return std::make_tuple(r, r1, r2);
      },
      nb::arg("code"), nb::arg("scale"), nb::arg("s"),
      "(rho(s), rho'(s), rho''(s)) of the robust loss ``code`` (loss.LOSS_CODES).");
  m.def(
      "dense_mul",
      [](In A, In B, Out out) {
        if (A.ndim() != 2 || B.ndim() != 2 || B.shape(0) != A.shape(1))
          throw std::invalid_argument("A (m, k) and B (k, p) expected");
        check_shape(out, {Index(A.shape(0)), Index(B.shape(1))}, "out");
        dense_mul(A.shape(0), A.shape(1), B.shape(1), A.data(), B.data(), out.data());
      },
      nb::arg("A"), nb::arg("B"), nb::arg("out"), "out = A B, written out.");
  m.def(
      "dense_cholesky",
      [](In A, Out L) {
        const Index n = A.ndim() == 2 ? A.shape(0) : -1;
        check_shape(A, {n, n}, "A");
        check_shape(L, {n, n}, "L");
        return dense_cholesky(n, A.data(), L.data());
      },
      nb::arg("A"), nb::arg("L"),
      "Lower Cholesky factor L of a symmetric A; False if A is not positive definite.");
  m.def(
      "dense_inverse_gram",
      [](In L, Out out) {
        const Index n = L.ndim() == 2 ? L.shape(0) : -1;
        check_shape(L, {n, n}, "L");
        check_shape(out, {n, n}, "out");
        std::vector<double> Li(n * n);
        dense_inverse_gram(n, L.data(), out.data(), Li.data());
      },
      nb::arg("L"), nb::arg("out"), "out = (L L^T)^-1 for a lower-triangular L.");
}
