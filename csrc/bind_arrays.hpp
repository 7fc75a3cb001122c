// NumPy arrays at the bindings' edge: the input type, its size check, and new arrays
// that own their data (shared by the bind_*.cpp files).
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstring>
#include <initializer_list>
#include <stdexcept>
#include <string>

namespace cmhe {

// a C-contiguous float64 array from Python, any shape
using InArray = nanobind::ndarray<const double, nanobind::c_contig, nanobind::device::cpu>;
// a new float64 NumPy array
using NewArray = nanobind::ndarray<nanobind::numpy, double>;

// std::invalid_argument naming ``name`` unless ``a`` holds ``size`` values
inline void check_size(const InArray& a, size_t size, const char* name) {
  if (a.size() != size)
    throw std::invalid_argument(std::string(name) + " has " + std::to_string(a.size()) +
                                " values, expected " + std::to_string(size));
}

// a new array of ``shape`` that owns its (uninitialised) data
inline NewArray new_array(std::initializer_list<size_t> shape) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  double* data = new double[n > 0 ? n : 1];
  nanobind::capsule owner(data, [](void* p) noexcept { delete[] static_cast<double*>(p); });
  return NewArray(data, shape.size(), shape.begin(), owner);
}

// a new array of ``shape`` holding a copy of ``data``
inline NewArray copy_of(const double* data, std::initializer_list<size_t> shape) {
  NewArray a = new_array(shape);
  std::memcpy(a.data(), data, a.size() * sizeof(double));
  return a;
}

}  // namespace cmhe
