// The functions of the expression language, each once: its name (in mechanism files, in
// GiNaC's reader and in generated C++ as std::<name>), the operation the program stage lowers
// it to, its value in CLN arithmetic (the reference) and, in apply_function below, in the std
// arithmetic of the evaluator's scalar types. GiNaC's function of the same name is the one the
// parser builds (symbol_table.cpp takes it from GiNaC's reader table by this name).
//
// The motion laws (cycloidal, ...) are apart: each is one GiNaC function kinegen_law(law,
// order, x), the order-th derivative of the law, so that differentiating stays in the family.
#pragma once

#include <ginac/ginac.h>

#include <cmath>
#include <complex>
#include <string>

#include "kinegen/codegen/program/program.hpp"
#include "kinegen/kernels/motion_law.hpp"

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

// The built-in motion laws: `name(x)` in an expression is kinegen_law(law, 0, x),
// law the kernel's number (kernels/motion_law.hpp).
struct MotionLawName {
  const char* name;
  int law;
};

inline const MotionLawName kMotionLaws[] = {
    {"cycloidal", kernels::kCycloidal},
    {"harmonic", kernels::kHarmonic},
    {"poly345", kernels::kPoly345},
    {"poly4567", kernels::kPoly4567},
};

// The law called `name`, or -1.
inline int find_motion_law(const std::string& name) {
  for (const auto& l : kMotionLaws)
    if (name == l.name) return l.law;
  return -1;
}

// d^order/dx^order of a law at x, as a GiNaC function (law and order exact integers): its
// derivative in x is kinegen_law(law, order + 1, x); evalf gives the value at the precision of
// x (or Digits), exact for the polynomials at rational x; it prints as `poly345''(x)`.
DECLARE_FUNCTION_3P(kinegen_law)

// Whether `e` is a kinegen_law(law, order, x); then law and order are set.
bool is_motion_law(const GiNaC::ex& e, int& law, int& order);

// The law's value in CLN arithmetic at the precision of x (the reference; an exact x gets the
// current Digits, the polynomials stay exact). The formula on [0, 1), clamped outside it (a
// value at 0 or 1 is the limit from the right), chosen on the real part, like the kernel.
GiNaC::numeric motion_law_high_precision(int law, int order, const GiNaC::numeric& x);

// The parser's readers of the laws' names, one argument each (symbol_table.cpp).
void add_motion_law_readers(GiNaC::prototype_table& table);

// Drivers in pieces: kinegen_select(c, lo, hi) is lo while the real part of c is
// below 0, else hi (c = t - until: a time at a boundary takes the later piece). Its derivative
// in any symbol is kinegen_select(c, lo', hi'): each piece is differentiated on its own, and
// the boundary's own jump is not (the continuity check warns of it). Prints as
// `select(c < 0, lo, hi)`.
DECLARE_FUNCTION_3P(kinegen_select)
// Whole periods: floor of the real part of x, derivative 0 (`t - T floor(t/T)` wraps t into
// [0, T) and keeps the complex step's imaginary part).
DECLARE_FUNCTION_1P(kinegen_floor)
// A table's spline (table.hpp's registry; id its number there): d^order/dx^order at x (order
// 0..2), its derivative in x raising the order; the value at a real number is the spline's.
DECLARE_FUNCTION_3P(kinegen_table)

// A run-time input driver (`f: input`): d^order/dt^order of driver `driver`'s commanded
// value at t; its derivative in t raises the order. Never evaluated here: generated
// code reads it from Params, and `analyze --input` replaces the driver by a table.
DECLARE_FUNCTION_3P(kinegen_input)

bool is_select(const GiNaC::ex& e);
// Whether `e` is a kinegen_input(driver, order, t); then driver and order are set.
bool is_input(const GiNaC::ex& e, int& driver, int& order);
bool is_floor(const GiNaC::ex& e);
// Whether `e` is a kinegen_table(id, order, x); then id and order are set.
bool is_table(const GiNaC::ex& e, int& id, int& order);

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
