// A formulation's process noise Q(dt) and its inverse from the tape of its covariance
// (continuum_mhe.estimators.process_noise): what every estimator's prediction and the
// MHE's process weights take, in compiled code for any time step.
#pragma once

#include <vector>

#include "model_function.hpp"

namespace cmhe {

class ProcessNoise {
 public:
  // ``q``: dt (s) -> Q (nx, nx), dense, one input of one value; ``held``: states without
  // process noise, whose rows and columns of Q and Q^-1 are zero (Q^-1 elsewhere that of
  // the whole Q). ``q`` must outlive this object.
  ProcessNoise(const TapeFunction& q, int nx, std::vector<int> held);
  // Q and Q^-1 (nx, nx each) of a step of ``dt`` s, Q^-1 from Q's Cholesky factor; false
  // where Q is not positive definite to the factorisation (Q written, Q^-1 not)
  bool compute(double dt, double* Q, double* Qinv) const;
  int nx;

 private:
  const TapeFunction& q_;
  std::vector<int> held_;
};

}  // namespace cmhe
