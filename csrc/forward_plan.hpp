// The plan of a forward-mode evaluation of a tape (forward.hpp): which tangent entries
// each instruction can make nonzero.
#pragma once

#include <cstdint>
#include <vector>

#include "tape.hpp"

namespace cmhe {

// Which tangent entries each instruction of a tape can make nonzero, for one seed input:
// per instruction the half-open ranges ``[lo, hi)`` of the seed's entries that its value
// (``res``) and its two operands' tangents (``a``, ``b``, where the operation's derivative
// uses them) may depend on. A range holds every seed entry the value depends on
// through differentiable operations (it may hold more). A model's long shooting
// depends on a few of the state's entries (the IMUs' error states enter only at its
// end), so its tangents are propagated over those alone.
//
// A work slot's tangent is kept zero outside its value's range, so that an operation
// reads its operands over the result's whole range without tests: each instruction also
// names the entries the slot's previous value may have left nonzero (``lo_old, hi_old``:
// that value's range, or the whole tangent where the slot has not been written yet in
// this evaluation or its last write may have been skipped by a GUARD), which it clears
// outside its own range.
struct ForwardPlan {
  static constexpr int kStride = 8;  // entries of ``ranges`` per instruction
  int seed = 0;
  // per instruction: lo_res, hi_res, lo_a, hi_a, lo_b, hi_b, lo_old, hi_old
  std::vector<int32_t> ranges;
};
ForwardPlan plan_forward(const Tape& tape, int seed);

}  // namespace cmhe
