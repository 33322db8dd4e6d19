#include "kinegen/codegen/base/format.hpp"

#include <cstdio>
#include <cstdlib>

namespace kinegen::codegen {

std::string format_number(double value, NumberStyle style) {
  char buf[40];
  switch (style) {
    case NumberStyle::kExact:
      std::snprintf(buf, sizeof buf, "%.17g", value);
      return buf;
    case NumberStyle::kLiteral: {
      if (value == 0) return "0";
      // The shortest form that reads back to the same double.
      for (int digits = 15; digits <= 17; ++digits) {
        std::snprintf(buf, sizeof buf, "%.*g", digits, value);
        if (std::strtod(buf, nullptr) == value) break;
      }
      std::string s = buf;
      // Keep it a floating literal so T(...) never sees an integer that overflows int.
      if (s.find_first_of(".en") == std::string::npos) s += ".0";
      return s;
    }
    case NumberStyle::kEstimate:
      std::snprintf(buf, sizeof buf, "%.3g", value);
      return buf;
    case NumberStyle::kShort:
      std::snprintf(buf, sizeof buf, "%.4g", value);
      return buf;
    case NumberStyle::kPixels: {
      std::snprintf(buf, sizeof buf, "%.2f", value);
      const std::string s = buf;
      return s == "-0.00" ? "0.00" : s;
    }
  }
  return "";
}

std::string format_number(double value) { return format_number(value, NumberStyle::kExact); }
std::string format_double(double value) { return format_number(value, NumberStyle::kLiteral); }
std::string format_estimate(double value) { return format_number(value, NumberStyle::kEstimate); }
std::string format_time(double t) { return "t = " + format_number(t); }

}  // namespace kinegen::codegen
