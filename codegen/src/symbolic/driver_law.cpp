// A driver's law in pieces, with a period, from a table or a run-time input: DriverLawBuilder,
// which also checks its boundaries and seams.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

using namespace symbolic_detail;

namespace {

// A driver's law in pieces, with a period, from a table or a run-time input, as
// one expression in t. Checks the pieces' order, the period and, with `warnings`, at every
// boundary and seam, f, f' and f'' from either side: a jump in f throws, one in f' or f'' is
// added to `warnings`.
class DriverLawBuilder {
 public:
  // unit: the driven quantity's (1 rad for an angle, the mechanism's length scale for a
  // length, 1 for an expression), the least scale a jump is measured against.
  DriverLawBuilder(const Constraint& c, const Mechanism& m, const SymbolTable& s,
                   const std::vector<GiNaC::numeric>& values, double unit = 1)
      : c_(c), m_(m), s_(s), values_(values), unit_(unit) {}

  ex build(std::vector<std::string>* warnings) const {
    const DriverLaw& law = c_.law;
    const ex t = s_.t();
    std::optional<ex> period;
    if (law.period) {
      period = geometry_value(m_, s_, values_, *law.period, c_.item + " period");
      if (!(number(*period) > 0))
        fail(law.period->loc,
             "period must be greater than 0 (it is " + format_number(number(*period)) + ")");
    }
    if (law.table_id >= 0) {
      const Spline& spline = registered_table(law.table_id);
      if (period && std::abs(number(*period) - spline.period) >
                        1e-12 * std::max(1.0, std::abs(spline.period)))
        fail(law.period->loc, "a periodic table's period must be its last t (" +
                                  format_number(spline.period) + "), not " +
                                  format_number(number(*period)));
      return kinegen_table(law.table_id, 0, t);
    }
    if (law.input) return kinegen_input_law(t);
    // Pieces: f_k on [until_{k-1}, until_k), the last one open.
    const std::size_t n = law.pieces.size();
    std::vector<ex> f(n), until(n - 1);
    std::vector<double> at(n - 1);
    for (std::size_t k = 0; k < n; ++k) {
      const DriverPiece& p = law.pieces[k];
      const std::string item = piece_item(k);
      f[k] = s_.parse(p.f, Scope::kDriverTime, item + " f");
      check_defined_value(m_, s_, values_, f[k], p.f, item + " f");
      if (k + 1 == n) break;
      until[k] = geometry_value(m_, s_, values_, p.until, item + " until");
      at[k] = number(until[k]);
      if (k > 0 && !(at[k] > at[k - 1]))
        fail(p.until.loc, "pieces out of order: until " + format_number(at[k]) +
                              " must be greater than the previous piece's " +
                              format_number(at[k - 1]));
      if (period && !(at[k] > 0 && at[k] < number(*period)))
        fail(p.until.loc, "until " + format_number(at[k]) + " must lie inside (0, period) = (0, " +
                              format_number(number(*period)) + ")");
    }
    // The law in x: t itself, or t wrapped into [0, T).
    const ex x = period ? t - *period * kinegen_floor(t / *period) : t;
    ex value = f[n - 1].subs(t == x);
    for (std::size_t k = n - 1; k-- > 0;)
      value = kinegen_select(x - until[k], f[k].subs(t == x), value);
    std::vector<Joint> joints;
    for (std::size_t k = 0; k + 1 < n; ++k)
      joints.push_back({f[k], f[k + 1], until[k], until[k],
                        "the boundary t = " + format_number(at[k]), law.pieces[k + 1].loc});
    if (period) {
      // Each period adds f(T) - f(0); the seam compares the last piece's end with the first
      // piece's start moved up by that rise.
      const ex rise = f[n - 1].subs(t == *period) - f[0].subs(t == 0);
      value += kinegen_floor(t / *period) * rise;
      joints.push_back({f[n - 1], f[0] + rise, *period, 0,
                        "the period's seam t = " + format_number(number(*period)),
                        law.period->loc});
    }
    if (warnings) check_joints(joints, *warnings);
    return value;
  }

 private:
  struct Joint {
    ex before, after;        // the pieces on either side (in t)
    ex at_before, at_after;  // where each is taken
    std::string name;
    SourceLoc loc;  // the piece after it
  };

  // f, f', f'' across each joint; a difference above 1e-9 of the local scale counts: the
  // larger of the two sides' magnitudes of that derivative there and the driven quantity's
  // unit (before version 3 the scale was the law's largest magnitude anywhere, which a
  // later piece's growth far from the boundary raises, could hide a real jump). At 40 digits,
  // so rounding never counts.
  void check_joints(const std::vector<Joint>& joints, std::vector<std::string>& warnings) const {
    if (joints.empty()) return;
    const ex t = s_.t();
    const DigitsGuard digits(kEvalDigits);
    double left[3][kMaxJoints], right[3][kMaxJoints];
    const std::size_t count = std::min(joints.size(), kMaxJoints);
    // Each side is taken a hair inside its piece (1e-25 of the time's size, far below the
    // 1e-9 that counts), so that a clamped law's corner at the boundary (harmonic'' at 0)
    // is seen as its piece's one-sided limit, not as the clamped value.
    const GiNaC::numeric hair = GiNaC::numeric(1, 10).power(25);
    for (std::size_t j = 0; j < count; ++j) {
      ex a = joints[j].before, b = joints[j].after;
      const ex tb = joints[j].at_before, ta = joints[j].at_after;
      const ex before = tb - hair * std::max(1.0, std::abs(number(tb)));
      const ex after = ta + hair * std::max(1.0, std::abs(number(ta)));
      for (int o = 0; o < 3; ++o) {
        left[o][j] = number(a.subs(t == before));
        right[o][j] = number(b.subs(t == after));
        a = a.diff(GiNaC::ex_to<GiNaC::symbol>(t));
        b = b.diff(GiNaC::ex_to<GiNaC::symbol>(t));
      }
    }
    const char* what[3] = {"f", "f'", "f''"};
    for (std::size_t j = 0; j < count; ++j)
      for (int o = 0; o < 3; ++o) {
        const double scale = std::max({std::abs(left[o][j]), std::abs(right[o][j]), unit_});
        // Halves: a difference of two values near the largest double must not overflow.
        const double half = left[o][j] / 2 - right[o][j] / 2;
        if (!(std::abs(half) > 0.5e-9 * scale) && std::isfinite(half)) continue;
        const std::string message = std::string(what[o]) + " jumps at " + joints[j].name + ": " +
                                    format_number(shown(left[o][j], scale)) + " before it, " +
                                    format_number(shown(right[o][j], scale)) + " after it";
        if (o == 0) fail(joints[j].loc, message);
        warnings.push_back(m_.source + ":" + std::to_string(joints[j].loc.line) + ": " + c_.item +
                           ": " + message +
                           (o == 1 ? "; velocities jump there" : "; accelerations jump there"));
      }
  }

  // A side's value as a message shows it: taken a hair inside its piece, a value that is 0 at
  // the boundary (a rise's f'' at its end) comes out as a few 1e-23; below 1e-12 of the scale
  // the jump is measured in, it is that hair's rounding, so it reads 0.
  static double shown(double v, double scale) { return std::abs(v) <= 1e-12 * scale ? 0.0 : v; }

  // The run-time input law: inputs(driver, order, t) (functions.hpp), its derivatives the
  // inputs of the next order.
  ex kinegen_input_law(const ex& t) const { return kinegen_input(driver_index(), 0, t); }

  int driver_index() const {
    for (std::size_t k = 0; k < m_.drivers.size(); ++k)
      if (&m_.drivers[k] == &c_) return static_cast<int>(k);
    throw std::logic_error("an input driver that is not in the mechanism");
  }

  std::string piece_item(std::size_t k) const { return c_.item + " f[" + std::to_string(k) + "]"; }

  double number(const ex& e) const { return to_double(substitute_params(e, s_, values_)); }

  [[noreturn]] void fail(const SourceLoc& loc, const std::string& message) const {
    throw InputError(m_.source, c_.item, loc, message);
  }

  static constexpr std::size_t kMaxJoints = 1001;
  const Constraint& c_;
  const Mechanism& m_;
  const SymbolTable& s_;
  const std::vector<GiNaC::numeric>& values_;
  double unit_;
};

}  // namespace

namespace symbolic_detail {

ex driver_law(const Constraint& c, const Mechanism& m, const SymbolTable& s,
              const std::vector<GiNaC::numeric>& values) {
  return DriverLawBuilder(c, m, s, values).build(nullptr);
}

std::vector<std::string> driver_law_warnings(const Mechanism& m, const SymbolTable& s,
                                             const std::vector<GiNaC::numeric>& values,
                                             double length_scale) {
  std::vector<std::string> warnings;
  for (const Constraint& c : m.drivers) {
    if (c.law.pieces.empty()) continue;
    const std::string type = c.kind->name;
    const bool angle = type == "absolute_angle" || type == "relative_angle";
    const bool length = type == "absolute_x" || type == "absolute_y" || type == "distance";
    DriverLawBuilder(c, m, s, values, angle ? 1.0 : length ? length_scale : 1.0).build(&warnings);
  }
  return warnings;
}

}  // namespace symbolic_detail

}  // namespace kinegen::codegen
