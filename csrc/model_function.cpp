#include "model_function.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "forward.hpp"

namespace cmhe {

namespace {
void check_proc(const MeasurementPiece& meas, const Tape& proc) {
  if (proc.input_sizes().size() != 4 || proc.output_sizes().size() != 2)
    throw std::invalid_argument("proc must map (x, xn, u, dt) to (w, fj)");
  if (proc.input_sizes()[0] != meas.nx)
    throw std::invalid_argument("meas and proc disagree on the state size");
}
}  // namespace

MeasurementPiece::MeasurementPiece(const Tape& meas) : tape(meas), forward(false) {
  if (meas.input_sizes().size() != 3 || meas.output_sizes().size() != 3)
    throw std::invalid_argument("meas must map (x, z, m) to (r, jr, sr)");
  nx = meas.input_sizes()[0];
  nz = meas.input_sizes()[1];
  nr = meas.output_sizes()[0];
  njr = meas.output_sizes()[1];
  nsr = meas.output_sizes()[2];
}

MeasurementPiece::MeasurementPiece(const Tape& residual, int64_t sr_size)
    : tape(residual), forward(true) {
  if (residual.input_sizes().size() != 2 || residual.output_sizes().size() != 1)
    throw std::invalid_argument("the residual must map (x, z) to r");
  if (sr_size < 0) throw std::invalid_argument("sr_size must be nonnegative");
  nx = residual.input_sizes()[0];
  nz = residual.input_sizes()[1];
  nr = residual.output_sizes()[0];
  if (nr != nz) throw std::invalid_argument("the residual must have one entry per measurement");
  njr = nr * nx;
  nsr = sr_size;
  check_forward(residual);
  plan = plan_forward(residual, 0);
}

void MeasurementPiece::evaluate(const double* x, const double* z, const double* m, double* r,
                                double* jr, double* sr) const {
  if (!forward) {
    const double* args[3] = {x, z, m};
    double* res[3] = {r, jr, sr};
    tape.evaluate(args, res);
    return;
  }
  const double* args[2] = {x, z};
  double* vals[1] = {r};
  double* jac[1] = {jr};
  evaluate_forward(tape, plan, args, vals, jac);
  for (int64_t i = 0; i < nr; ++i) {  // as the symbolic piece: m r and its Jacobian
    const double mi = m ? m[i] : 0.0;
    r[i] *= mi;
    for (int64_t j = 0; j < nx; ++j) jr[i * nx + j] *= mi;
  }
  if (sr) std::fill(sr, sr + nsr, 0.0);
}

void MeasurementPiece::evaluate_batch(const double* X, const double* Z, const double* M,
                                      double* R, double* JR, double* SR, int64_t count) const {
  if (!forward) {
    const double* args[3] = {X, Z, M};
    const int64_t stride[3] = {nx, nz, nz};
    double* res[3] = {R, JR, SR};
    const int64_t res_stride[3] = {nr, njr, nsr};
    tape.evaluate_batch(args, stride, res, res_stride, count);
    return;
  }
  for (int64_t k = 0; k < count; ++k)
    evaluate(X + k * nx, Z + k * nz, M + k * nz, R + k * nr, JR + k * njr, SR + k * nsr);
}

WindowFunction::WindowFunction(const MeasurementPiece& meas, const Tape& proc, int64_t horizon)
    : meas_(meas), proc_(proc), n_(horizon) {
  check_proc(meas, proc);
  if (horizon < 2) throw std::invalid_argument("a window has at least 2 nodes");
  nu_ = proc.input_sizes()[2];
  nw_ = proc.output_sizes()[0];
  nfj_ = proc.output_sizes()[1];
}

int64_t WindowFunction::output_size() const {
  return n_ * (meas_.nr + meas_.njr + meas_.nsr) + (n_ - 1) * (nw_ + nfj_);
}

int WindowFunction::evaluate(const double* const* in, double* out) const {
  const double *X = in[0], *Z = in[1], *M = in[2], *U = in[3], *DT = in[4];
  const int64_t nx = meas_.nx;
  double* R = out;
  double* JR = R + n_ * meas_.nr;
  double* W = JR + n_ * meas_.njr;
  double* FJ = W + (n_ - 1) * nw_;
  double* SR = FJ + (n_ - 1) * nfj_;
  // every node's measurement terms, then every stage's process terms, each as one batch
  meas_.evaluate_batch(X, Z, M, R, JR, SR, n_);
  const double* pargs[4] = {X, X + nx, nu_ ? U : nullptr, DT};
  const int64_t pstride[4] = {nx, nx, nu_, 1};
  double* pres[2] = {W, FJ};
  const int64_t pres_stride[2] = {nw_, nfj_};
  proc_.evaluate_batch(pargs, pstride, pres, pres_stride, n_ - 1);
  return 0;
}

TailFunction::TailFunction(const MeasurementPiece& meas, const Tape& proc)
    : meas_(meas), proc_(proc) {
  check_proc(meas, proc);
  nw_ = proc.output_sizes()[0];
  nfj_ = proc.output_sizes()[1];
}

int64_t TailFunction::output_size() const {
  return meas_.nr + meas_.njr + meas_.nsr + nw_ + nfj_;
}

int TailFunction::evaluate(const double* const* in, double* out) const {
  // inputs (x_prev, x, z, m, u, dt); outputs r, JR, W, FJ, SR
  const int64_t nr = meas_.nr, njr = meas_.njr;
  meas_.evaluate(in[1], in[2], in[3], out, out + nr, out + nr + njr + nw_ + nfj_);
  const double* pargs[4] = {in[0], in[1], in[4], in[5]};
  double* pres[2] = {out + nr + njr, out + nr + njr + nw_};
  proc_.evaluate(pargs, pres);
  return 0;
}

}  // namespace cmhe

namespace cmhe {

namespace {
// an evaluation of a RememberedFunction kept on this thread: its function's id, inputs
// (each input's presence, then its values) and outputs
struct LastEvaluation {
  uint64_t id = 0;
  std::vector<double> in, out;
};
// the last two evaluations on this thread (two filters stepping one model side by side,
// then a check at either's prediction), and which of them is the latest
thread_local std::array<LastEvaluation, 2> last_evaluations;
thread_local int latest_evaluation = 0;
std::atomic<uint64_t> next_remembered_id{1};
}  // namespace

RememberedFunction::RememberedFunction(const ModelFunction& inner,
                                       std::vector<int64_t> input_sizes)
    : inner_(inner), input_sizes_(std::move(input_sizes)), id_(next_remembered_id++) {
  for (int64_t n : input_sizes_) {
    if (n < 0) throw std::invalid_argument("an input size is negative");
    inputs_ += 1 + n;
  }
}

bool RememberedFunction::same_inputs(const double* kept, const double* const* in) const {
  for (size_t i = 0; i < input_sizes_.size(); ++i) {
    const int64_t n = input_sizes_[i];
    const bool present = in[i] != nullptr;
    if ((*kept++ != 0.0) != present) return false;
    if (present && std::memcmp(kept, in[i], n * sizeof(double)) != 0) return false;
    kept += n;
  }
  return true;
}

int RememberedFunction::evaluate(const double* const* in, double* out) const {
  const int64_t nout = inner_.output_size();
  for (int k : {latest_evaluation, 1 - latest_evaluation}) {
    const LastEvaluation& kept = last_evaluations[k];
    if (kept.id == id_ && same_inputs(kept.in.data(), in)) {
      std::memcpy(out, kept.out.data(), nout * sizeof(double));
      latest_evaluation = k;
      hits_.fetch_add(1, std::memory_order_relaxed);
      return 0;
    }
  }
  // the older one gives way; the inputs are kept before the evaluation (an output may
  // overwrite an input)
  const int k = 1 - latest_evaluation;
  LastEvaluation& last = last_evaluations[k];
  last.id = 0;
  last.in.resize(inputs_);
  double* kept = last.in.data();
  for (size_t i = 0; i < input_sizes_.size(); ++i) {
    const int64_t n = input_sizes_[i];
    *kept++ = in[i] ? 1.0 : 0.0;
    if (in[i])
      std::memcpy(kept, in[i], n * sizeof(double));
    else
      std::fill(kept, kept + n, 0.0);
    kept += n;
  }
  const int status = inner_.evaluate(in, out);
  if (status != 0) return status;
  last.out.assign(out, out + nout);
  last.id = id_;
  latest_evaluation = k;
  return 0;
}

MaskedResidualFunction::MaskedResidualFunction(const Tape& residual) : residual_(residual) {
  if (residual.input_sizes().size() != 2 || residual.output_sizes().size() != 1 ||
      residual.output_sizes()[0] != residual.input_sizes()[1])
    throw std::invalid_argument("the residual must map (x, z) to r, one entry per measurement");
  nz_ = residual.output_sizes()[0];
}

int MaskedResidualFunction::evaluate(const double* const* in, double* out) const {
  const double* args[2] = {in[0], in[3]};
  double* vals[1] = {out};
  residual_.evaluate(args, vals);
  const double* m = in[4];
  for (int64_t i = 0; i < nz_; ++i) out[i] *= m ? m[i] : 0.0;
  return 0;
}

}  // namespace cmhe
