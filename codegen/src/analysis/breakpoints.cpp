// Breakpoints of a simulation (analysis/breakpoints.hpp): the times where a driver's or a
// load's function of t is not smooth, found on the expressions.
#include "kinegen/codegen/analysis/breakpoints.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <string>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

[[noreturn]] void too_many(double t0, double t1) {
  throw UsageError("more than " + std::to_string(kMaxBreakpoints) +
                   " breakpoints (piece boundaries, period seams, motion laws' ends, table "
                   "knots) in [" +
                   format_number(t0) + ", " + format_number(t1) +
                   "]: a period or a table far finer than the run; shorten the run");
}

using Levels = BreakpointLevels;

// Which calls are smooth only piecewise: their argument and its levels; false for others.
bool nonsmooth_call(const ex& e, ex& argument, Levels& levels) {
  int id = 0, order = 0;
  if (is_select(e)) {
    argument = e.op(0);
    levels.base = {0};
    return true;
  }
  if (is_floor(e)) {
    argument = e.op(0);
    levels.base = {0};
    levels.period = 1;
    return true;
  }
  if (is_motion_law(e, id, order)) {
    argument = e.op(2);
    levels.base = {0, 1};
    return true;
  }
  if (is_table(e, id, order)) {
    argument = e.op(2);
    const Spline& s = registered_table(id);
    levels.base = s.t;
    if (s.periodic) levels.period = s.period;
    return true;
  }
  return false;
}

// Fixes every floor and select of an expression to its value at time `at` (a time inside one
// smooth piece of the expression, so the same all over that piece).
class Freeze : public GiNaC::map_function {
 public:
  Freeze(const ex& t, const numeric& at) : t_(t), at_(at) {}
  ex operator()(const ex& e) override {
    if (is_select(e)) {
      const numeric c = value(e.op(0).map(*this));
      return (c.real().is_negative() ? e.op(1) : e.op(2)).map(*this);
    }
    if (is_floor(e)) return kinegen_floor(value(e.op(0).map(*this)));
    return e.map(*this);
  }

 private:
  numeric value(const ex& e) const {
    const ex v = GiNaC::evalf(e.subs(t_ == at_));
    if (!GiNaC::is_a<numeric>(v)) return 0;
    return GiNaC::ex_to<numeric>(v);
  }
  ex t_;
  numeric at_;
};

class Finder {
 public:
  Finder(const ex& t, double t0, double t1) : t_(t), t0_(t0), t1_(t1) {}

  // Every breakpoint of e in [t0, t1] (with duplicates) into out.
  void of(const ex& e, std::vector<double>& out) {
    std::set<ex, GiNaC::ex_is_less> calls;
    for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it) {
      ex argument;
      Levels levels;
      if (nonsmooth_call(*it, argument, levels)) calls.insert(*it);
    }
    for (const ex& call : calls) {
      const std::vector<double>& times = of_call(call);
      out.insert(out.end(), times.begin(), times.end());
      if (out.size() > 4 * kMaxBreakpoints) too_many(t0_, t1_);
    }
  }

 private:
  const std::vector<double>& of_call(const ex& call) {
    const auto found = memo_.find(call);
    if (found != memo_.end()) return found->second;
    std::vector<double> times;
    ex argument;
    Levels levels;
    nonsmooth_call(call, argument, levels);
    if (depends_on_t_alone(argument)) {
      // The argument's own breakpoints are the call's too (a law of a wrapped time).
      of(argument, times);
      crossings(argument, levels, times);
    }
    return memo_.emplace(call, std::move(times)).first->second;
  }

  bool depends_on_t_alone(const ex& e) const {
    bool has_t = false;
    for (auto it = e.preorder_begin(); it != e.preorder_end(); ++it)
      if (GiNaC::is_a<GiNaC::symbol>(*it)) {
        if (!it->is_equal(t_)) return false;  // the state: events, not breakpoints
        has_t = true;
      }
    return has_t;
  }

  // The times in [t0, t1] where g crosses a level, into out (g's own breakpoints are there).
  void crossings(const ex& g, const Levels& levels, std::vector<double>& out) {
    std::vector<double> cuts;
    of(g, cuts);
    cuts.push_back(t0_);
    cuts.push_back(t1_);
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
      const double a = cuts[k], b = cuts[k + 1];
      if (!(a >= t0_ && b <= t1_ && b > a)) continue;
      Freeze freeze(t_, exact_numeric(a + (b - a) / 2));
      const ex piece = g.map(freeze);
      piece_crossings(piece, levels, a, b, out);
    }
  }

  void piece_crossings(const ex& g, const Levels& levels, double a, double b,
                       std::vector<double>& out) {
    const GiNaC::symbol& t = GiNaC::ex_to<GiNaC::symbol>(t_);
    const ex expanded = g.expand();
    if (expanded.is_polynomial(t) && expanded.degree(t) <= 1) {
      // evalf: a constant such as Pi in a coefficient is a number too; a coefficient that is
      // still no number (or not real) is found by sampling below, never skipped.
      const ex slope = expanded.coeff(t, 1).evalf(), offset = expanded.coeff(t, 0).evalf();
      const bool exact = GiNaC::is_a<numeric>(slope) && GiNaC::is_a<numeric>(offset) &&
                         GiNaC::ex_to<numeric>(slope).is_real() &&
                         GiNaC::ex_to<numeric>(offset).is_real();
      if (exact) return linear_crossings(GiNaC::ex_to<numeric>(slope),
                                         GiNaC::ex_to<numeric>(offset), levels, a, b, out);
    }
    sampled_crossings(g, levels, a, b, out);
  }

  // A linear g = s t + c: its crossings of each level, exactly.
  void linear_crossings(const numeric& s, const numeric& c, const Levels& levels, double a,
                        double b, std::vector<double>& out) {
    if (s.is_zero()) return;
    const double ga = (s * exact_numeric(a) + c).to_double();
    const double gb = (s * exact_numeric(b) + c).to_double();
    std::vector<double> hit;
    levels.within(std::min(ga, gb), std::max(ga, gb), hit);
    for (double level : hit) {
      const double time = ((exact_numeric(level) - c) / s).to_double();
      if (time >= a && time <= b) out.push_back(time);
    }
  }

  // Each sign change of g - level between two of kBreakpointSamples samples, bisected.
  void sampled_crossings(const ex& g, const Levels& levels, double a, double b,
                         std::vector<double>& out) {
    double previous_t = a, previous = value(g, a);
    for (int i = 1; i <= kBreakpointSamples; ++i) {
      const double ti = i == kBreakpointSamples ? b : a + (b - a) * i / kBreakpointSamples;
      const double gi = value(g, ti);
      if (std::isfinite(previous) && std::isfinite(gi)) {
        std::vector<double> hit;
        levels.within(std::min(previous, gi), std::max(previous, gi), hit);
        for (double level : hit) out.push_back(bisect(g, level, previous_t, previous, ti));
      }
      previous_t = ti;
      previous = gi;
      if (out.size() > 4 * kMaxBreakpoints) too_many(t0_, t1_);
    }
  }

  // The time in [lo, hi] where g = level, g(lo) = glo and g(hi) on the level's other side.
  double bisect(const ex& g, double level, double lo, double glo, double hi) {
    if (glo == level) return lo;
    const bool below = glo < level;
    for (int it = 0; it < 200; ++it) {
      const double mid = lo + (hi - lo) / 2;
      if (!(mid > lo && mid < hi)) break;
      const double gm = value(g, mid);
      if (!std::isfinite(gm)) break;
      if ((gm < level) == below && gm != level) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    return hi;
  }

  double value(const ex& g, double at) const {
    try {
      const ex v = GiNaC::evalf(g.subs(t_ == exact_numeric(at)));
      if (!GiNaC::is_a<numeric>(v) || !GiNaC::ex_to<numeric>(v).is_real())
        return std::numeric_limits<double>::quiet_NaN();
      return GiNaC::ex_to<numeric>(v).to_double();
    } catch (const std::exception&) {
      return std::numeric_limits<double>::quiet_NaN();  // outside a table: no crossing there
    }
  }

  ex t_;
  double t0_, t1_;
  std::map<ex, std::vector<double>, GiNaC::ex_is_less> memo_;
};

}  // namespace

void BreakpointLevels::within(double lo, double hi, std::vector<double>& out) const {
  if (!(lo <= hi)) return;
  if (period <= 0) {
    for (auto it = std::lower_bound(base.begin(), base.end(), lo); it != base.end() && *it <= hi;
         ++it)
      out.push_back(*it);
    return;
  }
  const double k0 = std::floor(lo / period) - 1, k1 = std::floor(hi / period) + 1;
  if (!(k1 - k0 < static_cast<double>(kMaxBreakpoints))) too_many(lo, hi);
  for (double k = k0; k <= k1; ++k)
    for (double b : base) {
      const double level = b + k * period;
      if (level >= lo && level <= hi) out.push_back(level);
    }
}

std::vector<double> breakpoints(const CompiledModel& model, double t0, double t1) {
  return breakpoints(model, derive_forces(model), t0, t1);
}

std::vector<double> breakpoints(const CompiledModel& model, const ForceModel& forces, double t0,
                                double t1) {
  if (!(t1 > t0) || !std::isfinite(t0) || !std::isfinite(t1)) return {};
  const SymbolTable& symbols = model.symbols();
  const SymbolicModel& sym = model.symbolic();
  Finder finder(symbols.t(), t0, t1);
  std::vector<double> times;
  const auto add = [&](const ex& e) {
    finder.of(substitute_params(e, symbols, sym.param_values), times);
  };
  for (const ex& row : sym.phi) add(row);
  for (const ex& q : forces.applied) add(q);
  std::sort(times.begin(), times.end());
  // Times a few ulps apart are one (a piece's boundary found both by its select and by the law
  // that starts there, each rounded once).
  constexpr double kUlps = 4 * std::numeric_limits<double>::epsilon();
  const auto near = [&](double a, double b) {
    return std::abs(a - b) <= kUlps * std::max(std::abs(a), std::abs(b));
  };
  std::vector<double> out;
  for (double t : times) {
    if (!(t > t0 && t < t1) || near(t, t0) || near(t, t1)) continue;
    if (!out.empty() && near(out.back(), t)) continue;
    out.push_back(t);
  }
  if (out.size() > kMaxBreakpoints) too_many(t0, t1);
  return out;
}

}  // namespace kinegen::codegen

namespace kinegen::codegen {

std::vector<StateSwitch> state_switches(const CompiledModel& model, const ForceModel& forces) {
  const SymbolTable& symbols = model.symbols();
  const SymbolicModel& sym = model.symbolic();
  std::set<ex, GiNaC::ex_is_less> calls;
  const auto add = [&](const ex& e) {
    const ex v = substitute_params(e, symbols, sym.param_values);
    for (auto it = v.preorder_begin(); it != v.preorder_end(); ++it) {
      ex argument;
      Levels levels;
      if (!nonsmooth_call(*it, argument, levels)) continue;
      for (auto s = argument.preorder_begin(); s != argument.preorder_end(); ++s)
        if (GiNaC::is_a<GiNaC::symbol>(*s) && !s->is_equal(symbols.t())) {
          calls.insert(*it);
          break;
        }
    }
  };
  for (const ex& row : sym.phi) add(row);
  for (const ex& q : forces.applied) add(q);
  std::vector<StateSwitch> out;
  for (const ex& call : calls) {
    StateSwitch s;
    nonsmooth_call(call, s.argument, s.levels);
    // The same argument and levels twice (poly345(x) and poly345'(x)) is one switch.
    bool seen = false;
    for (const StateSwitch& o : out)
      seen = seen || (o.argument.is_equal(s.argument) && o.levels.base == s.levels.base &&
                      o.levels.period == s.levels.period);
    if (!seen) out.push_back(std::move(s));
  }
  return out;
}

}  // namespace kinegen::codegen

namespace kinegen::codegen {

void check_input_coverage(const CompiledModel& model, const std::string& name,
                          const std::string& path, double t0, double t1) {
  const Mechanism& m = model.mechanism();
  int id = -1;
  for (const Constraint& d : m.drivers)
    if (d.name == name && d.law.table_id >= 0) id = d.law.table_id;
  for (const Load& l : m.forces.loads)
    for (const Load::Input& in : l.inputs)
      if (in.name == name && in.table_id >= 0) id = in.table_id;
  if (id < 0) return;
  const Spline& s = registered_table(id);
  if (table_covers(s, t0) && table_covers(s, t1)) return;
  const double lo = s.t.front(), hi = s.t.back();
  // 15 digits: a table's 0.1 reads 0.1, not its double's 0.10000000000000001.
  const auto shown = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.15g", v);
    return std::string(text);
  };
  throw UsageError("--input " + name + "=" + path + ": the table covers t = " + shown(lo) + " to " +
                   shown(hi) + ", the run t = " + shown(t0) + " to " + shown(t1) +
                   ": an input table must cover the whole run (it is never extrapolated)");
}

void check_input_coverage(const CompiledModel& model, double t0, double t1) {
  for (const auto& [name, path] : model.build_options().inputs)
    check_input_coverage(model, name, path, t0, t1);
}

}  // namespace kinegen::codegen
