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
struct ForwardPlan {
  int seed = 0;
  std::vector<int32_t> ranges;  // per instruction: lo_res, hi_res, lo_a, hi_a, lo_b, hi_b
};
ForwardPlan plan_forward(const Tape& tape, int seed);

}  // namespace cmhe
