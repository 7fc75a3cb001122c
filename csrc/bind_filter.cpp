#include "bindings.hpp"

void cmhe::bind_filter(nanobind::module_& m) { (void)m; }
