// Dense and block-tridiagonal linear algebra of the MHE window solve.
//
// The window Hessian is symmetric block-tridiagonal, H = (D, E), with diagonal blocks D
// (n, nx, nx) and super-diagonal blocks E (n-1, nx, nx) (E_i couples node i with node
// i+1); every array is row-major and contiguous. The kernels are templates on the
// block size NX: a positive NX is the size as a constant (the compiler unrolls the
// nx-loops), NX = 0 reads it at run time (with_block_size picks one).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <vector>

namespace cmhe {

using Index = int64_t;

// NX where positive (a compile-time size), else the run-time ``nx``
template <int NX>
constexpr Index block_size(Index nx) {
  return NX > 0 ? NX : nx;
}

// ``f(std::integral_constant<int, NX>{})`` with NX = nx for the specialised sizes, else
// NX = 0. The sizes are the bend model's state of one to four sections (4 per section),
// and one to three sections with a gyro bias per section's IMU (7 per section).
template <class F>
decltype(auto) with_block_size(Index nx, F&& f) {
  switch (nx) {
    case 4:
      return f(std::integral_constant<int, 4>{});
    case 7:
      return f(std::integral_constant<int, 7>{});
    case 8:
      return f(std::integral_constant<int, 8>{});
    case 12:
      return f(std::integral_constant<int, 12>{});
    case 14:
      return f(std::integral_constant<int, 14>{});
    case 16:
      return f(std::integral_constant<int, 16>{});
    case 21:
      return f(std::integral_constant<int, 21>{});
    default:
      return f(std::integral_constant<int, 0>{});
  }
}

// The factor's scratch: the current block's unscaled rows V and W, the previous block's
// W, and the reciprocal pivots of both (nx x nx blocks, rows of nx), on the stack for a
// constant size, else on the heap
template <int NX>
struct FactorScratch {
  double v[NX * NX], w[2][NX * NX], p[2][NX], row[NX];
  explicit FactorScratch(Index) {}
};
template <>
struct FactorScratch<0> {  // one buffer per thread, grown once (no allocation per call)
  double *v, *w[2], *p[2], *row;
  explicit FactorScratch(Index nx) {
    thread_local std::vector<double> buf;
    const Index bs = nx * nx;
    if (Index(buf.size()) < 3 * bs + 3 * nx) buf.resize(3 * bs + 3 * nx);
    v = buf.data();
    w[0] = v + bs;
    w[1] = w[0] + bs;
    p[0] = w[1] + bs;
    p[1] = p[0] + nx;
    row = p[1] + nx;
  }
};

// A loop that the compiler unrolls completely where its trip count is a constant (the
// block kernels' rows of NX values stay in registers)
#if defined(__GNUC__)
#define CMHE_UNROLL _Pragma("GCC unroll 32")
#define CMHE_SIMD _Pragma("omp simd")
#define CMHE_ALWAYS_INLINE __attribute__((always_inline))
#else
#define CMHE_UNROLL
#define CMHE_SIMD
#define CMHE_ALWAYS_INLINE
#endif

// The block factor also in an AVX2 version that the loader picks where the processor has
// it (target clones; without FMA contraction each operation rounds as in the default)
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CMHE_BLOCK_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define CMHE_BLOCK_CLONES
#endif

// ``row -= t x`` over values k0 to nx - 1: over all nx values, unrolled into registers,
// for the smallest constant sizes (the factor's chain of dependent rows is its cost
// there), vectorised otherwise
template <int NX>
inline void row_axpy(Index nx_, double* row, double t, const double* x, Index k0 = 0) {
  if constexpr (NX > 0 && NX <= 4) {
    CMHE_UNROLL
    for (Index k = 0; k < NX; ++k) row[k] -= t * x[k];
  } else {
    const Index nx = block_size<NX>(nx_);
    CMHE_SIMD
    for (Index k = k0; k < nx; ++k) row[k] -= t * x[k];
  }
}

// ``out = A B`` for nx x nx blocks (out distinct from A and B)
template <int NX>
inline void block_product(Index nx_, const double* A, const double* B, double* out) {
  const Index nx = block_size<NX>(nx_);
  for (Index j = 0; j < nx; ++j) {  // row j as a sum of B's rows, in the order of a
    double* oj = out + j * nx;
    for (Index k = 0; k < nx; ++k) oj[k] = 0.0;
    for (Index a = 0; a < nx; ++a) {
      const double t = A[j * nx + a];
      const double* Ba = B + a * nx;
      for (Index k = 0; k < nx; ++k) oj[k] += t * Ba[k];
    }
  }
}

// ``out = H v`` for the symmetric block-tridiagonal H = (D, E); v, out (n, nx)
template <int NX>
void btd_matvec(Index n, Index nx_, const double* D, const double* E, const double* v,
                double* out) {
  const Index nx = block_size<NX>(nx_);
  for (Index i = 0; i < n; ++i) {
    const double* Di = D + i * nx * nx;
    for (Index j = 0; j < nx; ++j) {
      double s = 0.0;
      for (Index k = 0; k < nx; ++k) {
        s += Di[j * nx + k] * v[i * nx + k];
        if (i < n - 1) s += E[(i * nx + j) * nx + k] * v[(i + 1) * nx + k];
        if (i > 0) s += E[((i - 1) * nx + k) * nx + j] * v[(i - 1) * nx + k];
      }
      out[i * nx + j] = s;
    }
  }
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CMHE_NODE4_AVX2 1
}  // namespace cmhe
#include <immintrin.h>
namespace cmhe {

// Whether the processor has AVX2 (eliminate_node4_avx2 is used then); the processor
// is read first, as a static initialiser may run before libgcc's
inline const bool kNode4Avx2 = [] {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") != 0;
}();

// The columns of a 4 x 4 block (row-major), each in a register
__attribute__((target("avx2"), always_inline)) inline void columns4_avx2(const double* A,
                                                                         __m256d* c) {
  const __m256d r0 = _mm256_loadu_pd(A), r1 = _mm256_loadu_pd(A + 4);
  const __m256d r2 = _mm256_loadu_pd(A + 8), r3 = _mm256_loadu_pd(A + 12);
  const __m256d a = _mm256_unpacklo_pd(r0, r1), b = _mm256_unpackhi_pd(r0, r1);
  const __m256d e = _mm256_unpacklo_pd(r2, r3), f = _mm256_unpackhi_pd(r2, r3);
  c[0] = _mm256_permute2f128_pd(a, e, 0x20);
  c[1] = _mm256_permute2f128_pd(b, f, 0x20);
  c[2] = _mm256_permute2f128_pd(a, e, 0x31);
  c[3] = _mm256_permute2f128_pd(b, f, 0x31);
}

// eliminate_node for NX = 4 with AVX2: a row of four values in one register, each
// lane's operations the scalar code's (a product, then a difference; no FMA), in its
// order, so that the results are its bits. Rows of V, G and the Schur complement as
// registers; the scalar factors t = V[c, j] p[c] as in the scalar code.
template <bool transposed>
__attribute__((target("avx2"))) bool eliminate_node4_avx2(
    const double* Dn, const double* bn, const double* Gn, const double* pn, const double* hn,
    const double* Eo, double* V, double* p, double* h, double* G) {
  __m256d row[4];
  columns4_avx2(Dn, row);
  __m256d g[4];
  if (Gn) {
    alignas(32) double t[4][4];  // t[c][j] = Gn[c, j] pn[c]
    for (int c = 0; c < 4; ++c) {
      g[c] = _mm256_loadu_pd(Gn + 4 * c);
      _mm256_store_pd(t[c], _mm256_mul_pd(g[c], _mm256_broadcast_sd(pn + c)));
    }
    for (int j = 0; j < 4; ++j)
      for (int c = 0; c < 4; ++c)
        row[j] = _mm256_sub_pd(row[j], _mm256_mul_pd(_mm256_broadcast_sd(&t[c][j]), g[c]));
  }
  __m256d v[4];
  for (int j = 0; j < 4; ++j) {
    for (int c = 0; c < j; ++c) {
      const double t = V[4 * c + j] * p[c];
      row[j] = _mm256_sub_pd(row[j], _mm256_mul_pd(_mm256_set1_pd(t), v[c]));
    }
    v[j] = row[j];
    _mm256_storeu_pd(V + 4 * j, v[j]);
    const double s = V[4 * j + j];
    if (!(s >= std::numeric_limits<double>::min())) return false;  // 1 / s finite
    p[j] = 1.0 / s;
  }
  if (bn) {
    __m256d hv = _mm256_loadu_pd(bn);
    if (Gn)
      for (int c = 0; c < 4; ++c)
        hv = _mm256_sub_pd(hv, _mm256_mul_pd(_mm256_set1_pd(pn[c] * hn[c]), g[c]));
    alignas(32) double hs[4];
    for (int c = 0; c < 3; ++c) {  // h[c] is complete
      _mm256_store_pd(hs, hv);
      const __m256d d = _mm256_sub_pd(
          hv, _mm256_mul_pd(_mm256_mul_pd(v[c], _mm256_set1_pd(p[c])), _mm256_set1_pd(hs[c])));
      hv = c == 0 ? _mm256_blend_pd(hv, d, 0xE) : c == 1 ? _mm256_blend_pd(hv, d, 0xC)
                                                         : _mm256_blend_pd(hv, d, 0x8);
    }
    _mm256_storeu_pd(h, hv);
  }
  if (Eo) {
    __m256d er[4], out[4];
    if constexpr (transposed) {
      columns4_avx2(Eo, er);
    } else {
      for (int j = 0; j < 4; ++j) er[j] = _mm256_loadu_pd(Eo + 4 * j);
    }
    for (int j = 0; j < 4; ++j) {
      __m256d r = er[j];
      for (int c = 0; c < j; ++c) {
        const double t = V[4 * c + j] * p[c];
        r = _mm256_sub_pd(r, _mm256_mul_pd(_mm256_set1_pd(t), out[c]));
      }
      out[j] = r;
      _mm256_storeu_pd(G + 4 * j, r);
    }
  }
  return true;
}
#endif

// One node's elimination in the block-tridiagonal recursions (btd_factor,
// btd_solve_two_ended, btd_last_block_inverse): the Schur complement of the node
// (its block Dn less the eliminated neighbour's sum_c pn_c Gn[c,:]^T Gn[c,:], where Gn is
// given), its rows V (unscaled, upper) and reciprocal pivots p (S = V^T P V), h = U~^-T c
// of its right-hand side c (bn less the neighbour's sum_c pn_c hn_c Gn[c,:]; none
// without bn) and, where Eo is given, the coupling G = U~^-T Eo^(T) for the next node (Eo
// read transposed with ``transposed``); U~ = P V is V with unit diagonal. False if the
// block is not positive definite.
template <int NX, bool transposed>
inline bool eliminate_node(Index nx_, const double* Dn, const double* bn, const double* Gn,
                           const double* pn, const double* hn, const double* Eo, double* V,
                           double* p, double* h, double* G, double* row_scratch) {
#if defined(CMHE_NODE4_AVX2)
  if constexpr (NX == 4)
    if (kNode4Avx2) return eliminate_node4_avx2<transposed>(Dn, bn, Gn, pn, hn, Eo, V, p, h, G);
#endif
  const Index nx = block_size<NX>(nx_);
  double row_local[NX > 0 ? NX : 1];  // a local row for a constant size (no aliasing)
  double* row = NX > 0 ? row_local : row_scratch;
  // row j of V (false if its pivot is not positive), from the whole vector of 4 values
  // that holds its diagonal on for a constant NX of 5 to 12, whose rows are unrolled (the
  // entries below the diagonal are dropped; those of the rows above that the row reads
  // are formed); larger blocks whole, in a loop (unrolled, their code grows with NX^3)
  constexpr bool unrolled = NX > 0 && NX <= 12;
  auto v_row = [&](Index j) CMHE_ALWAYS_INLINE {
    const Index k0 = unrolled && NX > 4 ? j - j % 4 : 0;
    for (Index k = k0; k < nx; ++k) row[k] = Dn[k * nx + j];
    if (Gn) {
      CMHE_UNROLL
      for (Index c = 0; c < nx; ++c)
        row_axpy<NX>(nx, row, Gn[c * nx + j] * pn[c], Gn + c * nx, k0);
    }
    for (Index c = 0; c < j; ++c) row_axpy<NX>(nx, row, V[c * nx + j] * p[c], V + c * nx, k0);
    const double s = row[j];
    if (!(s >= std::numeric_limits<double>::min())) return false;  // 1 / s finite
    p[j] = 1.0 / s;
    for (Index k = k0; k < nx; ++k) V[j * nx + k] = row[k];
    return true;
  };
  if constexpr (unrolled) {  // each row's start is a constant
    CMHE_UNROLL
    for (Index j = 0; j < NX; ++j)
      if (!v_row(j)) return false;
  } else {
    for (Index j = 0; j < nx; ++j)
      if (!v_row(j)) return false;
  }
  if (bn) {  // h[j] = bn[j] - sum_c pn_c hn_c Gn[c, j] - sum_{c<j} V[c, j] p_c h_c, in
             // that order, by rows of Gn and V
    for (Index j = 0; j < nx; ++j) h[j] = bn[j];
    if (Gn)
      for (Index c = 0; c < nx; ++c) {
        const double t = pn[c] * hn[c];
        const double* Gc = Gn + c * nx;
        CMHE_SIMD
        for (Index j = 0; j < nx; ++j) h[j] -= t * Gc[j];
      }
    for (Index c = 0; c + 1 < nx; ++c) {  // h[c] is complete
      const double pc = p[c], hc = h[c];
      const double* Vc = V + c * nx;
      for (Index j = c + 1; j < nx; ++j) h[j] -= Vc[j] * pc * hc;
    }
  }
  if (Eo) {
    for (Index j = 0; j < nx; ++j) {
      if constexpr (transposed)
        for (Index k = 0; k < nx; ++k) row[k] = Eo[k * nx + j];
      else
        for (Index k = 0; k < nx; ++k) row[k] = Eo[j * nx + k];
      for (Index c = 0; c < j; ++c) row_axpy<NX>(nx, row, V[c * nx + j] * p[c], G + c * nx);
      for (Index k = 0; k < nx; ++k) G[j * nx + k] = row[k];
    }
  }
  return true;
}

// y = U~^-1 P (h - G x) for one node (G and x the eliminated neighbour's coupling and
// solution, or G null); y may be h
template <int NX>
inline void back_substitute_node(Index nx_, const double* V, const double* p, const double* h,
                                 const double* G, const double* x, double* y) {
  const Index nx = block_size<NX>(nx_);
  for (Index j = nx - 1; j >= 0; --j) {
    double t = h[j];
    if (G)
      for (Index k = 0; k < nx; ++k) t -= G[j * nx + k] * x[k];
    for (Index k = j + 1; k < nx; ++k) t -= V[j * nx + k] * y[k];
    y[j] = p[j] * t;
  }
}

// Block-tridiagonal Cholesky H = L L^T of H = (D, E); false if not positive definite.
// L (n, nx, nx) receives the diagonal factors, M (n-1, nx, nx) the sub-diagonal blocks
// transposed, M_i^T = L_i^-1 E_i (row r of M_i^T is column r of M_i), rd (n, nx) the
// reciprocals of L's diagonal. The recursion runs on the square-root-free form (each
// block's S = V^T P V with P the reciprocal pivots p_j = 1 / s_j and U~ = P V of unit
// diagonal): block i's Schur complement S_i = D_i - W_{i-1}^T P_{i-1} W_{i-1}, its rows
// V_i by elimination with the reciprocal pivots, and W_i = U~_i^-T E_i the same way, so
// that the chain from one block to the next holds a division per pivot and no square
// root; L = (P^1/2 V)^T and M^T = P^1/2 W are scaled off that chain. A pivot below the
// smallest normal double (2^-1022) is taken as not positive definite (its reciprocal
// overflows). Each row is gathered in a row of nx values (kept in registers where NX is
// a constant); entries below V's diagonal are formed along with the row, from its first
// whole vector of 4 for a constant NX of 5 to 12, else whole (D is read below its
// diagonal for the upper triangle), and dropped.
template <int NX>
CMHE_BLOCK_CLONES bool btd_factor(Index n, Index nx_, const double* D, const double* E,
                                  double* L, double* M, double* rd) {
  const Index nx = block_size<NX>(nx_);
  const Index bs = nx * nx;
  FactorScratch<NX> scratch(nx);
  double* V = scratch.v;
  for (Index i = 0; i < n; ++i) {
    double* Li = L + i * bs;
    double* W = scratch.w[i & 1];
    const bool first = i == 0, last = i == n - 1;
    // V's rows from the Schur complement with the previous block's W and pivots, and
    // W = U~^-T E_i for the next
    const double* Wp = first ? nullptr : scratch.w[(i + 1) & 1];
    const double* pp = first ? nullptr : scratch.p[(i + 1) & 1];
    if (!eliminate_node<NX, false>(nx, D + i * bs, nullptr, Wp, pp, nullptr,
                                   last ? nullptr : E + i * bs, V, scratch.p[i & 1], nullptr, W,
                                   scratch.row))
      return false;
    for (Index j = 0; j < nx; ++j) {  // the scaled factors, off the recursion's chain
      const double ujj = std::sqrt(V[j * nx + j]);
      const double r = 1.0 / ujj;
      rd[i * nx + j] = r;
      for (Index k = 0; k < nx; ++k)
        Li[k * nx + j] = k > j ? V[j * nx + k] * r : (k == j ? ujj : 0.0);
      if (i < n - 1)
        for (Index k = 0; k < nx; ++k) M[i * bs + j * nx + k] = W[j * nx + k] * r;
    }
  }
  return true;
}

// ``y = (L L^T)^-1 b`` from btd_factor's L, M (transposed blocks) and rd; b, y (n, nx),
// y may be b
template <int NX>
void btd_substitute(Index n, Index nx_, const double* L, const double* M, const double* rd,
                    const double* b, double* y) {
  const Index nx = block_size<NX>(nx_);
  const Index bs = nx * nx;
  for (Index i = 0; i < n; ++i) {  // L z = b
    for (Index j = 0; j < nx; ++j) {
      double t = b[i * nx + j];
      if (i > 0)
        for (Index c = 0; c < nx; ++c) t -= M[(i - 1) * bs + c * nx + j] * y[(i - 1) * nx + c];
      for (Index c = 0; c < j; ++c) t -= L[i * bs + j * nx + c] * y[i * nx + c];
      y[i * nx + j] = t * rd[i * nx + j];
    }
  }
  for (Index i = n - 1; i >= 0; --i) {  // L^T y = z
    for (Index j = nx - 1; j >= 0; --j) {
      double t = y[i * nx + j];
      if (i < n - 1)
        for (Index c = 0; c < nx; ++c) t -= M[i * bs + j * nx + c] * y[(i + 1) * nx + c];
      for (Index c = j + 1; c < nx; ++c) t -= L[i * bs + c * nx + j] * y[i * nx + c];
      y[i * nx + j] = t * rd[i * nx + j];
    }
  }
}

// Solve H y = b by block-tridiagonal Cholesky (into L, M, rd); false if not PD
template <int NX>
bool btd_solve(Index n, Index nx, const double* D, const double* E, const double* b,
               double* L, double* M, double* rd, double* y) {
  if (!btd_factor<NX>(n, nx, D, E, L, M, rd)) return false;
  btd_substitute<NX>(n, nx, L, M, rd, b, y);
  return true;
}

// Solve H y = b for the symmetric block-tridiagonal H = (D, E) (as btd_solve) by
// eliminating nodes from both ends towards the middle node m = n / 2: nodes 0..m-1
// forwards, nodes n-1..m+1 backwards, two independent recursions that the loop runs
// side by side (the processor overlaps their chains of dependent divisions), then node
// m, then the solution outwards from m. False if H is not positive definite. Scratch: V
// (n, nx, nx), G (n - 1, nx, nx), p (n, nx), row (2 nx: one per end); y (n, nx) holds
// the eliminated right-hand sides on the way.
template <int NX>
CMHE_BLOCK_CLONES bool btd_solve_two_ended(Index n, Index nx_, const double* D,
                                           const double* E, const double* b, double* V,
                                           double* G, double* p, double* row, double* y) {
  const Index nx = block_size<NX>(nx_);
  const Index bs = nx * nx, m = n / 2;
  const Index steps = std::max(m, n - 1 - m);
  for (Index s = 0; s < steps; ++s) {
    if (s < m) {  // node s from the start: coupling G[s] = U~^-T E_s
      const Index i = s;
      const bool first = i == 0;
      if (!eliminate_node<NX, false>(nx, D + i * bs, b + i * nx,
                                     first ? nullptr : G + (i - 1) * bs,
                                     first ? nullptr : p + (i - 1) * nx,
                                     first ? nullptr : y + (i - 1) * nx, E + i * bs, V + i * bs,
                                     p + i * nx, y + i * nx, G + i * bs, row))
        return false;
    }
    if (s < n - 1 - m) {  // node n-1-s from the end: coupling G[i-1] = U~^-T E_{i-1}^T
      const Index i = n - 1 - s;
      const bool last = s == 0;
      if (!eliminate_node<NX, true>(nx, D + i * bs, b + i * nx, last ? nullptr : G + i * bs,
                                    last ? nullptr : p + (i + 1) * nx,
                                    last ? nullptr : y + (i + 1) * nx, E + (i - 1) * bs,
                                    V + i * bs, p + i * nx, y + i * nx, G + (i - 1) * bs,
                                    row + nx))
        return false;
    }
  }
  // node m: both neighbours' Schur terms (the one after m enters as a second pass)
  {
    double* Vm = V + m * bs;
    double* pm = p + m * nx;
    double* hm = y + m * nx;
    const bool left = m > 0, right = m < n - 1;
    // the block less the right neighbour's term, then eliminated with the left one's
    FactorScratch<NX> scratch(nx);
    double* Dr = scratch.w[0];
    double* br = scratch.row;
    for (Index j = 0; j < nx; ++j) {
      for (Index k = 0; k < nx; ++k) Dr[j * nx + k] = D[m * bs + j * nx + k];
      br[j] = b[m * nx + j];
    }
    if (right) {
      const double* Gr = G + m * bs;
      const double* pr = p + (m + 1) * nx;
      const double* hr = y + (m + 1) * nx;
      for (Index c = 0; c < nx; ++c) {
        const double t = pr[c];
        for (Index j = 0; j < nx; ++j) {
          br[j] -= t * hr[c] * Gr[c * nx + j];
          for (Index k = 0; k < nx; ++k) Dr[j * nx + k] -= Gr[c * nx + j] * t * Gr[c * nx + k];
        }
      }
    }
    if (!eliminate_node<NX, false>(nx, Dr, br, left ? G + (m - 1) * bs : nullptr,
                                   left ? p + (m - 1) * nx : nullptr,
                                   left ? y + (m - 1) * nx : nullptr, nullptr, Vm, pm, hm,
                                   nullptr, row))
      return false;
    back_substitute_node<NX>(nx, Vm, pm, hm, nullptr, nullptr, hm);
  }
  for (Index s = 1; s <= steps; ++s) {  // outwards from m, both sides side by side
    if (m - s >= 0) {
      const Index i = m - s;
      back_substitute_node<NX>(nx, V + i * bs, p + i * nx, y + i * nx, G + i * bs,
                               y + (i + 1) * nx, y + i * nx);
    }
    if (m + s <= n - 1) {
      const Index i = m + s;
      back_substitute_node<NX>(nx, V + i * bs, p + i * nx, y + i * nx, G + (i - 1) * bs,
                               y + (i - 1) * nx, y + i * nx);
    }
  }
  return true;
}

// The last diagonal block of H^-1 (out, nx x nx) for the symmetric block-tridiagonal
// H = (D, E): the forward Schur recursion of btd_solve_two_ended's elimination alone,
// nothing kept per node, then the last Schur complement's inverse U~^-1 P U~^-T column
// by column; where H is an information matrix, the last node's covariance. False if H
// is not positive definite. Scratch: 3 nx^2 + 3 nx values.
template <int NX>
CMHE_BLOCK_CLONES bool btd_last_block_inverse(Index n, Index nx_, const double* D,
                                              const double* E, double* out, double* scratch) {
  const Index nx = block_size<NX>(nx_);
  const Index bs = nx * nx;
  double* V = scratch;
  double* G[2] = {V + bs, V + 2 * bs};
  double* p[2] = {V + 3 * bs, V + 3 * bs + nx};
  double* row = V + 3 * bs + 2 * nx;
  for (Index i = 0; i < n; ++i) {
    const bool first = i == 0, last = i == n - 1;
    if (!eliminate_node<NX, false>(nx, D + i * bs, nullptr, first ? nullptr : G[(i + 1) & 1],
                                   first ? nullptr : p[(i + 1) & 1], nullptr,
                                   last ? nullptr : E + i * bs, V, p[i & 1], nullptr, G[i & 1],
                                   row))
      return false;
  }
  const double* pl = p[(n - 1) & 1];
  for (Index c = 0; c < nx; ++c) {  // column c: U~^-T e_c, then U~^-1 P of it
    for (Index j = 0; j < nx; ++j) {
      double t = j == c ? 1.0 : 0.0;
      for (Index k = 0; k < j; ++k) t -= V[k * nx + j] * pl[k] * row[k];
      row[j] = t;
    }
    back_substitute_node<NX>(nx, V, pl, row, nullptr, nullptr, row);
    for (Index j = 0; j < nx; ++j) out[j * nx + c] = row[j];
  }
  return true;
}

// Symmetric orthogonal T (nx, nx) with T n = -+e_c for the unit normal ``nrm`` (nx) of
// a ball on the coordinates ``idx`` (k of them); returns the pivot coordinate c
inline Index householder(Index nx, const double* nrm, const int64_t* idx, Index k, double* T,
                         double* v) {
  for (Index j = 0; j < nx; ++j)
    for (Index c = 0; c < nx; ++c) T[j * nx + c] = j == c ? 1.0 : 0.0;
  Index piv = idx[0];
  for (Index a = 0; a < k; ++a)
    if (std::fabs(nrm[idx[a]]) > std::fabs(nrm[piv])) piv = idx[a];
  const double sg = nrm[piv] >= 0.0 ? 1.0 : -1.0;
  for (Index j = 0; j < nx; ++j) v[j] = 0.0;
  for (Index a = 0; a < k; ++a) v[idx[a]] = nrm[idx[a]];
  v[piv] += sg;
  double vv = 0.0;
  for (Index j = 0; j < nx; ++j) vv += v[j] * v[j];
  for (Index j = 0; j < nx; ++j)
    for (Index c = 0; c < nx; ++c) T[j * nx + c] -= 2.0 * v[j] * v[c] / vv;
  return piv;
}

// ``out = A B`` for A (m, k) and B (k, p), written out: on few-by-few matrices a BLAS
// call costs more than its arithmetic
inline void dense_mul(Index m, Index k, Index p, const double* A, const double* B,
                      double* out) {
  for (Index i = 0; i < m; ++i)
    for (Index j = 0; j < p; ++j) {
      double s = 0.0;
      for (Index a = 0; a < k; ++a) s += A[i * k + a] * B[a * p + j];
      out[i * p + j] = s;
    }
}

// Lower Cholesky factor L (n, n) of a symmetric positive definite A; false if A is
// not positive definite
inline bool dense_cholesky(Index n, const double* A, double* L) {
  for (Index j = 0; j < n * n; ++j) L[j] = 0.0;
  for (Index j = 0; j < n; ++j) {
    double s = A[j * n + j];
    for (Index c = 0; c < j; ++c) s -= L[j * n + c] * L[j * n + c];
    if (!(s > 0.0)) return false;
    L[j * n + j] = std::sqrt(s);
    for (Index k = j + 1; k < n; ++k) {
      double t = A[k * n + j];
      for (Index c = 0; c < j; ++c) t -= L[k * n + c] * L[j * n + c];
      L[k * n + j] = t / L[j * n + j];
    }
  }
  return true;
}

// ``out = (L L^T)^-1 = L^-T L^-1`` (n, n), symmetric, for a lower-triangular L with a
// nonzero diagonal; Li (n, n) scratch
inline void dense_inverse_gram(Index n, const double* L, double* out, double* Li) {
  for (Index j = 0; j < n * n; ++j) Li[j] = 0.0;
  for (Index c = 0; c < n; ++c)
    for (Index j = c; j < n; ++j) {
      double t = j == c ? 1.0 : 0.0;
      for (Index k = c; k < j; ++k) t -= L[j * n + k] * Li[k * n + c];
      Li[j * n + c] = t / L[j * n + j];
    }
  for (Index j = 0; j < n; ++j)
    for (Index k = j; k < n; ++k) {
      double s = 0.0;
      for (Index a = k; a < n; ++a) s += Li[a * n + j] * Li[a * n + k];
      out[j * n + k] = s;
      out[k * n + j] = s;
    }
}

}  // namespace cmhe
