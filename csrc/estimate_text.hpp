// The lines of an estimate CSV for a block of samples, written as Python's "%.10g" writes
// each number (continuum_mhe.io.estimate_csv.estimate_lines).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cmhe {

// One block of estimates: n samples of ny outputs, row-major.
struct EstimateRows {
  size_t n = 0;
  size_t ny = 0;
  const double* t = nullptr;           // (n) s
  const double* output = nullptr;      // (n, ny); written where ``estimated``
  const double* output_std = nullptr;  // (n, ny); a non-finite one is an empty cell
  const uint8_t* estimated = nullptr;  // (n) 0: the row's outputs are empty cells
  const uint8_t* outlier = nullptr;    // (n) 0 or 1 before the status, or null: no such column
  const std::vector<std::string>* status = nullptr;  // (n) each row's status
  const double* solve_ms = nullptr;    // (n) ms
};

// Appends the rows' CSV lines to ``out``: ``t``, the outputs (empty where not
// estimated), their standard deviations (empty where not estimated or not finite), the
// outlier flag, the status and ``solve_ms``; numbers in 10 significant digits as C's (and
// Python's) ``%.10g``. Throws std::domain_error for a non-finite ``t``, ``solve_ms`` or
// estimated output (a bug upstream: never written).
void append_estimate_lines(const EstimateRows& rows, std::string& out);

}  // namespace cmhe
