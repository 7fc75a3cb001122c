#include "model_function.hpp"

#include <array>
#include <atomic>
#include <mutex>
#include <stdexcept>
#include <utility>

namespace cmhe {

namespace {

// A C function pointer carries no object: each live ModelFunction holds one of these
// slots, and the slot's own entry point calls it.
constexpr int kSlots = 1024;
std::array<std::atomic<const ModelFunction*>, kSlots> g_slots{};
std::mutex g_slot_mutex;

template <int K>
int trampoline(const double* const* in, double* out) {
  const ModelFunction* f = g_slots[K].load(std::memory_order_acquire);
  return f ? f->evaluate(in, out) : 1;
}

template <int... K>
constexpr std::array<Entry, sizeof...(K)> make_entries(std::integer_sequence<int, K...>) {
  return {&trampoline<K>...};
}

const std::array<Entry, kSlots> g_entries = make_entries(std::make_integer_sequence<int, kSlots>{});

}  // namespace

ModelFunction::ModelFunction() : slot_(-1) {
  std::lock_guard<std::mutex> lock(g_slot_mutex);
  for (int k = 0; k < kSlots; ++k) {
    if (g_slots[k].load() == nullptr) {
      g_slots[k].store(this, std::memory_order_release);
      slot_ = k;
      return;
    }
  }
  throw std::runtime_error("more than 1024 model functions alive at once");
}

ModelFunction::~ModelFunction() {
  std::lock_guard<std::mutex> lock(g_slot_mutex);
  g_slots[slot_].store(nullptr, std::memory_order_release);
}

std::uintptr_t ModelFunction::address() const {
  return reinterpret_cast<std::uintptr_t>(g_entries[slot_]);
}

namespace {
void check_pieces(const Tape& meas, const Tape& proc) {
  if (meas.input_sizes().size() != 3 || meas.output_sizes().size() != 3)
    throw std::invalid_argument("meas must map (x, z, m) to (r, jr, sr)");
  if (proc.input_sizes().size() != 4 || proc.output_sizes().size() != 2)
    throw std::invalid_argument("proc must map (x, xn, u, dt) to (w, fj)");
  if (proc.input_sizes()[0] != meas.input_sizes()[0])
    throw std::invalid_argument("meas and proc disagree on the state size");
}
}  // namespace

WindowFunction::WindowFunction(const Tape& meas, const Tape& proc, int64_t horizon)
    : meas_(meas), proc_(proc), n_(horizon) {
  check_pieces(meas, proc);
  if (horizon < 2) throw std::invalid_argument("a window has at least 2 nodes");
  nx_ = meas.input_sizes()[0];
  nz_ = meas.input_sizes()[1];
  nu_ = proc.input_sizes()[2];
  nr_ = meas.output_sizes()[0];
  njr_ = meas.output_sizes()[1];
  nsr_ = meas.output_sizes()[2];
  nw_ = proc.output_sizes()[0];
  nfj_ = proc.output_sizes()[1];
}

int64_t WindowFunction::output_size() const {
  return n_ * (nr_ + njr_ + nsr_) + (n_ - 1) * (nw_ + nfj_);
}

int WindowFunction::evaluate(const double* const* in, double* out) const {
  const double *X = in[0], *Z = in[1], *M = in[2], *U = in[3], *DT = in[4];
  double* R = out;
  double* JR = R + n_ * nr_;
  double* W = JR + n_ * njr_;
  double* FJ = W + (n_ - 1) * nw_;
  double* SR = FJ + (n_ - 1) * nfj_;
  // every node's measurement terms, then every stage's process terms, each as one batch
  const double* margs[3] = {X, Z, M};
  const int64_t mstride[3] = {nx_, nz_, nz_};
  double* mres[3] = {R, JR, SR};
  const int64_t mres_stride[3] = {nr_, njr_, nsr_};
  meas_.evaluate_batch(margs, mstride, mres, mres_stride, n_);
  const double* pargs[4] = {X, X + nx_, nu_ ? U : nullptr, DT};
  const int64_t pstride[4] = {nx_, nx_, nu_, 1};
  double* pres[2] = {W, FJ};
  const int64_t pres_stride[2] = {nw_, nfj_};
  proc_.evaluate_batch(pargs, pstride, pres, pres_stride, n_ - 1);
  return 0;
}

TailFunction::TailFunction(const Tape& meas, const Tape& proc) : meas_(meas), proc_(proc) {
  check_pieces(meas, proc);
  nr_ = meas.output_sizes()[0];
  njr_ = meas.output_sizes()[1];
  nsr_ = meas.output_sizes()[2];
  nw_ = proc.output_sizes()[0];
  nfj_ = proc.output_sizes()[1];
}

int64_t TailFunction::output_size() const { return nr_ + njr_ + nsr_ + nw_ + nfj_; }

int TailFunction::evaluate(const double* const* in, double* out) const {
  // inputs (x_prev, x, z, m, u, dt); outputs r, JR, W, FJ, SR
  const double* margs[3] = {in[1], in[2], in[3]};
  double* mres[3] = {out, out + nr_, out + nr_ + njr_ + nw_ + nfj_};
  meas_.evaluate(margs, mres);
  const double* pargs[4] = {in[0], in[1], in[4], in[5]};
  double* pres[2] = {out + nr_ + njr_, out + nr_ + njr_ + nw_};
  proc_.evaluate(pargs, pres);
  return 0;
}

}  // namespace cmhe
