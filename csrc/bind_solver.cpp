#include "bindings.hpp"

void cmhe::bind_solver(nanobind::module_& m) { (void)m; }
