// The QP subproblem of the SQP: a primal active-set method.
//
// min 1/2 d^T H d + g^T d over the window's step d (n, nx), H block-tridiagonal (btd.hpp),
// subject to the box lo <= X + d <= hi and each ball sum_{S_b} x_j^2 <= r_b^2 linearised
// at X. Box-fixed coordinates are removed; every active ball of a node is eliminated by
// a Householder reflection on its own coordinates (the balls are disjoint, so a node's
// reflections commute and their product is one symmetric orthogonal T), so each
// equality-constrained step is one block-tridiagonal Cholesky solve.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "btd.hpp"

namespace cmhe {

// Solver outcomes of the QP and of the window solve (continuum_mhe's OUTCOMES order)
enum Outcome : int {
  CONVERGED = 0,
  MAX_ITER = 1,
  LINE_SEARCH_FAILED = 2,
  QP_FAILED = 3,
  NOT_PD = 4,
};

// The feasible set of one node: a box and balls on disjoint coordinate sets of one size
struct Feasible {
  const double* lo;       // (nx,)
  const double* hi;       // (nx,)
  const int64_t* ball;    // (nb, bk): the coordinates of each ball
  const double* ball_r2;  // (nb,) squared radii
  Index nb, bk;
};

// Buffers of the QP, sized for one window (resized by ``resize``; kept across calls)
struct QPScratch {
  std::vector<int8_t> wbox, wball, fixed, anyb;
  std::vector<double> nrm, gnorm, slack, p, grad, b, L, M, rd, Dt, Et, T, tmp, Tb, v, rows;

  void resize(Index n, Index nx, Index nb) {
    const Index nbm = std::max<Index>(nb, 1), bs = nx * nx, ne = std::max<Index>(n - 1, 0);
    wbox.resize(n * nx);
    wball.resize(n * nbm);
    fixed.resize(n * nx);
    anyb.resize(n);
    nrm.resize(n * nbm * nx);
    gnorm.resize(n * nbm);
    slack.resize(n * nbm);
    for (auto* a : {&p, &grad, &b, &rd}) a->resize(n * nx);
    L.resize(n * bs);
    M.resize(ne * bs);
    Dt.resize(n * bs);
    Et.resize(ne * bs);
    T.resize(n * bs);
    tmp.resize(bs);
    Tb.resize(bs);
    v.resize(nx);
    rows.resize(2 * nx);
  }
};

// Equality-constrained Newton step H p = -grad on the working set (wbox (n, nx) box
// fixes, wball (n, nbm) active balls with unit normals nrm (n, nbm, nx)). Box-fixed
// coordinates get p = 0; each active ball b of a node gets n_b . p = 0, eliminated by a
// Householder reflection on its coordinates; the blocks keep their structure. Uses s's
// fixed, anyb, Dt, Et, T, b, L, M, rd, tmp, Tb, v; false if the reduced H is not PD.
template <int NX>
bool eqp(Index n, Index nx_, const double* D, const double* E, const double* grad,
         const int8_t* wbox, const int8_t* wball, const double* nrm, const Feasible& fs,
         double* p, QPScratch& s) {
  const Index nx = block_size<NX>(nx_);
  const Index bs = nx * nx, nb = fs.nb, nbm = std::max<Index>(nb, 1);
  int8_t* anyb = s.anyb.data();
  int8_t* fixed = s.fixed.data();
  double *Dt = s.Dt.data(), *Et = s.Et.data(), *T = s.T.data(), *b = s.b.data();
  double *tmp = s.tmp.data(), *Tb = s.Tb.data();
  std::fill(anyb, anyb + n, 0);
  std::fill(fixed, fixed + n * nx, 0);
  for (Index i = 0; i < n; ++i) {
    for (Index bb = 0; bb < nb; ++bb) {
      if (wball[i * nbm + bb] != 0) {
        double* Ti = T + i * bs;
        if (!anyb[i]) {
          for (Index j = 0; j < nx; ++j)
            for (Index k = 0; k < nx; ++k) Ti[j * nx + k] = j == k ? 1.0 : 0.0;
          anyb[i] = 1;
        }
        const int64_t* idx = fs.ball + bb * fs.bk;
        const Index piv = householder(nx, nrm + (i * nbm + bb) * nx, idx, fs.bk, Tb, s.v.data());
        fixed[i * nx + piv] = 1;
        for (Index a = 0; a < fs.bk; ++a)
          for (Index c = 0; c < fs.bk; ++c)
            Ti[idx[a] * nx + idx[c]] = Tb[idx[a] * nx + idx[c]];
      }
    }
  }
  for (Index i = 0; i < n; ++i) {
    const double* Di = D + i * bs;
    double* Dti = Dt + i * bs;
    const double* Ti = T + i * bs;
    if (anyb[i]) {
      block_product<NX>(nx, Di, Ti, tmp);
      block_product<NX>(nx, Ti, tmp, Dti);
      for (Index j = 0; j < nx; ++j) {
        double t = 0.0;
        for (Index a = 0; a < nx; ++a) t += Ti[j * nx + a] * grad[i * nx + a];
        b[i * nx + j] = -t;
      }
    } else {
      for (Index j = 0; j < nx; ++j) {
        b[i * nx + j] = -grad[i * nx + j];
        for (Index k = 0; k < nx; ++k) Dti[j * nx + k] = Di[j * nx + k];
      }
    }
    if (i < n - 1) {
      double* Eti = Et + i * bs;
      std::memcpy(Eti, E + i * bs, bs * sizeof(double));
      if (anyb[i]) {
        block_product<NX>(nx, Ti, Eti, tmp);
        std::memcpy(Eti, tmp, bs * sizeof(double));
      }
      if (anyb[i + 1]) {
        block_product<NX>(nx, Eti, T + (i + 1) * bs, tmp);
        std::memcpy(Eti, tmp, bs * sizeof(double));
      }
    }
  }
  for (Index i = 0; i < n; ++i) {
    for (Index c = 0; c < nx; ++c) {
      if (wbox[i * nx + c] != 0 || fixed[i * nx + c]) {
        double* Dti = Dt + i * bs;
        for (Index k = 0; k < nx; ++k) {
          Dti[c * nx + k] = 0.0;
          Dti[k * nx + c] = 0.0;
          if (i < n - 1) Et[i * bs + c * nx + k] = 0.0;
          if (i > 0) Et[(i - 1) * bs + k * nx + c] = 0.0;
        }
        Dti[c * nx + c] = 1.0;
        b[i * nx + c] = 0.0;
      }
    }
  }
  if (!btd_solve<NX>(n, nx, Dt, Et, b, s.L.data(), s.M.data(), s.rd.data(), p)) return false;
  for (Index i = 0; i < n; ++i) {
    if (anyb[i]) {
      const double* Ti = T + i * bs;
      for (Index j = 0; j < nx; ++j) {
        double t = 0.0;
        for (Index a = 0; a < nx; ++a) t += Ti[j * nx + a] * p[i * nx + a];
        tmp[j] = t;
      }
      for (Index j = 0; j < nx; ++j) p[i * nx + j] = tmp[j];
    }
    for (Index c = 0; c < nx; ++c)
      if (wbox[i * nx + c] != 0) p[i * nx + c] = 0.0;
  }
  return true;
}

struct QPResult {
  int status;
  Index iterations, active;
};

// Primal active-set solution d (n, nx) of the SQP subproblem at X (n, nx): min 1/2 d^T H
// d + g^T d s.t. lo <= X + d <= hi and every ball linearised at X. Starts from d = 0
// with the constraints active at X. On success lam (n, nb) holds the ball multipliers.
template <int NX>
QPResult solve_qp(Index n, Index nx_, const double* X, const double* D, const double* E,
                  const double* g, const Feasible& fs, Index max_it, double* d, double* lam,
                  QPScratch& s) {
  const Index nx = block_size<NX>(nx_);
  const Index nb = fs.nb, nbm = std::max<Index>(nb, 1), bk = fs.bk;
  const double* lo = fs.lo;
  const double* hi = fs.hi;
  constexpr double inf = std::numeric_limits<double>::infinity();
  s.resize(n, nx, nb);
  int8_t *wbox = s.wbox.data(), *wball = s.wball.data();
  double *nrm = s.nrm.data(), *gnorm = s.gnorm.data(), *slack = s.slack.data();
  double *p = s.p.data(), *grad = s.grad.data(), *b = s.b.data();
  std::fill(s.wbox.begin(), s.wbox.end(), 0);
  std::fill(s.wball.begin(), s.wball.end(), 0);
  std::fill(s.gnorm.begin(), s.gnorm.end(), 0.0);
  std::fill(s.slack.begin(), s.slack.end(), 0.0);
  for (Index i = 0; i < n; ++i) {
    for (Index j = 0; j < nx; ++j) {
      if (X[i * nx + j] <= lo[j])
        wbox[i * nx + j] = -1;
      else if (X[i * nx + j] >= hi[j])
        wbox[i * nx + j] = 1;
    }
    for (Index bb = 0; bb < nb; ++bb) {
      const int64_t* idx = fs.ball + bb * bk;
      double q = 0.0;
      for (Index a = 0; a < bk; ++a) q += X[i * nx + idx[a]] * X[i * nx + idx[a]];
      double* nr = nrm + (i * nbm + bb) * nx;  // of a ball's normal, its coordinates are read
      for (Index a = 0; a < bk; ++a) nr[idx[a]] = 0.0;
      if (q > 0.0) {
        const double rq = std::sqrt(q);
        for (Index a = 0; a < bk; ++a) nr[idx[a]] = X[i * nx + idx[a]] / rq;
        gnorm[i * nbm + bb] = 2.0 * rq;
        slack[i * nbm + bb] = std::max(fs.ball_r2[bb] - q, 0.0) / gnorm[i * nbm + bb];
        if (q >= fs.ball_r2[bb] * (1.0 - 1e-12)) {
          wball[i * nbm + bb] = 1;
          slack[i * nbm + bb] = 0.0;
        }
      }
    }
  }
  double gscale = 1.0;
  for (Index i = 0; i < n * nx; ++i) gscale = std::max(gscale, std::fabs(g[i]));
  const double mu_tol = 1e-12 * gscale;
  std::fill(d, d + n * nx, 0.0);
  auto count_active = [&]() {
    Index c = 0;
    for (Index i = 0; i < n * nx; ++i) c += wbox[i] != 0;
    for (Index i = 0; i < n * nbm; ++i) c += wball[i] != 0;
    return c;
  };
  for (Index it = 0; it < max_it; ++it) {
    const Index nfix = count_active();
    if (it == 0) {  // d = 0
      std::memcpy(grad, g, n * nx * sizeof(double));
    } else {
      btd_matvec<NX>(n, nx, D, E, d, grad);
      for (Index i = 0; i < n * nx; ++i) grad[i] += g[i];
    }
    if (nfix == 0) {  // nothing fixed: the plain Newton system
      for (Index i = 0; i < n * nx; ++i) b[i] = -grad[i];
      if (!btd_solve_two_ended<NX>(n, nx, D, E, b, s.L.data(), s.M.data(), s.rd.data(),
                                   s.rows.data(), p))
        return {NOT_PD, it, 0};
    } else if (!eqp<NX>(n, nx, D, E, grad, wbox, wball, nrm, fs, p, s)) {
      return {NOT_PD, it, 0};
    }
    double alpha = 1.0;
    int kind = 0;
    Index bi = -1, bj = -1;
    for (Index i = 0; i < n; ++i) {
      for (Index j = 0; j < nx; ++j) {
        if (wbox[i * nx + j] == 0) {
          const double pij = p[i * nx + j];
          if (pij > 0.0 && hi[j] < inf) {
            const double a = std::max((hi[j] - X[i * nx + j] - d[i * nx + j]) / pij, 0.0);
            if (a < alpha) alpha = a, kind = 1, bi = i, bj = j;
          } else if (pij < 0.0 && lo[j] > -inf) {
            const double a = std::max((lo[j] - X[i * nx + j] - d[i * nx + j]) / pij, 0.0);
            if (a < alpha) alpha = a, kind = -1, bi = i, bj = j;
          }
        }
      }
      for (Index bb = 0; bb < nb; ++bb) {
        if (wball[i * nbm + bb] == 0 && gnorm[i * nbm + bb] > 0.0) {
          const int64_t* idx = fs.ball + bb * bk;
          const double* nr = nrm + (i * nbm + bb) * nx;
          double sp = 0.0, sd = 0.0;
          for (Index a = 0; a < bk; ++a) {
            sp += nr[idx[a]] * p[i * nx + idx[a]];
            sd += nr[idx[a]] * d[i * nx + idx[a]];
          }
          if (sp > 0.0) {
            const double a = std::max((slack[i * nbm + bb] - sd) / sp, 0.0);
            if (a < alpha) alpha = a, kind = 2, bi = i, bj = bb;
          }
        }
      }
    }
    for (Index i = 0; i < n * nx; ++i) d[i] += alpha * p[i];
    if (kind != 0) {
      if (kind == 2) {
        wball[bi * nbm + bj] = 1;
      } else {
        wbox[bi * nx + bj] = static_cast<int8_t>(kind);
        d[bi * nx + bj] = (kind == 1 ? hi[bj] : lo[bj]) - X[bi * nx + bj];
      }
      continue;
    }
    // at the minimiser on the working set: check the multipliers' signs
    if (nfix == 0) {
      std::fill(lam, lam + n * nb, 0.0);
      return {CONVERGED, it + 1, 0};
    }
    btd_matvec<NX>(n, nx, D, E, d, grad);
    double worst = -mu_tol;
    Index wi = -1, wj = 0;
    for (Index i = 0; i < n; ++i) {
      for (Index j = 0; j < nx; ++j) {
        const int8_t w = wbox[i * nx + j];
        if (w != 0) {
          const double mu = w == 1 ? -grad[i * nx + j] - g[i * nx + j]
                                   : grad[i * nx + j] + g[i * nx + j];
          if (mu < worst) worst = mu, wi = i, wj = j;
        }
      }
      for (Index bb = 0; bb < nb; ++bb) {
        lam[i * nb + bb] = 0.0;
        if (wball[i * nbm + bb] != 0) {
          const int64_t* idx = fs.ball + bb * bk;
          const double* nr = nrm + (i * nbm + bb) * nx;
          double t = 0.0;
          for (Index a = 0; a < bk; ++a)
            t += (grad[i * nx + idx[a]] + g[i * nx + idx[a]]) * nr[idx[a]];
          lam[i * nb + bb] = -t / gnorm[i * nbm + bb];
          if (lam[i * nb + bb] < worst) worst = lam[i * nb + bb], wi = i, wj = -1 - bb;
        }
      }
    }
    if (wi < 0) return {CONVERGED, it + 1, count_active()};
    if (wj < 0)
      wball[wi * nbm + (-1 - wj)] = 0;
    else
      wbox[wi * nx + wj] = 0;
  }
  return {QP_FAILED, max_it, 0};
}

// Project each node of X (n, nx) onto the box and the balls, in place (the bounds hold
// exactly)
inline void project(Index n, Index nx, double* X, const Feasible& fs) {
  for (Index i = 0; i < n; ++i) {
    double* x = X + i * nx;
    for (Index j = 0; j < nx; ++j) x[j] = std::min(std::max(x[j], fs.lo[j]), fs.hi[j]);
    for (Index bb = 0; bb < fs.nb; ++bb) {
      const int64_t* idx = fs.ball + bb * fs.bk;
      const double r2 = fs.ball_r2[bb];
      double q = 0.0;
      for (Index a = 0; a < fs.bk; ++a) q += x[idx[a]] * x[idx[a]];
      if (q > r2) {
        double c = std::sqrt(r2 / q);
        for (int rep = 0; rep < 4; ++rep) {  // rounding: shrink by ulps until it holds exactly
          q = 0.0;
          for (Index a = 0; a < fs.bk; ++a) q += (c * x[idx[a]]) * (c * x[idx[a]]);
          if (q <= r2) break;
          c = std::nextafter(c, 0.0) * (1.0 - 2e-16);
        }
        for (Index a = 0; a < fs.bk; ++a) x[idx[a]] *= c;
      }
    }
  }
}

}  // namespace cmhe
