// What the symbolic stage's source files share (symbol_table.cpp, cost.cpp,
// equation_context.cpp, driver_law.cpp, derive.cpp): the bounds on exact arithmetic, the
// checks of a parsed value, and the drivers' laws. Private to the stage.
#pragma once

#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen::symbolic_detail {

// Digits of the evaluation that rounds a constant to double once (to_double, parameter_values).
constexpr long kEvalDigits = 40;

// Bounded cost (cost.cpp). GiNaC evaluates exact numbers eagerly (2^(2^40) is computed while the
// text is read, until GMP gives up and aborts the process), and derivatives of long products grow
// with the square of their length. Both are bounded before the work is done.

// The estimated size of one derivative, and of all of a model's together (a 1000-body chain's
// are about N; hostile products of 300 factors reach 1e7 and more).
constexpr double kMaxDerivativeSize = 2e5;
constexpr double kMaxDerivedSize = 5e7;
// Terms of an expanded equation (check_expansion_cost).
constexpr double kMaxExpandedTerms = 1e5;

// The cost of exact arithmetic exceeds a limit; the message says which.
struct CostError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// v with 6 significant digits, for the limits' messages.
std::string short_value(long double v);

// Cleans GiNaC's messages of their source-location suffixes.
std::string clean_message(const std::string& what);

// Refuses (CostError) a text whose powers would be too costly to read exactly, before GiNaC
// reads it.
void check_text_cost(const std::string& text);

// Exact powers that the parameters' values would make too costly (see check_power).
void check_cost(const Mechanism& m, const SymbolTable& s, const std::vector<GiNaC::numeric>& values,
                const GiNaC::ex& value, const Expr& e, const std::string& item);

// Derivatives: the size (leaves and operators of the expression tree) that d e / d x would have,
// estimated from e without building it, so a derivative too large to be worth computing is
// refused before it takes minutes and gigabytes. The product rule makes d(f1 ... fn) about n
// times the size of the product, and every function's derivative repeats its argument.
struct TreeSize {
  double size = 0, derivative = 0;
  bool depends = false;
};

TreeSize tree_size(const GiNaC::ex& e, const GiNaC::ex& x);

// Where row `component` of a constraint is written: its equation, a driver's f, or the item.
SourceLoc row_loc(const Constraint& c, int component);

// f(), with GiNaC's errors while it differentiates turned into one input error naming the item
// ("what: GiNaC's message"): GiNaC differentiates b^e through log(b) even where e is constant,
// so 0^a (a a parameter) meets a pole (the fuzzer's find; it was an internal error). Input
// errors and interrupts pass as they are.
template <class F>
auto naming_errors(const Mechanism& m, const std::string& item, SourceLoc loc,
                   const std::string& what, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const InputError&) {
    throw;
  } catch (const Interrupted&) {
    throw;
  } catch (const AnalysisError&) {
    throw;
  } catch (const UsageError&) {
    throw;
  } catch (const OutputError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;  // not the file's fault: the command line's internal error
  } catch (const std::exception& err) {
    throw InputError(m.source, item, loc, what + ": " + clean_message(err.what()));
  }
}

// A constant of the geometry, checked to evaluate to a finite number.
void check_finite(const Mechanism& m, const SymbolTable& s,
                  const std::vector<GiNaC::numeric>& values, const GiNaC::ex& value, const Expr& e,
                  const std::string& item);
// e parsed as geometry (numbers and parameters) and checked finite.
GiNaC::ex geometry_value(const Mechanism& m, const SymbolTable& s,
                         const std::vector<GiNaC::numeric>& values, const Expr& e,
                         const std::string& item);
// An expression in t or q with the parameters put in: no division by zero appears, and every
// number in it is finite (1e999 * t is not).
void check_defined_value(const Mechanism& m, const SymbolTable& s,
                         const std::vector<GiNaC::numeric>& values, const GiNaC::ex& value,
                         const Expr& e, const std::string& item);

// A spatial body's q0 (spatial_context.cpp): r0, and p from p0 (or q0) or rot0, normalized;
// in the parameters. InputError for a zero rot0 axis or |p0| < 1e-12.
std::vector<GiNaC::ex> spatial_q0(const Mechanism& m, const SymbolTable& s,
                                  const std::vector<GiNaC::numeric>& values, int body);

// Spatial files: names each point's global P.x, P.y, P.z and each vector's V.x, V.y, V.z for
// the outputs (as P__x ...: the expression reader knows no dots), and rewrites an output's text
// to use them.
void define_spatial_names(const Mechanism& m, SymbolTable& s, const SymbolicModel& model);
Expr spatial_output_text(const Mechanism& m, const Expr& e);
// A `suspension:` block's numbers (suspension.cpp): InputError for a tire radius not > 0 or a
// zero spin axis; returns design_t.
double check_suspension(const Mechanism& m, const SymbolTable& s,
                        const std::vector<GiNaC::numeric>& values);

// A driver's law in pieces, with a period, from a table or an input, as one expression
// in t (driver_law.cpp). Its boundaries are checked by driver_law_warnings, which
// derive() runs first.
GiNaC::ex driver_law(const Constraint& c, const Mechanism& m, const SymbolTable& s,
                     const std::vector<GiNaC::numeric>& values);
// Checks every driver's boundaries and seams at the local scale: a jump in f throws
// InputError; those in f' or f'' are returned as warnings. `length_scale`: the mechanism's
// (the unit of a driven length; an angle's is 1 rad).
std::vector<std::string> driver_law_warnings(const Mechanism& m, const SymbolTable& s,
                                             const std::vector<GiNaC::numeric>& values,
                                             double length_scale);

}  // namespace kinegen::codegen::symbolic_detail
