// The motion laws as one GiNaC function, kinegen_law(law, order, x) (functions.hpp).
#include "kinegen/codegen/symbolic/functions.hpp"

#include <cln/cln.h>

#include <limits>
#include <stdexcept>
#include <string>

#include "kinegen/codegen/model/table.hpp"

namespace kinegen::codegen {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

// The largest table number: a slot's index and its generation (table.cpp).
constexpr long kMaxTableNumber = std::numeric_limits<int>::max();

// A law's number, a derivative's order, a driver's index or a table's number (up to
// `largest`).
int small_integer(const ex& e, const char* what, long largest = 1000) {
  if (!GiNaC::is_a<numeric>(e) || !GiNaC::ex_to<numeric>(e).is_integer() ||
      GiNaC::ex_to<numeric>(e).is_negative() || GiNaC::ex_to<numeric>(e) > largest)
    throw std::logic_error(std::string("kinegen_law: the ") + what + " is not a small integer");
  return GiNaC::ex_to<numeric>(e).to_int();
}

// pi at the precision of x, or of Digits when x is exact.
numeric pi_like(const numeric& x) {
  const numeric re = x.real();
  if (!re.is_rational())
    return numeric(cln::pi(cln::the<cln::cl_F>(cln::the<cln::cl_R>(re.to_cl_N()))));
  return GiNaC::ex_to<numeric>(GiNaC::Pi.evalf());
}

// The n-th derivative of cos at 0, cos(n pi / 2).
int cos_derivative_at_zero(int n) {
  static const int kValues[4] = {1, 0, -1, 0};
  return kValues[n % 4];
}

// A law's d^order/dx^order at exactly 0, its formula's value (a law is its formula
// on [0, 1)), exact: pi stays GiNaC's Pi, so that harmonic''(0) is Pi^2/2, not a float.
ex law_at_zero(int law, int order) {
  switch (law) {
    case kernels::kCycloidal:  // f' = 1 - cos(2 pi x); f^(n) = -(2 pi)^(n-1) cos^(n-1)(2 pi x)
      if (order <= 1) return 0;
      return -GiNaC::pow(2 * GiNaC::Pi, order - 1) * cos_derivative_at_zero(order - 1);
    case kernels::kHarmonic:  // f^(n) = -(pi^n / 2) cos^(n)(pi x), n >= 1
      if (order == 0) return 0;
      return -GiNaC::pow(GiNaC::Pi, order) / 2 * cos_derivative_at_zero(order);
    default:  // the polynomials: exact rationals at a rational x
      return motion_law_high_precision(law, order, 0);
  }
}

ex law_eval(const ex& law, const ex& order, const ex& x) {
  // Clamped values and those at 0 are exact; floats are evaluated, as GiNaC does for sin(0.5).
  if (GiNaC::is_a<numeric>(x) && GiNaC::ex_to<numeric>(x).is_real()) {
    const numeric v = GiNaC::ex_to<numeric>(x);
    const int l = small_integer(law, "law"), n = small_integer(order, "order");
    if (v.is_zero() && v.is_rational()) return law_at_zero(l, n);
    if (!v.is_rational() || v.is_negative() || v >= 1) return motion_law_high_precision(l, n, v);
  }
  return kinegen_law(law, order, x).hold();
}

ex law_evalf(const ex& law, const ex& order, const ex& x) {
  const ex v = x.evalf();
  if (!GiNaC::is_a<numeric>(v)) return kinegen_law(law, order, v).hold();
  return motion_law_high_precision(small_integer(law, "law"), small_integer(order, "order"),
                                   GiNaC::ex_to<numeric>(v));
}

ex law_derivative(const ex& law, const ex& order, const ex& x, unsigned diff_param) {
  // law and order are integers, never functions of anything.
  if (diff_param != 2) return 0;
  return kinegen_law(law, order + 1, x);
}

void law_print(const ex& law, const ex& order, const ex& x, const GiNaC::print_context& c) {
  const int l = small_integer(law, "law"), n = small_integer(order, "order");
  const char* name = "kinegen_law";
  for (const auto& m : kMotionLaws)
    if (m.law == l) name = m.name;
  c.s << name << std::string(static_cast<std::size_t>(n), '\'') << "(";
  x.print(c);
  c.s << ")";
}

// One reader per law (GiNaC's reader table holds plain function pointers). GiNaC tells them
// from function serials, which it stores in the same table, by their lowest bit, so they are
// aligned.
template <int kLaw>
[[gnu::aligned(16)]] ex read_law(const GiNaC::exvector& args) {
  if (args.size() != 1)  // GiNaC's message for other functions
    throw std::invalid_argument("no function \"" + std::string(kMotionLaws[kLaw].name) +
                                "\" with " + std::to_string(args.size()) + " arguments");
  return kinegen_law(kLaw, 0, args[0]);
}

}  // namespace

REGISTER_FUNCTION(kinegen_law, eval_func(law_eval)
                                   .evalf_func(law_evalf)
                                   .derivative_func(law_derivative)
                                   .print_func<GiNaC::print_context>(law_print)
                                   .do_not_evalf_params())

namespace {

// Whether a numeric argument decides a choice: real (GiNaC's numbers from parameters are).
bool decides(const ex& x) { return GiNaC::is_a<numeric>(x) && GiNaC::ex_to<numeric>(x).is_real(); }

ex select_eval(const ex& c, const ex& lo, const ex& hi) {
  if (decides(c)) return GiNaC::ex_to<numeric>(c).is_negative() ? lo : hi;
  if (lo.is_equal(hi)) return lo;
  return kinegen_select(c, lo, hi).hold();
}

ex select_evalf(const ex& c, const ex& lo, const ex& hi) {
  return select_eval(c.evalf(), lo.evalf(), hi.evalf());
}

ex select_derivative(const ex& c, const ex& lo, const ex& hi, const GiNaC::symbol& s) {
  return kinegen_select(c, lo.diff(s), hi.diff(s));
}

void select_print(const ex& c, const ex& lo, const ex& hi, const GiNaC::print_context& pc) {
  pc.s << "select(";
  c.print(pc);
  pc.s << " < 0, ";
  lo.print(pc);
  pc.s << ", ";
  hi.print(pc);
  pc.s << ")";
}

ex floor_eval(const ex& x) {
  if (decides(x)) {
    const numeric v = GiNaC::ex_to<numeric>(x);
    if (v.is_rational()) return numeric(cln::floor1(cln::the<cln::cl_RA>(v.to_cl_N())));
    return numeric(cln::floor1(cln::the<cln::cl_R>(v.to_cl_N())));
  }
  return kinegen_floor(x).hold();
}

ex floor_evalf(const ex& x) { return floor_eval(x.evalf()); }

ex floor_derivative(const ex&, unsigned) { return 0; }

ex table_eval(const ex& id, const ex& order, const ex& x) {
  if (decides(x) && !GiNaC::ex_to<numeric>(x).is_rational()) {
    double f[3];
    const Spline& s = registered_table(small_integer(id, "table", kMaxTableNumber));
    const int n = small_integer(order, "order");
    if (n > 2 || !s.eval(GiNaC::ex_to<numeric>(x).to_double(), f))
      return numeric(std::numeric_limits<double>::quiet_NaN());
    return numeric(f[n]);
  }
  return kinegen_table(id, order, x).hold();
}

ex table_evalf(const ex& id, const ex& order, const ex& x) {
  const ex v = x.evalf();
  if (!decides(v)) return kinegen_table(id, order, v).hold();
  return table_eval(id, order,
                    GiNaC::ex_to<numeric>(v).is_rational()
                        ? ex(numeric(GiNaC::ex_to<numeric>(v).to_double()))
                        : v);
}

ex table_derivative(const ex& id, const ex& order, const ex& x, unsigned diff_param) {
  if (diff_param != 2) return 0;
  return kinegen_table(id, order + 1, x);
}

void table_print(const ex& id, const ex& order, const ex& x, const GiNaC::print_context& c) {
  c.s << "table" << small_integer(id, "table", kMaxTableNumber)
      << std::string(static_cast<std::size_t>(small_integer(order, "order")), '\'') << "(";
  x.print(c);
  c.s << ")";
}

ex input_derivative(const ex& driver, const ex& order, const ex& x, unsigned diff_param) {
  if (diff_param != 2) return 0;
  return kinegen_input(driver, order + 1, x);
}

void input_print(const ex& driver, const ex& order, const ex& x, const GiNaC::print_context& c) {
  c.s << "input" << small_integer(driver, "driver")
      << std::string(static_cast<std::size_t>(small_integer(order, "order")), '\'') << "(";
  x.print(c);
  c.s << ")";
}

}  // namespace

REGISTER_FUNCTION(kinegen_select, eval_func(select_eval)
                                      .evalf_func(select_evalf)
                                      .expl_derivative_func(select_derivative)
                                      .print_func<GiNaC::print_context>(select_print))
REGISTER_FUNCTION(kinegen_floor,
                  eval_func(floor_eval).evalf_func(floor_evalf).derivative_func(floor_derivative))
REGISTER_FUNCTION(kinegen_table, eval_func(table_eval)
                                     .evalf_func(table_evalf)
                                     .derivative_func(table_derivative)
                                     .print_func<GiNaC::print_context>(table_print)
                                     .do_not_evalf_params())

REGISTER_FUNCTION(kinegen_input, derivative_func(input_derivative)
                                     .print_func<GiNaC::print_context>(input_print)
                                     .do_not_evalf_params())

bool is_input(const ex& e, int& driver, int& order) {
  if (!GiNaC::is_a<GiNaC::function>(e) ||
      GiNaC::ex_to<GiNaC::function>(e).get_serial() != kinegen_input_SERIAL::serial)
    return false;
  driver = small_integer(e.op(0), "driver");
  order = small_integer(e.op(1), "order");
  return true;
}

bool is_select(const ex& e) {
  return GiNaC::is_a<GiNaC::function>(e) &&
         GiNaC::ex_to<GiNaC::function>(e).get_serial() == kinegen_select_SERIAL::serial;
}

bool is_floor(const ex& e) {
  return GiNaC::is_a<GiNaC::function>(e) &&
         GiNaC::ex_to<GiNaC::function>(e).get_serial() == kinegen_floor_SERIAL::serial;
}

bool is_table(const ex& e, int& id, int& order) {
  if (!GiNaC::is_a<GiNaC::function>(e) ||
      GiNaC::ex_to<GiNaC::function>(e).get_serial() != kinegen_table_SERIAL::serial)
    return false;
  id = small_integer(e.op(0), "table", kMaxTableNumber);
  order = small_integer(e.op(1), "order");
  return true;
}

bool is_motion_law(const ex& e, int& law, int& order) {
  if (!GiNaC::is_a<GiNaC::function>(e) ||
      GiNaC::ex_to<GiNaC::function>(e).get_serial() != kinegen_law_SERIAL::serial)
    return false;
  law = small_integer(e.op(0), "law");
  order = small_integer(e.op(1), "order");
  return true;
}

numeric motion_law_high_precision(int law, int order, const numeric& x) {
  // The formula on [0, 1), clamped outside it; the branch on the real part.
  const numeric re = x.real();
  if (re.is_negative()) return 0;
  if (re >= 1) return order == 0 ? 1 : 0;
  const numeric pi = pi_like(x);
  // n-th derivative of cos at w: cos(w + n pi / 2), exactly by quadrant.
  const auto cos_derivative = [](int n, const numeric& w) -> numeric {
    switch (n % 4) {
      case 0:
        return GiNaC::cos(w);
      case 1:
        return -GiNaC::sin(w);
      case 2:
        return -GiNaC::cos(w);
      default:
        return GiNaC::sin(w);
    }
  };
  switch (law) {
    case kernels::kCycloidal: {
      const numeric w = 2 * pi * x;
      if (order == 0) return x - GiNaC::sin(w) / (2 * pi);
      if (order == 1) return 1 - GiNaC::cos(w);
      return -(2 * pi).power(order - 1) * cos_derivative(order - 1, w);
    }
    case kernels::kHarmonic: {
      const numeric w = pi * x;
      if (order == 0) return (1 - GiNaC::cos(w)) / 2;
      return -pi.power(order) / 2 * cos_derivative(order, w);
    }
    case kernels::kPoly345:
    case kernels::kPoly4567: {
      numeric c[8] = {0, 0, 0, 0, 0, 0, 0, 0};
      if (law == kernels::kPoly345) {
        c[3] = 10, c[4] = -15, c[5] = 6;
      } else {
        c[4] = 35, c[5] = -84, c[6] = 70, c[7] = -20;
      }
      if (order > 7) return 0;
      for (int d = 0; d < order; ++d) {
        for (int k = 0; k < 7; ++k) c[k] = c[k + 1] * (k + 1);
        c[7] = 0;
      }
      numeric v = c[7];
      for (int k = 6; k >= 0; --k) v = v * x + c[k];
      return v;
    }
  }
  throw std::logic_error("kinegen_law: unknown law " + std::to_string(law));
}

void add_motion_law_readers(GiNaC::prototype_table& table) {
  for (int k = 0; k < 4; ++k)  // read_law<k> names itself by kMotionLaws[k]
    if (kMotionLaws[k].law != k) throw std::logic_error("kMotionLaws is not in law order");
  const GiNaC::reader_func readers[] = {read_law<0>, read_law<1>, read_law<2>, read_law<3>};
  for (const auto& l : kMotionLaws) table[{l.name, 1}] = readers[l.law];
}

}  // namespace kinegen::codegen
