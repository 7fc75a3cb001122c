// A window of rows that slides by one row without moving the others (horizon.hpp's
// process noise, sqp.hpp's stage products).
#pragma once

#include <algorithm>
#include <cstring>
#include <vector>

#include "btd.hpp"

namespace cmhe {

// ``rows`` rows of ``row`` values, contiguous at data(). The storage holds twice the
// rows and the window moves along it: slide() drops the first row and opens a new last
// one (holding stale values, for the caller to write) by moving the window's start, and
// copies the window's rows back to the storage's start only when it reaches the end
// (once every ``rows`` slides).
class SlidingRows {
 public:
  void assign(Index rows, Index row, double value) {
    rows_ = rows;
    row_ = row;
    start_ = 0;
    buf_.assign(2 * rows * row, value);
  }
  void fill(double value) {
    std::fill(buf_.begin(), buf_.end(), value);
    start_ = 0;
  }
  double* data() { return buf_.data() + start_ * row_; }
  const double* data() const { return buf_.data() + start_ * row_; }
  // rows [0, rows - 1) take rows [1, rows); row rows - 1 is stale
  void slide() {
    if (rows_ == 0) return;
    if (start_ < rows_) {
      ++start_;
      return;
    }
    std::memmove(buf_.data(), data() + row_, (rows_ - 1) * row_ * sizeof(double));
    start_ = 0;
  }

 private:
  std::vector<double> buf_;
  Index rows_ = 0, row_ = 0, start_ = 0;
};

}  // namespace cmhe
