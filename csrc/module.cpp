// The compiled core of continuum-mhe (continuum_mhe._core._ext).
#include "bindings.hpp"

NB_MODULE(_ext, m) {
  m.doc() = "The compiled core of continuum-mhe: model evaluation, MHE solver, filters.";
  // model functions live in caches (build_window_model) until the interpreter exits;
  // nanobind's report of them at exit would be a false alarm on every command's stderr
  nanobind::set_leak_warnings(false);
  cmhe::bind_model(m);
  cmhe::bind_solver(m);
  cmhe::bind_filter(m);
  cmhe::bind_consistency(m);
  cmhe::bind_horizon(m);
  cmhe::bind_sensor_health(m);
  cmhe::bind_estimate_text(m);
}
