#include "covariance.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cmhe {

namespace {

// Whether ball ``b`` is active at the node ``x`` (within ``tol`` of r^2); ``q`` its
// coordinates' squared norm.
bool on_ball(const double* x, const Feasible& fs, Index b, double tol, double& q) {
  const int64_t* idx = fs.ball + b * fs.bk;
  q = 0.0;
  for (Index a = 0; a < fs.bk; ++a) q += x[idx[a]] * x[idx[a]];
  return q > 0.0 && q >= fs.ball_r2[b] * (1.0 - tol);
}

// Mark the box bounds (wbox -1/+1) and balls (wball, unit normals nrm: of an active ball,
// its coordinates' entries, the ones read) active at X.
void active_constraints(Index n, Index nx, const double* X, const Feasible& fs, double tol,
                        int8_t* wbox, int8_t* wball, double* nrm, bool balls) {
  const Index nbm = std::max<Index>(fs.nb, 1);
  for (Index i = 0; i < n; ++i) {
    const double* x = X + i * nx;
    for (Index j = 0; j < nx; ++j) {
      int8_t w = 0;
      if (x[j] <= fs.lo[j] + tol * (1.0 + std::fabs(fs.lo[j])))
        w = -1;
      else if (x[j] >= fs.hi[j] - tol * (1.0 + std::fabs(fs.hi[j])))
        w = 1;
      wbox[i * nx + j] = w;
    }
    for (Index b = 0; b < fs.nb; ++b) {
      wball[i * nbm + b] = 0;
      const int64_t* idx = fs.ball + b * fs.bk;
      double q = 0.0;
      if (balls && on_ball(x, fs, b, tol, q)) {
        wball[i * nbm + b] = 1;
        const double rq = std::sqrt(q);
        for (Index a = 0; a < fs.bk; ++a) nrm[(i * nbm + b) * nx + idx[a]] = x[idx[a]] / rq;
      }
    }
  }
}

}  // namespace

bool last_node_on_a_ball(Index n, Index nx, const double* X, const Feasible& fs, double tol) {
  double q = 0.0;
  for (Index b = 0; b < fs.nb; ++b)
    if (on_ball(X + (n - 1) * nx, fs, b, tol, q)) return true;
  return false;
}

bool last_block_covariance(Index n, Index nx, const double* X, const double* D,
                           const double* E, const Feasible& fs, double tol, double* out,
                           CovarianceScratch& cs, bool condition_balls) {
  QPScratch& s = cs.qp;
  s.resize(n, nx, fs.nb);
  const Index nbm = std::max<Index>(fs.nb, 1), bs = nx * nx;
  active_constraints(n, nx, X, fs, tol, s.wbox.data(), s.wball.data(), s.nrm.data(),
                     condition_balls);
  const bool none = std::all_of(s.wbox.begin(), s.wbox.end(), [](int8_t w) { return w == 0; }) &&
                    std::all_of(s.wball.begin(), s.wball.end(), [](int8_t w) { return w == 0; });
  std::vector<double>&C = cs.C, &Li = cs.Li, &Tn = cs.Tn, &Tb = cs.Tb, &v = cs.v, &tmp = cs.tmp;
  for (auto* a : {&C, &Li, &Tb, &tmp}) a->resize(bs);
  v.resize(nx);
  Tn.assign(bs, 0.0);
  bool ok;
  if (none) {  // the forward recursion alone, to the last block's inverse
    cs.last.resize(3 * bs + 3 * nx);
    ok = with_block_size(nx, [&](auto c) {
      return btd_last_block_inverse<decltype(c)::value>(n, nx, D, E, C.data(), cs.last.data());
    });
  } else {  // the reduced Hessian, factored as the QP's equality-constrained step does
    std::fill(s.grad.begin(), s.grad.end(), 0.0);
    ok = with_block_size(nx, [&](auto c) {
      return eqp<decltype(c)::value>(n, nx, D, E, s.grad.data(), s.wbox.data(),
                                     s.wball.data(), s.nrm.data(), fs, s.p.data(), s);
    });
    if (ok) dense_inverse_gram(nx, s.L.data() + (n - 1) * bs, C.data(), Li.data());
  }
  if (!ok) return false;
  // fixed coordinates of the last node carry no variance (in the rotated frame)
  std::vector<char>& fixed = cs.fixed;
  fixed.assign(nx, 0);
  for (Index j = 0; j < nx; ++j) Tn[j * nx + j] = 1.0;
  bool any_ball = false;
  for (Index b = 0; b < fs.nb; ++b) {
    if (s.wball[(n - 1) * nbm + b] == 0) continue;
    any_ball = true;
    const int64_t* idx = fs.ball + b * fs.bk;
    const Index piv = householder(nx, s.nrm.data() + ((n - 1) * nbm + b) * nx, idx, fs.bk,
                                  Tb.data(), v.data());
    fixed[piv] = 1;
    for (Index a = 0; a < fs.bk; ++a)
      for (Index c = 0; c < fs.bk; ++c) Tn[idx[a] * nx + idx[c]] = Tb[idx[a] * nx + idx[c]];
  }
  for (Index j = 0; j < nx; ++j)
    if (s.wbox[(n - 1) * nx + j] != 0) fixed[j] = 1;
  for (Index j = 0; j < nx; ++j)
    if (fixed[j])
      for (Index k = 0; k < nx; ++k) {
        C[j * nx + k] = 0.0;
        C[k * nx + j] = 0.0;
      }
  if (any_ball) {  // x = T y with T symmetric and orthogonal
    dense_mul(nx, nx, nx, Tn.data(), C.data(), tmp.data());
    dense_mul(nx, nx, nx, tmp.data(), Tn.data(), C.data());
  }
  for (Index j = 0; j < nx; ++j)
    for (Index k = 0; k < nx; ++k) out[j * nx + k] = 0.5 * (C[j * nx + k] + C[k * nx + j]);
  return true;
}

}  // namespace cmhe
