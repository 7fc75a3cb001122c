#include "process_noise.hpp"

#include <stdexcept>
#include <string>
#include <utility>

#include "filter.hpp"

namespace cmhe {

ProcessNoise::ProcessNoise(const TapeFunction& q, int nx_, std::vector<int> held)
    : nx(nx_), q_(q), held_(std::move(held)) {
  if (q_.tape().input_sizes() != std::vector<int64_t>{1})
    throw std::invalid_argument("the process noise function takes one input, dt (one value)");
  if (q_.output_size() != int64_t(nx) * nx)
    throw std::invalid_argument("the process noise function writes " +
                                std::to_string(q_.output_size()) + " values, expected nx^2");
  for (int i : held_)
    if (i < 0 || i >= nx) throw std::invalid_argument("a held state outside the state");
}

bool ProcessNoise::compute(double dt, double* Q, double* Qinv) const {
  const double* in[] = {&dt};
  if (q_.evaluate(in, Q) != 0) return false;
  const size_t n2 = size_t(nx) * nx;
  std::vector<double> L(n2);
  if (!small::cholesky(Q, L.data(), nx)) return false;
  small::inverse_gram(L.data(), Qinv, nx);
  for (int h : held_)
    for (int k = 0; k < nx; ++k)
      for (double* a : {Q, Qinv}) {
        a[h * nx + k] = 0.0;
        a[k * nx + h] = 0.0;
      }
  return true;
}

}  // namespace cmhe
