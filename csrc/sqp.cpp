// The MHE window solve (sqp.hpp): assembly, curvature, line search, certificates.
#include "sqp.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "model_function.hpp"

namespace cmhe {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Safety factor on the quadratic-rate error estimate of the SQP: on the 494 windows of
// the benchmark's recording (paper3d, N = 30) that needed a third iteration under the
// contraction bound alone, the true next step was at most 4.8 times the estimate
// |d_1|^3 / |d_0|^2 (median 0.7)
constexpr double kQuadraticSafety = 10.0;

// Safety factor after a Gauss-Newton step, on the contraction bound |d_1|^2 / (|d_0| -
// |d_1|) and on step_tol (which it divides): its rate is linear and drifts from one
// iteration to the next; on a three-section model with the IMUs' own acceleration the
// bound and a step under step_tol alone let answers 8.7 times err_tol from the
// converged one through (17 of 161 windows); with the factor, the worst at 1.33 times
// err_tol (a rate that jumps between iterations: no factor bounds that)
constexpr double kContractionSafety = 10.0;

// dst[start:stop] = src[start + 1:stop + 1] along the first axis (rows of ``row``
// values; src may be dst)
void shift_rows(double* dst, const double* src, Index start, Index stop, Index row) {
  if (stop <= start) return;
  std::memmove(dst + start * row, src + (start + 1) * row, (stop - start) * row * sizeof(double));
}

// One process stage's constant products: eq = -(Q^-1 F)^T (the Hessian's off-diagonal
// block) and the upper triangle of fqf = F^T Q^-1 F; qf scratch
template <int NX>
void stage_product(Index nx_, const double* qinv, const double* F, double* eq, double* fqf,
                   double* qf) {
  const Index nx = block_size<NX>(nx_);
  block_product<NX>(nx, qinv, F, qf);
  for (Index j = 0; j < nx; ++j) {
    for (Index k = 0; k < nx; ++k) eq[j * nx + k] = -qf[k * nx + j];
    double* fj = fqf + j * nx;
    for (Index k = j; k < nx; ++k) fj[k] = 0.0;
    for (Index a = 0; a < nx; ++a) {
      const double f = F[a * nx + j];
      const double* qa = qf + a * nx;
      for (Index k = j; k < nx; ++k) fj[k] += f * qa[k];
    }
  }
}

// The leading state coordinates that measurement block b's products run over: its
// block_cols, or all NX for the smallest constant sizes (there the loops of a constant
// count, unrolled, cost less than the fewer columns of a variable one)
template <int NX>
Index block_width(const WindowSolver& w, Index b) {
  if constexpr (NX > 0 && NX <= 4) return NX;
  return w.block_cols[b];
}

// Views of one buffer's model outputs: measurement residuals R (n, nz) and their
// Jacobians JR (n, nz, nx), process residuals W (n-1, nx) and their Jacobians FJ (n-1,
// nx, nx), the residuals' second-order term S (n, sr_size: each block's leading square)
struct Outputs {
  const double *R, *JR, *W, *FJ, *S;
};

Outputs split_outputs(const WindowSolver& w, const double* out) {
  const Index n = w.n, nx = w.nx, nz = w.nz;
  const Index o1 = nz * n, o2 = o1 + nz * nx * n, o3 = o2 + nx * (n - 1);
  const Index o4 = o3 + nx * nx * (n - 1);
  return {out, out + o1, out + o2, out + o3, out + o4};
}

// Gauss-Newton Hessian blocks Dgn[buf] (diagonal), E[buf], exact gradient g[buf] and the
// cost at X (n, nx) from the model outputs ``out`` (the QP's diagonal blocks D[buf] add
// the balls' curvature and the exact Newton term to Dgn[buf]: form_hessian).
//
// The process stages' constant products are taken from the solver's stage buffers when
// present (an affine transition; those not done yet are formed first), else formed
// here. An arrival block whose diagonal is zero is skipped: the arrival weights are
// positive semidefinite, so the whole block is zero. ncost[buf] (n,) receives each
// node's cost (its measurement, arrival and outgoing stage terms, in that order); the
// cost is their sum in node order.
//
// ``prev >= 0``: X is buffer prev's iterate of the previous window shifted by one node,
// and that buffer's assembly (its Gauss-Newton Dgn, E, g, wgt, extra, gb, ncost; it may
// be buf) shifts with it: its nodes 2 to N-1 become nodes 1 to N-2, and only node 0 (the
// new arrival term), the new last stage and the new last node are formed. The same bits
// as the whole assembly where the previous window's arrival weighted only its node 0 and
// this one's weights only node 0 (else, or below 3 nodes, the whole assembly runs): node
// N-2's incoming stage and measurement are the previous window's node N-1, whose block,
// gradient and cost had nothing else.
//
// Measurement block b of node i (R block-diagonal) costs 1/2 rho(s), s = r_b^T R_b^-1
// r_b: gradient rho' J_b^T R_b^-1 r_b and Hessian J_b^T (rho' R_b^-1 + a R_b^-1 r_b r_b^T
// R_b^-1) J_b with a the exact 2 rho'' clipped at -rho'/s so that the block stays
// positive semidefinite (a Triggs-type correction; Cauchy beyond its scale). Kept for
// the exact Newton term (form_hessian): wgt = m rho', extra = m (2 rho'' - a) and gb =
// J_b^T R_b^-1 r_b.
template <int NX>
double assemble(WindowSolver& w, int buf, const double* X, const double* out,
                const double* zmask, const WindowData& data, int prev) {
  const Index n = w.n, nx = block_size<NX>(w.nx), nz = w.nz, nblk = w.nblk;
  const Index bs = nx * nx;
  const Outputs o = split_outputs(w, out);
  const double* qinv = data.qinv;
  const double* arrival = data.arrival;
  const double* rinv = w.rinv.data();
  const bool pre = !w.stage_done.empty();
  if (pre) {
    for (Index i = 0; i < n - 1; ++i)
      if (w.stage_done[i] == 0) {
        stage_product<NX>(nx, qinv + i * bs, o.FJ + i * bs, w.stage_eq.data() + i * bs,
                          w.stage_fqf.data() + i * bs, w.qf.data());
        w.stage_done[i] = 1;
      }
  }
  double* D = w.Dgn.data() + buf * n * bs;  // the Gauss-Newton diagonal blocks
  double* E = w.E.data() + buf * (n - 1) * bs;
  double* g = w.g.data() + buf * n * nx;
  double* wgt = w.wgt.data() + buf * n * nblk;
  double* extra = w.extra.data() + buf * n * nblk;
  double* gb = w.gb.data() + buf * n * nblk * nx;
  double* ncost = w.ncost.data() + buf * n;
  bool shifted = prev >= 0;
  if (shifted) {
    for (Index i = 1; i < n; ++i)
      for (Index j = 0; j < nx; ++j) shifted = shifted && arrival[i * bs + j * nx + j] == 0.0;
    shifted = shifted && n >= 3;
  }
  if (shifted) {
    shift_rows(D, w.Dgn.data() + prev * n * bs, 1, n - 1, bs);
    shift_rows(g, w.g.data() + prev * n * nx, 1, n - 1, nx);
    shift_rows(ncost, w.ncost.data() + prev * n, 1, n - 1, 1);
    shift_rows(E, w.E.data() + prev * (n - 1) * bs, 1, n - 2, bs);
    shift_rows(wgt, w.wgt.data() + prev * n * nblk, 0, n - 1, nblk);
    shift_rows(extra, w.extra.data() + prev * n * nblk, 0, n - 1, nblk);
    shift_rows(gb, w.gb.data() + prev * n * nblk * nx, 0, n - 1, nblk * nx);
  }
  const int64_t* blocks = w.blocks.data();
  double *wr = w.wr.data(), *wj = w.wj.data(), *qw = w.qw.data(), *qf = w.qf.data();
  double* e = w.e.data();
  double acc_row[NX > 0 ? NX : 1];  // a row of nx sums, in registers for a constant size
  double* acc = NX > 0 ? acc_row : w.acc.data();
  const Index nodes = shifted ? 3 : n;
  for (Index node = 0; node < nodes; ++node) {
    Index i = node;
    bool measured = true;  // node i's measurement and arrival terms are formed
    bool push = true;      // stage i's terms of node i + 1 are added
    if (shifted) {
      i = node == 0 ? 0 : (node == 1 ? n - 2 : n - 1);
      measured = i != n - 2;  // node N-2 is the previous window's node N-1
      push = i != 0;          // node 1 came with them
    }
    double* Di = D + i * bs;
    double* gi = g + i * nx;
    if (i == 0) {  // node 0's sums start from zero, every other node's from its stage in
      std::fill(Di, Di + bs, 0.0);
      std::fill(gi, gi + nx, 0.0);
    }
    double mk = zmask[i];
    double cost = 0.0;
    if (!measured) {
      cost = ncost[i];
      mk = 0.0;
    } else {
      for (Index bk_ = 0; bk_ < nblk; ++bk_) {
        wgt[i * nblk + bk_] = 0.0;
        extra[i * nblk + bk_] = 0.0;
        std::fill(gb + (i * nblk + bk_) * nx, gb + (i * nblk + bk_ + 1) * nx, 0.0);
      }
    }
    if (mk != 0.0) {
      const double* Ri = o.R + i * nz;
      const double* JRi = o.JR + i * nz * nx;
      for (Index bk_ = 0; bk_ < nblk; ++bk_) {
        const Index b0 = blocks[2 * bk_], nb_ = blocks[2 * bk_ + 1];
        const Index cb = block_width<NX>(w, bk_);  // J_b is zero beyond its first cb columns
        // the products below run along rows of cb contiguous values (loops the compiler
        // vectorises); each entry's sum is formed in the order of its index a or c
        double ssq = 0.0;
        for (Index a = 0; a < nb_; ++a) {
          const double* ra = rinv + (b0 + a) * nz + b0;
          double t = 0.0;
          for (Index c = 0; c < nb_; ++c) t += ra[c] * Ri[b0 + c];
          wr[a] = t;
          ssq += Ri[b0 + a] * t;
          double* wja = wj + a * nx;  // (R_b^-1 J_b)[a, :]
          for (Index k = 0; k < cb; ++k) wja[k] = 0.0;
          for (Index c = 0; c < nb_; ++c) {
            const double rc = ra[c];
            const double* jc = JRi + (b0 + c) * nx;
            for (Index k = 0; k < cb; ++k) wja[k] += rc * jc[k];
          }
        }
        double rho, rho1, rho2;
        rho_derivatives(w.block_loss[bk_], w.loss_scale, ssq, rho, rho1, rho2);
        cost += 0.5 * mk * rho;
        double a2 = 2.0 * rho2;
        if (ssq > 0.0 && a2 < -rho1 / ssq) a2 = -rho1 / ssq;
        wgt[i * nblk + bk_] = mk * rho1;
        extra[i * nblk + bk_] = mk * (2.0 * rho2 - a2);
        double* gbi = gb + (i * nblk + bk_) * nx;
        for (Index j = 0; j < nx; ++j) gbi[j] = 0.0;
        for (Index a = 0; a < nb_; ++a) {
          const double ra = wr[a];
          const double* ja = JRi + (b0 + a) * nx;
          for (Index j = 0; j < cb; ++j) gbi[j] += ja[j] * ra;
        }
        for (Index j = 0; j < cb; ++j) gi[j] += mk * rho1 * gbi[j];
        // J_b^T (rho' R_b^-1 + a2 ...) J_b by whole rows of its leading cb x cb block (the
        // entries below the diagonal are formed along and replaced by the mirror of the
        // upper triangle below); where rho' = 1 and a2 = 0 (the quadratic loss, a robust
        // one within its scale) the terms that multiply by 1 and add 0 are left out
        const bool plain = rho1 == 1.0 && a2 == 0.0;
        for (Index j = 0; j < cb; ++j) {
          for (Index k = 0; k < cb; ++k) acc[k] = 0.0;
          for (Index a = 0; a < nb_; ++a) {
            const double ja = JRi[(b0 + a) * nx + j];
            const double* wja = wj + a * nx;
            CMHE_UNROLL
            for (Index k = 0; k < cb; ++k) acc[k] += ja * wja[k];
          }
          const double gj = gbi[j];
          double* Dj = Di + j * nx;
          if (plain)
            for (Index k = 0; k < cb; ++k) Dj[k] += mk * acc[k];
          else
            for (Index k = 0; k < cb; ++k) Dj[k] += mk * (rho1 * acc[k] + a2 * gj * gbi[k]);
        }
      }
    }
    bool weighted = false;
    const double* Ai = arrival + i * bs;
    for (Index j = 0; j < nx; ++j) {
      e[j] = X[i * nx + j] - data.xbar[j];
      weighted = weighted || (measured && Ai[j * nx + j] != 0.0);
    }
    if (weighted) {
      for (Index j = 0; j < nx; ++j) {
        double s = 0.0;
        for (Index k = 0; k < nx; ++k) s += Ai[j * nx + k] * e[k];
        gi[j] += s;
        cost += 0.5 * e[j] * s;
        for (Index k = j; k < nx; ++k) Di[j * nx + k] += Ai[j * nx + k];
      }
    }
    if (i < n - 1) {
      const double* Qi = qinv + i * bs;
      const double* Wi = o.W + i * nx;
      const double* Fi = o.FJ + i * bs;
      for (Index j = 0; j < nx; ++j) {
        double s = 0.0;
        for (Index k = 0; k < nx; ++k) s += Qi[j * nx + k] * Wi[k];
        qw[j] = s;
        cost += 0.5 * Wi[j] * s;
      }
      const double *eqi, *fqfi;
      if (pre) {
        eqi = w.stage_eq.data() + i * bs;
        fqfi = w.stage_fqf.data() + i * bs;
      } else {
        stage_product<NX>(nx, Qi, Fi, w.eql.data(), w.fqfl.data(), qf);
        eqi = w.eql.data();
        fqfi = w.fqfl.data();
      }
      double* Ei = E + i * bs;
      double* Dn = D + (i + 1) * bs;
      for (Index j = 0; j < nx; ++j) acc[j] = 0.0;
      for (Index a = 0; a < nx; ++a) {  // acc = F^T qw
        const double qa = qw[a];
        const double* Fa = Fi + a * nx;
        for (Index j = 0; j < nx; ++j) acc[j] += Fa[j] * qa;
      }
      for (Index j = 0; j < nx; ++j) {
        gi[j] -= acc[j];
        for (Index k = 0; k < nx; ++k) Ei[j * nx + k] = eqi[j * nx + k];
        for (Index k = j; k < nx; ++k) Di[j * nx + k] += fqfi[j * nx + k];
        if (push) {  // node i + 1's first terms (the upper triangle of its block)
          g[(i + 1) * nx + j] = qw[j];
          for (Index k = j; k < nx; ++k) Dn[j * nx + k] = Qi[j * nx + k];
        }
      }
    }
    for (Index j = 0; j < nx; ++j)  // D[i] is complete: mirror its upper triangle
      for (Index k = 0; k < j; ++k) Di[j * nx + k] = Di[k * nx + j];
    ncost[i] = cost;
  }
  double total = 0.0;
  for (Index i = 0; i < n; ++i) total += ncost[i];
  return total;
}

// D[buf], the QP's diagonal blocks, from buffer buf's Gauss-Newton ones Dgn[buf]: each
// ball's curvature 2 lam_ib I_{S_b} with its multiplier (n, nb) where positive, then,
// where ``exact``, the exact Hessian's terms that Gauss-Newton leaves out, sum_b (wgt_ib
// S_ib + extra_ib gb_ib gb_ib^T) (see assemble), node by node
template <int NX>
void form_hessian(WindowSolver& w, int buf, const double* lam, bool exact) {
  const Index n = w.n, nx = block_size<NX>(w.nx), nblk = w.nblk, bs = nx * nx;
  const double* S = w.out.data() + (buf + 1) * w.window_size - n * w.sr_size;
  const double* Dgn = w.Dgn.data() + buf * n * bs;
  double* D = w.D.data() + buf * n * bs;
  const double* wgt = w.wgt.data() + buf * n * nblk;
  const double* extra = w.extra.data() + buf * n * nblk;
  const double* gb = w.gb.data() + buf * n * nblk * nx;
  for (Index i = 0; i < n; ++i) {
    double* Di = D + i * bs;
    std::memcpy(Di, Dgn + i * bs, bs * sizeof(double));
    for (Index bb = 0; bb < w.nb; ++bb)
      if (lam[i * w.nb + bb] > 0.0)
        for (Index a = 0; a < w.bk; ++a) {
          const Index s = w.ball[bb * w.bk + a];
          Di[s * nx + s] += 2.0 * lam[i * w.nb + bb];
        }
    if (!exact) continue;
    for (Index b = 0; b < nblk; ++b) {
      const double wb = wgt[i * nblk + b], x2 = extra[i * nblk + b];
      const Index cb = w.block_cols[b];  // S_b (cb x cb) and gb_b are zero beyond cb
      const double* Sb = S + i * w.sr_size + w.sr_start[b];
      if (x2 != 0.0) {
        const double* g = gb + (i * nblk + b) * nx;
        for (Index j = 0; j < cb; ++j)
          for (Index k = 0; k < cb; ++k) Di[j * nx + k] += wb * Sb[j * cb + k] + x2 * g[j] * g[k];
      } else if (wb != 0.0) {  // the same sums without the zero term
        for (Index j = 0; j < cb; ++j)
          for (Index k = 0; k < cb; ++k) Di[j * nx + k] += wb * Sb[j * cb + k];
      }
    }
  }
}

template <int NX>
double evaluate_sized(WindowSolver& w, int buf, const WindowData& data, const double* zmask) {
  double* out = w.out.data() + buf * w.window_size;
  if (!w.window || w.window->evaluate(w.ptrs.data() + 5 * buf, out) != 0) return kInf;
  return assemble<NX>(w, buf, w.Xb.data() + buf * w.n * w.nx, out, zmask, data, -1);
}

template <int NX>
SqpResult sqp(WindowSolver& w, const WindowData& data, const double* zmask, double* lam,
              const SqpOptions& opt, bool evaluated, int shifted) {
  const Index n = w.n, nx = block_size<NX>(w.nx), nb = w.nb, size = n * nx;
  const Feasible fs = w.feasible();
  double* d = w.d.data();
  double* lam_qp = w.lam_qp.data();
  auto X = [&](int b) { return w.Xb.data() + b * size; };
  auto Dp = [&](int b) { return w.D.data() + b * n * nx * nx; };
  auto Ep = [&](int b) { return w.E.data() + b * (n - 1) * nx * nx; };
  auto gp = [&](int b) { return w.g.data() + b * size; };
  int cur = 0;
  project(n, nx, X(0), fs);
  double cost;
  if (evaluated)  // out[0] holds the model's outputs at Xb[0] (shift_outputs)
    cost = assemble<NX>(w, 0, X(0), w.out.data(), zmask, data, shifted >= 0 ? shifted : -1);
  else
    cost = evaluate_sized<NX>(w, 0, data, zmask);
  bool exact = opt.newton;  // exact Hessian at the current iterate (else Gauss-Newton)
  form_hessian<NX>(w, 0, lam, exact);
  double step = kInf;
  double prev = kInf;       // previous full step (inf after a shortened one)
  bool prev_exact = false;  // ... and whether it was an exact Newton step
  Index prev_active = 1;    // ... and its QP's number of active constraints
  double rate = 0.0;        // the largest |d_k| / |d_k-1|^2 over consecutive full steps
  for (Index it = 1; it <= opt.max_iter; ++it) {
    if (!std::isfinite(cost)) return {LINE_SEARCH_FAILED, it, step, cost, cur};
    QPResult qp = solve_qp<NX>(n, nx, X(cur), Dp(cur), Ep(cur), gp(cur), fs, opt.max_qp_iter,
                               d, lam_qp, w.qp);
    if (qp.status == NOT_PD && exact) {  // indefinite: fall back to Gauss-Newton here
      exact = false;
      form_hessian<NX>(w, cur, lam, exact);
      qp = solve_qp<NX>(n, nx, X(cur), Dp(cur), Ep(cur), gp(cur), fs, opt.max_qp_iter, d,
                        lam_qp, w.qp);
    }
    if (qp.status != CONVERGED) return {qp.status, it, step, cost, cur};
    const bool step_exact = exact;  // d is an exact Newton step
    step = 0.0;
    const double* scale = w.step_scale.data();
    for (Index i = 0; i < n; ++i)
      for (Index j = 0; j < nx; ++j) step = std::max(step, std::fabs(d[i * nx + j]) * scale[j]);
    const int tr = 1 - cur;
    if (prev < kInf) rate = std::max(rate, step / (prev * prev));
    const bool contracted = qp.active == 0 && prev < kInf && step <= 0.5 * prev;
    double err = kInf;  // the estimated error of X_k + d_k
    if (contracted) {
      err = step * step / (prev - step);
      if (!step_exact) err *= kContractionSafety;
      if (opt.quadratic && exact && prev_exact && prev_active == 0)  // two Newton steps
        err = std::min(err, kQuadraticSafety * rate * (step * step));
    }
    // a Gauss-Newton step's size says less of the error left (its rate may be slow)
    const double step_tol = step_exact ? opt.step_tol : opt.step_tol / kContractionSafety;
    if (step <= step_tol || err <= opt.err_tol) {
      std::copy(lam_qp, lam_qp + n * nb, lam);
      for (Index i = 0; i < size; ++i) X(tr)[i] = X(cur)[i] + 1.0 * d[i];
      project(n, nx, X(tr), fs);
      return {CONVERGED, it, step, cost, tr};
    }
    double alpha = 1.0;
    const double slack = 1e-13 * (1.0 + std::fabs(cost));
    bool accepted = false, corrected = false;
    double ct = kInf;
    const double* gc = gp(cur);
    // the sufficient decrease from X(cur) to X(tr), whose cost is c
    auto decreases = [&](double c) {
      double dd = 0.0;
      const double* xt = X(tr);
      const double* xc = X(cur);
      for (Index i = 0; i < size; ++i) dd += gc[i] * (xt[i] - xc[i]);
      return c <= cost + 1e-4 * dd + slack;
    };
    for (int ls = 0; ls < 30; ++ls) {
      double* xt = X(tr);
      const double* xc = X(cur);
      for (Index i = 0; i < size; ++i) xt[i] = xc[i] + alpha * d[i];
      project(n, nx, xt, fs);
      ct = evaluate_sized<NX>(w, tr, data, zmask);
      if (decreases(ct)) {
        accepted = true;
        break;
      }
      if (ls == 0 && w.watchdog && std::isfinite(ct)) {  // the full step, corrected
        std::copy(d, d + size, w.d_kept.data());
        std::copy(lam_qp, lam_qp + n * nb, w.lam_kept.data());
        form_hessian<NX>(w, tr, lam_qp, false);  // a Gauss-Newton step
        const QPResult q2 = solve_qp<NX>(n, nx, xt, Dp(tr), Ep(tr), gp(tr), fs,
                                         opt.max_qp_iter, d, lam_qp, w.qp);
        if (q2.status == CONVERGED) {
          for (Index i = 0; i < size; ++i) xt[i] += d[i];
          project(n, nx, xt, fs);
          ct = evaluate_sized<NX>(w, tr, data, zmask);
          if (decreases(ct)) {
            accepted = corrected = true;
            break;
          }
        }
        std::copy(w.d_kept.begin(), w.d_kept.end(), d);
        std::copy(w.lam_kept.begin(), w.lam_kept.end(), lam_qp);
      }
      alpha *= 0.5;
    }
    if (!accepted) return {LINE_SEARCH_FAILED, it, step, cost, cur};
    exact = opt.newton;
    form_hessian<NX>(w, tr, lam_qp, exact);
    prev = alpha == 1.0 && !corrected ? step : kInf;
    prev_exact = step_exact;
    prev_active = qp.active;
    cur = tr;
    cost = ct;
    std::copy(lam_qp, lam_qp + n * nb, lam);
  }
  return {MAX_ITER, opt.max_iter, step, cost, cur};
}

}  // namespace

void rho_derivatives(int code, double scale, double s, double& rho, double& rho1,
                     double& rho2) {
  if (code == 1) {  // huber
    const double c2 = scale * scale;
    if (s <= c2) {
      rho = s, rho1 = 1.0, rho2 = 0.0;
      return;
    }
    const double r = std::sqrt(s);
    rho = 2.0 * scale * r - c2, rho1 = scale / r, rho2 = -0.5 * scale / (s * r);
    return;
  }
  if (code == 2) {  // cauchy
    const double c2 = scale * scale;
    const double q = 1.0 + s / c2;
    rho = c2 * std::log1p(s / c2), rho1 = 1.0 / q, rho2 = -1.0 / (c2 * q * q);
    return;
  }
  if (code == 3) {  // welsch
    const double c2 = scale * scale;
    const double wv = std::exp(-s / c2);
    rho = c2 * (1.0 - wv), rho1 = wv, rho2 = -wv / c2;
    return;
  }
  rho = s, rho1 = 1.0, rho2 = 0.0;  // l2
}

WindowSolver::WindowSolver(Index horizon, Index nx_, Index nz_, Index nu_,
                           const ModelFunction* window_, const ModelFunction* tail_,
                           std::vector<double> lo_, std::vector<double> hi_,
                           std::vector<int64_t> ball_, Index ball_size,
                           std::vector<double> ball_r2_, std::vector<double> rinv_,
                           std::vector<int64_t> blocks_, int loss_code_, double loss_scale_,
                           bool linear_transition, std::vector<int64_t> block_cols_,
                           std::vector<int64_t> block_robust)
    : n(horizon), nx(nx_), nz(nz_), nu(nu_), nblk(Index(blocks_.size() / 2)),
      nb(Index(ball_r2_.size())), bk(ball_size), window(window_), tail(tail_),
      lo(std::move(lo_)), hi(std::move(hi_)), ball_r2(std::move(ball_r2_)),
      rinv(std::move(rinv_)), ball(std::move(ball_)), blocks(std::move(blocks_)),
      block_cols(std::move(block_cols_)), loss_code(loss_code_), loss_scale(loss_scale_),
      linear(linear_transition) {
  if (n < 2) throw std::invalid_argument("a window needs at least 2 nodes");
  if (Index(lo.size()) != nx || Index(hi.size()) != nx)
    throw std::invalid_argument("lo and hi need nx values");
  if (Index(ball.size()) != nb * bk) throw std::invalid_argument("ball is not (nb, ball_size)");
  for (int64_t s : ball)
    if (s < 0 || s >= nx) throw std::invalid_argument("a ball coordinate is out of range");
  if (Index(rinv.size()) != nz * nz) throw std::invalid_argument("rinv is not (nz, nz)");
  for (Index b = 0; b < nblk; ++b)
    if (blocks[2 * b] < 0 || blocks[2 * b + 1] < 0 || blocks[2 * b] + blocks[2 * b + 1] > nz)
      throw std::invalid_argument("a measurement block is out of range");
  if (!block_robust.empty() && Index(block_robust.size()) != nblk)
    throw std::invalid_argument("block_robust needs one value per measurement block");
  block_loss.assign(nblk, loss_code);
  for (Index b = 0; b < Index(block_robust.size()); ++b)
    if (block_robust[b] == 0) block_loss[b] = 0;
  if (block_cols.empty()) block_cols.assign(nblk, nx);
  if (Index(block_cols.size()) != nblk)
    throw std::invalid_argument("block_cols needs one value per measurement block");
  sr_size = 0;
  for (int64_t c : block_cols) {
    if (c < 0 || c > nx) throw std::invalid_argument("a block's column count is out of range");
    sr_start.push_back(sr_size);
    sr_size += c * c;
  }
  const Index bs = nx * nx;
  window_size = nz * n + nz * nx * n + nx * (n - 1) + bs * (n - 1) + sr_size * n;
  if (window && window->output_size() != window_size)
    throw std::invalid_argument(
        "the window function writes " + std::to_string(window->output_size()) +
        " values, the window's layout holds " + std::to_string(window_size) +
        ": a window function of another horizon, nx or nz, or give the solver the "
        "block_cols its window function was built with");
  if (tail && tail->output_size() != Index(nz + nz * nx + nx + bs + sr_size))
    throw std::invalid_argument("the tail function's outputs do not fit the window's layout");
  z.assign(n * nz, 0.0);
  m.assign(n * nz, 0.0);
  u.assign((n - 1) * nu, 0.0);
  dt.assign(n - 1, 0.0);
  step_scale.assign(nx, 1.0);
  Xb.assign(2 * n * nx, 0.0);
  out.assign(2 * window_size, 0.0);
  D.assign(2 * n * bs, 0.0);
  E.assign(2 * (n - 1) * bs, 0.0);
  g.assign(2 * n * nx, 0.0);
  d.assign(n * nx, 0.0);
  lam_qp.assign(n * nb, 0.0);
  d_kept.assign(n * nx, 0.0);
  lam_kept.assign(n * nb, 0.0);
  wgt.assign(2 * n * nblk, 0.0);
  extra.assign(2 * n * nblk, 0.0);
  gb.assign(2 * n * nblk * nx, 0.0);
  Dgn.assign(2 * n * bs, 0.0);
  ncost.assign(2 * n, 0.0);
  const Index ns = linear ? n - 1 : 0;
  stage_done.assign(ns, 0);
  stage_eq.assign(ns, bs, 0.0);
  stage_fqf.assign(ns, bs, 0.0);
  tail_out.assign(nz + nz * nx + nx + bs + sr_size, 0.0);
  ptrs.resize(10);
  for (int b = 0; b < 2; ++b) {
    ptrs[5 * b] = Xb.data() + b * n * nx;
    ptrs[5 * b + 1] = z.data();
    ptrs[5 * b + 2] = m.data();
    ptrs[5 * b + 3] = nu ? u.data() : nullptr;
    ptrs[5 * b + 4] = dt.data();
  }
  tail_ptrs = {Xb.data() + (n - 2) * nx, Xb.data() + (n - 1) * nx,
               z.data() + (n - 1) * nz, m.data() + (n - 1) * nz,
               nu ? u.data() + (n - 2) * nu : nullptr, dt.data() + (n - 2)};
  wr.resize(nz);
  wj.resize(nz * nx);
  qw.resize(nx);
  qf.resize(bs);
  e.resize(nx);
  acc.resize(nx);
  eql.resize(bs);
  fqfl.resize(bs);
  qp.resize(n, nx, nb);
}

SqpResult WindowSolver::solve(const WindowData& data, const double* zmask, double* lam,
                              const SqpOptions& opt, bool evaluated, int shifted) {
  ++generation;
  return with_block_size(nx, [&](auto k) {
    return sqp<decltype(k)::value>(*this, data, zmask, lam, opt, evaluated, shifted);
  });
}

double WindowSolver::evaluate(int buf, const WindowData& data, const double* zmask) {
  ++generation;
  return with_block_size(
      nx, [&](auto k) { return evaluate_sized<decltype(k)::value>(*this, buf, data, zmask); });
}

double WindowSolver::assemble(int buf, const WindowData& data, const double* zmask, int prev) {
  ++generation;
  return with_block_size(nx, [&](auto k) {
    return cmhe::assemble<decltype(k)::value>(*this, buf, Xb.data() + buf * n * nx,
                                              out.data() + buf * window_size, zmask, data, prev);
  });
}

bool WindowSolver::shift_outputs(int src, int dst) {
  ++generation;
  if (!tail) throw std::invalid_argument("the window model has no tail function");
  if (tail->evaluate(tail_ptrs.data(), tail_out.data()) != 0) return false;
  double* to = out.data() + dst * window_size;
  const double* from = out.data() + src * window_size;
  const Index counts[5] = {n, n, n - 1, n - 1, n};
  const Index chunks[5] = {nz, nz * nx, nx, nx * nx, sr_size};
  Index off = 0, toff = 0;  // section start in the window's outputs and in the tail's
  for (int s = 0; s < 5; ++s) {
    const Index count = counts[s], chunk = chunks[s];
    std::memmove(to + off, from + off + chunk, (count - 1) * chunk * sizeof(double));
    std::memcpy(to + off + (count - 1) * chunk, tail_out.data() + toff, chunk * sizeof(double));
    off += count * chunk;
    toff += chunk;
  }
  return true;
}

void WindowSolver::shift_stages() {
  const Index ns = Index(stage_done.size());
  if (ns == 0) return;
  std::memmove(stage_done.data(), stage_done.data() + 1, (ns - 1) * sizeof(int64_t));
  stage_done[ns - 1] = 0;
  stage_eq.slide();
  stage_fqf.slide();
}

void WindowSolver::node_mask(double* zmask) const {
  for (Index i = 0; i < n; ++i) {
    bool any = false;
    for (Index j = 0; j < nz; ++j) any = any || m[i * nz + j] != 0.0;
    zmask[i] = any ? 1.0 : 0.0;
  }
}

}  // namespace cmhe
