#include "vector_math.hpp"

#include <cmath>

#if defined(CMHE_LIBMVEC)
#include <immintrin.h>

// glibc's AVX2 variants (the vector function ABI's names: 'd' AVX2, 'N4' four lanes, 'v' a
// vector argument), declared for AVX2 as they are called (Clang refuses a 256-bit vector
// passed between functions of different targets)
extern "C" __attribute__((target("avx2"))) __m256d _ZGVdN4v_sin(__m256d);
extern "C" __attribute__((target("avx2"))) __m256d _ZGVdN4v_cos(__m256d);
#endif

namespace cmhe {

namespace {

#if defined(CMHE_LIBMVEC)
// four at a time, then the rest (n not a multiple of 4) one at a time
__attribute__((target("avx2,fma"))) void sin_row_avx2(const double* x, double* r, int64_t n) {
  int64_t k = 0;
  for (; k + 4 <= n; k += 4) _mm256_storeu_pd(r + k, _ZGVdN4v_sin(_mm256_loadu_pd(x + k)));
  for (; k < n; ++k) r[k] = std::sin(x[k]);
}

__attribute__((target("avx2,fma"))) void cos_row_avx2(const double* x, double* r, int64_t n) {
  int64_t k = 0;
  for (; k + 4 <= n; k += 4) _mm256_storeu_pd(r + k, _ZGVdN4v_cos(_mm256_loadu_pd(x + k)));
  for (; k < n; ++k) r[k] = std::cos(x[k]);
}

bool cpu_has_avx2_fma() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}
#else
bool cpu_has_avx2_fma() { return false; }
#endif

const bool kUseLibmvec = cpu_has_avx2_fma();

}  // namespace

bool uses_vector_sin_cos() { return kUseLibmvec; }

void sin_row(const double* x, double* r, int64_t n) {
#if defined(CMHE_LIBMVEC)
  if (kUseLibmvec) return sin_row_avx2(x, r, n);
#endif
  for (int64_t k = 0; k < n; ++k) r[k] = std::sin(x[k]);
}

void cos_row(const double* x, double* r, int64_t n) {
#if defined(CMHE_LIBMVEC)
  if (kUseLibmvec) return cos_row_avx2(x, r, n);
#endif
  for (int64_t k = 0; k < n; ++k) r[k] = std::cos(x[k]);
}

}  // namespace cmhe
