// The functions of the expression language, each once: its name (in mechanism files, in
// GiNaC's reader and in generated C++ as std::<name>), the operation the program stage lowers
// it to, its value in CLN arithmetic (the reference) and, in apply_function below, in the std
// arithmetic of the evaluator's scalar types. GiNaC's function of the same name is the one the
// parser builds (symbolic.cpp takes it from GiNaC's reader table by this name).
#pragma once

#include <ginac/ginac.h>

#include <cmath>
#include <complex>
#include <string>

#include "kinegen/codegen/program.hpp"

namespace kinegen::codegen {

struct MathFunction {
  const char* name;
  OpKind op;
  GiNaC::numeric (*high_precision)(const GiNaC::numeric& x);
  // Real only on part of the real line: the reference checks each value it computes.
  bool partial;
};

inline const MathFunction kMathFunctions[] = {
    {"sqrt", OpKind::kSqrt, [](const GiNaC::numeric& x) { return GiNaC::sqrt(x); }, true},
    {"sin", OpKind::kSin, [](const GiNaC::numeric& x) { return GiNaC::sin(x); }, false},
    {"cos", OpKind::kCos, [](const GiNaC::numeric& x) { return GiNaC::cos(x); }, false},
    {"tan", OpKind::kTan, [](const GiNaC::numeric& x) { return GiNaC::tan(x); }, false},
    {"asin", OpKind::kAsin, [](const GiNaC::numeric& x) { return GiNaC::asin(x); }, true},
    {"acos", OpKind::kAcos, [](const GiNaC::numeric& x) { return GiNaC::acos(x); }, true},
    {"atan", OpKind::kAtan, [](const GiNaC::numeric& x) { return GiNaC::atan(x); }, false},
    {"exp", OpKind::kExp, [](const GiNaC::numeric& x) { return GiNaC::exp(x); }, false},
    {"log", OpKind::kLog, [](const GiNaC::numeric& x) { return GiNaC::log(x); }, true},
};

// The function called `name` (one argument), or nullptr.
inline const MathFunction* find_math_function(const std::string& name) {
  for (const auto& f : kMathFunctions)
    if (name == f.name) return &f;
  return nullptr;
}

// The function lowered to `op`, or nullptr when op is not a function.
inline const MathFunction* math_function(OpKind op) {
  for (const auto& f : kMathFunctions)
    if (op == f.op) return &f;
  return nullptr;
}

// std::<name>(x) for a function's `op`, on any scalar type with std overloads (double, float,
// std::complex); one case per row of kMathFunctions.
template <class T>
T apply_function(OpKind op, const T& x) {
  using std::acos, std::asin, std::atan, std::cos, std::exp, std::log, std::sin, std::sqrt,
      std::tan;
  switch (op) {
    case OpKind::kSqrt:
      return sqrt(x);
    case OpKind::kSin:
      return sin(x);
    case OpKind::kCos:
      return cos(x);
    case OpKind::kTan:
      return tan(x);
    case OpKind::kAsin:
      return asin(x);
    case OpKind::kAcos:
      return acos(x);
    case OpKind::kAtan:
      return atan(x);
    case OpKind::kExp:
      return exp(x);
    case OpKind::kLog:
      return log(x);
    default:
      return x;  // not a function (the caller's switch handles every other kind)
  }
}

}  // namespace kinegen::codegen
