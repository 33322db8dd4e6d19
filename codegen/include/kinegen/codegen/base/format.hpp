// How kinegen prints a double: every number that reaches a user, a file or generated code goes
// through format_number, in one of a few styles.
#pragma once

#include <string>

namespace kinegen::codegen {

enum class NumberStyle {
  kExact,     // 17 significant digits (%.17g): CSV, JSON, messages; reads back to the same double
  kLiteral,   // the shortest text that reads back to the same double, always a floating literal
              // ("0.1", "2.0", "1e+300"): generated code
  kEstimate,  // three significant digits: condition numbers, step sizes
  kShort,     // four significant digits: titles
  kPixels,    // two decimals, never "-0.00": SVG coordinates
};

std::string format_number(double value, NumberStyle style);
// kExact.
std::string format_number(double value);
// kLiteral, the emitter's name for it.
std::string format_double(double value);
// kEstimate.
std::string format_estimate(double value);
// How messages name a time: "t = " and the time in kExact.
std::string format_time(double t);

}  // namespace kinegen::codegen
