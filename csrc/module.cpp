// The compiled core of continuum-mhe (continuum_mhe._core).
#include "bindings.hpp"

NB_MODULE(_core, m) {
  m.doc() = "The compiled core of continuum-mhe: model evaluation, MHE solver, filters.";
  cmhe::bind_model(m);
  cmhe::bind_solver(m);
  cmhe::bind_filter(m);
}
