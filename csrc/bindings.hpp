// Each part of the core binds its own names into continuum_mhe._core (module.cpp).
#pragma once

#include <nanobind/nanobind.h>

namespace cmhe {
void bind_model(nanobind::module_& m);   // bind_model.cpp: tapes, window and tail functions
void bind_solver(nanobind::module_& m);  // bind_solver.cpp: the MHE window solve and step
void bind_filter(nanobind::module_& m);  // bind_filter.cpp: EKF step, arrival prior, outputs
void bind_consistency(nanobind::module_& m);  // bind_consistency.cpp: the consistency check
void bind_horizon(nanobind::module_& m); // bind_horizon.cpp: the fast MHE's per-sample step
void bind_sensor_health(nanobind::module_& m);  // bind_sensor_health.cpp: the policy
void bind_estimate_text(nanobind::module_& m);  // bind_estimate_text.cpp: estimate CSV lines
}  // namespace cmhe
