// Covariance of the MHE's estimate: the last block of the window Hessian's inverse,
// conditioned on the bounds active at the answer (continuum_mhe.estimators.fast.covariance
// describes the method).
#pragma once

#include <vector>

#include "qp.hpp"

namespace cmhe {

// Buffers of last_block_covariance, kept by a caller that computes one covariance per
// sample (resized to the window on each call, allocated only when it grows)
struct CovarianceScratch {
  QPScratch qp;
  std::vector<double> C, Li, Tn, Tb, v, tmp, last;
  std::vector<char> fixed;
};

// ``out`` (nx, nx): the last diagonal block of H^-1 for H = (D, E) (n blocks), with the
// coordinates on a box bound (within ``tol`` relative to 1 + |bound|) and the normal of
// each ball active at X (within ``tol`` of r^2) carrying no variance; false if the
// reduced Hessian is not positive definite. ``s``: the buffers.
// ``condition_balls`` false: the balls are not conditioned on (their normals keep the
// variance the readings give them), only the box bounds.
bool last_block_covariance(Index n, Index nx, const double* X, const double* D,
                           const double* E, const Feasible& fs, double tol, double* out,
                           CovarianceScratch& s, bool condition_balls = true);

// Whether a ball is active at the last node of X (within ``tol`` of r^2).
bool last_node_on_a_ball(Index n, Index nx, const double* X, const Feasible& fs, double tol);

}  // namespace cmhe
