// sin and cos over rows of values (the batched tape's loops), four at a time from glibc's
// vector math library (libmvec) where the build found it and the processor has AVX2 and
// FMA, else one at a time from the C library. libmvec's results are within 4 ulp of the
// C library's, not always the same bits: a batched evaluation may differ from a single
// one (Tape::evaluate, always the C library's) in the last bits of what depends on a sin
// or cos.
#pragma once

#include <cstdint>

namespace cmhe {

// r[k] = sin(x[k]) for k < n (four at a time where n allows); x and r the same row or
// disjoint
void sin_row(const double* x, double* r, int64_t n);
// r[k] = cos(x[k]) for k < n; as sin_row
void cos_row(const double* x, double* r, int64_t n);
// whether sin_row and cos_row take the vector library's four-at-a-time functions here
bool uses_vector_sin_cos();

}  // namespace cmhe
