#include "vector_math.hpp"

#include <cmath>

#if defined(CMHE_LIBMVEC)
#include <immintrin.h>

// glibc's AVX2 variants (the vector function ABI's names: 'd' AVX2, 'N4' four lanes, 'v' a
// vector argument)
extern "C" __m256d _ZGVdN4v_sin(__m256d);
extern "C" __m256d _ZGVdN4v_cos(__m256d);
#endif

namespace cmhe {

namespace {

#if defined(CMHE_LIBMVEC)
__attribute__((target("avx2,fma"))) void sin_row_avx2(const double* x, double* r, int64_t n) {
  for (int64_t k = 0; k < n; k += 4) _mm256_storeu_pd(r + k, _ZGVdN4v_sin(_mm256_loadu_pd(x + k)));
}

__attribute__((target("avx2,fma"))) void cos_row_avx2(const double* x, double* r, int64_t n) {
  for (int64_t k = 0; k < n; k += 4) _mm256_storeu_pd(r + k, _ZGVdN4v_cos(_mm256_loadu_pd(x + k)));
}

bool detect() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}
#else
bool detect() { return false; }
#endif

const bool kVector = detect();

}  // namespace

bool vector_sin_cos() { return kVector; }

void sin_row(const double* x, double* r, int64_t n) {
#if defined(CMHE_LIBMVEC)
  if (kVector) return sin_row_avx2(x, r, n);
#endif
  for (int64_t k = 0; k < n; ++k) r[k] = std::sin(x[k]);
}

void cos_row(const double* x, double* r, int64_t n) {
#if defined(CMHE_LIBMVEC)
  if (kVector) return cos_row_avx2(x, r, n);
#endif
  for (int64_t k = 0; k < n; ++k) r[k] = std::cos(x[k]);
}

}  // namespace cmhe
