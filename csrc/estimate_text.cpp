#include "estimate_text.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace cmhe {

namespace {

// ``v`` as "%.10g" writes it: std::to_chars with a precision formats as printf does in
// the "C" locale, correctly rounded (the digits of Python's ``"%.10g" % v``); a negative
// zero as 0 (adding +0 turns -0 into +0 and leaves every other value as it is)
void append_number(std::string& out, double v) {
  char buf[32];
  v += 0.0;
  auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 10);
  out.append(buf, r.ptr);
}

void append_finite(std::string& out, double v, const char* what) {
  if (!std::isfinite(v))
    throw std::domain_error(std::string("refusing to write a non-finite ") + what);
  append_number(out, v);
}

// A time ``t`` (s) as "%.10g" writes it where that keeps it to half a microsecond (below
// 1e4 s it always does) or |t| >= 1e15 s, else with six decimals, trailing zeros dropped:
// a device clock past 1e6 s keeps samples a millisecond or less apart distinct
void append_time(std::string& out, double t) {
  if (!std::isfinite(t)) throw std::domain_error("refusing to write a non-finite time");
  t += 0.0;  // a negative zero as 0
  char buf[40];
  auto r = std::to_chars(buf, buf + sizeof buf, t, std::chars_format::general, 10);
  double back = 0.0;
  std::from_chars(buf, r.ptr, back);
  if (std::fabs(back - t) <= 5e-7 || std::fabs(t) >= 1e15) {
    out.append(buf, r.ptr);
    return;
  }
  r = std::to_chars(buf, buf + sizeof buf, t, std::chars_format::fixed, 6);
  const char* end = r.ptr;
  while (end > buf && end[-1] == '0') --end;
  if (end > buf && end[-1] == '.') --end;
  out.append(buf, static_cast<size_t>(end - buf));
}

}  // namespace

void append_estimate_lines(const EstimateRows& rows, std::string& out) {
  const size_t n = rows.n, ny = rows.ny;
  if (rows.status->size() != n) throw std::invalid_argument("one status per sample needed");
  out.reserve(out.size() + n * (24 + 26 * ny));
  for (size_t i = 0; i < n; ++i) {
    append_time(out, rows.t[i]);
    out.push_back(',');
    const double* y = rows.output + i * ny;
    const double* s = rows.output_std + i * ny;
    if (rows.estimated[i]) {
      for (size_t j = 0; j < ny; ++j) {
        append_finite(out, y[j], "output");
        out.push_back(',');
      }
      for (size_t j = 0; j < ny; ++j) {
        if (std::isfinite(s[j])) append_number(out, s[j]);
        out.push_back(',');
      }
    } else {
      out.append(2 * ny, ',');
    }
    if (rows.outlier != nullptr) {
      out.push_back(rows.outlier[i] ? '1' : '0');
      out.push_back(',');
    }
    out += (*rows.status)[i];
    out.push_back(',');
    append_finite(out, rows.solve_ms[i], "solve time");
    out.push_back('\n');
  }
}

}  // namespace cmhe
