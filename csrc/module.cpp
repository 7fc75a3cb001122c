// The compiled core of continuum-mhe (continuum_mhe._core._ext).
#include "bindings.hpp"

NB_MODULE(_ext, m) {
  m.doc() = "The compiled core of continuum-mhe: model evaluation, MHE solver, filters.";
  cmhe::bind_model(m);
  cmhe::bind_solver(m);
  cmhe::bind_filter(m);
}
